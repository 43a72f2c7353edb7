"""What the menus need of the app window: a :class:`typing.Protocol`, so the menu modules do
not import :mod:`vtkvol.ui.app` (which imports them: that would be an import circle)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from PySide6.QtCore import QSettings
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QMenuBar, QStatusBar, QWidget

from vtkvol.model.document import Document
from vtkvol.model.scene import SceneModel
from vtkvol.ui.docks.base import ModelDock
from vtkvol.ui.undo import UndoRecorder
from vtkvol.ui.view_actions import ViewActions
from vtkvol.ui.viewport import Viewport


class MenuHost(Protocol):
    """The app window as its menus see it (:class:`vtkvol.ui.app.MainWindow`)."""

    document: Document
    model: SceneModel
    settings: QSettings
    viewport: Viewport
    recorder: UndoRecorder
    view_actions: ViewActions
    docks: list[ModelDock]
    #: The time series' actions (made with the window's time bar).
    time_actions: list[QAction]

    # QWidget's: the window itself (the parent of the menus' actions and dialogs).
    def window(self) -> QWidget: ...

    def menuBar(self) -> QMenuBar: ...

    def statusBar(self) -> QStatusBar: ...

    def open_path(self, path: str | os.PathLike[str]) -> None: ...

    def open_session(self, path: str | os.PathLike[str]) -> None: ...

    def open_sample(self) -> None: ...

    def save_session(self, path: str | os.PathLike[str]) -> Path | None: ...

    def save_screenshot(self, path: str | os.PathLike[str], *, scale: int = 1) -> Path | None: ...

    def show_movie_dialog(self) -> object: ...

    def request_quit(self) -> None: ...

    def choose_voxel_size(self) -> None: ...

    def refine_selection(self) -> None: ...

    def back_to_overview(self) -> None: ...

    def gpu_budget(self) -> int: ...

    def set_gpu_budget(self, nbytes: int) -> None: ...


def make_action(parent: QWidget, text: str, slot: Callable[..., Any],
                shortcut: QKeySequence | QKeySequence.StandardKey | str | None = None,
                tip: str = "") -> QAction:
    """A menu action owned by ``parent`` that calls ``slot()`` (no arguments) when
    triggered; ``tip`` is its status and tool tip."""
    action = QAction(text, parent)
    if shortcut is not None:
        action.setShortcut(shortcut)
    if tip:
        action.setStatusTip(tip)
        action.setToolTip(tip)
    action.triggered.connect(lambda *_: slot())
    return action
