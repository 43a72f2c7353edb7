"""Several stacks of one shape and voxel size read as the channels of one volume (the
folder's stacks found by :func:`vtkvol.io.folder.folder_stacks`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.folder import folder_stacks, stacks_summary
from vtkvol.io.progress import CancelCallback, Progress, ProgressCallback
from vtkvol.io.read import MAX_CHANNELS, read_volume
from vtkvol.io.registry import VoxelSizeArg
from vtkvol.io.volume_data import VolumeData

__all__ = ["read_folder_as_channels", "read_stacks_as_channels"]

#: Relative difference of voxel edges still counted as the same voxel size (metadata round
#: trips through ImageJ's decimal text lose about 1e-6).
_SPACING_RTOL = 1e-3


def read_folder_as_channels(folder: str | PathLike[str], **kwargs: Any) -> VolumeData:
    """Every stack of ``folder`` (:func:`folder_stacks`) as the channels of one volume;
    ``kwargs`` as for :func:`read_stacks_as_channels`.

    Raises
    ------
    VolumeReadError
        ``folder`` is not a folder, holds fewer than two stacks, or as
        :func:`read_stacks_as_channels`.
    """
    path = Path(folder)
    if not path.is_dir():
        problem = "no such folder" if not path.exists() else "is a file, not a folder of stacks"
        raise VolumeReadError(path, f"{problem}; only a folder's stacks can be read as channels")
    stacks = folder_stacks(path)
    if len(stacks) < 2:
        what = "the slices of one stack" if not stacks else f"one stack ({stacks[0].name})"
        raise VolumeReadError(path, f"holds {what}; reading stacks as channels needs a folder "
                                    "of two or more stacks")
    return read_stacks_as_channels(stacks, **kwargs)


def read_stacks_as_channels(
    stacks: Sequence[str | PathLike[str]],
    *,
    voxel_size_um: VoxelSizeArg = None,
    time_index: int = 0,
    memory_budget_bytes: int | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelCallback | None = None,
) -> VolumeData:
    """Read several stacks of one shape and voxel size as the channels of one volume.

    Each stack is read with :func:`~vtkvol.io.read_volume` (its channels keep their order;
    a channel is named after its file, ``nucleus`` or ``nucleus-ch1``). ``voxel_size_um``
    overrides every file's voxel size (x, y, z) in µm, so stacks without one can match;
    ``memory_budget_bytes`` is shared evenly between the stacks. Data types differing between
    stacks are promoted to the common one (uint8 + uint16 → uint16; float32 otherwise).

    Raises
    ------
    VolumeReadError
        Fewer than two stacks, more channels than :data:`~vtkvol.io.read.MAX_CHANNELS`, a
        stack that cannot be read (its own message), or stacks whose shape (z, y, x) or
        voxel size differ (naming both files).
    ReadCancelled
        ``cancel()`` returned True.
    """
    paths = [Path(p) for p in stacks]
    source = paths[0].parent if paths else None
    if len(paths) < 2:
        raise VolumeReadError(source, "reading stacks as channels needs at least two stacks")
    if len(paths) > MAX_CHANNELS:
        raise VolumeReadError(
            source, f"{len(paths)} stacks ({stacks_summary(paths)}) are more channels than the "
                    f"{MAX_CHANNELS} vtkvol shows at once; open them one at a time")
    prog = Progress(progress, cancel)
    share = None if memory_budget_bytes is None else max(1, memory_budget_bytes // len(paths))
    parts: list[VolumeData] = []
    for i, path in enumerate(paths):
        part = read_volume(path, voxel_size_um=voxel_size_um, time_index=time_index,
                           memory_budget_bytes=share,
                           progress=prog.sub(i / len(paths), (i + 1) / len(paths)))
        if parts:
            _check_match(parts[0], paths[0], part, path)
        if sum(p.n_channels for p in parts) + part.n_channels > MAX_CHANNELS:
            raise VolumeReadError(
                source, f"the stacks hold more than {MAX_CHANNELS} channels together "
                        f"({path.name} brings {part.n_channels}); vtkvol shows up to "
                        f"{MAX_CHANNELS} at once")
        parts.append(part)
    dtype = np.result_type(*(p.array.dtype for p in parts))
    if dtype not in (np.uint8, np.uint16, np.int16, np.float32):
        dtype = np.dtype(np.float32)
    array = np.concatenate([p.array.astype(dtype, copy=False) for p in parts], axis=0)
    names: list[str] = []
    for part, path in zip(parts, paths, strict=True):
        stem = path.name.split(".")[0] or path.name
        names += ([stem] if part.n_channels == 1
                  else [f"{stem}-{name}" for name in part.channel_names])
    notes = [f"{path.name}: {note}" for part, path in zip(parts, paths, strict=True)
             for note in part.notes]
    metadata = {"format": "stacks-as-channels", "files": [p.name for p in paths],
                "time_index": time_index,
                "time_points": min(int(p.metadata.get("time_points", 1)) for p in parts),
                "voxel_size_source": parts[0].metadata.get("voxel_size_source", "")}
    prog(1.0, f"read {len(paths)} stacks as channels")
    return VolumeData(array, parts[0].voxel_size_um, names, source=str(source),
                      voxel_size_from_metadata=all(p.voxel_size_from_metadata for p in parts),
                      metadata=metadata, notes=notes)


def _check_match(first: VolumeData, first_path: Path, other: VolumeData, path: Path) -> None:
    """VolumeReadError naming both files when ``other`` cannot be a channel of ``first``."""
    shape_a, shape_b = first.array.shape[1:], other.array.shape[1:]
    if shape_a != shape_b:
        raise VolumeReadError(
            path, f"its shape (z, y, x) {tuple(shape_b)} differs from {first_path.name}'s "
                  f"{tuple(shape_a)}; only stacks of one shape can be channels of one volume")
    a, b = first.voxel_size_um, other.voxel_size_um
    if not all(math.isclose(x, y, rel_tol=_SPACING_RTOL) for x, y in zip(a, b, strict=True)):
        def fmt(s: Sequence[float]) -> str:
            return " × ".join(f"{v:g}" for v in s)

        raise VolumeReadError(
            path, f"its voxel size {fmt(b)} µm differs from {first_path.name}'s {fmt(a)} µm; "
                  "give one voxel size for all (--voxel-size) if they are the same")
