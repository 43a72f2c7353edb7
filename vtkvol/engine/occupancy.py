"""Empty-space skipping: which bricks of the volume can hold a visible ray sample.

The volume is split into bricks of ``BRICK``³ voxels. Once per data set the host computes each
brick's minimum and maximum scalar per component over the brick **plus an apron** (one voxel
on every side for trilinear sampling; two, and a widened range, for the corrected trilinear
filter, whose six neighbour fetches reach one voxel further and can overshoot). Every sample
the ray caster takes in a brick interpolates only voxels of that brick and its apron, so its
scalar lies in the brick's range. A transfer-function, crop or slice-weight edit then turns the
ranges into occupancy without another pass over the data: a brick is empty when

* every used component's opacity function is 0 over the whole range (a table lookup: the
  maximum of a piecewise-linear function over an interval, widened by two entries of VTK's
  opacity table so the GPU's interpolated table is 0 there as well), or
* the brick lies entirely in regions the cropping flags hide, or
* a slice weight is 0 (below VTK's 1e-10 cut) across the brick on some axis.

Samples in empty bricks contribute exactly nothing (opacity 0), so the ray caster may jump
over them (``resources/shaders/host_empty_space.glsl``). docs/empty-space-skipping.md has the
method and the measurements.

Coordinates: arrays are ``[z, y, x]``; voxel coordinates put voxel centres at integers
(``v = texture · N − 0.5``); brick ``b`` covers voxel coordinates ``[B·b, B·b + B)`` on each axis.
This module is numpy only; the host reads VTK's objects and passes plain values in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Brick edge in voxels along the finest axis: 8³ bricks cost 1/512 of the data in occupancy
#: (Krüger & Westermann); coarser axes get fewer voxels (:func:`brick_for_spacing`).
BRICK = 8
#: VTK samples an opacity function into a table of (at least) this many entries and the GPU
#: interpolates linearly between entries; ranges are widened by two entries' worth.
TABLE_ENTRIES = 1024
#: Below this share of empty bricks the host leaves skipping out of the shader: in occupied
#: bricks each sample pays one grid fetch (8–13 % of a frame on llvmpipe), which a few jumps
#: do not win back.
MIN_EMPTY_FRACTION = 0.1
#: VTK discards samples whose slice weight is below this (host_slice_weights.glsl).
WEIGHT_CUT = 1e-10


@dataclass(frozen=True)
class BrickRanges:
    """Per-brick scalar range of every component, apron included.

    ``lo``/``hi``: float64 ``[c, bz, by, bx]`` in data units; a brick holding NaN gets the
    range (−inf, +inf), so it is never skipped. ``apron``: voxels added on every side.
    ``shape_zyx``: the data's shape.
    """

    lo: np.ndarray
    hi: np.ndarray
    apron: int
    shape_zyx: tuple[int, int, int]

    @property
    def bricks_zyx(self) -> tuple[int, int, int]:
        return tuple(int(n) for n in self.lo.shape[1:])  # type: ignore[return-value]


Brick = int | Sequence[int]
"""A brick's edge in voxels: one for every axis, or ``(bz, by, bx)``."""


def brick_shape(brick: Brick) -> tuple[int, int, int]:
    """``(bz, by, bx)`` voxels of a brick."""
    if isinstance(brick, int | np.integer):
        return (int(brick),) * 3
    bz, by, bx = (int(b) for b in brick)
    return bz, by, bx


def brick_for_spacing(spacing_xyz: Sequence[float], brick: int = BRICK) -> tuple[int, int, int]:
    """``(bz, by, bx)``: ``brick`` voxels along the finest axis and about as many µm along the
    others (at least 2 voxels), so bricks of anisotropic stacks are near cubes in space: an
    8³-voxel brick of a confocal stack with 5× coarser z would reach 5× deeper than wide."""
    sizes = [abs(float(s)) or 1.0 for s in spacing_xyz]  # negative spacing: mirrored axes
    finest = min(sizes)
    x, y, z = (max(2, min(brick, round(brick * finest / s))) for s in sizes)
    return z, y, x


def brick_grid(shape_zyx: Sequence[int], brick: Brick = BRICK) -> tuple[int, int, int]:
    """Number of bricks per axis, ``[z, y, x]``."""
    return tuple(-(-int(n) // b)  # type: ignore[return-value]
                 for n, b in zip(shape_zyx, brick_shape(brick), strict=True))


def brick_ranges(values: np.ndarray, apron: int = 1, brick: Brick = BRICK) -> BrickRanges:
    """Min/max per brick and component of ``values`` (``[z, y, x]`` or ``[z, y, x, c]``) over
    the brick and ``apron`` voxels around it (clamped at the volume's faces, as the texture's
    clamp-to-edge sampling is)."""
    if values.ndim == 3:
        values = values[..., None]
    if values.ndim != 4 or min(values.shape[:3]) < 1:
        raise ValueError(f"expected a [z, y, x] or [z, y, x, c] array, not shape {values.shape}")
    shape = tuple(int(n) for n in values.shape[:3])
    grid = brick_grid(shape, brick)
    los, his = [], []
    edges = brick_shape(brick)
    for c in range(values.shape[3]):
        lo = hi = values[..., c]
        # min/max over a box is separable: reduce z, then y, then x, each over its bricks
        # and their aprons; after the first axis the arrays are a brick's width smaller.
        for axis in (0, 1, 2):
            lo = _reduce_axis(lo, axis, grid[axis], edges[axis], apron, np.minimum)
            hi = _reduce_axis(hi, axis, grid[axis], edges[axis], apron, np.maximum)
        lo = lo.astype(np.float64)
        hi = hi.astype(np.float64)
        bad = np.isnan(lo) | np.isnan(hi)
        lo[bad], hi[bad] = -np.inf, np.inf
        los.append(lo)
        his.append(hi)
    return BrickRanges(np.stack(los), np.stack(his), apron, shape)  # type: ignore[arg-type]


def _reduce_axis(a: np.ndarray, axis: int, bricks: int, edge: int, apron: int,
                 op: np.ufunc) -> np.ndarray:
    """``op`` (np.minimum or np.maximum) along ``axis`` over each brick of ``edge`` voxels and
    ``apron`` voxels either side, clamped at the faces (clamp-to-edge sampling): the axis
    shrinks to ``bricks``. NaN propagates, as ``op`` does."""
    n = a.shape[axis]
    padded = bricks * edge - n
    if padded:  # the last brick is partial: repeat the face voxel (it is in its window)
        a = np.concatenate([a, np.repeat(a.take([n - 1], axis=axis), padded, axis=axis)],
                           axis=axis)
    shape = (*a.shape[:axis], bricks, edge, *a.shape[axis + 1:])
    out = op.reduce(a.reshape(shape), axis=axis + 1)
    starts = np.arange(bricks) * edge
    for s in range(1, apron + 1):
        before = np.clip(starts - s, 0, n - 1)
        after = np.clip(starts + edge - 1 + s, 0, n - 1)
        op(out, a.take(before, axis=axis), out=out)
        op(out, a.take(after, axis=axis), out=out)
    return out


def widen_for_corrected(ranges: BrickRanges) -> BrickRanges:
    """Ranges for Csébfalvi's corrected trilinear filter: f̃ = f + Σ_a s_a·(t_a² − t_a)/2 with
    |s_a| ≤ 2·(hi − lo) and (t² − t)/2 ∈ [−1/8, 0] can leave the neighbours' range by
    3·2/8 = 3/4 of its width on either side."""
    span = ranges.hi - ranges.lo
    with np.errstate(invalid="ignore"):
        lo = np.where(np.isfinite(span), ranges.lo - 0.75 * span, -np.inf)
        hi = np.where(np.isfinite(span), ranges.hi + 0.75 * span, np.inf)
    return BrickRanges(lo, hi, ranges.apron, ranges.shape_zyx)


def max_over_intervals(
    xs: np.ndarray, ys: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """Maximum of the piecewise-linear function through ``(xs, ys)`` (constant beyond its end
    nodes, as VTK clamps) over each interval ``[lo, hi]``: the larger of its ends and of the
    nodes inside."""
    xs = np.asarray(xs, np.float64)
    ys = np.asarray(ys, np.float64)
    if xs.size == 0:
        return np.zeros(lo.shape)
    ends_lo = np.interp(np.clip(lo, xs[0], xs[-1]), xs, ys)
    ends_hi = np.interp(np.clip(hi, xs[0], xs[-1]), xs, ys)
    out = np.maximum(ends_lo, ends_hi)
    # Nodes inside [lo, hi] are a contiguous run xs[first:stop] (xs sorted): a range-maximum
    # query on a sparse table, so label transfer functions with thousands of nodes stay cheap.
    first = np.searchsorted(xs, lo, side="left")
    stop = np.searchsorted(xs, hi, side="right")
    count = stop - first
    has = count > 0
    if np.any(has):
        table = [ys]
        while (1 << len(table)) <= len(ys):  # level k: maxima of 2^k consecutive nodes
            prev, half = table[-1], 1 << (len(table) - 1)
            table.append(np.maximum(prev[:-half], prev[half:]))
        f, n = first[has], count[has]
        level = np.floor(np.log2(n)).astype(int)
        inner = np.empty(len(f))
        for k in np.unique(level):
            sel = level == k
            row = table[k]
            inner[sel] = np.maximum(row[f[sel]], row[f[sel] + n[sel] - (1 << k)])
        out[has] = np.maximum(out[has], inner)
    return out


def transfer_occupancy(
    ranges: BrickRanges,
    functions: Sequence[tuple[np.ndarray, np.ndarray] | None],
    table_range: Sequence[tuple[float, float]],
) -> np.ndarray:
    """Bricks where some component's opacity can be non-zero: bool ``[bz, by, bx]``.

    ``functions[c]``: the nodes ``(xs, ys)`` of component ``c``'s opacity function in data
    units, or None for a component that cannot contribute (weight 0, or not the opacity
    component of dependent data). ``table_range[c]``: the value range (r0, r1) VTK samples
    component ``c``'s opacity table over (its scalar range).

    The GPU reads the table, not the function: entry i holds f(r0 + i·(r1 − r0)/(W − 1)),
    W ≥ 1024 entries, interpolated linearly with clamping at both ends. A value v therefore
    mixes entries up to two entries' width away, so ranges are widened by that much; they are
    also clamped to [r0, r1], since no lookup reaches beyond the end entries, and a brick all
    at r0 (or all at r1) reads exactly the end entry f(r0) (f(r1)): the empty background of a
    volume whose opacity ramp starts right at its minimum stays empty."""
    occupied = np.zeros(ranges.bricks_zyx, bool)
    for c, function in enumerate(functions):
        if function is None:
            continue
        xs, ys = function
        r0, r1 = (float(v) for v in table_range[c])
        if not (np.isfinite(r0) and np.isfinite(r1)) or r1 < r0:
            r0, r1 = -np.inf, np.inf
        span = max(r1 - r0, float(xs[-1] - xs[0]), 1e-30) if np.isfinite(r1 - r0) else np.inf
        delta = 2.0 * span / TABLE_ENTRIES
        lo, hi = ranges.lo[c], ranges.hi[c]
        with np.errstate(invalid="ignore"):
            lo_w = np.where(lo >= r1, r1, np.clip(lo - delta, r0, r1))
            hi_w = np.where(hi <= r0, r0, np.clip(hi + delta, r0, r1))
        # NaN bricks (−inf, inf) read anything the table holds.
        lo_w = np.where(np.isfinite(lo), lo_w, r0 if np.isfinite(r0) else -np.inf)
        hi_w = np.where(np.isfinite(hi), hi_w, r1 if np.isfinite(r1) else np.inf)
        occupied |= max_over_intervals(xs, ys, lo_w, hi_w) > 0
    return occupied


def _axis_extent(n: int, grid: int, brick: int, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Voxel-coordinate span ``[lo, hi]`` of every brick along one axis, ``margin`` voxels
    wider, clipped to where samples can lie (−0.5 … n − 0.5)."""
    b = np.arange(grid, dtype=np.float64)
    lo = np.maximum(b * brick - margin, -0.5)
    hi = np.minimum(b * brick + brick + margin, n - 0.5)
    return lo, hi


def crop_occupancy(
    shape_zyx: Sequence[int],
    origin: Sequence[float],
    spacing: Sequence[float],
    planes: Sequence[float],
    flags: int,
    brick: Brick = BRICK,
) -> np.ndarray:
    """Bricks that reach a region VTK's cropping shows: bool ``[bz, by, bx]``.

    ``origin``, ``spacing`` (x, y, z; µm, dataset space), ``planes`` (xmin, xmax, ymin, ymax,
    zmin, zmax; µm) and the 27 region ``flags`` as the mapper holds them. Per axis a brick
    overlaps region 0 (below the first plane), 1 (between) and/or 2 (above); it is kept when
    any overlapped combination is shown. Half a voxel of margin absorbs rounding."""
    nz, ny, nx = (int(n) for n in shape_zyx)
    grid = brick_grid((nz, ny, nx), brick)
    overlaps = []  # per axis x, y, z: bool [3, bricks]
    edges = brick_shape(brick)[::-1]
    for axis, (n, g) in enumerate(zip((nx, ny, nz), grid[::-1], strict=True)):
        lo, hi = _axis_extent(n, g, edges[axis], 0.5)
        lo = origin[axis] + spacing[axis] * lo
        hi = origin[axis] + spacing[axis] * hi
        lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)  # negative spacing
        p0, p1 = planes[2 * axis], planes[2 * axis + 1]
        overlaps.append(np.stack([lo < p0, (hi >= p0) & (lo < p1), hi >= p1]))
    ox, oy, oz = overlaps
    kept = np.zeros(grid, bool)
    for region in range(27):
        if not (int(flags) >> region) & 1:
            continue
        rx, ry, rz = region % 3, (region // 3) % 3, region // 9
        kept |= oz[rz][:, None, None] & oy[ry][None, :, None] & ox[rx][None, None, :]
    return kept


def weight_occupancy(
    shape_zyx: Sequence[int], weights: np.ndarray, brick: Brick = BRICK
) -> np.ndarray:
    """Bricks where every axis' slice weight can reach ``WEIGHT_CUT``: bool ``[bz, by, bx]``.

    ``weights``: (3, W) rows x, y, z over 0…1 across the point bounds, interpolated linearly
    between the W entries as the shader's lookup table is; a brick's maximum on an axis is the
    largest entry of the table cells its span touches."""
    nz, ny, nx = (int(n) for n in shape_zyx)
    grid = brick_grid((nz, ny, nx), brick)
    width = weights.shape[1]
    keep_axis = []
    edges = brick_shape(brick)[::-1]
    for axis, (n, g) in enumerate(zip((nx, ny, nz), grid[::-1], strict=True)):
        lo, hi = _axis_extent(n, g, edges[axis], 0.5)
        scale = (width - 1) / max(n - 1, 1)
        first = np.clip(np.floor(lo * scale), 0, width - 1).astype(int)
        last = np.clip(np.ceil(hi * scale), 0, width - 1).astype(int)
        row = weights[axis]
        peak = np.array([row[f : t + 1].max() for f, t in zip(first, last, strict=True)])
        keep_axis.append(peak >= WEIGHT_CUT)
    kx, ky, kz = keep_axis
    return kz[:, None, None] & ky[None, :, None] & kx[None, None, :]


def non_decreasing(function: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether an opacity function never decreases (then its zero set is a prefix of the
    value axis: what maximum-intensity projection needs to skip zero-opacity samples)."""
    _xs, ys = function
    return bool(np.all(np.diff(np.asarray(ys, np.float64)) >= 0))
