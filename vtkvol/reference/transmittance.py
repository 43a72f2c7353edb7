"""Transmittance to a light: the hard-shadow reference, the cone (soft-shadow) reference and
the extended-light reference (transmittance averaged over the light's physical extent).

T(x) = exp(−∫ σ ds) along the segment from x towards the light, until it leaves the volume's box
(directional light) or reaches the light (point light). Spaces and units: see
:mod:`vtkvol.reference.raymarch` (world µm, (x, y, z) tuples, ``[z, y, x]`` arrays).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from vtkvol.reference.lights import DirectionalLight, Light, PointLight, light_rays
from vtkvol.reference.raymarch import (
    RAY_CHUNK,
    EvalPoints,
    as_field,
    check_count,
    check_distance,
    optical_depth,
    step_um,
)
from vtkvol.reference.sampling import (
    orthonormal_basis,
    point_keys,
    stream_keys,
    uniform,
    uniform_cone,
)

#: Largest angular radius (°) of a directional light, as the model clamps it
#: (``vtkvol.model.scene.Light.angular_radius_deg``).
MAX_ANGULAR_RADIUS_DEG = 45.0
#: Golden-ratio conjugate: the second coordinate of a Fibonacci lattice.
_PHI = (math.sqrt(5.0) - 1.0) / 2.0


def transmittance(
    opacity: np.ndarray,
    spacing: Sequence[float],
    light: Light,
    *,
    unit_distance: float | None = None,
    step: float = 0.25,
    points: np.ndarray | None = None,
    min_distance: float = 0.0,
) -> np.ndarray:
    """Transmittance from every voxel centre (or from each of ``points``) to ``light``.

    Parameters
    ----------
    opacity
        Transfer-function opacity α ∈ [0, 1] per voxel, ``[z, y, x]``, or an
        :class:`~vtkvol.reference.raymarch.ExtinctionField` (then ``spacing`` and
        ``unit_distance`` are the field's), e.g. one classified after interpolation.
    spacing
        Voxel edge (x, y, z) in µm.
    light
        :class:`DirectionalLight` (march until the ray leaves the box) or :class:`PointLight`
        (march until the light's position, which may be inside the box).
    unit_distance
        Thickness in µm of the slab whose opacity α is; default the smallest voxel edge.
    step
        March step in units of the smallest voxel edge (0.25 → a quarter voxel). Midpoint rule
        with a final partial step: exact where σ is linear within a step, O(step²) otherwise.
    points
        Optional world positions (N, 3) in µm, order (x, y, z), to evaluate instead of every
        voxel centre; they may lie outside the box.
    min_distance
        Skip the first ``min_distance`` µm of every ray (the self-shadowing offset the GPU
        methods use); 0, the default, is the physical transmittance.

    Returns
    -------
    float32 transmittance in [0, 1]: ``[z, y, x]``, or (N,) when ``points`` is given.
    """
    field = as_field(opacity, spacing, unit_distance)
    where = EvalPoints.of(field, points)
    t_min = check_distance(min_distance, "min_distance")
    h = step_um(field, step)
    out = np.empty(where.n)
    for start, stop, pts in where.chunks(RAY_CHUNK):
        dirs, t_end = light_rays(pts, light)
        out[start:stop] = np.exp(-optical_depth(field, pts, dirs, t_min, t_end, h))
    return where.finish(out)


def cone_transmittance_mc(
    opacity: np.ndarray,
    spacing: Sequence[float],
    light: Light,
    *,
    half_angle_deg: float,
    n_rays: int = 128,
    seed: int = 0,
    unit_distance: float | None = None,
    step: float = 0.25,
    points: np.ndarray | None = None,
    min_distance: float = 0.0,
) -> np.ndarray:
    """Mean transmittance over ``n_rays`` rays uniform (in solid angle) in a cone towards ``light``.

    The reference for cone-traced soft shadows: the light is an extended source of uniform
    radiance filling the cone (a sphere seen under the angular radius ``half_angle_deg``), so
    directions are weighted uniformly in solid angle, not by their cosine to the axis. The
    cone's axis is the direction from the point to the light. Each ray is marched like
    :func:`transmittance`: until it leaves the box (directional light) or for the point-to-light
    distance (point light). ``half_angle_deg = 0`` reproduces :func:`transmittance` exactly.

    The estimate is (1/n_rays)·Σ_j exp(−τ(x, ω_j)); the rays of each point are drawn from a
    counter-based generator keyed on ``seed`` and the point's coordinates (see
    :mod:`vtkvol.reference.sampling`), so results are deterministic and a point gets the same
    value whether or not it is evaluated together with others. Standard error ≤ 0.5/√n_rays.

    Other parameters and the return value are as in :func:`transmittance`.
    """
    if not (0.0 <= half_angle_deg <= 180.0):
        raise ValueError(f"half_angle_deg {half_angle_deg} must be in [0, 180] degrees")
    n_rays = check_count(n_rays, "n_rays")
    field = as_field(opacity, spacing, unit_distance)
    where = EvalPoints.of(field, points)
    t_min = check_distance(min_distance, "min_distance")
    h = step_um(field, step)
    cos_max = math.cos(math.radians(half_angle_deg))
    out = np.empty(where.n)
    for start, stop, pts in where.chunks(max(1, RAY_CHUNK // n_rays)):
        m = stop - start
        axis, t_end = light_rays(pts, light)
        ray = np.tile(np.arange(n_rays), m)
        keys = stream_keys(np.repeat(point_keys(pts, seed), n_rays), ray)
        dirs = uniform_cone(
            np.repeat(axis, n_rays, axis=0), cos_max, uniform(keys, 0), uniform(keys, 1)
        )
        tau = optical_depth(
            field, np.repeat(pts, n_rays, axis=0), dirs, t_min, np.repeat(t_end, n_rays), h
        )
        out[start:stop] = np.exp(-tau).reshape(m, n_rays).mean(axis=1)
    return where.finish(out)


def stratified_unit_square(
    pts: np.ndarray, n_rays: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """``n_rays`` stratified samples of the unit square per point, flattened point-major.

    A jittered Fibonacci lattice: u1 = (j + ξ)/n puts exactly one sample in each of the n
    strata of u1 (area or solid angle, below), and u2 = frac(j·φ + η) spreads them evenly in
    angle, so a smooth integrand converges like O(1/n) rather than Monte-Carlo's O(1/√n). ξ
    (per sample) and η (per point, a Cranley–Patterson rotation) come from the counter-based
    generator keyed on ``seed`` and the point's coordinates: deterministic, and the same for a
    point whether or not it is evaluated with others.
    """
    m = pts.shape[0]
    ray = np.tile(np.arange(n_rays), m)
    base = point_keys(pts, seed)
    keys = stream_keys(np.repeat(base, n_rays), ray)
    u1 = (ray + uniform(keys, 0) * (1.0 - 1e-12)) / n_rays  # in (0, 1): never exactly 1
    u2 = np.mod(ray * _PHI + np.repeat(uniform(base, 7), n_rays), 1.0)
    return u1, u2


def extended_transmittance(
    opacity: np.ndarray,
    spacing: Sequence[float],
    light: Light,
    *,
    size: float,
    n_rays: int = 64,
    seed: int = 0,
    unit_distance: float | None = None,
    step: float = 0.25,
    points: np.ndarray | None = None,
    min_distance: float = 0.0,
) -> np.ndarray:
    """Transmittance averaged over the extent of a light of physical ``size``.

    The one physical truth of the light visibility that every surface method approximates.

    * :class:`DirectionalLight`: ``size`` is the angular radius in degrees (clamped to
      :data:`MAX_ANGULAR_RADIUS_DEG`, as the model does). The light is a disc of uniform
      radiance seen under that radius, so directions are uniform in solid angle within the
      cone about the light's direction (cos θ uniform on [cos size, 1]).
    * :class:`PointLight`: ``size`` is the radius in µm of a disc centred on the light's
      position and perpendicular to the direction from the point to the light, uniform in
      area (r = size·√u). A sphere of that radius seen from the point has the same silhouette
      (to O(size²/distance²)); the disc makes the distance to every sample exact, so a light
      inside the volume is handled without deciding which part of a sphere is visible.

    Samples are stratified (:func:`stratified_unit_square`) and seeded: the result is
    deterministic and its error, for the smooth visibility of a penumbra, falls like 1/n_rays.
    ``size = 0`` (an ideal light) returns :func:`transmittance` exactly.

    Parameters
    ----------
    size
        Angular radius (°) of a directional light or radius (µm) of a point light; ≥ 0.
    n_rays
        Samples of the light's extent per point.
    seed
        Seed of the sample jitter.

    Other parameters and the return value are as in :func:`transmittance`.
    """
    if not (math.isfinite(size) and size >= 0.0):
        raise ValueError(f"light size {size} must be finite and ≥ 0")
    if size == 0.0:
        return transmittance(opacity, spacing, light, unit_distance=unit_distance, step=step,
                             points=points, min_distance=min_distance)
    n_rays = check_count(n_rays, "n_rays")
    field = as_field(opacity, spacing, unit_distance)
    where = EvalPoints.of(field, points)
    t_min = check_distance(min_distance, "min_distance")
    h = step_um(field, step)
    out = np.empty(where.n)
    for start, stop, pts in where.chunks(max(1, RAY_CHUNK // n_rays)):
        m = stop - start
        u1, u2 = stratified_unit_square(pts, n_rays, seed)
        origins = np.repeat(pts, n_rays, axis=0)
        if isinstance(light, DirectionalLight):
            cos_max = math.cos(math.radians(min(size, MAX_ANGULAR_RADIUS_DEG)))
            axis = np.broadcast_to(light.unit(), (m * n_rays, 3))
            dirs = uniform_cone(axis, cos_max, u1, u2)
            t_end = np.full(m * n_rays, np.inf)
        elif isinstance(light, PointLight):
            axis, _ = light_rays(pts, light)
            e1, e2 = orthonormal_basis(np.repeat(axis, n_rays, axis=0))
            r = size * np.sqrt(u1)[:, None]
            phi = 2.0 * np.pi * u2[:, None]
            target = np.asarray(light.position) + r * (np.cos(phi) * e1 + np.sin(phi) * e2)
            v = target - origins
            t_end = np.linalg.norm(v, axis=1)
            dirs = v / np.maximum(t_end, 1e-300)[:, None]
        else:
            raise TypeError(f"expected DirectionalLight or PointLight, got {type(light).__name__}")
        tau = optical_depth(field, origins, dirs, t_min, t_end, h)
        out[start:stop] = np.exp(-tau).reshape(m, n_rays).mean(axis=1)
    return where.finish(out)
