"""Development study of the scalar reconstruction filters (``RenderSettings.interpolation``):
trilinear, Csébfalvi's corrected trilinear (seed 001 eq. 2.55) and the tricubic anchors, on the
Marschner–Lobb signal (f_M = 6, α = 0.25 on [−1, 1]³). For docs/reconstruction.md.

Three tables, printed as markdown:

1. RMSE against the analytic function at 10⁵ seeded random points (numpy filters from
   ``vtkvol.reference.reconstruction``), grid sizes 32, 41, 64; points in the interior
   (every filter's support inside the grid) and in the whole cube (edge clamping included).
2. Image RMSE (8-bit levels, RGB) of GPU renderings of the 41³ sampling against a rendering of
   the 201³ sampling (its trilinear error is ≈ 25× smaller than the 41³ one), shaded and
   unshaded: GPU trilinear, GPU corrected, and the tricubic anchors (the 41³ samples upsampled
   ×5 per axis with Catmull-Rom or the interpolating B-spline in numpy, then rendered
   trilinear: the GPU has no tricubic filter; the residual trilinear error of the fine grid is
   what the ground truth has too), and the same for corrected trilinear (its values with the
   fine grid's normals). All renders share the world-space step and opacity unit.
3. Frame times (ms, median) of trilinear and corrected, shaded and unshaded, measured
   frame by frame alternately in one run, and their ratio.

Run from the checkout: ``python benchmarks/reconstruction.py [--image 512] [--frames 12]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from vtkvol.reference.reconstruction import (
    FILTERS,
    marschner_lobb_rmse,
    phantom_marschner_lobb,
)

Row = dict[str, Any]
#: World-space (on [−1, 1]³) ray step and opacity unit distance shared by every render:
#: a quarter and one voxel of the 41³ grid.
STEP = 0.0125
UNIT = 0.05
#: An isosurface-like transfer function around the usual isovalue 0.5, with a colour ramp so
#: unshaded images show the reconstructed values too.
OPACITY = [(0.0, 0.0), (0.45, 0.0), (0.55, 0.8), (1.0, 0.8)]
COLORS = [(0.4, 0.1, 0.2, 1.0), (0.5, 0.2, 1.0, 0.3), (0.6, 1.0, 0.3, 0.1)]


def point_rmse(sizes: Sequence[int] = (32, 41, 64), count: int = 100_000) -> list[Row]:
    rows = []
    for n in sizes:
        inner = marschner_lobb_rmse(n, count=count, interior=True)
        whole = marschner_lobb_rmse(n, count=count, interior=False)
        rows += [{"n": n, "filter": f, "interior": inner[f], "whole cube": whole[f]}
                 for f in FILTERS]
    return rows


def _upsample_matrix(n: int, m: int, method: str) -> np.ndarray:
    """(m, n) matrix taking n samples to m samples over the same span with a 1-D filter."""
    u = np.linspace(0.0, n - 1.0, m)
    if method == "catmull_rom":
        from vtkvol.reference.reconstruction import _catmull_rom_weights

        i = np.minimum(np.floor(u).astype(int), n - 2)
        weights = _catmull_rom_weights(u - i)
        mat = np.zeros((m, n))
        for d, w in zip((-1, 0, 1, 2), weights, strict=True):
            np.add.at(mat, (np.arange(m), np.clip(i + d, 0, n - 1)), w)
        return mat
    from scipy import ndimage

    eye = np.eye(n)
    return np.stack([ndimage.map_coordinates(eye[k], [u], order=3, mode="nearest")
                     for k in range(n)], axis=1)


def upsample(volume: np.ndarray, m: int, method: str) -> np.ndarray:
    """Filter ``method`` evaluated on an m³ lattice spanning the same box as the n³ ``volume``:
    ``catmull_rom`` and ``bspline`` (tensor products) separably, ``corrected`` point by point
    (it is not a tensor product), in slabs to bound memory."""
    n = volume.shape[0]
    if method == "corrected":
        from vtkvol.reference.reconstruction import reconstruct

        u = np.linspace(0.0, n - 1.0, m)
        y, x = np.meshgrid(u, u, indexing="ij")
        out = np.empty((m, m, m), np.float32)
        for k, z in enumerate(u):
            pts = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], 1)
            out[k] = reconstruct(volume, pts, "corrected").reshape(m, m)
        return out
    mat = _upsample_matrix(n, m, method)
    out = np.tensordot(mat, volume.astype(np.float64), axes=(1, 0))      # z
    out = np.tensordot(mat, out, axes=(1, 1)).transpose(1, 0, 2)          # y
    out = np.tensordot(out, mat, axes=(2, 1))                             # x
    return out.astype(np.float32)


def _scene(volume: np.ndarray, interpolation: str, shade: bool, size: int) -> tuple[Any, ...]:
    """An ML scene (box [−1, 1]³ whatever the grid): (render window, renderer, illuminator)."""
    import vtk

    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import simple_volume_scene

    n = volume.shape[0]
    spacing = 2.0 / (n - 1)
    rw, ren, vol = simple_volume_scene(volume, spacing=(spacing,) * 3, size=(size, size),
                                       opacity=OPACITY, azimuth=20.0, elevation=35.0)
    prop = vol.GetProperty()
    prop.SetScalarOpacityUnitDistance(UNIT)
    ctf = vtk.vtkColorTransferFunction()
    for value, r, g, b in COLORS:
        ctf.AddRGBPoint(value, r, g, b)
    prop.SetColor(ctf)
    prop.SetShade(int(shade))
    vol.GetMapper().SetSampleDistance(STEP)
    il = Illuminator(vol, ren, method="local", keep_local_shading=True)
    il.set_interpolation(interpolation)
    return rw, ren, il


def render(volume: np.ndarray, interpolation: str, shade: bool, size: int = 256) -> np.ndarray:
    """One ML rendering as float RGB (8-bit levels)."""
    from vtkvol.engine.offscreen import grab

    rw, _ren, il = _scene(volume, interpolation, shade, size)
    try:
        grab(rw)  # compile
        image = grab(rw).astype(np.float64)
        if il.last_error:
            raise RuntimeError(il.last_error)
        return image
    finally:
        il.release()
        rw.Finalize()


def _finish(rw: Any) -> None:
    from vtkvol.engine import gl as vgl

    rw.MakeCurrent()
    vgl.gl(rw).glFinish()


def image_rmse(n: int = 41, truth_n: int = 201, size: int = 256) -> list[Row]:
    coarse = phantom_marschner_lobb(n)
    upsampled = {m: upsample(coarse, truth_n, m)
                 for m in ("catmull_rom", "bspline", "corrected")}
    truth_volume = phantom_marschner_lobb(truth_n)
    rows = []
    for shade in (False, True):
        truth = render(truth_volume, "trilinear", shade, size)
        images = {
            "trilinear (GPU)": render(coarse, "trilinear", shade, size),
            "corrected (GPU)": render(coarse, "corrected", shade, size),
            "catmull_rom (numpy ×5, then trilinear)":
                render(upsampled["catmull_rom"], "trilinear", shade, size),
            "bspline (numpy ×5, then trilinear)":
                render(upsampled["bspline"], "trilinear", shade, size),
            # Corrected values with the fine grid's normals: separates the value from the
            # gradient (the GPU's corrected mode keeps the coarse central-difference normal).
            "corrected (numpy ×5, then trilinear)":
                render(upsampled["corrected"], "trilinear", shade, size),
        }
        for name, image in images.items():
            rmse = float(np.sqrt(np.mean((image - truth) ** 2)))
            rows.append({"shaded": shade, "filter": name, "image RMSE (8-bit)": rmse})
    return rows


def frame_times(sizes: Sequence[int] = (41, 128), image: int = 512,
                frames: int = 12) -> list[Row]:
    """Median frame times (ms). Both filters' scenes exist side by side and their frames
    alternate (trilinear, corrected, trilinear, …), so load changes on the shared machine hit
    both alike. Each frame follows a small camera move; ``glFinish`` ends it."""
    rows = []
    for n in sizes:
        volume = phantom_marschner_lobb(n)
        for shade in (False, True):
            scenes = {f: _scene(volume, f, shade, image) for f in ("trilinear", "corrected")}
            times: dict[str, list[float]] = {f: [] for f in scenes}
            try:
                for rw, _ren, _il in scenes.values():
                    rw.Render()  # compile
                    rw.Render()
                for _ in range(frames):
                    for f, (rw, ren, _il) in scenes.items():
                        ren.GetActiveCamera().Azimuth(0.5)
                        t0 = time.perf_counter()
                        rw.Render()
                        _finish(rw)
                        times[f].append((time.perf_counter() - t0) * 1e3)
                for _rw, _ren, il in scenes.values():
                    if il.last_error:
                        raise RuntimeError(il.last_error)
            finally:
                for rw, _ren, il in scenes.values():
                    il.release()
                    rw.Finalize()
            tri = statistics.median(times["trilinear"])
            cor = statistics.median(times["corrected"])
            rows.append({"volume": f"{n}³", "shaded": shade, "trilinear ms": tri,
                         "corrected ms": cor, "ratio": f"{cor / tri:.2f}"})
    return rows


def _markdown(rows: list[Row]) -> str:
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        cells = [f"{v:.4f}" if isinstance(v, float) and v < 1 else
                 f"{v:.1f}" if isinstance(v, float) else str(v) for v in row.values()]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--image", type=int, default=512, help="timing image size (pixels)")
    parser.add_argument("--frames", type=int, default=12, help="timed frames per filter")
    parser.add_argument("--skip-timing", action="store_true")
    args = parser.parse_args(argv)
    print("## RMSE at 10⁵ random points (analytic Marschner–Lobb)\n")
    print(_markdown(point_rmse()))
    print("\n## Image RMSE, 41³ against the 201³ sampling (256², 8-bit levels)\n")
    print(_markdown(image_rmse()))
    if not args.skip_timing:
        print(f"\n## Frame times ({args.image}², median, interleaved)\n")
        print(_markdown(frame_times(image=args.image, frames=args.frames)))


if __name__ == "__main__":
    main()
