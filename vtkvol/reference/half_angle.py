"""Numpy twin of half-angle slicing (:mod:`vtkvol.engine.renderers.half_angle`).

One frame of the renderer for a few pixels of a small volume (≤ 32³ in the tests), written
from the algorithm's description rather than from the shader's control flow:

* the **light buffer** is propagated plane by plane over the whole ``M × M`` grid (vectorised),
  exactly as the renderer's light pass: direct T·(1 − α_u)^(Δ_l/unit), indirect: the mean of 4
  bilinear taps (clamped at the edges, like a GL texture) at the per-slice rotation
  ``blur_angles[k]``, times exp(−τ_i Δ_l), τ_i = k·τ·(1 − tint·colour);
* each pixel's **eye samples** (the ray's crossing with every plane, inside the voxel-centre
  box) are collected with the light buffer *as it was before that plane* and then composited
  **front to back along the ray, sorted by distance** — whatever the slice order was. So a
  renderer that used the wrong operator for its slice order (under for back-to-front) would
  not match.

Medium: pre-classified (``alpha`` ``[z, y, x]`` opacity per unit distance and ``colour``
``[z, y, x, ≥3]``, trilinear, clamped at the edges) or post-classified (``scalars`` normalised
to [0, 1], trilinear, then ``table`` ``[4, N]``: opacity, r, g, b, interpolated linearly
between entries). Coordinates: dataset µm, voxel centres at ``origin + i·spacing``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from vtkvol.reference.camera_paths import _Medium


class _Classified(_Medium):
    """α_u(p) and colour(p), pre- or post-classified."""

    def __init__(self, spacing: Sequence[float], origin: Sequence[float], unit_distance: float,
                 *, alpha: np.ndarray | None = None, colour: np.ndarray | None = None,
                 scalars: np.ndarray | None = None, table: np.ndarray | None = None) -> None:
        grid = alpha if alpha is not None else scalars
        col = colour if colour is not None else np.zeros((*np.shape(grid), 3))
        super().__init__(grid, col, spacing, origin, unit_distance)
        self.table = None if table is None else np.asarray(table, np.float64)

    def _lookup(self, s: np.ndarray, row: int) -> np.ndarray:
        n = self.table.shape[1]
        x = np.clip(s, 0, 1) * (n - 1)
        i0 = np.minimum(np.floor(x).astype(np.int64), n - 2)
        f = x - i0
        return self.table[row, i0] * (1 - f) + self.table[row, i0 + 1] * f

    def alpha_at(self, p: np.ndarray) -> np.ndarray:
        v = self._trilinear(self.alpha, p)
        if self.table is not None:
            v = self._lookup(v, 0)
        return np.clip(v, 0.0, 0.999999)

    def colour_at(self, p: np.ndarray) -> np.ndarray:
        if self.table is not None:
            s = self._trilinear(self.alpha, p)
            return np.stack([self._lookup(s, r) for r in (1, 2, 3)], axis=-1)
        return self._trilinear(self.colour, p)

    def inside(self, p: np.ndarray) -> np.ndarray:
        v = (p - self.origin) / self.spacing
        return np.all((v >= -1e-4) & (v <= self.dims - 1 + 1e-4), axis=1)


def _bilinear(buf: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """GL ``texture()`` of ``buf`` ``[M, M, C]`` (row = y) at ``uv`` ``[n, 2]``, linear filter,
    clamp to edge."""
    m = buf.shape[0]
    x = uv * m - 0.5
    i0 = np.floor(x).astype(np.int64)
    f = x - i0
    a = np.clip(i0, 0, m - 1)
    b = np.clip(i0 + 1, 0, m - 1)
    fx, fy = f[:, 0:1], f[:, 1:2]
    return ((buf[a[:, 1], a[:, 0]] * (1 - fx) + buf[a[:, 1], b[:, 0]] * fx) * (1 - fy)
            + (buf[b[:, 1], a[:, 0]] * (1 - fx) + buf[b[:, 1], b[:, 0]] * fx) * fy)


def half_angle_pixels(medium: dict[str, Any], geometry: dict[str, Any],
                      ndc_to_data: np.ndarray, viewport: tuple[int, int],
                      pixels: Sequence[tuple[int, int]],
                      blur_angle: Callable[[int, int], float]) -> np.ndarray:
    """Premultiplied RGBA ``[len(pixels), 4]`` of one frame at window pixels ``(x, y)`` (y from
    the bottom, viewport at the window's origin).

    ``medium``: ``spacing``, ``origin``, ``unit_distance`` and either ``alpha`` + ``colour``
    or ``scalars`` + ``table`` (see the module docstring). ``geometry``: the renderer's
    :meth:`~vtkvol.engine.renderers.half_angle.HalfAngleSlicing.frame_geometry` (slice
    normal ``axis``, plane positions ``sigmas``, ``step``, light frame ``light_dir``/``u``/
    ``w``/``centre``/``radius``, ``light_resolution``, ``blur_radius``, the light and the
    material). ``blur_angle(k, frame)``: the rotation of slice k's blur taps."""
    med = _Classified(medium["spacing"], medium["origin"], medium["unit_distance"],
                      alpha=medium.get("alpha"), colour=medium.get("colour"),
                      scalars=medium.get("scalars"), table=medium.get("table"))
    g = geometry
    s, ldir = np.asarray(g["axis"], float), np.asarray(g["light_dir"], float)
    u_ax, w_ax, centre = (np.asarray(g[k], float) for k in ("u", "w", "centre"))
    radius, step, m = float(g["radius"]), float(g["step"]), int(g["light_resolution"])
    unit = float(medium["unit_distance"])
    spec = g["light"]
    E = np.asarray(spec.color, float)
    wgt, kind, tint = g["indirect_strength"], g["indirect_extinction"], g["tint"]
    hg = float(g["g"])

    def phase4pi(c: np.ndarray) -> np.ndarray:
        dn = 1.0 + hg * hg - 2.0 * hg * c
        return (1.0 - hg * hg) / (dn * np.sqrt(dn))

    def light_uv(p: np.ndarray) -> np.ndarray:
        q = p - centre
        return np.stack([q @ u_ax, q @ w_ax], axis=1) / (2 * radius) + 0.5

    # Camera rays through the pixel centres, clipped to the voxel-centre box.
    pix = np.asarray(pixels, float)
    ndc = 2 * (pix + 0.5) / np.asarray(viewport, float) - 1

    def unproject(z: float) -> np.ndarray:
        q = np.c_[ndc, np.full(len(ndc), z), np.ones(len(ndc))] @ np.asarray(ndc_to_data).T
        return q[:, :3] / q[:, 3:]

    o = unproject(-1.0)
    d = unproject(1.0) - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t0, t1 = med.box(o, d)
    # Light-buffer texel centres as points on the plane through the centre ⟂ l.
    c = (np.arange(m) + 0.5) / m
    uu, vv = np.meshgrid(c, c)  # [row y, column x]
    uv_grid = np.c_[uu.ravel(), vv.ravel()]
    xy = (uv_grid - 0.5) * 2 * radius
    q = centre + xy[:, :1] * u_ax + xy[:, 1:] * w_ax
    sl = float(s @ ldir)
    dl = step / sl
    light = np.ones((m, m, 4))
    samples: list[list[tuple[float, float, np.ndarray]]] = [[] for _ in pixels]
    cos_t = d @ s
    for k, sigma in enumerate(g["sigmas"]):
        # Eye: each pixel's crossing with plane k, lit by the buffer before this plane.
        t = (sigma - o @ s) / cos_t
        hit = (t >= t0) & (t <= t1)
        if hit.any():
            idx = np.nonzero(hit)[0]
            p = o[idx] + t[idx, None] * d[idx]
            au = med.alpha_at(p)
            lt = _bilinear(light, light_uv(p))
            L = (lt[:, 3:4] + wgt * lt[:, :3]) / (1 + wgt)
            if spec.is_point:
                r = np.asarray(spec.vector, float) - p
                to_light = r / np.linalg.norm(r, axis=1, keepdims=True)
                e = E * (spec.falloff_distance ** 2 / np.maximum((r * r).sum(1), 1e-12)
                         )[:, None] if spec.falloff_distance > 0 else np.broadcast_to(E, L.shape)
            else:
                to_light = np.broadcast_to(-ldir, p.shape)
                e = np.broadcast_to(E, L.shape)
            ph = phase4pi((to_light * d[idx]).sum(1))[:, None]
            col = g["exposure"] * g["albedo"] * med.colour_at(p) * (e * ph * L + g["ambient"])
            a = 1.0 - (1.0 - au) ** (step / np.abs(cos_t[idx]) / unit)
            for j, i in enumerate(idx):
                if au[j] > 0:
                    samples[i].append((float(t[i]), float(a[j]), col[j]))
        # Light: plane k attenuates the buffer.
        p = q + ((sigma - q @ s) / sl)[:, None] * ldir
        au = np.where(med.inside(p), med.alpha_at(p), 0.0)
        tau = -np.log(1.0 - au) / unit
        tau_i = kind * tau[:, None] * (1.0 - tint * med.colour_at(p))
        r_uv = g["blur_radius"] / (2 * radius)
        ang = blur_angle(k, int(g["frame"]))
        blur = np.zeros((len(uv_grid), 3))
        for n in range(4):
            ph = ang + np.pi / 2 * n
            blur += _bilinear(light, uv_grid + r_uv * np.array([np.cos(ph), np.sin(ph)]))[:, :3]
        blur *= 0.25
        new = np.empty((m * m, 4))
        new[:, :3] = blur * np.exp(-tau_i * dl)
        new[:, 3] = light.reshape(-1, 4)[:, 3] * np.exp(-tau * dl)
        light = new.reshape(m, m, 4)
    out = np.zeros((len(pixels), 4))
    for i, ss in enumerate(samples):
        acc = np.zeros(4)
        for _t, a, col in sorted(ss, key=lambda x: x[0]):
            acc += (1 - acc[3]) * np.r_[col * a, a]
        out[i] = acc
    return out


__all__ = ["half_angle_pixels"]
