"""Last-resort reader: any file no other reader claims, handed to ``bioio`` when it is installed.

``bioio`` is not a vtkvol dependency (several of its plugins are GPL, e.g. bioio-czi, and
vtkvol's own readers cover the common formats); a user who has installed it and a plugin
(``pip install bioio bioio-lif``…) gets those formats too. The spec is last in the registry, and
it claims a file only when bioio is importable and one of its plugins says it supports the
file, so unknown files keep their "unknown file type" message otherwise.

bioio gives the image as ``TCZYX``; the voxel size from ``physical_pixel_sizes`` with the
unit of ``dimension_properties`` (bioio ≥ 3; older versions give no unit, read as µm with a
note), channel names from ``channel_names``; the first scene.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
from collections.abc import Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = ["BIOIO_READER", "read_with_bioio"]


def _bioio() -> Any | None:
    if importlib.util.find_spec("bioio") is None:
        return None
    try:
        return importlib.import_module("bioio")
    except Exception:  # a broken bioio install must not break reading other files
        return None


def _unit_scale(img: Any, axis: str, notes: list[str]) -> float:
    """µm per unit of ``axis`` ("X", "Y", "Z") as bioio declares it; 1 with a note if unknown."""
    try:
        unit = getattr(img.dimension_properties, axis).unit
    except Exception:
        unit = None
    if unit is None:
        notes.append(f"bioio gives no unit for {axis}: read as µm")
        return 1.0
    scale = unit_scale_um(str(unit))
    if scale is None:
        notes.append(f"unknown unit {str(unit)!r} for {axis}: read as µm")
        return 1.0
    return scale


def read_with_bioio(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of the first scene through bioio as ``[c, z, y, x]``."""
    progress = progress or Progress()
    path = Path(path)
    bioio = _bioio()
    if bioio is None:
        raise VolumeReadError(path, "reading this format needs 'bioio' and one of its plugins "
                                    "(pip install bioio bioio-…); it is not installed")
    progress(0.0, "opening with bioio")
    try:
        img = bioio.BioImage(str(path))
        dims = img.dims
        sizes = {a: int(getattr(dims, a, 1)) for a in ("T", "C", "Z", "Y", "X")}
        dtype = np.dtype(img.dtype)
        scenes = list(getattr(img, "scenes", []) or [])
    except Exception as exc:  # every plugin raises its own types
        raise VolumeReadError(path, f"bioio cannot read it ({type(exc).__name__}: "
                                    f"{exc})") from exc
    notes: list[str] = [f"read through bioio ({type(getattr(img, 'reader', img)).__name__})"]
    if len(scenes) > 1:
        notes.append(f"the file holds {len(scenes)} scenes: {scenes[0]!r} is shown")
    n_time, n_c = sizes["T"], sizes["C"]
    if not 0 <= time_index < n_time:
        raise VolumeReadError(path, f"time_index {time_index} is out of range: the file has "
                                    f"{n_time} time point(s)")
    names = default_channel_names(n_c)
    try:
        found = [str(n) for n in (img.channel_names or [])]
    except Exception:
        found = []
    if len(found) == n_c and all(found):
        names = found if len(set(found)) == n_c else [f"{n} ({i})" for i, n in enumerate(found)]
    chosen = resolve_channels(channels, names, str(path))
    nz, ny, nx = sizes["Z"], sizes["Y"], sizes["X"]
    check_declared_bytes(path, len(chosen) * nz * ny * nx * dtype.itemsize,
                         f"{len(chosen)} × {nz} × {ny} × {nx} {dtype} voxels")
    out = np.empty((len(chosen), nz, ny, nx), dtype=dtype)
    for k, c in enumerate(chosen):
        try:
            block = img.get_image_dask_data("ZYX", T=time_index, C=c)
            out[k] = np.asarray(block.compute() if hasattr(block, "compute") else block)
        except Exception as exc:
            raise VolumeReadError(path, f"channel {names[c]!r} cannot be read through bioio "
                                        f"({type(exc).__name__}: {exc})") from exc
        progress((k + 1) / len(chosen), f"reading {names[c]}")
    try:
        pps = img.physical_pixel_sizes
        raw = {"X": pps.X, "Y": pps.Y, "Z": pps.Z}
    except Exception:
        raw = {"X": None, "Y": None, "Z": None}
    values = []
    for axis in ("X", "Y", "Z"):
        value = raw[axis]
        if value is None or not math.isfinite(float(value)):
            values.append(math.nan)
            continue
        values.append(float(value) * _unit_scale(img, axis, notes))
    if nz == 1 and not values[2] > 0:
        values[2] = values[0]  # a single plane: its thickness does not matter
    spacing, from_metadata = spacing_or_default(
        values, f"bioio gives no usable voxel size {tuple(raw.values())}: using 1 × 1 × 1 µm",
        notes)
    return VolumeData(
        out,
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "bioio",
            "time_points": n_time,
            "time_index": time_index,
            "voxel_size_source": "bioio physical_pixel_sizes" if from_metadata
            else "default 1 µm",
        },
        notes=notes,
    )


@dataclass(frozen=True)
class BioioFallbackSpec(ReaderSpec):
    """A :class:`ReaderSpec` that claims a file only when bioio has a plugin for it."""

    def matches(self, path: str | PathLike[str]) -> bool:
        """Whether bioio is installed and one of its plugins supports ``path`` (a file)."""
        p = Path(path)
        if p.is_dir():
            return False
        bioio = _bioio()
        if bioio is None:
            return False
        try:
            bioio.BioImage.determine_plugin(str(p))
        except Exception:  # UnsupportedFileFormatError, or a plugin failing to probe
            return False
        return True


BIOIO_READER = BioioFallbackSpec(
    name="bioio",
    label="Other formats through bioio, when installed",
    filename_patterns=(),
    accepts_directories=False,
    read=read_with_bioio,
)
