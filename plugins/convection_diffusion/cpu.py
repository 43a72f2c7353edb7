"""Convection–diffusion light transport (seed 003 §3.2, "KD") on the data grid: the numpy path.

It is the fallback without compute shaders and the oracle the GPU path is compared with. Arrays
are ``[z, y, x]`` float32 on the data's voxel centres; lengths are µm (dataset space). The grid,
extinction, diffusion steps and the source model's solver are the engine's
(:mod:`vtkvol.engine.diffusion`, shared with hybrid diffusion); what is KD's own is here. What
the paper leaves open and how it is decided (docs/multiple-scattering.md has the derivations):

* **Convection** (eq. 8, upwind differences eqs. 10–12): per light, an energy density ρ_l moves
  away from the light by h = ½·(smallest voxel edge) per iteration (the paper's Courant ½) and is
  attenuated by a fraction σ_a. The update is split — advect, then attenuate:
  ρ' = (1 − σ_a)·(ρ − ½ Σ_axes c_a (ρ − ρ_upwind,a)), c_a = |u_a|·Δx_min/Δx_a —, not eq. 13's
  (1 − σ_a)ρ − ½Δx·u·Δρ, whose coefficient of ρ turns negative (oscillation) for σ_a > 0.13 on
  diagonal light. The split form keeps ρ ≥ 0 and monotone for every opacity.
* **Absorption mapping**: with the split update, an axis-aligned steady state loses a factor
  (1 − σ_a)/(1 + σ_a) per cell; ``matched`` sets it to the physical exp(−σ·Δx), i.e.
  σ_a = tanh(σ·h), exact for axis-aligned light and never clamped; ``vpt`` is the authors' code,
  σ_a = ½·α_cell. σ is the absorbed part (1 − a)·σ_t in the ``published`` model (eq. 8
  attenuates by absorption only) and the extinction σ_t in the ``source`` model (the direct
  light there is the uncollided beam).
* **Inflow**: the upwind neighbour outside the box is a unit irradiance (1) on the faces the
  light enters; for a point light inside the box, voxels within one voxel edge of it are held at 1.
* **published** (eq. 7 split into eqs. 8–9 on one field per light): each iteration convects ρ_l,
  then diffuses the same ρ_l with ρ_l' = ρ_l + λ(x)·Σ_a w_a ∂²_a ρ_l (eq. 14 with its missing ρ(t)
  term restored), w_a = (Δx_min/Δx_a)², λ = a·σ_t·Δx_min clamped to the stability bound
  1/(2 Σ w_a); zero flux at the box. ρ_l is all the light; the scattered volume stays 0.
* **source**: the direct light is final at the restart (warm start): the transmittance
  ray-marched from every voxel centre to the light (:func:`vtkvol.engine.diffusion.
  marched_transmittance`, exact up to the march's midpoint rule; the upwind convection's
  steady state smears shadow edges oblique to the grid, which cost 4–8 dB in the image —
  docs/benchmarks.md, issue 24's error split); each iteration is then
  ``diffusion_steps`` Jacobi sweeps of the source model for the scattered light ρ_s — on the
  data grid, or with a coarse ``scatter`` grid (``scatter_grid`` "half"/"quarter",
  :mod:`vtkvol.engine.coarse_diffusion`) on its cells, from the restricted source.
* **traced orders** (source model, ``traced_orders`` k > 0): each iteration first draws one
  Monte-Carlo path per voxel for the first k scattering orders
  (:func:`vtkvol.engine.traced_orders.traced_orders_sample`; the GPU's ``tracker.comp.glsl``
  draws other random numbers: the two agree in the mean) into running means of
  E_1 + … + E_k (shown beside the direct and the diffused light) and of E_k; the sweeps' source
  is then σ_s·E_k instead of σ_s·E_0 — the diffusion carries on from the last traced order, and
  light crosses empty space (a cavity, the gap between two objects), which it cannot. After
  ``traced_paths`` paths the traced light is final and the sweeps go on alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from vtkvol.engine.coarse_diffusion import ScatterGrid
from vtkvol.engine.diffusion import (  # noqa: F401  (re-exported: KD's numpy API)
    MAX_OPACITY,
    Grid,
    LightSource,
    diffusion_rate,
    diffusion_step,
    extinction,
    falloff,
    iterations_to_cross,
    jacobi_sweep,
    light_quadrature,
    marched_transmittance,
    propagation,
    propagation_sweeps,
    relative_residual,
    shifted,
    source_coefficients,
    source_mask,
    source_term,
    steady_convection_sweep,
)
from vtkvol.engine.traced_orders import RGB_AS_LIGHTS, traced_orders_sample

AbsorptionMapping = Literal["matched", "vpt"]
ConvectionExtinction = Literal["total", "paper"]
DiffusionModel = Literal["published", "source"]


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
        before = shifted(rho, array_axis, +1, fill=1.0)
        after = shifted(rho, array_axis, -1, fill=1.0)
        upwind = np.where(ua > 0, before, after)
        flow += c * (rho - upwind)
    out = (np.float32(1.0) - sigma_a) * (rho - np.float32(0.5) * flow)
    if source is not None:
        out[source] = 1.0
    return out.astype(np.float32)


@dataclass
class Transport:
    """The whole state of the numpy path: per-light ρ_l, the scattered RGB ρ_s, the iteration.

    ``colors`` are the lights' colour × intensity (RGB). ``model`` selects the published one-field
    split or the source model (which needs ``coefficients``, see
    :func:`vtkvol.engine.diffusion.source_coefficients`, and computes the direct light at once).
    With a coarse ``scatter`` grid the source model's ρ_s lives on its cells (``[m_z, m_y,
    m_x, 3]``), solved with ``scatter_coefficients`` (:meth:`ScatterGrid.coefficients`) from
    the restricted source. With ``orders`` > 0 (the source model's traced orders, which need
    ``sigma_t``) each iteration first draws one path per voxel of the first ``orders``
    scattering orders (until ``traced_paths`` are drawn; ``albedo``, ``phase_g`` and ``seed``
    are the paths') and the sweeps' source is σ_s·E_k of their running mean (see the module
    docstring).
    """

    grid: Grid
    lights: Sequence[LightSource]
    colors: Sequence[tuple[float, float, float]]
    sigma_a: np.ndarray
    lam: np.ndarray
    diffusion_steps: int = 1
    model: DiffusionModel = "published"
    coefficients: np.ndarray | None = None
    scatter: ScatterGrid | None = None
    scatter_coefficients: np.ndarray | None = None
    #: Source model: the extinction σ_t (per µm, ``[z, y, x]``) and the opacity's unit
    #: distance (µm) the direct light is ray-marched through (the exact transmittance); None:
    #: the steady state of the upwind convection instead (smeared at oblique shadow edges).
    sigma_t: np.ndarray | None = None
    unit_distance: float = 1.0
    orders: int = 0
    albedo: float = 1.0
    phase_g: float = 0.0
    traced_paths: int = 256
    seed: int = 0
    rho: np.ndarray = field(init=False)
    rho_s: np.ndarray = field(init=False)
    iteration: int = field(init=False, default=0)
    #: Relative residual ‖b − Aφ‖/‖b‖ of the source model's last sweep (inf before the first).
    residual: float = field(init=False, default=float("inf"))
    #: Traced orders: running means of E_1 + … + E_k and of E_k, ``[z, y, x, 3]`` (lights'
    #: colours, fall-off included), and the paths drawn; None without traced orders.
    traced: np.ndarray | None = field(init=False, default=None)
    last: np.ndarray | None = field(init=False, default=None)
    samples: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        n = len(self.lights)
        self.rho = np.zeros((max(n, 1), *self.grid.shape_zyx), np.float32)
        self.rho_s = np.zeros((*self.grid.shape_zyx, 3), np.float32)
        self._u = [propagation(self.grid, light) for light in self.lights]
        self._sources = [source_mask(self.grid, light) for light in self.lights]
        if self.model == "source":
            if self.coefficients is None:
                raise ValueError("the source model needs its coefficients")
            self.warm_start()
            if self.orders:
                if self.sigma_t is None:
                    raise ValueError("traced orders need the extinction sigma_t")
                self.traced = np.zeros((*self.grid.shape_zyx, 3), np.float32)
                self.last = np.zeros_like(self.traced)
                # the source is E_k of the traced paths: nothing before the first
                q = np.zeros((*self.grid.shape_zyx, 3), np.float32)
            else:
                q = source_term(self.coefficients, self.rho[:n], self.colors,
                                [falloff(self.grid, light) for light in self.lights])
            self._solve_grid, self._solve_coefficients = self.grid, self.coefficients
            if self.scatter is not None and self.scatter.coarse:
                if self.scatter_coefficients is None:
                    raise ValueError("a reduced scattered-light grid needs its coefficients")
                q = self.scatter.restrict(q)
                self._solve_grid = self.scatter.grid
                self._solve_coefficients = self.scatter_coefficients
                self.rho_s = np.zeros((*self.scatter.grid.shape_zyx, 3), np.float32)
            self._q = q

    def warm_start(self) -> None:
        """The final direct light of every light at once (a sized light: the weighted sum over
        its :func:`~vtkvol.engine.diffusion.light_quadrature`): with ``sigma_t``, the
        transmittance ray-marched from every voxel centre
        (:func:`~vtkvol.engine.diffusion.marched_transmittance`); without, the converged
        upwind convection in one propagation pass."""
        for i, light in enumerate(self.lights):
            total = np.zeros(self.grid.shape_zyx, np.float32)
            for ideal, weight in light_quadrature(light):
                if self.sigma_t is not None:
                    rho = marched_transmittance(self.sigma_t, self.grid, ideal,
                                                self.unit_distance)
                else:
                    u, source = propagation(self.grid, ideal), source_mask(self.grid, ideal)
                    rho = np.zeros(self.grid.shape_zyx, np.float32)
                    for _ in range(propagation_sweeps(self.grid)):
                        rho = steady_convection_sweep(rho, self.sigma_a, u, self.grid, source)
                total += np.float32(weight) * rho
            self.rho[i] = total

    def direct_rgb(self) -> np.ndarray:
        """Σ_l E_l ρ_l, ``[z, y, x, 3]`` (without fall-off)."""
        out = np.zeros((*self.grid.shape_zyx, 3), np.float32)
        for rho, color in zip(self.rho, self.colors, strict=False):
            out += rho[..., None] * np.asarray(color, np.float32)
        return out

    def step(self, iterations: int = 1) -> None:
        """Run ``iterations`` iterations: published, one convection step per light then
        ``diffusion_steps`` diffusion steps of the same field; source, ``diffusion_steps``
        Jacobi sweeps of the scattered light (with traced orders, after one path per voxel
        while fewer than ``traced_paths`` are drawn)."""
        for _ in range(iterations):
            if self.model == "source":
                if self.orders and self.samples < self.traced_paths:
                    self.sample_orders()
                for _ in range(self.diffusion_steps):
                    new, r2, q2 = jacobi_sweep(self.rho_s, self._q, self._solve_coefficients,
                                               self._solve_grid)
                    self.residual = relative_residual(r2, q2)
                    self.rho_s = new
            else:
                for i, (u, source) in enumerate(zip(self._u, self._sources, strict=True)):
                    rho = convection_step(self.rho[i], self.sigma_a, u, self.grid, source)
                    for _ in range(self.diffusion_steps):
                        rho = diffusion_step(rho, rho, self.lam, self.grid)
                    self.rho[i] = rho
            self.iteration += 1

    def sample_orders(self) -> None:
        """One path per voxel of the traced orders into their running means, and the sweeps'
        source σ_s·E_k from the new mean of E_k (restricted to a coarse scatter grid)."""
        assert self.traced is not None and self.last is not None
        assert self.coefficients is not None
        nz, ny, _nx = self.grid.shape_zyx
        traced, last = traced_orders_sample(self, (0, nz, 0, ny), self.samples, self.seed)
        weight = np.float32(1.0 / (self.samples + 1))
        self.traced += (traced - self.traced) * weight
        self.last += (last - self.last) * weight
        self.samples += 1
        q = source_term(self.coefficients, np.moveaxis(self.last, -1, 0), RGB_AS_LIGHTS,
                        [1.0] * 3)
        if self.scatter is not None and self.scatter.coarse:
            q = self.scatter.restrict(q)
        self._q = q
