"""Readers: file -> :class:`VolumeData` (numpy ``[c, z, y, x]`` + voxel size (x, y, z) in µm).

No VTK and no Qt at import time (VTK is imported lazily, only to read VTK files).
See docs/file-formats.md for the supported formats.
"""

from vtkvol.io.errors import ReadCancelled, VolumeReadError
from vtkvol.io.fit import FIT_STRATEGIES, FitStrategy, fit_volume
from vtkvol.io.folder import SeveralStacksError, folder_stacks
from vtkvol.io.folder_channels import read_folder_as_channels, read_stacks_as_channels
from vtkvol.io.read import read_volume
from vtkvol.io.registry import ReaderSpec, available_readers, get_reader, reload_readers
from vtkvol.io.sample import confocal_phantom
from vtkvol.io.volume_data import Spacing, VolumeData


def from_vtk_image(image: "vtkImageData", *, source: str | None = None) -> VolumeData:  # noqa: F821
    """Wrap any ``vtkImageData`` as a checked :class:`VolumeData` (imports VTK lazily).

    Point scalars with 1–4 components become channels, spacing the voxel size (x, y, z) in
    µm. See :func:`vtkvol.io.vti.from_vtk_image`.
    """
    from vtkvol.io.vti import from_vtk_image as _from_vtk_image

    return _from_vtk_image(image, source=source)


__all__ = [
    "FIT_STRATEGIES",
    "FitStrategy",
    "ReadCancelled",
    "ReaderSpec",
    "SeveralStacksError",
    "Spacing",
    "VolumeData",
    "VolumeReadError",
    "available_readers",
    "confocal_phantom",
    "fit_volume",
    "folder_stacks",
    "from_vtk_image",
    "get_reader",
    "read_folder_as_channels",
    "read_stacks_as_channels",
    "read_volume",
    "reload_readers",
]
