"""Issue 15 in the app: its bugs, framing what is visible, the voxel-size dialog, the overlays
and the background colour; each checked from the widget to the model (and the pixels where
it shows), and from the model back to the widget. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import QApplication, QScrollArea

from vtkvol.io import VolumeData
from vtkvol.model.defaults import contrast_limits
from vtkvol.model.scene import Overlays, SceneModel
from vtkvol.ui import app as app_module
from vtkvol.ui import errors
from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


def shot(window) -> np.ndarray:
    window.viewport.render_now()
    return window.viewport.screenshot().astype(np.float64)


def changed_pixels(a: np.ndarray, b: np.ndarray, threshold: float = 30.0) -> np.ndarray:
    return np.abs(a - b).max(axis=-1) > threshold


@pytest.fixture(scope="module")
def pristine() -> dict[str, Any]:
    return {}


@pytest.fixture
def window(opened_window, pristine):
    """The module's window with the small volume, reset to its opened state after each test."""
    if not pristine:
        pristine.update(opened_window.model.model_dump())
    yield opened_window
    QApplication.processEvents()
    apply_state(opened_window.model, pristine)
    opened_window.recorder.reset()
    opened_window._unsaved_data_edit = False


def handle_point(viewport) -> QPoint:
    """Widget position of the light handle."""
    renderer = viewport.renderer
    renderer.SetWorldPoint(*viewport.gizmo.handle_position(), 1.0)
    renderer.WorldToDisplay()
    x, y, _ = renderer.GetDisplayPoint()
    ratio = viewport.plotter.devicePixelRatioF()
    return QPoint(round(x / ratio), round(viewport.plotter.height() - y / ratio))


def mouse(widget, kind, pos: QPoint, button, buttons) -> None:
    event = QMouseEvent(kind, QPointF(pos), QPointF(widget.mapToGlobal(pos)), button, buttons,
                        Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(widget, event)


# -- bugs -------------------------------------------------------------------------------------
def test_save_session_as_and_screenshot_have_their_own_shortcuts(window):
    shortcuts: dict[str, list[str]] = {}
    for action in window.findChildren(app_module.QAction):
        for key in action.shortcuts():
            if not key.isEmpty():
                shortcuts.setdefault(key.toString(), []).append(action.text())
    assert {k: v for k, v in shortcuts.items() if len(v) > 1} == {}
    assert window.save_session_as_action.shortcut().toString() == "Ctrl+Shift+S"
    assert window.screenshot_actions[1].shortcut().toString() == app_module.SCREENSHOT_SHORTCUT


def test_save_session_as_shortcut_saves(window, qtbot, monkeypatch, tmp_path):
    target = tmp_path / "by-shortcut.vtkvol.json"
    monkeypatch.setattr(app_module.QFileDialog, "getSaveFileName",
                        staticmethod(lambda *a, **k: (str(target), "")))
    window.windowHandle().requestActivate()  # Xvfb has no window manager to do it
    qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=3000)
    window.viewport.plotter.setFocus()
    qtbot.keyClick(window.viewport.plotter, Qt.Key.Key_S,
                   Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier)
    qtbot.waitUntil(target.exists, timeout=5000)
    assert window.session_path == target


def test_light_handle_lets_go_when_its_release_is_lost(window, qtbot):
    """A press on the handle whose release never reaches the view (a dialog took the mouse,
    the button came up outside the window) must not leave the view moving the light, with
    no button held, instead of the camera."""
    viewport, plotter = window.viewport, window.viewport.plotter
    window.lights_dock.light_list.setCurrentRow(0)
    viewport.render_now()
    start = handle_point(viewport)
    left, none = Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton
    press, move = QMouseEvent.Type.MouseButtonPress, QMouseEvent.Type.MouseMove
    release = QMouseEvent.Type.MouseButtonRelease
    mouse(plotter, press, start, left, left)
    assert viewport.gizmo.dragging
    # No release: the pointer just moves on with no button held.
    direction = window.model.lights[0].direction
    for step in range(1, 5):
        mouse(plotter, move, start + QPoint(-10 * step, 8 * step), none, none)
    assert not viewport.gizmo.dragging
    assert window.model.lights[0].direction == pytest.approx(direction)
    # A left drag away from the handle now turns the camera, and leaves the light alone.
    camera = viewport.renderer.GetActiveCamera().GetPosition()
    far = QPoint(20, plotter.height() - 20)
    mouse(plotter, press, far, left, left)
    for step in range(1, 6):
        mouse(plotter, move, far + QPoint(12 * step, -4 * step), none, left)
    mouse(plotter, release, far + QPoint(60, -20), left, none)
    assert window.model.lights[0].direction == pytest.approx(direction)
    assert viewport.renderer.GetActiveCamera().GetPosition() != pytest.approx(camera)
    qtbot.waitUntil(lambda: not viewport.scene.interactive, timeout=3000)
