"""The object-space reference without its grid: the host's medium model integrated along
camera rays, with the reference's light evaluated exactly where each ray samples it.

Why (issue 23, docs/benchmarks.md "The two truths at seeded pixels"): the bench's reference
stores the direct and in-scattered light at voxel centres and VTK's ray caster interpolates them
trilinearly at 0.5-voxel steps through pixel centres. That discretisation is a bias of up to
several dB against the camera path tracer (:mod:`vtkvol.reference.camera_paths`), which
integrates the continuous medium over each pixel. Here the same estimators —
:func:`~vtkvol.reference.transmittance.extended_transmittance` for each light's visibility over
its extent and :func:`~vtkvol.reference.scattering.inscattered_mc` for the in-scattered light —
are evaluated at points drawn along each camera ray, so no grid stands between them and the
pixel. It costs Monte-Carlo paths per *sample point*, not per voxel, so it is meant for a few
hundred seeded pixels, which is enough to test two estimators for a bias.

Estimator of one pixel (all positions world µm, the reference's frame: voxel (0, 0, 0) at the
origin; radiance in the lights' irradiance units, before the exposure):

* a camera ray through a point stratified in the pixel (the path tracer box-filters its pixel);
* its extinction σ(t) marched at ``step`` unit distances (trapezoid rule), the optical depth
  τ(t) and the coverage W = 1 − e^{−τ(t₁)} over the voxel-centre box;
* the medium model's radiance L = ∫ e^{−τ(t)} σ(t) C(x_t) dt = ∫₀^W C(x(s)) ds with
  s = 1 − e^{−τ(t)}: ``emission_points`` values of s stratified in [0, W] (one uniform draw per
  stratum), each mapped back to its t, so L ≈ W/K · Σ C(x_j) — unbiased for the marched τ;
* the shading C = a·colour·(k_a + F + Σ_l E_l·T_l(x)·4π·p_g(l·d) + S(x)) of
  ``resources/shaders/host_medium.glsl`` (``ambient`` = k_a + F; colour = 1, the bench's white
  transfer functions), with T_l the light's transmittance averaged over its extent
  (``light_rays`` stratified rays, deterministic) and S the in-scattered light
  (``scatter_paths`` Monte-Carlo paths per point, all orders up to ``max_bounces``; "single"
  orders: S = 0).

The in-scattered light is the medium model's: isotropic towards the eye and, as in the bench's
reference, next-event estimation towards each light's centre (its extent is applied to the
direct light only). For g = 0 and lights a few degrees wide the camera path tracer estimates
the same quantity.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from vtkvol.reference.lights import DirectionalLight, Light, PointLight
from vtkvol.reference.raymarch import ExtinctionField, check_count, clip_to_box
from vtkvol.reference.scattering import falloff, hg_4pi, inscattered_mc
from vtkvol.reference.transmittance import extended_transmittance

#: Rays marched together (each holds a few thousand float64 samples while it is marched).
RAY_BLOCK = 256


def pixel_rays(ndc_to_data: np.ndarray, viewport: tuple[int, int], pixels: np.ndarray,
               per_side: int, rng: np.random.Generator, origin: Sequence[float] = (0.0, 0.0, 0.0)
               ) -> tuple[np.ndarray, np.ndarray]:
    """Camera rays through ``per_side``² points stratified in each pixel (one uniform draw per
    stratum): origins on the near plane and unit directions (N, 3), world µm relative to
    ``origin`` (the dataset's origin: the references put voxel (0, 0, 0) at 0), ``per_side``²
    consecutive rays per pixel. ``pixels``: (P, 2) window pixels (x, y), bottom left first, of
    a ``viewport`` = (w, h); ``ndc_to_data``: 4 × 4 from NDC to dataset µm."""
    px = np.asarray(pixels, np.float64).reshape(-1, 2)
    k = int(per_side)
    grid = (np.stack(np.meshgrid(np.arange(k), np.arange(k), indexing="xy"), -1)
            .reshape(-1, 2).astype(np.float64))
    frag = (px[:, None, :] + (grid[None] + rng.random((px.shape[0], k * k, 2))) / k).reshape(-1, 2)
    ndc = 2.0 * frag / np.asarray(viewport, np.float64) - 1.0
    m = np.asarray(ndc_to_data, np.float64)

    def unproject(z: float) -> np.ndarray:
        q = np.c_[ndc, np.full(len(ndc), z), np.ones(len(ndc))] @ m.T
        return q[:, :3] / q[:, 3:]

    near = unproject(-1.0)
    d = unproject(1.0) - near
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return near - np.asarray(origin, np.float64), d


def reference_lights(specs: Sequence[tuple[Any, ...]], origin: Sequence[float] = (0.0, 0.0, 0.0)
                     ) -> list[tuple[Light, float, np.ndarray]]:
    """The host's lights ``(kind, vector, colour, size, falloff_distance)`` (dataset space, as
    :class:`vtkvol.engine.technique.LightSpec`: size in radians or µm) as reference lights in
    the frame relative to ``origin``: ``(light, size, colour)`` with the size as
    :func:`~vtkvol.reference.transmittance.extended_transmittance` takes it (degrees or µm)."""
    out: list[tuple[Light, float, np.ndarray]] = []
    for kind, vector, colour, size, fall in specs:
        rgb = np.broadcast_to(np.asarray(colour, np.float64), (3,)).copy()
        if kind == "point":
            pos = tuple(float(v) for v in np.asarray(vector, np.float64) - np.asarray(origin))
            out.append((PointLight(pos, falloff_distance=float(fall)),  # type: ignore[arg-type]
                        float(size), rgb))
        else:
            out.append((DirectionalLight(tuple(float(v) for v in vector)),  # type: ignore[arg-type]
                        math.degrees(float(size)), rgb))
    return out


def medium_radiance(
    field: ExtinctionField,
    origins: np.ndarray,
    directions: np.ndarray,
    lights: Sequence[tuple[Light, float, np.ndarray]],
    *,
    albedo: float,
    phase_g: float = 0.0,
    ambient: float = 0.0,
    orders: str = "multiple",
    emission_points: int = 8,
    scatter_paths: int = 64,
    light_rays: int = 32,
    step: float = 1.0 / 32.0,
    light_step: float = 0.125,
    max_bounces: int = 256,
    seed: int = 0,
) -> np.ndarray:
    """The medium model's radiance (N, 3) along each ray (see the module docstring), in the
    lights' units before the exposure. ``origins``/``directions``: (N, 3) world µm, unit
    directions; ``lights``: from :func:`reference_lights`; ``step`` and ``light_step``: the
    camera ray's and the light rays' march steps in unit distances (smallest voxel edge)."""
    if orders not in ("single", "multiple"):
        raise ValueError(f"orders {orders!r} must be 'single' or 'multiple'")
    k = check_count(emission_points, "emission_points")
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    out = np.zeros((o.shape[0], 3))
    rng = np.random.default_rng([seed, 0x5EED])
    for start in range(0, o.shape[0], RAY_BLOCK):
        sl = slice(start, start + RAY_BLOCK)
        weight, points, owner = _emission_points(field, o[sl], d[sl], k, step, rng)
        if owner.size == 0:
            continue
        light = np.full((owner.size, 3), float(ambient))
        for lt, size, rgb in lights:
            vis = extended_transmittance(field, field.spacing, lt, size=size, n_rays=light_rays,
                                         step=light_step, points=points)
            to_light = _towards(lt, points)
            dist = (np.linalg.norm(np.asarray(lt.position) - points, axis=1)
                    if isinstance(lt, PointLight) else np.inf)
            f = vis * falloff(lt, dist) * hg_4pi(np.sum(to_light * d[sl][owner], axis=1),
                                                 phase_g)
            light += f[:, None] * rgb
        if orders == "multiple":
            light += inscattered_mc(
                field, field.spacing, [lt for lt, _s, _c in lights], albedo=albedo,
                phase_g=phase_g, n_paths=scatter_paths, seed=seed, max_bounces=max_bounces,
                points=points, light_colors=[c for _l, _s, c in lights]).reshape(-1, 3)
        shaded = albedo * np.maximum(light, 0.0) * weight[:, None]
        for c in range(3):
            out[start:start + RAY_BLOCK, c] += np.bincount(owner, shaded[:, c],
                                                           minlength=o[sl].shape[0])
    return out


def _towards(light: Light, points: np.ndarray) -> np.ndarray:
    """Unit directions from ``points`` towards the light's centre."""
    if isinstance(light, PointLight):
        v = np.asarray(light.position) - points
        return v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]
    return np.broadcast_to(light.unit(), points.shape)


def _emission_points(field: ExtinctionField, o: np.ndarray, d: np.ndarray, k: int, step: float,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``k`` points per ray stratified in the ray's coverage s = 1 − e^{−τ}: their weights
    W/k (W the ray's coverage), positions (M, 3) and owning ray (M,)."""
    t0, t1 = clip_to_box(o, d, 0.0, np.inf, field.box_max)
    hit = np.flatnonzero(t1 > t0)
    if hit.size == 0 or field.majorant <= 0.0:
        return np.zeros(0), np.zeros((0, 3)), np.zeros(0, np.intp)
    h = step * field.unit_distance
    n = int(np.ceil((t1[hit] - t0[hit]).max() / h)) + 1
    ts = t0[hit, None] + h * np.arange(n)[None]
    ts = np.minimum(ts, t1[hit, None])  # the last sample sits on the exit
    inv = 1.0 / field.spacing
    c = (o[hit, None, :] + ts[..., None] * d[hit, None, :]) * inv
    c = np.clip(c, 0.0, field.box_max * inv)
    sigma = field.sample_index(c[..., 0].ravel(), c[..., 1].ravel(), c[..., 2].ravel())
    sigma = sigma.reshape(ts.shape)
    dt = np.diff(ts, axis=1)
    tau = np.concatenate([np.zeros((hit.size, 1)),
                          np.cumsum(0.5 * (sigma[:, 1:] + sigma[:, :-1]) * dt, axis=1)], axis=1)
    coverage = -np.expm1(-tau[:, -1])
    s = coverage[:, None] * (np.arange(k)[None] + rng.random((hit.size, k))) / k
    target = -np.log1p(-np.minimum(s, 1.0 - 1e-15))
    # t where the piecewise-linear τ reaches each target, one row at a time in one search:
    # rows are offset so the flattened τ stays increasing across rows.
    offset = (np.arange(hit.size) * (tau[:, -1].max() + 1.0))[:, None]
    flat = (tau + offset).ravel()
    idx = np.searchsorted(flat, (target + offset).ravel(), side="left")
    row = np.repeat(np.arange(hit.size), k)
    idx = np.clip(idx - row * n, 1, n - 1)
    lo_tau, hi_tau = tau[row, idx - 1], tau[row, idx]
    frac = np.where(hi_tau > lo_tau, (target.ravel() - lo_tau) / np.maximum(hi_tau - lo_tau,
                                                                             1e-300), 0.0)
    t = ts[row, idx - 1] + np.clip(frac, 0.0, 1.0) * (ts[row, idx] - ts[row, idx - 1])
    owner = hit[row]
    points = o[owner] + t[:, None] * d[owner]
    return np.repeat(coverage / k, k), points, owner
