"""What the command line, batch rendering and movie export read and write, in one place: the
input of a render (a volume file or folder, or ``"sample"``) and PNG images (atomic writes)."""

from __future__ import annotations

import errno
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from vtkvol.io import VolumeData


def load_input(path: str, voxel_size: Sequence[float] | None, time_index: int = 0,
               budget: int | None = None, *, as_channels: bool = False) -> VolumeData:
    """``"sample"`` (the built-in confocal phantom) or the volume at ``path``, read with
    ``voxel_size`` (µm, x y z; None: the file's own), time point ``time_index`` and a memory
    budget of ``budget`` bytes (None: the reader's default). An address (OME-Zarr over
    HTTP(S)/S3) reports its fetching progress on stderr. ``as_channels``: ``path`` is a
    folder of stacks, read as the channels of one volume (``--as-channels``)."""
    from vtkvol.io import confocal_phantom, read_volume
    from vtkvol.io.remote import fetch_progress, is_remote

    if as_channels:
        from vtkvol.io.folder_channels import read_folder_as_channels

        return read_folder_as_channels(path, voxel_size_um=voxel_size, time_index=time_index,
                                       memory_budget_bytes=budget)
    if path == "sample":
        return confocal_phantom()
    return read_volume(path, voxel_size_um=voxel_size, time_index=time_index,
                       memory_budget_bytes=budget,
                       progress=fetch_progress(path) if is_remote(path) else None)


def write_png(image: np.ndarray, path: Path, *, replace: bool = True) -> None:
    """An ``(h, w, 3)`` uint8 image, top row first, as a PNG: encoded in memory, then written
    atomically (vtkvol.io.atomic), so a failed write raises OSError and never leaves a
    truncated PNG, nor replaces the previous one. With ``replace=False`` an existing file
    (even one created meanwhile) raises FileExistsError."""
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

    from vtkvol.io.atomic import write_atomic

    h, w, _ = image.shape
    img = vtk.vtkImageData()
    img.SetDimensions(w, h, 1)
    img.GetPointData().SetScalars(numpy_to_vtk(image[::-1].reshape(-1, 3).copy(), deep=True))
    writer = vtk.vtkPNGWriter()
    writer.WriteToMemoryOn()
    writer.SetInputData(img)
    writer.Write()
    if path.parent.exists() and not path.parent.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, f"{path.parent} is not a folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, vtk_to_numpy(writer.GetResult()).tobytes(), replace=replace)
