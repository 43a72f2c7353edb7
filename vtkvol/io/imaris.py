"""Imaris ``.ims`` files (Bitplane/Oxford Instruments): HDF5 with a resolution pyramid.

Read with h5py (optional extra ``formats``), a small adapter over Imaris' documented layout
(not the unmaintained IMS reader that rounds voxel sizes):

* voxels: ``/DataSet/ResolutionLevel L/TimePoint t/Channel c/Data``, ``(z, y, x)``, possibly
  padded beyond the image to whole chunks (the padding is cut off);
* size and extent: attributes ``X``, ``Y``, ``Z``, ``ExtMin0..2``, ``ExtMax0..2`` and ``Unit`` of
  ``/DataSetInfo/Image`` (stored as arrays of single characters); the voxel size is
  (ExtMax − ExtMin)/size per axis, in ``Unit`` (µm when absent);
* channels: ``Name`` and ``Color`` ("r g b" in 0…1) of ``/DataSetInfo/Channel c``.

Every ``ResolutionLevel L`` with ``ImageSizeX/Y/Z`` attributes on its channel groups is a pyramid
level (:mod:`vtkvol.io.pyramid`): the finest level that fits the budget is read, or a region of
one, through h5py's lazy dataset slicing (only the HDF5 chunks a slab touches are read).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.pyramid import DEFAULT_MAX_TEXTURE, Pyramid, PyramidLevel, Region, read_pyramid
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import VolumeData, resolve_channels, spacing_or_default

__all__ = ["IMARIS_READER", "ImarisPyramid", "open_imaris", "read_imaris"]


def _text(attrs: Any, key: str) -> str | None:
    """An Imaris attribute as text (Imaris stores strings as arrays of single bytes)."""
    if key not in attrs:
        return None
    value = attrs[key]
    if isinstance(value, bytes):
        return value.decode("latin-1")
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "S":
            return b"".join(value.ravel().tolist()).decode("latin-1")
        return " ".join(str(v) for v in value.ravel())
    return str(value)


def _number(attrs: Any, key: str, path: Path) -> float:
    text = _text(attrs, key)
    try:
        return float(text) if text is not None else float("nan")
    except ValueError:
        raise VolumeReadError(path, f"DataSetInfo/Image attribute {key} = {text!r} is not a "
                                    "number") from None


def _numbered(group: Any, prefix: str, path: Path) -> list[str]:
    """The members of ``group`` named ``prefix`` + a whole number (``"TimePoint 3"``), by
    number. A name with anything else after the prefix (``"TimePoint zero"``) is refused: it
    is not Imaris' layout, and guessing its order would show the wrong time point."""
    keys = [k for k in group if k.startswith(prefix)]
    for key in keys:
        if not key[len(prefix):].isdigit():
            raise VolumeReadError(path, f"{group.name}/{key}: expected {prefix.strip()} "
                                        f"followed by a whole number")
    return sorted(keys, key=lambda k: int(k[len(prefix):]))


def _group(h5py: Any, parent: Any, name: str, path: Path) -> Any:
    """Member ``name`` of ``parent`` if it is an HDF5 group (None when absent); a dataset or
    anything else where Imaris has a group is refused with the name."""
    item = parent.get(name)
    if item is not None and not isinstance(item, h5py.Group):
        raise VolumeReadError(path, f"{parent.name.rstrip('/')}/{name} is an HDF5 "
                                    f"{type(item).__name__.lower()}, not the group Imaris "
                                    "stores there")
    return item


class ImarisPyramid(Pyramid):
    """An open Imaris file's resolution levels (h5py datasets, sliced lazily: HDF5 reads only
    the chunks a slice touches). Keeps the file open until :meth:`close`."""

    def __init__(self, handle: Any, datasets: list[list[Any]], **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._handle = handle
        self._datasets = datasets  # [level][chosen channel]

    def chunk_z(self, level: int) -> int:
        chunks = self._datasets[level][0].chunks
        return int(chunks[0]) if chunks else 1

    def chunk_y(self, level: int) -> int:
        chunks = self._datasets[level][0].chunks
        return int(chunks[1]) if chunks else 1

    def read_block(self, level: int, channel: int, z: slice, y: slice, x: slice) -> np.ndarray:
        return np.asarray(self._datasets[level][channel][z, y, x])

    def close(self) -> None:
        self._handle.close()


def _level_size(group: Any, path: Path) -> tuple[int, int, int] | None:
    """``(nx, ny, nz)`` from a channel group's ``ImageSizeX/Y/Z`` attributes; None if absent."""
    if not all(f"ImageSize{a}" in group.attrs for a in "XYZ"):
        return None
    size = [_number(group.attrs, f"ImageSize{a}", path) for a in "XYZ"]
    if not all(np.isfinite(v) and v >= 1 and v == int(v) for v in size):
        raise VolumeReadError(path, f"{group.name} ImageSize X, Y, Z = {size} is not a positive "
                                    "integer")
    return int(size[0]), int(size[1]), int(size[2])


def open_imaris(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
) -> ImarisPyramid:
    """Open an Imaris file's resolution levels as a :class:`~vtkvol.io.pyramid.Pyramid`.

    Level 0's size is ``DataSetInfo/Image`` X, Y, Z; a coarser level's is its channel group's
    ``ImageSizeX/Y/Z`` (levels without them are left out, with a note). Voxel size per level is
    the image extent / the level's size; voxel centres sit at ExtMin + (i + ½)·size.
    """
    path = Path(path)
    h5py = require("h5py", "Imaris files", path)
    try:
        handle = h5py.File(str(path), "r")
    except OSError as exc:
        raise VolumeReadError(path, f"not a readable Imaris (HDF5) file ({exc})") from exc
    try:
        return _open_imaris(handle, path, time_index, channels)
    except (OSError, KeyError, RuntimeError) as exc:
        # h5py's errors for a damaged object or link inside an otherwise readable file
        handle.close()
        raise VolumeReadError(path, f"damaged Imaris (HDF5) file "
                                    f"({' '.join(str(exc).split()) or type(exc).__name__})"
                              ) from exc
    except BaseException:
        handle.close()
        raise


def _open_imaris(f: Any, path: Path, time_index: int,
                 channels: Sequence[int | str] | None) -> ImarisPyramid:
    import h5py

    dataset_group = _group(h5py, f, "DataSet", path)
    if dataset_group is None or "DataSetInfo/Image" not in f:
        raise VolumeReadError(path, "an HDF5 file without Imaris' DataSet and "
                                    "DataSetInfo/Image groups")
    info = f["DataSetInfo/Image"].attrs
    size = [_number(info, k, path) for k in ("X", "Y", "Z")]
    if not all(np.isfinite(s) and s >= 1 and s == int(s) for s in size):
        raise VolumeReadError(path, f"image size X, Y, Z = {size} is not a positive integer")
    nx, ny, nz = (int(s) for s in size)
    level0 = _group(h5py, dataset_group, "ResolutionLevel 0", path)
    if level0 is None:
        raise VolumeReadError(path, "no resolution level 0 in /DataSet")
    times = _numbered(level0, "TimePoint ", path)
    if not 0 <= time_index < len(times):
        raise VolumeReadError(
            path, f"time_index {time_index} is out of range: the file has {len(times)} "
                  "time point(s)"
        )
    point = _group(h5py, level0, times[time_index], path)
    channel_keys = _numbered(point, "Channel ", path)
    if not channel_keys:
        raise VolumeReadError(path, f"no channels in {times[time_index]}")
    names = []
    for key in channel_keys:
        group = f.get(f"DataSetInfo/{key}")
        name = _text(group.attrs, "Name") if group is not None else None
        names.append(name or key.lower().replace(" ", ""))
    chosen = resolve_channels(channels, names, str(path))
    extent = [(_number(info, f"ExtMin{a}", path), _number(info, f"ExtMax{a}", path))
              for a in range(3)]
    unit = _text(info, "Unit")
    notes: list[str] = []
    scale = unit_scale_um(unit) if unit else 1.0
    if scale is None:
        notes.append(f"unknown length unit {unit!r} in the file: voxel size read as µm")
        scale = 1.0
    level_numbers = sorted(int(k.split()[-1]) for k in dataset_group
                           if k.startswith("ResolutionLevel ") and k.split()[-1].isdigit())
    levels: list[PyramidLevel] = []
    datasets: list[list[Any]] = []
    from_metadata = True
    for number in level_numbers:
        level_name = f"ResolutionLevel {number}"
        lp = _group(h5py, _group(h5py, dataset_group, level_name, path), times[time_index],
                    path)
        if lp is None:
            if number == 0:
                raise VolumeReadError(path, f"{level_name} has no {times[time_index]}")
            notes.append(f"{level_name} has no {times[time_index]}: level not used")
            continue
        if number == 0:
            lsize: tuple[int, int, int] | None = (nx, ny, nz)
        else:
            first = _group(h5py, lp, channel_keys[chosen[0]], path)
            lsize = _level_size(first, path) if first is not None else None
            if lsize is None:
                notes.append(f"{level_name} has no ImageSizeX/Y/Z attributes: level not used")
                continue
        lx, ly, lz = lsize
        level_sets = []
        for c in chosen:
            group = _group(h5py, lp, channel_keys[c], path)
            dataset = group.get("Data") if group is not None else None
            if dataset is not None and not isinstance(dataset, h5py.Dataset):
                raise VolumeReadError(path, f"{group.name}/Data is an HDF5 group, not the "
                                            "voxel data")
            if dataset is None:
                if number == 0:
                    raise VolumeReadError(path, f"{channel_keys[c]} has no Data")
                raise VolumeReadError(path, f"{level_name} {channel_keys[c]} has no Data "
                                            "(pyramid level missing)")
            if dataset.ndim != 3 or any(
                have < want for have, want in zip(dataset.shape, (lz, ly, lx), strict=True)
            ):
                where = channel_keys[c] if number == 0 else f"{level_name} {channel_keys[c]}"
                raise VolumeReadError(
                    path, f"{where} Data has shape {dataset.shape}, smaller than the "
                          f"image's (z, y, x) = {(lz, ly, lx)}"
                )
            level_sets.append(dataset)
        level_notes: list[str] = []
        spacing, ok = spacing_or_default(
            [(hi - lo) / n * scale for (lo, hi), n in zip(extent, (lx, ly, lz), strict=True)],
            f"extent {extent} gives no positive voxel size: using 1 × 1 × 1 µm", level_notes,
        )
        if not ok:
            from_metadata = False
            notes.extend(n for n in level_notes if n not in notes)
        levels.append(PyramidLevel(
            name=level_name,
            shape_czyx=(len(chosen), lz, ly, lx),
            voxel_size_um=spacing,
            # Voxel centres at ExtMin + (i + 1/2)·s; pyramid space starts at level 0's first.
            offset_um=(0.0, 0.0, 0.0) if not levels else tuple(  # type: ignore[arg-type]
                (s - s0) / 2 for s, s0 in zip(spacing, levels[0].voxel_size_um, strict=True)),
        ))
        datasets.append(level_sets)
    return ImarisPyramid(
        f, datasets,
        source=path,
        levels=levels,
        dtype=np.dtype(datasets[0][0].dtype),
        channel_names=[names[c] for c in chosen],
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "imaris",
            "time_points": len(times),
            "time_index": time_index,
            "voxel_size_source": "Imaris extent / size" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


def read_imaris(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
    memory_budget_bytes: int | None = None,
    max_texture_size: int | None = DEFAULT_MAX_TEXTURE,
    level: int | None = None,
    region_um: Region | None = None,
) -> VolumeData:
    """Read one time point of an Imaris file as ``[c, z, y, x]`` from one resolution level:
    ``level``, or the finest that fits ``memory_budget_bytes`` (default
    :data:`~vtkvol.io.pyramid.DEFAULT_GPU_BUDGET_BYTES`) and ``max_texture_size``;
    ``region_um`` as in :func:`vtkvol.io.pyramid.read_pyramid`."""
    with open_imaris(Path(path), time_index=time_index, channels=channels) as pyramid:
        return read_pyramid(pyramid, budget_bytes=memory_budget_bytes,
                            max_texture_size=max_texture_size, level=level, region_um=region_um,
                            progress=progress)


IMARIS_READER = ReaderSpec(
    name="imaris",
    label="Imaris (.ims)",
    filename_patterns=("*.ims",),
    accepts_directories=False,
    read=read_imaris,
    open_pyramid=open_imaris,
)
