"""Leica ``.lif``/``.lof``/``.xlif`` files (LAS X), read with ``liffile`` (BSD; extra ``formats``).

A LIF file is a collection of images; the first 3-D one (a ``Z`` axis) is read, or the first
image when none is 3-D, with a note naming the others. ``liffile`` gives the axes (``dims``:
``T``, ``Z``, ``C``, ``Y``, ``X``, ``S`` for RGB samples, ``M`` for mosaic tiles…) and the data,
memory-mapped where the file allows; the selected time point and channels are copied out.

Voxel size: the image's XML ``DimensionDescription`` elements give ``Length`` (first to last
element) and ``Unit`` per axis (LAS X writes metres): voxel = Length / (n − 1), converted to
µm, the same spacing liffile's coordinates use. Channel names are the channels' LUT names
(``Green``, ``Red``…), the only name LAS X stores per channel; they also give the colours.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = ["LIF_READER", "read_lif"]

#: LAS X dimension ids of x, y, z (``DimensionDescription/@DimID``).
_DIM_IDS = {"1": "x", "2": "y", "3": "z"}
_LUT_COLORS = {
    "red": (1.0, 0.0, 0.0), "green": (0.0, 1.0, 0.0), "blue": (0.0, 0.0, 1.0),
    "cyan": (0.0, 1.0, 1.0), "magenta": (1.0, 0.0, 1.0), "yellow": (1.0, 1.0, 0.0),
    "gray": (1.0, 1.0, 1.0), "grey": (1.0, 1.0, 1.0),
}
_KNOWN_AXES = {"T", "Z", "C", "Y", "X", "S", "M"}


def _spacing_from_xml(element: Any) -> dict[str, tuple[float, str]]:
    """``{"x": (step, unit), …}`` from the image's ``DimensionDescription`` elements."""
    found: dict[str, tuple[float, str]] = {}
    if element is None:
        return found
    for dim in element.iter("DimensionDescription"):
        axis = _DIM_IDS.get(str(dim.get("DimID")))
        if axis is None:
            continue
        try:
            n = int(dim.get("NumberOfElements", "0"))
            length = float(dim.get("Length", "nan"))
        except ValueError:
            continue
        if n > 1:
            found[axis] = (length / (n - 1), str(dim.get("Unit", "")))
    return found


def _channel_luts(element: Any) -> list[str]:
    if element is None:
        return []
    return [str(ch.get("LUTName", "")).strip() for ch in element.iter("ChannelDescription")]


def _pick_image(images: Sequence[Any], notes: list[str]) -> Any:
    if not images:
        return None
    chosen = next((im for im in images if dict(im.sizes).get("Z", 1) > 1), images[0])
    if len(images) > 1:
        others = ", ".join(repr(im.name) for im in images if im is not chosen)
        notes.append(f"the file holds {len(images)} images; {chosen.name!r} is shown "
                     f"(others: {others})")
    return chosen


def read_lif(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of a Leica image as ``[c, z, y, x]`` (see the module docstring)."""
    progress = progress or Progress()
    path = Path(path)
    liffile = require("liffile", "Leica LIF/LOF files", path)
    progress(0.0, "reading LIF header")
    try:
        handle = liffile.LifFile(str(path))
    except Exception as exc:  # LifFileError (a ValueError), OSError, struct errors…
        raise VolumeReadError(path, f"not a readable Leica image file ({exc})") from exc
    try:
        return _read_open(handle, path, time_index, channels, progress)
    finally:
        handle.close()


def _read_open(handle: Any, path: Path, time_index: int,
               channels: Sequence[int | str] | None, progress: Progress) -> VolumeData:
    notes: list[str] = []
    try:
        images = list(handle.images)
        image = _pick_image(images, notes)
        if image is None:
            raise VolumeReadError(path, "the file holds no image")
        sizes = {str(k): int(v) for k, v in dict(image.sizes).items()}
        dims = [str(d) for d in image.dims]
        dtype = np.dtype(image.dtype)
    except VolumeReadError:
        raise
    except Exception as exc:  # malformed XML surfaces as ValueError/KeyError in liffile
        raise VolumeReadError(path, f"the image description cannot be read ({exc})") from exc
    unknown = [f"{d}={sizes[d]}" for d in dims if d not in _KNOWN_AXES]
    if unknown:
        raise VolumeReadError(path, f"image {image.name!r} has unsupported axes "
                                    f"{', '.join(unknown)}; vtkvol reads T, Z, C, Y, X, RGB")
    if "X" not in sizes or "Y" not in sizes:
        raise VolumeReadError(path, f"image {image.name!r} has no image plane (axes {dims})")
    n_time = sizes.get("T", 1)
    if not 0 <= time_index < n_time:
        raise VolumeReadError(path, f"time_index {time_index} is out of range: the image has "
                                    f"{n_time} time point(s)")
    if sizes.get("M", 1) > 1:
        notes.append(f"{sizes['M']} mosaic tiles: tile 0 is shown (tiles are not stitched)")
    n_c, n_s = sizes.get("C", 1), sizes.get("S", 1)
    if n_c > 1 and n_s > 1:
        raise VolumeReadError(path, f"{n_c} channels of RGB samples are not supported")
    luts = _channel_luts(getattr(image, "xml_element", None))
    if n_s > 1:
        names = ["red", "green", "blue", "alpha"][:n_s]
        colors: list[tuple[float, float, float] | None] = [None] * n_s
        channel_axis = "S"
    else:
        names = default_channel_names(n_c)
        if len(luts) == n_c and all(luts):
            names = luts if len(set(luts)) == n_c else [f"{n} ({i})" for i, n in enumerate(luts)]
        colors = [_LUT_COLORS.get(lut.lower()) for lut in luts] if len(luts) == n_c else [
            None] * n_c
        channel_axis = "C"
    chosen = resolve_channels(channels, names, str(path))
    nz, ny, nx = sizes.get("Z", 1), sizes["Y"], sizes["X"]
    check_declared_bytes(path, len(chosen) * nz * ny * nx * dtype.itemsize,
                         f"{len(chosen)} × {nz} × {ny} × {nx} {dtype} voxels")
    try:
        # Memory-mapped where the data are stored plainly: only the selection is copied.
        data = image.asarray(out="memmap")
    except Exception as exc:  # a memory block past the end of a truncated file
        raise VolumeReadError(path, f"the voxel data of image {image.name!r} cannot be read; "
                                    f"the file is truncated or corrupt ({exc})") from exc
    if tuple(data.shape) != tuple(sizes[d] for d in dims):
        raise VolumeReadError(path, f"image {image.name!r} data shape {tuple(data.shape)} does "
                                    f"not match its axes {sizes}")
    out = np.empty((len(chosen), nz, ny, nx), dtype=dtype)
    for k, c in enumerate(chosen):
        index = tuple({"T": time_index, "M": 0, channel_axis: c}.get(d, slice(None)) for d in dims)
        block = np.asarray(data[index])
        kept = [d for d in dims if d not in ("T", "M", channel_axis)]
        out[k] = block.transpose([kept.index(d) for d in ("Z", "Y", "X") if d in kept]).reshape(
            nz, ny, nx)
        progress((k + 1) / len(chosen), f"reading {names[c]}")
    del data
    steps = _spacing_from_xml(getattr(image, "xml_element", None))
    values: list[float] = []
    units_unknown = []
    for axis in ("x", "y", "z"):
        step, unit = steps.get(axis, (float("nan"), ""))
        scale = unit_scale_um(unit)
        if scale is None and axis in steps:
            units_unknown.append(f"{axis}: {unit!r}")
        values.append(step * scale if scale is not None else float("nan"))
    if units_unknown:
        notes.append(f"unknown length unit ({', '.join(units_unknown)}): voxel size not used")
    if nz == 1 and not (values[2] > 0):
        values[2] = values[0]  # a single plane: its thickness does not matter
    spacing, from_metadata = spacing_or_default(
        values, f"no usable voxel size in the image description ({values}): using 1 × 1 × 1 µm",
        notes)
    return VolumeData(
        out,
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "lif",
            "image": str(image.name),
            "axes": "".join(dims),
            "time_points": n_time,
            "time_index": time_index,
            "channel_colors": [colors[c] for c in chosen],
            "voxel_size_source": "LIF DimensionDescription" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


LIF_READER = ReaderSpec(
    name="lif",
    label="Leica LIF / LOF / XLIF (.lif, .lof, .xlif)",
    filename_patterns=("*.lif", "*.lof", "*.xlif"),
    accepts_directories=False,
    read=read_lif,
)
