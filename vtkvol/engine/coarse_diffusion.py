"""The source model's scattered light on a reduced-resolution grid (issue 24): ½ or ¼ of the
data grid per axis, numpy.

Restriction (fine → coarse, blocks of ``factor``³ voxels, partial blocks at the far faces
averaged over the voxels they hold):

* σ_t: the block's mean extinction, then the coarse cell's optical properties from it
  (:func:`~vtkvol.engine.diffusion.source_coefficients` on the coarse grid: D = 1/(3σ_tr) limited
  by the coarse edge, σ_a, σ_s). The mean σ_t keeps the block's mean optical depth along an
  axis; averaging D instead would weight thin voxels too much (D ∝ 1/σ).
* q (the single-scattering source, per µm³): the block's mean, so the source power
  q × volume is conserved.

Prolongation (coarse → fine): trilinear interpolation of φ at the fine voxel centres, clamped
at the coarse grid's outer centres — what a GL texture of the same extent sampled with
normalized coordinates, linear filtering and clamp-to-edge returns (exact when each axis is a
multiple of ``factor``).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from vtkvol.engine.diffusion import DEFAULT_TOLERANCE, Grid, solve_source, source_coefficients

Resolution = Literal["full", "half", "quarter"]
#: Coarsening factor per axis of each ``scattered_resolution`` choice.
FACTORS: dict[str, int] = {"full": 1, "half": 2, "quarter": 4}


def coarse_grid(grid: Grid, factor: int) -> Grid:
    """The grid of ``factor``-voxel blocks: ⌈n/f⌉ cells per axis of ``f × spacing`` µm, the
    first centre at the centre of the first block (dataset space, µm)."""
    nz, ny, nx = grid.shape_zyx
    shape = (math.ceil(nz / factor), math.ceil(ny / factor), math.ceil(nx / factor))
    spacing = tuple(s * factor for s in grid.spacing)
    origin = tuple(o + 0.5 * (factor - 1) * s for o, s in zip(grid.origin, grid.spacing,
                                                                strict=True))
    return Grid(shape, spacing, origin)  # type: ignore[arg-type]


def restrict(a: np.ndarray, factor: int) -> np.ndarray:
    """Block means of ``a`` (``[z, y, x]`` or ``[z, y, x, c]``) over ``factor``³ voxels;
    a partial block at a far face is the mean of the voxels it holds. float32."""
    if factor == 1:
        return a.astype(np.float32)
    spatial = a.shape[:3]
    padded_shape = [math.ceil(n / factor) * factor for n in spatial]
    pad = [(0, p - n) for p, n in zip(padded_shape, spatial, strict=True)]
    pad += [(0, 0)] * (a.ndim - 3)
    total = np.pad(a.astype(np.float64), pad)
    count = np.pad(np.ones(spatial, np.float64), pad[:3])
    blocks = [padded_shape[0] // factor, factor, padded_shape[1] // factor, factor,
              padded_shape[2] // factor, factor]
    sums = total.reshape(*blocks, *a.shape[3:]).sum(axis=(1, 3, 5))
    counts = count.reshape(blocks).sum(axis=(1, 3, 5))
    if a.ndim == 4:
        counts = counts[..., None]
    return (sums / counts).astype(np.float32)


def prolong(coarse: np.ndarray, shape_zyx: tuple[int, int, int], factor: int) -> np.ndarray:
    """Trilinear interpolation of ``coarse`` (``[z, y, x]`` or ``[z, y, x, c]``) at the centres
    of the ``shape_zyx`` fine voxels: fine index i sits at coarse index (i + ½)/f − ½, clamped
    to the outer coarse centres. float32."""
    if factor == 1:
        return coarse.astype(np.float32)
    out = coarse.astype(np.float64)
    for axis in range(3):
        n_coarse = coarse.shape[axis]
        pos = np.clip((np.arange(shape_zyx[axis]) + 0.5) / factor - 0.5, 0.0, n_coarse - 1)
        lo = np.floor(pos).astype(int)
        hi = np.minimum(lo + 1, n_coarse - 1)
        w = (pos - lo).reshape([-1 if k == axis else 1 for k in range(out.ndim)])
        out = np.take(out, lo, axis=axis) * (1.0 - w) + np.take(out, hi, axis=axis) * w
    return out.astype(np.float32)


def solve_source_coarse(q: np.ndarray, sigma_t: np.ndarray, grid: Grid, albedo: float,
                        factor: int, *, phase_g: float = 0.0,
                        tolerance: float = DEFAULT_TOLERANCE) -> tuple[np.ndarray, np.ndarray]:
    """The source model solved on the ``factor``-coarse grid (``q`` ``[z, y, x, 3]`` per µm³,
    ``sigma_t`` ``[z, y, x]`` per µm on ``grid``): (φ prolonged to the fine voxels, the coarse
    φ — what a scattered texture of the coarse size holds)."""
    cgrid = coarse_grid(grid, factor)
    coefficients = source_coefficients(restrict(sigma_t, factor), cgrid, albedo, phase_g)
    phi_c, _ = solve_source(restrict(q, factor), coefficients, cgrid, tolerance=tolerance)
    return prolong(phi_c, grid.shape_zyx, factor), phi_c
