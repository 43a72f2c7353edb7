"""Work off the GUI thread: a job run in a ``QThread`` that reports back by queued signals.

:class:`Worker` runs ``job(progress=, cancel=)`` once; :class:`~vtkvol.ui.app.BackgroundTask`
adds a progress dialog for opening files, and the time slider
(:mod:`vtkvol.ui.time_series`) reads time points with it, without a dialog.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, Signal


class Worker(QObject):
    """Runs ``job(progress=, cancel=)`` in a worker thread and reports back by signals.

    ``cancel()`` is thread-safe: it sets an event that ``cancel=`` returns, which readers poll
    at every slice or chunk (they then raise ``ReadCancelled``).
    """

    progressed = Signal(float, str)
    succeeded = Signal(object)
    failed = Signal(object)

    def __init__(self, job: Callable[..., Any]) -> None:
        super().__init__()
        self._job = job
        self._cancel = threading.Event()

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def run(self) -> None:
        try:
            result = self._job(progress=self._progress, cancel=self._cancel.is_set)
        except BaseException as exc:  # reported to the GUI thread, which decides what to show
            self.failed.emit(exc)
        else:
            self.succeeded.emit(result)

    def _progress(self, fraction: float, message: str) -> None:
        self.progressed.emit(float(fraction), str(message))
