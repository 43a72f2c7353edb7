"""Development study of the translucency technique (not part of the installed library):
light-volume recompute times beside the shadow volume's (the same propagation, run four times
per light), and frame times beside local shading and the shadow volume. For
docs/translucency.md; ``vtkvol bench`` measures every technique generically.

Run from the checkout: ``python benchmarks/translucency_timing.py`` prints the tables as
markdown. Scenes and timing helpers are the shadow volume study's
(``benchmarks/shadow_volume_timing.py``): the sphere-over-slab phantom as 8-bit data, 1 µm
voxels, GPU times from timer queries read after a ``glFinish``.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Sequence
from typing import Any

from shadow_volume_timing import LIGHT, _light_moves, _markdown, _recompute_ms, _recomputes, _scene

Row = dict[str, Any]


def recompute_times(sizes: Sequence[int] = (64, 128), *, repeats: int = 5,
                    cpu_max_size: int = 64) -> list[Row]:
    """Median recompute (ms) after a light move and after a transfer-function edit, per method,
    size and path (``full`` resolution, one light)."""
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.model import Light

    rows: list[Row] = []
    for n in sizes:
        rw, ren, volume = _scene(n, 32)
        otf = volume.GetProperty().GetScalarOpacity()
        for method in ("shadow_volume", "translucency"):
            backends = ["auto"] + (["cpu"] if n <= cpu_max_size else [])
            for backend in backends:
                il = Illuminator(volume, ren, method=method, lights=[Light(direction=LIGHT)],
                                 parameters={"backend": backend})
                # GPU path: timer queries; numpy path: the wall time is its whole cost.
                il.profiling = backend == "auto"
                try:
                    rw.Render()
                    tech = il.technique
                    light_ms = _light_moves(il, rw, tech, repeats)
                    tf_ms = []
                    for i in range(max(2, repeats // 2)):
                        otf.AddPoint(128.0, 0.5 + 0.01 * (i % 2))
                        count = _recomputes(tech)
                        rw.Render()
                        if _recomputes(tech) > count:
                            tf_ms.append(_recompute_ms(rw, tech))
                    rows.append({
                        "size": n, "method": method, "backend": tech.stats()["backend"],
                        "light_ms": statistics.median(light_ms),
                        "tf_ms": statistics.median(tf_ms) if tf_ms else math.nan,
                        "texture_mib": tech.stats()["texture_bytes"] / 2**20,
                    })
                finally:
                    il.release()
        rw.Finalize()
    return rows


def frame_times(size: int = 128, image: int = 256, frames: int = 12) -> list[Row]:
    """Median frame time (ms, ``glFinish`` inside) while the camera turns, the three methods
    interleaved frame by frame so that load on a shared machine hits them alike."""
    from vtkvol.engine.gl import gl
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.model import Light

    methods = ("local", "shadow_volume", "translucency")
    scenes = {m: _scene(size, image) for m in methods}
    ils = {m: Illuminator(scenes[m][2], scenes[m][1], method=m,
                          lights=[Light(direction=LIGHT)]) for m in methods}
    samples: dict[str, list[float]] = {m: [] for m in methods}
    try:
        for m in methods:  # compile and precompute outside the timing
            scenes[m][0].Render()
            scenes[m][0].Render()
        for _ in range(frames):
            for m in methods:
                rw, ren, _vol = scenes[m]
                ren.GetActiveCamera().Azimuth(2.0)
                t0 = time.perf_counter()
                rw.Render()
                gl(rw).glFinish()
                samples[m].append((time.perf_counter() - t0) * 1e3)
        for m in methods:
            assert ils[m].method == m, ils[m].last_error
    finally:
        for m in methods:
            ils[m].release()
            scenes[m][0].Finalize()
    local = statistics.median(samples["local"])
    return [{"method": m, "frame_ms": statistics.median(samples[m]),
             "÷ local": statistics.median(samples[m]) / local} for m in methods]


def main() -> None:
    rows = recompute_times()
    print("## Recompute (one light, full resolution)\n")
    print(_markdown(rows, list(rows[0])) + "\n")
    rows = frame_times()
    print("## Frame time (128³, 256² image)\n")
    print(_markdown(rows, list(rows[0])))


if __name__ == "__main__":
    main()
