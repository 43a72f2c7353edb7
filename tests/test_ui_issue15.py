"""Issue 15 in the app: its bugs, framing what is visible, the voxel-size dialog, the overlays
and the background colour; each checked from the widget to the model (and the pixels where
it shows), and from the model back to the widget. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QAction, QCloseEvent, QMouseEvent
from PySide6.QtWidgets import QApplication, QProgressDialog, QScrollArea

from vtkvol.model.defaults import contrast_limits
from vtkvol.model.scene import Overlays, SceneModel
from vtkvol.ui import app as app_module
from vtkvol.ui import background, errors
from vtkvol.ui.menus import file_menu
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
    opened_window.document.unsaved_data_edit = False


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
    for action in window.findChildren(QAction):
        for key in action.shortcuts():
            if not key.isEmpty():
                shortcuts.setdefault(key.toString(), []).append(action.text())
    assert {k: v for k, v in shortcuts.items() if len(v) > 1} == {}
    assert window.save_session_as_action.shortcut().toString() == "Ctrl+Shift+S"
    assert window.screenshot_actions[1].shortcut().toString() == file_menu.SCREENSHOT_SHORTCUT


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


def test_progress_window_is_painted_while_the_view_is_built(main_window, qtbot):
    """After a long read the new view is built on the main thread. The progress window used
    to be closed first and then stayed on screen unpainted (blank) until that was done."""
    import time

    import shiboken6

    seen: list[tuple[bool, str, float]] = []

    def job(progress, cancel):
        for i in range(8):
            progress(i / 8, f"slice {i}")
            time.sleep(0.1)
        return "data"

    def on_success(result):
        # What the user sees while the main thread is busy building the view.
        dialog = task.dialog
        image = dialog.grab().toImage()
        pixels = np.array([image.pixelColor(x, y).lightness()
                           for x in range(0, image.width(), 3)
                           for y in range(0, image.height(), 3)])
        seen.append((dialog.isVisible(), dialog.labelText(), float(pixels.std())))

    task = app_module.BackgroundTask(main_window, "Reading big.tif…", job, on_success,
                                     lambda exc: None)
    dialog = task.dialog
    done: list[bool] = []
    task.finished.connect(lambda: done.append(True))
    task.start()
    qtbot.waitUntil(lambda: bool(seen), timeout=10_000)
    visible, label, contrast = seen[0]
    assert visible and label.endswith("Preparing the view…")
    assert contrast > 5.0  # text and a bar, not an empty window
    qtbot.waitUntil(lambda: not shiboken6.isValid(dialog) or not dialog.isVisible(),
                    timeout=2000)  # closed once the view is there
    assert done == [True]


def test_no_progress_window_after_a_quick_read(main_window, qtbot, small_volume_file):
    window = main_window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(small_volume_file)
    qtbot.wait(background.PROGRESS_DELAY_MS + 300)
    shown = [d for d in window.findChildren(QProgressDialog) if d.isVisible()]
    assert shown == []


def test_lights_dock_fits_point_lights_and_shows_parameters_in_its_body(window, qtbot):
    dock = window.lights_dock
    scroll = dock.widget()
    body = scroll.widget()
    # The parameters are part of the dock's body: no scroll area inside the scrolling dock.
    assert body.findChildren(QScrollArea) == []
    window.model.lights[0].kind = "point"
    QApplication.processEvents()
    assert all(b.isVisibleTo(dock) for b in dock.position_boxes)
    # The default layout's dock width holds a point light without scrolling sideways.
    assert body.minimumSizeHint().width() <= scroll.viewport().width()
    assert not scroll.horizontalScrollBar().isVisible()


def test_point_light_is_placed_by_the_data(window, qtbot):
    dock, viewport = window.lights_dock, window.viewport
    light = window.model.lights[0]
    light.direction = (0.0, 0.0, 1.0)
    dock.kind.setCurrentIndex(dock.kind.findData("point"))  # widget → model
    assert light.kind == "point"
    z, y, x = window.data.shape_zyx
    sx, sy, sz = window.data.voxel_size_um
    extent = np.array([(x - 1) * sx, (y - 1) * sy, (z - 1) * sz])
    # Straight above the data's centre, just outside it: not at (0, 0, 1000 µm).
    assert light.position[:2] == pytest.approx(tuple(extent[:2] / 2))
    assert light.position[2] == pytest.approx(extent[2] / 2 + 0.525 * np.linalg.norm(extent))
    # From the default direction, its handle is inside the view that Reset view frames.
    dock.kind.setCurrentIndex(dock.kind.findData("directional"))
    light.direction = type(light)().direction
    dock.kind.setCurrentIndex(dock.kind.findData("point"))
    window.reset_camera_action.trigger()
    viewport.render_now()
    assert viewport.plotter.rect().contains(handle_point(viewport))
    # model → widgets
    light.position = (1.0, 2.0, 3.0)
    assert [b.value() for b in dock.position_boxes] == [1.0, 2.0, 3.0]


def test_choice_parameters_show_their_declared_labels(qapp):
    from vtkvol.model.techniques import technique_specs
    from vtkvol.ui.docks.lights import LightsDock

    model = SceneModel()
    model.illumination.method = "cone_traced"
    dock = LightsDock(model, techniques=technique_specs())
    try:
        combo = dock.param_widget("ao_mode")
        shown = [combo.itemText(i) for i in range(combo.count())]
        assert shown == ["Off", "View cone", "Hemisphere (per sample)", "Hemisphere (baked)"]
        assert not any("_" in text for text in shown)
        combo.setCurrentIndex(shown.index("View cone"))  # widget → model: the identifier
        assert model.illumination.values_for()["ao_mode"] == "view_cone"
        model.illumination.set_value("ao_mode", "hemisphere")  # model → widget: the label
        assert combo.currentText() == "Hemisphere (per sample)"
        assert "Hemisphere (baked)" in combo.toolTip()
    finally:
        dock.release()
        dock.deleteLater()


def test_auto_contrast_is_the_opening_contrast(window):
    row = window.channels_dock.rows[0]
    tf = window.model.channels[0].tf
    opened = tf.value_span
    assert opened == pytest.approx(contrast_limits(window.data, 0))
    row.maximum.setValue(opened[1] * 0.5)  # widget → model
    assert tf.value_span[1] == pytest.approx(opened[1] * 0.5, abs=1.0)
    row.auto.click()
    assert tf.value_span == pytest.approx(opened)
    assert row.minimum.value() == pytest.approx(opened[0], abs=1.0)  # model → widget
    assert row.maximum.value() == pytest.approx(opened[1], abs=1.0)


def test_drawing_a_curve_keeps_the_contrast(window, qtbot):
    dock = window.tf_dock
    tf = window.model.channels[0].tf
    lo, hi = tf.value_span
    window_lo, window_hi = tf.window
    assert window_lo < lo and hi < window_hi  # the editor shows more than the TF spans
    dock.mode_curve.setChecked(True)
    editor = dock.editor
    rect = editor.plot_rect()

    def at(value: float, alpha: float) -> QPoint:
        t = (value - window_lo) / (window_hi - window_lo)
        return QPoint(round(rect.left() + t * rect.width()),
                      round(rect.bottom() - alpha * rect.height()))

    a, b = lo + 0.3 * (hi - lo), lo + 0.6 * (hi - lo)
    qtbot.mousePress(editor, Qt.MouseButton.LeftButton, pos=at(a, 0.2))
    for k in range(1, 11):
        qtbot.mouseMove(editor, at(a + k / 10 * (b - a), 0.2 + 0.02 * k))
    qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, pos=at(b, 0.4))
    qtbot.waitUntil(lambda: tf.opacity_at(np.array([0.5 * (a + b)]))[0] > 0.25, timeout=3000)
    assert tf.value_span == pytest.approx((lo, hi))  # the contrast limits did not move
    row = window.channels_dock.rows[0]
    assert (row.minimum.value(), row.maximum.value()) == pytest.approx((lo, hi), abs=1.0)
    assert tf.opacity_at(np.array([hi]))[0] == pytest.approx(0.6)  # outside the stroke: kept
    dock.mode_curve.setChecked(False)


def test_slice_weight_axis_and_ranges_agree(window):
    slices, ranges = window.slice_dock, window.ranges_dock
    for name in "xyz":
        slices.editor.set_active(name)
        lo_box, hi_box = ranges.lo_boxes[name], ranges.hi_boxes[name]
        assert slices._format_position(1.0) == hi_box.text()
        assert slices._format_position(0.0) == lo_box.text()
    x = window.data.shape_zyx[2]
    slices.editor.set_active("x")
    assert slices._format_position(1.0) == f"{(x - 1) * window.data.voxel_size_um[0]:.2f} µm"


def test_closing_with_unsaved_changes_asks(window, monkeypatch, tmp_path):
    asked: list[str] = []
    closed: list[bool] = []
    answer = {"value": "cancel"}

    def ask(parent, name):
        asked.append(name)
        return answer["value"]

    monkeypatch.setattr(errors, "ask_unsaved_changes", ask)
    monkeypatch.setattr(window, "close", lambda: closed.append(True))
    window.recorder.reset()
    assert not window.has_unsaved_changes()
    window.quit_action.trigger()  # nothing to lose: no question
    assert asked == [] and closed == [True]
    window.model.lights[0].intensity = 2.0  # an edit
    assert window.has_unsaved_changes()
    window.quit_action.trigger()
    assert asked == ["nuclei.npy"] and closed == [True]  # cancelled: still open

    class ClosedByUser(QCloseEvent):  # the title bar's close button: a spontaneous event
        def spontaneous(self) -> bool:
            return True

    event = ClosedByUser()
    window.closeEvent(event)
    assert len(asked) == 2 and not event.isAccepted()  # asked again, and stays open
    assert window.viewport.scene is not None
    answer["value"] = "discard"
    window.quit_action.trigger()
    assert closed == [True, True]
    answer["value"] = "save"
    target = tmp_path / "before-quit.vtkvol.json"
    monkeypatch.setattr(app_module.QFileDialog, "getSaveFileName",
                        staticmethod(lambda *a, **k: (str(target), "")))
    window.session_path = None
    window.quit_action.trigger()
    assert target.exists() and closed == [True, True, True]
    assert not window.has_unsaved_changes()  # saving made the history clean


# -- framing ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def corner_object_file(tmp_path_factory):
    """A 48³ box, empty but for a bright 8³ cube in one corner (and faint noise)."""
    rng = np.random.default_rng(3)
    arr = rng.integers(0, 12, (48, 48, 48)).astype(np.uint16)
    arr[4:12, 36:44, 36:44] = 2000
    path = tmp_path_factory.mktemp("framing") / "corner.npy"
    np.save(path, arr)
    return path


def foreground_box(image: np.ndarray, background: np.ndarray) -> tuple[int, int]:
    """Width and height (px) of the pixels that differ from the background."""
    mask = np.abs(image - background).max(axis=-1) > 20
    rows, cols = np.nonzero(mask)
    return int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1)


def test_first_view_and_reset_view_frame_the_visible_content(main_window, qtbot,
                                                             corner_object_file):
    window = main_window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(corner_object_file)
    background = np.array(window.model.render.background) * 255
    scene = window.viewport.scene
    # The camera looks at the cube's centre, not the box's.
    cube_centre = np.array([39.5, 39.5, 7.5])  # voxel centres (x, y, z), 1 µm voxels
    assert np.array(window.model.camera.focal_point) == pytest.approx(cube_centre, abs=1.5)
    width, height = foreground_box(shot(window), background)
    assert max(width, height) > 0.55 * 256  # the 8³ cube in a 48³ box fills the view
    # Box framing (what the first view was) shows the cube several times smaller.
    scene.framing = "box"
    window.viewport.reset_camera()
    box_width, _ = foreground_box(shot(window), background)
    assert box_width < 0.5 * width
    scene.framing = "visible"
    # Reset view (Ctrl+R) after an orbit and zoom frames the cube again.
    scene.orbit(60.0, 10.0)
    window.viewport.renderer.GetActiveCamera().Zoom(0.3)
    window.reset_camera_action.trigger()
    assert np.array(window.model.camera.focal_point) == pytest.approx(cube_centre, abs=1.5)
    again, _ = foreground_box(shot(window), background)
    assert again == pytest.approx(width, abs=3)
    # What is visible follows the TF: an opacity that also shows the noise frames the box.
    window.model.channels[0].tf.opacity = [(0.0, 0.0), (1.0, 0.02), (2000.0, 0.6)]
    window.reset_camera_action.trigger()
    assert np.array(window.model.camera.focal_point) == pytest.approx((23.5,) * 3, abs=1.5)


# -- voxel size -------------------------------------------------------------------------------
def test_voxel_size_dialog_applies_to_view_and_model(window, qtbot, monkeypatch):
    data = window.data
    assert data.voxel_size_um == (1.0, 1.0, 1.0)  # .npy files store none
    # The note's advice is for users: the menu entry, not an API argument.
    assert "Edit → Voxel size…" in window.data_label.toolTip()
    assert "voxel_size_um" not in window.data_label.toolTip()
    before = shot(window)
    background = np.array(window.model.render.background) * 255
    asked: list[tuple[Any, ...]] = []

    def ask(parent, current, file_size, from_file):
        asked.append((tuple(current), tuple(file_size), from_file))
        return (1.0, 1.0, 3.0)

    monkeypatch.setattr(app_module, "ask_voxel_size", ask)
    window.voxel_size_action.trigger()  # widget → model and view
    assert asked == [((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), False)]
    assert window.model.volume.voxel_size_um == (1.0, 1.0, 3.0)
    assert window.data.voxel_size_um == (1.0, 1.0, 3.0)
    z = window.data.shape_zyx[0]
    assert window.viewport.scene.bounds[5] == pytest.approx((z - 1) * 3.0)
    assert window.ranges_dock.full_range("z") == (0.0, pytest.approx((z - 1) * 3.0))
    assert "voxel 1×1×3 µm" in window.data_label.text()
    assert "set in the app" in window.data_label.toolTip()
    assert "using 1 × 1 × 1 µm" not in window.data_label.toolTip()  # that note is moot now
    assert window.has_unsaved_changes()
    after = shot(window)
    (w0, h0), (w1, h1) = foreground_box(before, background), foreground_box(after, background)
    assert h1 / w1 > 1.3 * h0 / w0  # three times deeper in z (up): a taller picture
    # Back to the file's value: no override is stored.
    monkeypatch.setattr(app_module, "ask_voxel_size", lambda *a: (1.0, 1.0, 1.0))
    window.voxel_size_action.trigger()
    assert window.model.volume.voxel_size_um is None
    assert window.data is data  # the data exactly as read, its note included
    assert "Edit → Voxel size…" in window.data_label.toolTip()


def test_voxel_size_dialog_shows_the_files_value(qtbot):
    from vtkvol.ui.voxel_size import VoxelSizeDialog, user_note

    dialog = VoxelSizeDialog((0.2, 0.2, 1.0), (0.2, 0.2, 0.5), True)
    qtbot.addWidget(dialog)
    assert [b.value() for b in dialog.boxes] == [0.2, 0.2, 1.0]
    assert "0.2 × 0.2 × 0.5 µm" in dialog.source_label.text()
    dialog.file_button.click()
    assert dialog.value() == (0.2, 0.2, 0.5)
    missing = VoxelSizeDialog((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), False)
    qtbot.addWidget(missing)
    assert "does not store a voxel size" in missing.source_label.text()
    note = user_note("voxel size not stored in the file: using 1 × 1 × 1 µm (pass "
                     "voxel_size_um to set it)")
    assert note.endswith("(set it with Edit → Voxel size…)") and "voxel_size_um" not in note


# -- overlays and background --------------------------------------------------------------------
OVERLAY_REGIONS = {
    # field: (rows, cols) of the 256² view where it draws
    "scale_bar": (slice(200, 256), slice(150, 256)),
    "orientation_axes": (slice(195, 256), slice(0, 56)),
    "color_legend": (slice(0, 215), slice(180, 256)),
    "bounding_box": (slice(0, 256), slice(0, 256)),
}


@pytest.mark.parametrize("name", list(OVERLAY_REGIONS))
def test_overlay_toggles_draw_in_the_view_and_screenshots(window, name, qtbot):
    action = window.view_actions.overlay_actions[name]
    assert not action.isChecked() and not getattr(window.model.overlays, name)
    window.model.render.background = (0.0, 0.0, 0.0)
    before = shot(window)
    action.trigger()  # widget → model → pixels (screenshot() is what File → Save writes)
    assert getattr(window.model.overlays, name) is True
    after = shot(window)
    rows, cols = OVERLAY_REGIONS[name]
    changed = changed_pixels(before, after)
    assert changed[rows, cols].sum() > 20
    assert changed.sum() - changed[rows, cols].sum() <= 2
    assert window.undo_action.text() == "&Undo Toggle overlay"
    window.undo_action.trigger()  # model → widget and pixels (through undo)
    assert not action.isChecked() and getattr(window.model.overlays, name) is False
    assert changed_pixels(before, shot(window)).sum() <= 2


def test_scale_bar_measures_the_view(window):
    window.model.overlays.scale_bar = True
    shot(window)
    overlays = window.viewport.scene.overlays
    cam = window.viewport.renderer.GetActiveCamera()
    height = window.viewport.renderer.GetSize()[1]
    world = 2 * cam.GetDistance() * np.tan(np.radians(cam.GetViewAngle()) / 2)
    assert overlays.bar_length_um / overlays.bar_length_px == pytest.approx(world / height)
    assert overlays.bar_length_um in {1, 2, 5, 10, 20, 50, 100}
    assert overlays.bar_text.GetInput() == f"{overlays.bar_length_um:g} µm"


def test_overlays_are_saved_in_sessions(window, qtbot, tmp_path):
    window.view_actions.overlay_actions["bounding_box"].trigger()
    window.view_actions.overlay_actions["orientation_axes"].trigger()
    path = window.save_session(tmp_path / "overlays")
    window.model.overlays.update(Overlays().model_dump())
    assert not window.view_actions.overlay_actions["bounding_box"].isChecked()
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert window.model.overlays == Overlays(bounding_box=True, orientation_axes=True)
    assert window.view_actions.overlay_actions["bounding_box"].isChecked()
    assert window.view_actions.overlay_actions["orientation_axes"].isChecked()


def test_background_colour(window, monkeypatch):
    from vtkvol.ui.docks import base

    monkeypatch.setattr(base, "pick_color", lambda parent, initial, title: (1.0, 1.0, 1.0))
    window.view_actions.background_action.trigger()  # widget → model → pixels
    assert window.model.render.background == (1.0, 1.0, 1.0)
    image = shot(window)
    assert image[2, 2] == pytest.approx([255, 255, 255], abs=1)
    window.model.overlays.bounding_box = True  # overlays turn dark on a light background
    boxed = shot(window)
    assert (boxed.max(axis=-1) < 80).sum() > 50
    assert window.undo_action.text().endswith("Toggle overlay")
    window.model.render.background = (0.0, 0.0, 0.0)  # model → widget
    assert window.view_actions.background_action.toolTip().endswith("#000000")
    assert window.undo_action.text() == "&Undo Change background colour"


def test_pyvista_blend_mode_names(window):
    combo = window.channels_dock.blend
    window.model.render.blend_mode = "maximum"  # PyVista's name for MIP
    assert window.model.render.blend_mode == "mip"
    assert combo.itemData(combo.currentIndex()) == "mip"
    window.model.render.blend_mode = "Minimum"
    assert combo.itemData(combo.currentIndex()) == "minip"
    combo.setCurrentIndex(combo.findData("composite"))  # widget → model
    assert window.model.render.blend_mode == "composite"


def test_magnified_screenshot_measures_like_the_view(window):
    """A 2× screenshot is rendered in tiles; its scale bar is where, and as long, as in the
    view, in the image's pixels."""
    window.model.render.background = (0.0, 0.0, 0.0)
    window.model.channels[0].visible = False  # only the overlay is bright
    window.model.overlays.scale_bar = True
    shot(window)
    overlays = window.viewport.scene.overlays
    length_px = overlays.bar_length_px

    def longest_bright_run(image: np.ndarray, rows: slice) -> int:
        bright = image[rows].min(axis=-1) > 150
        best = 0
        for row in bright:
            run = 0
            for value in row:
                run = run + 1 if value else 0
                best = max(best, run)
        return best

    single = window.viewport.screenshot(1)
    double = window.viewport.screenshot(2)
    assert longest_bright_run(single, slice(230, 256)) == pytest.approx(length_px, abs=3)
    assert longest_bright_run(double, slice(460, 512)) == pytest.approx(2 * length_px, abs=5)
    # In the lower-right corner of the large image, not repeated in other tiles.
    assert longest_bright_run(double, slice(200, 300)) < 10


# -- the engine without the app -----------------------------------------------------------------
def test_visible_bounds_follow_tf_crop_links_and_noise():
    from vtkvol.engine.framing import visible_bounds
    from vtkvol.io import VolumeData
    from vtkvol.model.defaults import scene_for

    rng = np.random.default_rng(0)
    arr = rng.integers(0, 20, (2, 32, 40, 50)).astype(np.uint16)
    arr[0, 10:20, 5:15, 30:45] = 1000  # channel 0: a block
    arr[0, 2, 35, 3] = 5000  # one hot pixel far away (noise above the TF's low limit)
    arr[1, 25:30, 30:38, 2:8] = 1000  # channel 1: another block
    data = VolumeData.from_array(arr, (0.5, 1.0, 2.0), ["a", "b"])
    model = scene_for(data)
    model.channels[1].visible = False
    assert visible_bounds(data, model) == pytest.approx((15.0, 22.0, 5.0, 14.0, 20.0, 38.0))
    model.crop.x = (16.0, 20.0)
    assert visible_bounds(data, model)[:2] == pytest.approx((16.0, 20.0))
    model.crop.x = None
    model.channels[1].visible = True
    both = visible_bounds(data, model)
    assert both[0] == pytest.approx(1.0) and both[5] == pytest.approx(58.0)
    model.channels[0].tf.opacity = [(0.0, 0.0), (1e6, 0.0)]  # channel 0 transparent
    assert visible_bounds(data, model)[:2] == pytest.approx((1.0, 3.5))
    model.channels[0].tf_linked_to = 1  # follows channel 1's TF again
    assert visible_bounds(data, model) == pytest.approx(both)
    for channel in model.channels:
        channel.visible = False
    assert visible_bounds(data, model) is None


def test_overlays_in_offscreen_renders(small_volume):
    """`vtkvol render` of a session with overlays draws them (no app, no interactor)."""
    from vtkvol.engine.api import render_image
    from vtkvol.model.defaults import scene_for

    model = scene_for(small_volume)
    plain = render_image(small_volume, model=model, size=(128, 128)).astype(float)
    for name in ("bounding_box", "orientation_axes", "scale_bar", "color_legend"):
        model.overlays = Overlays(**{name: True})
        image = render_image(small_volume, model=model, size=(128, 128)).astype(float)
        assert changed_pixels(plain, image).sum() > 15, name


@pytest.mark.parametrize("method", ["shadow_volume", "cone_traced", "convection_diffusion",
                                    "hybrid_diffusion"])
def test_built_in_choices_are_words_not_identifiers(qapp, method):
    from vtkvol.model.techniques import technique_specs
    from vtkvol.ui.docks.lights import LightsDock

    specs = technique_specs()
    model = SceneModel()
    model.illumination.method = method
    dock = LightsDock(model, techniques=specs)
    try:
        for param in specs[method].parameters:
            if param.kind != "choice" or all(c.isdigit() for c in param.choices):
                continue
            combo = dock.param_widget(param.name)
            shown = [combo.itemText(i) for i in range(combo.count())]
            assert shown == list(param.choice_labels), param.name
            assert [combo.itemData(i) for i in range(combo.count())] == list(param.choices)
    finally:
        dock.release()
        dock.deleteLater()


def test_colour_legend_follows_the_channels(window):
    overlays = window.viewport.scene.overlays
    channel = window.model.channels[0]
    channel.name = "before"  # while the legend is hidden
    window.model.overlays.color_legend = True
    assert [bar.GetTitle() for bar in overlays.legends] == ["before"]
    bar = overlays.legends[0]
    channel.tf.rescale(100.0, 900.0)  # edited in place: the same bar shows the new range
    assert overlays.legends[0] is bar
    assert bar.GetLookupTable().GetRange() == pytest.approx((100.0, 900.0))
    channel.name = "nuclei (DAPI)"
    assert [b.GetTitle() for b in overlays.legends] == ["nuclei (DAPI)"]
    channel.visible = False
    assert overlays.legends == []


def test_a_dead_listener_does_not_break_a_nested_change():
    """A slot that changes the model again (a nested event) while a listener that was
    garbage-collected is still connected: both loops drop the dead slot, neither fails."""
    import gc

    from vtkvol.model.scene import Channel

    channel = Channel()

    class Listener:
        def on_change(self, paths):
            pass

    seen: list[frozenset[str]] = []

    def nested(paths):
        seen.append(paths)
        if "name" in paths:
            channel.visible = False  # an edit in reaction to an edit

    dead = Listener()
    channel.changed.connect(nested)
    channel.changed.connect(dead.on_change)
    del dead
    gc.collect()
    channel.name = "renamed"
    assert seen == [frozenset({"name"}), frozenset({"visible"})]
    assert len(channel.changed) == 1
