"""Progress with Cancel for work the GUI thread does in chunks (GL work must stay on the
thread whose context is current: illumination precomputation, tiled screenshots).

:class:`ChunkProgress` is the callback such work calls between two chunks. It keeps the event
loop running (repaints, the Cancel button, other timers), shows a window-modal progress dialog
only once the work has taken longer than :data:`SHOW_AFTER_S` (quick work does not flash a
window), and answers whether to go on.
"""

from __future__ import annotations

import time

from PySide6.QtCore import QEventLoop, Qt
from PySide6.QtWidgets import QApplication, QProgressDialog, QWidget

#: Work shorter than this (s) shows no dialog.
SHOW_AFTER_S = 0.5
#: Progress bar steps.
STEPS = 1000


class ChunkProgress:
    """``progress(fraction) -> bool`` for chunked work on the GUI thread.

    Each call runs the pending events (user input to the main window is blocked by the
    window-modal dialog once it is shown) and returns False once the user pressed Cancel.
    :meth:`close` removes the dialog; use the object as a context manager to be sure.
    """

    def __init__(self, parent: QWidget | None, label: str, *, title: str = "vtkvol",
                 show_after_s: float = SHOW_AFTER_S) -> None:
        self._parent = parent
        self._label = label
        self._title = title
        self._show_after_s = show_after_s
        self._t0 = time.perf_counter()
        self.dialog: QProgressDialog | None = None
        self.cancelled = False
        self.calls = 0

    def __call__(self, fraction: float, text: str | None = None) -> bool:
        self.calls += 1
        if self.cancelled:
            return False
        if self.dialog is None and time.perf_counter() - self._t0 >= self._show_after_s:
            self._show()
        if self.dialog is not None:
            self.dialog.setValue(round(min(max(fraction, 0.0), 1.0) * STEPS))
            if text:
                self.dialog.setLabelText(f"{self._label}\n{text}")
        QApplication.processEvents(QEventLoop.ProcessEventsFlag.AllEvents)
        return not self.cancelled

    def _show(self) -> None:
        dialog = QProgressDialog(self._label, "Cancel", 0, STEPS, self._parent)
        dialog.setWindowTitle(self._title)
        dialog.setWindowModality(Qt.WindowModality.WindowModal)
        dialog.setMinimumDuration(0)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.canceled.connect(self.cancel)
        dialog.show()
        self.dialog = dialog

    def cancel(self) -> None:
        """Stop at the next chunk (the dialog's Cancel button calls this)."""
        self.cancelled = True

    @property
    def shown(self) -> bool:
        """Whether the dialog has appeared."""
        return self.dialog is not None

    def close(self) -> None:
        dialog, self.dialog = self.dialog, None
        if dialog is not None:
            dialog.canceled.disconnect(self.cancel)
            dialog.reset()
            dialog.close()
            dialog.deleteLater()

    def __enter__(self) -> ChunkProgress:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
