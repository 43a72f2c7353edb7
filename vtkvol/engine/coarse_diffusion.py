"""The source model's scattered light on a reduced-resolution grid (issue 24): ½ or ¼ of the
data grid per axis (``scatter_grid`` = "half" / "quarter"), numpy.

Geometry: the host's one mechanism for auxiliary grids (``vv_unitToGrid(vv_texToUnit(texPos),
dims)`` in ``host_prelude.glsl``, also the shadow volume's, translucency's and the baked AO's):
m = ⌈n/f⌉ points per axis (at least 2 where the data has 2) spanning the data's point bounds, so
the first and last coarse centres sit on the first and last voxel centres; spacing
(n − 1)·h/(m − 1) µm. The scattered texture is then m³ texels (1/f³ of the data's) and the ray
caster samples it with linear filtering at the same dataset position as the data.

Prolongation (coarse → fine) is that texture lookup: trilinear interpolation with the hat
weights w(i, j) = max(0, 1 − |i·r − j|), r = (m − 1)/(n − 1) per axis (:func:`axis_weights`).
Restriction (fine → coarse) is its transpose, normalised ("full weighting"): each coarse node is
the hat-weighted mean of the fine voxels around it, of σ_t (then the coarse cell's D, σ_a, σ_s
from it by :func:`~vtkvol.engine.diffusion.source_coefficients` on the coarse grid: the mean σ_t
keeps the mean optical depth, where averaging D would weight thin voxels too much, D ∝ 1/σ) and
of q (the single-scattering source per µm³, so its power is kept up to the boundary nodes).
``shaders/source_restrict.comp.glsl`` is the GPU twin of :meth:`ScatterGrid.restrict` for q.
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
    """Points of an axis of ``n`` voxels on the ``factor``-coarse grid: ⌈n/f⌉, at least
    min(n, 2) so both ends of the point bounds are kept."""
    if factor == 1:
        return n
    return max(min(n, 2), -(-n // factor))


def coarse_grid(grid: Grid, factor: int) -> Grid:
    """The ``factor``-coarse grid over ``grid``'s point bounds (dataset space, µm): same
    origin (first voxel centre), :func:`coarse_points` per axis, spacing (n − 1)h/(m − 1)."""
    if factor == 1:
        return grid
    shape = tuple(coarse_points(n, factor) for n in grid.shape_zyx)
    spacing = []
    for s, n, m in zip(grid.spacing, grid.shape_zyx[::-1], shape[::-1], strict=True):
        spacing.append(s * (n - 1) / (m - 1) if m > 1 else s * n)
    return Grid(shape, tuple(spacing), grid.origin)  # type: ignore[arg-type]


def axis_weights(n: int, m: int) -> np.ndarray:
    """``[m, n]`` float64 hat weights w(i, j) = max(0, 1 − |i·r − j|), r = (m − 1)/(n − 1):
    column i holds the trilinear weights of fine voxel i on the coarse points (they sum to 1)."""
    if m == n:
        return np.eye(n)
    r = (m - 1) / (n - 1) if n > 1 else 0.0
    pos = np.arange(n, dtype=np.float64) * r
    return np.maximum(0.0, 1.0 - np.abs(pos[None, :] - np.arange(m, dtype=np.float64)[:, None]))


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
        self._weights = [axis_weights(n, m) for n, m in
                         zip(grid.shape_zyx, self.grid.shape_zyx, strict=True)]

    @classmethod
    def named(cls, grid: Grid, resolution: str) -> ScatterGrid:
        """The grid of the ``scatter_grid`` choice ``resolution`` ("full", "half", "quarter")."""
        return cls(grid, FACTORS[resolution])

    @property
    def coarse(self) -> bool:
        return self.factor > 1

    @property
    def dims_xyz(self) -> tuple[float, float, float]:
        """Points per axis (x, y, z): the shader's ``vv_<technique>_scatteredDims``."""
        nz, ny, nx = self.grid.shape_zyx
        return float(nx), float(ny), float(nz)

    @property
    def ratios_xyz(self) -> tuple[float, float, float]:
        """r = (m − 1)/(n − 1) per axis (x, y, z): coarse index per fine index."""
        out = []
        for n, m in zip(self.fine.shape_zyx[::-1], self.grid.shape_zyx[::-1], strict=True):
            out.append((m - 1) / (n - 1) if n > 1 else 0.0)
        return out[0], out[1], out[2]

    def restrict(self, a: np.ndarray) -> np.ndarray:
        """Full weighting of ``a`` (``[z, y, x]`` or ``[z, y, x, c]`` on the data grid): each
        coarse point's hat-weighted mean. float32."""
        if not self.coarse:
            return a.astype(np.float32)
        out = a.astype(np.float64)
        for axis, w in enumerate(self._weights):
            out = _along(out, w / w.sum(axis=1, keepdims=True), axis)
        return out.astype(np.float32)

    def prolong(self, a: np.ndarray) -> np.ndarray:
        """Trilinear interpolation of ``a`` (coarse, ``[z, y, x(, c)]``) at the data's voxel
        centres — what the ray caster's linear lookup of the scattered texture returns. float32."""
        if not self.coarse:
            return a.astype(np.float32)
        out = a.astype(np.float64)
        for axis, w in enumerate(self._weights):
            out = _along(out, w.T, axis)
        return out.astype(np.float32)

    def coefficients(self, sigma_t: np.ndarray, albedo: float,
                     phase_g: float = 0.0) -> np.ndarray:
        """The source model's per-point (D, σ_a, σ_s, 0) on this grid from the data's σ_t
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
