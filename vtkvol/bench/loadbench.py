"""Load-time benchmark: how long :func:`~vtkvol.io.read_volume` takes on a typical stack.

``time_load(tmpdir)`` writes a 512 × 512 × 128, 2-channel uint16 ImageJ hyperstack (what Fiji
saves for a confocal stack, 128 MiB) and reports the median of three full
``read_volume`` calls (open, memory-map, rearrange to ``[c, z, y, x]``, range scan, fit
check). The target recorded in docs/benchmarks.md is ≤ 1 s.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import tifffile

from vtkvol.io.read import read_volume

__all__ = ["time_load", "write_benchmark_stack"]


def write_benchmark_stack(
    path: str | os.PathLike[str],
    shape_czyx: Sequence[int] = (2, 128, 512, 512),
    *,
    seed: int = 0,
) -> Path:
    """Write an uncompressed ImageJ hyperstack (ZCYX on disk) of 12-bit noise-like data.

    Voxel size 0.2 × 0.2 × 0.5 µm (x, y, z), stored as ImageJ resolution + spacing.
    """
    c, z, y, x = (int(v) for v in shape_czyx)
    rng = np.random.default_rng(seed)
    # Structured (not pure noise) so that range and percentiles have something to find.
    ramp = (np.arange(x, dtype=np.uint16) * (3000 // max(x, 1))).astype(np.uint16)
    data = rng.integers(0, 1000, size=(z, c, y, x), dtype=np.uint16)
    data += ramp
    path = Path(path)
    tifffile.imwrite(
        path,
        data,
        imagej=True,
        resolution=(1 / 0.2, 1 / 0.2),
        metadata={"axes": "ZCYX", "spacing": 0.5, "unit": "um"},
    )
    return path


def time_load(
    tmpdir: str | os.PathLike[str],
    *,
    shape_czyx: Sequence[int] = (2, 128, 512, 512),
    repeats: int = 3,
) -> dict[str, Any]:
    """Write the benchmark stack into ``tmpdir`` and time ``read_volume`` on it.

    Returns
    -------
    dict
        ``median_s`` (the number to report), ``runs_s``, ``write_s``, ``shape_czyx``,
        ``file_bytes``, ``dtype``, ``memory_mapped``, ``voxel_size_um`` and ``path``.
    """
    tmp = Path(tmpdir)
    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / "loadbench_{}x{}x{}x{}.tif".format(*shape_czyx)
    start = time.perf_counter()
    write_benchmark_stack(path, shape_czyx)
    write_s = time.perf_counter() - start
    runs: list[float] = []
    data = None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        data = read_volume(path)
        runs.append(time.perf_counter() - start)
        assert data.array.shape == tuple(shape_czyx), data.array.shape
    assert data is not None
    return {
        "median_s": statistics.median(runs),
        "runs_s": runs,
        "write_s": write_s,
        "shape_czyx": tuple(int(v) for v in data.array.shape),
        "dtype": str(data.array.dtype),
        "file_bytes": path.stat().st_size,
        "memory_mapped": bool(data.metadata.get("memory_mapped")),
        "voxel_size_um": tuple(data.voxel_size_um),
        "path": str(path),
    }


if __name__ == "__main__":  # python -m vtkvol.bench.loadbench [tmpdir]
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as default_tmp:
        result = time_load(sys.argv[1] if len(sys.argv) > 1 else default_tmp)
    for key, value in result.items():
        print(f"{key}: {value}")
