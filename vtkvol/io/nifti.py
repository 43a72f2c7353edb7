"""NIfTI-1/-2 volumes (``.nii``, ``.nii.gz``): MRI templates, light-sheet exports, atlases.

Read with nibabel (optional extra ``formats``). NIfTI stores voxels x fastest, indexed
``[x, y, z, t, c]``; they are returned as ``[c, z, y, x]`` for the chosen time point. The voxel
size comes from the header's ``pixdim`` in its declared unit (metre, mm or µm); NIfTI's
"unknown" unit is read as mm, the format's customary unit, with a note. The orientation matrix
(``qform``/``sform``) is not applied: voxels are shown in file order, with a note when the
matrix is not diagonal.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from vtkvol.io.errors import VolumeReadError
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

__all__ = ["NIFTI_READER", "read_nifti"]

#: nibabel's names for NIfTI's spatial units → µm.
_UNITS = {"meter": 1e6, "mm": 1e3, "micron": 1.0}


def read_nifti(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of a NIfTI file as ``[c, z, y, x]`` (see the module docstring)."""
    progress = progress or Progress()
    path = Path(path)
    nib = require("nibabel", "NIfTI files", path)
    try:
        image = nib.load(str(path))
    except Exception as exc:  # nibabel raises many types for bad headers
        raise VolumeReadError(path, f"not a readable NIfTI file ({exc})") from exc
    if not isinstance(image, nib.Nifti1Image | nib.Nifti2Image):
        raise VolumeReadError(path, f"not a NIfTI image (nibabel read a {type(image).__name__})")
    shape = tuple(int(n) for n in image.shape)
    if len(shape) < 3 or min(shape[:3]) < 1:
        raise VolumeReadError(path, f"expected at least 3 dimensions (x, y, z), got {shape}")
    if len(shape) > 5:
        raise VolumeReadError(path, f"{len(shape)}-D data {shape}: at most x, y, z, t, channel")
    n_time = shape[3] if len(shape) > 3 else 1
    n_channels = shape[4] if len(shape) > 4 else 1
    if not 0 <= time_index < n_time:
        raise VolumeReadError(
            path, f"time_index {time_index} is out of range: the file has {n_time} time point(s)"
        )
    names = default_channel_names(n_channels)
    chosen = resolve_channels(channels, names, str(path))
    progress(0.0, "reading NIfTI")
    try:
        proxy = image.dataobj
        index = (slice(None),) * 3 + ((time_index,) if len(shape) > 3 else ())
        volumes = []
        for c in chosen:
            block = np.asanyarray(proxy[(*index, c) if len(shape) > 4 else index])
            volumes.append(np.ascontiguousarray(block.transpose(2, 1, 0)))  # → [z, y, x]
            progress(len(volumes) / len(chosen), "reading NIfTI")
    except (OSError, ValueError, EOFError) as exc:
        raise VolumeReadError(path, f"the voxel data are truncated or unreadable ({exc})") from exc
    array = np.stack(volumes)
    if array.dtype.kind == "c":
        raise VolumeReadError(path, "complex-valued voxels cannot be displayed")
    notes: list[str] = []
    zooms = [float(z) for z in image.header.get_zooms()[:3]]
    unit = image.header.get_xyzt_units()[0]
    scale = _UNITS.get(unit)
    if scale is None:
        scale = unit_scale_um("mm")
        notes.append("NIfTI header gives no length unit: voxel size read as mm")
    spacing, from_metadata = spacing_or_default(
        [z * scale for z in zooms],  # type: ignore[operator]
        f"NIfTI voxel size {tuple(zooms)} is not positive: using 1 × 1 × 1 µm", notes,
    )
    affine = image.affine
    if affine is not None and np.count_nonzero(affine[:3, :3] - np.diag(np.diag(affine[:3, :3]))):
        notes.append("the file's orientation matrix is rotated or sheared: shown in voxel order")
    return VolumeData(
        array,
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "nifti",
            "time_points": n_time,
            "time_index": time_index,
            "voxel_size_source": "NIfTI pixdim" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


NIFTI_READER = ReaderSpec(
    name="nifti",
    label="NIfTI (.nii, .nii.gz)",
    filename_patterns=("*.nii", "*.nii.gz"),
    accepts_directories=False,
    read=read_nifti,
)
