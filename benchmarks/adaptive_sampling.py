"""Adaptive sampling against fixed steps (issue 23): frame time against image error, side by
side in one run. For docs/benchmarks.md ("Adaptive sampling") and docs/rendering.md.

Scenes: ``halo`` (a synthetic 64³ radial ramp: a faint halo with a slow opacity ramp, then a
sharp step into a dense core) and ``bead`` (``../shared/data/Bead_Image1_crop.tif``, its
default transfer function). Both at the default sample distance 0.5 voxel and at 1.0.
Reference: fixed steps at 1/8 voxel. Local shading, parallel projection, no jitter; RMSE in
8-bit levels over RGB; frame time: median of ``--frames`` frames of the settled view.

Run from the checkout: ``python benchmarks/adaptive_sampling.py [--size 128] [--frames 5]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from vtkvol.engine.api import offscreen_view, settled_frame
from vtkvol.io.volume_data import VolumeData
from vtkvol.model import TransferFunction
from vtkvol.model.defaults import scene_for

BEAD = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "Bead_Image1_crop.tif"


def halo() -> tuple[VolumeData, TransferFunction | None]:
    n = 64
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float32)
    r = np.sqrt((x - 31.5) ** 2 + (y - 30.5) ** 2 + (z - 32.5) ** 2)
    data = VolumeData.from_array((1000.0 - 25.0 * r).astype(np.float32),
                                 voxel_size_um=(1.0, 1.0, 1.0))
    return data, TransferFunction(
        colors=[(-700.0, 1.0, 0.6, 0.2), (1000.0, 0.2, 0.6, 1.0)],
        opacity=[(-700.0, 0.0), (300.0, 0.01), (600.0, 0.02), (610.0, 0.8), (1000.0, 0.8)])


def bead() -> tuple[VolumeData, TransferFunction | None] | None:
    if not BEAD.exists():
        return None
    from vtkvol.io import read_volume

    return read_volume(str(BEAD)), None


def render(data: VolumeData, tf: TransferFunction | None, distance: float, adaptive: bool,
           size: int, frames: int) -> tuple[np.ndarray, float, float]:
    model = scene_for(data)
    model.render.jitter = False
    model.render.sample_distance = distance
    model.render.adaptive_sampling = adaptive
    model.camera.parallel_projection = True
    if tf is not None:
        model.channels[0].tf = tf
    with offscreen_view(data, model=model, size=(size, size), method="local") as (rw, scene, _):
        settled_frame(rw, scene, max_seconds=None, iterations=None)
        image, _s = settled_frame(rw, scene, max_seconds=None, iterations=None)
        times = []
        for _ in range(frames):
            t0 = time.perf_counter()
            rw.Render()
            times.append((time.perf_counter() - t0) * 1e3)
        stats = scene.illuminator.adaptive_sampling.stats
        assert stats["active"] == adaptive, stats
        coarse = float(stats.get("coarse_fraction", 0.0))
    return image.astype(np.float64), statistics.median(times), coarse


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()
    print("| scene | sample distance (voxel) | coarse bricks | ms fixed | ms adaptive | "
          "RMSE fixed | RMSE adaptive | RMSE adaptive vs fixed | max adaptive vs fixed |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, scene in {"halo": halo(), "bead": bead()}.items():
        if scene is None:
            print(f"| {name} | (data not found) | | | | | | | |")
            continue
        data, tf = scene
        reference, _ms, _c = render(data, tf, 0.125, False, args.size, 1)
        for distance in (0.5, 1.0):
            fixed, fixed_ms, _c = render(data, tf, distance, False, args.size, args.frames)
            adaptive, adaptive_ms, coarse = render(data, tf, distance, True, args.size,
                                                   args.frames)

            def rmse(a: np.ndarray, b: np.ndarray) -> float:
                return float(np.sqrt(((a - b) ** 2).mean()))

            print(f"| {name} | {distance:g} | {100 * coarse:.0f} % | {fixed_ms:.0f} | "
                  f"{adaptive_ms:.0f} | {rmse(fixed, reference):.2f} | "
                  f"{rmse(adaptive, reference):.2f} | {rmse(adaptive, fixed):.2f} | "
                  f"{np.abs(adaptive - fixed).max():.0f} |", flush=True)


if __name__ == "__main__":
    main()
