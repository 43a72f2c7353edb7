"""Fit a volume into GPU limits: a maximum 3-D texture size per axis and a memory budget.

Strategies (``fit_volume(strategy=…)``):

- ``"average"``: area-average (block mean) downsampling by integer factors per axis; edge
  blocks that are cut off by the volume border average the voxels they have, so no voxel
  is dropped. Voxel size grows by the factors.
- ``"subsample"``: keep every f-th voxel per axis (fast, aliases fine structure).
- ``"crop"``: keep a sub-box at full resolution, centred unless ``crop_offset`` is given.
- ``"none"``: never change the data; raise :class:`VolumeReadError` if it does not fit.
- ``"auto"``: ``"average"`` (the choice that keeps all of the data's extent and the least
  aliasing).

Whatever is done is written into ``notes`` (from what shape to what shape, why) and into
``metadata["fit"]``; nothing is dropped silently.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, get_args

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.progress import CancelCallback, Progress, ProgressCallback, slabs
from vtkvol.io.volume_data import Spacing, VolumeData, format_bytes

__all__ = ["FIT_STRATEGIES", "FitStrategy", "fit_volume", "plan_factors"]

FitStrategy = Literal["auto", "crop", "subsample", "average", "none"]
FIT_STRATEGIES: tuple[str, ...] = get_args(FitStrategy)


def _shape_text(shape: Sequence[int]) -> str:
    c, z, y, x = shape
    return f"{x}×{y}×{z} (x×y×z, {c} channel{'s' if c != 1 else ''})"


def _reasons(
    shape: Sequence[int], itemsize: int, max_texture_size: int | None, budget: int | None
) -> list[str]:
    """Why a volume of ``shape`` [c, z, y, x] does not fit; empty when it does."""
    reasons: list[str] = []
    _, z, y, x = shape
    if max_texture_size is not None:
        for axis, n in zip("xyz", (x, y, z), strict=True):
            if n > max_texture_size:
                reasons.append(f"{axis} has {n} voxels > max texture size {max_texture_size}")
    nbytes = math.prod(shape) * itemsize
    if budget is not None and nbytes > budget:
        reasons.append(f"{format_bytes(nbytes)} > memory budget {format_bytes(budget)}")
    return reasons


def plan_factors(
    shape_czyx: Sequence[int],
    itemsize: int,
    voxel_size_um: Sequence[float],
    max_texture_size: int | None,
    memory_budget_bytes: int | None,
    source: str | None = None,
) -> tuple[int, int, int]:
    """Smallest integer reduction factors (x, y, z) that make the volume fit.

    First each axis is reduced to at most ``max_texture_size``; then, while over the memory
    budget, the factor of the axis with the finest effective voxel (voxel size × factor) is
    raised, so that anisotropic data become more isotropic rather than losing z first.
    """
    c, z, y, x = (int(v) for v in shape_czyx)
    sizes = [x, y, z]
    limit = max_texture_size
    factors = [max(1, math.ceil(n / limit)) if limit else 1 for n in sizes]

    def out_sizes() -> list[int]:
        return [math.ceil(n / f) for n, f in zip(sizes, factors, strict=True)]

    if memory_budget_bytes is not None:
        per_voxel = c * itemsize
        if per_voxel > memory_budget_bytes:
            raise VolumeReadError(
                source,
                f"the memory budget {format_bytes(memory_budget_bytes)} cannot hold even one "
                f"voxel of {c} channel(s)",
            )
        while math.prod(out_sizes()) * per_voxel > memory_budget_bytes:
            current = out_sizes()
            candidates = [i for i in range(3) if current[i] > 1]
            i = min(
                candidates,
                key=lambda a: (voxel_size_um[a] * factors[a], -current[a]),
            )
            # Jump to the next factor that actually shrinks this axis.
            target = current[i] - 1
            factors[i] = max(factors[i] + 1, math.ceil(sizes[i] / target))
    return factors[0], factors[1], factors[2]


def _crop_sizes(
    shape_czyx: Sequence[int],
    itemsize: int,
    max_texture_size: int | None,
    budget: int | None,
    source: str | None,
) -> list[int]:
    """Box size (x, y, z) in voxels that fits the limits, shrinking all axes alike."""
    c, z, y, x = (int(v) for v in shape_czyx)
    sizes = [min(n, max_texture_size) if max_texture_size else n for n in (x, y, z)]
    if budget is None:
        return sizes
    per_voxel = c * itemsize
    if per_voxel > budget:
        raise VolumeReadError(
            source,
            f"the memory budget {format_bytes(budget)} cannot hold even one voxel of {c} "
            "channel(s)",
        )
    allowed = budget // per_voxel
    if math.prod(sizes) > allowed:
        scale = (allowed / math.prod(sizes)) ** (1.0 / 3.0)
        sizes = [max(1, int(n * scale)) for n in sizes]
        while math.prod(sizes) > allowed:
            sizes[sizes.index(max(sizes))] -= 1
    return sizes


def _sum_blocks_2d(plane: np.ndarray, fy: int, fx: int) -> np.ndarray:
    """Sums over (fy, fx) blocks of a 2-D array; the last row/column of blocks may be partial.

    Strided adds (one per offset in the block) instead of ``np.add.reduceat``: about 8×
    faster on large planes, which matters when averaging multi-GB stacks.
    """
    ny, nx = plane.shape
    ny_full, nx_full = ny - ny % fy, nx - nx % fx
    rows = plane[0:ny_full:fy].copy()
    for k in range(1, fy):
        rows += plane[k:ny_full:fy]
    if ny_full < ny:
        rows = np.concatenate([rows, plane[ny_full:].sum(axis=0, keepdims=True)])
    out = rows[:, 0:nx_full:fx].copy()
    for k in range(1, fx):
        out += rows[:, k:nx_full:fx]
    if nx_full < nx:
        out = np.concatenate([out, rows[:, nx_full:].sum(axis=1, keepdims=True)], axis=1)
    return out


def _block_mean(array: np.ndarray, factors: tuple[int, int, int], progress: Progress) -> np.ndarray:
    """Block mean over (fz, fy, fx) blocks of a [c, z, y, x] array; partial edge blocks too."""
    fx, fy, fz = factors
    n_c, n_z, n_y, n_x = array.shape
    out_shape = (n_c, math.ceil(n_z / fz), math.ceil(n_y / fy), math.ceil(n_x / fx))
    out = np.empty(out_shape, dtype=array.dtype)
    is_float = array.dtype.kind == "f"
    info = np.iinfo(array.dtype) if array.dtype.kind in "ui" else None
    per_block = fx * fy * fz
    # float32 sums are exact for integers below 2**24; otherwise accumulate in float64.
    if info is not None:
        exact32 = max(abs(int(info.min)), int(info.max)) * per_block < 2**24
    else:
        exact32 = per_block <= 64
    acc = np.dtype(np.float32 if exact32 else np.float64)
    y_counts = np.full(out_shape[2], fy, dtype=acc)
    y_counts[-1] = n_y - fy * (out_shape[2] - 1)
    x_counts = np.full(out_shape[3], fx, dtype=acc)
    x_counts[-1] = n_x - fx * (out_shape[3] - 1)
    area = np.outer(y_counts, x_counts)
    total = n_c * out_shape[1]
    done = 0
    for c in range(n_c):
        for zo in range(out_shape[1]):
            block = np.asarray(array[c, zo * fz : min(n_z, (zo + 1) * fz)])
            if is_float:
                # NaN voxels do not poison their block: average the finite ones only.
                finite = np.isfinite(block)
                values = np.where(finite, block, 0).astype(acc, copy=False)
                sums = _sum_blocks_2d(values.sum(axis=0, dtype=acc), fy, fx)
                counts = _sum_blocks_2d(finite.sum(axis=0, dtype=acc), fy, fx)
                with np.errstate(invalid="ignore", divide="ignore"):
                    mean = np.where(counts > 0, sums / counts, np.nan)
            else:
                plane = block[0].astype(acc)
                for k in range(1, block.shape[0]):
                    plane += block[k]
                mean = _sum_blocks_2d(plane, fy, fx) / (area * block.shape[0])
            if info is not None:
                mean = np.clip(np.rint(mean), info.min, info.max)
            out[c, zo] = mean
            done += 1
            progress(done / total, f"averaging: slice {done} of {total}")
    return out


def _copy_view(view: np.ndarray, progress: Progress, message: str) -> np.ndarray:
    """C-contiguous copy of a (strided) [c, z, y, x] view, slab by slab."""
    out = np.empty(view.shape, dtype=view.dtype)
    n_c, n_z = view.shape[:2]
    for c in range(n_c):
        for sl in slabs(n_z, view[0, 0].nbytes):
            out[c, sl] = view[c, sl]
            progress((c + sl.stop / n_z) / n_c, message)
    return out


def fit_volume(
    data: VolumeData,
    *,
    max_texture_size: int | None = 2048,
    memory_budget_bytes: int | None = None,
    strategy: FitStrategy = "auto",
    crop_offset: Sequence[int | None] | None = None,
    progress: ProgressCallback | Progress | None = None,
    cancel: CancelCallback | None = None,
) -> VolumeData:
    """Return ``data`` reduced to fit the GPU limits (or ``data`` itself if it fits).

    Parameters
    ----------
    data
        The volume; not modified.
    max_texture_size
        Largest number of voxels allowed along any axis (the GPU's 3-D texture limit);
        None for no limit.
    memory_budget_bytes
        Largest size of all channels together, in bytes; None for no limit.
    strategy
        ``"auto"`` (= ``"average"``), ``"average"``, ``"subsample"``, ``"crop"`` or ``"none"``
        (raise instead of reducing). See the module docstring.
    crop_offset
        For ``"crop"``: first voxel (x, y, z) of the box; None (or a None entry) centres the
        box along that axis.

    Returns
    -------
    VolumeData
        A new object with the reduced array, the voxel size multiplied by the reduction
        factors (x, y, z), ``metadata["fit"]`` describing the change, and a note saying
        from what shape to what shape and why.

    Raises
    ------
    VolumeReadError
        With ``strategy="none"`` when the volume does not fit, or when the budget cannot
        hold a single voxel.
    ValueError
        For an unknown strategy or an out-of-range ``crop_offset``.
    """
    if strategy not in FIT_STRATEGIES:
        raise ValueError(f"unknown fit strategy {strategy!r}; use one of {FIT_STRATEGIES}")
    if max_texture_size is not None and max_texture_size < 1:
        raise ValueError(f"max_texture_size must be ≥ 1, got {max_texture_size}")
    prog = Progress.wrap(progress, cancel)
    array = data.array
    shape = tuple(int(v) for v in array.shape)
    reasons = _reasons(shape, array.dtype.itemsize, max_texture_size, memory_budget_bytes)
    if not reasons:
        prog(1.0, "volume fits")
        return data
    why = "; ".join(reasons)
    if strategy == "none":
        raise VolumeReadError(
            data.source,
            f"the volume {_shape_text(shape)}, {format_bytes(array.nbytes)}, does not fit: "
            f"{why}; use fit='average', 'subsample' or 'crop' to reduce it",
        )
    method = "average" if strategy == "auto" else strategy
    sx, sy, sz = data.voxel_size_um
    fit_info: dict[str, object] = {"strategy": method, "from_shape_czyx": shape, "reason": why}
    if method == "crop":
        box = _crop_sizes(shape, array.dtype.itemsize, max_texture_size, memory_budget_bytes,
                          data.source)  # fmt: skip
        full = [shape[3], shape[2], shape[1]]
        offsets: list[int] = []
        given = list(crop_offset) if crop_offset is not None else [None, None, None]
        if len(given) != 3:
            raise ValueError(f"crop_offset needs 3 values (x, y, z), got {crop_offset!r}")
        for axis, n, b, o in zip("xyz", full, box, given, strict=True):
            if o is None:
                offsets.append((n - b) // 2)
                continue
            if not 0 <= int(o) <= n - b:
                raise ValueError(
                    f"crop_offset {axis}={o} is out of range 0–{n - b} for a {b}-voxel box "
                    f"in {n} voxels"
                )
            offsets.append(int(o))
        ox, oy, oz = offsets
        bx, by, bz = box
        view = array[:, oz : oz + bz, oy : oy + by, ox : ox + bx]
        new_array = _copy_view(view, prog, "cropping")
        new_spacing = Spacing(sx, sy, sz)
        fit_info["offset_xyz"] = (ox, oy, oz)
        fit_info["origin_um"] = (ox * sx, oy * sy, oz * sz)
        note = (
            f"cropped from {_shape_text(shape)} to {_shape_text(new_array.shape)} at voxel "
            f"offset x={ox}, y={oy}, z={oz} (because {why}); the rest of the volume is not "
            "loaded"
        )
    else:
        factors = plan_factors(
            shape,
            array.dtype.itemsize,
            data.voxel_size_um,
            max_texture_size,
            memory_budget_bytes,
            data.source,
        )
        fx, fy, fz = factors
        if method == "subsample":
            view = array[:, ::fz, ::fy, ::fx]
            new_array = _copy_view(view, prog, "subsampling")
            verb = f"subsampled (kept one voxel per {fx}×{fy}×{fz} block in x×y×z)"
        else:
            new_array = _block_mean(array, factors, prog)
            verb = f"downsampled by area averaging (block mean {fx}×{fy}×{fz} in x×y×z)"
        new_spacing = Spacing(sx * fx, sy * fy, sz * fz)
        fit_info["factors_xyz"] = factors
        note = (
            f"{verb} from {_shape_text(shape)} to {_shape_text(new_array.shape)} because {why}; "
            f"voxel size now {new_spacing.x:.4g} × {new_spacing.y:.4g} × {new_spacing.z:.4g} µm"
        )
    fit_info["to_shape_czyx"] = tuple(int(v) for v in new_array.shape)
    metadata = dict(data.metadata)
    metadata["fit"] = fit_info
    metadata["memory_mapped"] = False
    prog(1.0, "fitted")
    return VolumeData(
        new_array,
        new_spacing,
        list(data.channel_names),
        source=data.source,
        voxel_size_from_metadata=data.voxel_size_from_metadata,
        metadata=metadata,
        notes=[*data.notes, note],
    )
