"""Monte-Carlo in-scattered light (multiple scattering) with delta and ratio tracking.

Model (radiative transfer, 003_summary §3.2): extinction σ(x) from the opacity as everywhere in
this package, a constant single-scattering albedo a (σ_s = a·σ, σ_a = (1 − a)·σ; one value, or
one per colour channel for the colour shift of seed 003's Fig. 2), a Henyey–Greenstein phase
function p_g with asymmetry g (g = 0: isotropic, p = 1/4π), no emission, nothing outside the box
(no background radiance). Each light has **unit irradiance** wherever it arrives unattenuated;
a point light with ``falloff_distance`` d₀ > 0 has irradiance (d₀/r)² at distance r instead (the
host's inverse-square fall-off). Its direct contribution at x is the transmittance T_l(x) of
:func:`transmittance` (times the fall-off): the GPU techniques' illumination volumes hold
visibility, and the host applies the light's colour and fall-off when it shades.

Quantity returned. The light arriving at x, integrated over all directions (the fluence, in
units of the lights' irradiance), split by the number k of scattering events it underwent
between the light and x:

    E(x)   = Σ_k E_k(x),   E_0(x) = Σ_l T_l(x)                        (direct light)
    E_k(x) = ∫_{S²} L_k(x, −ω) dω,  L_k(x, −ω) = ∫_0^{d(ω)} T(x, x_t) · a·σ(x_t) · L_s,k(x_t, −ω) dt

with x_t = x + t·ω, d(ω) the distance to the box's exit and L_s,k the radiance of order k−1
scattered towards −ω (for isotropic scattering L_s,k = E_{k−1}/4π). The function returns
Σ_{k=min_bounces}^{max_bounces} E_k(x); the default ``min_bounces=1`` gives the in-scattered
(indirect) light only, zero in an empty volume. A renderer whose illumination volume is view
independent shades with albedo · α · E (isotropic last scattering towards the eye), which is how
the host's ``medium`` model uses the GPU multiple-scattering methods' volumes (E_0 + E_indirect):
g shapes how light travels inside the volume, the host applies it to the direct light only.

Estimator (per point x, ``n_paths`` independent paths, the result is their mean):

    vertex v_0 = x, weight w_0 = 1
    for k = 0 … max_bounces:
        if k ≥ min_bounces: score w_k · Σ_l T̂_l(v_k) · F_l(v_k) · P_k,l   (next-event estimation)
        draw ω_{k+1}: uniform on the sphere (pdf 1/4π) for k = 0, from p_g about ω_k for k ≥ 1;
        delta-track (Woodcock) from v_k along ω_{k+1} with the majorant σ̄ = max σ: tentative
        free flights t += −ln(ξ)/σ̄, accepted as a real collision with probability σ(x_t)/σ̄.
        Escape from the box ends the path; otherwise v_{k+1} = the collision point and
        w_{k+1} = a · w_k = a^{k+1} (per colour channel with an RGB albedo).

F_l is light l's fall-off (1, or (d₀/r)²), P_0,l = 1 and P_k,l = 4π·p_g(l̂·ω_k) for k ≥ 1: the
light travels along −l̂ (l̂ towards the light) and leaves towards v_{k−1}, along −ω_k. Delta
tracking samples the real-collision distance with density σ(x_t)·T(x, x_t); with the first
direction's pdf 1/4π and later ones drawn from the phase function itself, every step's weight
is a: the estimator is unbiased for E_k, with no truncation other than ``max_bounces``. T̂_l
is ratio tracking towards light l: the product of (1 − σ(x_i)/σ̄) over tentative collisions
x_i (free flights −ln(ξ)/σ̄) before the ray leaves the box or reaches a point light;
unbiased, in [0, 1]. Ratio tracking stops once the product falls below 1e-12 (bias below
1e-12). Without fall-off and with g = 0 every path's score
is bounded by n_lights · Σ_{k=min}^{max} a^k, so the result is bounded by that too (energy
bound; a forward-peaked phase function concentrates, but does not add, energy).

Random numbers come from the counter-based generator of :mod:`vtkvol.reference.sampling`, keyed
on seed, point coordinates, path number, bounce and purpose: deterministic, chunk-independent,
and identical for a voxel whether it is evaluated in the full volume or in a ``points=`` subset.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vtkvol.reference.lights import Light, PointLight, as_light_list, light_rays
from vtkvol.reference.raymarch import (
    EvalPoints,
    ExtinctionField,
    as_field,
    check_count,
    clip_to_box,
)
from vtkvol.reference.sampling import (
    around,
    point_keys,
    stream_keys,
    tagged,
    uniform,
    uniform_sphere,
)

#: Paths simulated together; each carries ~10 float64/uint64 values per array it lives in.
PATH_CHUNK = 1 << 15

#: Ratio tracking retires a ray once its transmittance estimate is below this.
RATIO_CUTOFF = 1e-12

# Purpose tags of the random streams (combined with the bounce number and light index).
_DIRECTION, _FLIGHT, _SHADOW = 1, 2, 3


def _tag(purpose: int, bounce: int, light: int = 0) -> int:
    return purpose | (light << 8) | (bounce << 24)


def inscattered_mc(
    opacity: np.ndarray,
    spacing: Sequence[float],
    lights: Light | Sequence[Light],
    *,
    albedo: float | Sequence[float] = 0.9,
    phase_g: float = 0.0,
    n_paths: int = 64,
    seed: int = 0,
    unit_distance: float | None = None,
    max_bounces: int = 16,
    min_bounces: int = 1,
    points: np.ndarray | None = None,
    light_colors: Sequence[Sequence[float]] | None = None,
) -> np.ndarray:
    """Monte-Carlo in-scattered light per voxel centre (or per point); see the module docstring.

    Parameters
    ----------
    opacity
        Transfer-function opacity α ∈ [0, 1] per voxel, ``[z, y, x]``, or an
        :class:`~vtkvol.reference.raymarch.ExtinctionField` (then ``spacing`` and
        ``unit_distance`` are the field's), e.g. one classified after interpolation.
    spacing
        Voxel edge (x, y, z) in µm.
    lights
        One light or a sequence of :class:`DirectionalLight` / :class:`PointLight`, each of unit
        irradiance (directional: arriving from ``direction``; point: unit irradiance everywhere,
        or (d₀/r)² with its ``falloff_distance`` d₀).
    albedo
        Single-scattering albedo a = σ_s/σ ∈ [0, 1], constant over the volume: one value, or
        three (R, G, B), which makes the result RGB.
    phase_g
        Henyey–Greenstein asymmetry g ∈ (−1, 1): 0 isotropic, > 0 forward scattering.
    n_paths
        Paths per point; the result is their mean.
    seed
        Seed of the counter-based generator.
    unit_distance
        Thickness in µm of the slab whose opacity α is; default the smallest voxel edge.
    max_bounces, min_bounces
        Scattering orders included: light that scattered k times between the light and the
        point, min_bounces ≤ k ≤ max_bounces. The default (1, 16) is the indirect light;
        (0, 0) is the direct light Σ_l T_l estimated by ratio tracking; (1, 1) is light
        scattered exactly once.
    points
        Optional world positions (N, 3) in µm, order (x, y, z), instead of every voxel centre.
    light_colors
        Optional (R, G, B) irradiance of each light (≥ 0) instead of unit white lights; makes
        the result RGB.

    Returns
    -------
    float32 light in units of the lights' irradiance (≥ 0; without fall-off and with g = 0 at
    most n_lights · Σ_{k=min_bounces}^{max_bounces} albedo^k): ``[z, y, x]``, or (N,) with
    ``points``; a trailing axis of 3 with an RGB albedo or light colours.
    """
    light_list = as_light_list(lights)
    albedo_rgb = np.atleast_1d(np.asarray(albedo, dtype=np.float64))
    if albedo_rgb.shape not in ((1,), (3,)) or not np.all((albedo_rgb >= 0) & (albedo_rgb <= 1)):
        raise ValueError(f"albedo {albedo} must be one value or three (R, G, B) in [0, 1]")
    if not (-1.0 < float(phase_g) < 1.0):
        raise ValueError(f"phase_g {phase_g} must be in (-1, 1)")
    g = float(phase_g)
    colors = np.ones((len(light_list), 1))
    if light_colors is not None:
        colors = np.asarray(light_colors, dtype=np.float64)
        if colors.shape != (len(light_list), 3) or not np.all(np.isfinite(colors) & (colors >= 0)):
            raise ValueError("light_colors must give one finite, non-negative (R, G, B) per light")
    channels = max(albedo_rgb.size, colors.shape[1])
    albedo_rgb = np.broadcast_to(albedo_rgb, (channels,))
    colors = np.broadcast_to(colors, (len(light_list), channels))
    n_paths = check_count(n_paths, "n_paths")
    if int(min_bounces) != min_bounces or int(max_bounces) != max_bounces or min_bounces < 0:
        raise ValueError("min_bounces and max_bounces must be integers >= 0")
    field = as_field(opacity, spacing, unit_distance)
    where = EvalPoints.of(field, points)
    out = np.zeros((where.n, channels))
    if max_bounces >= min_bounces:
        for start, stop, pts in where.chunks(max(1, PATH_CHUNK // n_paths)):
            out[start:stop] = _paths(field, pts, light_list, colors, albedo_rgb, g, n_paths,
                                     seed, int(min_bounces), int(max_bounces))
    if channels == 1:
        return where.finish(out[:, 0])
    return np.stack([where.finish(out[:, c]) for c in range(channels)], axis=-1)


def _paths(field: ExtinctionField, pts: np.ndarray, light_list: Sequence[Light],
           colors: np.ndarray, albedo: np.ndarray, g: float, n_paths: int, seed: int,
           min_bounces: int, max_bounces: int) -> np.ndarray:
    """The mean score of ``n_paths`` paths from each of ``pts`` (M, 3): (M, channels);
    ``colors`` (lights, channels) weighs each light, ``albedo`` (channels,) each bounce."""
    m = pts.shape[0]
    owner = np.repeat(np.arange(m), n_paths)
    keys = stream_keys(np.repeat(point_keys(pts, seed), n_paths), np.tile(np.arange(n_paths), m))
    pos = np.repeat(pts, n_paths, axis=0)
    travel = np.zeros_like(pos)  # ω_k: the direction the path took to reach pos (k ≥ 1)
    acc = np.zeros((m, albedo.size))
    weight = np.ones(albedo.size)
    for k in range(max_bounces + 1):
        if k >= min_bounces:
            score = np.zeros((pos.shape[0], albedo.size))
            for li, light in enumerate(light_list):
                dirs, t_end = light_rays(pos, light)
                contribution = ratio_tracking(
                    field, pos, dirs, t_end, tagged(keys, _tag(_SHADOW, k, li))
                ) * falloff(light, t_end)
                if k >= 1 and g != 0.0:
                    contribution *= hg_4pi(np.einsum("ij,ij->i", dirs, travel), g)
                score += contribution[:, None] * colors[li]
            for c in range(albedo.size):
                acc[:, c] += np.bincount(owner, weights=weight[c] * score[:, c], minlength=m)
        weight = weight * albedo
        if k == max_bounces or not weight.any():
            break  # no further order can contribute
        dk = tagged(keys, _tag(_DIRECTION, k))
        if k == 0 or g == 0.0:
            dirs = uniform_sphere(uniform(dk, 0), uniform(dk, 1))
        else:
            dirs = around(travel, hg_cosine(uniform(dk, 0), g), 2.0 * np.pi * uniform(dk, 1))
        hit, t = delta_tracking(field, pos, dirs, tagged(keys, _tag(_FLIGHT, k)))
        keep = np.flatnonzero(hit)
        if keep.size == 0:
            break
        pos = pos[keep] + t[keep, None] * dirs[keep]
        travel = dirs[keep]
        keys, owner = keys[keep], owner[keep]
    return acc / n_paths


def hg_4pi(cos_theta: np.ndarray, g: float) -> np.ndarray:
    """4π times the Henyey–Greenstein phase function (1 for g = 0), as the host's
    ``vv_phase4pi``: (1 − g²) / (1 + g² − 2g·cos θ)^{3/2}."""
    denom = 1.0 + g * g - 2.0 * g * np.asarray(cos_theta, dtype=np.float64)
    return (1.0 - g * g) / (denom * np.sqrt(denom))


def hg_cosine(u: np.ndarray, g: float) -> np.ndarray:
    """cos θ distributed as the Henyey–Greenstein phase function, from uniform numbers ``u``
    (inversion of its CDF; g = 0 gives 1 − 2u, uniform)."""
    if abs(g) < 1e-6:
        return 1.0 - 2.0 * u
    s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    return np.clip((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0)


def falloff(light: Light, distance: np.ndarray) -> np.ndarray | float:
    """Irradiance factor of ``light`` at ``distance`` µm: (d₀/r)² for a point light with a
    fall-off distance d₀ > 0 (as the host's ``vv_lightColor``), otherwise 1."""
    d0 = getattr(light, "falloff_distance", 0.0)
    if not isinstance(light, PointLight) or d0 <= 0.0:
        return 1.0
    return (d0 * d0) / np.maximum(distance * distance, 1e-12)


def delta_tracking(
    field: ExtinctionField, origins: np.ndarray, directions: np.ndarray, keys: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance to the first real collision along each ray (Woodcock / delta tracking).

    ``origins`` and unit ``directions`` are world (M, 3); rays run until they leave the box.
    Returns ``(hit, t)``: whether a real collision happened inside the box and its distance in
    µm (undefined where not hit). Draw 2i of a key is the i-th free flight, draw 2i+1 its
    acceptance test.
    """
    m = origins.shape[0]
    hit = np.zeros(m, dtype=bool)
    t_hit = np.zeros(m)
    maj = field.majorant
    t0, t1 = clip_to_box(origins, directions, 0.0, np.inf, field.box_max)
    idx = np.flatnonzero(t1 > t0)
    if maj <= 0.0 or idx.size == 0:
        return hit, t_hit
    rays = _Rays(field, origins, directions, idx, t0, t1, keys)
    i = 0
    while rays.live_count():
        rays.t -= np.log(uniform(rays.key, 2 * i)) / maj
        rays.live &= rays.t < rays.tend
        real = rays.live & (uniform(rays.key, 2 * i + 1) * maj < rays.sigma())
        hit[rays.idx[real]] = True
        t_hit[rays.idx[real]] = rays.t[real]
        rays.live &= ~real
        if rays.refresh():
            rays.compact()
        i += 1
    return hit, t_hit


def ratio_tracking(
    field: ExtinctionField,
    origins: np.ndarray,
    directions: np.ndarray,
    t_end: np.ndarray,
    keys: np.ndarray,
) -> np.ndarray:
    """Unbiased transmittance estimate along origin + t·direction, t ∈ [0, t_end] ∩ box.

    Ratio tracking: T̂ = Π (1 − σ(x_i)/σ̄) over tentative collisions with the majorant σ̄ = max σ;
    the i-th free flight uses draw i of each key. ``t_end`` in µm (``inf`` for a directional
    light). Returns (M,) float64 in [0, 1].
    """
    out = np.ones(origins.shape[0])
    maj = field.majorant
    t0, t1 = clip_to_box(origins, directions, 0.0, t_end, field.box_max)
    idx = np.flatnonzero(t1 > t0)
    if maj <= 0.0 or idx.size == 0:
        return out
    rays = _Rays(field, origins, directions, idx, t0, t1, keys)
    rays.extra = np.ones(idx.size)  # the running transmittance estimate
    i = 0
    while rays.live_count():
        rays.t -= np.log(uniform(rays.key, i)) / maj
        rays.live &= rays.t < rays.tend
        # σ ≤ σ̄ holds for the trilinear interpolant; the clamp only absorbs rounding.
        factor = np.maximum(0.0, 1.0 - rays.sigma() / maj)
        rays.extra *= np.where(rays.live, factor, 1.0)
        rays.live &= rays.extra > RATIO_CUTOFF
        if rays.refresh():
            out[rays.idx] = rays.extra  # finished rays are about to leave the arrays
            rays.compact()
        i += 1
    out[rays.idx] = rays.extra
    return out


class _Rays:
    """Lock-step state of the tracked rays, compacted lazily.

    Finished rays are only flagged (``live`` False) and dropped once fewer than half the entries
    are live: compacting a dozen arrays every iteration would cost more than sampling the dead
    ones. Dead rays are sampled at their segment end, which is inside the box.
    """

    def __init__(
        self,
        field: ExtinctionField,
        origins: np.ndarray,
        directions: np.ndarray,
        idx: np.ndarray,
        t0: np.ndarray,
        t1: np.ndarray,
        keys: np.ndarray,
    ) -> None:
        self.field = field
        inv_s = 1.0 / field.spacing
        self.idx = idx
        self.o = (origins[idx] * inv_s).T.copy()  # index space, rows x, y, z
        self.d = (directions[idx] * inv_s).T.copy()
        self.t = t0[idx].copy()
        self.tend = t1[idx]
        self.key = keys[idx]
        self.extra = np.zeros(0)
        self.live = np.ones(idx.size, dtype=bool)
        self._n_live = idx.size

    def live_count(self) -> int:
        return self._n_live

    def sigma(self) -> np.ndarray:
        """σ at the current positions (clamped to the segment end for finished rays)."""
        t = np.minimum(self.t, self.tend)
        o, d = self.o, self.d
        return self.field.sample_index(o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2])

    def refresh(self) -> bool:
        """Count the live rays; True when compaction is due (fewer than half are live)."""
        self._n_live = int(np.count_nonzero(self.live))
        return 2 * self._n_live < self.live.size

    def compact(self) -> None:
        """Drop the finished rays from every array."""
        keep = self.live
        self.idx, self.t, self.tend, self.key = (
            self.idx[keep],
            self.t[keep],
            self.tend[keep],
            self.key[keep],
        )
        self.o, self.d = self.o[:, keep], self.d[:, keep]
        if self.extra.size:
            self.extra = self.extra[keep]
        self.live = np.ones(self._n_live, dtype=bool)
