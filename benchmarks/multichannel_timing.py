"""Development study of multi-channel frame cost (not part of the installed library): the frame
time of two channels beside one channel of the same size, with VTK's own per-component loop
("before") and the host's multi-channel sample (``host_multichannel.glsl``, "after"), in one
run, per illumination method; and the image difference between the two two-channel paths.

Run from the checkout: ``python benchmarks/multichannel_timing.py [N] [IMAGE] [methods]``
(default 128³ data, a 256² image, local shading, shadow volume, cone tracing, translucency)
prints a markdown table. Data: the built-in confocal phantom (uint16 nuclei and membranes,
0.5 µm voxels); one channel = its nuclei channel alone. Each frame time is the median of
``FRAMES`` full-quality frames after two warm-up frames (render + read-back), the three
configurations interleaved so machine load affects them alike.
"""

from __future__ import annotations

import statistics
import sys
import time
from typing import Any

import numpy as np

FRAMES = 3


def _frames(data: Any, method: str, image: int, *, vtk_loop: bool) -> tuple[float, np.ndarray]:
    """Median frame time (ms) and the last image of ``data`` under ``method``."""
    from vtkvol.engine.api import offscreen_view
    from vtkvol.engine.offscreen import grab

    with offscreen_view(data, size=(image, image), method=method) as (rw, scene, _):
        assert scene.illuminator is not None
        scene.illuminator.multichannel_sample = not vtk_loop
        grab(rw)
        grab(rw)
        times = []
        for _ in range(FRAMES):
            t0 = time.perf_counter()
            last = grab(rw)
            times.append((time.perf_counter() - t0) * 1e3)
        return statistics.median(times), last


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def study(n: int = 128, image: int = 256,
          methods: tuple[str, ...] = ("local", "shadow_volume", "cone_traced", "translucency"),
          ) -> list[dict[str, Any]]:
    from vtkvol.io import VolumeData, confocal_phantom

    two = confocal_phantom((n, n, n), voxel_size_um=(0.5, 0.5, 0.5))
    one = VolumeData.from_array(np.ascontiguousarray(two.array[:1]), two.voxel_size_um,
                                ["nuclei"])
    rows = []
    for method in methods:
        t_one, _ = _frames(one, method, image, vtk_loop=False)
        t_before, before = _frames(two, method, image, vtk_loop=True)
        t_after, after = _frames(two, method, image, vtk_loop=False)
        t_one_again, _ = _frames(one, method, image, vtk_loop=False)
        t_one = min(t_one, t_one_again)
        diff = np.abs(before.astype(int) - after.astype(int))
        rows.append({"method": method, "size": f"{n}³", "image": f"{image}²",
                     "one_ms": t_one, "before_ms": t_before, "after_ms": t_after,
                     "max_diff": int(diff.max()), "psnr": psnr(before, after)})
        print(_row(rows[-1]), flush=True)
    return rows


def _row(r: dict[str, Any]) -> str:
    psnr_text = "identical" if r["psnr"] == float("inf") else f"{r['psnr']:.1f} dB"
    return (f"| {r['method']} | {r['size']}, {r['image']} | {r['one_ms']:.0f} | "
            f"{r['before_ms']:.0f} ({r['before_ms'] / r['one_ms']:.2f}×) | "
            f"{r['after_ms']:.0f} ({r['after_ms'] / r['one_ms']:.2f}×) | "
            f"{r['max_diff']} levels, {psnr_text} |")


if __name__ == "__main__":
    args = sys.argv[1:]
    size = int(args[0]) if args else 128
    image = int(args[1]) if len(args) > 1 else 256
    chosen = tuple(args[2].split(",")) if len(args) > 2 else (
        "local", "shadow_volume", "cone_traced", "translucency")
    print("| method | data, image | 1 channel (ms) | 2 channels, VTK's loop (ms) | "
          "2 channels, host's sample (ms) | after vs before (max 8-bit, PSNR) |")
    print("|---|---|---|---|---|---|")
    study(size, image, chosen)
