"""Development study of multi-channel frame cost (not part of the installed library): the frame
time of two channels beside one channel of the same size, with VTK's own per-component loop
("before"), the host's multi-channel sample (``host_multichannel.glsl``, "after", lit per
channel) and shared lighting (``RenderSettings.multichannel_lighting = "shared"``,
``host_multichannel_lighting.glsl``), in one run, per illumination method (and "unshaded",
local shading switched off, to separate classification from lighting); and the image
differences: host's sample vs VTK's loop, shared vs per-channel lighting.

Run from the checkout: ``python benchmarks/multichannel_timing.py [N] [IMAGE] [methods]``
(default 128³ data, a 256² image, local shading, shadow volume, cone tracing, translucency,
unshaded)
prints a markdown table. Data: the built-in confocal phantom (uint16 nuclei and membranes,
0.5 µm voxels); one channel = its nuclei channel alone. Each frame time is the median of
``FRAMES`` full-quality frames after two warm-up frames (render + read-back); the four views
of a method are open together and their frames interleaved, so a change of machine load
during the run affects them alike.
"""

from __future__ import annotations

import contextlib
import statistics
import sys
import time
from typing import Any

import numpy as np

FRAMES = 5
#: The configurations of one method, in the order their frames are interleaved.
CONFIGS = ("one", "before", "after", "shared")


def _timed_frames(views: dict[str, Any]) -> dict[str, tuple[float, np.ndarray]]:
    """Median frame time (ms) and last image of every open view, their frames interleaved
    (A, B, C, D, A, B, …) so that a change of machine load during the run hits all alike."""
    from vtkvol.engine.offscreen import grab

    for rw in views.values():
        grab(rw)
        grab(rw)
    times: dict[str, list[float]] = {name: [] for name in views}
    last: dict[str, np.ndarray] = {}
    for _ in range(FRAMES):
        for name, rw in views.items():
            t0 = time.perf_counter()
            last[name] = grab(rw)
            times[name].append((time.perf_counter() - t0) * 1e3)
    return {name: (statistics.median(times[name]), last[name]) for name in views}


def _open_view(stack: contextlib.ExitStack, data: Any, method: str, image: int, *,
               vtk_loop: bool = False, lighting: str = "per_channel") -> Any:
    """A render window showing ``data`` under ``method`` (``"unshaded"``: local shading
    switched off, so nothing is lit), closed with ``stack``."""
    from vtkvol.engine.api import offscreen_view
    from vtkvol.model.defaults import scene_for

    model = scene_for(data)
    model.render.multichannel_lighting = lighting
    if method == "unshaded":
        model.render.shade = False
        method = "local"
    rw, scene, _ = stack.enter_context(
        offscreen_view(data, model=model, size=(image, image), method=method))
    assert scene.illuminator is not None
    scene.illuminator.multichannel_sample = not vtk_loop
    return rw


def difference(image: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Largest 8-bit level difference, PSNR (dB) and SSIM of two RGB(A) frames."""
    from vtkvol.reference import image_metrics

    metrics = image_metrics(image[..., :3], reference[..., :3])
    return {"max": int(metrics["max_abs"]), "psnr": metrics["psnr"], "ssim": metrics["ssim"]}


def study(n: int = 128, image: int = 256,
          methods: tuple[str, ...] = ("local", "shadow_volume", "cone_traced", "translucency",
                                      "unshaded"),
          ) -> list[dict[str, Any]]:
    from vtkvol.io import VolumeData, confocal_phantom

    two = confocal_phantom((n, n, n), voxel_size_um=(0.5, 0.5, 0.5))
    one = VolumeData.from_array(np.ascontiguousarray(two.array[:1]), two.voxel_size_um,
                                ["nuclei"])
    rows = []
    for method in methods:
        with contextlib.ExitStack() as stack:
            views = {
                "one": _open_view(stack, one, method, image),
                "before": _open_view(stack, two, method, image, vtk_loop=True),
                "after": _open_view(stack, two, method, image),
                "shared": _open_view(stack, two, method, image, lighting="shared"),
            }
            measured = _timed_frames(views)
        (t_one, _), (t_before, before), (t_after, after), (t_shared, shared) = (
            measured[name] for name in CONFIGS)
        rows.append({"method": method, "size": f"{n}³", "image": f"{image}²",
                     "one_ms": t_one, "before_ms": t_before, "after_ms": t_after,
                     "shared_ms": t_shared, "after_vs_before": difference(after, before),
                     "shared_vs_after": difference(shared, after)})
        print(_row(rows[-1]), flush=True)
    return rows


def _difference_text(d: dict[str, float]) -> str:
    if d["psnr"] == float("inf"):
        return "identical"
    return f"{d['max']} levels, {d['psnr']:.1f} dB, SSIM {d['ssim']:.4f}"


def _row(r: dict[str, Any]) -> str:
    return (f"| {r['method']} | {r['size']}, {r['image']} | {r['one_ms']:.0f} | "
            f"{r['before_ms']:.0f} ({r['before_ms'] / r['one_ms']:.2f}×) | "
            f"{r['after_ms']:.0f} ({r['after_ms'] / r['one_ms']:.2f}×) | "
            f"{r['shared_ms']:.0f} ({r['shared_ms'] / r['one_ms']:.2f}×) | "
            f"{_difference_text(r['after_vs_before'])} | "
            f"{_difference_text(r['shared_vs_after'])} |")


if __name__ == "__main__":
    args = sys.argv[1:]
    size = int(args[0]) if args else 128
    image = int(args[1]) if len(args) > 1 else 256
    chosen = tuple(args[2].split(",")) if len(args) > 2 else (
        "local", "shadow_volume", "cone_traced", "translucency", "unshaded")
    print("| method | data, image | 1 channel (ms) | 2 channels, VTK's loop (ms) | "
          "2 channels, host's sample, per-channel lighting (ms) | "
          "2 channels, shared lighting (ms) | host's sample vs VTK's loop | "
          "shared vs per-channel (max 8-bit, PSNR, SSIM) |")
    print("|---|---|---|---|---|---|---|---|")
    study(size, image, chosen)
