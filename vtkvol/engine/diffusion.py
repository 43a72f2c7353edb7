"""Grid diffusion of light, shared by the multiple-scattering techniques (seed 003's
convection–diffusion "KD" and hybrid diffusion "HD"; docs/multiple-scattering.md): the data grid,
extinction, the explicit diffusion step of the published model, the single-scattering-source
diffusion solve of the ``"source"`` model — each with its numpy twin and its GPU driver — and
the technique base class that shows a direct and a scattered texture.

Arrays are ``[z, y, x]`` (``[..., 3]`` for RGB) float32 on the data's voxel centres; lengths are
µm (dataset space), extinction coefficients per µm.

The ``"source"`` model (docs/multiple-scattering.md, "The source model") solves for the collided
fluence φ (the scattered light the host adds as ``vv_irradiance``)

    −∇·(D ∇φ) + σ_a φ = σ_s E_0,   σ_s = a·σ_t, σ_a = (1 − a)·σ_t,
    D = min(1 / (3 σ_t (1 − a g)), D_MAX_EDGES · Δx_min)

with E_0 the uncollided (direct) light, by cell-centred finite volumes: faces between two medium
voxels carry the harmonic mean of D; a face to an empty voxel or to the box is a vacuum
(Marshak) boundary with no incoming diffuse light, outflow J = φ / (2 + Δx/(2D)) — bounded by
φ/2 whatever D (the flux limit). The matrix is a symmetric M-matrix, so Jacobi sweeps from φ = 0
rise monotonically to the solution and φ ≥ 0 at every sweep; they stop on the relative residual
‖σ_s E_0 − Aφ‖ / ‖σ_s E_0‖, not on a sweep count.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
import vtk

from vtkvol.engine.gl import ComputeProgram, GLUnavailableError, Texture3D, gl, unbind_images
from vtkvol.engine.shaders import compute_source
from vtkvol.engine.technique import ComputePath, Technique, TechniqueStats
from vtkvol.model.diffusion import DEFAULT_TOLERANCE as _MODEL_TOLERANCE

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator

#: α is clamped below 1 before −ln(1 − α) (a fully opaque voxel keeps a finite extinction).
MAX_OPACITY = 1.0 - 1e-6
GROUP = (8, 8, 4)  #: work-group size of the diffusion compute shaders
#: The source model's diffusion coefficient is bounded by this many smallest voxel edges
#: (thin voxels: 1/(3σ_t) would otherwise grow without bound towards empty space).
D_MAX_EDGES = 4.0
#: Voxels whose optical thickness σ_t·Δx_min is below this are empty: no unknown, φ = 0 (light
#: does not diffuse through vacuum; it leaves through the Marshak boundary instead).
EMPTY_OPTICAL_THICKNESS = 1e-4
#: Default stopping tolerance of the source model: relative residual ‖b − Aφ‖/‖b‖.
DEFAULT_TOLERANCE = _MODEL_TOLERANCE

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


class ReducedGrid(Protocol):
    """What the GPU solver reads of the grid the scattered light is solved on
    (:class:`vtkvol.engine.coarse_diffusion.ScatterGrid`, which builds on this module)."""

    @property
    def grid(self) -> Grid: ...  # the grid φ is solved on (the data's, or coarser)

    @property
    def coarse(self) -> bool: ...  # whether that grid is coarser than the data's

    @property
    def cells_xyz(self) -> tuple[float, float, float]: ...  # data voxels per coarse cell


@dataclass(frozen=True)
class LightSource:
    """A light as the transport sees it (dataset space): ``kind`` "directional" (``vector`` =
    unit direction towards the light) or "point" (``vector`` = position, µm);
    ``falloff_distance`` d0 (µm) scales the irradiance by (d0/r)² (0 = no fall-off);
    ``size`` is the light's extent as :class:`~vtkvol.engine.technique.LightSpec` holds it:
    angular radius (radians, directional) or radius (µm, point; the light is a sphere)."""

    kind: str
    vector: tuple[float, float, float]
    falloff_distance: float = 0.0
    size: float = 0.0


def falloff(grid: Grid, light: LightSource) -> np.ndarray | float:
    """Inverse-square fall-off (d0/r)² of ``light`` at every voxel centre (float32 ``[z, y, x]``),
    or 1.0 where the light has none — as the host's ``vv_lightColor`` computes it."""
    d0 = float(light.falloff_distance)
    if light.kind != "point" or d0 <= 0.0:
        return 1.0
    x, y, z = grid.centres()
    px, py, pz = light.vector
    r2 = (x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2
    return (d0 * d0 / np.maximum(r2, 1e-12)).astype(np.float32)


def light_quadrature(light: LightSource) -> list[tuple[LightSource, float]]:
    """Ideal lights and weights whose weighted sum of direct light stands for the sized
    ``light`` (itself, weight 1, when it has no size): a point light's sphere by the six points
    ±size along the axes (exact for polynomials of degree 3 on the sphere); a directional
    light's cone by its axis (weight 1/4) and six directions at √(2/3)·size from it, 60° apart
    (1/8 each; the disc rule of degree 3 in the small-angle plane of the cone). The light is
    sampled as the camera path tracer samples it: uniformly on the sphere, or in the cone."""
    size = float(light.size)
    if size <= 0.0:
        return [(light, 1.0)]
    if light.kind == "point":
        centre = np.asarray(light.vector, np.float64)
        out = []
        for axis in range(3):
            for sign in (1.0, -1.0):
                p = centre.copy()
                p[axis] += sign * size
                out.append((LightSource("point", (float(p[0]), float(p[1]), float(p[2])),
                                        light.falloff_distance), 1.0 / 6.0))
        return out
    w = np.asarray(light.vector, np.float64)
    w /= max(float(np.linalg.norm(w)), 1e-30)
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(w, a)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(w, t1)
    theta = math.sqrt(2.0 / 3.0) * min(size, math.pi / 2)
    out = [(LightSource("directional", (float(w[0]), float(w[1]), float(w[2]))), 0.25)]
    for k in range(6):
        phi = k * math.pi / 3.0
        d = math.cos(theta) * w + math.sin(theta) * (math.cos(phi) * t1 + math.sin(phi) * t2)
        out.append((LightSource("directional", (float(d[0]), float(d[1]), float(d[2]))), 0.125))
    return out


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


def diffusion_step(total: np.ndarray, rho_s: np.ndarray, lam: np.ndarray,
                   grid: Grid) -> np.ndarray:
    """One explicit Euler step of ρ_s' = ρ_s + λ·Σ_a w_a ∂²_a(total); ``total`` and ``rho_s``
    are ``[..., 3]`` (RGB) or scalar fields; zero flux at the box."""
    weights = grid.axis_weights
    lap = np.zeros_like(total)
    for axis_xyz, array_axis in ((0, 2), (1, 1), (2, 0)):
        lap += weights[axis_xyz] * (
            shifted(total, array_axis, +1, fill=None) + shifted(total, array_axis, -1, fill=None)
            - np.float32(2.0) * total
        )
    scale = lam if lap.ndim == lam.ndim else lam[..., None]
    return (rho_s + scale * lap).astype(np.float32)


def shifted(a: np.ndarray, axis: int, offset: int, fill: float | None) -> np.ndarray:
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


def iterations_to_cross(grid: Grid) -> int:
    """Iterations the light front needs to cross the box's diagonal (h per iteration)."""
    nz, ny, nx = grid.shape_zyx
    sx, sy, sz = grid.spacing
    diagonal = math.sqrt(((nx - 1) * sx) ** 2 + ((ny - 1) * sy) ** 2 + ((nz - 1) * sz) ** 2)
    return math.ceil(diagonal / grid.step) + 1


# -- the "source" model ---------------------------------------------------------------------------
def source_coefficients(sigma_t: np.ndarray, grid: Grid, albedo: float,
                        phase_g: float = 0.0) -> np.ndarray:
    """Per voxel (D µm, σ_a per µm, σ_s per µm, 0) of the source model, ``[z, y, x, 4]``
    float32; D = 0 marks an empty voxel (no unknown). With an anisotropic phase function the
    diffusion uses the reduced scattering (1 − g)σ_s (similarity), σ_tr = σ_t(1 − a·g)."""
    sigma = sigma_t.astype(np.float64)
    h = min(grid.spacing)
    inside = sigma * h > EMPTY_OPTICAL_THICKNESS
    sigma_tr = np.maximum(sigma * (1.0 - albedo * phase_g), 1e-30)
    d = np.where(inside, np.minimum(1.0 / (3.0 * sigma_tr), D_MAX_EDGES * h), 0.0)
    out = np.zeros((*sigma.shape, 4), np.float32)
    out[..., 0] = d
    out[..., 1] = np.where(inside, (1.0 - albedo) * sigma, 0.0)
    out[..., 2] = np.where(inside, albedo * sigma, 0.0)
    return out


def source_term(coefficients: np.ndarray, direct: np.ndarray,
                colors: Sequence[tuple[float, float, float]],
                falloffs: Sequence[np.ndarray | float]) -> np.ndarray:
    """q = σ_s · Σ_l colour_l · fall-off_l · direct_l, ``[z, y, x, 3]`` float32: the
    single-scattering source from the uncollided light (``direct`` ``[lights, z, y, x]``, each
    0…1 transmittance-like) — the phase function integrates to 1 over the sphere."""
    e0 = np.zeros((*coefficients.shape[:3], 3), np.float32)
    for rho, color, f in zip(direct, colors, falloffs, strict=False):
        e0 += (np.asarray(rho, np.float32) * np.float32(1.0) * f)[..., None] * np.asarray(
            color, np.float32)
    return (coefficients[..., 2:3] * e0).astype(np.float32)


def jacobi_sweep(phi: np.ndarray, q: np.ndarray, coefficients: np.ndarray,
                 grid: Grid) -> tuple[np.ndarray, float, float]:
    """One Jacobi sweep of the source model's system (``phi``, ``q`` ``[z, y, x, 3]``):
    (new φ, Σ residual² of the old φ, Σ q²). Every coefficient is ≥ 0, so φ ≥ 0 whenever
    q ≥ 0 and the old φ ≥ 0. An empty voxel (no unknown) next to the medium gets the mean of
    its medium neighbours' old φ (:func:`surface_fill`), the others 0.
    ``shaders/source_diffusion.comp.glsl`` is its GPU twin."""
    d = coefficients[..., 0]
    inside = d > 0
    diag = coefficients[..., 1].copy()
    acc = q.astype(np.float32).copy()
    two = np.float32(2.0)
    for axis_xyz, array_axis in ((0, 2), (1, 1), (2, 0)):
        h = np.float32(grid.spacing[axis_xyz])
        for offset in (+1, -1):
            dn = shifted(d, array_axis, offset, fill=0.0)
            pn = shifted(phi, array_axis, offset, fill=0.0)
            neighbour = dn > 0
            with np.errstate(divide="ignore", invalid="ignore"):
                cond = np.where(neighbour, two * d * dn / (d + dn) / (h * h), np.float32(0.0))
                leak = np.where(inside & ~neighbour,
                                np.float32(1.0) / (h * (two + h / (two * d))), np.float32(0.0))
            diag += (cond + leak).astype(np.float32)
            acc += cond[..., None] * pn
    safe = np.where(inside, diag, np.float32(1.0))[..., None]
    residual = np.where(inside[..., None], acc - safe * phi, np.float32(0.0))
    new = np.where(inside[..., None], acc / safe, surface_fill(phi, inside)).astype(np.float32)
    q_in = np.where(inside[..., None], q, np.float32(0.0))
    return new, float((residual.astype(np.float64) ** 2).sum()), float(
        (q_in.astype(np.float64) ** 2).sum())


def surface_fill(phi: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """φ (``[z, y, x, c]``) carried out of the medium one voxel: at every voxel the mean of φ
    over its medium (``inside``) neighbours in the 26-neighbourhood, 0 without any (float32).
    Why: the scattered light is sampled trilinearly at every visible point, and a point in the
    medium's outer half voxel interpolates towards the empty voxels beside it; with φ = 0
    there, every surface darkens (the Monte-Carlo reference's in-scattered light is about the
    surface's value there). Issue 24's error split measured +0.7 to +5 dB in the image. The
    empty voxels are no unknowns: the fill never feeds back into the medium's equations."""
    nz, ny, nx = inside.shape
    w = np.pad(inside.astype(np.float32), 1)
    v = np.pad(np.where(inside[..., None], phi, np.float32(0.0)).astype(np.float32),
               ((1, 1), (1, 1), (1, 1), (0, 0)))
    acc = np.zeros(phi.shape, np.float32)
    count = np.zeros(inside.shape, np.float32)
    for dz in range(3):
        for dy in range(3):
            for dx in range(3):
                if dz == dy == dx == 1:
                    continue
                acc += v[dz:dz + nz, dy:dy + ny, dx:dx + nx]
                count += w[dz:dz + nz, dy:dy + ny, dx:dx + nx]
    return np.where(count[..., None] > 0, acc / np.maximum(count, 1.0)[..., None],
                    np.float32(0.0)).astype(np.float32)


def relative_residual(residual2: float, source2: float) -> float:
    """‖b − Aφ‖/‖b‖ from the sums of squares; 0 when there is no source at all."""
    return math.sqrt(residual2 / source2) if source2 > 0.0 else 0.0


def solve_source(q: np.ndarray, coefficients: np.ndarray, grid: Grid,
                 tolerance: float = DEFAULT_TOLERANCE, max_sweeps: int = 200000,
                 phi: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Jacobi sweeps from ``phi`` (default 0) until the relative residual is below
    ``tolerance``: (φ, sweeps). A reference solve for tests and the bench."""
    phi = np.zeros_like(q) if phi is None else phi
    for sweep in range(1, max_sweeps + 1):
        new, r2, q2 = jacobi_sweep(phi, q, coefficients, grid)
        if relative_residual(r2, q2) < tolerance:
            return phi, sweep - 1
        phi = new
    return phi, max_sweeps


# -- the upwind convection's steady state (KD's former warm start), the exact march -------------
def steady_convection_sweep(rho: np.ndarray, sigma_a: np.ndarray, u: np.ndarray, grid: Grid,
                            source: np.ndarray | None = None) -> np.ndarray:
    """One sweep of the *steady state* of the split upwind convection (plugins'
    ``convection_step``): ρ = (1 − σ_a)·½ Σ_a c_a ρ_upwind,a / (1 − (1 − σ_a)(1 − ½ Σ_a c_a)).
    Each voxel depends only on its upwind neighbours, so ``nx + ny + nz`` sweeps from any start
    give the converged convected light exactly (a propagation pass, as the shadow volume's)."""
    ratio = grid.axis_ratios
    upwind_sum = np.zeros_like(rho)
    c_sum = np.zeros_like(rho)
    for axis_xyz, array_axis in ((0, 2), (1, 1), (2, 0)):
        ua = np.broadcast_to(u[axis_xyz], rho.shape)
        c = np.abs(ua) * ratio[axis_xyz]
        before = shifted(rho, array_axis, +1, fill=1.0)
        after = shifted(rho, array_axis, -1, fill=1.0)
        upwind_sum += c * np.where(ua > 0, before, after)
        c_sum += c
    keep = np.float32(1.0) - sigma_a
    half = np.float32(0.5)
    out = keep * half * upwind_sum / (np.float32(1.0) - keep * (np.float32(1.0) - half * c_sum))
    if source is not None:
        out[source] = 1.0
    return out.astype(np.float32)


#: March step of :func:`marched_transmittance`, in smallest voxel edges.
MARCH_STEP_EDGES = 0.5


def _trilinear(field: np.ndarray, grid: Grid, px: np.ndarray, py: np.ndarray,
               pz: np.ndarray) -> np.ndarray:
    """``field`` (``[z, y, x]``) interpolated at dataset positions (µm), clamped to the box of
    voxel centres — as ``march.comp.glsl``'s ``sigmaAt``."""
    nz, ny, nx = field.shape
    coords = []
    for p, o, s, n in zip((px, py, pz), grid.origin, grid.spacing, (nx, ny, nz), strict=True):
        f = np.clip((p - np.float32(o)) / np.float32(s), np.float32(0), np.float32(n - 1))
        i0 = np.minimum(np.floor(f), np.float32(max(n - 2, 0))).astype(np.int64)
        coords.append((i0, np.minimum(i0 + 1, n - 1), (f - i0).astype(np.float32)))
    (x0, x1, wx), (y0, y1, wy), (z0, z1, wz) = coords

    def lerp(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
        return a + (b - a) * w

    c0 = lerp(lerp(field[z0, y0, x0], field[z0, y0, x1], wx),
              lerp(field[z0, y1, x0], field[z0, y1, x1], wx), wy)
    c1 = lerp(lerp(field[z1, y0, x0], field[z1, y0, x1], wx),
              lerp(field[z1, y1, x0], field[z1, y1, x1], wx), wy)
    return lerp(c0, c1, wz)


def marched_transmittance(sigma_t: np.ndarray, grid: Grid, light: LightSource,
                          unit_distance: float, step: float = MARCH_STEP_EDGES) -> np.ndarray:
    """The exact direct light's transmittance at every voxel centre towards the ideal
    ``light``, ``[z, y, x]`` float32 in (0, 1]: exp(−∫σ_t ds) along the straight ray to the
    light, σ_t (per µm) that of the trilinearly interpolated opacity α = 1 − exp(−σ_t·u)
    (``unit_distance`` u µm, as the renderer and the exact reference interpolate), up to
    where the ray leaves the box of voxel centres (directional) or reaches the light (point).
    Midpoint rule with n = ⌈length/(step·h)⌉ equal steps per ray (h the smallest voxel edge,
    no partial step). The source model's direct light (KD's warm start): unlike the upwind
    convection's steady state it does not smear a shadow edge that is oblique to the grid
    axes. ``march.comp.glsl`` is its GPU twin."""
    f = np.float32
    x, y, z = (np.broadcast_to(c, grid.shape_zyx).astype(f).ravel() for c in grid.centres())
    if light.kind == "point":
        d = np.stack([np.full_like(x, f(c)) for c in light.vector]) - np.stack([x, y, z])
        dist = np.sqrt((d * d).sum(axis=0))
        d = d / np.maximum(dist, f(1e-12))
    else:
        u = np.asarray(light.vector, np.float64)
        u = (u / max(float(np.linalg.norm(u)), 1e-30)).astype(f)
        d = np.broadcast_to(u.reshape(3, 1), (3, x.size)).astype(f)
        dist = np.full_like(x, f(np.inf))
    exit_t = np.full_like(x, f(np.inf))
    for p, da, o, s, n in zip((x, y, z), d, grid.origin, grid.spacing, grid.shape_zyx[::-1],
                              strict=True):
        lo = f(o)
        hi = lo + f(s) * f(n - 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(da > 0, (hi - p) / da, np.where(da < 0, (lo - p) / da, np.inf))
        exit_t = np.minimum(exit_t, t.astype(f))
    length = np.minimum(np.maximum(exit_t, f(0.0)), dist)
    ds = f(step * min(grid.spacing))
    steps = np.ceil(length / ds).astype(np.int64)
    h = np.where(steps > 0, length / np.maximum(steps, 1).astype(f), f(0.0)).astype(f)
    alpha = (-np.expm1(-np.asarray(sigma_t, np.float64) * unit_distance)).astype(f)
    tau = np.zeros_like(x)
    for k in range(int(steps.max(initial=0))):
        live = steps > k
        t = (f(k) + f(0.5)) * h[live]
        a = _trilinear(alpha, grid, x[live] + t * d[0, live], y[live] + t * d[1, live],
                       z[live] + t * d[2, live])
        tau[live] += h[live] * -np.log1p(-np.minimum(a, f(MAX_OPACITY))) / f(unit_distance)
    return np.exp(-tau).astype(f).reshape(grid.shape_zyx)


def propagation_sweeps(grid: Grid) -> int:
    """Sweeps after which :func:`steady_convection_sweep` has converged: the longest upwind
    chain, nx + ny + nz."""
    return int(sum(grid.shape_zyx))


# -- GPU drivers and the technique base -----------------------------------------------------------
def light_channels(count: int) -> int:
    """Texture channels that hold ``count`` lights (1, 2 or 4)."""
    return 1 if count <= 1 else (2 if count == 2 else 4)


class GridScattering(Technique):
    """What seed 003's two methods share: progressive light on the data grid with a GPU
    (``ComputePath``) and a numpy path, shown through two textures — the direct light and the
    scattered light — bound under ``vv_<NAME>_direct`` and ``vv_<NAME>_scattered`` (the names
    the technique's shader samples); their counters in ``stats()``.

    The frame loop is here: :meth:`prepare` restarts the accumulation when
    ``Changes.reset_accumulation`` says so (:meth:`_restart`: a new :meth:`build_setup`, the
    counters zeroed, the GPU driver reset or the numpy state made), then runs the subclass's
    :meth:`advance` (this frame's iterations; it sets ``converged``) and binds what is shown.
    """

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._compute = ComputePath(self.NAME, self.make_driver)
        self._direct: Texture3D | None = None  # numpy path: what the shader samples
        self._scattered: Texture3D | None = None
        self._restarts = 0
        self._backend = ""
        self._last_ms = 0.0
        #: What the current accumulation runs on (the subclass's ``build_setup``); None before.
        self.setup: Any = None
        #: Source model: relative residual of the scattered light's equation (inf before).
        self.residual = float("inf")

    # -- what a subclass provides -------------------------------------------------------------
    def make_driver(self, window: vtk.vtkRenderWindow) -> Any:
        """The GPU driver (compute programs and textures) of this technique; its ``shown`` is
        the (direct, scattered) texture pair the shader samples."""
        raise NotImplementedError

    def build_setup(self, grid: Grid, sigma_t: np.ndarray, values: Mapping[str, Any]) -> Any:
        """What one accumulation runs on, for the host's data ``grid`` (µm) and extinction
        ``sigma_t`` (per µm, ``[z, y, x]``)."""
        raise NotImplementedError

    def start_gpu(self, gpu: Any, values: Mapping[str, Any]) -> None:
        """Reset the GPU driver for :attr:`setup` (may raise ``GLUnavailableError``)."""
        raise NotImplementedError

    def start_cpu(self, values: Mapping[str, Any]) -> None:
        """Make the numpy path's state for :attr:`setup` and upload it for display."""
        raise NotImplementedError

    def advance(self, values: Mapping[str, Any]) -> None:
        """This frame's iterations on the current path; sets ``converged``."""
        raise NotImplementedError

    # -- the shared loop ----------------------------------------------------------------------
    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        if changes.reset_accumulation or self.setup is None:
            self._restart(values)
        self.advance(values)
        gpu = self._gpu
        self._bind(gpu.shown if gpu is not None else None)

    def _restart(self, values: Mapping[str, Any]) -> None:
        """A new accumulation from the host's current opacity, lights and parameters: on the
        GPU when the ``backend`` allows it (numpy for good after a GL failure), else numpy."""
        nx, ny, nz = self.host.dims
        grid = Grid((nz, ny, nx), self.host.spacing, self._origin())
        sigma_t = extinction(self.host.opacity_volume(), self.host.unit_distance)
        self.setup = self.build_setup(grid, sigma_t, values)
        self.iteration = 0
        self.residual = float("inf")
        self.converged = False
        self._restarts += 1
        gpu = self._compute.get(self.host, values["backend"])
        if gpu is not None:
            try:
                self.start_gpu(gpu, values)
                self._backend = "gpu"
                return
            except GLUnavailableError as exc:
                self._compute.disable(exc)
        self.start_cpu(values)
        self._backend = "cpu"

    @property
    def _gpu(self) -> Any:
        return self._compute.driver

    def _bind(self, gpu_textures: tuple[Texture3D, Texture3D] | None) -> None:
        """Bind the GPU path's (direct, scattered) textures, or the numpy path's."""
        direct, scattered = gpu_textures or (self._direct, self._scattered)
        assert direct is not None and scattered is not None
        self.host.bind_texture(f"vv_{self.NAME}_direct", direct)
        self.host.bind_texture(f"vv_{self.NAME}_scattered", scattered)

    def _show(self, texture: Texture3D | None, data: np.ndarray, channels: int) -> Texture3D:
        """``texture`` holding ``data`` (``[z, y, x(, channels)]``): uploaded into it, or a new
        texture when there is none or its shape or channel count differs (``texture`` is then
        released)."""
        shape = data.shape[:3]
        if texture is None or texture.shape != shape or texture.channels != channels:
            if texture is not None:
                texture.release()
            return Texture3D(self.host.render_window, shape, channels=channels, data=data)
        texture.upload(data)
        return texture

    def stats(self) -> TechniqueStats:
        """Restarts as ``recomputes``; ``recompute_ms``: milliseconds of the last frame's
        iterations; ``extra``: the source model's relative ``residual``."""
        textures = [self._direct, self._scattered]
        if self._gpu is not None:
            textures += self._gpu.textures
        return TechniqueStats(
            recomputes=self._restarts, recompute_ms=self._last_ms, backend=self._backend,
            texture_bytes=sum(t.nbytes for t in textures if t is not None),
            iterations=self.iteration, extra={"residual": self.residual})

    def release(self) -> None:
        for tex in (self._direct, self._scattered):
            if tex is not None:
                tex.release()
        self._direct = self._scattered = None
        self._compute.release()
        self.setup = None

    def _origin(self) -> tuple[float, float, float]:
        return tuple(float(o) for o in self.host.image.GetOrigin())  # type: ignore[return-value]


def dispatch_groups(grid: Grid) -> tuple[int, int, int]:
    """Work groups of :data:`GROUP` that cover ``grid`` (x, y, z)."""
    nz, ny, nx = grid.shape_zyx
    return (-(-nx // GROUP[0]), -(-ny // GROUP[1]), -(-nz // GROUP[2]))


def fits(texture: Texture3D | None, shape_zyx: tuple[int, int, int], channels: int) -> bool:
    """``texture`` exists with this shape and channel count (:func:`storage` keeps it)."""
    return (texture is not None and texture.shape == tuple(shape_zyx)
            and texture.channels == channels)


def storage(texture: Texture3D | None, render_window: vtk.vtkRenderWindow,
            shape_zyx: tuple[int, int, int], channels: int, *, zero: bool = False) -> Texture3D:
    """``texture`` when it already has ``shape_zyx`` and ``channels`` (a restart on the same
    grid keeps its storage: no reallocation), else a new one (``texture`` released); zeroed
    on the GPU with ``zero``. Left unbound from texture units (compute uses image units)."""
    if not fits(texture, shape_zyx, channels):
        if texture is not None:
            texture.release()
        texture = Texture3D(render_window, shape_zyx, channels=channels)
        texture.tex.Deactivate()  # allocated bound to a unit; image units are separate
    if zero:
        texture.clear()
    return texture


class GridPrograms:
    """One diffusion compute shader (``SHADER``), compiled once per light-channel count, and
    the dispatch loop its drivers share: image units bound, sweeps ping-ponged between two
    textures, units detached after the last dispatch."""

    SHADER: ClassVar[str]
    LABEL: ClassVar[str]

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[int, ComputeProgram] = {}

    def program(self, channels: int) -> ComputeProgram:
        prog = self._programs.get(channels)
        if prog is None:
            source = compute_source(self.SHADER, {"VV_CHANNELS": str(channels)})
            prog = ComputeProgram(self.render_window, source, self.LABEL)
            self._programs[channels] = prog
        return prog

    @staticmethod
    def bind(prog: ComputeProgram, grid: Grid, images: Sequence[tuple[str, Texture3D | None]],
             *, weights: bool = False, placement: bool = False) -> None:
        """Use ``prog``: image uniform ``name`` i on unit i (its texture bound for reading
        when given; None: bound per sweep), ``vv_dims``, the axis ``vv_weights`` and/or
        the grid's ``vv_origin`` and ``vv_spacing`` (µm)."""
        prog.use()
        for unit, (name, texture) in enumerate(images):
            prog.set_uniform(name, unit)
            if texture is not None:
                texture.bind_image(unit, "read")
        nz, ny, nx = grid.shape_zyx
        prog.set_uniform("vv_dims", nx, ny, nz)
        if weights:
            prog.set_uniform("vv_weights", *grid.axis_weights.tolist(), kind="f")
        if placement:
            prog.set_uniform("vv_origin", *grid.origin, kind="f")
            prog.set_uniform("vv_spacing", *grid.spacing, kind="f")

    def sweep(self, prog: ComputeProgram, grid: Grid, pair: list[Texture3D],
              units: tuple[int, int], count: int, bound: int) -> None:
        """``count`` dispatches over ``grid``, each reading ``pair[0]`` on ``units[0]`` and
        writing ``pair[1]`` on ``units[1]``, the two swapped after each (``pair[0]`` holds
        the result); then image units 0…``bound``−1 are detached and the program released."""
        groups = dispatch_groups(grid)
        for _ in range(count):
            pair[0].bind_image(units[0], "read")
            pair[1].bind_image(units[1], "write")
            prog.dispatch(groups)
            pair.reverse()
        unbind_images(self.render_window, bound)
        prog.done()

    def release(self) -> None:
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()


def _colours_uniforms(prog: ComputeProgram, colors: Sequence[tuple[float, float, float]]
                      ) -> None:
    """``vv_numLights`` and the lights' RGB ``vv_color[4]`` (unused entries 0)."""
    flat = [c for color in colors for c in color]
    prog.set_uniform("vv_numLights", len(colors))
    prog.set_uniform_array("vv_color", flat + [0.0] * (12 - len(flat)), size=3)


class GpuDiffusion(GridPrograms):
    """The diffusion step on the GPU (``diffusion.comp.glsl``): ρ_s ping-pongs between two RGBA
    textures; the direct light comes from a texture of up to four channels weighted by RGB
    colours. Also used by the hybrid method (seed 003 HD), which shares KD's diffusion."""

    SHADER = "diffusion.comp.glsl"
    LABEL = "diffusion"

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        super().__init__(render_window)
        self._rho_s: list[Texture3D] = []
        self._lam: Texture3D | None = None
        self._grid = Grid((1, 1, 1), (1.0, 1.0, 1.0))
        self._channels = 1

    @property
    def rho_s(self) -> Texture3D:
        return self._rho_s[0]

    @property
    def textures(self) -> list[Texture3D]:
        return [*self._rho_s, *(t for t in (self._lam,) if t)]

    def reset(self, grid: Grid, lam: np.ndarray, channels: int) -> None:
        """Zero ρ_s on ``grid`` with diffusion rate ``lam``; the direct light will have
        ``channels`` channels."""
        self._release_textures()
        rw = self.render_window
        empty = np.zeros((*grid.shape_zyx, 4), np.float32)
        self._rho_s = [Texture3D(rw, grid.shape_zyx, channels=4, data=empty) for _ in range(2)]
        self._lam = Texture3D(rw, grid.shape_zyx, data=lam)
        for tex in self.textures:
            tex.tex.Deactivate()  # created bound to units; image units are separate
        self._grid, self._channels = grid, channels

    def run(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
            steps: int) -> None:
        """``steps`` diffusion steps of Σ_l colors[l]·direct[l] + ρ_s into ρ_s."""
        prog = self.program(self._channels)
        self.bind(prog, self._grid, (("vv_direct", direct), ("vv_scatteredIn", None),
                                     ("vv_scatteredOut", None), ("vv_lambda", self._lam)),
                  weights=True)
        _colours_uniforms(prog, colors)
        self.sweep(prog, self._grid, self._rho_s, (1, 2), steps, bound=4)

    def _release_textures(self) -> None:
        for tex in self.textures:
            tex.release()
        self._rho_s = []
        self._lam = None

    def release(self) -> None:
        self._release_textures()
        super().release()


class GpuSourceDiffusion(GridPrograms):
    """The source model on the GPU (``source_diffusion.comp.glsl``): φ ping-pongs between two
    RGBA textures; the per-point coefficients are one RGBA texture; each sweep also writes the
    per-point squared residual and source, read back (once per frame) for the stopping test.

    On a reduced grid (a coarse :class:`~vtkvol.engine.coarse_diffusion.ScatterGrid`) φ, the
    coefficients and the residual live on the coarse cells; :meth:`run` restricts q = σ_s·E_0
    from the data grid's direct light into a coarse source texture (``source_restrict.comp.glsl``)
    when the direct light changed, and the sweeps read it (``VV_SOURCE_IMAGE``)."""

    SHADER = "source_diffusion.comp.glsl"
    LABEL = "source diffusion"

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        super().__init__(render_window)
        self._phi: list[Texture3D] = []
        self._coefficients: Texture3D | None = None
        self._residual: Texture3D | None = None
        self._source: Texture3D | None = None  # reduced grid: the restricted q
        self._sigma_s: Texture3D | None = None  # reduced grid: σ_s on the data grid
        self._grid = Grid((1, 1, 1), (1.0, 1.0, 1.0))
        self._scatter: ReducedGrid | None = None
        self._channels = 1
        self._falloff: list[float] = [0.0] * 16
        self._variants: dict[tuple[str, int, bool], ComputeProgram] = {}
        self._restricted = False  # reduced grid: the source texture holds the current q

    @property
    def phi(self) -> Texture3D:
        return self._phi[0]

    @property
    def coefficients(self) -> Texture3D | None:
        """The per-voxel coefficients' texture (None before the first restart)."""
        return self._coefficients

    @property
    def textures(self) -> list[Texture3D]:
        return [*self._phi, *(t for t in (self._coefficients, self._residual, self._source,
                                          self._sigma_s) if t)]

    def variant(self, shader: str, channels: int, source_image: bool = False) -> ComputeProgram:
        """``shader`` compiled for ``channels`` lights (and ``VV_SOURCE_IMAGE``), once."""
        key = (shader, channels, source_image)
        prog = self._variants.get(key)
        if prog is None:
            defines = {"VV_CHANNELS": str(channels), "VV_SOURCE_IMAGE": str(int(source_image))}
            prog = ComputeProgram(self.render_window, compute_source(shader, defines),
                                  f"{self.LABEL} {key}")
            self._variants[key] = prog
        return prog

    def reset(self, grid: Grid, coefficients: np.ndarray, channels: int,
              lights: Sequence[LightSource], scatter: ReducedGrid | None = None,
              fine_sigma_s: np.ndarray | None = None) -> None:
        """Zero φ; the direct light will have ``channels`` channels on the data ``grid``, one
        per light of ``lights`` (their fall-off applies to the source). ``coefficients`` are
        those of the grid φ is solved on: ``grid``'s, or with a coarse ``scatter`` its
        cells', and then ``fine_sigma_s`` (``[z, y, x]`` per µm, the data grid's σ_s, 0 where
        empty) is needed for the restriction of q."""
        self.allocate_coefficients(coefficients.shape[:3])
        self.upload_coefficients(coefficients, 0)
        self.zero(grid, channels, lights, scatter, fine_sigma_s)

    def allocate_coefficients(self, shape_zyx: tuple[int, int, int]) -> None:
        """Storage for the per-point coefficients of the grid φ is solved on, ``shape_zyx``
        (kept when it already has that shape), filled by :meth:`upload_coefficients` — a
        restart in parts."""
        self._coefficients = storage(self._coefficients, self.render_window, shape_zyx, 4)

    def upload_coefficients(self, slab: np.ndarray, z0: int) -> None:
        """Coefficients ``[z, y, x, 4]`` (:func:`source_coefficients`) of layers z0… ."""
        assert self._coefficients is not None
        self._coefficients.upload_slab(slab, z0)
        self._coefficients.tex.Deactivate()

    def allocation_steps(self, shape_zyx: tuple[int, int, int]) -> Iterator[None]:
        """New storage for φ (two textures) and the residual where the solved grid's shape
        ``shape_zyx`` differs, one texture a step (a large allocation is a large part of a
        frame); :meth:`zero` then clears them. Between the steps φ is not consistent: show
        nothing of it."""
        rw = self.render_window
        for i in range(2):
            if len(self._phi) <= i or not fits(self._phi[i], shape_zyx, 4):
                tex = storage(self._phi[i] if len(self._phi) > i else None, rw, shape_zyx, 4)
                self._phi = [*self._phi[:i], tex, *self._phi[i + 1:]]
                yield
        if not fits(self._residual, shape_zyx, 2):
            self._residual = storage(self._residual, rw, shape_zyx, 2)
            yield

    def zero(self, grid: Grid, channels: int, lights: Sequence[LightSource],
             scatter: ReducedGrid | None = None,
             fine_sigma_s: np.ndarray | None = None) -> None:
        """φ and the residual zeroed on the grid they are solved on (``grid``, or a coarse
        ``scatter``'s; storage kept when its shape is unchanged); the direct light will have
        ``channels`` channels on ``grid``, one per light of ``lights``. A coarse ``scatter``
        needs ``fine_sigma_s`` (see :meth:`reset`)."""
        rw = self.render_window
        coarse = scatter is not None and scatter.coarse
        shape = scatter.grid.shape_zyx if coarse else grid.shape_zyx  # type: ignore[union-attr]
        old = self._phi or [None, None]
        self._phi = [storage(t, rw, shape, 4, zero=True) for t in old]
        self._residual = storage(self._residual, rw, shape, 2, zero=True)
        if coarse:
            if fine_sigma_s is None:
                raise ValueError("a reduced scattered-light grid needs the data grid's sigma_s")
            self._source = storage(self._source, rw, shape, 4, zero=True)
            self._sigma_s = storage(self._sigma_s, rw, grid.shape_zyx, 1)
            self._sigma_s.upload_slab(np.ascontiguousarray(fine_sigma_s, np.float32), 0)
            self._sigma_s.tex.Deactivate()
        else:
            for tex in (self._source, self._sigma_s):
                if tex is not None:
                    tex.release()
            self._source = self._sigma_s = None
        self._grid, self._channels = grid, channels
        self._scatter = scatter if coarse else None
        self._restricted = False
        flat: list[float] = []
        for light in lights:
            d0 = float(light.falloff_distance) if light.kind == "point" else 0.0
            flat += [*(float(v) for v in light.vector), d0]
        self._falloff = flat + [0.0] * (16 - len(flat))

    def run(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
            sweeps: int, source_changed: bool = True) -> None:
        """``sweeps`` Jacobi sweeps with the source from ``direct`` × ``colors``. On a reduced
        grid q is restricted first when ``source_changed`` (the direct light changed since the
        last run) or not yet since :meth:`reset` (:meth:`restrict`)."""
        self.restrict(direct, colors, source_changed)
        prog = self._bind_sweep(direct, colors, 0)
        assert self._residual is not None
        self._residual.bind_image(4, "write")
        self.sweep(prog, self.solved_grid, self._phi, (2, 3), sweeps, bound=5)

    @property
    def solved_grid(self) -> Grid:
        """The grid φ is solved on: the data grid, or the reduced one."""
        return self._scatter.grid if self._scatter is not None else self._grid

    def restrict(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
                 source_changed: bool = True) -> None:
        """On a reduced grid: q from ``direct`` restricted into the coarse source texture
        when ``source_changed`` or not yet since :meth:`reset` (a restriction is a pass over
        the data grid, which would cost more than the coarse sweeps it feeds); nothing on the
        data grid."""
        if self._scatter is None or (self._restricted and not source_changed):
            return
        self._restrict(direct, colors, self._scatter)
        self._restricted = True

    def sweep_slab(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
                   z0: int, z1: int) -> None:
        """Layers z0…z1 (of the solved grid) of one Jacobi sweep (a sweep in bounded parts):
        they read the current φ and write the next one, so the slabs of a sweep add up to
        :meth:`run`'s sweep bit for bit; :meth:`swap` after its last slab. On a reduced grid
        :meth:`restrict` must have run since the direct light changed."""
        prog = self._bind_sweep(direct, colors, z0)
        assert self._residual is not None
        self._phi[0].bind_image(2, "read")
        self._phi[1].bind_image(3, "write")
        self._residual.bind_image(4, "write")
        groups = dispatch_groups(self.solved_grid)
        prog.dispatch((groups[0], groups[1], -(-(z1 - z0) // GROUP[2])))
        unbind_images(self.render_window, 5)
        prog.done()

    def swap(self) -> None:
        """End a sweep drawn in slabs: the φ it wrote becomes the current one."""
        self._phi.reverse()

    def _bind_sweep(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
                    z0: int) -> ComputeProgram:
        """The sweep program bound to its inputs, from layer ``z0`` of the solved grid."""
        assert self._coefficients is not None and self._residual is not None
        scatter = self._scatter
        if scatter is None:
            prog = self.variant(self.SHADER, self._channels)
            self.bind(prog, self._grid, (("vv_direct", direct),
                                         ("vv_coefficients", self._coefficients),
                                         ("vv_phiIn", None), ("vv_phiOut", None),
                                         ("vv_residual", None)), placement=True)
            _colours_uniforms(prog, colors)
            prog.set_uniform_array("vv_falloff", self._falloff, size=4)
        else:
            assert self._source is not None
            prog = self.variant(self.SHADER, 4, source_image=True)
            self.bind(prog, scatter.grid, (("vv_source", self._source),
                                           ("vv_coefficients", self._coefficients),
                                           ("vv_phiIn", None), ("vv_phiOut", None),
                                           ("vv_residual", None)))
            # vv_origin is unused on a reduced grid
            prog.set_uniform("vv_spacing", *scatter.grid.spacing, kind="f")
        prog.set_uniform("vv_zFirst", z0)
        return prog

    def _restrict(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
                  scatter: ReducedGrid) -> None:
        """q on the data grid, restricted into the coarse source texture."""
        assert self._source is not None and self._sigma_s is not None
        prog = self.variant("source_restrict.comp.glsl", self._channels)
        self.bind(prog, scatter.grid, (("vv_direct", direct), ("vv_sigmaS", self._sigma_s),
                                       ("vv_source", None)))
        nz, ny, nx = self._grid.shape_zyx
        prog.set_uniform("vv_fineDims", nx, ny, nz)
        prog.set_uniform("vv_cell", *scatter.cells_xyz, kind="f")
        prog.set_uniform("vv_origin", *self._grid.origin, kind="f")
        prog.set_uniform("vv_spacing", *self._grid.spacing, kind="f")
        _colours_uniforms(prog, colors)
        prog.set_uniform_array("vv_falloff", self._falloff, size=4)
        self._source.bind_image(2, "write")
        prog.dispatch(dispatch_groups(scatter.grid))
        unbind_images(self.render_window, 3)
        prog.done()

    def residual(self) -> tuple[float, float]:
        """(Σ residual², Σ source²) of the last sweep's starting φ."""
        assert self._residual is not None
        r = self._residual.download().astype(np.float64)
        return float(r[..., 0].sum()), float(r[..., 1].sum())

    def residual_layers(self, z0: int, z1: int) -> tuple[np.ndarray, np.ndarray]:
        """(Σ residual², Σ source²) of each z layer z0…z1 of the last sweep, float64: read
        back only those layers (a sweep in slabs reads each slab once). Summed layer by layer,
        so the totals do not depend on how a sweep was cut into slabs."""
        assert self._residual is not None
        GL = gl(self.render_window)
        _nz, ny, nx = self.solved_grid.shape_zyx
        out = np.empty((z1 - z0, ny, nx, 2), np.float32)
        GL.glMemoryBarrier(GL.GL_ALL_BARRIER_BITS)
        self.render_window.GetState().vtkglPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glGetTextureSubImage(self._residual.handle, 0, 0, 0, z0, nx, ny, z1 - z0, GL.GL_RG,
                                GL.GL_FLOAT, out.nbytes, out)
        return (out[..., 0].sum(axis=(1, 2), dtype=np.float64),
                out[..., 1].sum(axis=(1, 2), dtype=np.float64))

    def _release_textures(self) -> None:
        for tex in self.textures:
            tex.release()
        self._phi = []
        self._coefficients = self._residual = self._source = self._sigma_s = None

    def release(self) -> None:
        self._release_textures()
        for prog in self._variants.values():
            prog.release()
        self._variants.clear()
        super().release()


class GpuFieldDiffusion(GridPrograms):
    """The published model's explicit diffusion of each light's own field
    (``field_diffusion.comp.glsl``), from one texture into another of the same format."""

    SHADER = "field_diffusion.comp.glsl"
    LABEL = "field diffusion"

    def run(self, field_in: Texture3D, field_out: Texture3D, lam: Texture3D, grid: Grid,
            channels: int) -> None:
        """One step ``field_out = field_in + λ ∇²field_in`` (zero flux at the box)."""
        prog = self.program(channels)
        self.bind(prog, grid, (("vv_fieldIn", None), ("vv_fieldOut", None), ("vv_lambda", lam)),
                  weights=True)
        self.sweep(prog, grid, [field_in, field_out], (0, 1), 1, bound=3)
