"""Reconstruction filters and the Marschner–Lobb test signal (numpy; no VTK).

The reference for ``RenderSettings.interpolation`` (docs/reconstruction.md): how well a
filter reconstructs a continuous function from its samples, measured against the analytic
function, so the GPU's corrected trilinear filter (``resources/shaders/host_interpolation.glsl``)
has an independent CPU counterpart and the seed-001 claim ("corrected trilinear ≈ Catmull-Rom
quality for the cost of trilinear") can be checked.

Conventions:

* volumes are ``[z, y, x]`` arrays; sample positions are **voxel coordinates** ``(x, y, z)``
  as an ``(N, 3)`` array, voxel ``(i, j, k)`` at ``(i, j, k)`` (so GL texture coordinate
  ``t`` of an ``n``-voxel axis is voxel coordinate ``t·n − 0.5``);
* outside ``[0, n−1]`` every filter reads the edge voxel (GL's ``CLAMP_TO_EDGE``, which is what
  VTK sets on its volume texture), also for the neighbours of cubic filters;
* the Marschner–Lobb signal lives on world ``[−1, 1]³``; an ``n``³ sampling puts voxel 0 at −1
  and voxel ``n−1`` at +1 (:func:`ml_voxel_to_world`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Filters by name, each ``f(volume, points) -> values`` (see :func:`reconstruct`).
FILTERS = ("trilinear", "corrected", "catmull_rom", "bspline")


# -- the test signal ----------------------------------------------------------------------------
def marschner_lobb(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, *, f_m: float = 6.0, alpha: float = 0.25
) -> np.ndarray:
    """The Marschner–Lobb function (Marschner & Lobb 1994) at world points in ``[−1, 1]³``.

    ``ρ(x, y, z) = (1 − sin(πz/2) + α(1 + ρ_r(√(x² + y²)))) / (2(1 + α))`` with
    ``ρ_r(r) = cos(2π f_M cos(πr/2))``; values in ``[0, 1]``. With the standard ``f_M = 6``,
    ``α = 0.25`` a 41³ sampling is barely above the Nyquist rate of the radial ripples, which
    is why it is the standard stress test for reconstruction filters. Arrays broadcast.
    """
    x, y, z = (np.asarray(v, dtype=np.float64) for v in (x, y, z))
    r = np.sqrt(x * x + y * y)
    rho_r = np.cos(2.0 * np.pi * f_m * np.cos(np.pi * r / 2.0))
    return (1.0 - np.sin(np.pi * z / 2.0) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha))


def ml_voxel_to_world(points: np.ndarray, n: int) -> np.ndarray:
    """Voxel coordinates ``(x, y, z)`` of an ``n``³ Marschner–Lobb sampling → world ``[−1, 1]``."""
    return np.asarray(points, dtype=np.float64) * (2.0 / (n - 1)) - 1.0


def phantom_marschner_lobb(
    n: int = 41, *, f_m: float = 6.0, alpha: float = 0.25
) -> np.ndarray:
    """The Marschner–Lobb function sampled on an ``n``³ grid over ``[−1, 1]³``: float32
    ``[z, y, x]``, values in ``[0, 1]`` (the isosurface usually shown is 0.5)."""
    if int(n) != n or n < 4:
        raise ValueError(f"phantom size n must be an integer >= 4, got {n}")
    c = np.linspace(-1.0, 1.0, int(n))
    v = marschner_lobb(c[None, None, :], c[None, :, None], c[:, None, None], f_m=f_m, alpha=alpha)
    return v.astype(np.float32)


# -- filters ------------------------------------------------------------------------------------
def _check(volume: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    vol = np.asarray(volume, dtype=np.float64)
    if vol.ndim != 3 or min(vol.shape) < 2:
        raise ValueError(f"volume must be 3-D with at least 2 voxels per axis, not {vol.shape}")
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), not {pts.shape}")
    return vol, pts


def _cell(coord: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower corner index and fractional part of clamped voxel coordinates on an ``n`` axis."""
    c = np.clip(coord, 0.0, n - 1.0)
    i = np.minimum(np.floor(c).astype(np.int64), n - 2)
    return i, c - i


def trilinear(volume: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Trilinear interpolation (seed 001 eq. 2.53) at voxel coordinates ``(x, y, z)``."""
    vol, pts = _check(volume, points)
    nz, ny, nx = vol.shape
    ix, u = _cell(pts[:, 0], nx)
    iy, v = _cell(pts[:, 1], ny)
    iz, w = _cell(pts[:, 2], nz)
    out = np.zeros(len(pts))
    for dz, wz in ((0, 1.0 - w), (1, w)):
        for dy, wy in ((0, 1.0 - v), (1, v)):
            for dx, wx in ((0, 1.0 - u), (1, u)):
                out += wz * wy * wx * vol[iz + dz, iy + dy, ix + dx]
    return out


def corrected_trilinear(volume: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Csébfalvi's corrected trilinear filter, seed 001 eq. 2.55 (with its factor ½).

    At ``p = (i + α, j + β, k + γ)`` (voxel coordinates, α, β, γ ∈ [0, 1) the fractional
    parts), with ``f(·)`` trilinear interpolation (eq. 2.53) and ``e_x, e_y, e_z`` one voxel::

        s_x = f(p − e_x) − 2 f(p) + f(p + e_x)          (and s_y, s_z: eq. 2.51 per axis)
        f̃(p) = f(p) + s_x (α² − α)/2 + s_y (β² − β)/2 + s_z (γ² − γ)/2

    The six shifted fetches are the ones a central-difference gradient (eq. 2.54) makes anyway.
    In 1-D this is exactly Catmull-Rom; eq. 2.52 prints it without the ½, which is an erratum
    (with the ½ the weights of f[i−1..i+2] are −α(1−α)²/2, (3α³ − 5α² + 2)/2,
    (−3α³ + 4α² + α)/2, (α³ − α²)/2). In 3-D it reproduces grid samples (α = β = γ = 0) and
    every polynomial of degree ≤ 2 exactly, but it is not tensor-product Catmull-Rom.
    Neighbours outside the grid read the edge voxel (GL ``CLAMP_TO_EDGE``).
    """
    vol, pts = _check(volume, points)
    f0 = trilinear(vol, pts)
    out = f0.copy()
    for axis, n in enumerate((vol.shape[2], vol.shape[1], vol.shape[0])):
        step = np.zeros(3)
        step[axis] = 1.0
        s = trilinear(vol, pts - step) - 2.0 * f0 + trilinear(vol, pts + step)
        _, t = _cell(pts[:, axis], n)
        out += s * (t * t - t) / 2.0
    return out


def _catmull_rom_weights(t: np.ndarray) -> tuple[np.ndarray, ...]:
    t2, t3 = t * t, t * t * t
    return (
        (-t3 + 2.0 * t2 - t) / 2.0,
        (3.0 * t3 - 5.0 * t2 + 2.0) / 2.0,
        (-3.0 * t3 + 4.0 * t2 + t) / 2.0,
        (t3 - t2) / 2.0,
    )


def catmull_rom(volume: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Tensor-product tricubic Catmull-Rom interpolation (64 voxel reads per point)."""
    vol, pts = _check(volume, points)
    nz, ny, nx = vol.shape
    axes = []
    for axis, n in enumerate((nx, ny, nz)):
        i, t = _cell(pts[:, axis], n)
        idx = [np.clip(i + d, 0, n - 1) for d in (-1, 0, 1, 2)]
        axes.append((idx, _catmull_rom_weights(t)))
    (ix, wx), (iy, wy), (iz, wz) = axes
    out = np.zeros(len(pts))
    for a in range(4):
        for b in range(4):
            wzy = wz[a] * wy[b]
            for c in range(4):
                out += wzy * wx[c] * vol[iz[a], iy[b], ix[c]]
    return out


def cubic_bspline(volume: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Interpolating tricubic B-spline: the samples are prefiltered into B-spline coefficients
    (scipy.ndimage, mirror-free ``nearest`` boundary), so the spline passes through them.
    The usual high-quality anchor (4th order accurate, C² smooth)."""
    from scipy import ndimage

    vol, pts = _check(volume, points)
    coords = np.stack([pts[:, 2], pts[:, 1], pts[:, 0]])
    return ndimage.map_coordinates(vol, coords, order=3, mode="nearest", prefilter=True)


_BY_NAME: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "trilinear": trilinear,
    "corrected": corrected_trilinear,
    "catmull_rom": catmull_rom,
    "bspline": cubic_bspline,
}


def reconstruct(volume: np.ndarray, points: np.ndarray, method: str) -> np.ndarray:
    """Evaluate filter ``method`` (one of :data:`FILTERS`) at voxel coordinates ``(x, y, z)``."""
    try:
        return _BY_NAME[method](volume, points)
    except KeyError:
        raise ValueError(f"unknown filter {method!r}; choose one of {FILTERS}") from None


def marschner_lobb_rmse(
    n: int,
    *,
    count: int = 100_000,
    seed: int = 0,
    interior: bool = True,
    methods: tuple[str, ...] = FILTERS,
) -> dict[str, float]:
    """RMSE of each filter against the analytic Marschner–Lobb function at ``count`` uniform
    random points (seeded), for an ``n``³ sampling.

    ``interior=True`` draws points in voxel coordinates ``[1, n−2]³``, where every filter's
    support lies inside the grid (edge clamping would otherwise penalise the wider filters for
    a boundary effect, not for their reconstruction); ``False``: the whole ``[0, n−1]³``.
    Values are in the signal's units (its range is ``[0, 1]``).
    """
    rng = np.random.default_rng(seed)
    lo, hi = (1.0, n - 2.0) if interior else (0.0, n - 1.0)
    pts = rng.uniform(lo, hi, size=(count, 3))
    world = ml_voxel_to_world(pts, n)
    truth = marschner_lobb(world[:, 0], world[:, 1], world[:, 2])
    vol = phantom_marschner_lobb(n).astype(np.float64)
    return {m: float(np.sqrt(np.mean((reconstruct(vol, pts, m) - truth) ** 2))) for m in methods}
