"""Work off the GUI thread: a job run in a ``QThread`` that reports back by queued signals.

:class:`Worker` runs ``job(progress=, cancel=)`` once; :class:`BackgroundTask` adds a
progress dialog with Cancel (the window's reads: files, sessions, pyramid levels), and the
time slider (:mod:`vtkvol.ui.time_series`) reads time points with a plain Worker.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, Qt, QThread, Signal
from PySide6.QtWidgets import QProgressDialog, QWidget

from vtkvol.ui import APP_NAME

#: Progress dialogs appear only for reads longer than this (ms): quick opens do not flash.
PROGRESS_DELAY_MS = 400


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


class BackgroundTask(QObject):
    """A read in a ``QThread`` with a ``QProgressDialog``; Cancel makes ``cancel()`` True, so
    the reader raises ``ReadCancelled`` at its next progress call."""

    finished = Signal()

    def __init__(self, parent: QWidget, label: str, job: Callable[..., Any],
                 on_success: Callable[[Any], None], on_failure: Callable[[BaseException], None]):
        super().__init__(parent)
        self._on_success, self._on_failure = on_success, on_failure
        self.dialog = QProgressDialog(label, "Cancel", 0, 1000, parent)
        self.dialog.setWindowTitle(APP_NAME)
        self.dialog.setWindowModality(Qt.WindowModality.WindowModal)
        self.dialog.setMinimumDuration(PROGRESS_DELAY_MS)
        self.dialog.setAutoClose(False)
        self.dialog.setAutoReset(False)
        self.dialog.setValue(0)
        self.thread = QThread(self)
        self.worker = Worker(job)
        self.worker.moveToThread(self.thread)
        self.thread.started.connect(self.worker.run)
        self.worker.progressed.connect(self._on_progress)
        self.worker.succeeded.connect(self._on_succeeded)
        self.worker.failed.connect(self._on_failed)
        # Through this object (GUI thread), not to the worker directly: a queued call into the
        # worker's thread would wait for the read to finish, which is what Cancel must stop.
        self.dialog.canceled.connect(self.cancel)
        self._label = label
        self._done = False

    def start(self) -> None:
        self.thread.start()

    def cancel(self) -> None:
        """Ask the read to stop (thread-safe: sets an event the reader polls)."""
        self.worker.cancel()

    def _on_progress(self, fraction: float, message: str) -> None:
        if self._done:
            return
        self.dialog.setValue(int(fraction * 1000))
        if message:
            self.dialog.setLabelText(f"{self._label}\n{message}")

    def _finish(self) -> None:
        self._done = True
        self.thread.quit()
        self.thread.wait()

    def _close_dialog(self) -> None:
        # reset() also stops the dialog's show-after-minimumDuration timer.
        self.dialog.reset()
        self.dialog.close()
        self.dialog.deleteLater()

    # ``finished`` goes out before the callback: the window forgets this task first, so a
    # callback may start the next one (the retry after "Locate…").
    def _on_succeeded(self, result: Any) -> None:
        self._finish()
        if self.dialog.isVisible():
            # The new view is built on this thread next (seconds for a large stack: its
            # statistics, textures, first frame). A dialog closed now stays on screen until
            # the event loop runs again, unpainted: a blank window. So it says what is
            # happening, painted at once, and closes when the view is there.
            self.dialog.setCancelButton(None)  # nothing to cancel on this thread
            self.dialog.setValue(self.dialog.maximum())
            self.dialog.setLabelText(f"{self._label}\nPreparing the view…")
            self.dialog.repaint()
        self.finished.emit()
        try:
            self._on_success(result)
        finally:
            self._close_dialog()

    def _on_failed(self, exc: BaseException) -> None:
        self._finish()
        self._close_dialog()
        self.finished.emit()
        self._on_failure(exc)
