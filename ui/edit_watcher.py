"""Dock edits as interactions of the 3-D view: :class:`DockEditWatcher`."""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject
from PySide6.QtWidgets import QWidget

from vtkvol.ui.docks.base import ModelDock
from vtkvol.ui.viewport import Viewport


class DockEditWatcher(QObject):
    """Tells the 3-D view when the user drags something in a dock.

    A mouse press inside a dock (a curve in an editor, a range slider, a parameter slider, a
    spin box's held arrow) starts an edit, the release ends it
    (:meth:`Viewport.begin_edit` / :meth:`Viewport.end_edit`); a wheel step over a dock is a
    short edit of its own. The view renders at the interactive quality meanwhile and at full
    quality once the edit settles, as for camera moves. An application-wide event filter: it
    sees widgets the docks create later (the technique parameters) and releases that land
    elsewhere (a popup, outside the window)."""

    def __init__(self, docks: list[ModelDock], viewport: Viewport,
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._docks = docks
        self._viewport = viewport
        self._pressed = False

    def _in_dock(self, obj: QObject) -> bool:
        widget = obj if isinstance(obj, QWidget) else None
        while widget is not None:
            if widget in self._docks:
                return True
            widget = widget.parentWidget()
        return False

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        kind = event.type()
        if kind == QEvent.Type.MouseButtonPress and not self._pressed:
            if self._in_dock(watched):
                self._pressed = True
                self._viewport.begin_edit()
        elif kind == QEvent.Type.MouseButtonRelease and self._pressed:
            self._pressed = False
            self._viewport.end_edit()
        elif kind == QEvent.Type.Wheel and not self._pressed and self._in_dock(watched):
            self._viewport.begin_edit()
            self._viewport.end_edit()
        return False

    def release(self) -> None:
        if self._pressed:
            self._pressed = False
            self._viewport.end_edit()
