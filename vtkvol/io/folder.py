"""Folders that hold several stacks: find them, and read them together as channels.

A folder is read as one z-stack of single-slice TIFFs (:func:`vtkvol.io.tiff.read_tiff_folder`).
A folder of whole stacks (``nucleus.tif``, ``membrane.tif``; ``a.npy``, ``b.nrrd``; ``x.zarr``
folders) is something else: :func:`folder_stacks` lists them, :func:`read_volume` refuses such a
folder with :class:`SeveralStacksError` (which carries the list, so the app can offer a choice)
and :func:`read_stacks_as_channels` reads stacks of the same shape and voxel size as the channels
of one volume.

How a folder is told apart: every file (or ``*.zarr`` folder) whose name a reader accepts is a
candidate; when the candidates include TIFFs, the first TIFF (natural order) decides: one 2-D
image (with colour samples) means a folder of slices, anything with more planes means every
file is a stack of its own. Only that one TIFF header is read, so a folder of 10⁵ files is
classified after one directory listing and one header.
"""

from __future__ import annotations

import fnmatch
import math
import os
import re
from collections.abc import Sequence
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.progress import CancelCallback, Progress, ProgressCallback
from vtkvol.io.registry import VoxelSizeArg, available_readers
from vtkvol.io.volume_data import VolumeData

__all__ = ["LISTED_NAMES", "SeveralStacksError", "folder_stacks", "read_folder_as_channels",
           "read_stacks_as_channels", "stacks_summary"]

#: How many stack names a one-line message lists before "… and N more".
LISTED_NAMES = 6

#: TIFF headers looked at to classify a folder: the first readable one decides.
_PEEKS = 3

#: Relative difference of voxel edges still counted as the same voxel size (metadata round
#: trips through ImageJ's decimal text lose about 1e-6).
_SPACING_RTOL = 1e-3


class SeveralStacksError(VolumeReadError):
    """A folder holds several stacks rather than the slices of one.

    ``stacks``: their paths, natural order. The message lists the first
    :data:`LISTED_NAMES` and says how to open one of them or all as channels.
    """

    def __init__(self, folder: str | PathLike[str], stacks: Sequence[Path]) -> None:
        self.stacks = tuple(stacks)
        super().__init__(folder, f"holds {len(self.stacks)} stacks rather than the slices of "
                                 f"one ({stacks_summary(self.stacks)}); open one of them, or "
                                 "all of them as channels (--as-channels)")


def stacks_summary(stacks: Sequence[Path], listed: int = LISTED_NAMES) -> str:
    """``"a.tif, b.tif, c.tif"``, or the first ``listed`` names and ``"… and N more"``."""
    names = [p.name for p in stacks[:listed]]
    more = len(stacks) - len(names)
    return ", ".join(names) + (f" and {more} more" if more > 0 else "")


def _natural_key(name: str) -> list[object]:
    from vtkvol.io.tiff import natural_sort_key

    return natural_sort_key(name)


def _candidates(folder: Path) -> list[Path]:
    """Files (and ``*.zarr`` folders) in ``folder`` whose name a reader accepts, hidden ones
    left out, in natural order. Reader patterns that name a store's metadata file
    (``.zattrs``) do not count: such a folder is itself a store."""
    patterns = sorted({pat for spec in available_readers() for pat in spec.filename_patterns
                       if pat.startswith("*.")})
    # One regular expression for all patterns: matching ~30 patterns one by one took 13 s
    # for 10⁵ names on a busy 2-core machine.
    accepted = re.compile("|".join(f"(?:{fnmatch.translate(pat)})" for pat in patterns))
    found: list[str] = []
    with os.scandir(folder) as entries:
        for entry in entries:
            name = entry.name
            if name.startswith("."):
                continue
            lowered = name.lower()
            if not accepted.match(lowered):
                continue
            try:
                is_dir = entry.is_dir()
            except OSError:
                continue
            if is_dir and not lowered.endswith(".zarr"):
                continue
            found.append(name)
    found.sort(key=_natural_key)
    return [folder / name for name in found]


def _is_single_slice(path: Path) -> bool | None:
    """Whether a TIFF holds one 2-D image (colour samples allowed); None when unreadable."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            if not tif.series:
                return None
            series = tif.series[0]
            axes = series.get_axes(False)
            shape = series.get_shape(False)
            return not any(a not in "YXCS" and int(n) > 1
                           for a, n in zip(axes, shape, strict=True))
    except Exception:  # a corrupt header: let the next file decide
        return None


def folder_stacks(folder: str | PathLike[str]) -> list[Path]:
    """The stacks a folder holds: [] for a folder of slices (or one with nothing a reader
    accepts), else every candidate file in natural order (one or more).

    Raises
    ------
    VolumeReadError
        The folder cannot be listed (permissions).
    """
    folder = Path(folder)
    try:
        candidates = _candidates(folder)
    except OSError as exc:
        raise VolumeReadError(folder, f"cannot list the folder ({exc.strerror or exc})") from exc
    from vtkvol.io.tiff import TIFF_SUFFIXES

    tiffs = [p for p in candidates if p.suffix.lower() in TIFF_SUFFIXES and p.is_file()]
    for path in tiffs[:_PEEKS]:
        single = _is_single_slice(path)
        if single is None:
            continue
        if single:
            return []  # slices of one stack: the TIFF folder reader's case
        break
    else:
        if tiffs:  # no readable TIFF header: the folder reader reports the corrupt file
            return []
    return candidates


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
    from vtkvol.io.read import MAX_CHANNELS, read_volume

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
