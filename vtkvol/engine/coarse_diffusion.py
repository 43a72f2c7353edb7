"""The source model's scattered light on a reduced-resolution grid (issue 24): ½ or ¼ of the
data grid per axis (``scatter_grid`` = "half" / "quarter"), numpy.

Geometry: m = ⌈n/f⌉ cells per axis tiling the data's cell bounds (the extent of the volume
texture), each n/m data voxels wide (f exactly when f divides n). The scattered texture is then
m³ texels (1/f³ of the data's) covering the same extent as the data texture, so the ray caster
samples it at the same texture coordinate ``texPos`` as the data — one lookup for every
scattered texture, full or reduced, no extra uniform.

Prolongation (coarse → fine) is that lookup: linear filtering with clamp-to-edge, the fine voxel
i at coarse index (i + ½)·m/n − ½ clamped to [0, m − 1] (:meth:`ScatterGrid.prolong`).
Restriction (fine → coarse) is the volume-weighted mean over each coarse cell (the overlap of
the fine and coarse cells per axis; block means when f divides n), of σ_t (then the coarse
cell's D, σ_a, σ_s from it by :func:`~vtkvol.engine.diffusion.source_coefficients` on the coarse
grid: the mean σ_t keeps the mean optical depth, where averaging D would weight thin voxels too
much, D ∝ 1/σ) and of q (the single-scattering source per µm³, so its power is conserved).
``shaders/source_restrict.comp.glsl`` is the GPU twin of :meth:`ScatterGrid.restrict` for q.

Measured alternatives (ball α 0.1 of ``benchmarks/coarse_scattering.py``, PSNR of φ against the
full grid): grids whose points span the data's point bounds (the shadow volume's
``vv_unitToGrid``) with hat-weighted restriction, 15.9 dB at half; with nearest-point means
37.6 dB at half but 11.6 dB at quarter (their finite-volume cells overhang the data by
(s − h)/2 per face); these cell-tiling means 22.4 dB at half, 17.7 dB at quarter.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from vtkvol.engine.diffusion import DEFAULT_TOLERANCE, Grid, solve_source, source_coefficients

Resolution = Literal["full", "half", "quarter"]
#: Coarsening factor per axis of each ``scatter_grid`` choice.
FACTORS: dict[str, int] = {"full": 1, "half": 2, "quarter": 4}


def coarse_points(n: int, factor: int) -> int:
    """Cells of an axis of ``n`` voxels on the ``factor``-coarse grid: ⌈n/f⌉."""
    return -(-n // factor)


def coarse_grid(grid: Grid, factor: int) -> Grid:
    """The ``factor``-coarse grid tiling ``grid``'s cell bounds (dataset space, µm):
    :func:`coarse_points` cells per axis of n·h/m µm, the first centre half a coarse cell
    inside the first voxel's outer face."""
    if factor == 1:
        return grid
    shape = tuple(coarse_points(n, factor) for n in grid.shape_zyx)
    spacing, origin = [], []
    for s, o, n, m in zip(grid.spacing, grid.origin, grid.shape_zyx[::-1], shape[::-1],
                          strict=True):
        spacing.append(s * n / m)
        origin.append(o - 0.5 * s + 0.5 * s * n / m)
    return Grid(shape, tuple(spacing), tuple(origin))  # type: ignore[arg-type]


def overlap_weights(n: int, m: int) -> np.ndarray:
    """``[m, n]`` float64: the length (in data voxels) of data cell [i, i + 1) inside coarse
    cell [j·c, (j + 1)·c), c = n/m — the restriction's weights before normalisation."""
    c = n / m
    i = np.arange(n, dtype=np.float64)[None, :]
    j = np.arange(m, dtype=np.float64)[:, None]
    return np.maximum(0.0, np.minimum(i + 1.0, (j + 1.0) * c) - np.maximum(i, j * c))


def lookup_weights(n: int, m: int) -> np.ndarray:
    """``[n, m]`` float64: the linear-filtering weights of a texture of ``m`` texels over the
    same extent as ``n`` voxels, at the voxel centres (clamp-to-edge)."""
    pos = np.clip((np.arange(n, dtype=np.float64) + 0.5) * m / n - 0.5, 0.0, m - 1)
    return np.maximum(0.0, 1.0 - np.abs(pos[:, None] - np.arange(m, dtype=np.float64)[None, :]))


def _along(a: np.ndarray, matrix: np.ndarray, axis: int) -> np.ndarray:
    """``matrix`` (``[out, in]``) applied along ``axis`` of ``a``."""
    return np.moveaxis(np.tensordot(matrix, np.moveaxis(a, axis, 0), axes=(1, 0)), 0, axis)


class ScatterGrid:
    """The grid the scattered light is solved on, for a data ``grid`` and a coarsening
    ``factor`` (1: the data grid itself), with its restriction and prolongation."""

    def __init__(self, grid: Grid, factor: int) -> None:
        self.fine = grid
        self.factor = factor
        self.grid = coarse_grid(grid, factor)
        pairs = list(zip(grid.shape_zyx, self.grid.shape_zyx, strict=True))
        self._restrict = [overlap_weights(n, m) / (n / m) for n, m in pairs]
        self._prolong = [lookup_weights(n, m) for n, m in pairs]

    @classmethod
    def named(cls, grid: Grid, resolution: str) -> ScatterGrid:
        """The grid of the ``scatter_grid`` choice ``resolution`` ("full", "half", "quarter")."""
        return cls(grid, FACTORS[resolution])

    @property
    def coarse(self) -> bool:
        return self.factor > 1

    @property
    def cells_xyz(self) -> tuple[float, float, float]:
        """c = n/m per axis (x, y, z): data voxels per coarse cell (the restriction's window)."""
        out = [n / m for n, m in zip(self.fine.shape_zyx[::-1], self.grid.shape_zyx[::-1],
                                     strict=True)]
        return out[0], out[1], out[2]

    def restrict(self, a: np.ndarray) -> np.ndarray:
        """The mean of ``a`` (``[z, y, x]`` or ``[z, y, x, c]`` on the data grid) over each
        coarse cell, weighted by the volume of each voxel inside it. float32."""
        if not self.coarse:
            return a.astype(np.float32)
        out = a.astype(np.float64)
        for axis, w in enumerate(self._restrict):
            out = _along(out, w, axis)
        return out.astype(np.float32)

    def prolong(self, a: np.ndarray) -> np.ndarray:
        """Trilinear interpolation of ``a`` (coarse, ``[z, y, x(, c)]``) at the data's voxel
        centres — what the ray caster's linear lookup of the scattered texture returns. float32."""
        if not self.coarse:
            return a.astype(np.float32)
        out = a.astype(np.float64)
        for axis, w in enumerate(self._prolong):
            out = _along(out, w, axis)
        return out.astype(np.float32)

    def coefficients(self, sigma_t: np.ndarray, albedo: float,
                     phase_g: float = 0.0) -> np.ndarray:
        """The source model's per-cell (D, σ_a, σ_s, 0) on this grid from the data's σ_t
        (per µm, ``[z, y, x]``): from the restricted σ_t (see the module docstring)."""
        return source_coefficients(self.restrict(sigma_t), self.grid, albedo, phase_g)


def solve_source_coarse(q: np.ndarray, sigma_t: np.ndarray, grid: Grid, albedo: float,
                        factor: int, *, phase_g: float = 0.0,
                        tolerance: float = DEFAULT_TOLERANCE
                        ) -> tuple[np.ndarray, np.ndarray, int]:
    """The source model solved on the ``factor``-coarse grid (``q`` ``[z, y, x, 3]`` per µm³,
    ``sigma_t`` ``[z, y, x]`` per µm on ``grid``): (φ prolonged to the data's voxels, the
    coarse φ — what the scattered texture holds —, the Jacobi sweeps it took)."""
    scatter = ScatterGrid(grid, factor)
    phi_c, sweeps = solve_source(scatter.restrict(q), scatter.coefficients(sigma_t, albedo,
                                                                           phase_g),
                                 scatter.grid, tolerance=tolerance)
    return scatter.prolong(phi_c), phi_c, sweeps


def texture_bytes(shape_zyx: tuple[int, ...]) -> int:
    """Bytes of an RGBA float32 texture of ``shape_zyx`` texels."""
    return 16 * math.prod(shape_zyx[:3])
