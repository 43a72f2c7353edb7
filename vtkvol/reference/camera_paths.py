"""Numpy twin of the camera path tracer (:mod:`vtkvol.engine.renderers.path_tracer`).

The same estimator for a few pixels of a small volume (≤ 32³ is what the tests use), written
independently of the GPU code: camera ray through a point jittered uniformly in the pixel,
clipped to the voxel-centre box and, where given, to an opaque depth; delta tracking against
**one global majorant** (the GPU walks per-brick majorants; both are unbiased, so agreement
also checks the brick walk); at each real collision the throughput is multiplied by the RGB
albedo a·colour(x) and next-event estimation adds, per light, E·T·4π·p_g(cos θ) with T by
ratio tracking, and at the camera ray's collision the host's ambient term k_a (``ambient``,
ambient visibility 1); Henyey–Greenstein directions; Russian roulette from the third collision with
survival q = min(max throughput, 0.95) and reweighting. ``single`` scattering stops after the
first collision's estimate.

Medium: α(x) trilinear in the ``[z, y, x]`` opacity grid (voxel centres at ``origin +
i·spacing``, clamped at the edges like a GL texture), σ = −ln(1 − α)/unit_distance per µm;
colour(x) trilinear in the ``[z, y, x, 3]`` colour grid. Lights: tuples ``(kind, vector,
colour, size, falloff_distance)`` as :class:`vtkvol.engine.illuminator.LightSpec` holds them
(dataset space). Returns per-path samples so callers can form means and standard errors.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

#: Collisions per path in multiple-scattering mode (as the GPU's cap).
MAX_BOUNCES = 256


class _Medium:
    def __init__(self, opacity: np.ndarray, colour: np.ndarray, spacing: Sequence[float],
                 origin: Sequence[float], unit_distance: float) -> None:
        self.alpha = np.asarray(opacity, np.float64)
        self.colour = np.asarray(colour, np.float64)[..., :3]
        self.spacing = np.asarray(spacing, np.float64)
        self.origin = np.asarray(origin, np.float64)
        self.unit = float(unit_distance)
        nz, ny, nx = self.alpha.shape
        self.dims = np.array([nx, ny, nz], np.float64)
        self.lo = self.origin
        self.hi = self.origin + (self.dims - 1) * self.spacing
        self.majorant = float(-np.log(np.maximum(1 - self.alpha.max(), 1e-6)) / self.unit)

    def _trilinear(self, grid: np.ndarray, p: np.ndarray) -> np.ndarray:
        v = (p - self.origin) / self.spacing  # voxel coordinates (x, y, z)
        v = np.clip(v, 0, self.dims - 1)
        i0 = np.minimum(np.floor(v).astype(np.int64), (self.dims - 2).clip(0).astype(np.int64))
        f = v - i0
        i1 = np.minimum(i0 + 1, (self.dims - 1).astype(np.int64))
        out = 0.0
        for cz in (0, 1):
            z = i1[:, 2] if cz else i0[:, 2]
            wz = f[:, 2] if cz else 1 - f[:, 2]
            for cy in (0, 1):
                y = i1[:, 1] if cy else i0[:, 1]
                wy = f[:, 1] if cy else 1 - f[:, 1]
                for cx in (0, 1):
                    x = i1[:, 0] if cx else i0[:, 0]
                    wx = f[:, 0] if cx else 1 - f[:, 0]
                    w = wz * wy * wx
                    val = grid[z, y, x]
                    out = out + (w[:, None] * val if val.ndim == 2 else w * val)
        return out

    def sigma(self, p: np.ndarray) -> np.ndarray:
        a = self._trilinear(self.alpha, p)
        return -np.log(np.maximum(1.0 - a, 1e-6)) / self.unit

    def albedo_rgb(self, p: np.ndarray) -> np.ndarray:
        return self._trilinear(self.colour, p)

    def box(self, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            ta, tb = (self.lo - o) * inv, (self.hi - o) * inv
        t0 = np.nan_to_num(np.minimum(ta, tb), nan=-np.inf).max(axis=1)
        t1 = np.nan_to_num(np.maximum(ta, tb), nan=np.inf).min(axis=1)
        return np.maximum(t0, 0.0), t1

    def _tentative_collisions(self, rng: np.random.Generator, o: np.ndarray, d: np.ndarray,
                              t: np.ndarray, t_max: np.ndarray, live: np.ndarray
                              ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Free flights against the majorant: yields ``(idx, sigma)`` of the rays still live
        after each flight (``t`` advanced in place; rays past ``t_max`` leave ``live``). The
        caller decides what a tentative collision does and may take rays out of ``live``."""
        mu = self.majorant
        while live.any():
            idx = np.nonzero(live)[0]
            t[idx] += -np.log(1.0 - rng.random(len(idx))) / mu
            inside = t[idx] < t_max[idx]
            live[idx[~inside]] = False
            idx = idx[inside]
            if len(idx) == 0:
                return
            yield idx, self.sigma(o[idx] + t[idx, None] * d[idx])

    def delta_track(self, rng: np.random.Generator, o: np.ndarray, d: np.ndarray,
                    t: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """Distance of the next real collision, or -1 where the ray leaves [t, t_max]."""
        t = t.copy()
        out = np.full(len(t), -1.0)
        live = t < t_max
        if self.majorant <= 0:
            return out
        for idx, s in self._tentative_collisions(rng, o, d, t, t_max, live):
            real = rng.random(len(idx)) * self.majorant < s
            out[idx[real]] = t[idx[real]]
            live[idx[real]] = False
        return out

    def ratio_track(self, rng: np.random.Generator, o: np.ndarray, d: np.ndarray,
                    t_max: np.ndarray) -> np.ndarray:
        T = np.ones(len(o))
        t = np.zeros(len(o))
        live = t < t_max
        if self.majorant <= 0:
            return T
        for idx, s in self._tentative_collisions(rng, o, d, t, t_max, live):
            T[idx] *= 1.0 - np.minimum(s / self.majorant, 1.0)
            live[idx[T[idx] <= 1e-6]] = False
        return T


def _around(w: np.ndarray, c: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors at cosine ``c`` and azimuth ``phi`` about unit vectors ``w`` (rows)."""
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    a = np.where(np.abs(w[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t1 = np.cross(w, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(w, t1)
    v = (s * np.cos(phi))[:, None] * t1 + (s * np.sin(phi))[:, None] * t2 + c[:, None] * w
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _phase4pi(c: np.ndarray, g: float) -> np.ndarray:
    dn = 1.0 + g * g - 2.0 * g * c
    return (1.0 - g * g) / (dn * np.sqrt(dn))


def _sample_hg(rng: np.random.Generator, w: np.ndarray, g: float) -> np.ndarray:
    u = rng.random(len(w))
    if abs(g) < 1e-3:
        c = 1.0 - 2.0 * u
    else:
        s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
        c = (1.0 + g * g - s * s) / (2.0 * g)
    return _around(w, np.clip(c, -1, 1), 2 * np.pi * rng.random(len(w)))


def _next_event(rng: np.random.Generator, medium: _Medium, p: np.ndarray, d: np.ndarray,
                lights: Sequence[tuple[Any, ...]], g: float) -> np.ndarray:
    L = np.zeros((len(p), 3))
    for kind, vector, colour, size, falloff in lights:
        E = np.broadcast_to(np.asarray(colour, np.float64), (len(p), 3)).copy()
        vec = np.asarray(vector, np.float64)
        if kind == "point":
            q = np.broadcast_to(vec, p.shape).copy()
            if size > 0:
                q += size * _around(np.tile([[0.0, 0.0, 1.0]], (len(p), 1)),
                                    1.0 - 2.0 * rng.random(len(p)), 2 * np.pi * rng.random(len(p)))
            r = q - p
            dist = np.linalg.norm(r, axis=1)
            ldir = r / np.maximum(dist, 1e-6)[:, None]
            _, s1 = medium.box(p, ldir)
            t_max = np.minimum(s1, dist)
            if falloff > 0:
                E *= (falloff * falloff / np.maximum(dist * dist, 1e-12))[:, None]
        else:
            axis = np.broadcast_to(vec / np.linalg.norm(vec), p.shape).copy()
            if size > 0:
                c = 1.0 - rng.random(len(p)) * (1.0 - np.cos(size))
                ldir = _around(axis, c, 2 * np.pi * rng.random(len(p)))
            else:
                ldir = axis
            _, t_max = medium.box(p, ldir)
        T = medium.ratio_track(rng, p, ldir, np.maximum(t_max, 0.0))
        L += E * (T * _phase4pi(np.sum(ldir * d, axis=1), g))[:, None]
    return L


def camera_path_samples(
    opacity: np.ndarray,
    colour: np.ndarray,
    *,
    spacing: Sequence[float],
    origin: Sequence[float],
    unit_distance: float,
    ndc_to_data: np.ndarray,
    viewport: tuple[int, int],
    pixel: tuple[int, int],
    lights: Sequence[tuple[Any, ...]],
    albedo: float = 1.0,
    g: float = 0.0,
    ambient: float = 0.0,
    scattering: str = "multiple",
    n_paths: int = 1024,
    depth: float | None = None,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """``n_paths`` independent path estimates for window pixel ``pixel`` = (x, y) (origin at
    the bottom left of a ``viewport`` = (w, h) renderer): radiance ``(n, 3)`` (host medium
    units) and coverage ``(n,)`` (1 where the camera ray collided in the volume).

    ``ndc_to_data``: 4×4 matrix from NDC to dataset µm. ``depth``: the pixel's window depth
    (0…1) of opaque geometry, or None."""
    medium = _Medium(opacity, colour, spacing, origin, unit_distance)
    rng = np.random.default_rng(seed)
    n = int(n_paths)
    w, h = viewport
    frag = np.array(pixel, np.float64)[None] + rng.random((n, 2))
    ndc = 2.0 * frag / np.array([w, h], np.float64) - 1.0

    def unproject(z: float) -> np.ndarray:
        q = np.c_[ndc, np.full(n, z), np.ones(n)] @ np.asarray(ndc_to_data, np.float64).T
        return q[:, :3] / q[:, 3:]

    o = unproject(-1.0)
    d = unproject(1.0) - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t0, t1 = medium.box(o, d)
    if depth is not None and depth < 1.0:
        pd = unproject(2.0 * depth - 1.0)
        t1 = np.minimum(t1, np.sum((pd - o) * d, axis=1))
    L = np.zeros((n, 3))
    t = medium.delta_track(rng, o, d, t0, np.where(t1 > t0, t1, t0))
    hit = t >= 0
    idx = np.nonzero(hit)[0]
    p = o[idx] + t[idx, None] * d[idx]
    dd = d[idx]
    thr = np.ones((len(idx), 3))
    max_bounces = 1 if scattering == "single" else MAX_BOUNCES
    for k in range(max_bounces):
        if len(idx) == 0:
            break
        thr *= albedo * medium.albedo_rgb(p)
        L[idx] += thr * _next_event(rng, medium, p, dd, lights, g)
        if k == 0:
            L[idx] += thr * ambient  # the host's k_a·A(x) with A = 1
        if k + 1 >= max_bounces:
            break
        if k >= 2:
            q = np.minimum(thr.max(axis=1), 0.95)
            keep = (q > 0) & (rng.random(len(idx)) < q)
            thr = thr[keep] / q[keep, None]
            idx, p, dd = idx[keep], p[keep], dd[keep]
        dd = _sample_hg(rng, dd, g)
        _, s1 = medium.box(p, dd)
        tn = medium.delta_track(rng, p, dd, np.zeros(len(idx)), np.maximum(s1, 0.0))
        keep = tn >= 0
        p = p[keep] + tn[keep, None] * dd[keep]
        idx, dd, thr = idx[keep], dd[keep], thr[keep]
    return L, hit.astype(np.float64)
