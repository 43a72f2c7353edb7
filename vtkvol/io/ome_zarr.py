"""OME-Zarr images (NGFF v0.4 on Zarr v2, v0.5 on Zarr v3): a ``.zarr`` folder with a pyramid.

Read with ``zarr`` (optional extra ``formats``). The ``multiscales`` metadata (in the group's
attributes for v0.4, under ``attributes["ome"]`` for v0.5) is interpreted here, a few dozen
lines of a published JSON schema: the ``ome-zarr`` package's reader is built for napari (it
returns every level and label as dask arrays and pulls in dask, aiohttp and fsspec), while
what vtkvol needs is one level sliced lazily, which a zarr array does by itself.

* axes: up to five of ``t``, ``c``, ``z``, ``y``, ``x`` (by ``type`` "time"/"channel"/"space"),
  with a ``unit`` per axis (``micrometer``, ``nanometer``…; none means µm, with a note);
* voxel size: the dataset's ``scale`` transformation times the multiscale's own, per level;
* channel names and colours: ``omero.channels[i].label`` and ``color`` (hex ``RRGGBB``);
* a ``bioformats2raw.layout`` root holds its first image in the group ``0``.

**Pyramid level**: the finest level whose chosen channels, at one time point, fit both the
budget (:data:`vtkvol.io.pyramid.DEFAULT_GPU_BUDGET_BYTES`, or ``memory_budget_bytes`` of
:func:`read_ome_zarr`) and the texture size per axis. Only that level (or a region of it) is
read, z-slab by z-slab, as zarr reads only the chunks a slice touches: a level larger than the
budget is never loaded (:mod:`vtkvol.io.pyramid`). The level read and why is in the notes and in
``metadata["level"]``; ``translation`` transformations give each level's offset.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.pyramid import (
    DEFAULT_GPU_BUDGET_BYTES,
    DEFAULT_MAX_TEXTURE,
    Pyramid,
    PyramidLevel,
    Region,
    choose_level,
    read_pyramid,
)
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.time_series import time_unit_seconds
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = [
    "DEFAULT_LEVEL_BUDGET_BYTES", "DEFAULT_MAX_TEXTURE", "OME_ZARR_READER", "ZarrPyramid",
    "choose_level", "open_ome_zarr", "read_ome_zarr",
]

#: The default budget of the level read (kept under its former name).
DEFAULT_LEVEL_BUDGET_BYTES = DEFAULT_GPU_BUDGET_BYTES

_AXIS_TYPES = {"time": "t", "channel": "c", "space": None}


def _zarr_root(path: Path) -> Path:
    """The store folder: ``path`` itself, or its folder when the metadata file was named."""
    if path.is_file() and path.name in ("zarr.json", ".zattrs", ".zgroup"):
        return path.parent
    return path


def _multiscales(attrs: dict[str, Any]) -> tuple[list[Any] | None, str]:
    """``(multiscales, version)`` from a group's attributes (v0.5 nests them under ``ome``)."""
    ome = attrs.get("ome")
    if isinstance(ome, dict) and "multiscales" in ome:
        return ome["multiscales"], str(ome.get("version", "0.5"))
    if "multiscales" in attrs:
        ms = attrs["multiscales"]
        version = ms[0].get("version", "0.4") if isinstance(ms, list) and ms and isinstance(
            ms[0], dict) else "0.4"
        return ms, str(version)
    return None, ""


def _omero(attrs: dict[str, Any]) -> dict[str, Any]:
    ome = attrs.get("ome")
    omero = ome.get("omero") if isinstance(ome, dict) else None
    omero = omero if omero is not None else attrs.get("omero")
    return omero if isinstance(omero, dict) else {}


def _axes(ms: dict[str, Any], ndim: int, path: Path) -> list[tuple[str, str | None]]:
    """``[(name, unit)]`` per array axis, names normalised to t/c/z/y/x."""
    raw = ms.get("axes")
    if raw is None:  # v0.1/v0.2: always 5-D tczyx
        raw = ["t", "c", "z", "y", "x"][-ndim:]
    if not isinstance(raw, list) or len(raw) != ndim:
        raise VolumeReadError(path, f"multiscales axes {raw!r} do not match the {ndim}-D arrays")
    axes: list[tuple[str, str | None]] = []
    for item in raw:
        if isinstance(item, str):  # v0.3: names only
            name, unit, kind = item, None, None
        elif isinstance(item, dict) and isinstance(item.get("name"), str):
            name, unit, kind = item["name"], item.get("unit"), item.get("type")
        else:
            raise VolumeReadError(path, f"multiscales axis {item!r} has no name")
        name = name.lower()
        if name not in ("t", "c", "z", "y", "x"):
            mapped = _AXIS_TYPES.get(kind) if isinstance(kind, str) else None
            if mapped is None:
                raise VolumeReadError(path, f"unsupported axis {name!r} (type {kind!r}); vtkvol "
                                            "reads t, c, z, y, x")
            name = mapped
        axes.append((name, unit if isinstance(unit, str) else None))
    names = [a for a, _ in axes]
    if len(set(names)) != len(names) or "x" not in names or "y" not in names:
        raise VolumeReadError(path, f"axes {names} need x and y once each")
    return axes


def _scale(transforms: Any, ndim: int, path: Path, where: str) -> list[float]:
    """The product of the ``scale`` transformations in ``transforms`` (ones if none)."""
    scale = [1.0] * ndim
    if transforms is None:
        return scale
    if not isinstance(transforms, list):
        raise VolumeReadError(path, f"{where} coordinateTransformations is not a list")
    for t in transforms:
        if isinstance(t, dict) and t.get("type") == "scale":
            values = t.get("scale")
            if not isinstance(values, list) or len(values) != ndim:
                raise VolumeReadError(path, f"{where} scale {values!r} does not have {ndim} values")
            try:
                scale = [s * float(v) for s, v in zip(scale, values, strict=True)]
            except (TypeError, ValueError):
                raise VolumeReadError(path, f"{where} scale {values!r} is not numeric") from None
    return scale


def _color(value: Any) -> tuple[float, float, float] | None:
    if isinstance(value, str) and len(value) == 6:
        try:
            return tuple(int(value[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]
        except ValueError:
            return None
    return None


def _translation(transforms: Any, ndim: int, path: Path, where: str) -> list[float]:
    """The sum of the ``translation`` transformations in ``transforms`` (zeros if none)."""
    shift = [0.0] * ndim
    if not isinstance(transforms, list):
        return shift
    for t in transforms:
        if isinstance(t, dict) and t.get("type") == "translation":
            values = t.get("translation")
            if not isinstance(values, list) or len(values) != ndim:
                raise VolumeReadError(path, f"{where} translation {values!r} does not have "
                                            f"{ndim} values")
            try:
                shift = [s + float(v) for s, v in zip(shift, values, strict=True)]
            except (TypeError, ValueError):
                raise VolumeReadError(path, f"{where} translation {values!r} is not "
                                            "numeric") from None
    return shift


class ZarrPyramid(Pyramid):
    """An OME-Zarr image's levels as zarr arrays (sliced lazily: zarr reads only the chunks a
    slice touches)."""

    def __init__(self, arrays: list[Any], positions: dict[str, int], axis_names: list[str],
                 time_index: int, channel_indices: list[int], **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._arrays = arrays
        self._pos = positions
        self._names = axis_names
        self._time = time_index
        self._channels = channel_indices

    def chunk_z(self, level: int) -> int:
        z = self._pos.get("z")
        return 1 if z is None else int(self._arrays[level].chunks[z])

    def chunk_y(self, level: int) -> int:
        return int(self._arrays[level].chunks[self._pos["y"]])

    def has_stored_chunks(self, level: int) -> bool:
        """Whether the level's array has at least one chunk (or shard) file in the store; a
        store with none holds only the fill value. Stops at the first file found; True when
        the store is not a local folder (it cannot be listed cheaply)."""
        array = self._arrays[level]
        root = getattr(getattr(array, "store", None), "root", None)
        if root is None:
            return True
        folder = Path(root) / str(getattr(array, "path", "") or "")
        metadata = {"zarr.json", ".zarray", ".zattrs", ".zgroup", ".zmetadata"}
        return any(name not in metadata for _, _, files in os.walk(folder) for name in files)

    def read_block(self, level: int, channel: int, z: slice, y: slice, x: slice) -> np.ndarray:
        index = {"t": self._time, "c": self._channels[channel], "z": z, "y": y, "x": x}
        block = np.asarray(self._arrays[level][tuple(index[n] for n in self._names)])
        return block.reshape(z.stop - z.start, y.stop - y.start, x.stop - x.start)


def open_ome_zarr(
    path: Path | str,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    group: Any = None,
    pyramid_type: type[ZarrPyramid] = ZarrPyramid,
) -> ZarrPyramid:
    """Open an OME-Zarr image as a :class:`~vtkvol.io.pyramid.Pyramid` (metadata only; no
    voxel is read). Raises VolumeReadError for anything that is not a readable image.

    ``group``: an already opened zarr group (a remote store, :mod:`vtkvol.io.remote`); then
    ``path`` is only its name in messages and ``source`` (an address stays a string).
    ``pyramid_type``: the :class:`ZarrPyramid` subclass to return."""
    if group is None:
        path = Path(path)
        zarr = require("zarr", "OME-Zarr images", path)
        root = _zarr_root(path)
        try:
            group = zarr.open_group(str(root), mode="r")
        except Exception as exc:  # zarr raises many types for a folder that is not a group
            raise VolumeReadError(path, f"not a readable Zarr group ({type(exc).__name__}: "
                                        f"{exc})") from exc
    attrs = dict(group.attrs)
    notes: list[str] = []
    multiscales, version = _multiscales(attrs)
    if multiscales is None and "0" in group:
        # bioformats2raw layout: the images are the numbered child groups.
        try:
            child = group["0"]
            child_ms, version = _multiscales(dict(child.attrs))
        except Exception:
            child_ms = None
        if child_ms is not None:
            group, multiscales = child, child_ms
            notes.append("bioformats2raw layout: image 0 read")
    if not multiscales:
        ome = attrs.get("ome") if isinstance(attrs.get("ome"), dict) else attrs
        for kind, example in (("plate", "A/1/0"), ("well", "0")):
            if kind in ome:
                raise VolumeReadError(path, f"an OME-Zarr high-content-screening {kind}, not an "
                                            f"image: open one image folder inside it (e.g. "
                                            f"{example})")
        raise VolumeReadError(path, "a Zarr group without OME-Zarr 'multiscales' metadata "
                                    "(not an OME-Zarr image)")
    if not isinstance(multiscales, list) or not isinstance(multiscales[0], dict):
        raise VolumeReadError(path, "the 'multiscales' metadata is not a list of objects")
    ms = multiscales[0]
    datasets = ms.get("datasets")
    if not isinstance(datasets, list) or not datasets or not all(
            isinstance(d, dict) and isinstance(d.get("path"), str) for d in datasets):
        raise VolumeReadError(path, "the multiscales 'datasets' list is missing, empty or has "
                                    "entries without a path")
    arrays = []
    for d in datasets:
        try:
            arr = group[d["path"]]
        except Exception:
            raise VolumeReadError(path, f"pyramid level {d['path']!r} named in the metadata is "
                                        "missing") from None
        if not hasattr(arr, "shape") or not hasattr(arr, "dtype"):
            raise VolumeReadError(path, f"pyramid level {d['path']!r} is a group, not an array")
        arrays.append(arr)
    ndim = arrays[0].ndim
    if any(a.ndim != ndim for a in arrays):
        raise VolumeReadError(path, f"pyramid levels differ in dimensions: "
                                    f"{[a.shape for a in arrays]}")
    if any(a.dtype != arrays[0].dtype for a in arrays):
        raise VolumeReadError(path, f"pyramid levels differ in data type: "
                                    f"{[str(a.dtype) for a in arrays]}")
    axes = _axes(ms, ndim, path)
    names_axes = [a for a, _ in axes]
    global_transforms = ms.get("coordinateTransformations")
    global_scale = _scale(global_transforms, ndim, path, "multiscales")
    global_shift = _translation(global_transforms, ndim, path, "multiscales")
    scales, shifts = [], []
    for d in datasets:
        where = f"level {d['path']!r}"
        transforms = d.get("coordinateTransformations")
        level_scale = _scale(transforms, ndim, path, where)
        level_shift = _translation(transforms, ndim, path, where)
        scales.append([g * s for g, s in zip(global_scale, level_scale, strict=True)])
        shifts.append([g * t + gt for g, t, gt in zip(global_scale, level_shift, global_shift,
                                                       strict=True)])
    pos = {name: i for i, name in enumerate(names_axes)}
    shape0 = arrays[0].shape
    n_time = shape0[pos["t"]] if "t" in pos else 1
    n_channels = shape0[pos["c"]] if "c" in pos else 1
    if not 0 <= time_index < n_time:
        raise VolumeReadError(path, f"time_index {time_index} is out of range: the image has "
                                    f"{n_time} time point(s)")
    omero = _omero(dict(group.attrs))
    omero_channels = omero.get("channels") if isinstance(omero.get("channels"), list) else []
    names = default_channel_names(n_channels)
    colors: list[tuple[float, float, float] | None] = [None] * n_channels
    if len(omero_channels) == n_channels:
        for i, ch in enumerate(omero_channels):
            if isinstance(ch, dict):
                if isinstance(ch.get("label"), str) and ch["label"].strip():
                    names[i] = ch["label"].strip()
                colors[i] = _color(ch.get("color"))
        if len(set(names)) != len(names):  # duplicate labels cannot be chosen by name
            names = [f"{n} ({i})" for i, n in enumerate(names)]
    elif omero_channels:
        notes.append(f"omero metadata names {len(omero_channels)} channels, the data has "
                     f"{n_channels}: channel names ignored")
    chosen = resolve_channels(channels, names, str(path))

    factors: dict[str, float] = {}
    for name in ("x", "y", "z"):
        if name not in pos:
            continue
        unit = axes[pos[name]][1]
        factor = unit_scale_um(unit) if unit else 1.0
        if factor is None:
            notes.append(f"unknown unit {unit!r} on axis {name}: read as µm")
            factor = 1.0
        factors[name] = factor
    if not any(axes[pos[n]][1] for n in ("x", "y", "z") if n in pos):
        notes.append("the axes declare no unit: scale read as µm")
    interval = _time_interval_s(axes, pos, scales[0], n_time, notes)

    levels: list[PyramidLevel] = []
    from_metadata = True
    for d, arr, level_scale, level_shift in zip(datasets, arrays, scales, shifts, strict=True):
        s = arr.shape
        spacing_values: list[float] = []
        offsets: list[float] = []
        for name in ("x", "y", "z"):
            if name not in pos:  # a 2-D image: one slice, z as x
                spacing_values.append(spacing_values[0])
                offsets.append(0.0)
                continue
            spacing_values.append(level_scale[pos[name]] * factors[name])
            offsets.append(level_shift[pos[name]] * factors[name])
        level_notes: list[str] = []
        spacing, ok = spacing_or_default(
            spacing_values, f"OME-Zarr scale {spacing_values} is not positive: using 1 × 1 × 1 "
                            "µm", level_notes)
        if not ok:
            from_metadata = False
            notes.extend(n for n in level_notes if n not in notes)
        if not all(math.isfinite(o) for o in offsets):
            offsets = [0.0, 0.0, 0.0]
        levels.append(PyramidLevel(
            name=d["path"],
            shape_czyx=(len(chosen), s[pos["z"]] if "z" in pos else 1, s[pos["y"]], s[pos["x"]]),
            voxel_size_um=spacing,
            offset_um=tuple(offsets),  # type: ignore[arg-type]
        ))
    base = levels[0].offset_um
    levels = [PyramidLevel(lv.name, lv.shape_czyx, lv.voxel_size_um,
                           tuple(o - b for o, b in zip(lv.offset_um, base, strict=True)))  # type: ignore[arg-type]
              for lv in levels]
    return pyramid_type(
        arrays, pos, names_axes, time_index, chosen,
        source=path,
        levels=levels,
        dtype=np.dtype(arrays[0].dtype),
        channel_names=[names[c] for c in chosen],
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": f"ome-zarr {version}",
            "axes": "".join(names_axes).upper(),
            "time_points": n_time,
            "time_index": time_index,
            "channel_colors": [colors[c] for c in chosen],
            "voxel_size_source": "OME-Zarr scale" if from_metadata else "default 1 µm",
            **({"time_interval_s": interval} if interval is not None else {}),
            "pyramid_offset_um": list(base),
        },
        notes=notes,
    )


def _time_interval_s(axes: list[tuple[str, str | None]], pos: dict[str, int],
                     scale: list[float], n_time: int, notes: list[str]) -> float | None:
    """Seconds between time points: the ``t`` axis's scale in its unit; None without a ``t``
    axis, a unit, or a positive scale (NGFF's scale on ``t`` is meaningless without one)."""
    if "t" not in pos or n_time < 2:
        return None
    unit = axes[pos["t"]][1]
    if unit is None:
        return None
    factor = time_unit_seconds(unit)
    if factor is None:
        notes.append(f"unknown unit {unit!r} on axis t: the time interval is ignored")
        return None
    value = scale[pos["t"]] * factor
    return value if math.isfinite(value) and value > 0 else None


def read_ome_zarr(
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
    """Read one time point of an OME-Zarr image as ``[c, z, y, x]`` from one pyramid level.

    ``level`` forces a level (0 = finest); by default the finest one that fits
    ``memory_budget_bytes`` (default :data:`~vtkvol.io.pyramid.DEFAULT_GPU_BUDGET_BYTES`) and
    ``max_texture_size`` voxels per axis is read. ``region_um`` ((x0, x1), (y0, y1),
    (z0, z1)) µm in pyramid space (see :mod:`vtkvol.io.pyramid`) reads only that box. The voxel
    size is that level's, in µm.
    """
    pyramid = open_ome_zarr(Path(path), time_index=time_index, channels=channels)
    return read_pyramid(pyramid, budget_bytes=memory_budget_bytes,
                        max_texture_size=max_texture_size, level=level, region_um=region_um,
                        progress=progress)


OME_ZARR_READER = ReaderSpec(
    name="ome_zarr",
    label="OME-Zarr (.zarr folder)",
    # A folder is offered to this reader when it holds a Zarr group's metadata file.
    filename_patterns=("*.zarr", "zarr.json", ".zattrs", ".zgroup"),
    accepts_directories=True,
    read=read_ome_zarr,
    open_pyramid=open_ome_zarr,
)
