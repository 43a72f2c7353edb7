"""The light grid on the CPU (numpy): the grid, the propagation passes and the slice-by-slice
propagation, mirrored formula by formula by resources/shaders/propagate.comp.glsl
(docs/shadow-volume.md has the derivation). No VTK, no GL. Engine machinery shared by the
techniques that propagate light through a grid (shadow volume, translucency): a plugin imports
it from here, never from a sibling plugin.

Spaces: "data index" = voxel indices of the image; "grid" = indices of the light grid, cell g
at data index g · step (step = (n − 1)/(m − 1) per axis); lights arrive in dataset space (µm).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from vtkvol.engine.technique import LightSpec


#: Resolution choice -> reduction factor per axis.
RESOLUTIONS: dict[str, int] = {"full": 1, "half": 2, "quarter": 4}
#: Largest filter radius R in cells (the filter has (2R + 2)² taps per cell).
RMAX = 8
#: α is clamped here before s = −ln(1 − α), as in the compute shader (float32 of 0.999999).
MAX_OPACITY = float(np.float32(0.999999))
#: Tap radius of the thesis model (8×8 neighbourhood, σ = 1).
SEED000_RADIUS = 3


# ---------------------------------------------------------------------------------------------
# Geometry shared by both paths
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LightGrid:
    """The light grid: ``dims`` cells (x, y, z) spanning the data's point bounds.

    ``step`` is the distance between cell centres in data voxels per axis, ``cell_um`` in µm.
    """

    data_dims: tuple[int, int, int]
    dims: tuple[int, int, int]
    spacing: tuple[float, float, float]

    @classmethod
    def for_data(
        cls, data_dims: Sequence[int], spacing: Sequence[float], resolution: str
    ) -> LightGrid:
        factor = RESOLUTIONS[resolution]
        dims = []
        for n in data_dims:
            n = int(n)
            m = n if factor == 1 or n <= 2 else max(2, math.ceil(n / factor))
            dims.append(m)
        return cls(
            tuple(int(n) for n in data_dims),  # type: ignore[arg-type]
            tuple(dims),  # type: ignore[arg-type]
            tuple(float(s) for s in spacing),  # type: ignore[arg-type]
        )

    @property
    def shape_zyx(self) -> tuple[int, int, int]:
        return self.dims[2], self.dims[1], self.dims[0]

    @property
    def step(self) -> tuple[float, float, float]:
        return tuple(  # type: ignore[return-value]
            (n - 1) / (m - 1) if m > 1 else 1.0
            for n, m in zip(self.data_dims, self.dims, strict=True)
        )

    @property
    def cell_um(self) -> tuple[float, float, float]:
        return tuple(st * s for st, s in zip(self.step, self.spacing, strict=True))  # type: ignore

    def light(
        self, spec: LightSpec, origin: Sequence[float] = (0.0, 0.0, 0.0),
        direction: np.ndarray | None = None,
    ) -> tuple[str, np.ndarray]:
        """``(kind, vector)`` of a dataset-space light in grid index space: a direction in grid
        cells (not normalised) or a position in grid coordinates. float32-rounded, as the GPU
        sees it, so both paths make the same tie decisions."""
        rot = np.eye(3) if direction is None else np.asarray(direction, float)
        vec = np.asarray(spec.vector, float)
        cell = np.asarray(self.cell_um)
        if spec.kind == "point":
            index = rot.T @ (vec - np.asarray(origin, float))  # µm along the image axes
            out = index / cell
        else:
            out = (rot.T @ vec) / cell
        return spec.kind, out.astype(np.float32).astype(np.float64)

    def to_data(self, grid_values: np.ndarray) -> np.ndarray:
        """Trilinear resampling of a grid volume ``[z, y, x]`` at the data voxel centres."""
        if self.dims == self.data_dims:
            return np.asarray(grid_values, np.float32)
        from scipy.ndimage import map_coordinates

        axes = [np.arange(n) / st for n, st in zip(self.data_dims, self.step, strict=True)]
        zz, yy, xx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
        out = map_coordinates(grid_values, [zz, yy, xx], order=1, mode="nearest")
        return out.astype(np.float32)

    def nbytes_per_light(self) -> int:
        return 4 * self.dims[0] * self.dims[1] * self.dims[2]


@dataclass(frozen=True)
class Pass:
    """Slices processed along ``axis`` (0 = x) in the order given, away from the light.

    ``restrict``: store only the cells of this pass's pyramid (point lights).
    """

    axis: int
    sweep: int
    slices: tuple[int, ...]
    restrict: bool


def plan_passes(dims: Sequence[int], kind: str, vec: np.ndarray) -> list[Pass]:
    """The passes that cover the grid for one light (grid-space ``kind``/``vec``)."""
    dims = [int(d) for d in dims]
    if kind != "point":
        mag = np.abs(vec) if np.any(vec) else np.array([0.0, 0.0, 1.0])
        axis = int(np.argmax(mag))  # ties -> lowest axis, as np.argmax
        sweep = -1 if vec[axis] > 0 else 1  # start at the face nearest the light
        n = dims[axis]
        slices = tuple(range(n)) if sweep > 0 else tuple(range(n - 1, -1, -1))
        return [Pass(axis, sweep, slices, restrict=False)]
    passes = []
    for axis in range(3):
        la = float(vec[axis])
        n = dims[axis]
        start = math.ceil(la)
        for sweep in (1, -1):
            if sweep > 0:
                slices = list(range(max(0, start), n))
            else:
                slices = list(range(min(n - 1, start - 1), -1, -1))
            # Skip slices whose pyramid cross-section misses the box (it only grows).
            while slices and not _pyramid_meets_slice(dims, axis, vec, slices[0]):
                slices.pop(0)
            if slices:
                passes.append(Pass(axis, sweep, tuple(slices), restrict=True))
    return passes


def _pyramid_meets_slice(dims: Sequence[int], axis: int, pos: np.ndarray, k: int) -> bool:
    reach = abs(k - float(pos[axis]))
    for b in range(3):
        if b == axis:
            continue
        lo = max(0.0, float(pos[b]) - reach)
        hi = min(dims[b] - 1.0, float(pos[b]) + reach)
        if math.ceil(lo) > math.floor(hi):
            return False
    return True


def in_plane_axes(axis: int) -> tuple[int, int]:
    """The (u, v) axes of a slice across ``axis`` (0 = x): the other two, in increasing order."""
    return (1, 2) if axis == 0 else ((0, 2) if axis == 1 else (0, 1))


def light_softness(
    spec: LightSpec, grid: LightGrid, values: Mapping[str, Any],
    origin: Sequence[float] = (0.0, 0.0, 0.0), direction: np.ndarray | None = None,
) -> float:
    """The per-slice blur σ (light-grid cells) for ``spec``: the declared ``softness``, or, with
    ``softness_from = "light size"``, the σ whose penumbra equals the light's geometric one
    half-way through the grid along the light.

    A light of angular radius r casts a penumbra of half-width d·tan r at distance d; k slices
    of a per-slice blur of standard deviation s widen an edge to √k·s. Matching both at
    k = n/2 slices (n along the dominant axis) asks for s = √k·(Δ_axis/Δ_plane)·tan r cells;
    the σ returned is the one whose *discrete, truncated* kernel (:func:`gauss_taps`) has that
    standard deviation (:func:`softness_for_std`; for σ ≲ 0.5 the sampled Gaussian is much
    narrower than σ), at most the declared range's 4 cells. Nearer occluders get a slightly too
    wide penumbra, farther ones a too narrow one (√k against k): the limit of a slice-by-slice
    blur (docs/shadow-volume.md). ``origin`` and ``direction`` place the image in dataset space
    (as in :meth:`LightGrid.light`), so a point light's distance is to the grid's real centre.
    """
    if values.get("softness_from", "custom") == "custom" or values.get("model") == "seed000":
        return float(values["softness"])
    cell = np.asarray(grid.cell_um, float)
    if spec.is_point:
        _kind, position = grid.light(spec, origin, direction)  # grid index coordinates
        centre = (np.asarray(grid.dims, float) - 1.0) / 2.0
        to_centre = (centre - position) * cell  # µm along the grid axes
        distance = float(np.linalg.norm(to_centre))
        tan_r = spec.size / max(distance, 1e-9)
        direction = to_centre
    else:
        tan_r = math.tan(spec.size)
        direction = np.asarray(spec.vector, float)
    if tan_r <= 0:
        return 0.0
    axis = int(np.argmax(np.abs(direction / cell)))
    k = max(grid.dims[axis] / 2.0, 1.0)
    plane = float(np.mean([cell[a] for a in range(3) if a != axis]))
    return softness_for_std(math.sqrt(k) * cell[axis] / plane * tan_r)


def tap_std(softness: float) -> float:
    """Standard deviation (cells) of the per-slice kernel :func:`gauss_taps` (``softness``)."""
    radius, g = gauss_taps(softness)
    k = np.arange(radius + 1)
    return float(math.sqrt(2.0 * np.sum(g[1:] * k[1:] ** 2)))


def softness_for_std(std: float, largest: float = 4.0) -> float:
    """The softness σ ≤ ``largest`` whose kernel :func:`gauss_taps` has standard deviation
    ``std`` cells (``largest`` when even that kernel is narrower). Bisection: the kernel's
    standard deviation grows monotonically with σ."""
    if std <= 0.0:
        return 0.0
    if tap_std(largest) <= std:
        return largest
    lo, hi = 0.0, largest
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tap_std(mid) < std else (lo, mid)
    return hi


def gauss_taps(softness: float) -> tuple[int, np.ndarray]:
    """Radius R and one-sided normalised discrete Gaussian g(0..R) for ``softness`` cells.

    The Gaussian is cut at 2σ (R = ⌈2σ⌉, at most RMAX) and renormalised: the taps cost
    (2R + 2)² per cell, and the 2σ tail (4.6 %) only shortens the penumbra slightly.
    """
    if softness <= 0:
        return 0, np.ones(1)
    radius = min(RMAX, math.ceil(2.0 * softness - 1e-9))
    k = np.arange(radius + 1)
    g = np.exp(-0.5 * (k / softness) ** 2)
    return radius, g / (g[0] + 2.0 * g[1:].sum())


# ---------------------------------------------------------------------------------------------
# CPU path (numpy): the same algorithm, vectorised over a slice
# ---------------------------------------------------------------------------------------------
def prefilter_cpu(alpha: np.ndarray, grid: LightGrid) -> np.ndarray:
    """s = −ln(1 − α) averaged over each grid cell's box (see the compute shader's pass 0).

    ``alpha`` is ``[z, y, x]`` at data resolution; returns float64 ``grid.shape_zyx``.
    """
    a = np.clip(np.asarray(alpha, np.float64), 0.0, MAX_OPACITY)
    s = -np.log1p(-a)
    if grid.dims == grid.data_dims:
        return s
    for axis_xyz in range(3):
        w = _box_weights(grid.data_dims[axis_xyz], grid.dims[axis_xyz], grid.step[axis_xyz])
        s = np.moveaxis(np.tensordot(w, s, axes=([1], [2 - axis_xyz])), 0, 2 - axis_xyz)
    return s


def _box_weights(n: int, m: int, step: float) -> np.ndarray:
    """(m, n) row-normalised overlap of voxel cells with each grid cell's box."""
    half = 0.5 * max(step, 1.0)
    centres = np.arange(m) * step
    i = np.arange(n)
    lo = np.maximum(i[None, :] - 0.5, centres[:, None] - half)
    hi = np.minimum(i[None, :] + 0.5, centres[:, None] + half)
    w = np.maximum(hi - lo, 0.0)
    return w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)


def light_volume_cpu(
    opacity: np.ndarray,
    spacing: Sequence[float],
    light: LightSpec,
    *,
    unit_distance: float | None = None,
    model: str = "transmittance",
    resolution: str = "full",
    softness: float = 0.5,
    origin: Sequence[float] = (0.0, 0.0, 0.0),
    direction: np.ndarray | None = None,
) -> np.ndarray:
    """Light volume of one light on the light grid, ``[z, y, x]`` float32 visibility in 0…1.

    ``opacity`` is the TF opacity per data voxel (``[z, y, x]``, per ``unit_distance`` µm,
    default the smallest voxel edge); ``spacing`` (x, y, z) µm; ``light`` in dataset space.
    """
    grid = LightGrid.for_data(np.shape(opacity)[::-1], spacing, resolution)
    u = float(min(spacing)) if unit_distance is None else float(unit_distance)
    kind, vec = grid.light(light, origin, direction)
    return propagate_cpu(
        prefilter_cpu(opacity, grid), grid, kind, vec, model=model, softness=softness,
        unit_distance=u,
    )


def propagate_cpu(
    sigma: np.ndarray,
    grid: LightGrid,
    kind: str,
    vec: np.ndarray,
    *,
    model: str,
    softness: float,
    unit_distance: float,
) -> np.ndarray:
    """Propagate one light through the extinction grid ``sigma`` (s per cell, ``[z, y, x]``);
    ``kind``/``vec`` in grid space (:meth:`LightGrid.light`). Returns visibility, float32."""
    seed = model == "seed000"
    radius, g = (SEED000_RADIUS, np.ones(1)) if seed else gauss_taps(softness)
    inv_unit = 1.0 / unit_distance
    cell = np.asarray(grid.cell_um)
    dims = grid.dims
    out = np.ones(grid.shape_zyx, np.float64)
    point = kind == "point"
    for p in plan_passes(dims, kind, vec):
        a = p.axis
        ua, va = in_plane_axes(a)
        nu, nv, na = dims[ua], dims[va], dims[a]
        cu = np.arange(nu, dtype=np.float64)
        cv = np.arange(nv, dtype=np.float64)
        work = np.zeros((nv, nu))  # S, or 1 − W (see the compute shader): 0 outside
        for index, k in enumerate(p.slices):
            kp = k - p.sweep
            prev_inside = 0 <= kp < na
            direct = point and abs(vec[a] - k) < 1.0
            # This cell's step to the previous slice (grid cells), separable in u and v.
            if point:
                reach = max(abs(vec[a] - k), 1.0)
                step_u, step_v = (vec[ua] - cu) / reach, (vec[va] - cv) / reach
            else:
                step_u = np.full(nu, vec[ua] / abs(vec[a]))
                step_v = np.full(nv, vec[va] / abs(vec[a]))
            acc = np.zeros((nv, nu))
            pu, pv = cu + step_u, cv + step_v
            # A crossing outside the outermost cell centres has left the volume.
            p_inside = _inside(pv, nv)[:, None] & _inside(pu, nu)[None, :]
            if prev_inside and not direct and index > 0:
                acc = _filter_slice(work, pu, pv, radius, g, seed)
                if not seed:  # (the thesis model keeps what the taps inside give)
                    acc *= p_inside
            s_a = _slice(sigma, a, k)
            if seed:
                stored = np.minimum(1.0, -np.expm1(-s_a) + acc)
                vis = 1.0 - stored
            else:
                ds = np.sqrt(
                    ((step_u * cell[ua]) ** 2)[None, :]
                    + ((step_v * cell[va]) ** 2)[:, None]
                    + cell[a] ** 2
                )
                depth_per_s = ds * inv_unit
                if not prev_inside:
                    vis = np.ones((nv, nu))
                elif direct:
                    du = (cu - vec[ua]) * cell[ua]
                    dv = (cv - vec[va]) * cell[va]
                    dist = np.sqrt(
                        du[None, :] ** 2 + dv[:, None] ** 2 + ((k - vec[a]) * cell[a]) ** 2
                    )
                    vis = np.exp(-s_a * dist * inv_unit)
                else:
                    plane_k, plane_p = s_a, _slice(sigma, a, kp)
                    vv_, uu_ = np.meshgrid(cv, cu, indexing="ij")
                    su = np.broadcast_to(step_u[None, :], (nv, nu))
                    svv = np.broadcast_to(step_v[:, None], (nv, nu))
                    s_m = _between(plane_k, plane_p, uu_ + 0.5 * su, vv_ + 0.5 * svv, 0.5)
                    vis = np.clip(
                        (1.0 - acc) * np.exp(-(4.0 * s_m + s_a) / 6.0 * depth_per_s), 0.0, 1.0
                    )
                    # Rays leaving through a side face before the previous slice: Simpson's
                    # rule on the fraction f of the segment inside the volume.
                    out_mask = ~p_inside
                    if out_mask.any():
                        f = np.ones((nv, nu))
                        for c, st, n_b in ((uu_, su, nu), (vv_, svv, nv)):
                            with np.errstate(divide="ignore", invalid="ignore"):
                                f = np.where(c + st > n_b - 1, np.minimum(f, (n_b - 1 - c) / st), f)
                                f = np.where(c + st < 0, np.minimum(f, -c / st), f)
                        f = np.maximum(f, 0.0)[out_mask]
                        cu_o, cv_o = uu_[out_mask], vv_[out_mask]
                        su_o, sv_o = su[out_mask], svv[out_mask]
                        s_mf = _between(plane_k, plane_p, cu_o + 0.5 * f * su_o,
                                        cv_o + 0.5 * f * sv_o, 0.5 * f)
                        s_e = _between(plane_k, plane_p, cu_o + f * su_o, cv_o + f * sv_o, f)
                        vis[out_mask] = np.exp(
                            -(s_a[out_mask] + 4.0 * s_mf + s_e) / 6.0 * f * depth_per_s[out_mask]
                        )
                stored = 1.0 - vis * np.exp(-s_a / 6.0 * depth_per_s)
            work = stored
            target = _slice(out, a, k)
            if p.restrict:
                mask = _pyramid_mask(cu, cv, k, a, ua, va, vec)
                target[mask] = vis[mask]
            else:
                target[...] = vis
    return out.astype(np.float32)


def _slice(arr: np.ndarray, axis_xyz: int, k: int) -> np.ndarray:
    """View of slice k along x/y/z of a ``[z, y, x]`` array, indexed ``[v, u]``."""
    index: list[Any] = [slice(None)] * 3
    index[2 - axis_xyz] = k
    return arr[tuple(index)]


def _tap_weights(
    p: np.ndarray, radius: int, g: np.ndarray, seed: bool
) -> tuple[np.ndarray, np.ndarray]:
    f = np.floor(p)
    m = np.arange(2 * radius + 2)
    idx = (f[:, None] - radius + m[None, :]).astype(np.int64)
    if seed:
        x = idx - p[:, None]
        return idx, 0.3989422804014327 * np.exp(-0.5 * x * x)
    t = (p - f)[:, None]
    k = m - radius

    def gk(kk: np.ndarray) -> np.ndarray:
        ak = np.abs(kk)
        return np.where(ak <= radius, g[np.minimum(ak, radius)], 0.0)

    return idx, (1.0 - t) * gk(k)[None, :] + t * gk(k - 1)[None, :]


def _filter_slice(
    prev: np.ndarray, pu: np.ndarray, pv: np.ndarray, radius: int, g: np.ndarray, seed: bool
) -> np.ndarray:
    """Σ w_u w_v · prev over the (2R + 2)² taps around the crossings (pu × pv); 0 outside the
    slice. Separable: a u pass over all rows, then a v pass."""
    nv, nu = prev.shape
    iu, wu = _tap_weights(pu, radius, g, seed)
    iv, wv = _tap_weights(pv, radius, g, seed)
    rows = np.zeros((nv, pu.size))
    for m in range(iu.shape[1]):
        col = iu[:, m]
        ok = (col >= 0) & (col < nu)
        rows += prev[:, np.clip(col, 0, nu - 1)] * np.where(ok, wu[:, m], 0.0)[None, :]
    res = np.zeros((pv.size, pu.size))
    for m in range(iv.shape[1]):
        row = iv[:, m]
        ok = (row >= 0) & (row < nv)
        res += rows[np.clip(row, 0, nv - 1), :] * np.where(ok, wv[:, m], 0.0)[:, None]
    return res


def _inside(p: np.ndarray, n: int) -> np.ndarray:
    return (p >= 0.0) & (p <= n - 1)


def _between(
    plane_k: np.ndarray, plane_p: np.ndarray, pu: np.ndarray, pv: np.ndarray,
    lam: np.ndarray | float,
) -> np.ndarray:
    """s at in-plane points (pu, pv) a fraction ``lam`` of the way from slice k (``plane_k``,
    ``[v, u]``) to slice kp (``plane_p``): trilinear, 0 outside the grid (``sigmaBetween``)."""
    nv, nu = plane_k.shape
    iu = np.floor(pu).astype(np.int64)
    iv = np.floor(pv).astype(np.int64)
    tu = pu - iu
    tv = pv - iv
    res = np.zeros(np.shape(pu))
    for dv, wv in ((0, 1.0 - tv), (1, tv)):
        rv = iv + dv
        for du, wu in ((0, 1.0 - tu), (1, tu)):
            ru = iu + du
            ok = (rv >= 0) & (rv < nv) & (ru >= 0) & (ru < nu)
            r, c = np.clip(rv, 0, nv - 1), np.clip(ru, 0, nu - 1)
            vals = (1.0 - lam) * plane_k[r, c] + lam * plane_p[r, c]
            res += np.where(ok, vals, 0.0) * wv * wu
    return res


def _pyramid_mask(
    cu: np.ndarray, cv: np.ndarray, k: int, a: int, ua: int, va: int, vec: np.ndarray
) -> np.ndarray:
    """Cells of slice k whose largest |cell − light| component is along ``a`` (ties: lower
    axis wins), as in the compute shader."""
    da = abs(k - vec[a])
    du = np.abs(cu - vec[ua])[None, :]
    dv = np.abs(cv - vec[va])[:, None]

    def beats(d: np.ndarray, b: int) -> np.ndarray:
        return d < da if b < a else d <= da

    return beats(du, ua) & beats(dv, va)
