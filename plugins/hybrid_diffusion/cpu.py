"""Hybrid diffusion (seed 003 §3.3, "HD"): the direct light estimated per voxel by tracking
towards a light, averaged over iterations — the numpy path (fallback and test oracle of
the engine's ``tracker.comp.glsl``, which mirrors it operation by operation in float32).

Per iteration k and voxel x: a counter-based random stream (a 32-bit PCG hash of the voxel's
index, k and the seed, so the CPU and the GPU draw the same numbers) picks one light uniformly
(weight = number of lights; or every light with ``light_sampling="all"``) and tracks from x
towards it through σ_t (trilinear, per µm) with the global majorant σ̄: free flights
t += −ln(1 − ξ)/σ̄ up to the box exit (or the point light).

* ``delta`` (the paper's Woodcock tracking): at each tentative collision a real collision with
  probability σ/σ̄ ends the path with 0; escaping yields the light's colour × weight;
* ``ratio`` (unbiased, lower variance): the throughput is multiplied by (1 − σ/σ̄) at each
  tentative collision instead.

A path longer than :data:`MAX_STEPS` tentative collisions counts as absorbed (a bias below
e^−(MAX_STEPS/2) for any volume the majorant describes well). The estimate ρ_d is an RGB running
mean, with the light's inverse-square fall-off where it has one; the multiple scattering is the
engine's grid diffusion (:mod:`vtkvol.engine.diffusion`: the source model from ρ_d, or the
published explicit step applied to ρ_d + ρ_s).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from vtkvol.engine.diffusion import Grid, LightSource, falloff
from vtkvol.engine.traced_orders import (  # noqa: F401  (re-exported: HD's numpy API)
    BRICK,
    MAX_STEPS,
    MIN_THROUGHPUT,
    ORDERS_SEED_BASE,
    brick_majorants,
    traced_orders_sample,
)

#: Largest interpolated opacity :func:`extinction_at` converts (the engine's MAX_OPACITY).
MAX_ALPHA = 1.0 - 1e-6

Estimator = Literal["delta", "ratio"]
LightSampling = Literal["one", "all"]

_U32 = np.uint32


def pcg(v: np.ndarray) -> np.ndarray:
    """The 32-bit PCG hash (RXS-M-XS) of every element of a uint32 array."""
    v = np.asarray(v, _U32)
    state = v * _U32(747796405) + _U32(2891336453)
    word = ((state >> ((state >> _U32(28)) + _U32(4))) ^ state) * _U32(277803737)
    return (word >> _U32(22)) ^ word


def stream_keys(shape_zyx: Sequence[int], iteration: int, seed: int,
                region: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """One key per voxel (flat index x + nx·(y + ny·z)) for iteration ``iteration``; with
    ``region`` (z0, z1, y0, y1) only that region's keys are computed (the others are 0)."""
    base = pcg(np.array([(iteration + int(pcg(np.array([seed], _U32))[0])) & 0xFFFFFFFF], _U32))
    nz, ny, nx = (int(n) for n in shape_zyx)
    if region is None:
        return pcg(np.arange(nz * ny * nx, dtype=_U32) ^ base[0]).reshape((nz, ny, nx))
    z0, z1, y0, y1 = region
    index = (np.arange(z0, z1, dtype=_U32)[:, None, None] * _U32(ny)
             + np.arange(y0, y1, dtype=_U32)[None, :, None]) * _U32(nx) + np.arange(
                 nx, dtype=_U32)[None, None, :]
    keys = np.zeros((nz, ny, nx), _U32)
    keys[z0:z1, y0:y1] = pcg(index ^ base[0])
    return keys


def uniform(keys: np.ndarray, draw: int) -> np.ndarray:
    """The ``draw``-th number of each stream, in [0, 1) with 24-bit resolution (float32)."""
    bits = pcg(keys + _U32(draw)) >> _U32(8)
    return bits.astype(np.float32) * np.float32(1.0 / 16777216.0)


def unit(vector: Sequence[float]) -> np.ndarray:
    """``vector`` normalised in float32 (the exact numbers the GPU path is given)."""
    v = np.asarray(vector, np.float64)
    return (v / max(float(np.linalg.norm(v)), 1e-30)).astype(np.float32)


def centres32(grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voxel-centre coordinates (µm) computed in float32 as the GPU does, each ``[z, y, x]``."""
    nz, ny, nx = grid.shape_zyx
    out = []
    for o, s, n, axis in zip(grid.origin, grid.spacing, (nx, ny, nz), (2, 1, 0), strict=True):
        c = np.float32(o) + np.float32(s) * np.arange(n, dtype=np.float32)
        shape = [1, 1, 1]
        shape[axis] = n
        out.append(np.broadcast_to(c.reshape(shape), grid.shape_zyx))
    return out[0], out[1], out[2]


def trilinear(sigma: np.ndarray, grid: Grid, px: np.ndarray, py: np.ndarray,
              pz: np.ndarray) -> np.ndarray:
    """``sigma`` interpolated at dataset positions (µm; float32), clamped to the box."""
    nz, ny, nx = sigma.shape
    coords = []
    for p, o, s, n in zip((px, py, pz), grid.origin, grid.spacing, (nx, ny, nz), strict=True):
        f = np.clip((p - np.float32(o)) / np.float32(s), np.float32(0), np.float32(n - 1))
        i0 = np.minimum(np.floor(f), np.float32(max(n - 2, 0))).astype(np.int64)
        coords.append((i0, np.minimum(i0 + 1, n - 1), f - i0.astype(np.float32)))
    (x0, x1, wx), (y0, y1, wy), (z0, z1, wz) = coords
    one = np.float32(1.0)

    def lerp(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
        return a * (one - w) + b * w

    c00 = lerp(sigma[z0, y0, x0], sigma[z0, y0, x1], wx)
    c01 = lerp(sigma[z0, y1, x0], sigma[z0, y1, x1], wx)
    c10 = lerp(sigma[z1, y0, x0], sigma[z1, y0, x1], wx)
    c11 = lerp(sigma[z1, y1, x0], sigma[z1, y1, x1], wx)
    return lerp(lerp(c00, c01, wy), lerp(c10, c11, wy), wz)


def extinction_at(sigma: np.ndarray, grid: Grid, px: np.ndarray, py: np.ndarray,
                  pz: np.ndarray, unit_distance: float | None) -> np.ndarray:
    """σ_t (per µm) at dataset positions (µm; float32), clamped to the box: with
    ``unit_distance`` u (µm), the extinction of the trilinearly interpolated opacity
    α = 1 − exp(−σ_t·u) — what the ray caster and the exact reference sample (interpolating
    σ_t itself overestimates the optical depth at every surface: a dark bias of the direct
    light, 0.01–0.02 mean on the phantoms, issue 24's error split); None: σ_t interpolated
    linearly. Never above the largest corner σ_t, so every majorant stays one."""
    if unit_distance is None:
        return trilinear(sigma, grid, px, py, pz)
    f = np.float32
    u = f(unit_distance)
    alpha = trilinear(f(1.0) - np.exp(-sigma.astype(f) * u), grid, px, py, pz)
    return (-np.log(f(1.0) - np.minimum(alpha, f(MAX_ALPHA))) / u).astype(f)


def around(w: np.ndarray, c: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors ``[3, n]`` at cosine ``c`` and azimuth ``phi`` about the unit vectors ``w``
    (``[3, n]`` or ``[3]``), float32 — ``around`` in ``tracker.comp.glsl``."""
    f = np.float32
    w = np.broadcast_to(np.asarray(w, f).reshape(3, -1), (3, c.size))
    s = np.sqrt(np.maximum(f(0.0), f(1.0) - c * c))
    a = np.where(np.abs(w[0]) < f(0.9), np.array([[1.0], [0.0], [0.0]], f),
                 np.array([[0.0], [1.0], [0.0]], f))
    t1 = np.cross(w, a, axis=0)
    t1 = t1 / np.linalg.norm(t1, axis=0)
    t2 = np.cross(w, t1, axis=0)
    v = s * np.cos(phi) * t1 + s * np.sin(phi) * t2 + c * w
    return (v / np.linalg.norm(v, axis=0)).astype(f)


def _towards(grid: Grid, light: LightSource, x: np.ndarray, y: np.ndarray,
             z: np.ndarray, keys: np.ndarray | None = None, first_draw: int = 0,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(dx, dy, dz, t_end): unit direction to the light and the tracking distance (µm). A
    sized light is sampled per path with draws ``first_draw`` + 4094, 4095 of ``keys``: a
    point on its sphere (point light, radius ``size`` µm) or a direction in its cone
    (directional, half-angle ``size`` rad) — uniform, as the camera path tracer samples them."""
    f = np.float32
    size = f(light.size) if keys is not None else f(0.0)
    if size > 0:
        u1, u2 = uniform(keys, first_draw + 4094), uniform(keys, first_draw + 4095)
        phi = f(2.0 * np.pi) * u2
    if light.kind == "point":
        target = np.asarray(light.vector, f).reshape(3, 1)
        if size > 0:
            target = target + size * around(np.array([0.0, 0.0, 1.0], f), f(1.0) - f(2.0) * u1,
                                            phi)
        dx, dy, dz = (t - c for t, c in zip(target, (x, y, z), strict=True))
        dist = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv = np.float32(1.0) / np.maximum(dist, np.float32(1e-12))
        dx, dy, dz = dx * inv, dy * inv, dz * inv
    else:
        if size > 0:
            cone = f(1.0) - u1 * (f(1.0) - f(np.cos(float(size))))
            dx, dy, dz = around(unit(light.vector), cone, phi)
        else:
            dx, dy, dz = (np.full_like(x, c) for c in unit(light.vector))
        dist = None
    exit_t = np.full_like(x, np.float32(np.inf))
    for p, d, o, s, n in zip((x, y, z), (dx, dy, dz), grid.origin, grid.spacing,
                             grid.shape_zyx[::-1], strict=True):
        lo = np.float32(o)
        hi = lo + np.float32(s) * np.float32(n - 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d > 0, (hi - p) / d, np.where(d < 0, (lo - p) / d, np.inf))
        exit_t = np.minimum(exit_t, t.astype(np.float32))
    exit_t = np.maximum(exit_t, np.float32(0.0))
    t_end = exit_t if dist is None else np.minimum(exit_t, dist)
    return dx, dy, dz, t_end


def direct_sample(
    sigma_t: np.ndarray, grid: Grid, lights: Sequence[LightSource],
    colors: Sequence[tuple[float, float, float]], *, iteration: int, seed: int,
    estimator: Estimator, light_sampling: LightSampling,
    region: tuple[int, int, int, int] | None = None, bricks: np.ndarray | None = None,
    unit_distance: float | None = None,
) -> np.ndarray:
    """One sample of the direct light at every voxel centre, ``[z, y, x, 3]`` float32; with
    ``region`` (z0, z1, y0, y1) only the voxels with z0 ≤ z < z1 and y0 ≤ y < y1 are sampled
    (the others stay 0):
    each voxel's random stream depends only on its index, so a sample drawn in z slabs equals
    the whole one (the GPU's bounded chunks, ``tracker.comp.glsl``'s ``vv_first``). With
    ``bricks`` (:func:`~vtkvol.engine.traced_orders.brick_majorants`) the tracking uses each
    brick's majorant instead of the
    global one: the same mean, fewer steps through sparse data. ``unit_distance``: σ_t is
    sampled as the extinction of the interpolated opacity (:func:`extinction_at`; the
    techniques pass the host's), None: interpolated linearly."""
    shape = grid.shape_zyx
    out = np.zeros((*shape, 3), np.float32)
    if not lights:
        return out
    keys = stream_keys(shape, iteration, seed, region)  # only the region's are drawn
    xs, ys, zs = centres32(grid)
    majorant = np.float32(sigma_t.max())
    n = len(lights)
    inside = np.ones(shape, bool)
    if region is not None:
        inside[:] = False
        inside[region[0]:region[1], region[2]:region[3]] = True
    if light_sampling == "one":
        pick = np.minimum((uniform(keys, 0) * np.float32(n)).astype(np.int64), n - 1)
        chosen = [(index, (pick == index) & inside, np.float32(n)) for index in range(n)]
    else:
        chosen = [(index, inside, np.float32(1.0)) for index in range(n)]
    for index, mask, weight in chosen:
        if not mask.any():
            continue
        throughput = _track(sigma_t, grid, lights[index], keys[mask], xs[mask], ys[mask],
                            zs[mask], majorant, estimator, first_draw=1 + 4096 * index,
                            bricks=bricks, unit_distance=unit_distance)
        f = falloff(grid, lights[index])
        f_mask = np.float32(f) if np.isscalar(f) else np.asarray(f)[mask]
        out[mask] += (throughput * weight * f_mask)[:, None] * np.asarray(colors[index],
                                                                          np.float32)
    return out


def _brick_step(grid: Grid, bricks: np.ndarray, px: np.ndarray, py: np.ndarray, pz: np.ndarray,
                dx: np.ndarray, dy: np.ndarray, dz: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray]:
    """(majorant, distance µm to the brick's exit along d) of the brick holding each point
    (``tracker.comp.glsl``'s ``brickAt``): the brick is looked up a thousandth of a voxel
    further along d, so a point on a face belongs to the brick the path enters."""
    f = np.float32
    nb = bricks.shape[::-1]  # x, y, z
    index = []
    exit_t = np.full_like(px, f(np.inf))
    nudge = f(1e-3)
    for p, d, o, s, n, count in zip((px, py, pz), (dx, dy, dz), grid.origin, grid.spacing,
                                    grid.shape_zyx[::-1], nb, strict=True):
        v = (p - f(o)) / f(s) + nudge * d / f(s) * f(min(grid.spacing))
        b = np.clip(np.floor(v / f(BRICK)), 0, count - 1).astype(np.int64)
        index.append(b)
        lo = f(o) + f(s) * (b * BRICK).astype(f)
        hi = f(o) + f(s) * np.minimum((b + 1) * BRICK, n - 1).astype(f)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d > 0, (hi - p) / d, np.where(d < 0, (lo - p) / d, f(np.inf)))
        exit_t = np.minimum(exit_t, np.maximum(t.astype(f), f(0.0)))
    return bricks[index[2], index[1], index[0]], exit_t


def _track(sigma_t: np.ndarray, grid: Grid, light: LightSource, keys: np.ndarray,
           x: np.ndarray, y: np.ndarray, z: np.ndarray, majorant: np.float32,
           estimator: Estimator, first_draw: int,
           bricks: np.ndarray | None = None,
           unit_distance: float | None = None) -> np.ndarray:
    """Throughput from each point towards ``light``: tracking against the global
    ``majorant``, or with ``bricks`` (:func:`~vtkvol.engine.traced_orders.brick_majorants`)
    against each brick's own —
    a flight that would leave its brick stops at the face without an event (the exponential
    flight is memoryless, so restarting it there with the next brick's majorant is exact) and
    an empty brick is crossed in one step."""
    dx, dy, dz, t_end = _towards(grid, light, x, y, z, keys, first_draw)
    throughput = np.ones_like(x)
    if majorant <= 0:
        return throughput
    t = np.zeros_like(x)
    alive = np.ones(x.shape, bool)
    draw = first_draw
    f = np.float32
    inv_majorant = f(1.0) / majorant
    min_step = f(1e-4 * min(grid.spacing))
    for _ in range(MAX_STEPS):
        if not alive.any():
            break
        xi = uniform(keys, draw)
        draw += 1
        if bricks is None:  # as before the bricks, operation for operation (GPU twin)
            local = np.full_like(x, majorant)
            flight = t - np.log(f(1.0) - xi) * inv_majorant
            event = alive
        else:
            local, to_face = _brick_step(grid, bricks, x + t * dx, y + t * dy, z + t * dz,
                                         dx, dy, dz)
            with np.errstate(divide="ignore", invalid="ignore"):
                free = np.where(local > 0, -np.log(f(1.0) - xi) / local, f(np.inf))
            # At least a ten-thousandth of a voxel per face: float rounding can leave a
            # point a hair before a face (or the box's exit) that it cannot then leave.
            to_face = np.maximum(to_face, min_step)
            event = alive & (free < to_face)
            flight = t + np.where(event, free, to_face)
        t = np.where(alive, flight, t)
        escaped = alive & (t >= t_end)
        alive &= ~escaped
        event &= alive
        sigma = extinction_at(sigma_t, grid, x + t * dx, y + t * dy, z + t * dz, unit_distance)
        if bricks is None:
            ratio = np.minimum(sigma * inv_majorant, f(1.0))
        else:
            ratio = np.where(event, np.minimum(sigma / np.maximum(local, f(1e-30)), f(1.0)),
                             f(0.0))
        if estimator == "ratio":
            throughput = np.where(alive, throughput * (np.float32(1.0) - ratio), throughput)
            alive &= throughput >= np.float32(MIN_THROUGHPUT)
        else:
            collide = alive & (uniform(keys, draw) < ratio)
            throughput = np.where(collide, np.float32(0.0), throughput)
            alive &= ~collide
        draw += 1  # both estimators use two draws per step, so their streams line up
    return np.where(alive, np.float32(0.0), throughput)  # too many steps: absorbed
