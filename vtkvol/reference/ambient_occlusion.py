"""Monte-Carlo ambient occlusion: the reference for volumetric AO (full sphere or hemisphere).

For a point x and a direction ω, the occlusion of the ray is 1 − T(x, ω, D) with
T = exp(−∫ σ ds) over s ∈ [min_distance, D] µm (clipped to the box): only absorbers within
``max_distance`` = D of the point count, the same semantics as the GPU method's maximum
distance. The AO value is the mean over ``n_rays`` directions:

* no ``normals``: ω uniform on the sphere, estimating (1/4π)∫_{S²} (1 − T) dω (volumes have no
  surface normal; this is the "full spherical neighbourhood" volumetric AO);
* ``normals`` n: ω cosine-distributed about n, estimating (1/π)∫_{H(n)} (1 − T)(n·ω) dω, the
  classic surface AO. A zero normal falls back to the uniform sphere for that point.

Spaces and units: world µm, (x, y, z) vectors, ``[z, y, x]`` arrays
(:mod:`vtkvol.reference.raymarch`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

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
    cosine_hemisphere,
    point_keys,
    stream_keys,
    uniform,
    uniform_sphere,
)


def ambient_occlusion_mc(
    opacity: np.ndarray,
    spacing: Sequence[float],
    *,
    max_distance: float,
    n_rays: int = 256,
    seed: int = 0,
    unit_distance: float | None = None,
    step: float = 0.5,
    points: np.ndarray | None = None,
    normals: np.ndarray | None = None,
    min_distance: float = 0.0,
) -> np.ndarray:
    """Monte-Carlo ambient occlusion per voxel centre (or per point), 0 = fully open, 1 = closed.

    Parameters
    ----------
    opacity
        Transfer-function opacity α ∈ [0, 1] per voxel, ``[z, y, x]``.
    spacing
        Voxel edge (x, y, z) in µm.
    max_distance
        Only absorbers within this many µm of the point occlude.
    n_rays
        Directions per point. Each ray's occlusion is in [0, 1], so the standard error of a
        point's value is at most 0.5/√n_rays.
    seed
        Seed of the counter-based generator (:mod:`vtkvol.reference.sampling`): same seed, same
        result, independent of chunking and of which other points are evaluated.
    unit_distance
        Thickness in µm of the slab whose opacity α is; default the smallest voxel edge.
    step
        March step in units of the smallest voxel edge (midpoint rule, final partial step).
    points
        Optional world positions (N, 3) in µm, order (x, y, z), instead of every voxel centre.
    normals
        Optional world-space normals (x, y, z), ``[z, y, x, 3]`` (or (N, 3) with ``points``),
        not necessarily unit length: switches to cosine-weighted hemisphere sampling.
    min_distance
        Ignore absorbers closer than this many µm (the GPU methods' self-occlusion offset);
        0, the default, is the physical definition.

    Returns
    -------
    float32 occlusion in [0, 1]: ``[z, y, x]``, or (N,) when ``points`` is given.
    """
    d_max = check_distance(max_distance, "max_distance")
    d_min = check_distance(min_distance, "min_distance")
    n_rays = check_count(n_rays, "n_rays")
    field = as_field(opacity, spacing, unit_distance)
    where = EvalPoints.of(field, points)
    h = step_um(field, step)
    nrm = where.per_point(normals, "normals")
    out = np.empty(where.n)
    for start, stop, pts in where.chunks(max(1, RAY_CHUNK // n_rays)):
        m = stop - start
        keys = stream_keys(np.repeat(point_keys(pts, seed), n_rays), np.tile(np.arange(n_rays), m))
        u1, u2 = uniform(keys, 0), uniform(keys, 1)
        dirs = uniform_sphere(u1, u2)
        if nrm is not None:
            n = np.repeat(nrm[start:stop], n_rays, axis=0)
            length = np.linalg.norm(n, axis=1)
            ok = length > 0.0
            dirs[ok] = cosine_hemisphere(n[ok] / length[ok, None], u1[ok], u2[ok])
        tau = optical_depth(field, np.repeat(pts, n_rays, axis=0), dirs, d_min, d_max, h)
        out[start:stop] = (-np.expm1(-tau)).reshape(m, n_rays).mean(axis=1)
    return where.finish(out)
