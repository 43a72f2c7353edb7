"""Exceptions raised by the readers in :mod:`vtkvol.io`."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

__all__ = ["ReadCancelled", "VolumeReadError", "display_name"]


class VolumeReadError(ValueError):
    """A file could not be turned into a :class:`~vtkvol.io.VolumeData`.

    The message always starts with the file name and says what is wrong, e.g.
    ``"psf_all_nan.tif: every voxel is NaN or infinite; nothing to display"``, so that the
    app can show it to the user unchanged.

    Parameters
    ----------
    source
        The file or folder being read (or ``None`` for in-memory data).
    problem
        What is wrong, in words, without the file name.
    """

    def __init__(self, source: str | PathLike[str] | None, problem: str) -> None:
        self.source = None if source is None else str(source)
        self.problem = problem
        super().__init__(f"{display_name(source)}: {problem}")


class ReadCancelled(Exception):
    """Raised by a reader when the caller's ``cancel()`` callback returned True.

    Deliberately not a :class:`VolumeReadError`: cancelling is not an error to report.
    """


def display_name(source: str | PathLike[str] | None) -> str:
    """The short name used at the start of error messages and notes (file name only)."""
    if source is None:
        return "array"
    if "://" in str(source):  # an address (vtkvol.io.remote): the host matters, say it all
        return str(source)
    name = Path(source).name
    return name or str(source)
