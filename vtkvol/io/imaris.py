"""Imaris ``.ims`` files (Bitplane/Oxford Instruments): HDF5 with a resolution pyramid.

Read with h5py (optional extra ``formats``), a small adapter over Imaris' documented layout
(not the unmaintained IMS reader that rounds voxel sizes):

* voxels: ``/DataSet/ResolutionLevel L/TimePoint t/Channel c/Data``, ``(z, y, x)``, possibly
  padded beyond the image to whole chunks (the padding is cut off);
* size and extent: attributes ``X``, ``Y``, ``Z``, ``ExtMin0..2``, ``ExtMax0..2`` and ``Unit`` of
  ``/DataSetInfo/Image`` (stored as arrays of single characters); the voxel size is
  (ExtMax − ExtMin)/size per axis, in ``Unit`` (µm when absent);
* channels: ``Name`` and ``Color`` ("r g b" in 0…1) of ``/DataSetInfo/Channel c``.

The finest resolution level is read; :func:`vtkvol.io.read_volume` then fits it to the GPU as it
does every volume.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import VolumeData, resolve_channels, spacing_or_default

__all__ = ["IMARIS_READER", "read_imaris"]


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


def read_imaris(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of an Imaris file's finest resolution level as ``[c, z, y, x]``."""
    progress = progress or Progress()
    path = Path(path)
    h5py = require("h5py", "Imaris files", path)
    try:
        handle = h5py.File(str(path), "r")
    except OSError as exc:
        raise VolumeReadError(path, f"not a readable Imaris (HDF5) file ({exc})") from exc
    with handle as f:
        if "DataSet" not in f or "DataSetInfo/Image" not in f:
            raise VolumeReadError(path, "an HDF5 file without Imaris' DataSet and "
                                        "DataSetInfo/Image groups")
        info = f["DataSetInfo/Image"].attrs
        size = [_number(info, k, path) for k in ("X", "Y", "Z")]
        if not all(np.isfinite(s) and s >= 1 and s == int(s) for s in size):
            raise VolumeReadError(path, f"image size X, Y, Z = {size} is not a positive integer")
        nx, ny, nz = (int(s) for s in size)
        level = f["DataSet"].get("ResolutionLevel 0")
        if level is None:
            raise VolumeReadError(path, "no resolution level 0 in /DataSet")
        times = sorted((k for k in level if k.startswith("TimePoint ")),
                       key=lambda k: int(k.split()[-1]))
        if not 0 <= time_index < len(times):
            raise VolumeReadError(
                path, f"time_index {time_index} is out of range: the file has {len(times)} "
                      "time point(s)"
            )
        point = level[times[time_index]]
        channel_keys = sorted((k for k in point if k.startswith("Channel ")),
                              key=lambda k: int(k.split()[-1]))
        if not channel_keys:
            raise VolumeReadError(path, f"no channels in {times[time_index]}")
        names = []
        for key in channel_keys:
            group = f.get(f"DataSetInfo/{key}")
            name = _text(group.attrs, "Name") if group is not None else None
            names.append(name or key.lower().replace(" ", ""))
        chosen = resolve_channels(channels, names, str(path))
        volumes = []
        for i, c in enumerate(chosen):
            dataset = point[channel_keys[c]].get("Data")
            if dataset is None:
                raise VolumeReadError(path, f"{channel_keys[c]} has no Data")
            if dataset.ndim != 3 or any(
                have < want for have, want in zip(dataset.shape, (nz, ny, nx), strict=True)
            ):
                raise VolumeReadError(
                    path, f"{channel_keys[c]} Data has shape {dataset.shape}, smaller than the "
                          f"image's (z, y, x) = {(nz, ny, nx)}"
                )
            try:
                volumes.append(np.asarray(dataset[:nz, :ny, :nx]))
            except OSError as exc:
                raise VolumeReadError(path, f"{channel_keys[c]} cannot be read ({exc})") from exc
            progress((i + 1) / len(chosen), f"reading {names[c]}")
        extent = [(_number(info, f"ExtMin{a}", path), _number(info, f"ExtMax{a}", path))
                  for a in range(3)]
        unit = _text(info, "Unit")
    notes: list[str] = []
    scale = unit_scale_um(unit) if unit else 1.0
    if scale is None:
        notes.append(f"unknown length unit {unit!r} in the file: voxel size read as µm")
        scale = 1.0
    spacing, from_metadata = spacing_or_default(
        [(hi - lo) / n * scale for (lo, hi), n in zip(extent, (nx, ny, nz), strict=True)],
        f"extent {extent} gives no positive voxel size: using 1 × 1 × 1 µm", notes,
    )
    return VolumeData(
        np.stack(volumes),
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "imaris",
            "time_points": len(times),
            "time_index": time_index,
            "voxel_size_source": "Imaris extent / size" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


IMARIS_READER = ReaderSpec(
    name="imaris",
    label="Imaris (.ims)",
    filename_patterns=("*.ims",),
    accepts_directories=False,
    read=read_imaris,
)
