"""The one place where exceptions become dialogs.

Expected problems (a file that cannot be read, a bad session, a missing data file, a refused
value) are shown as a plain message: what failed, and the reader's or the session module's
own sentence saying why. They never show a traceback. GL failures get a hint about the
graphics driver. Anything else is a bug: a short message, with the traceback under
"Show Details…" for a bug report.

Every dialog goes through :func:`run_dialog`, so tests replace that one function to record
dialogs instead of blocking on them.
"""

from __future__ import annotations

import sys
import traceback
from types import TracebackType

from PySide6.QtWidgets import QMessageBox, QWidget

from vtkvol.engine.errors import GLUnavailableError
from vtkvol.io.errors import VolumeReadError
from vtkvol.model.session import MissingDataError, SessionError

APP_NAME = "vtkvol"
#: Exception types whose message is written for the user (shown as-is, no traceback).
EXPECTED: tuple[type[BaseException], ...] = (VolumeReadError, SessionError, ValueError, OSError)
_GL_WORDS = ("opengl", "glsl", "shader", "gl context", "framebuffer")


def run_dialog(box: QMessageBox) -> int:
    """Show ``box`` modally and return the clicked standard button (tests replace this)."""
    return box.exec()


def is_gl_failure(exc: BaseException) -> bool:
    """Whether ``exc`` says the graphics stack failed (not the data or the user)."""
    if isinstance(exc, GLUnavailableError):
        return True
    text = str(exc).lower()
    return isinstance(exc, RuntimeError) and any(w in text for w in _GL_WORDS)


def message_for(exc: BaseException) -> str:
    """The user-facing sentence for an expected exception."""
    if isinstance(exc, OSError) and not isinstance(exc, VolumeReadError):
        where = f"{exc.filename}: " if exc.filename else ""
        return f"{where}{exc.strerror or exc}"
    return str(exc) or type(exc).__name__


def make_error_box(
    parent: QWidget | None, exc: BaseException, *, action: str
) -> QMessageBox:
    """Build (not show) the dialog for ``exc``; ``action`` says what failed, e.g.
    "Could not open the file"."""
    box = QMessageBox(parent)
    box.setWindowTitle(APP_NAME)
    box.setText(action)
    if is_gl_failure(exc):
        box.setIcon(QMessageBox.Icon.Critical)
        box.setInformativeText(
            f"{message_for(exc)}\n\nThe graphics driver could not do what vtkvol needs. "
            "Updating the driver, or choosing the \"Local shading\" illumination method, "
            "usually helps."
        )
    elif isinstance(exc, EXPECTED):
        box.setIcon(QMessageBox.Icon.Warning)
        box.setInformativeText(message_for(exc))
    else:
        box.setIcon(QMessageBox.Icon.Critical)
        box.setInformativeText(
            f"An unexpected error occurred ({type(exc).__name__}: {exc}). The current view "
            "is unchanged. Details are below for a bug report."
        )
        box.setDetailedText("".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    box.setStandardButtons(QMessageBox.StandardButton.Ok)
    return box


def show_error(parent: QWidget | None, exc: BaseException, *, action: str) -> None:
    """Show ``exc`` as a dialog (see the module docstring for the three kinds)."""
    run_dialog(make_error_box(parent, exc, action=action))


def show_message(parent: QWidget | None, title: str, message: str) -> None:
    """A one-line problem the app has already handled (e.g. an illumination method that
    failed and was replaced by local shading): a warning dialog."""
    box = QMessageBox(parent)
    box.setWindowTitle(APP_NAME)
    box.setIcon(QMessageBox.Icon.Warning)
    box.setText(title)
    box.setInformativeText(message)
    box.setStandardButtons(QMessageBox.StandardButton.Ok)
    run_dialog(box)


def show_warnings(parent: QWidget | None, title: str, lines: list[str]) -> None:
    """Non-fatal notes (a session repaired on load, a converted file): one dialog, listed."""
    if not lines:
        return
    box = QMessageBox(parent)
    box.setWindowTitle(APP_NAME)
    box.setIcon(QMessageBox.Icon.Information)
    box.setText(title)
    box.setInformativeText("\n".join(f"• {line}" for line in lines))
    box.setStandardButtons(QMessageBox.StandardButton.Ok)
    run_dialog(box)


def ask_locate(parent: QWidget | None, exc: MissingDataError) -> bool:
    """Offer "Locate…" for a session whose data file is missing; True if the user wants to."""
    box = QMessageBox(parent)
    box.setWindowTitle(APP_NAME)
    box.setIcon(QMessageBox.Icon.Warning)
    box.setText("The session's data file was not found")
    box.setInformativeText(f"{exc}\n\nLocate the data file to open the session.")
    locate = box.addButton("Locate…", QMessageBox.ButtonRole.AcceptRole)
    box.addButton(QMessageBox.StandardButton.Cancel)
    box.setDefaultButton(locate)
    run_dialog(box)
    return box.clickedButton() is locate


def ask_unsaved_changes(parent: QWidget | None, name: str) -> str:
    """Closing with unsaved changes: ``"save"``, ``"discard"`` or ``"cancel"``."""
    box = QMessageBox(parent)
    box.setWindowTitle(APP_NAME)
    box.setIcon(QMessageBox.Icon.Question)
    box.setText(f"Save the view of {name} before closing?" if name
                else "Save the view before closing?")
    box.setInformativeText("Settings changed since the view was opened or saved (transfer "
                           "functions, lights, crop, …). Without saving them as a session, "
                           "they are lost.")
    buttons = QMessageBox.StandardButton
    box.setStandardButtons(buttons.Save | buttons.Discard | buttons.Cancel)
    box.setDefaultButton(buttons.Save)
    answer = run_dialog(box)
    if answer == buttons.Save:
        return "save"
    if answer == buttons.Discard:
        return "discard"
    return "cancel"


class ExceptionDialogHook:
    """``sys.excepthook`` for the app: exceptions raised in Qt slots or VTK observers (which
    VTK reports through the hook) become dialogs instead of a silent console traceback.

    The same message is shown once: a failure repeated every frame does not bury the user in
    dialogs.
    """

    def __init__(self, parent: QWidget | None = None) -> None:
        self.parent = parent
        self._shown: set[str] = set()
        self._previous = sys.excepthook

    def __call__(
        self,
        exc_type: type[BaseException],
        exc: BaseException,
        tb: TracebackType | None,
    ) -> None:
        self._previous(exc_type, exc, tb)  # keep the console traceback for bug reports
        if issubclass(exc_type, KeyboardInterrupt):
            return
        key = f"{exc_type.__name__}: {exc}"
        if key in self._shown:
            return
        self._shown.add(key)
        action = "The graphics driver failed" if is_gl_failure(exc) else "Something went wrong"
        show_error(self.parent, exc, action=action)

    def install(self) -> None:
        sys.excepthook = self

    def uninstall(self) -> None:
        if sys.excepthook is self:
            sys.excepthook = self._previous
