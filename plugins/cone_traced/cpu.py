"""Cone tracing on the CPU (numpy/scipy): the filtered-opacity pyramid, the cone march, the
AO patterns and the AO bake — the verification reference and the fallback without compute
shaders, the same algorithm as shaders/cone_march.glsl (docs/cone-tracing.md). No VTK, no GL.

Spaces: arrays ``[z, y, x]``; voxel space = index coordinates (voxel centres at integers);
directions in dataset space (µm); distances h, h0, σ in voxels of the data grid along the cone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from vtkvol.plugins.cone_traced import AO_RESOLUTIONS

#: Mean opacities are clamped below 1 before −ln(1 − F): D ≤ 13.8 per unit distance, so a fully
#: opaque voxel still gives finite optical depths (the same clamp as vtkvol.reference).
MAX_OPACITY = 1.0 - 1e-6

#: The cone stops once its transmittance drops below 5 % (the thesis' ERT at 0.95 occlusion).
TAU_EXIT = -math.log(0.05)

#: Largest Gaussian radius (texels): σ ≤ 4 texels × span ≤ 4 → 16.
MAX_RADIUS = 16

#: Rings of the AO hemisphere patterns (cones per ring, inner to outer).
_AO_RINGS: dict[int, tuple[int, ...]] = {1: (1,), 3: (3,), 6: (1, 5), 12: (3, 9)}

#: Never trace further than this many steps (the march normally ends at the box, the light,
#: the maximum distance or 95 % occlusion long before; this bounds pathological inputs).
MAX_STEPS = 4096

#: The bake's normal is undefined (full sphere) where every central difference of the
#: filtered mean opacity F_0 = 1 − exp(−D_0), (F(p+e) − F(p−e))/2, is at most this (F, not D:
#: near-opaque plateaus would turn float32 noise of D into random normals).
NORMAL_EPS = 1e-5

#: AO "infinite" distance for shadow cones towards directional lights (µm).
_FAR = 1e30

# ------------------------------------------------------------------------------------------------
# Pyramid geometry and the CPU filter (the verification reference and the no-compute fallback)
# ------------------------------------------------------------------------------------------------
def mip_level_count(shape_zyx: Sequence[int]) -> int:
    """Levels of the full GL mip chain (down to 1×1×1) of a volume of ``shape_zyx`` texels."""
    return math.floor(math.log2(max(1, *(int(s) for s in shape_zyx)))) + 1


def level_shapes(shape_zyx: Sequence[int], levels: int) -> list[tuple[int, int, int]]:
    """Shapes ``[z, y, x]`` of levels 0…levels−1 (GL: ``max(1, n >> L)`` per axis)."""
    return [tuple(max(1, int(s) >> lev) for s in shape_zyx) for lev in range(levels)]  # type: ignore[misc]


def gaussian_weights(sigma: float, span: float) -> np.ndarray:
    """Normalised 1D Gaussian taps (float64) of σ texels, radius ``int(span·σ + 0.5)`` texels
    (the rule of ``scipy.ndimage.gaussian_filter(truncate=span)``); the 3D kernel is their
    outer product, which sums to 1 like the thesis' normalised (2s+1)³ kernel."""
    if not (sigma > 0 and span > 0):
        raise ValueError(f"sigma {sigma} and span {span} must be positive")
    radius = min(MAX_RADIUS, int(span * sigma + 0.5))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    w = np.exp(-0.5 * (x / sigma) ** 2)
    return w / w.sum()


def area_weights(n: int, m: int) -> np.ndarray:
    """(m, n) matrix: destination texel j of ``m`` covers source texels [j·n/m, (j+1)·n/m) of
    ``n``; entries are the overlaps divided by n/m (rows sum to 1)."""
    scale = n / m
    lo = np.arange(m)[:, None] * scale
    hi = lo + scale
    i = np.arange(n)[None, :]
    overlap = np.clip(np.minimum(hi, i + 1.0) - np.maximum(lo, i), 0.0, None)
    return overlap / scale


def downsample_area(volume: np.ndarray) -> np.ndarray:
    """One mip step: area-weighted box reduction to ``max(1, n // 2)`` texels per axis
    (float32; even axes are plain pair means, odd ones use :func:`area_weights`)."""
    out = np.asarray(volume, dtype=np.float32)
    for axis in range(3):
        n = out.shape[axis]
        m = max(1, n // 2)
        if m == n:
            continue
        if n == 2 * m:
            shape = (*out.shape[:axis], m, 2, *out.shape[axis + 1 :])
            out = out.reshape(shape).mean(axis=axis + 1, dtype=np.float64).astype(np.float32)
        else:
            w = area_weights(n, m)
            moved = np.tensordot(w, np.moveaxis(out, axis, 0).astype(np.float64), axes=(1, 0))
            out = np.ascontiguousarray(np.moveaxis(moved, 0, axis), dtype=np.float32)
    return out


def source_pyramid(values: np.ndarray, levels: int) -> list[np.ndarray]:
    """``values`` and its ``levels − 1`` area-averaged reductions (float32, ``[z, y, x]``)."""
    pyramid = [np.asarray(values, dtype=np.float32)]
    for _ in range(1, levels):
        pyramid.append(downsample_area(pyramid[-1]))
    return pyramid


def blur_level(level: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Separable Gaussian (``weights`` taps) over one level, zero outside it."""
    from scipy.ndimage import correlate1d

    out = np.asarray(level, dtype=np.float32)
    for axis in (2, 1, 0):  # x, y, z: the order of the GPU passes
        out = correlate1d(out, weights, axis=axis, output=np.float32, mode="constant", cval=0.0)
    return out


def optical_depth(mean_opacity: np.ndarray) -> np.ndarray:
    """D = −ln(1 − F): optical depth per opacity unit distance of a mean opacity F (float32)."""
    f = np.clip(np.asarray(mean_opacity, dtype=np.float32), 0.0, np.float32(MAX_OPACITY))
    return -np.log1p(-f)


def filtered_pyramid_cpu(
    opacity: np.ndarray, sigma: float = 1.0, span: float = 3.0, levels: int | None = None,
    *, alpha_levels: Sequence[np.ndarray] | None = None,
) -> list[np.ndarray]:
    """The filtered-opacity pyramid the cone tracer samples, computed with numpy/scipy.

    Parameters
    ----------
    opacity
        TF opacity α per opacity unit distance, ``[z, y, x]`` (``host.opacity_volume()``).
    sigma, span
        Gaussian σ in texels of each level and kernel radius in σ.
    levels
        Number of mip levels (default: the full chain, :func:`mip_level_count`).
    alpha_levels
        Optional per-level opacities to filter instead of the area-averaged pyramid of
        ``opacity`` (used to measure the thesis' variant, TF applied to averaged intensities).

    Returns
    -------
    One float32 array per level: D_L = −ln(1 − G_σ * S_L), where S_L is the level's mean opacity.
    """
    levels = mip_level_count(opacity.shape) if levels is None else int(levels)
    src = list(alpha_levels) if alpha_levels is not None else source_pyramid(opacity, levels)
    w = gaussian_weights(sigma, span)
    return [optical_depth(blur_level(s, w)).astype(np.float32) for s in src[:levels]]


# ------------------------------------------------------------------------------------------------
# AO hemisphere patterns and the CPU cone tracer (same algorithm as cone_traced.glsl)
# ------------------------------------------------------------------------------------------------
def hemisphere_pattern(cones: int) -> tuple[np.ndarray, float]:
    """Cone axes in a local frame (z = normal), shape (cones, 3), and the cone half-angle (°).

    Cosine-weighted equal-weight quadrature (Malley): the unit disk, which is the projection of
    the hemisphere under cosine weighting, is cut into equal-area annular sectors (rings of
    ``_AO_RINGS[cones]``); each cone's axis is its sector's centroid lifted back onto the
    hemisphere, so every cone carries weight 1/N of (1/π)∫(1−T)(n·ω)dω. The half-angle makes
    N cones cover the hemisphere's solid angle: cos θ = 1 − 1/N (90°, 48.2°, 33.6°, 23.6°).
    """
    if cones not in _AO_RINGS:
        raise ValueError(f"AO cone count must be one of {sorted(_AO_RINGS)}, not {cones}")
    dirs = []
    done = 0
    for ring, count in enumerate(_AO_RINGS[cones]):
        r0, r1 = math.sqrt(done / cones), math.sqrt((done + count) / cones)
        wedge = 2.0 * math.pi / count
        # Centroid radius of an annular sector: (2/3)(r1³−r0³)/(r1²−r0²)·sin(θ/2)/(θ/2).
        shrink = math.sin(wedge / 2) / (wedge / 2) if count > 1 else 0.0
        rc = (2.0 / 3.0) * (r1**3 - r0**3) / (r1**2 - r0**2) * shrink
        for k in range(count):
            phi = (k + 0.5 * ring) * wedge  # stagger alternate rings
            dirs.append((rc * math.cos(phi), rc * math.sin(phi), math.sqrt(max(0.0, 1 - rc * rc))))
        done += count
    return np.array(dirs), math.degrees(math.acos(1.0 - 1.0 / cones))


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent of unit normals ``n`` (M, 3) (Duff et al. 2017, branchless)."""
    s = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + s * n[:, 0] ** 2 * a, s * b, -s * n[:, 0]], axis=1)
    bt = np.stack([b, s + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, bt


def _sample_level(level: np.ndarray, tc: np.ndarray) -> np.ndarray:
    """Trilinear fetch of a level at texture coordinates ``tc`` (M, 3) (x, y, z) with GL's
    clamp-to-border(0) behaviour."""
    from scipy.ndimage import map_coordinates

    shape = np.array(level.shape[::-1], dtype=np.float64)  # (mx, my, mz)
    coords = tc * shape - 0.5
    return map_coordinates(level, coords[:, ::-1].T, order=1, mode="grid-constant", cval=0.0)


def cone_trace_cpu(
    pyramid: Sequence[np.ndarray],
    spacing: Sequence[float],
    points: np.ndarray,
    directions: np.ndarray,
    *,
    sin_angle: float,
    sigma: float = 1.0,
    lod_width: float = 4.0,
    h: float = 2.5,
    h0: float = 3.0,
    max_distance_um: float | np.ndarray = _FAR,
    unit_distance: float | None = None,
) -> np.ndarray:
    """Cone transmittance (0…1) from ``points`` along ``directions``: the shader's algorithm.

    Parameters
    ----------
    pyramid
        Optical-depth levels D_L (:func:`filtered_pyramid_cpu`), ``[z, y, x]``.
    spacing
        Voxel size (x, y, z) µm.
    points
        (M, 3) voxel index coordinates (x, y, z), voxel centres at integers.
    directions
        (M, 3) dataset-space unit vectors (µm), the cone axes.
    sin_angle
        sin of the cone half-angle.
    sigma, lod_width
        Filter σ (texels); the level rises while b·sin α > lod_width·σ·2^L voxels.
    h, h0
        Level-0 step and start offset (voxels along the cone).
    max_distance_um
        Where the march stops (µm; scalar or (M,)), besides the box and 95 % occlusion.
    unit_distance
        Opacity unit distance u (µm); default the smallest voxel edge.
    """
    spacing_a = np.asarray(spacing, dtype=np.float64)
    u = float(spacing_a.min()) if unit_distance is None else float(unit_distance)
    dims = np.array(pyramid[0].shape[::-1], dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64)
    d_vox = np.asarray(directions, dtype=np.float64) / spacing_a  # voxels per µm
    per_um = np.linalg.norm(d_vox, axis=1)
    per_um = np.where(per_um > 0, per_um, 1.0)
    step_tex = d_vox / per_um[:, None] / dims  # texture coordinates per voxel along the cone
    depth_per_voxel = 1.0 / (per_um * u)  # unit distances per voxel along the cone
    b_max = np.broadcast_to(np.asarray(max_distance_um, dtype=np.float64), per_um.shape) * per_um
    tex0 = (pts + 0.5) / dims
    tau = np.zeros(len(pts))
    active = np.ones(len(pts), dtype=bool)
    max_lod = len(pyramid) - 1
    lod, scale, b = 0, 1.0, float(h0)
    width = lod_width * sigma
    for _ in range(MAX_STEPS):
        while b * sin_angle > width * scale and lod < max_lod:
            lod += 1
            scale *= 2.0
        s = np.clip(b_max - b, 0.0, h * scale)
        active &= s > 0.0
        if not active.any():
            break
        idx = np.nonzero(active)[0]
        tc = tex0[idx] + (b + 0.5 * s[idx, None]) * step_tex[idx]
        inside = np.all((tc >= 0.0) & (tc <= 1.0), axis=1)
        active[idx[~inside]] = False
        idx, tc = idx[inside], tc[inside]
        if idx.size == 0:
            break
        tau[idx] += _sample_level(pyramid[lod], tc) * s[idx]
        active[idx[tau[idx] * depth_per_voxel[idx] > TAU_EXIT]] = False
        b += h * scale
    return np.exp(-tau * depth_per_voxel)


def voxel_normals(opacity: np.ndarray, spacing: Sequence[float]) -> np.ndarray:
    """Outward unit normals (x, y, z) per voxel, ``[z, y, x, 3]``: −∇α by central differences
    in µm (zero where the gradient vanishes), like the ray caster's −gradient."""
    gz, gy, gx = np.gradient(np.asarray(opacity, dtype=np.float64))
    g = np.stack([gx / spacing[0], gy / spacing[1], gz / spacing[2]], axis=-1)
    length = np.linalg.norm(g, axis=-1, keepdims=True)
    return np.where(length > 1e-12, -g / np.where(length > 0, length, 1.0), 0.0)


def ambient_occlusion_cpu(
    pyramid: Sequence[np.ndarray],
    spacing: Sequence[float],
    points: np.ndarray,
    normals: np.ndarray,
    view_direction: Sequence[float],
    *,
    mode: str = "hemisphere",
    cones: int = 6,
    ao_angle: float = 30.0,
    max_distance_um: float,
    **march: float | None,
) -> np.ndarray:
    """Cone-traced occlusion (0 = open, 1 = closed) at ``points``, as the shader computes it.

    ``normals`` (M, 3) are outward dataset-space normals (zero where undefined: the view
    direction is used instead); ``view_direction`` points from the scene towards the viewer.
    ``march``: :func:`cone_trace_cpu`'s ``sigma``, ``lod_width``, ``h``, ``h0`` and
    ``unit_distance`` (its defaults where not given), the same for every cone.
    """
    v = np.asarray(view_direction, dtype=np.float64)
    v = v / np.linalg.norm(v)
    m = len(points)
    kw: dict[str, Any] = dict(march, max_distance_um=max_distance_um)
    if mode == "view_cone":
        dirs = np.broadcast_to(v, (m, 3))
        sin_a = math.sin(math.radians(ao_angle))
        return 1.0 - cone_trace_cpu(pyramid, spacing, points, dirs, sin_angle=sin_a, **kw)
    if mode != "hemisphere":
        raise ValueError(f"unknown AO mode {mode!r}")
    n = np.asarray(normals, dtype=np.float64).reshape(m, 3)
    length = np.linalg.norm(n, axis=1)
    n = np.where(length[:, None] > 0, n / np.where(length > 0, length, 1.0)[:, None], v)
    t, bt = orthonormal_basis(n)
    pattern, half_angle = hemisphere_pattern(cones)
    sin_a = math.sin(math.radians(half_angle))
    occ = np.zeros(m)
    for px, py, pz in pattern:
        dirs = px * t + py * bt + pz * n
        occ += 1.0 - cone_trace_cpu(pyramid, spacing, points, dirs, sin_angle=sin_a, **kw)
    return occ / len(pattern)


def voxel_points(shape_zyx: Sequence[int]) -> np.ndarray:
    """(M, 3) voxel index coordinates (x, y, z) of every voxel centre, C order."""
    z, y, x = np.meshgrid(*(np.arange(int(s)) for s in shape_zyx), indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1).astype(np.float64)


# ------------------------------------------------------------------------------------------------
# Baked AO: grid geometry and the CPU bake (the GPU bake's verification reference and fallback)
# ------------------------------------------------------------------------------------------------
#: Helper axes of the bake's tangent frame: t = normalize(a × n), b = n × t, with a = _FRAME_A
#: (or _FRAME_B where n is within 0.6° of ±a). Generic axes: the frame is continuous except at
#: n = ±a, whereas Duff et al.'s frame (the per-sample shader's) jumps on the great circle
#: n_z = 0, i.e. on every vertical face of axis-aligned data, where float noise then decides the
#: pattern's rotation.
_FRAME_A = (0.35, 0.6, 0.72)
_FRAME_B = (-0.72, 0.35, 0.6)


def helper_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent of unit normals ``n`` (M, 3) about the generic helper axes
    (:data:`_FRAME_A`; the bake's frame, the same arithmetic as its compute shader)."""
    a = np.asarray(_FRAME_A, dtype=np.float64)
    a = a / np.linalg.norm(a)
    b = np.asarray(_FRAME_B, dtype=np.float64)
    b = b / np.linalg.norm(b)
    c = np.cross(a, n)
    near = np.linalg.norm(c, axis=1) < 1e-2
    c[near] = np.cross(b, n[near])
    t = c / np.linalg.norm(c, axis=1, keepdims=True)
    return t, np.cross(n, t)


def ao_grid_dims(data_dims: Sequence[int], resolution: str) -> tuple[int, int, int]:
    """Points (x, y, z) of the baked-AO grid for data of ``data_dims`` (x, y, z) voxels: the
    data's own voxels (``"full"``) or ``ceil(n/2)`` per axis (``"half"``, at least 2, axes of
    ≤ 2 voxels kept), spanning the same point bounds (first to last voxel centre)."""
    factor = AO_RESOLUTIONS[resolution]
    return tuple(  # type: ignore[return-value]
        int(n) if factor == 1 or n <= 2 else max(2, math.ceil(int(n) / factor))
        for n in data_dims
    )


def ao_grid_step(data_dims: Sequence[int], grid_dims: Sequence[int]) -> tuple[float, ...]:
    """Data voxels between neighbouring grid points, per axis (x, y, z): (n − 1)/(m − 1)."""
    return tuple(
        (int(n) - 1) / (int(m) - 1) if m > 1 else 0.0
        for n, m in zip(data_dims, grid_dims, strict=True)
    )


def ao_grid_points(data_dims: Sequence[int], grid_dims: Sequence[int]) -> np.ndarray:
    """(M, 3) data voxel index coordinates (x, y, z) of every grid point, C order ``[z, y, x]``
    (as the GPU computes them: float32 grid index × float32 step)."""
    step = np.asarray(ao_grid_step(data_dims, grid_dims), np.float32)
    pts = voxel_points(tuple(int(m) for m in grid_dims[::-1])).astype(np.float32) * step
    return pts.astype(np.float64)


def ao_gate(resolution: str) -> tuple[int, float]:
    """Pyramid level and tap offset (voxels) of the bake's emptiness gate.

    A grid point can only matter if a shaded ray sample interpolates it: the sample lies within
    one grid step of the point and has some opacity within one voxel, so material within
    step + 1 voxels (per axis) decides. A trilinear fetch of level L (texels of ≥ 2^L voxels)
    sees every voxel within 2^(L−1) + ½ of where it is taken (per axis, with positive weight).
    Full resolution (step 1): one fetch of level 1 at the point (sees ±1). Half (step ≈ 2, so
    ±3): eight fetches of level 2 at the point ± 1 voxel per axis (each sees ±2, together
    ±3) — one fetch of level 3 would also do, but it lets ~95 % of the points through.
    """
    return {"full": (1, 0.0), "half": (2, 1.0)}[resolution]


def ao_gate_open(source: Sequence[np.ndarray], points: np.ndarray, resolution: str) -> np.ndarray:
    """The bake's emptiness gate at ``points`` (data voxel coordinates x, y, z): True where
    some opacity lies close enough for a shaded sample to interpolate the point."""
    level, offset = ao_gate(resolution)
    lev = source[min(level, len(source) - 1)]
    dims = np.array(source[0].shape[::-1], dtype=np.float64)
    taps = [(0.0, 0.0, 0.0)] if offset == 0 else [
        (sx * offset, sy * offset, sz * offset)
        for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)
    ]
    total = np.zeros(len(points))
    for tap in taps:
        total += _sample_level(lev, (points + np.asarray(tap) + 0.5) / dims)
    return total > 0.0


def gradient_normals(
    depth: np.ndarray, spacing: Sequence[float], points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (M, 3) at ``points`` (voxel index coordinates x, y, z) of an
    optical-depth level ``depth`` (``[z, y, x]``, the bake uses D_0): −∇F of F = 1 − exp(−D),
    the trilinear D at ±1 voxel (zero outside the volume), central differences in µm; and a
    mask of where the gradient is defined (some difference above :data:`NORMAL_EPS`)."""
    dims = np.array(depth.shape[::-1], dtype=np.float64)
    level = np.asarray(depth, dtype=np.float32)
    diffs = []
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = 1.0
        plus = _sample_level(level, (points + e + 0.5) / dims).astype(np.float64)
        minus = _sample_level(level, (points - e + 0.5) / dims).astype(np.float64)
        diffs.append(0.5 * (np.exp(-minus) - np.exp(-plus)))  # (F(p+e) − F(p−e)) / 2
    dv = np.stack(diffs, axis=1)
    defined = np.abs(dv).max(axis=1) > NORMAL_EPS
    g = dv / np.asarray(spacing, dtype=np.float64)
    length = np.linalg.norm(g, axis=1)
    n = np.where(defined[:, None], -g / np.where(length > 0, length, 1.0)[:, None], 0.0)
    return n, defined


def baked_ao_cpu(
    opacity: np.ndarray,
    spacing: Sequence[float],
    *,
    resolution: str = "full",
    cones: int = 6,
    max_distance_um: float,
    sigma: float = 1.0,
    span: float = 3.0,
    pyramid: Sequence[np.ndarray] | None = None,
    source: Sequence[np.ndarray] | None = None,
    chunk: int = 1 << 17,
    **march: float | None,
) -> np.ndarray:
    """Baked hemisphere AO (0 = open, 1 = closed) at every point of the AO grid,
    ``[z, y, x]`` float32: what ``shaders/bake_ao.comp.glsl`` computes.

    Per grid point: the outward normal of the *filtered* opacity (:func:`gradient_normals` of
    D_0; the raw opacity's gradient vanishes one voxel inside a surface, and the full-sphere AO
    there, interpolated into surface samples, darkens them) and the mean occlusion of ``cones``
    cosine-weighted cones about it (:func:`hemisphere_pattern`); where the normal is undefined
    (deep inside or far outside), the same pattern about +z and −z (the full sphere). Points whose
    neighbourhood is empty (:func:`ao_gate`) are 0. ``pyramid``/``source`` (the filtered
    and the source pyramid) are computed from ``opacity`` when not given (filter ``sigma``,
    ``span``). ``march``: :func:`cone_trace_cpu`'s ``lod_width``, ``h``, ``h0`` and
    ``unit_distance`` (its defaults where not given); its ``sigma`` is this ``sigma``.
    """
    levels = mip_level_count(opacity.shape)
    if source is None:
        source = source_pyramid(opacity, levels)
    if pyramid is None:
        pyramid = filtered_pyramid_cpu(opacity, sigma, span, levels, alpha_levels=source)
    data_dims = opacity.shape[::-1]
    grid = ao_grid_dims(data_dims, resolution)
    pts_all = ao_grid_points(data_dims, grid)
    pattern, half_angle = hemisphere_pattern(cones)
    sin_a = math.sin(math.radians(half_angle))
    kw: dict[str, Any] = dict(march, sin_angle=sin_a, sigma=sigma,
                              max_distance_um=max_distance_um)
    out = np.zeros(len(pts_all))
    open_ = np.nonzero(ao_gate_open(source, pts_all, resolution))[0]
    for start in range(0, len(open_), chunk):
        idx = open_[start : start + chunk]
        pts = pts_all[idx]
        n, defined = gradient_normals(pyramid[0], spacing, pts)
        n[~defined] = (0.0, 0.0, 1.0)
        t, bt = helper_basis(n)
        occ = np.zeros(len(pts))
        for px, py, pz in pattern:
            occ += 1.0 - cone_trace_cpu(pyramid, spacing, pts, px * t + py * bt + pz * n, **kw)
        occ /= len(pattern)
        sphere = np.nonzero(~defined)[0]
        if sphere.size:  # the mirrored hemisphere completes the full sphere
            back = np.zeros(sphere.size)
            ps, ts, bts, ns = pts[sphere], t[sphere], bt[sphere], n[sphere]
            for px, py, pz in pattern:
                back += 1.0 - cone_trace_cpu(pyramid, spacing, ps, px * ts + py * bts - pz * ns,
                                             **kw)
            occ[sphere] = 0.5 * (occ[sphere] + back / len(pattern))
        out[idx] = occ
    return out.reshape(grid[::-1]).astype(np.float32)


def sample_grid(values: np.ndarray, data_dims: Sequence[int], points: np.ndarray) -> np.ndarray:
    """Trilinear value of a grid volume ``values`` (``[z, y, x]``, spanning the point bounds
    of data of ``data_dims`` voxels) at data voxel coordinates ``points`` (M, 3) (x, y, z): the
    fragment shader's single fetch of the baked AO."""
    from scipy.ndimage import map_coordinates

    step = np.asarray(ao_grid_step(data_dims, values.shape[::-1]), dtype=np.float64)
    coords = np.asarray(points, dtype=np.float64) / np.where(step > 0, step, 1.0)
    return map_coordinates(values, coords[:, ::-1].T, order=1, mode="nearest")
