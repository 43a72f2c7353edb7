"""Pre-integrated classification against post-classification (issue 23): image error against
sample distance, with and without pre-integration, and the frame time, side by side in one run.
For docs/benchmarks.md ("Pre-integrated classification") and docs/rendering.md.

Scenes with sharp transfer functions (per channel a narrow opacity spike, 1 % of the value
range wide, over the channel's own colour ramp):
* ``shell``: a synthetic 48³ radial ramp (values 1000 − 40·r), the spike at 400: a thin shell.
* ``bead``: ``../shared/data/Bead_Image1_crop.tif`` (first channel), the spike at the middle
  of its contrast limits: a thin iso-shell of the bead's blur.
* ``shells2``, ``shells3`` (several channels, independent components, VTK's additive mixing):
  ``shell`` plus one or two more radial ramps about other centres (values 1000 − 40·r and
  1000 − 50·r), spikes at 400 and 600: two or three thin shells that cut through each other.
* ``bead_f32``: ``bead`` as float32 (the same values; a float texture instead of VTK's 8-bit
  one, whose filtered values llvmpipe resolves coarsely: docs/benchmarks.md).
* ``bead2``: ``bead`` plus the same stack shifted by 30 voxels in x as a second channel, the
  second spike at a third of the contrast limits.
Reference: post-classified at a sample distance of 1/16 voxel, from the data as float32 (the
same values): the field the classification integrates. An 8-bit stack's own texture is filtered
coarsely by llvmpipe (about whole data values between two voxels), so a reference rendered
from it is off by ~2.5 levels from that field whatever its step (docs/benchmarks.md, "Why the
bead stack misses the goal"); the images compared are rendered from the stack as it is.
Local shading, no jitter,
parallel projection from the app's opening view; RMSE in 8-bit levels over RGB; frame time:
median of ``--frames`` frames of the settled view (llvmpipe unless a GPU is there).

Run from the checkout: ``python benchmarks/preintegration.py [--size 192] [--frames 5]
[--scenes shell bead shells2 shells3 bead2]``.
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


#: Per channel: the colour ramp's ends (low value, high value).
COLOURS = (((1.0, 0.6, 0.2), (0.2, 0.6, 1.0)), ((0.2, 1.0, 0.3), (0.6, 0.3, 1.0)),
           ((0.3, 0.3, 1.0), (1.0, 0.9, 0.2)))
#: A scene: the volume and, per channel, the spike's (centre, width) in data units.
Scene = tuple[VolumeData, list[tuple[float, float]]]


def shells(channels: int = 1) -> Scene:
    n = 48
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float32)
    ramps = [((23.5, 21.5, 24.5), 40.0, 400.0), ((30.5, 26.5, 20.5), 40.0, 600.0),
             ((17.5, 27.5, 27.5), 50.0, 400.0)][:channels]
    arrays = []
    for (cx, cy, cz), slope, _ in ramps:
        r = np.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2)
        arrays.append((1000.0 - slope * r).astype(np.float32))
    data = VolumeData.from_array(np.stack(arrays), voxel_size_um=(1.0, 1.0, 1.0))
    return data, [(centre, 10.0) for *_, centre in ramps]


def bead(channels: int = 1, dtype: type | None = None) -> Scene | None:
    if not BEAD.exists():
        return None
    from vtkvol.io import read_volume

    data = read_volume(str(BEAD))
    first = data.array[0]
    arrays = [first] + [np.roll(first, 30, axis=2)] * (channels - 1)
    stack = np.stack(arrays)
    data = VolumeData.from_array(stack if dtype is None else stack.astype(dtype),
                                 voxel_size_um=data.voxel_size_um)
    lo, hi = contrast_limits(data, 0)
    spikes = [(0.5 * (lo + hi), 0.01 * (hi - lo)), (lo + (hi - lo) / 3, 0.01 * (hi - lo))]
    return data, spikes[:channels]


def render(data: VolumeData, spikes: list[tuple[float, float]], distance: float, pre: bool,
           size: int, frames: int) -> tuple[np.ndarray, float]:
    model = scene_for(data)
    model.render.jitter = False
    model.render.sample_distance = distance
    model.render.preintegration = pre
    model.camera.parallel_projection = True
    for c, (centre, width) in enumerate(spikes):
        lo, hi = float(np.nanmin(data.array[c])), float(np.nanmax(data.array[c]))
        low, high = COLOURS[c]
        model.channels[c].tf = TransferFunction(
            colors=[(lo, *low), (hi, *high)],
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
    names = ["shell", "bead", "bead_f32", "shells2", "shells3", "bead2"]
    parser.add_argument("--scenes", nargs="+", default=names, choices=names)
    args = parser.parse_args()
    makers = {"shell": lambda: shells(1), "bead": lambda: bead(1),
              "bead_f32": lambda: bead(1, np.float32),
              "shells2": lambda: shells(2), "shells3": lambda: shells(3),
              "bead2": lambda: bead(2)}
    scenes = {name: makers[name]() for name in args.scenes}
    print("| scene | sample distance (voxel) | RMSE post | RMSE pre-integrated | "
          "ms post | ms pre-integrated |")
    print("|---|---|---|---|---|---|")
    for name, scene in scenes.items():
        if scene is None:
            print(f"| {name} | (data not found) | | | | |")
            continue
        data, spikes = scene
        exact = VolumeData.from_array(data.array.astype(np.float32),
                                      voxel_size_um=data.voxel_size_um)
        reference, _ = render(exact, spikes, REFERENCE_DISTANCE, False, args.size, 1)
        for distance in DISTANCES:
            cells = []
            for pre in (False, True):
                image, ms = render(data, spikes, distance, pre, args.size, args.frames)
                cells.append((float(np.sqrt(((image - reference) ** 2).mean())), ms))
            print(f"| {name} | {distance:g} | {cells[0][0]:.2f} | {cells[1][0]:.2f} | "
                  f"{cells[0][1]:.0f} | {cells[1][1]:.0f} |", flush=True)


if __name__ == "__main__":
    main()
