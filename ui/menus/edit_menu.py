"""The Edit menu: undo and redo (the window's undo history) and the voxel size."""

from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QKeySequence

from vtkvol.ui.menus.host import MenuHost, make_action


class EditMenu(QObject):
    """The Edit menu of one window and its actions."""

    def __init__(self, host: MenuHost) -> None:
        window = host.window()
        super().__init__(window)
        self.host = host
        stack = host.recorder.stack
        self.undo_action = stack.createUndoAction(window, "&Undo")
        self.undo_action.setShortcuts([QKeySequence.StandardKey.Undo])
        self.redo_action = stack.createRedoAction(window, "&Redo")
        self.redo_action.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")])
        self.voxel_size_action = make_action(
            window, "&Voxel size…", host.choose_voxel_size, None,
            "The distance between voxel centres along x, y and z (µm)")
        menu = self.menu = host.menuBar().addMenu("&Edit")
        menu.addAction(self.undo_action)
        menu.addAction(self.redo_action)
        menu.addSeparator()
        menu.addAction(self.voxel_size_action)

    def update_enabled(self) -> None:
        """The voxel size needs data on screen."""
        self.voxel_size_action.setEnabled(self.host.document.data is not None)
