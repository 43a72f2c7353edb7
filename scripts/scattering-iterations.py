"""Iterations per second of the multiple-scattering techniques (docs/multiple-scattering.md).

Measured as the extra time of frames that iterate over frames that do not (the technique has
converged), on a 64³ volume with 1 and 3 lights, for the GPU (compute) and numpy paths.
Run: ``python scripts/scattering-iterations.py`` (prints a markdown table).
"""

from __future__ import annotations

import time

import numpy as np

from vtkvol.engine.gl import gl
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model.scene import Light

SIZE = 64
FRAMES = 3
DIRECTIONS = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 1.0))


def seconds_per_frame(rw) -> float:
    gl(rw).glFinish()
    t0 = time.perf_counter()
    for _ in range(FRAMES):
        grab(rw)
    gl(rw).glFinish()
    return (time.perf_counter() - t0) / FRAMES


def measure(method: str, lights: int, backend: str) -> float:
    arr = np.zeros((SIZE,) * 3, np.float32)
    arr[SIZE // 4 : 3 * SIZE // 4, SIZE // 4 : 3 * SIZE // 4, SIZE // 4 : 3 * SIZE // 4] = 1.0
    rw, ren, volume = simple_volume_scene(arr, size=(64, 64), opacity=[(0.0, 0.0), (1.0, 0.3)])
    per_frame = 2 if (method, backend) == ("hybrid_diffusion", "cpu") else 8
    il = Illuminator(volume, ren, method=method,
                     lights=[Light(direction=d) for d in DIRECTIONS[:lights]],
                     parameters={"backend": backend, "iterations_per_frame": per_frame,
                                 "max_iterations": 10000})
    try:
        grab(rw)
        busy = seconds_per_frame(rw)
        il.set_parameters(max_iterations=il.technique.iteration)  # converged: rendering only
        grab(rw)
        idle = seconds_per_frame(rw)
        return per_frame / max(busy - idle, 1e-6)
    finally:
        il.release()
        rw.Finalize()


def main() -> None:
    print("| method | lights | GPU path | numpy path |\n|---|---|---|---|")
    for method in ("convection_diffusion", "hybrid_diffusion"):
        for lights in (1, 3):
            gpu, cpu = (measure(method, lights, b) for b in ("auto", "cpu"))
            print(f"| {method} | {lights} | {gpu:.1f} | {cpu:.1f} |")


if __name__ == "__main__":
    main()
