"""Transmittance to a light: the hard-shadow reference and the cone (soft-shadow) reference.

T(x) = exp(−∫ σ ds) along the segment from x towards the light, until it leaves the volume's box
(directional light) or reaches the light (point light). Spaces and units: see
:mod:`vtkvol.reference.raymarch` (world µm, (x, y, z) tuples, ``[z, y, x]`` arrays).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from vtkvol.reference.lights import Light, light_rays
from vtkvol.reference.raymarch import (
    RAY_CHUNK,
    EvalPoints,
    ExtinctionField,
    check_count,
    check_distance,
    optical_depth,
    step_um,
)
from vtkvol.reference.sampling import point_keys, stream_keys, uniform, uniform_cone


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
        Transfer-function opacity α ∈ [0, 1] per voxel, ``[z, y, x]``.
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
    field = ExtinctionField(opacity, spacing, unit_distance)
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
    field = ExtinctionField(opacity, spacing, unit_distance)
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
