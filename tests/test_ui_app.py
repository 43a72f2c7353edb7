"""The main window: open (file, error, cancel, drop, recent), screenshots, reduced quality
while the camera moves, undo/redo shortcuts, menus. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import shutil
import time

import numpy as np
import pytest
from PySide6.QtCore import QMimeData, QPoint, QPointF, Qt, QUrl
from PySide6.QtGui import QDropEvent, QImage
from PySide6.QtWidgets import QApplication, QMenu, QPushButton

from vtkvol.io import ReadCancelled
from vtkvol.ui import app as app_module
from vtkvol.ui.viewport import SETTLE_MS

pytestmark = pytest.mark.gui


def open_and_wait(window, qtbot, path, timeout=30_000):
    with qtbot.waitSignal(window.dataShown, timeout=timeout):
        window.open_path(path)


def background(window) -> np.ndarray:
    return np.array(window.model.render.background) * 255.0


def foreground_fraction(image: np.ndarray, window) -> float:
    """Share of pixels that are clearly not the background colour."""
    return float((np.abs(image.astype(float) - background(window)).max(axis=-1) > 12).mean())


def test_open_file_shows_the_volume(main_window, qtbot, small_volume_file):
    open_and_wait(main_window, qtbot, small_volume_file)
    window = main_window
    assert window.data.shape_zyx == (24, 48, 48)
    assert "nuclei.npy" in window.data_label.text()
    assert "48×48×24" in window.data_label.text() and "µm" in window.data_label.text()
    assert window.windowTitle().startswith("nuclei.npy")
    image = window.viewport.screenshot()
    assert image.shape[:2] == (256, 256)
    assert image.std() > 5.0
    assert 0.03 < foreground_fraction(image, window) < 0.9
    qtbot.waitUntil(lambda: "frame" in window.frame_label.text(), timeout=5000)


def test_open_error_keeps_the_scene_and_says_why(opened_window, qtbot, tmp_path, dialogs):
    window = opened_window
    data, tf = window.data, window.model.channels[0].tf.copy_state()
    before = window.viewport.screenshot()
    bad = tmp_path / "broken.tif"
    bad.write_bytes(b"II*\x00 this is not a TIFF")
    with qtbot.waitSignal(window.openFailed, timeout=20_000):
        window.open_path(bad)
    assert len(dialogs) == 1
    assert dialogs[0].text() == "Could not open broken.tif"
    assert "broken.tif" in dialogs[0].informativeText()
    assert dialogs[0].detailedText() == ""  # an expected error: no traceback
    assert window.data is data and window.model.channels[0].tf.copy_state() == tf
    after = window.viewport.screenshot()
    assert np.abs(after.astype(float) - before).mean() < 1.0


def test_cancel_keeps_the_scene(opened_window, qtbot, monkeypatch, tmp_path, dialogs):
    window = opened_window
    data = window.data
    started = []

    def slow_read(path, *, voxel_size_um=None, time_index=0, progress=None, cancel=None,
                  **budget):
        for i in range(2000):
            progress(i / 2000, f"slice {i}")
            started.append(i)
            if cancel():
                raise ReadCancelled("reading cancelled")
            time.sleep(0.005)
        raise AssertionError("the read was not cancelled")

    monkeypatch.setattr(app_module, "read_volume", slow_read)
    target = tmp_path / "slow.npy"
    target.write_bytes(b"")
    with qtbot.waitSignal(window.openFailed, timeout=20_000) as blocker:
        window.open_path(target)
        qtbot.waitUntil(lambda: len(started) > 3, timeout=5000)
        window._task.dialog.findChild(QPushButton).click()  # the dialog's Cancel button
    assert blocker.args == ["cancelled"]
    assert window.data is data
    assert dialogs == []
    assert "cancelled" in window.statusBar().currentMessage()


def test_drop_opens_the_file(opened_window, qtbot, tmp_path, small_volume_file):
    window = opened_window
    copy = tmp_path / "dropped.npy"
    shutil.copy(small_volume_file, copy)
    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(copy))])
    event = QDropEvent(QPointF(50, 50), Qt.DropAction.CopyAction, mime,
                       Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier)
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.dropEvent(event)
    assert event.isAccepted()
    assert window.data.source == str(copy)


def test_open_recent_lists_files_and_drops_vanished_ones(opened_window, qtbot, tmp_path,
                                                         small_volume_file):
    window = opened_window
    gone = tmp_path / "soon-gone.npy"
    shutil.copy(small_volume_file, gone)
    open_and_wait(window, qtbot, gone)
    open_and_wait(window, qtbot, small_volume_file)
    recent = window.recent_files()
    assert recent[:2] == [str(small_volume_file), str(gone)]
    titles = [a.text() for a in window.recent_menu.actions()]
    assert any("soon-gone.npy" in t for t in titles)
    gone.unlink()
    window._refresh_recent()
    assert str(gone) not in window.recent_files()
    assert "soon-gone.npy" in window.statusBar().currentMessage()
    action = next(a for a in window.recent_menu.actions() if "nuclei.npy" in a.text())
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        action.trigger()


def test_save_screenshot_writes_a_scaled_png(opened_window, tmp_path):
    window = opened_window
    target = tmp_path / "shot.png"
    assert window.save_screenshot(target, scale=2) == target
    image = QImage(str(target))
    assert (image.width(), image.height()) == (512, 512)
    pixels = np.array([[image.pixelColor(x, y).value() for x in range(0, 512, 8)]
                       for y in range(0, 512, 8)], dtype=float)
    assert pixels.std() > 5.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.png"]  # nothing half-written


def test_camera_drag_renders_reduced_then_full_quality(opened_window, qtbot, monkeypatch):
    window = opened_window
    scene = window.viewport.scene
    calls = []
    original = scene.set_interactive

    def spy(flag):
        calls.append(flag)
        original(flag)

    monkeypatch.setattr(scene, "set_interactive", spy)
    camera_before = window.model.camera.position
    plotter = window.viewport.plotter
    centre = QPoint(plotter.width() // 2, plotter.height() // 2)
    qtbot.mousePress(plotter, Qt.MouseButton.LeftButton, pos=centre)
    for dx in range(5, 60, 5):
        qtbot.mouseMove(plotter, centre + QPoint(dx, dx // 3))
    assert calls == [True] and scene.interactive
    qtbot.mouseRelease(plotter, Qt.MouseButton.LeftButton, pos=centre + QPoint(60, 20))
    qtbot.waitUntil(lambda: not scene.interactive, timeout=SETTLE_MS + 3000)
    assert calls == [True, False]
    assert window.model.camera.position != camera_before  # the model follows the camera


def test_undo_and_redo_shortcuts(opened_window, qtbot):
    window = opened_window
    checkbox = window.channels_dock.rows[0].visible
    window.recorder.reset()
    window.windowHandle().requestActivate()  # Xvfb has no window manager to do it
    qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=3000)
    qtbot.mouseClick(checkbox, Qt.MouseButton.LeftButton, pos=QPoint(8, checkbox.height() // 2))
    assert window.model.channels[0].visible is False
    assert window.undo_action.text() == "&Undo Toggle channel visibility"
    qtbot.keyClick(checkbox, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    assert window.model.channels[0].visible is True and checkbox.isChecked()
    qtbot.keyClick(checkbox, Qt.Key.Key_Z,
                   Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier)
    assert window.model.channels[0].visible is False
    checkbox.click()


def test_every_menu_entry_does_something(opened_window):
    window = opened_window
    window._update_file_actions()

    def walk(menu: QMenu):
        for action in menu.actions():
            if action.isSeparator():
                continue
            if action.menu() is not None:
                yield from walk(action.menu())
            else:
                yield action

    actions = [a for m in window.menuBar().findChildren(QMenu) if m.parent() is window.menuBar()
               for a in walk(m)]
    assert len(actions) >= 15
    for action in actions:
        assert action.receivers("2triggered(bool)") > 0 or action.receivers(
            "2toggled(bool)") > 0, action.text()


def test_a_failing_illumination_method_is_reported_and_the_dock_shows_local(
        opened_window, qtbot, dialogs, monkeypatch):
    from tests_support_techniques import BROKEN_SPEC

    from vtkvol.model.techniques import register
    from vtkvol.ui import undo

    window = opened_window
    window.model.illumination.method = "shadow_volume"
    window.recorder.reset()
    monkeypatch.setattr(undo, "MERGE_WINDOW_S", 0.0)  # the fallback must not merge by timing
    with register(BROKEN_SPEC):
        window.model.illumination.method = BROKEN_SPEC.name
        qtbot.waitUntil(lambda: window.model.illumination.method == "local", timeout=20_000)
        qtbot.waitUntil(lambda: len(dialogs) == 1, timeout=5_000)
    assert "could not be compiled" in dialogs[0].informativeText()
    assert "could not be compiled" in window.statusBar().currentMessage()
    dock = window.lights_dock
    assert dock.method.itemData(dock.method.currentIndex()) == "local"
    # The fallback amended the user's choice: one step, and undo returns to the method shown
    # before it (never to the broken one, which would fail again); redo to local shading.
    stack = window.recorder.stack
    assert stack.count() == 1
    stack.undo()
    assert window.model.illumination.method == "shadow_volume"
    stack.redo()
    assert window.model.illumination.method == "local" and len(dialogs) == 1
    # The app goes on: the next edit renders a frame (locally shaded) and reports nothing new.
    background = window.model.render.background
    with qtbot.waitSignal(window.viewport.frameRendered, timeout=10_000):
        window.model.render.background = (0.1, 0.2, 0.3)
    window.model.render.background = background  # the window is shared by the module
    assert window.isVisible() and len(dialogs) == 1
    window.model.illumination.method = "local"
    window.recorder.reset()


def test_refinement_progress_shows_in_the_status_bar(opened_window, qtbot):
    from tests_support_techniques import REFINING_SPEC

    from vtkvol.model.techniques import register

    window = opened_window
    seen: list[str] = []
    window.viewport.illuminationProgress.connect(
        lambda *_: seen.append(window.refine_label.text()))
    with register(REFINING_SPEC):
        window.model.illumination.method = REFINING_SPEC.name
        qtbot.waitUntil(lambda: len(seen) >= 5 and window.refine_label.text() == "",
                        timeout=30_000)
        window.model.illumination.method = "local"
    assert any(text.startswith("Refining lighting — iteration") for text in seen)


def test_missing_voxel_size_shows_a_badge_until_set(main_window, qtbot, small_volume_file,
                                                      monkeypatch):
    """A .npy stores no voxel size: a badge in the status bar says so (issue 25: the note in
    the truncated data label was missed) and opens the voxel-size dialog; it goes once a size
    is chosen, even the assumed 1 × 1 × 1 µm, and comes back for the next such file; data with
    a voxel size (the sample) shows none."""
    window = main_window
    open_and_wait(window, qtbot, small_volume_file)
    badge = window.voxel_badge
    assert not badge.isHidden() and "Voxel size unknown" in badge.text()
    asked = []

    def ask(parent, current, file_size, from_file):
        asked.append(tuple(current))
        return (0.5, 0.5, 2.0)

    monkeypatch.setattr(app_module, "ask_voxel_size", ask)
    badge.click()
    assert asked == [(1.0, 1.0, 1.0)]
    assert tuple(window.data.voxel_size_um) == (0.5, 0.5, 2.0)
    assert badge.isHidden()

    open_and_wait(window, qtbot, small_volume_file)
    assert not badge.isHidden()
    window.set_voxel_size((1.0, 1.0, 1.0))  # the assumed size, confirmed
    assert badge.isHidden()

    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_sample()
    assert badge.isHidden()
