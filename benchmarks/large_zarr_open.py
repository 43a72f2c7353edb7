"""Acceptance measurement (issue 13): a 2048 × 2048 × 512 uint16 OME-Zarr pyramid opens within
a GPU-memory budget, lazily, with the peak memory stated.

Run from the checkout (not part of the installed library)::

    python benchmarks/large_zarr_open.py [--folder /tmp] [--budget 1GiB] [--budget 2GiB] [--keep]

1. **Generate** (in this process) a 5-level pyramid under ``--folder`` (default the system's
   temporary folder): every level is a lazy dask array whose chunks (64 × 256 × 256) are
   computed from an analytic field — a lattice of bright nuclei on a dim background, plus a
   little noise — at that level's voxel centres, and written chunk by chunk by ome-zarr-py's
   ``write_multiscale`` (NGFF 0.5, zarr's default zstd compression). No level is ever held in
   memory; the peak RSS of this step is printed.
2. **Open** it the way the app does, once per budget, each in a fresh child process so its
   peak RSS is its own: ``read_volume(path, memory_budget_bytes=budget)`` (the level the
   budget chooses, read z-slab by z-slab), ``scene_for`` (statistics and default transfer
   functions), a ``VolumeScene`` that frames the visible content, and the first frame
   rendered offscreen (EGL) and read back. Times per step and ``ru_maxrss`` are printed.
3. Delete the pyramid (unless ``--keep``).

On a machine without a GPU, Mesa's llvmpipe keeps the 3-D texture in the process's own
memory, so the first frame adds a second copy of the level to the RSS; on a GPU it lives in
video memory.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SHAPE_ZYX = (512, 2048, 2048)
VOXEL_XYZ = (0.2, 0.2, 0.4)  # µm
CHUNKS = (1, 64, 256, 256)
LEVELS = 5
NUCLEUS_PITCH_UM = 12.0
NUCLEUS_SIGMA_UM = 2.5


def peak_rss_bytes() -> int:
    """This process's peak resident set size (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _field_block(template: np.ndarray, block_info: dict | None = None, *,
                 scale_xyz: tuple[float, float, float]) -> np.ndarray:
    """One chunk of the analytic field at a level's voxel centres (µm = index · scale);
    ``template`` is the empty chunk it replaces (it gives map_blocks the shape)."""
    info = block_info[None]
    _, (z0, z1), (y0, y1), (x0, x1) = info["array-location"]
    sx, sy, sz = scale_xyz
    z = (np.arange(z0, z1, dtype=np.float32) * sz)[:, None, None]
    y = (np.arange(y0, y1, dtype=np.float32) * sy)[None, :, None]
    x = (np.arange(x0, x1, dtype=np.float32) * sx)[None, None, :]
    half = NUCLEUS_PITCH_UM / 2

    def wrapped(v: np.ndarray) -> np.ndarray:
        return (np.mod(v, NUCLEUS_PITCH_UM) - half) ** 2

    d2 = wrapped(x) + wrapped(y) + wrapped(z)
    value = 120.0 + 2800.0 * np.exp(-d2 / (2 * NUCLEUS_SIGMA_UM ** 2))
    seed = (z0 * 7919 + y0 * 104729 + x0) % (2 ** 32)
    value += np.random.default_rng(seed).normal(0.0, 6.0, size=value.shape).astype(np.float32)
    return np.clip(np.rint(value), 0, 65535).astype(np.uint16)[None]


def generate(path: Path, shape_zyx: tuple[int, int, int] = SHAPE_ZYX) -> dict:
    """Write the pyramid lazily; returns the sizes, time and peak RSS of this step."""
    import dask
    import dask.array as da
    import ome_zarr.format
    import zarr
    from ome_zarr.writer import write_multiscale

    levels, transforms = [], []
    for k in range(LEVELS):
        f = 2 ** k
        shape = (1, max(1, shape_zyx[0] // f), max(1, shape_zyx[1] // f),
                 max(1, shape_zyx[2] // f))
        scale = tuple(v * f for v in VOXEL_XYZ)
        chunks = tuple(min(c, n) for c, n in zip(CHUNKS, shape, strict=True))
        template = da.empty(shape, dtype=np.uint16, chunks=chunks)  # never computed
        levels.append(da.map_blocks(_field_block, template, dtype=np.uint16, scale_xyz=scale))
        transforms.append([{"type": "scale", "scale": [1.0, scale[2], scale[1], scale[0]]}])
    start = time.perf_counter()
    group = zarr.open_group(str(path), mode="w", zarr_format=3)
    with dask.config.set(scheduler="threads", num_workers=2):
        write_multiscale(levels, group, fmt=ome_zarr.format.FormatV05(), axes="czyx",
                         coordinate_transformations=transforms,
                         axes_units={"z": "micrometer", "y": "micrometer", "x": "micrometer"},
                         storage_options={"chunks": CHUNKS}, name="nuclei lattice")
    seconds = time.perf_counter() - start
    stored = sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    raw = sum(math.prod(a.shape) * 2 for a in levels)
    return {"levels_czyx": [list(a.shape) for a in levels], "write_s": seconds,
            "stored_bytes": stored, "raw_bytes": raw, "peak_rss_bytes": peak_rss_bytes()}


def open_like_the_app(path: Path, budget: int) -> dict:
    """Child process: read within ``budget``, build the scene, render the first frame."""
    import vtk

    from vtkvol.engine.offscreen import grab, make_render_window
    from vtkvol.engine.scene import VolumeScene
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for

    rss_start = peak_rss_bytes()
    t0 = time.perf_counter()
    data = read_volume(path, memory_budget_bytes=budget)
    t_read = time.perf_counter() - t0
    rss_read = peak_rss_bytes()
    model = scene_for(data)
    t_model = time.perf_counter() - t0
    rw = make_render_window((512, 512))
    renderer = vtk.vtkRenderer()
    rw.AddRenderer(renderer)
    scene = VolumeScene(renderer, model, data, request_render=lambda: None, framing="visible")
    scene.reset_camera()
    image = grab(rw)
    t_frame = time.perf_counter() - t0
    lit = float((np.abs(image.astype(float) - image[0, 0]).max(axis=-1) > 12).mean())
    renderer_name = ""
    info = rw.ReportCapabilities() if hasattr(rw, "ReportCapabilities") else ""
    for line in str(info).splitlines():
        if "OpenGL renderer string" in line:
            renderer_name = line.split(":", 1)[1].strip()
    scene.close()
    return {"budget_bytes": budget, "level": data.metadata["level"],
            "shape_czyx": list(data.array.shape), "data_bytes": int(data.array.nbytes),
            "read_s": t_read, "scene_model_s": t_model, "first_frame_s": t_frame,
            "peak_rss_before_read_bytes": rss_start,
            "peak_rss_after_read_bytes": rss_read, "peak_rss_bytes": peak_rss_bytes(),
            "foreground_fraction": lit, "renderer": renderer_name, "note": data.notes[0]}


def read_region(path: Path, budget: int) -> dict:
    """Child process: "Refine selection" of the central quarter (x and y halves, all z) at the
    finest level that fits ``budget`` (no rendering)."""
    from vtkvol.io import read_volume
    from vtkvol.io.ome_zarr import open_ome_zarr

    (x0, x1), (y0, y1), (z0, z1) = open_ome_zarr(path).levels[0].extent_um()
    region = ((x0 + (x1 - x0) / 4, x1 - (x1 - x0) / 4), (y0 + (y1 - y0) / 4, y1 - (y1 - y0) / 4),
              (z0, z1))
    rss_start = peak_rss_bytes()
    t0 = time.perf_counter()
    data = read_volume(path, memory_budget_bytes=budget, region_um=region)
    return {"budget_bytes": budget, "level": data.metadata["level"],
            "shape_czyx": list(data.array.shape), "data_bytes": int(data.array.nbytes),
            "read_s": time.perf_counter() - t0, "peak_rss_before_read_bytes": rss_start,
            "peak_rss_bytes": peak_rss_bytes(), "region_um": data.metadata["region_um"]}


def _gib(n: float) -> str:
    return f"{n / 2 ** 30:.2f} GiB"


def _measure_in_child(mode: str, path: Path, budget: str) -> dict | None:
    """Run this script's ``mode`` (``--open`` or ``--region``) in a fresh process, so that its
    peak RSS is that measurement's alone; its last stdout line is the JSON result. None (the
    child's stderr printed) when it failed."""
    out = subprocess.run([sys.executable, __file__, mode, str(path), "--budget", budget],
                         capture_output=True, text=True, check=False)
    if out.returncode != 0:
        print(out.stderr, file=sys.stderr)
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--folder", default=tempfile.gettempdir())
    parser.add_argument("--budget", action="append", default=[],
                        help="GPU-memory budget(s) to open with (default: 1GiB and 2GiB)")
    parser.add_argument("--keep", action="store_true", help="keep the pyramid afterwards")
    parser.add_argument("--open", metavar="PATH", help=argparse.SUPPRESS)  # child process
    parser.add_argument("--region", metavar="PATH", help=argparse.SUPPRESS)  # child process
    parser.add_argument("--shape", nargs=3, type=int, default=SHAPE_ZYX, metavar=("Z", "Y", "X"),
                        help="a smaller pyramid to try the script (default 512 2048 2048)")
    args = parser.parse_args(argv)
    from vtkvol.io.pyramid import parse_bytes

    if args.open:
        print(json.dumps(open_like_the_app(Path(args.open), parse_bytes(args.budget[0]))))
        return 0
    if args.region:
        print(json.dumps(read_region(Path(args.region), parse_bytes(args.budget[0]))))
        return 0
    budgets = args.budget or ["1GiB", "2GiB", "256MiB"]
    path = Path(args.folder) / f"vtkvol_large_{int(time.time())}.ome.zarr"
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else "?"
    print(f"machine: {platform.node()}, {platform.machine()}, python "
          f"{platform.python_version()}, load average {' '.join(load)}")
    shape = tuple(args.shape)
    print(f"generating {shape[2]}×{shape[1]}×{shape[0]} uint16 in {path} …", flush=True)
    try:
        made = generate(path, shape)
        print(f"  {LEVELS} levels {made['levels_czyx']}, {_gib(made['raw_bytes'])} of voxels "
              f"stored in {_gib(made['stored_bytes'])}, written in {made['write_s']:.0f} s, "
              f"peak RSS {_gib(made['peak_rss_bytes'])}", flush=True)
        for budget in budgets:
            r = _measure_in_child("--open", path, budget)
            if r is None:
                return 1
            _, z, y, x = r["shape_czyx"]
            print(f"budget {budget}: level {r['level']} ({x}×{y}×{z}, {_gib(r['data_bytes'])}); "
                  f"read {r['read_s']:.1f} s, scene {r['scene_model_s']:.1f} s, first frame "
                  f"{r['first_frame_s']:.1f} s; peak RSS before the read "
                  f"{_gib(r['peak_rss_before_read_bytes'])}, after the read "
                  f"{_gib(r['peak_rss_after_read_bytes'])}, after the first frame "
                  f"{_gib(r['peak_rss_bytes'])}; {r['foreground_fraction']:.0%} of the frame lit;"
                  f" {r['renderer']}", flush=True)
        for budget in budgets[:1]:
            r = _measure_in_child("--region", path, budget)
            if r is None:
                return 1
            _, z, y, x = r["shape_czyx"]
            print(f"refine the central quarter, budget {budget}: level {r['level']} "
                  f"({x}×{y}×{z}, {_gib(r['data_bytes'])}) read in {r['read_s']:.1f} s; peak "
                  f"RSS before {_gib(r['peak_rss_before_read_bytes'])}, after "
                  f"{_gib(r['peak_rss_bytes'])}", flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(path, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
