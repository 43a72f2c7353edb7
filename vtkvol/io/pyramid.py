"""Multiscale images (pyramids) read lazily: choose a level within a budget, read a region.

A :class:`Pyramid` is an open multiscale image (an OME-Zarr folder, an Imaris file) whose
levels are read only where asked: :func:`read_pyramid` reads one level, or one region of one
level, z-slab by z-slab aligned on the store's chunks, so a level or region larger than the
budget is never loaded, and a region read touches only the chunks it overlaps.

Coordinates
-----------
**Pyramid space** is the image's physical space in µm with the finest level's first voxel
centre at 0 (the file's own offset, an OME-Zarr ``translation`` or Imaris' ``ExtMin``, is
subtracted). Every level has its voxel size and the position of its first voxel centre in
pyramid space (``offset_um``; a coarser level's first voxel may sit half a coarse voxel further
in, as in Imaris files). A region is ``((x0, x1), (y0, y1), (z0, z1))`` µm in pyramid space; it
selects the voxels whose centres lie inside it (at least one voxel per axis).

The budget counts the voxel bytes of the data read (all chosen channels, one time point):
what the view uploads as its 3-D texture. :data:`DEFAULT_GPU_BUDGET_BYTES` is 1 GiB, what a
4 GB GPU holds next to its illumination volumes (at most a quarter of this machine's memory).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import ReadCancelled, VolumeReadError
from vtkvol.io.limits import check_declared_bytes, physical_memory_bytes
from vtkvol.io.progress import Progress
from vtkvol.io.volume_data import Spacing, VolumeData, format_bytes

__all__ = [
    "DEFAULT_GPU_BUDGET_BYTES", "DEFAULT_MAX_TEXTURE", "Pyramid", "PyramidLevel", "Region",
    "choose_level", "parse_bytes", "read_pyramid", "region_voxels",
]

#: Voxel bytes of the level shown by default (all chosen channels, one time point): 1 GiB,
#: what a 4 GB GPU holds next to its illumination volumes; at most a quarter of this
#: machine's memory.
DEFAULT_GPU_BUDGET_BYTES = min(1 << 30, physical_memory_bytes() // 4)
#: Largest number of voxels per axis of the level chosen (the default GPU 3-D texture limit).
DEFAULT_MAX_TEXTURE = 2048
#: Bytes per z-slab read at once.
SLAB_BYTES = 32 << 20

#: ((x0, x1), (y0, y1), (z0, z1)) in µm, pyramid space.
Region = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]


@dataclass(frozen=True)
class PyramidLevel:
    """One resolution level as it will be read (the chosen channels, one time point).

    ``shape_czyx`` in voxels; ``voxel_size_um`` (x, y, z) µm; ``offset_um`` (x, y, z): the
    centre of the level's first voxel in pyramid space (µm); ``name``: the level's name in the
    file (``'s1'``, ``'ResolutionLevel 1'``).
    """

    name: str
    shape_czyx: tuple[int, int, int, int]
    voxel_size_um: Spacing
    offset_um: tuple[float, float, float]

    @property
    def shape_xyz(self) -> tuple[int, int, int]:
        return (self.shape_czyx[3], self.shape_czyx[2], self.shape_czyx[1])

    def extent_um(self) -> Region:
        """The voxel-centre extent of the level in pyramid space."""
        return tuple(  # type: ignore[return-value]
            (o, o + (n - 1) * s)
            for o, n, s in zip(self.offset_um, self.shape_xyz, self.voxel_size_um, strict=True))


@dataclass
class Pyramid:
    """An open multiscale image; subclasses provide :meth:`read_block` and :meth:`chunk_z`.

    ``levels`` finest first; ``channel_names`` of the chosen channels; ``metadata`` and
    ``notes`` are copied into every :class:`VolumeData` read from it.
    """

    source: Path
    levels: list[PyramidLevel]
    dtype: np.dtype
    channel_names: list[str]
    voxel_size_from_metadata: bool
    metadata: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def read_block(self, level: int, channel: int, z: slice, y: slice, x: slice) -> np.ndarray:
        """Voxels ``[z, y, x]`` of the ``channel``-th chosen channel of ``level``."""
        raise NotImplementedError

    def chunk_z(self, level: int) -> int:
        """The store's chunk size along z at ``level`` (slabs start on chunk boundaries)."""
        return 1

    def chunk_y(self, level: int) -> int:
        """The store's chunk size along y at ``level`` (strips start on chunk boundaries)."""
        return 1

    def to_dask(self, level: int = 0, chunks: tuple[int, int, int, int] | None = None) -> Any:
        """``level`` as a lazy dask array ``[c, z, y, x]`` (dask must be installed): each
        dask chunk reads its block through :meth:`read_block` when computed. Default chunks:
        one channel, the store's z chunk, 256 × 256 in y and x. The pyramid must stay open
        while the array is used."""
        import dask.array as da

        lv = self.levels[level]
        if chunks is None:
            chunks = (1, self.chunk_z(level), 256, 256)
        return da.from_array(_LevelArray(self, level), asarray=True, fancy=False,
                             chunks=tuple(min(c, n) for c, n in
                                          zip(chunks, lv.shape_czyx, strict=True)))

    def close(self) -> None:
        """Release the file (Imaris keeps an HDF5 handle open)."""

    def __enter__(self) -> Pyramid:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _LevelArray:
    """One level of a :class:`Pyramid` as an array dask can slice (``[c, z, y, x]``)."""

    def __init__(self, pyramid: Pyramid, level: int) -> None:
        self._pyramid, self._level = pyramid, level
        self.shape = pyramid.levels[level].shape_czyx
        self.dtype = np.dtype(pyramid.dtype)
        self.ndim = 4

    def __getitem__(self, key: Any) -> np.ndarray:
        parts = key if isinstance(key, tuple) else (key,)
        parts = parts + (slice(None),) * (4 - len(parts))
        c, z, y, x = (slice(*(k if isinstance(k, slice) else slice(k, k + 1)).indices(n)[:2])
                      for k, n in zip(parts, self.shape, strict=True))
        blocks = [self._pyramid.read_block(self._level, k, z, y, x) for k in range(c.start, c.stop)]
        return np.stack(blocks) if blocks else np.empty(
            (0, z.stop - z.start, y.stop - y.start, x.stop - x.start), self.dtype)


def parse_bytes(text: str | int | float) -> int:
    """A byte count from ``"1.5GiB"``, ``"512 MiB"``, ``"2G"``, ``"800MB"`` or a number.

    Binary (KiB, MiB, GiB, TiB, or K, M, G, T) and decimal (kB, MB, GB, TB) units; a bare
    number is bytes. Raises ValueError for anything else, or a value ≤ 0 or not finite.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, unit = float(text), ""
    else:
        s = str(text).strip().replace(" ", "")
        i = len(s)
        while i > 0 and not (s[i - 1].isdigit() or s[i - 1] == "."):
            i -= 1
        try:
            value, unit = float(s[:i]), s[i:].lower()
        except ValueError:
            raise ValueError(f"{text!r} is not a size (e.g. 1GiB, 512MiB)") from None
    factors = {"": 1, "b": 1, "k": 1 << 10, "kib": 1 << 10, "m": 1 << 20, "mib": 1 << 20,
               "g": 1 << 30, "gib": 1 << 30, "t": 1 << 40, "tib": 1 << 40, "kb": 10 ** 3,
               "mb": 10 ** 6, "gb": 10 ** 9, "tb": 10 ** 12}
    if unit not in factors:
        raise ValueError(f"{text!r}: unknown unit {unit!r} (use KiB, MiB, GiB, MB, GB)")
    nbytes = value * factors[unit]
    if not math.isfinite(nbytes) or nbytes < 1:
        raise ValueError(f"{text!r} is not a positive size")
    return int(nbytes)


def choose_level(
    shapes: Sequence[Sequence[int]],
    voxel_bytes: int,
    budget_bytes: int,
    max_texture: int | None,
) -> tuple[int, str]:
    """Index of the finest level whose ``(c, z, y, x)`` shape fits, and why it was chosen.

    ``shapes`` are per level, finest first, for the data that will be read (chosen channels,
    one time point, possibly a region); ``voxel_bytes`` is the item size. Returns
    ``(-1, reason)`` when none fits.
    """
    for i, shape in enumerate(shapes):
        nbytes = math.prod(shape) * voxel_bytes
        too_wide = max_texture is not None and max(shape[1:]) > max_texture
        if nbytes <= budget_bytes and not too_wide:
            if i == 0:
                return 0, f"the finest level fits the budget {format_bytes(budget_bytes)}"
            finer = shapes[i - 1]
            reason = (f"{format_bytes(math.prod(finer) * voxel_bytes)} > budget "
                      f"{format_bytes(budget_bytes)}"
                      if math.prod(finer) * voxel_bytes > budget_bytes
                      else f"an axis of {max(finer[1:])} voxels > texture size {max_texture}")
            return i, f"level {i - 1} does not fit ({reason})"
    return -1, (f"even the coarsest level ({format_bytes(math.prod(shapes[-1]) * voxel_bytes)}, "
                f"shape {tuple(shapes[-1])}) exceeds the budget {format_bytes(budget_bytes)}"
                + (f" or texture size {max_texture}" if max_texture else ""))


def _check_region(region: Any) -> Region:
    try:
        values = [(float(lo), float(hi)) for lo, hi in region]
    except (TypeError, ValueError):
        raise ValueError(f"region {region!r} is not ((x0, x1), (y0, y1), (z0, z1)) in µm") from None
    if len(values) != 3 or not all(math.isfinite(v) for pair in values for v in pair):
        raise ValueError(f"region {region!r} needs three finite (low, high) pairs in µm")
    if any(lo > hi for lo, hi in values):
        raise ValueError(f"region {region!r} has a low end above its high end")
    return tuple(values)  # type: ignore[return-value]


def region_voxels(level: PyramidLevel, region: Region | None, source: Path | None = None,
                  ) -> tuple[slice, slice, slice]:
    """Voxel slices ``(x, y, z)`` of ``level`` whose centres lie in ``region`` (pyramid µm).

    Every axis keeps at least one voxel (the nearest, for a region thinner than a voxel).
    Raises VolumeReadError when the region lies outside the level's extent on an axis.
    """
    if region is None:
        return tuple(slice(0, n) for n in level.shape_xyz)  # type: ignore[return-value]
    out = []
    for axis, (lo, hi), off, s, n in zip("xyz", region, level.offset_um, level.voxel_size_um,
                                         level.shape_xyz, strict=True):
        first, last = off - s / 2, off + (n - 1) * s + s / 2  # the level's box, voxel edges
        if hi < first or lo > last:
            raise VolumeReadError(source, f"the region {axis} = {lo:.4g}…{hi:.4g} µm lies outside "
                                          f"the data ({off:.4g}…{off + (n - 1) * s:.4g} µm)")
        i0 = max(0, math.ceil((lo - off) / s - 1e-6))
        i1 = min(n - 1, math.floor((hi - off) / s + 1e-6))
        if i1 < i0:  # thinner than a voxel: the voxel nearest its middle
            i0 = i1 = min(n - 1, max(0, round(((lo + hi) / 2 - off) / s)))
        out.append(slice(i0, i1 + 1))
    return tuple(out)  # type: ignore[return-value]


def _region_shape(level: PyramidLevel, sl: tuple[slice, slice, slice]) -> tuple[int, ...]:
    sx, sy, sz = sl
    return (level.shape_czyx[0], sz.stop - sz.start, sy.stop - sy.start, sx.stop - sx.start)


def _aligned_edges(span: slice, step: int) -> list[int]:
    """``span.start``, the multiples of ``step`` inside the span, ``span.stop``."""
    inner = range((span.start // step + 1) * step, span.stop, step)
    return [span.start, *inner, span.stop]


def read_pyramid(
    pyramid: Pyramid,
    *,
    budget_bytes: int | None = None,
    max_texture_size: int | None = DEFAULT_MAX_TEXTURE,
    level: int | None = None,
    region_um: Region | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read ``region_um`` (pyramid µm; None: everything) of one level of ``pyramid``.

    ``level`` forces a level (0 = finest); by default the finest level whose region fits
    ``budget_bytes`` (default :data:`DEFAULT_GPU_BUDGET_BYTES`) and ``max_texture_size``
    voxels per axis. Only that level's chunks overlapping the region are read, z-slab by
    z-slab; the result never exceeds the budget unless ``level`` forces it.

    ``metadata`` gets ``level``, ``levels`` (every level's (c, z, y, x)), ``level_name``,
    ``budget_bytes``, ``region_um`` (the voxel-centre extent read, pyramid µm, or None when the
    whole level was read), ``origin_um`` (its first voxel centre, pyramid µm) and
    ``region_voxels`` ((x0, x1), (y0, y1), (z0, z1)) at that level. The first note says which
    level was read and why.
    """
    progress = progress or Progress()
    budget = DEFAULT_GPU_BUDGET_BYTES if budget_bytes is None else int(budget_bytes)
    if budget < 1:
        raise ValueError(f"budget_bytes must be ≥ 1, got {budget}")
    region = None if region_um is None else _check_region(region_um)
    source = pyramid.source
    levels = pyramid.levels
    itemsize = np.dtype(pyramid.dtype).itemsize
    slices = [region_voxels(lv, region, source) for lv in levels]
    shapes = [_region_shape(lv, sl) for lv, sl in zip(levels, slices, strict=True)]
    if level is None:
        index, reason = choose_level(shapes, itemsize, budget, max_texture_size)
        if index < 0:
            what = "no level fits the region" if region is not None else "no pyramid level fits"
            raise VolumeReadError(source, f"{what}: {reason}")
    else:
        if not 0 <= level < len(levels):
            raise VolumeReadError(source, f"level {level} is out of range: the pyramid has "
                                          f"{len(levels)} level(s)")
        index, reason = level, "level chosen by the caller"
    lv, (sx, sy, sz), shape = levels[index], slices[index], shapes[index]
    c_n, z_n, y_n, x_n = shape
    check_declared_bytes(source, math.prod(shape) * itemsize, f"level {index} {shape}")
    out = np.empty(shape, dtype=pyramid.dtype)
    message = f"reading level {index} ({lv.name})"
    progress(0.0, message)
    # Blocks of about SLAB_BYTES whose edges lie on the store's chunk boundaries (no chunk is
    # decoded twice): whole z-slabs, or, when one row of chunks is larger, y-strips of it.
    # Memory: the result plus one block and the chunks it decodes.
    row_bytes = x_n * itemsize
    # A remote store reports progress per row of chunks (its slab_bytes is small).
    slab_bytes = getattr(pyramid, "slab_bytes", SLAB_BYTES)
    chunk_z, chunk_y = max(1, pyramid.chunk_z(index)), max(1, pyramid.chunk_y(index))
    z_step = chunk_z * max(1, slab_bytes // max(1, y_n * row_bytes * chunk_z))
    z_edges = _aligned_edges(sz, z_step)
    try:
        for k in range(c_n):
            for z0, z1 in itertools.pairwise(z_edges):
                y_step = chunk_y * max(1, slab_bytes // max(1, (z1 - z0) * row_bytes * chunk_y))
                for y0, y1 in itertools.pairwise(_aligned_edges(sy, y_step)):
                    block = pyramid.read_block(index, k, slice(z0, z1), slice(y0, y1), sx)
                    out[k, z0 - sz.start:z1 - sz.start, y0 - sy.start:y1 - sy.start] = block
                progress((k + (z1 - sz.start) / z_n) / c_n, message)
    except (VolumeReadError, ReadCancelled):
        raise
    except Exception as exc:  # codec errors on truncated chunks, missing stores…
        raise VolumeReadError(source, f"level {lv.name!r} cannot be read: the chunks are "
                                      f"truncated or corrupt ({type(exc).__name__}: "
                                      f"{exc})") from exc
    vx, vy, vz = lv.voxel_size_um
    origin = (lv.offset_um[0] + sx.start * vx, lv.offset_um[1] + sy.start * vy,
              lv.offset_um[2] + sz.start * vz)
    read_extent = tuple((o, o + (n - 1) * s) for o, n, s in
                        zip(origin, (x_n, y_n, z_n), (vx, vy, vz), strict=True))
    where = "" if region is None else (
        " region " + " × ".join(f"{a} {lo:.4g}…{hi:.4g}" for a, (lo, hi) in
                                zip("xyz", read_extent, strict=True)) + " µm")
    note = (f"pyramid level {index} of {len(levels)} ({lv.name!r}, {x_n}×{y_n}×{z_n} x×y×z)"
            f"{where} read: {reason}")
    metadata = dict(pyramid.metadata)
    metadata.update({
        "level": index,
        "level_name": lv.name,
        "levels": [list(v.shape_czyx) for v in levels],
        "budget_bytes": budget,
        "level_budget_bytes": budget,
        "region_um": None if region is None else [list(p) for p in read_extent],
        "origin_um": list(origin),
        "region_voxels": [[s.start, s.stop] for s in (sx, sy, sz)],
        "level_reason": reason,
    })
    return VolumeData(
        out, lv.voxel_size_um, list(pyramid.channel_names), source=str(source),
        voxel_size_from_metadata=pyramid.voxel_size_from_metadata, metadata=metadata,
        notes=[note, *pyramid.notes],
    )

