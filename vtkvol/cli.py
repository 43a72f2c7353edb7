"""The ``vtkvol`` command: ``open`` (the app), ``render`` (headless PNG), ``info``, ``bench``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from vtkvol.model.scene import BLEND_MODES

SESSION_SUFFIX = ".vtkvol.json"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vtkvol",
        description="Volume rendering of microscopy data with real illumination.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p_open = sub.add_parser("open", help="start the desktop app (optionally with a file)")
    p_open.add_argument("file", nargs="?", help="volume, folder of slices or session file")
    p_open.add_argument("--sample", action="store_true", help="open the built-in sample volume")
    p_open.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"),
                        help="override the voxel size in µm")

    p_render = sub.add_parser("render", help="render a volume or session to PNG, headless")
    p_render.add_argument("file", help="volume file/folder, session file, or 'sample'")
    p_render.add_argument("-o", "--output", required=True, help="PNG file to write")
    p_render.add_argument("--size", nargs=2, type=int, default=(800, 600), metavar=("W", "H"))
    p_render.add_argument("--azimuth", type=float, default=None,
                          help="degrees from the front view (default 30; sessions: orbit)")
    p_render.add_argument("--elevation", type=float, default=None,
                          help="degrees from the front view (default 20; sessions: orbit)")
    p_render.add_argument("--preset", help="transfer-function preset or colormap name")
    p_render.add_argument("--method", help="illumination method (e.g. local, shadow_volume)")
    p_render.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                          help="illumination parameter (repeatable)")
    p_render.add_argument("--blend", choices=BLEND_MODES, help="blend mode")
    p_render.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"))
    p_render.add_argument("--time", type=int, default=0, help="time point to render")
    p_render.add_argument("--overwrite", action="store_true",
                          help="replace the output file if it exists")

    p_info = sub.add_parser("info", help="describe a volume file")
    p_info.add_argument("file")
    p_info.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"))

    p_bench = sub.add_parser("bench", help="speed against accuracy benchmark")
    p_bench.add_argument("-o", "--output", required=True, metavar="DIR",
                         help="folder for benchmarks.{json,csv,md} and charts (created; "
                              "earlier results there are merged, other files left alone)")
    p_bench.add_argument("--quick", action="store_true", help="a run of a few minutes")
    p_bench.add_argument("--data", action="append", default=[], metavar="FILE",
                         help="a volume of yours to measure on, besides the phantoms "
                              "(repeatable; any format vtkvol reads)")
    p_bench.add_argument("--size", type=int, default=None, help="override the scene size (voxels)")
    p_bench.add_argument("--scattering", action="store_true",
                         help="run the convergence study of the multiple-scattering techniques "
                              "instead (against path-traced references, 1 and 3 lights)")
    return parser


def _parse_value(text: str):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def _load(path: str, voxel_size, time_index: int = 0):
    from vtkvol.io import confocal_phantom, read_volume

    if path == "sample":
        return confocal_phantom()
    return read_volume(path, voxel_size_um=voxel_size, time_index=time_index)


def cmd_render(args: argparse.Namespace) -> int:
    from vtkvol.engine.api import render_image

    out = Path(args.output)
    if out.exists() and not args.overwrite:
        print(f"vtkvol: {out} exists; pass --overwrite to replace it", file=sys.stderr)
        return 2
    model = None
    if args.file.endswith(SESSION_SUFFIX):
        from vtkvol.model.session import load_session_with_data

        model, data = load_session_with_data(args.file)
    else:
        data = _load(args.file, args.voxel_size, args.time)
    if args.blend:
        from vtkvol.model.defaults import scene_for

        model = model or scene_for(data)
        model.render.blend_mode = args.blend
    params = {}
    for item in args.param:
        name, sep, value = item.partition("=")
        if not sep:
            print(f"vtkvol: --param needs NAME=VALUE, got {item!r}", file=sys.stderr)
            return 2
        params[name] = _parse_value(value)
    image = render_image(
        data, model=model, size=tuple(args.size), method=args.method, preset=args.preset,
        azimuth=args.azimuth, elevation=args.elevation, parameters=params or None,
        on_error=lambda message: print(f"vtkvol: {message}", file=sys.stderr),
    )
    _write_png(image, out)
    print(f"wrote {out} ({image.shape[1]}×{image.shape[0]})")
    return 0


def _write_png(image, path: Path) -> None:
    """Write atomically: a failed write never leaves a truncated PNG behind."""
    import os
    import tempfile

    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    h, w, _ = image.shape
    img = vtk.vtkImageData()
    img.SetDimensions(w, h, 1)
    img.GetPointData().SetScalars(numpy_to_vtk(image[::-1].reshape(-1, 3).copy(), deep=True))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; a PNG gets the usual permissions
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(tmp)
    writer.SetInputData(img)
    writer.Write()
    os.replace(tmp, path)


def cmd_info(args: argparse.Namespace) -> int:
    data = _load(args.file, args.voxel_size)
    print(data.describe())
    return 0


def cmd_open(args: argparse.Namespace) -> int:
    try:
        from vtkvol.ui.app import run_app
    except ImportError as exc:
        print(f"vtkvol: the desktop app needs the [app] extras ({exc})", file=sys.stderr)
        return 2
    return run_app(args.file, sample=args.sample or args.file is None,
                   voxel_size=args.voxel_size)


def cmd_bench(args: argparse.Namespace) -> int:
    from vtkvol.bench.runner import main as bench_main

    output = Path(args.output)
    if output.exists() and not output.is_dir():
        print(f"vtkvol: {output} is a file, not a folder for the results", file=sys.stderr)
        return 1
    for file in args.data:
        if not Path(file).exists():
            print(f"vtkvol: --data {file}: no such file", file=sys.stderr)
            return 1
    if args.scattering:
        from vtkvol.bench.runner import main_scattering

        return main_scattering(quick=args.quick, out=str(output), size=args.size, data=args.data)
    return bench_main(quick=args.quick, out=str(output), size=args.size, data=args.data)


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    handlers = {"render": cmd_render, "info": cmd_info, "open": cmd_open, "bench": cmd_bench}
    try:
        return handlers[args.command](args)
    except KeyboardInterrupt:
        return 130
    except (ValueError, OSError) as exc:  # VolumeReadError and SessionError are ValueErrors
        print(f"vtkvol: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
