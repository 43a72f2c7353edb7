"""The ``vtkvol`` command: ``open`` (the app), ``render`` (headless PNG or turntable movie),
``info``, ``bench``, ``batch`` (many renders on a Dask cluster), ``convert`` (an OME-Zarr
pyramid from a large volume)."""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from vtkvol.cli_movie import (
    _keyframe_option_problem,
    _movie_problem,
    _render_keyframes,
    _render_turntable,
)
from vtkvol.cli_signals import Terminated, _signals
from vtkvol.files import load_input as _load
from vtkvol.files import write_png as _write_png
from vtkvol.model.renderers import RENDERERS
from vtkvol.model.scene import BLEND_ALIASES, BLEND_MODES
from vtkvol.model.session import is_session_path


def _add_view_options(parser: argparse.ArgumentParser) -> None:
    """The options `render` and `batch` share: image size, view, transfer function, method."""
    parser.add_argument("--size", nargs=2, type=int, default=(800, 600), metavar=("W", "H"))
    parser.add_argument("--azimuth", type=float, default=None,
                        help="degrees from the front view (default 30; sessions: orbit)")
    parser.add_argument("--elevation", type=float, default=None,
                        help="degrees from the front view (default 20; sessions: orbit)")
    parser.add_argument("--preset", help="transfer-function preset or colormap name")
    parser.add_argument("--method", help="illumination method (e.g. local, shadow_volume)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="illumination parameter (repeatable)")
    # PyVista's names (maximum, minimum) are accepted too; the model stores ours.
    parser.add_argument("--blend", choices=(*BLEND_MODES, *BLEND_ALIASES),
                        help="blend mode (PyVista's maximum/minimum = mip/minip)")
    parser.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"))


def _budget(text: str) -> int:
    """``--gpu-budget`` as bytes (``1GiB``, ``512MiB``…); argparse shows the problem."""
    from vtkvol.io.pyramid import parse_bytes

    try:
        return parse_bytes(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


_BUDGET_HELP = ("GPU-memory budget of the volume shown (e.g. 512MiB, 2GiB; default 1GiB): "
                "the finest pyramid level of an OME-Zarr or Imaris file that fits is read")


def _parse_params(items: Sequence[str]) -> dict[str, Any] | str:
    """``--param NAME=VALUE`` items as a dict, or the one-line problem."""
    params: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            return f"--param needs NAME=VALUE, got {item!r}"
        parsed = _parse_value(value)
        if isinstance(parsed, float) and not math.isfinite(parsed):
            return f"--param {name}: the value must be a finite number, got {value!r}"
        params[name] = parsed
    return params


class _Parser(argparse.ArgumentParser):
    """argparse, with its complaints as one ``vtkvol:`` line (not the usage block) naming the
    command and the option."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"vtkvol: {self.prog}: {message} (see {self.prog} --help)\n")


#: The unit each float option is in, for its message when it is not a finite number.
_FLOAT_UNITS = {"azimuth": " of degrees", "elevation": " of degrees", "turntable": " of degrees",
                "fps": " of frames per second", "time_budget": " of seconds",
                "connect_timeout": " of seconds"}


def _non_finite_problem(args: argparse.Namespace) -> str | None:
    """The first float option of any command that is NaN or infinite (argparse's ``float``
    takes ``nan``, ``inf`` and ``1e999``; none of them is ever a meaningful value)."""
    for name, value in vars(args).items():
        values = value if isinstance(value, (list, tuple)) else [value]
        floats = [v for v in values if isinstance(v, float)]
        if all(math.isfinite(v) for v in floats):
            continue
        flag = "--" + name.replace("_", "-")
        shown = " ".join(f"{v:g}" for v in values)
        return f"{flag} must be a finite number{_FLOAT_UNITS.get(name, '')}, got {shown}"
    return None


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="vtkvol",
        description="Volume rendering of microscopy data with real illumination.",
    )
    parser.add_argument("--verbose", action="store_true",
                        help="show warnings of the libraries vtkvol uses in full (by default "
                             "each is one 'vtkvol: note:' line); may follow the command too")
    sub = parser.add_subparsers(dest="command", required=True)

    p_open = sub.add_parser("open", help="start the desktop app (optionally with a file)")
    p_open.add_argument("file", nargs="?", help="volume, folder of slices or session file")
    p_open.add_argument("--sample", action="store_true", help="open the built-in sample volume")
    p_open.add_argument("--as-channels", action="store_true",
                        help="FILE is a folder of stacks of one shape: read each as a channel")
    p_open.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"),
                        help="override the voxel size in µm")
    p_open.add_argument("--time", type=int, default=None, metavar="T",
                        help="time point to show first (0-based; a session's otherwise)")
    p_open.add_argument("--gpu-budget", type=_budget, default=None, metavar="SIZE",
                        help=_BUDGET_HELP + " (default: the app's setting)")

    p_render = sub.add_parser("render", help="render a volume or session to PNG, headless")
    p_render.add_argument("file", help="volume file/folder, session file, or 'sample'")
    p_render.add_argument("-o", "--output", required=True,
                          help="PNG file to write; with --turntable or --keyframes: .mp4, a "
                               ".png sequence (spin.png → spin_0000.png…), a .tif stack or a "
                               "folder of PNGs")
    _add_view_options(p_render)
    p_render.add_argument("--time", type=int, default=None, metavar="T",
                          help="time point to render (0-based; a session's own otherwise)")
    p_render.add_argument("--gpu-budget", type=_budget, default=None, metavar="SIZE",
                          help=_BUDGET_HELP)
    p_render.add_argument("--as-channels", action="store_true",
                          help="FILE is a folder of stacks of one shape: read each as a channel")
    p_render.add_argument("--overwrite", action="store_true",
                          help="replace the output file if it exists")
    p_render.add_argument("--turntable", type=float, default=None, metavar="DEG",
                          help="render a movie turning the view by DEG degrees (360: a loop)")
    p_render.add_argument("--keyframes", metavar="FILE",
                          help="render the keyframe animation of a *.keyframes.json file "
                               "(camera, time point, lights; saved by the app's File → Export "
                               "movie…)")
    p_render.add_argument("--frames", type=int, default=None, metavar="N",
                          help="frames of the turntable movie (default 120; a keyframe movie "
                               "has duration × fps + 1)")
    p_render.add_argument("--fps", type=float, default=30.0,
                          help="frames per second of the movie (default 30)")
    p_render.add_argument("--iterations", type=int, default=None, metavar="N",
                          help="progressive methods (multiple scattering): refine to N "
                               "iterations (default: the method's own end)")
    p_render.add_argument("--time-budget", type=float, default=300.0, metavar="SECONDS",
                          help="progressive methods: stop refining after this many seconds "
                               "(default 300)")
    p_render.add_argument("--renderer", choices=RENDERERS, default=None,
                          help="what draws the volume: raycast (VTK's ray caster with the "
                               "method, default), path_tracer (progressive camera path tracer, "
                               "256 paths per pixel; --iterations N stops it earlier), slicing "
                               "(view-aligned slices, local lighting); a session's own otherwise")
    p_render.add_argument("--preintegration", action="store_true",
                          help="pre-integrated classification: each sample classifies the "
                               "segment from the previous one (sharp transfer functions at "
                               "coarse sample distances; one to four channels, composite blend)")
    p_render.add_argument("--adaptive-sampling", action="store_true",
                          help="larger steps (4 samples in one) where the classified opacity "
                               "is smooth, every step elsewhere (one channel, composite blend)")
    p_render.add_argument("--labels", action="store_true",
                          help="the first channel is a label image (segmentation): one colour "
                               "per id (glasbey), no blending between ids")

    p_info = sub.add_parser("info", help="describe a volume file")
    p_info.add_argument("file")
    p_info.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"))
    p_info.add_argument("--as-channels", action="store_true",
                        help="FILE is a folder of stacks of one shape: read each as a channel")
    p_info.add_argument("--gpu-budget", type=_budget, default=None, metavar="SIZE",
                        help=_BUDGET_HELP)

    p_convert = sub.add_parser(
        "convert", help="write an OME-Zarr pyramid from a large TIFF (or any readable volume)",
        description="Write INPUT as an OME-Zarr pyramid (NGFF 0.5, or 0.4 with --ngff 0.4) "
                    "without holding it in memory: voxel size and channel names in the "
                    "metadata, progress on stderr, written to a temporary folder and renamed.")
    p_convert.add_argument("input", help="volume file or folder (TIFF, OME-Zarr, Imaris, …)")
    p_convert.add_argument("output", help="the .zarr folder to write")
    p_convert.add_argument("--overwrite", action="store_true",
                           help="replace OUTPUT if it exists (only once the new one is complete)")
    p_convert.add_argument("--time", type=int, default=0, help="time point to convert")
    p_convert.add_argument("--channels", nargs="+", metavar="C",
                           help="channel indices or names to convert (default all)")
    p_convert.add_argument("--voxel-size", nargs=3, type=float, metavar=("X", "Y", "Z"),
                           help="voxel size in µm instead of the file's")
    p_convert.add_argument("--ngff", choices=("0.4", "0.5"), default="0.5",
                           help="NGFF version: 0.5 (Zarr v3, default) or 0.4 (Zarr v2)")

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
    p_bench.add_argument("--empty-space", action="store_true",
                         help="measure empty-space skipping instead: frame time with it off and "
                              "on, side by side, on the phantoms and every --data file")

    p_batch = sub.add_parser(
        "batch", help="render many sessions or time points to PNGs on a Dask cluster",
        description="Render each input (session file, volume file or 'sample'), at each time "
                    "point of --time, to OUTPUT/<name>.png (<name>_t0003.png with --time) on a "
                    "local cluster of worker processes or an existing Dask scheduler.")
    p_batch.add_argument("files", nargs="+", metavar="FILE",
                         help="session files (*.vtkvol.json), volume files/folders, or 'sample'")
    p_batch.add_argument("-o", "--output", required=True, metavar="DIR",
                         help="folder for the PNGs (created)")
    p_batch.add_argument("--time", metavar="T|START:STOP[:STEP]",
                         help="time points to render, STOP excluded (0:20: the first 20)")
    p_batch.add_argument("--workers", type=int, default=2, metavar="N",
                         help="worker processes of the local cluster, one thread each "
                              "(default 2)")
    p_batch.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                         help="use this running Dask scheduler instead of a local cluster")
    p_batch.add_argument("--connect-timeout", type=float, default=10.0, metavar="SECONDS",
                         help="give up on --scheduler after this long (default 10)")
    p_batch.add_argument("--egl-devices", metavar="I,J,…",
                         help="local cluster: EGL device index of each worker, round robin "
                              "(one worker per GPU: --workers 4 --egl-devices 0,1,2,3)")
    p_batch.add_argument("--overwrite", action="store_true",
                         help="replace PNGs that exist (default: refuse before rendering)")
    _add_view_options(p_batch)
    p_batch.add_argument("--iterations", type=int, default=None, metavar="N",
                         help="progressive methods: refine each image to N iterations")
    p_batch.add_argument("--time-budget", type=float, default=300.0, metavar="SECONDS",
                         help="progressive methods: refinement limit per image (default 300)")
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


#: Largest image side `vtkvol render` makes (pixels): an 8192² window is ~0.5 GiB of colour and
#: depth buffers, which GPU drivers and llvmpipe allocate; 100000² aborted inside VTK.
MAX_IMAGE_SIDE = 8192


def _view_option_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with ``--size``, ``--azimuth`` and ``--elevation`` (render and batch)."""
    w, h = args.size
    if not (1 <= w <= MAX_IMAGE_SIDE and 1 <= h <= MAX_IMAGE_SIDE):
        return (f"--size W H must be whole numbers of pixels from 1 to {MAX_IMAGE_SIDE}, "
                f"got {w} {h}")
    for name in ("azimuth", "elevation"):
        value = getattr(args, name, None)
        if value is not None and not math.isfinite(value):
            return f"--{name} must be a finite number of degrees, got {value}"
    return None


def _render_option_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with `vtkvol render`'s numeric and data options, before anything is
    read or rendered (a window of -5 pixels crashed EGL; 100000² aborted in VTK)."""
    problem = _view_option_problem(args)
    if problem:
        return problem
    if args.voxel_size is not None:  # positive and finite: checked in main()
        if args.file == "sample":
            return "--voxel-size does not apply to the built-in sample (it has its own)"
        if is_session_path(args.file):
            return ("--voxel-size does not apply to a session: it keeps its data's voxel size "
                    "(set it in the app with Edit → Voxel size…)")
    if args.time is not None and args.time < 0:
        return f"--time must be a time point index >= 0, got {args.time}"
    if args.time and args.file == "sample":
        return "--time does not apply to the built-in sample (it has one time point)"
    return None


def cmd_render(args: argparse.Namespace) -> int:
    from vtkvol.engine.api import render_image

    problem = _render_option_problem(args)
    if problem:
        print(f"vtkvol: {problem}", file=sys.stderr)
        return 2
    out = Path(args.output)
    animation = None
    if args.keyframes is not None:
        from vtkvol.model.keyframes import KeyframeError, read_keyframes

        problem = _keyframe_option_problem(args, out)
        if problem:
            print(f"vtkvol: {problem}", file=sys.stderr)
            return 2
        try:
            animation = read_keyframes(args.keyframes)
        except KeyframeError as exc:
            print(f"vtkvol: {exc}", file=sys.stderr)
            return 2
        try:
            args.frames = animation.frame_count(args.fps)
        except KeyframeError as exc:
            print(f"vtkvol: {Path(args.keyframes).name}: {exc}", file=sys.stderr)
            return 2
        if animation.animates_time and args.time:
            print("vtkvol: --time does not apply: the keyframes choose the time points",
                  file=sys.stderr)
            return 2
    if args.frames is not None and args.turntable is None and animation is None:
        print("vtkvol: --frames applies to --turntable movies only", file=sys.stderr)
        return 2
    if args.turntable is not None or animation is not None:
        if args.turntable is not None and args.frames is None:
            args.frames = 120
        problem = _movie_problem(args, out)
        if problem:
            print(f"vtkvol: {problem}", file=sys.stderr)
            return 2
    elif out.exists() and not args.overwrite:
        print(f"vtkvol: {out} exists; pass --overwrite to replace it", file=sys.stderr)
        return 2
    model = None
    if is_session_path(args.file):
        from vtkvol.model.session import load_session_with_data
        from vtkvol.model.techniques import get_spec

        name = Path(args.file).name
        notes: list[str] = []
        model, data = load_session_with_data(args.file, time_index=args.time,
                                             on_warning=notes.append)
        if args.method is None:
            try:
                get_spec(model.illumination.method)
            except ValueError as exc:  # the session's technique is not installed here
                print(f"vtkvol: {name}: illumination.method: {exc} (or pass --method)",
                      file=sys.stderr)
                return 2
        for note in notes:
            print(f"vtkvol: {name}: {note}", file=sys.stderr)
    else:
        data = _load(args.file, args.voxel_size, args.time or 0, args.gpu_budget,
                     as_channels=args.as_channels)
    inputs = {Path(p).resolve() for p in (args.file, data.source) if p and p != "sample"}
    if out.resolve() in inputs:
        print(f"vtkvol: {out} is the input; choose another name for the image", file=sys.stderr)
        return 2
    if (args.blend or args.labels or args.renderer or args.preintegration
            or args.adaptive_sampling):
        from vtkvol.model.defaults import scene_for

        model = model or scene_for(data)
    if args.preintegration:
        model.render.preintegration = True
    if args.adaptive_sampling:
        model.render.adaptive_sampling = True
    if args.blend:
        model.render.blend_mode = args.blend
    if model is not None:
        problem = _renderer_problem(args, model)
        if problem:
            print(f"vtkvol: {problem}", file=sys.stderr)
            return 2
    if args.labels:
        problem = _show_labels(model, data)
        if problem:
            print(f"vtkvol: --labels: {problem}", file=sys.stderr)
            return 2
    params = _parse_params(args.param)
    if isinstance(params, str):
        print(f"vtkvol: {params}", file=sys.stderr)
        return 2
    if args.iterations is not None and args.iterations < 1:
        print(f"vtkvol: --iterations must be at least 1, got {args.iterations}", file=sys.stderr)
        return 2
    if not (math.isfinite(args.time_budget) and args.time_budget >= 0):
        print(f"vtkvol: --time-budget must be a number of seconds >= 0, got {args.time_budget}",
              file=sys.stderr)
        return 2
    # Noted once every refusal is behind us: a refused command says one line, the refusal.
    uniform = _uniform_note(data)
    if uniform:
        print(f"vtkvol: {uniform}", file=sys.stderr)
    if args.turntable is not None:
        return _render_turntable(args, out, data, model, params)
    if animation is not None:
        return _render_keyframes(args, out, data, model, params, animation)

    def refined(iterations: int, converged: bool, seconds: float) -> None:
        how = "converged" if converged else "stopped by the time budget"
        if args.iterations is not None and iterations >= args.iterations:
            how = "as asked"
        print(f"refined to {iterations} iterations in {seconds:.1f} s ({how})")

    with _signals.deferred():  # raises Terminated after the render if a signal came
        image = render_image(
            data, model=model, size=tuple(args.size), method=args.method, preset=args.preset,
            azimuth=args.azimuth, elevation=args.elevation, parameters=params or None,
            iterations=args.iterations, max_seconds=args.time_budget,
            on_error=lambda message: print(f"vtkvol: {message}", file=sys.stderr),
            on_refined=refined,
        )
    try:
        _write_png(image, out, replace=args.overwrite)
    except FileExistsError:
        print(f"vtkvol: {out} appeared while rendering; it is left as it is (pass --overwrite "
              "to replace it)", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"vtkvol: could not write {out}: {exc.strerror or exc} (an existing file is left "
              "as it was)", file=sys.stderr)
        return 1
    print(f"wrote {out} ({image.shape[1]}×{image.shape[0]})")
    return 0


def _renderer_problem(args: argparse.Namespace, model: Any) -> str | None:
    """Why ``--renderer`` (or the session's ``render.renderer``) cannot draw this scene with
    the method and blend mode asked for, or None."""
    from vtkvol.model.scene import model_unsupported_reason

    if args.renderer:
        model.render.renderer = args.renderer
    if args.method:
        model.illumination.method = args.method
    reason = model_unsupported_reason(model)
    if reason is None:
        return None
    where = (f"--renderer {args.renderer}" if args.renderer
             else f"{Path(args.file).name}: render.renderer")
    return f"{where}: {reason}"


def _uniform_note(data) -> str | None:
    """The reader's note that every voxel has one value (the image then shows nothing but a
    uniform block, or nothing), with the file name; None for data with contrast."""
    for note in data.notes:
        if note.startswith("every voxel of each channel has the same value"):
            return f"{Path(data.source).name if data.source else 'the data'}: {note}"
    return None


def _show_labels(model, data) -> str | None:
    """Show channel 0 of ``data`` as labels in ``model``; what is wrong, or None."""
    import numpy as np

    from vtkvol.model.labels import LabelImageError, apply_labels, label_ids

    name = Path(data.source).name if data.source else "the data"
    try:
        ids = label_ids(np.asarray(data.array[0]), name)
    except LabelImageError as exc:
        return str(exc)
    apply_labels(model, ids)
    return None


def _voxel_size_problem(voxel_size: Sequence[float] | None) -> str | None:
    """``--voxel-size`` of every command that has it: three positive, finite µm values."""
    if voxel_size is not None and not all(math.isfinite(v) and v > 0 for v in voxel_size):
        return ("--voxel-size X Y Z must be three positive µm values, got "
                + " ".join(f"{v:g}" for v in voxel_size))
    return None


def cmd_info(args: argparse.Namespace) -> int:
    data = _load(args.file, args.voxel_size, budget=args.gpu_budget,
                 as_channels=args.as_channels)
    print(data.describe())
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    from vtkvol.io.convert import ConvertError, convert_to_ome_zarr

    if args.time < 0:
        print(f"vtkvol: --time must be a time point index >= 0, got {args.time}", file=sys.stderr)
        return 2
    channels = None if args.channels is None else [
        int(c) if c.isdigit() else c for c in args.channels]
    end = "\r" if sys.stderr.isatty() else "\n"

    def progress(fraction: float, message: str) -> None:
        print(f"{message}: {fraction:4.0%}" if message.startswith("writing the") else message,
              end=end if 0 < fraction < 1 else "\n", file=sys.stderr, flush=True)

    try:
        result = convert_to_ome_zarr(
            args.input, args.output, overwrite=args.overwrite, time_index=args.time,
            channels=channels, voxel_size_um=args.voxel_size, version=args.ngff,
            progress=progress)
    except ConvertError as exc:
        print(f"vtkvol: {exc}", file=sys.stderr)
        refused = ("exists", "is the input", "inside the input", "holds the input")
        return 2 if any(text in str(exc) for text in refused) else 1
    c, z, y, x = result.levels[0]
    sx, sy, sz = result.voxel_size_um
    print(f"wrote {result.path}: {len(result.levels)} levels from {x}×{y}×{z} (x×y×z, "
          f"{c} channel{'s' if c != 1 else ''}: {', '.join(result.channel_names)}), voxel "
          f"{sx:.4g}×{sy:.4g}×{sz:.4g} µm, in {result.seconds:.1f} s")
    return 0


def no_display_reason() -> str | None:
    """Why Qt cannot open a window here, or None when it can (as far as the environment says).

    On Linux and the BSDs a window needs an X server ($DISPLAY) or a Wayland compositor
    ($WAYLAND_DISPLAY), unless $QT_QPA_PLATFORM names a platform that needs neither (offscreen,
    vnc, eglfs…); macOS and Windows always have one.
    """
    if not sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return None
    if os.environ.get("QT_QPA_PLATFORM") or os.environ.get("DISPLAY"):
        return None
    if os.environ.get("WAYLAND_DISPLAY"):
        return None
    return "no display found (neither DISPLAY nor WAYLAND_DISPLAY is set)"


def cmd_open(args: argparse.Namespace) -> int:
    if args.time is not None and args.time < 0:
        print(f"vtkvol: --time must be a time point index >= 0, got {args.time}", file=sys.stderr)
        return 2
    if args.time and args.file is None:
        print("vtkvol: --time does not apply to the built-in sample (it has one time point)",
              file=sys.stderr)
        return 2
    problem = _folder_problem(args)
    if problem:
        print(f"vtkvol: {problem}", file=sys.stderr)
        return 2
    if no_display_reason() is not None:
        print(f"vtkvol: {no_display_reason()}; the app needs a desktop session. Headless, render "
              f"images instead: vtkvol render {args.file or 'sample'} -o view.png",
              file=sys.stderr)
        return 2
    try:
        from vtkvol.ui.app import run_app
    except ImportError as exc:
        print(f"vtkvol: the desktop app needs the [app] extras ({exc})", file=sys.stderr)
        return 2
    return run_app(args.file, sample=args.sample or args.file is None,
                   voxel_size=args.voxel_size, time_index=args.time, gpu_budget=args.gpu_budget,
                   as_channels=args.as_channels)


def _folder_problem(args: argparse.Namespace) -> str | None:
    """`vtkvol open FOLDER` of several stacks: the one line that lists them (before the app
    starts); `--as-channels` on something that is not a folder of stacks: why not."""
    from vtkvol.io.folder import SeveralStacksError, folder_stacks

    path = Path(args.file) if args.file else None
    if args.as_channels and (path is None or not path.is_dir()):
        return (f"--as-channels needs a folder of stacks; {args.file} is not a folder"
                if path is not None else "--as-channels needs a folder of stacks")
    if path is None or not path.is_dir() or args.as_channels:
        return None
    try:
        stacks = folder_stacks(path)
    except ValueError as exc:
        return str(exc)
    if len(stacks) > 1:
        return str(SeveralStacksError(path, stacks))
    return None


def cmd_bench(args: argparse.Namespace) -> int:
    from vtkvol.bench.runner import check_size
    from vtkvol.bench.runner import main as bench_main

    try:
        check_size(args.size)  # before anything is made (a 100000³ phantom never finishes)
    except ValueError as exc:
        print(f"vtkvol: {exc}", file=sys.stderr)
        return 2
    output = Path(args.output)
    if output.exists() and not output.is_dir():
        print(f"vtkvol: {output} is a file, not a folder for the results", file=sys.stderr)
        return 1
    for file in args.data:
        if not Path(file).exists():
            print(f"vtkvol: --data {file}: no such file", file=sys.stderr)
            return 1
    if args.empty_space:
        from vtkvol.bench.empty_space import main as empty_space_main

        return empty_space_main(quick=args.quick, out=str(output), size=args.size,
                                data=args.data)
    if args.scattering:
        from vtkvol.bench.runner import main_scattering

        return main_scattering(quick=args.quick, out=str(output), size=args.size, data=args.data)
    return bench_main(quick=args.quick, out=str(output), size=args.size, data=args.data)


def cmd_batch(args: argparse.Namespace) -> int:
    """``vtkvol batch``: plan the jobs, refuse existing PNGs, render them on a Dask cluster
    (vtkvol.batch); one stderr line per finished job; exit 1 if any job failed."""
    import time

    from vtkvol.batch import (
        BatchError,
        RenderOptions,
        existing_outputs,
        max_local_workers,
        parse_time_range,
        plan_jobs,
        run_batch,
        scheduler_address_problem,
    )

    def fail(message: str) -> int:
        print(f"vtkvol: {message}", file=sys.stderr)
        return 2

    problem = _view_option_problem(args)
    if problem:
        return fail(problem)
    params = _parse_params(args.param)
    if isinstance(params, str):
        return fail(params)
    if args.iterations is not None and args.iterations < 1:
        return fail(f"--iterations must be at least 1, got {args.iterations}")
    if not (math.isfinite(args.time_budget) and args.time_budget >= 0):
        return fail(f"--time-budget must be a number of seconds >= 0, got {args.time_budget}")
    if not (math.isfinite(args.connect_timeout) and args.connect_timeout > 0):
        return fail(f"--connect-timeout must be a number of seconds > 0, "
                    f"got {args.connect_timeout}")
    if args.workers < 1:
        return fail(f"--workers must be at least 1, got {args.workers}")
    if args.scheduler is None and args.workers > max_local_workers():
        return fail(f"--workers must be at most {max_local_workers()} (4 per CPU core of this "
                    f"machine), got {args.workers}; for more, start a cluster and pass "
                    "--scheduler")
    if args.scheduler is not None:
        problem = scheduler_address_problem(args.scheduler)
        if problem:
            return fail(problem)
    devices = None
    if args.egl_devices:
        try:
            devices = [int(d) for d in args.egl_devices.split(",")]
        except ValueError:
            return fail(f"--egl-devices takes device numbers like 0,1,2, got {args.egl_devices!r}")
        if any(d < 0 for d in devices):
            return fail(f"--egl-devices takes device numbers >= 0, got {args.egl_devices!r}")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        return fail(f"{out} is a file, not a folder for the images")
    options = RenderOptions(
        size=tuple(args.size), azimuth=args.azimuth, elevation=args.elevation,
        method=args.method, preset=args.preset, parameters=params, blend=args.blend,
        voxel_size=tuple(args.voxel_size) if args.voxel_size else None,
        iterations=args.iterations, max_seconds=args.time_budget,
    )
    try:
        times = parse_time_range(args.time) if args.time is not None else None
        jobs = plan_jobs(args.files, out, times=times, options=options)
    except FileNotFoundError as exc:
        return fail(f"{exc.filename}: no such file or folder; nothing was rendered")
    except ValueError as exc:
        return fail(str(exc))
    existing = existing_outputs(jobs)
    if existing and not args.overwrite:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        return fail(f"{existing[0]} exists{more}; pass --overwrite to replace it")
    where = args.scheduler or f"a local cluster of {args.workers} worker process(es)"
    print(f"rendering {len(jobs)} image(s) on {where}", file=sys.stderr, flush=True)

    def progress(done: int, total: int, result) -> None:
        job = result.job
        for note in result.notes:
            print(f"vtkvol: {job.name}: {note}", file=sys.stderr)
        if result.ok:
            print(f"[{done}/{total}] {job.name} -> {job.output} ({result.seconds:.1f} s, "
                  f"{result.worker})", file=sys.stderr, flush=True)
        else:
            print(f"[{done}/{total}] FAILED {job.name}: {result.error}", file=sys.stderr,
                  flush=True)

    t0 = time.perf_counter()
    try:
        results = run_batch(jobs, scheduler=args.scheduler, workers=args.workers,
                            egl_devices=devices, overwrite=args.overwrite,
                            connect_timeout=args.connect_timeout, progress=progress)
    except BatchError as exc:
        print(f"vtkvol: {exc}", file=sys.stderr)
        return 1
    failed = [r for r in results if not r.ok]
    print(f"wrote {len(results) - len(failed)} of {len(results)} image(s) to {out} in "
          f"{time.perf_counter() - t0:.1f} s" + (f"; {len(failed)} failed" if failed else ""))
    return 1 if failed else 0


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` for the command line: one ``vtkvol:`` line, no source path
    and no source line (a library's warning is a note to the user, not a program listing)."""
    text = " ".join(str(message).split())
    if not issubclass(category, UserWarning):  # numpy's RuntimeWarning and the like
        text = f"{category.__name__}: {text}"
    print(f"vtkvol: note: {text}", file=sys.stderr if file is None else file)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # --verbose may stand anywhere (``vtkvol render x.tif -o y.png --verbose``): it is taken
    # out before the sub-command's parser sees it.
    verbose = "--verbose" in argv
    args = _parser().parse_args([a for a in argv if a != "--verbose"])
    problem = (_voxel_size_problem(getattr(args, "voxel_size", None))
               or _non_finite_problem(args))
    if problem:
        print(f"vtkvol: {problem}", file=sys.stderr)
        return 2
    handlers = {"render": cmd_render, "info": cmd_info, "open": cmd_open, "bench": cmd_bench,
                "batch": cmd_batch, "convert": cmd_convert}
    previous: dict[int, Any] = {}
    # Only the commands that write files; the app (open) has Qt's event loop, where a Python
    # exception from a signal handler would land in some slot instead of ending the process.
    # Handlers can be set only from the main thread (tests may call main from another).
    if args.command in ("render", "convert", "batch") and \
            threading.current_thread() is threading.main_thread():
        _signals.received, _signals.defer = None, False
        for signum in (signal.SIGTERM, signal.SIGINT):
            previous[signum] = signal.signal(signum, _signals.handler)
    with warnings.catch_warnings():  # restores warnings.showwarning afterwards
        if not verbose:
            warnings.showwarning = _one_line_warning
        try:
            return handlers[args.command](args)
        except KeyboardInterrupt:
            print("vtkvol: interrupted", file=sys.stderr)
            return 130
        except Terminated as exc:
            how = "interrupted" if exc.signum == signal.SIGINT else "terminated"
            print(f"vtkvol: {how}; unfinished output removed", file=sys.stderr)
            return 128 + exc.signum
        except (ValueError, OSError) as exc:  # VolumeReadError and SessionError are ValueErrors
            print(f"vtkvol: {exc}", file=sys.stderr)
            return 1
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)


if __name__ == "__main__":
    sys.exit(main())
