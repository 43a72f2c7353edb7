"""Convection–diffusion light transport (seed 003 §3.2, "KD") on the data grid: the numpy path.

It is the fallback without compute shaders and the oracle the GPU path is compared with. Arrays
are ``[z, y, x]`` float32 on the data's voxel centres; lengths are µm (dataset space). What the
paper leaves open and how it is decided here (docs/multiple-scattering.md has the derivations):

* **Convection** (eq. 8, upwind differences eqs. 10–12): per light, an energy density ρ_l moves
  away from the light by h = ½·(smallest voxel edge) per iteration (the paper's Courant ½) and is
  attenuated by a fraction σ_a. The update is split — advect, then attenuate:
  ρ' = (1 − σ_a)·(ρ − ½ Σ_axes c_a (ρ − ρ_upwind,a)), c_a = |u_a|·Δx_min/Δx_a —, not eq. 13's
  (1 − σ_a)ρ − ½Δx·u·Δρ, whose coefficient of ρ turns negative (oscillation) for σ_a > 0.13 on
  diagonal light. The split form keeps ρ ≥ 0 and monotone for every opacity.
* **Absorption mapping**: with the split update, an axis-aligned steady state loses a factor
  (1 − σ_a)/(1 + σ_a) per cell; ``matched`` sets it to the physical exp(−σ·Δx), i.e.
  σ_a = tanh(σ·h), exact for axis-aligned light and never clamped; ``vpt`` is the authors' code,
  σ_a = ½·α_cell. σ is the extinction σ_t (``total``, what the references use) or its absorbed
  part (1 − a)·σ_t (``paper``: eq. 8 attenuates by absorption only).
* **Inflow**: the upwind neighbour outside the box is a unit irradiance (1) on the faces the
  light enters; for a point light inside the box, voxels within one voxel edge of it are held at 1.
* **Diffusion** (eq. 9, central differences eq. 14 with the missing ρ(t) term restored): explicit
  Euler on the total field, kept in its own volume ρ_s (RGB, the lights' colours):
  ρ_s' = ρ_s + λ(x)·Σ_a w_a (ρ(x+e_a) + ρ(x−e_a) − 2ρ(x)), ρ = Σ_l E_l ρ_l + ρ_s,
  w_a = (Δx_min/Δx_a)², λ = a·σ_t·Δx_min clamped to the stability bound 1/(2 Σ w_a) (1/6 for
  cubic voxels); zero flux at the box (clamp to edge).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

#: α is clamped below 1 before −ln(1 − α) (a fully opaque voxel keeps a finite extinction).
MAX_OPACITY = 1.0 - 1e-6

AbsorptionMapping = Literal["matched", "vpt"]
ConvectionExtinction = Literal["total", "paper"]


def extinction(opacity: np.ndarray, unit_distance: float) -> np.ndarray:
    """σ_t per µm from the TF opacity α (per ``unit_distance`` µm): −ln(1 − α)/u."""
    alpha = np.clip(np.asarray(opacity, np.float64), 0.0, MAX_OPACITY)
    return (-np.log1p(-alpha) / unit_distance).astype(np.float32)


@dataclass(frozen=True)
class Grid:
    """The data grid: ``shape_zyx`` voxels of ``spacing`` (x, y, z) µm, first centre at
    ``origin`` (x, y, z) µm (dataset space)."""

    shape_zyx: tuple[int, int, int]
    spacing: tuple[float, float, float]
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def step(self) -> float:
        """h: how far (µm) the light front moves per iteration (half the smallest edge)."""
        return 0.5 * min(self.spacing)

    @property
    def axis_ratios(self) -> np.ndarray:
        """Δx_min/Δx_a for a = x, y, z (float32, as the GPU computes with them)."""
        s = np.asarray(self.spacing, np.float64)
        return (s.min() / s).astype(np.float32)

    @property
    def axis_weights(self) -> np.ndarray:
        """(Δx_min/Δx_a)² for a = x, y, z: the diffusion's per-axis weights (float32)."""
        return (self.axis_ratios.astype(np.float64) ** 2).astype(np.float32)

    @property
    def max_lambda(self) -> float:
        """Stability bound of the explicit diffusion step: 1/(2 Σ w_a)."""
        return float(1.0 / (2.0 * self.axis_weights.astype(np.float64).sum()))

    def centres(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x, y, z of every voxel centre (µm), each broadcastable to ``shape_zyx``."""
        nz, ny, nx = self.shape_zyx
        ox, oy, oz = self.origin
        sx, sy, sz = self.spacing
        return (
            (ox + sx * np.arange(nx, dtype=np.float64))[None, None, :],
            (oy + sy * np.arange(ny, dtype=np.float64))[None, :, None],
            (oz + sz * np.arange(nz, dtype=np.float64))[:, None, None],
        )


@dataclass(frozen=True)
class LightSource:
    """A light as the transport sees it (dataset space): ``kind`` "directional" (``vector`` =
    unit direction towards the light) or "point" (``vector`` = position, µm)."""

    kind: str
    vector: tuple[float, float, float]


def absorption_per_iteration(
    sigma_t: np.ndarray, grid: Grid, *, albedo: float, mapping: AbsorptionMapping,
    convection_extinction: ConvectionExtinction, unit_distance: float,
) -> np.ndarray:
    """σ_a ∈ [0, 1): the fraction of ρ absorbed per iteration (see the module docstring)."""
    sigma = sigma_t if convection_extinction == "total" else (1.0 - albedo) * sigma_t
    if mapping == "matched":
        return np.tanh(sigma.astype(np.float64) * grid.step).astype(np.float32)
    # vpt: half the opacity of one cell of the smallest edge.
    alpha_cell = 1.0 - np.exp(-sigma.astype(np.float64) * min(grid.spacing))
    return (0.5 * alpha_cell).astype(np.float32)


def diffusion_rate(sigma_t: np.ndarray, grid: Grid, albedo: float) -> np.ndarray:
    """λ per voxel: a·σ_t·Δx_min, clamped to the stability bound."""
    lam = albedo * sigma_t.astype(np.float64) * min(grid.spacing)
    return np.minimum(lam, grid.max_lambda).astype(np.float32)


def propagation(grid: Grid, light: LightSource) -> np.ndarray:
    """Unit direction u (x, y, z) in which the light travels, shape ``(3, 1|nz, 1|ny, 1|nx)``."""
    if light.kind == "point":
        x, y, z = grid.centres()
        px, py, pz = light.vector
        d = [np.broadcast_to(c - p, grid.shape_zyx) for c, p in zip((x, y, z), (px, py, pz),
                                                                   strict=True)]
        u = np.stack(d)
        norm = np.sqrt((u * u).sum(axis=0))
        return (u / np.maximum(norm, 1e-12)).astype(np.float32)
    d = -np.asarray(light.vector, np.float64)
    d /= max(float(np.linalg.norm(d)), 1e-30)
    return d.astype(np.float32).reshape(3, 1, 1, 1)


def source_mask(grid: Grid, light: LightSource) -> np.ndarray | None:
    """Voxels held at ρ = 1: within one voxel edge of a point light inside the box."""
    if light.kind != "point":
        return None
    x, y, z = grid.centres()
    px, py, pz = light.vector
    r2 = (x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2
    mask = r2 <= max(grid.spacing) ** 2
    return mask if mask.any() else None


def convection_step(
    rho: np.ndarray, sigma_a: np.ndarray, u: np.ndarray, grid: Grid,
    source: np.ndarray | None = None,
) -> np.ndarray:
    """One iteration of advection away from the light, then absorption (a new array)."""
    ratio = grid.axis_ratios  # x, y, z
    flow = np.zeros_like(rho)
    for axis_xyz, array_axis in ((0, 2), (1, 1), (2, 0)):
        ua = np.broadcast_to(u[axis_xyz], rho.shape)
        c = np.abs(ua) * ratio[axis_xyz]
        # Upwind neighbours: the voxel before (u > 0) or after (u < 0) along the axis; outside
        # the box, the inflow irradiance 1.
        before = _shifted(rho, array_axis, +1, fill=1.0)
        after = _shifted(rho, array_axis, -1, fill=1.0)
        upwind = np.where(ua > 0, before, after)
        flow += c * (rho - upwind)
    out = (np.float32(1.0) - sigma_a) * (rho - np.float32(0.5) * flow)
    if source is not None:
        out[source] = 1.0
    return out.astype(np.float32)


def diffusion_step(total: np.ndarray, rho_s: np.ndarray, lam: np.ndarray,
                   grid: Grid) -> np.ndarray:
    """One explicit Euler step of ρ_s' = ρ_s + λ·Σ_a w_a ∂²_a(total); ``total`` and ``rho_s``
    are ``[..., 3]`` (RGB) or scalar fields; zero flux at the box."""
    weights = grid.axis_weights
    lap = np.zeros_like(total)
    for axis_xyz, array_axis in ((0, 2), (1, 1), (2, 0)):
        lap += weights[axis_xyz] * (
            _shifted(total, array_axis, +1, fill=None) + _shifted(total, array_axis, -1, fill=None)
            - np.float32(2.0) * total
        )
    scale = lam if lap.ndim == lam.ndim else lam[..., None]
    return (rho_s + scale * lap).astype(np.float32)


def _shifted(a: np.ndarray, axis: int, offset: int, fill: float | None) -> np.ndarray:
    """``a`` moved by ``offset`` along ``axis``: out[i] = a[i − offset]. Outside the array:
    ``fill``, or the edge value (clamp to edge) when ``fill`` is None."""
    out = np.empty_like(a)
    n = a.shape[axis]
    src = [slice(None)] * a.ndim
    dst = [slice(None)] * a.ndim
    edge = [slice(None)] * a.ndim
    if offset > 0:
        dst[axis], src[axis], edge[axis] = slice(1, n), slice(0, n - 1), slice(0, 1)
        border = [slice(None)] * a.ndim
        border[axis] = slice(0, 1)
    else:
        dst[axis], src[axis], edge[axis] = slice(0, n - 1), slice(1, n), slice(n - 1, n)
        border = [slice(None)] * a.ndim
        border[axis] = slice(n - 1, n)
    out[tuple(dst)] = a[tuple(src)]
    out[tuple(border)] = a[tuple(edge)] if fill is None else fill
    return out


@dataclass
class Transport:
    """The whole state of the numpy path: per-light ρ_l, the scattered RGB ρ_s, the iteration.

    ``colors`` are the lights' colour × intensity (RGB), which weight the lights in the field the
    diffusion spreads.
    """

    grid: Grid
    lights: Sequence[LightSource]
    colors: Sequence[tuple[float, float, float]]
    sigma_a: np.ndarray
    lam: np.ndarray
    diffusion_steps: int = 1
    rho: np.ndarray = field(init=False)
    rho_s: np.ndarray = field(init=False)
    iteration: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        n = len(self.lights)
        self.rho = np.zeros((max(n, 1), *self.grid.shape_zyx), np.float32)
        self.rho_s = np.zeros((*self.grid.shape_zyx, 3), np.float32)
        self._u = [propagation(self.grid, light) for light in self.lights]
        self._sources = [source_mask(self.grid, light) for light in self.lights]

    def direct_rgb(self) -> np.ndarray:
        """Σ_l E_l ρ_l, ``[z, y, x, 3]``."""
        out = np.zeros((*self.grid.shape_zyx, 3), np.float32)
        for rho, color in zip(self.rho, self.colors, strict=False):
            out += rho[..., None] * np.asarray(color, np.float32)
        return out

    def step(self, iterations: int = 1) -> None:
        """Run ``iterations`` × (one convection step per light, ``diffusion_steps`` diffusion
        steps on the updated field)."""
        for _ in range(iterations):
            for i, (u, source) in enumerate(zip(self._u, self._sources, strict=True)):
                self.rho[i] = convection_step(self.rho[i], self.sigma_a, u, self.grid, source)
            direct = self.direct_rgb()
            for _ in range(self.diffusion_steps):
                self.rho_s = diffusion_step(direct + self.rho_s, self.rho_s, self.lam, self.grid)
            self.iteration += 1


def iterations_to_cross(grid: Grid) -> int:
    """Iterations the light front needs to cross the box's diagonal (h per iteration)."""
    nz, ny, nx = grid.shape_zyx
    sx, sy, sz = grid.spacing
    diagonal = math.sqrt(((nx - 1) * sx) ** 2 + ((ny - 1) * sy) ** 2 + ((nz - 1) * sz) ** 2)
    return math.ceil(diagonal / grid.step) + 1
