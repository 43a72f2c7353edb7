"""Folders that hold several stacks: find them, and read them together as channels.

A folder is read as one z-stack of single-slice TIFFs (:func:`vtkvol.io.tiff.read_tiff_folder`).
A folder of whole stacks (``nucleus.tif``, ``membrane.tif``; ``a.npy``, ``b.nrrd``; ``x.zarr``
folders) is something else: :func:`folder_stacks` lists them, :func:`read_volume` refuses such a
folder with :class:`SeveralStacksError` (which carries the list, so the app can offer a choice)
and :func:`vtkvol.io.folder_channels.read_stacks_as_channels` reads stacks of the same shape
and voxel size as the channels of one volume.

How a folder is told apart: every file (or ``*.zarr`` folder) whose name a reader accepts is a
candidate; when the candidates include TIFFs, the first TIFF (natural order) decides: one 2-D
image (with colour samples) means a folder of slices, anything with more planes means every
file is a stack of its own. Only that one TIFF header is read, so a folder of 10⁵ files is
classified after one directory listing and one header.
"""

from __future__ import annotations

import fnmatch
import os
import re
from collections.abc import Sequence
from os import PathLike
from pathlib import Path

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.registry import available_readers

__all__ = ["LISTED_NAMES", "SeveralStacksError", "folder_stacks", "stacks_summary"]

#: How many stack names a one-line message lists before "… and N more".
LISTED_NAMES = 6

#: TIFF headers looked at to classify a folder: the first readable one decides.
_PEEKS = 3

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
