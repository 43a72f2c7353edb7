"""Progress reporting and cancellation shared by all readers.

Readers receive a :class:`Progress` and call it once per page, slice or chunk. Each call
forwards a fraction (0…1 of the *whole* read) to the user's callback and raises
:class:`~vtkvol.io.errors.ReadCancelled` when the user's ``cancel()`` returns True, so
cancellation is checked exactly where work is done.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from vtkvol.io.errors import ReadCancelled

__all__ = ["CancelCallback", "Progress", "ProgressCallback", "slabs"]

ProgressCallback = Callable[[float, str], None]
"""``progress(fraction, message)``: fraction of the whole read in 0…1, message for a status bar."""

CancelCallback = Callable[[], bool]
"""``cancel() -> bool``: return True to stop the read with :class:`ReadCancelled`."""


class Progress:
    """A sub-range ``[start, end]`` of the overall progress of one read.

    Parameters
    ----------
    callback
        The user's ``progress(fraction, message)``, or None.
    cancel
        The user's ``cancel()``, or None.
    start, end
        The part of the overall 0…1 range that this object reports into.
    """

    __slots__ = ("_callback", "_cancel", "_end", "_start")

    def __init__(
        self,
        callback: ProgressCallback | None = None,
        cancel: CancelCallback | None = None,
        start: float = 0.0,
        end: float = 1.0,
    ) -> None:
        self._callback = callback
        self._cancel = cancel
        self._start = float(start)
        self._end = float(end)

    @classmethod
    def wrap(
        cls,
        progress: Progress | ProgressCallback | None,
        cancel: CancelCallback | None = None,
    ) -> Progress:
        """Return ``progress`` if it already is a :class:`Progress`, else wrap the callbacks."""
        if isinstance(progress, Progress):
            if cancel is None:
                return progress
            return cls(progress._callback, cancel, progress._start, progress._end)
        return cls(progress, cancel)

    def __call__(self, fraction: float, message: str) -> None:
        """Report ``fraction`` (0…1 of this sub-range) and check for cancellation."""
        self.check_cancelled()
        if self._callback is not None:
            fraction = min(max(float(fraction), 0.0), 1.0)
            self._callback(self._start + fraction * (self._end - self._start), message)

    def check_cancelled(self) -> None:
        """Raise :class:`ReadCancelled` if the user's ``cancel()`` returns True."""
        if self._cancel is not None and self._cancel():
            raise ReadCancelled("reading cancelled")

    def sub(self, start: float, end: float) -> Progress:
        """A :class:`Progress` for the part ``[start, end]`` (0…1) of this one."""
        span = self._end - self._start
        return Progress(
            self._callback, self._cancel, self._start + start * span, self._start + end * span
        )


def slabs(n: int, bytes_per_item: int, target_bytes: int = 32 << 20) -> Iterator[slice]:
    """Split ``range(n)`` into slices of about ``target_bytes`` each (at least one item).

    Used to stream over z so that big (memory-mapped) volumes are processed in bounded
    memory, with a progress and cancel check per slab.
    """
    step = max(1, int(target_bytes // max(1, bytes_per_item)))
    for start in range(0, n, step):
        yield slice(start, min(n, start + step))
