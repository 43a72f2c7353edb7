"""MRC/CCP4 volumes (``.mrc``, ``.map``, ``.rec``, ``.st``): electron microscopy and tomography.

Read with mrcfile (optional extra ``formats``), memory-mapped and validated. MRC stores
``(z, y, x)`` sections (or a stack of volumes, read as time points) and the voxel size in
ångström: 1 Å = 10⁻⁴ µm. A voxel size of 0 means "not set": 1 µm is used, with a note.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = ["MRC_READER", "read_mrc"]

ANGSTROM_UM = 1e-4


def read_mrc(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read an MRC volume (or one volume of a volume stack) as ``[1, z, y, x]``."""
    progress = progress or Progress()
    path = Path(path)
    mrcfile = require("mrcfile", "MRC files", path)
    progress(0.0, "reading MRC header")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            handle = mrcfile.mmap(str(path), mode="r", permissive=False)
    except (ValueError, OSError, EOFError, OverflowError) as exc:
        # OverflowError: numpy's memmap of a negative size from the header
        raise VolumeReadError(path, f"not a valid MRC file ({' '.join(str(exc).split())})"
                              ) from exc
    with handle as mrc:
        data = mrc.data
        if data is None:
            raise VolumeReadError(path, "the MRC file holds no voxel data")
        if data.dtype.kind == "c":
            raise VolumeReadError(path, "complex-valued voxels cannot be displayed")
        if data.ndim == 2:
            data = data[np.newaxis]
        n_time = data.shape[0] if data.ndim == 4 else 1
        if not 0 <= time_index < n_time:
            raise VolumeReadError(
                path,
                f"time_index {time_index} is out of range: the file has {n_time} volume(s)",
            )
        volume = data[time_index] if data.ndim == 4 else data
        if min(volume.shape) < 1:
            raise VolumeReadError(path, f"empty volume of shape {volume.shape}")
        names = default_channel_names(1)
        resolve_channels(channels, names, str(path))
        array = np.ascontiguousarray(volume)[np.newaxis].copy()  # independent of the mmap
        size = mrc.voxel_size
        angstrom = (float(size.x), float(size.y), float(size.z))
        axis_map = tuple(int(mrc.header[k]) for k in ("mapc", "mapr", "maps"))
    progress(1.0, "reading MRC")
    notes = [f"MRC header: {' '.join(str(w.message).split())}" for w in caught]
    if sorted(axis_map) != [1, 2, 3]:
        # mapc/mapr/maps say which axis (1 = x, 2 = y, 3 = z) the columns, rows and sections
        # run along; anything but an order of 1, 2, 3 is a damaged header
        raise VolumeReadError(path, f"impossible axis map (mapc, mapr, maps) = {axis_map}: it "
                                    "must be an order of 1, 2, 3 (x, y, z)")
    if axis_map != (1, 2, 3):
        notes.append(f"MRC axis map (mapc, mapr, maps) = {axis_map}, not (1, 2, 3): shown in "
                     "file order (columns as x, rows as y, sections as z)")
    spacing, from_metadata = spacing_or_default(
        [a * ANGSTROM_UM for a in angstrom],
        f"MRC voxel size {angstrom} Å is not set: using 1 × 1 × 1 µm", notes,
    )
    return VolumeData(
        array,
        spacing,
        names,
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "mrc",
            "time_points": n_time,
            "time_index": time_index,
            "voxel_size_source": "MRC header (Å)" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


MRC_READER = ReaderSpec(
    name="mrc",
    label="MRC / CCP4 (.mrc, .map, .rec, .st)",
    filename_patterns=("*.mrc", "*.map", "*.rec", "*.st", "*.mrcs"),
    accepts_directories=False,
    read=read_mrc,
)
