"""The extinction field and the vectorised ray march every reference is built on.

Spaces and units (``docs/architecture.md``):

* Volumes are numpy arrays indexed ``[z, y, x]``; ``spacing`` is the voxel edge (x, y, z) in µm.
* **World space** is in µm: voxel (i, j, k) (i along x) has its centre at (i·sx, j·sy, k·sz), so
  the volume occupies the box [0, (nx−1)·sx] × [0, (ny−1)·sy] × [0, (nz−1)·sz] spanned by the
  voxel centres. Outside that box the extinction is 0.
* **Index space** is world divided by spacing: voxel centres at integer coordinates.

The input of every reference is the transfer-function **opacity** α ∈ [0, 1] per voxel: the
opacity of a slab ``unit_distance`` µm thick. The medium is the one the renderers draw: α is
interpolated trilinearly between voxel centres and the extinction coefficient (per µm) at a
point is σ(x) = −ln(1 − α(x)) / unit_distance. VTK's ray caster samples the interpolated
value and applies the opacity per unit distance to each step (1 − (1 − α)^(Δ/u), the same
σ), and the camera path tracer and the techniques read α from a trilinear texture. Since
−ln(1 − α) is convex, interpolating σ instead would make a denser medium wherever a dense
voxel borders a clear one (a 0 / 0.9 pair: σ·u 1.15 instead of 0.60 halfway between; the
bench scenes' transmittance 0.108 instead of 0.159 at points of ``sphere_over_slab``).

"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

#: α is clamped below 1 so that σ stays finite: 1 − 1e-6 gives σ·u ≈ 13.8, i.e. a slab one unit
#: distance thick already transmits only 1e-6.
MAX_OPACITY = 1.0 - 1e-6

#: Rays whose optical depth exceeds this are retired early; exp(−50) ≈ 2e-22 is far below what a
#: float32 result or any comparison can see.
TAU_MAX = 50.0

#: Rays marched together: about 100 bytes of state per ray, so a few MB per chunk, small enough
#: to stay in cache-friendly sizes and far below the ~1 GB memory budget.
RAY_CHUNK = 1 << 16


def extinction(opacity: np.ndarray, unit_distance: float) -> np.ndarray:
    """Extinction σ per µm from the per-voxel opacity α of a slab ``unit_distance`` µm thick.

    σ = −ln(1 − min(α, 1 − 1e-6)) / unit_distance, with α clipped to [0, 1 − 1e-6]. The result
    has the input's shape (``[z, y, x]`` for a volume) and dtype float64.
    """
    if not (unit_distance > 0 and math.isfinite(unit_distance)):
        raise ValueError(f"unit_distance {unit_distance} µm must be positive and finite")
    a = np.asarray(opacity, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError("opacity must be finite")
    return -np.log1p(-np.clip(a, 0.0, MAX_OPACITY)) / float(unit_distance)


def check_spacing(spacing: Sequence[float]) -> np.ndarray:
    """Validate a voxel size (x, y, z) in µm and return it as a float64 array of shape (3,)."""
    s = np.asarray(spacing, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or not np.all(s > 0):
        raise ValueError(f"spacing {tuple(np.ravel(s))} must be three positive µm values (x, y, z)")
    return s


class ExtinctionField:
    """σ (per µm) of the trilinearly interpolated opacity: σ(x) = −ln(1 − α(x)) / u.

    ``alpha`` (clipped to [0, :data:`MAX_OPACITY`]) and ``sigma`` (its per-voxel extinction)
    are ``[z, y, x]``; ``spacing`` and ``box_max`` are (x, y, z) in µm; ``majorant`` is max σ
    over the voxels, an upper bound of σ(x) everywhere (the interpolated α never exceeds the
    largest voxel α, and σ grows with α; used by delta and ratio tracking).

    With ``transfer`` (a piecewise-linear opacity transfer function, ``(value, α)`` points in
    increasing value) the first argument is the **scalar data** instead, and the medium is
    classified after interpolation, as VTK's ray caster and the camera path tracer draw a
    one-channel volume: α(x) = TF(trilinear data(x)), constant beyond the end points.
    ``alpha`` is then the data's classification at the voxel centres and ``majorant`` the σ of
    the TF's largest α over the data's range (the interpolated value stays in that range).
    """

    def __init__(
        self, opacity: np.ndarray, spacing: Sequence[float], unit_distance: float | None = None,
        *, transfer: Sequence[tuple[float, float]] | None = None,
    ) -> None:
        a = np.asarray(opacity)
        if a.ndim != 3 or min(a.shape) < 1:
            raise ValueError(f"opacity must be a non-empty [z, y, x] volume, got shape {a.shape}")
        self.spacing = check_spacing(spacing)
        self.unit_distance = (
            float(self.spacing.min()) if unit_distance is None else float(unit_distance)
        )
        values = np.asarray(a, dtype=np.float64)
        self._tf: tuple[np.ndarray, np.ndarray] | None = None
        if transfer is not None:
            tf = np.asarray(transfer, dtype=np.float64)
            if (tf.ndim != 2 or tf.shape[1] != 2 or tf.shape[0] < 1
                    or not np.all(np.isfinite(tf)) or np.any(np.diff(tf[:, 0]) < 0)):
                raise ValueError("transfer must be (value, alpha) points in increasing value")
            if not np.all(np.isfinite(values)):
                raise ValueError("the data must be finite")
            self._tf = (tf[:, 0], np.clip(tf[:, 1], 0.0, MAX_OPACITY))
            a = self.classify(values)
        self.sigma = extinction(a, self.unit_distance)
        self.alpha = np.clip(np.asarray(a, dtype=np.float64), 0.0, MAX_OPACITY)
        self.shape = self.sigma.shape  # (nz, ny, nx)
        nz, ny, nx = self.shape
        self.box_max = np.array([nx - 1, ny - 1, nz - 1], dtype=np.float64) * self.spacing
        self.majorant = float(self.sigma.max())
        if self._tf is not None:
            xs, ys = self._tf
            lo, hi = float(values.min()), float(values.max())
            inside = ys[(xs > lo) & (xs < hi)]
            top = max(float(self.classify(np.array([lo, hi])).max()),
                      float(inside.max()) if inside.size else 0.0)
            self.majorant = float(extinction(np.array(top), self.unit_distance))
        self._inv_unit = 1.0 / self.unit_distance
        # Pair table: entry i holds (v[i], v[i+1]) of the flattened array as one complex128, so a
        # single gather fetches both x-neighbours; four gathers replace trilinear's eight. The
        # zero tail keeps the +x/+y/+z neighbour offsets in range for points on the box's upper
        # faces and on degenerate (size-1) axes, where those neighbours' weights are 0. v is α,
        # or the data when the field is classified after interpolation.
        flat = (values if self._tf is not None else self.alpha).ravel()
        pad = nx * ny + nx + 2
        pairs = np.zeros((flat.size + pad, 2), dtype=np.float64)
        pairs[: flat.size, 0] = flat
        pairs[: flat.size - 1, 1] = flat[1:]
        self._pairs = pairs.view(np.complex128).ravel()
        self._strides = (nx * ny, nx)

    def classify(self, values: np.ndarray) -> np.ndarray:
        """α of scalar ``values`` through the transfer function (post-classified fields)."""
        assert self._tf is not None
        return np.interp(values, *self._tf)

    def sample_index(self, cx: np.ndarray, cy: np.ndarray, cz: np.ndarray) -> np.ndarray:
        """σ of the trilinear α at index-space coordinates, which must lie inside [0, n−1]
        per axis.

        Used by the marches, whose sample points are inside the box by construction. No
        clamping is needed: at a coordinate of exactly n−1 the cell index is n−1 and the
        neighbour beyond (another row, or the zero padding) gets weight 0; a rounding error of
        ~1e-13 voxel outside gives it a weight of that size.
        """
        ix = cx.astype(np.intp)
        iy = cy.astype(np.intp)
        iz = cz.astype(np.intp)
        fx = cx - ix
        fy = cy - iy
        fz = cz - iz
        gx = 1.0 - fx
        szs, sys_ = self._strides
        base = iz * szs
        base += iy * sys_
        base += ix
        rows = []
        for off in (0, sys_, szs, szs + sys_):
            v = np.take(self._pairs, base + off if off else base)
            rows.append(v.real * gx + v.imag * fx)
        c0 = rows[0] + (rows[1] - rows[0]) * fy
        c1 = rows[2] + (rows[3] - rows[2]) * fy
        alpha = c0 + (c1 - c0) * fz
        if self._tf is not None:
            alpha = self.classify(alpha)
        # α ≤ MAX_OPACITY by construction; the clip only absorbs rounding of the weights.
        np.clip(alpha, 0.0, MAX_OPACITY, out=alpha)
        out = np.log1p(np.negative(alpha, out=alpha), out=alpha)
        out *= -self._inv_unit
        return out

    def sample(self, points: np.ndarray) -> np.ndarray:
        """σ (per µm) at world points (M, 3) in µm, order (x, y, z); 0 outside the box."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        eps = 1e-9 * (1.0 + self.box_max)
        inside = np.all((p >= -eps) & (p <= self.box_max + eps), axis=1)
        out = np.zeros(p.shape[0])
        c = np.clip(p[inside] / self.spacing, 0.0, self.box_max / self.spacing)
        if c.shape[0]:
            out[inside] = self.sample_index(c[:, 0], c[:, 1], c[:, 2])
        return out


def as_field(
    opacity: np.ndarray | ExtinctionField, spacing: Sequence[float], unit_distance: float | None
) -> ExtinctionField:
    """The :class:`ExtinctionField` of per-voxel ``opacity``, or ``opacity`` itself when it is
    a field already (e.g. one classified after interpolation), whose spacing and unit distance
    then apply."""
    if isinstance(opacity, ExtinctionField):
        return opacity
    return ExtinctionField(opacity, spacing, unit_distance)


def voxel_centres(
    shape: tuple[int, int, int], spacing: Sequence[float], start: int = 0, stop: int | None = None
) -> np.ndarray:
    """World positions (M, 3) in µm, order (x, y, z), of voxels ``start:stop`` in C order.

    C order of a ``[z, y, x]`` array (x fastest), so ``values.reshape(shape)`` puts each value
    back on its voxel. The positions are computed as index × spacing in float64, exactly as a
    caller computing ``np.argwhere(mask)[:, ::-1] * spacing`` would, which keeps the seeded
    Monte-Carlo references identical between the full volume and a ``points=`` subset.
    """
    s = check_spacing(spacing)
    n = int(np.prod(shape))
    stop = n if stop is None else min(stop, n)
    k, j, i = np.unravel_index(np.arange(start, stop), shape)
    return np.stack([i, j, k], axis=1) * s


@dataclass(frozen=True)
class EvalPoints:
    """Where a reference is evaluated: every voxel centre, or caller-given world points (N, 3)."""

    shape: tuple[int, int, int]
    spacing: np.ndarray
    points: np.ndarray | None

    @classmethod
    def of(cls, field: ExtinctionField, points: np.ndarray | None) -> EvalPoints:
        if points is None:
            return cls(field.shape, field.spacing, None)
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
            raise ValueError(
                f"points must be finite world positions of shape (N, 3), got {p.shape}"
            )
        return cls(field.shape, field.spacing, p)

    @property
    def n(self) -> int:
        return int(np.prod(self.shape)) if self.points is None else self.points.shape[0]

    def get(self, start: int, stop: int) -> np.ndarray:
        """World positions (M, 3) in µm of points ``start:stop``."""
        if self.points is None:
            return voxel_centres(self.shape, self.spacing, start, stop)
        return self.points[start:stop]

    def chunks(self, size: int) -> Iterator[tuple[int, int, np.ndarray]]:
        """Yield ``(start, stop, positions)`` for consecutive blocks of at most ``size`` points."""
        size = max(1, int(size))
        for start in range(0, self.n, size):
            stop = min(start + size, self.n)
            yield start, stop, self.get(start, stop)

    def per_point(self, array: np.ndarray | None, what: str) -> np.ndarray | None:
        """Reshape a per-point vector field (``[z, y, x, 3]`` or (N, 3)) to (N, 3) float64."""
        if array is None:
            return None
        a = np.asarray(array, dtype=np.float64)
        want = (*self.shape, 3) if self.points is None else (self.n, 3)
        if a.shape != want:
            raise ValueError(f"{what} must have shape {want}, got {a.shape}")
        return a.reshape(-1, 3)

    def finish(self, values: np.ndarray) -> np.ndarray:
        """float32 result: ``[z, y, x]`` for the whole volume, (N,) for ``points``."""
        out = np.asarray(values, dtype=np.float32)
        return out.reshape(self.shape) if self.points is None else out


def clip_to_box(
    origins: np.ndarray,
    directions: np.ndarray,
    t_start: np.ndarray | float,
    t_end: np.ndarray | float,
    box_max: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Intersect the ray segments origin + t·direction, t ∈ [t_start, t_end], with the box.

    ``origins`` and ``directions`` are (M, 3) world (x, y, z); t is in µm for unit directions.
    Returns ``(t0, t1)``; the segment is empty where ``t1 <= t0``. Slab method; an axis the ray
    runs parallel to keeps the ray if the origin lies within that slab (with a rounding margin, so
    voxel centres on a face count as inside).
    """
    m = origins.shape[0]
    t0 = np.broadcast_to(np.asarray(t_start, dtype=np.float64), (m,)).copy()
    t1 = np.broadcast_to(np.asarray(t_end, dtype=np.float64), (m,)).copy()
    for a in range(3):
        o = origins[:, a]
        d = directions[:, a]
        hi = float(box_max[a])
        eps = 1e-9 * (1.0 + hi)
        parallel = d == 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            ta = (0.0 - o) * inv
            tb = (hi - o) * inv
        near = np.minimum(ta, tb)
        far = np.maximum(ta, tb)
        if parallel.any():
            inside = (o >= -eps) & (o <= hi + eps)
            near = np.where(parallel, np.where(inside, -np.inf, np.inf), near)
            far = np.where(parallel, np.where(inside, np.inf, -np.inf), far)
        np.maximum(t0, near, out=t0)
        np.minimum(t1, far, out=t1)
    return t0, t1


def optical_depth(
    field: ExtinctionField,
    origins: np.ndarray,
    directions: np.ndarray,
    t_start: np.ndarray | float,
    t_end: np.ndarray | float,
    step_um: float,
) -> np.ndarray:
    """Optical depth τ = ∫ σ ds along origin + t·direction, t ∈ [t_start, t_end] ∩ box.

    ``origins`` (M, 3) and unit ``directions`` (M, 3) are world space (x, y, z); t and
    ``step_um`` are µm. Midpoint rule with steps of ``step_um`` and a final partial step that ends
    exactly at the segment's end: exact where σ is constant within a step, O(step²) otherwise
    (σ of the interpolated α is not linear along a ray where α varies). All rays advance in
    lock-step; rays are sorted by their number of steps so the still-running ones are always
    a prefix of the arrays (no masking).
    Rays whose τ passes :data:`TAU_MAX` are retired early (T error < 2e-22).
    """
    if not (step_um > 0 and math.isfinite(step_um)):
        raise ValueError(f"step {step_um} µm must be positive and finite")
    origins = np.asarray(origins, dtype=np.float64)
    directions = np.asarray(directions, dtype=np.float64)
    m_all = origins.shape[0]
    t_start = np.broadcast_to(np.asarray(t_start, dtype=np.float64), (m_all,))
    t_end = np.broadcast_to(np.asarray(t_end, dtype=np.float64), (m_all,))
    out = np.zeros(m_all)
    for c0 in range(0, m_all, RAY_CHUNK):
        sl = slice(c0, min(c0 + RAY_CHUNK, m_all))
        out[sl] = _optical_depth_chunk(
            field, origins[sl], directions[sl], t_start[sl], t_end[sl], float(step_um)
        )
    return out


def _optical_depth_chunk(
    field: ExtinctionField,
    origins: np.ndarray,
    directions: np.ndarray,
    t_start: np.ndarray,
    t_end: np.ndarray,
    h: float,
) -> np.ndarray:
    out = np.zeros(origins.shape[0])
    if field.majorant <= 0.0:
        return out  # empty volume: nothing to integrate
    t0, t1 = clip_to_box(origins, directions, t_start, t_end, field.box_max)
    length = t1 - t0
    with np.errstate(invalid="ignore"):
        nsteps = np.where(length > 0.0, np.ceil(length / h), 0.0).astype(np.int64)
    order = np.argsort(-nsteps, kind="stable")
    order = order[nsteps[order] > 0]
    if order.size == 0:
        return out
    owner = order
    neg_steps = -nsteps[order]  # ascending, so "rays with more than k steps" is a prefix
    inv_s = 1.0 / field.spacing
    o = (origins[order] * inv_s).T.copy()  # index space, rows x, y, z
    d = (directions[order] * inv_s).T.copy()
    t = t0[order]  # start of the current step, µm
    tend = t1[order]
    tau = np.zeros(order.size)
    k = 0
    while True:
        m = int(np.searchsorted(neg_steps, -k, side="left"))
        if m == 0:
            break
        if k % 16 == 15:
            dead = tau[:m] > TAU_MAX
            if np.count_nonzero(dead) * 16 > m:
                # Retire opaque rays: write back everything not kept, then compact the arrays.
                keep = np.flatnonzero(~dead)
                out[owner] = tau
                owner, neg_steps, t, tend, tau = (a[keep] for a in (owner, neg_steps, t, tend, tau))
                o, d = o[:, keep], d[:, keep]
                m = keep.size
                if m == 0:
                    break
        tt = t[:m]
        seg = np.minimum(h, tend[:m] - tt)
        mid = tt + 0.5 * seg
        s = field.sample_index(
            o[0, :m] + mid * d[0, :m], o[1, :m] + mid * d[1, :m], o[2, :m] + mid * d[2, :m]
        )
        s *= seg
        tau[:m] += s
        tt += h
        k += 1
    out[owner] = tau
    return out


def step_um(field: ExtinctionField, step: float) -> float:
    """March step in µm from a step given in units of the smallest voxel edge."""
    if not (step > 0 and math.isfinite(step)):
        raise ValueError(f"step {step} (voxels) must be positive and finite")
    return float(step) * float(field.spacing.min())


def check_count(n: int, what: str) -> int:
    """Validate a positive integer count (rays, paths)."""
    if int(n) != n or n < 1:
        raise ValueError(f"{what} must be a positive integer, got {n}")
    return int(n)


def check_distance(d: float, what: str) -> float:
    """Validate a non-negative finite distance in µm."""
    if not (d >= 0 and math.isfinite(d)):
        raise ValueError(f"{what} {d} µm must be >= 0 and finite")
    return float(d)
