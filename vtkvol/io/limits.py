"""Limits every reader applies before trusting a file's header: sizes the machine can hold,
data files that stay beside their descriptor, paths that are real files."""

from __future__ import annotations

import mmap
import os
import stat
from pathlib import Path

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.volume_data import format_bytes

__all__ = [
    "check_data_file", "check_declared_bytes", "check_inside", "check_path", "detach_from_file",
    "physical_memory_bytes",
]

#: Environment variable that lets detached headers name data files outside their folder.
ALLOW_EXTERNAL_DATA = "VTKVOL_ALLOW_EXTERNAL_DATA"
#: Longest path accepted (Linux's PATH_MAX).
MAX_PATH_CHARS = 4096
#: Memory-mapped voxel data up to this many bytes is copied into memory once read (None: a
#: quarter of this machine's memory); larger data stays mapped.
COPY_MAPPED_UP_TO: int | None = None


def physical_memory_bytes() -> int:
    """This machine's RAM (bytes); a large number when the platform cannot tell."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 1 << 50


def check_declared_bytes(source: Path, nbytes: int, what: str) -> None:
    """Refuse a header that declares more voxel data than this machine has memory, before
    anything is allocated (an allocation that large aborts the process, not Python)."""
    limit = physical_memory_bytes()
    if nbytes > limit:
        raise VolumeReadError(
            source,
            f"declares {what} ({format_bytes(nbytes)}), more than this machine's memory "
            f"({format_bytes(limit)}); the header is wrong or the data must be converted to a "
            "pyramid first",
        )


def check_inside(descriptor: Path, data_file: Path) -> None:
    """A detached header may name only data files in its own folder (or below), unless the
    user allows otherwise with ``VTKVOL_ALLOW_EXTERNAL_DATA=1``: a downloaded header must not
    make vtkvol read ``/etc/passwd`` or another user's files as a volume."""
    if os.environ.get(ALLOW_EXTERNAL_DATA) == "1":
        return
    folder = descriptor.resolve().parent
    target = data_file.resolve()
    if target != folder and folder not in target.parents:
        raise VolumeReadError(
            descriptor,
            f"names a data file outside its folder ({data_file}); move the data next to the "
            f"header, or set {ALLOW_EXTERNAL_DATA}=1 to allow it",
        )


def check_data_file(descriptor: Path, data_file: Path) -> None:
    """The data file a detached header names: inside the header's folder (:func:`check_inside`),
    present, and a regular file: a pipe named ``volume.raw`` would block the read forever, a
    link to ``/dev/zero`` would never end."""
    check_inside(descriptor, data_file)
    try:
        mode = data_file.stat().st_mode
    except OSError:
        raise VolumeReadError(
            descriptor, f"the data file {data_file.name!r} it names does not exist"
        ) from None
    if not stat.S_ISREG(mode):
        raise VolumeReadError(
            descriptor, f"the data file {data_file.name!r} it names is not a regular file (a "
                        "pipe, socket or device)",
        )


def check_path(path: Path) -> None:
    """The path names something readable as a volume: no NUL byte, not absurdly long, and a
    regular file or a folder (a FIFO or a device would block the read forever)."""
    text = str(path)
    if "\x00" in text:
        raise VolumeReadError(None, f"the path {text!r} contains a NUL byte")
    if len(text) > MAX_PATH_CHARS:
        raise VolumeReadError(None, f"the path is {len(text)} characters long; at most "
                                    f"{MAX_PATH_CHARS} are possible")
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        raise VolumeReadError(path, f"cannot read it ({exc.strerror or exc})") from exc
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise VolumeReadError(path, "is not a regular file or folder (a pipe, socket or "
                                    "device); vtkvol reads files")


def file_backed(array: np.ndarray) -> bool:
    """Whether ``array`` reads its values from a memory-mapped file (itself or a view)."""
    base: object = array
    while base is not None:
        if isinstance(base, (np.memmap, mmap.mmap)):
            return True
        base = getattr(base, "base", None)
    return False


def detach_from_file(array: np.ndarray) -> np.ndarray:
    """``array`` in private memory when it is memory-mapped and not larger than
    :data:`COPY_MAPPED_UP_TO` (by default a quarter of this machine's memory).

    A mapping reads the file at every access: if another program truncates the file in place
    (re-saving it under the same name), the next access kills the process with SIGBUS, in
    numpy or inside VTK. A copy is immune; only data too large to copy stays mapped.
    """
    limit = physical_memory_bytes() // 4 if COPY_MAPPED_UP_TO is None else COPY_MAPPED_UP_TO
    if not file_backed(array) or array.nbytes > limit:
        return array
    return np.array(array, copy=True, order="C")
