"""The Help menu: the mouse and keyboard controls and About."""

from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QMessageBox

from vtkvol.ui import APP_NAME
from vtkvol.ui.menus.file_menu import SCREENSHOT_SHORTCUT
from vtkvol.ui.menus.host import MenuHost, make_action


class HelpMenu(QObject):
    """The Help menu of one window and its actions."""

    def __init__(self, host: MenuHost) -> None:
        window = host.window()
        super().__init__(window)
        self.host = host
        self.about_action = make_action(window, "&About vtkvol", self.show_about)
        self.controls_action = make_action(window, "&Mouse and keyboard", self.show_controls,
                                           QKeySequence.StandardKey.HelpContents)
        menu = self.menu = host.menuBar().addMenu("&Help")
        menu.addAction(self.controls_action)
        menu.addAction(self.about_action)

    def show_about(self) -> None:
        from vtkvol import __version__

        QMessageBox.about(self.host.window(), f"About {APP_NAME}",
                          f"<b>{APP_NAME} {__version__}</b><br>Volume rendering of microscopy "
                          "data with real illumination, inside VTK's GPU ray caster.")

    def show_controls(self) -> None:
        QMessageBox.information(
            self.host.window(), "Mouse and keyboard",
            "<b>3-D view</b><br>Left drag: rotate · Shift+left or middle drag: pan · "
            "Right drag or wheel: zoom · Ctrl+left drag: spin<br>Drag the light's handle to "
            "move the light selected in the Lights dock.<br><br><b>Slice views</b><br>"
            "Click or drag: move the cursor · wheel or PageUp/PageDown: next slice<br><br>"
            "<b>Function editors</b><br>"
            "Points mode: click to add a node, drag to move, right-click or Delete to remove."
            "<br>Curve mode: press and drag to draw.<br>Double-click the colour bar to set a "
            "colour.<br><br><b>Keys</b><br>Ctrl+Z / Ctrl+Shift+Z: undo / redo · Ctrl+R: reset "
            "view · Ctrl+O: open · Ctrl+S: save session · Ctrl+Shift+S: save session as · "
            f"{SCREENSHOT_SHORTCUT}: screenshot<br><br><b>Time series</b><br>, / .: previous / "
            "next time point · P: play or pause")
