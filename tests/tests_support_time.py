"""A small time-lapse for the time-series tests (and the README's way to make one)."""

from __future__ import annotations

import numpy as np
import tifffile

N_TIME = 20
SHAPE_ZYX = (12, 32, 32)


def write_time_lapse(path, n_time: int = N_TIME, *, interval_s: float = 30.0) -> None:
    """An ImageJ TZYX uint16 stack: a bright ball that moves along x, one voxel per time
    point, over a dim noisy background; frames ``interval_s`` seconds apart."""
    rng = np.random.default_rng(1)
    z, y, x = np.mgrid[0:SHAPE_ZYX[0], 0:SHAPE_ZYX[1], 0:SHAPE_ZYX[2]].astype(np.float32)
    stack = np.empty((n_time, *SHAPE_ZYX), np.uint16)
    for t in range(n_time):
        cx = 6.0 + t * 1.0
        ball = np.exp(-(((x - cx) / 4.0) ** 2 + ((y - 16) / 4.0) ** 2 + ((z - 6) / 2.5) ** 2))
        stack[t] = (100 + 3000 * ball + rng.normal(0, 10, SHAPE_ZYX)).clip(0).astype(np.uint16)
    tifffile.imwrite(path, stack, imagej=True,
                     metadata={"axes": "TZYX", "finterval": interval_s, "tunit": "sec"})
