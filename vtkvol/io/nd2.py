"""Nikon NIS-Elements ``.nd2`` files, read with ``nd2`` (BSD; optional extra ``formats``).

``nd2`` reports the axes of the file by name (``sizes``: ``T`` time, ``P`` XY position, ``Z``,
``C`` channel, ``Y``, ``X``, ``S`` RGB component) and the voxel size in µm
(``voxel_size()``, from the calibration NIS stores). Channel names and colours come from
``metadata.channels[i].channel``. One time point is read, channel by channel, through the
file's dask array (only the frames needed are decoded). Multi-position files show position 0
with a note; RGB files (brightfield) give the channels ``red``, ``green``, ``blue``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = ["ND2_READER", "read_nd2"]

_KNOWN_AXES = {"T", "P", "Z", "C", "Y", "X", "S"}


def _channel_meta(handle: Any, n: int) -> tuple[list[str], list[tuple[float, float, float] | None]]:
    """Names and colours (r, g, b in 0…1) of the ``n`` channels; ``ch0…`` when missing."""
    names = default_channel_names(n)
    colors: list[tuple[float, float, float] | None] = [None] * n
    try:
        channels = list(handle.metadata.channels or [])
    except Exception:  # metadata of old (legacy) files can fail to parse; names are optional
        channels = []
    if len(channels) == n:
        for i, ch in enumerate(channels):
            meta = getattr(ch, "channel", None)
            name = getattr(meta, "name", None)
            if isinstance(name, str) and name.strip():
                names[i] = name.strip()
            color = getattr(meta, "color", None)
            if color is not None and len(color) >= 3:
                colors[i] = (color[0] / 255.0, color[1] / 255.0, color[2] / 255.0)
        if len(set(names)) != n:
            names = [f"{name} ({i})" for i, name in enumerate(names)]
    return names, colors


def _calibrated(handle: Any) -> tuple[bool, bool, bool] | None:
    """Whether x, y, z are calibrated (``volume.axesCalibrated`` of the first channel)."""
    try:
        flags = handle.metadata.channels[0].volume.axesCalibrated
        return bool(flags[0]), bool(flags[1]), bool(flags[2])
    except Exception:  # legacy files and files without channel metadata
        return None


def read_nd2(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of an ND2 file as ``[c, z, y, x]`` (see the module docstring)."""
    progress = progress or Progress()
    path = Path(path)
    nd2 = require("nd2", "Nikon ND2 files", path)
    progress(0.0, "reading ND2 header")
    try:
        handle = nd2.ND2File(str(path))
    except Exception as exc:  # OSError for a wrong magic number, ValueError/struct errors…
        raise VolumeReadError(path, f"not a readable ND2 file ({exc})") from exc
    try:
        return _read_open(handle, path, time_index, channels, progress)
    finally:
        handle.close()


def _read_open(handle: Any, path: Path, time_index: int,
               channels: Sequence[int | str] | None, progress: Progress) -> VolumeData:
    try:
        sizes = {str(k): int(v) for k, v in dict(handle.sizes).items()}
        dtype = np.dtype(handle.dtype)
    except Exception as exc:
        raise VolumeReadError(path, f"the ND2 header cannot be read ({exc})") from exc
    unknown = [f"{k}={v}" for k, v in sizes.items() if k not in _KNOWN_AXES and v > 1]
    if unknown:
        raise VolumeReadError(path, f"unsupported axes {', '.join(unknown)}; vtkvol reads "
                                    "T, P, Z, C, Y, X and RGB")
    if "X" not in sizes or "Y" not in sizes or min(sizes.values(), default=0) < 1:
        raise VolumeReadError(path, f"no image plane in the file's axes {sizes}")
    notes: list[str] = []
    n_time = sizes.get("T", 1)
    if not 0 <= time_index < n_time:
        raise VolumeReadError(path, f"time_index {time_index} is out of range: the file has "
                                    f"{n_time} time point(s)")
    if sizes.get("P", 1) > 1:
        notes.append(f"the file holds {sizes['P']} XY positions: position 0 is shown")
    n_c, n_s = sizes.get("C", 1), sizes.get("S", 1)
    if n_c > 1 and n_s > 1:
        raise VolumeReadError(path, f"{n_c} channels of {n_s}-component (RGB) pixels: save the "
                                    "channels as grey images")
    if n_s > 1:
        names = ["red", "green", "blue", "alpha"][:n_s]
        colors: list[tuple[float, float, float] | None] = [None] * n_s
        channel_axis = "S"
    else:
        names, colors = _channel_meta(handle, n_c)
        channel_axis = "C"
    chosen = resolve_channels(channels, names, str(path))
    nz, ny, nx = sizes.get("Z", 1), sizes["Y"], sizes["X"]
    check_declared_bytes(path, len(chosen) * nz * ny * nx * dtype.itemsize,
                         f"{len(chosen)} × {nz} × {ny} × {nx} {dtype} voxels")
    try:
        lazy = handle.to_dask()
    except Exception as exc:
        raise VolumeReadError(path, f"the ND2 frames cannot be indexed ({exc})") from exc
    axes = list(sizes)
    if tuple(lazy.shape) != tuple(sizes.values()):
        raise VolumeReadError(path, f"the frame data {tuple(lazy.shape)} disagree with the "
                                    f"axes {sizes}")
    out = np.empty((len(chosen), nz, ny, nx), dtype=dtype)
    for k, c in enumerate(chosen):
        index = tuple(
            {"T": time_index, "P": 0, channel_axis: c}.get(a, slice(None)) for a in axes
        )
        try:
            block = np.asarray(lazy[index])
        except Exception as exc:  # truncated frames surface here, as whatever nd2 raises
            raise VolumeReadError(path, f"channel {names[c]!r} cannot be read: the file is "
                                        f"truncated or corrupt ({exc})") from exc
        out[k] = block.reshape(nz, ny, nx)
        progress((k + 1) / len(chosen), f"reading {names[c]}")
    try:
        voxel = handle.voxel_size()
        values = [float(voxel.x), float(voxel.y), float(voxel.z)]
    except Exception:
        values = [math.nan] * 3
    calibrated = _calibrated(handle)
    if calibrated is not None and not (calibrated[0] and calibrated[1]):
        values = [math.nan] * 3  # nd2 reports 1 µm for an uncalibrated file: not a measurement
    elif calibrated is not None and not calibrated[2] and nz > 1:
        values[2] = values[0]
        notes.append("the ND2 file has no z calibration: z spacing taken equal to x")
    if nz == 1 and not (math.isfinite(values[2]) and values[2] > 0):
        values[2] = values[0]  # one plane: z spacing is not calibrated, and does not matter
    spacing, from_metadata = spacing_or_default(
        values, "the ND2 file is not calibrated: using 1 × 1 × 1 µm", notes)
    return VolumeData(
        out,
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "nd2",
            "axes": "".join(axes),
            "time_points": n_time,
            "time_index": time_index,
            "channel_colors": [colors[c] for c in chosen],
            "voxel_size_source": "ND2 calibration (µm)" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


ND2_READER = ReaderSpec(
    name="nd2",
    label="Nikon ND2 (.nd2)",
    filename_patterns=("*.nd2",),
    accepts_directories=False,
    read=read_nd2,
)
