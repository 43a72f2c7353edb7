"""Time of one slice of the slice views (vtkvol.engine.slices.slice_rgba) on a 512×512×200
two-channel uint16 stack, per plane: what a cursor move or a wheel step costs before the
views repaint. Run: ``python benchmarks/slice_views_timing.py`` (about 0.3 GiB of memory)."""

from __future__ import annotations

import time

import numpy as np

from vtkvol.engine.slices import PLANES, slice_rgba
from vtkvol.io import VolumeData
from vtkvol.model.defaults import scene_for


def main() -> None:
    rng = np.random.default_rng(0)
    array = rng.integers(0, 4096, size=(2, 200, 512, 512), dtype=np.uint16)
    data = VolumeData.from_array(array, (0.2, 0.2, 0.5), ["a", "b"])
    model = scene_for(data)
    for name, plane in PLANES.items():
        index = (256, 256, 100)[plane.normal]
        slice_rgba(data, model, plane, index)  # warm up
        times = []
        for _ in range(5):
            start = time.perf_counter()
            slice_rgba(data, model, plane, index)
            times.append(time.perf_counter() - start)
        times.sort()
        print(f"{name}: {1e3 * times[0]:.1f} ms (best of 5), median {1e3 * times[2]:.1f} ms")


if __name__ == "__main__":
    main()
