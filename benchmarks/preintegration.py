"""Pre-integrated classification against post-classification (issue 23): image error against
sample distance, with and without pre-integration, and the frame time, side by side in one run.
For docs/benchmarks.md ("Pre-integrated classification") and docs/rendering.md.

Scenes with sharp transfer functions (a narrow opacity spike, 1 % of the value range wide):
* ``shell``: a synthetic 48³ radial ramp (values 1000 − 40·r), the spike at 400: a thin shell.
* ``bead``: ``../shared/data/Bead_Image1_crop.tif`` (first channel), the spike at the middle
  of its contrast limits: a thin iso-shell of the bead's blur.
Reference: post-classified at a sample distance of 1/16 voxel. Local shading, no jitter,
parallel projection from the app's opening view; RMSE in 8-bit levels over RGB; frame time:
median of ``--frames`` frames of the settled view (llvmpipe unless a GPU is there).

Run from the checkout: ``python benchmarks/preintegration.py [--size 192] [--frames 5]``.
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
from vtkvol.model.defaults import contrast_limits, scene_for

DISTANCES = (0.25, 0.5, 1.0, 2.0)  # voxels
REFERENCE_DISTANCE = 0.0625
BEAD = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "Bead_Image1_crop.tif"


def shell() -> tuple[VolumeData, float, float]:
    n = 48
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float32)
    r = np.sqrt((x - 23.5) ** 2 + (y - 21.5) ** 2 + (z - 24.5) ** 2)
    return (VolumeData.from_array((1000.0 - 40.0 * r).astype(np.float32),
                                  voxel_size_um=(1.0, 1.0, 1.0)), 400.0, 10.0)


def bead() -> tuple[VolumeData, float, float] | None:
    if not BEAD.exists():
        return None
    from vtkvol.io import read_volume

    data = read_volume(str(BEAD))
    if data.array.shape[0] > 1:
        data = VolumeData.from_array(data.array[0], voxel_size_um=data.voxel_size_um)
    lo, hi = contrast_limits(data, 0)
    return data, 0.5 * (lo + hi), 0.01 * (hi - lo)


def render(data: VolumeData, centre: float, width: float, distance: float, pre: bool,
           size: int, frames: int) -> tuple[np.ndarray, float]:
    model = scene_for(data)
    model.render.jitter = False
    model.render.sample_distance = distance
    model.render.preintegration = pre
    model.camera.parallel_projection = True
    lo, hi = float(np.nanmin(data.array)), float(np.nanmax(data.array))
    model.channels[0].tf = TransferFunction(
        colors=[(lo, 1.0, 0.6, 0.2), (hi, 0.2, 0.6, 1.0)],
        opacity=[(lo, 0.0), (centre - width / 2, 0.0), (centre, 0.9),
                 (centre + width / 2, 0.0), (hi, 0.0)])
    model.illumination.method = "local"
    with offscreen_view(data, model=model, size=(size, size)) as (rw, scene, _):
        image, _s = settled_frame(rw, scene, max_seconds=None, iterations=None)
        times = []
        for _ in range(frames):
            t0 = time.perf_counter()
            rw.Render()
            times.append((time.perf_counter() - t0) * 1e3)
        assert scene.illuminator.preintegration.active == pre
    return image.astype(np.float64), statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=192)
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()
    scenes = {"shell": shell(), "bead": bead()}
    print("| scene | sample distance (voxel) | RMSE post | RMSE pre-integrated | "
          "ms post | ms pre-integrated |")
    print("|---|---|---|---|---|---|")
    for name, scene in scenes.items():
        if scene is None:
            print(f"| {name} | (data not found) | | | | |")
            continue
        data, centre, width = scene
        reference, _ = render(data, centre, width, REFERENCE_DISTANCE, False, args.size, 1)
        for distance in DISTANCES:
            cells = []
            for pre in (False, True):
                image, ms = render(data, centre, width, distance, pre, args.size, args.frames)
                cells.append((float(np.sqrt(((image - reference) ** 2).mean())), ms))
            print(f"| {name} | {distance:g} | {cells[0][0]:.2f} | {cells[1][0]:.2f} | "
                  f"{cells[0][1]:.0f} | {cells[1][1]:.0f} |", flush=True)


if __name__ == "__main__":
    main()
