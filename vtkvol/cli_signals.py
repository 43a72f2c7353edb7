"""SIGTERM and SIGINT in the commands that write files (:mod:`vtkvol.cli`): raised as
:class:`Terminated` so every writer removes its temporary files, deferred while VTK renders."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any


class Terminated(BaseException):
    """SIGTERM or SIGINT arrived. Raised in the main thread, so that every ``finally`` and
    ``except BaseException`` between here and the writer runs: movie writers and ``convert``
    remove their hidden temporary files and folders (the default SIGTERM action ends the
    process on the spot and leaves them behind). Not an Exception: the ``except Exception``
    of a reader or renderer must not swallow it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class _Signals:
    """SIGTERM and SIGINT of the commands that write files. Outside rendering the handler
    raises :class:`Terminated` at once. While VTK renders (:meth:`deferred`) it only records
    the signal: Python code then runs inside VTK's observer callbacks, where an exception is
    printed as a traceback and swallowed by VTK. The movie loop checks :attr:`received`
    before each frame (``write_movie``'s ``cancel``), a still image before it is written."""

    def __init__(self) -> None:
        self.received: int | None = None
        self.defer = False

    def handler(self, signum: int, frame: Any) -> None:
        self.received = signum
        if not self.defer:
            raise Terminated(signum)

    @contextlib.contextmanager
    def deferred(self) -> Iterator[None]:
        self.defer = True
        try:
            yield
        finally:
            self.defer = False
        self.check()

    def check(self) -> None:
        """Raise :class:`Terminated` if a signal was recorded."""
        if self.received is not None:
            raise Terminated(self.received)


_signals = _Signals()
