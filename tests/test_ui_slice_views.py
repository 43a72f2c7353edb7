"""The slice views (ui/docks/slice_views.py) in the app: widget → model (click, drag, wheel,
PageUp/PageDown move the cursor in µm) and model → widget and pixels (TF colour, channel
visibility, the cursor's crosshair, a phantom's bright voxel, the crop box), the View menu,
the 3-D slice planes, and the cursor in sessions. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QImage, QWheelEvent
from PySide6.QtWidgets import QApplication

from vtkvol.engine.slices import slice_rgba
from vtkvol.io import VolumeData
from vtkvol.model.session import SessionError, read_session
from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def pristine() -> dict:
    return {}


@pytest.fixture
def window(opened_window, pristine, qtbot):
    """The module's window with the small volume and the slice views shown; its model is
    reset to the opened state after each test."""
    if not pristine:
        pristine.update(opened_window.model.model_dump())
    dock = opened_window.slice_views_dock
    if not dock.isVisible():
        dock.toggleViewAction().trigger()
        qtbot.waitUntil(dock.isVisible, timeout=5000)
    opened_window.resizeDocks([dock], [420], Qt.Orientation.Horizontal)
    QApplication.processEvents()
    dock.refresh_now()
    yield opened_window
    QApplication.processEvents()
    apply_state(opened_window.model, pristine)
    opened_window.recorder.reset()
    opened_window.document.unsaved_data_edit = False


def grab(widget) -> np.ndarray:
    """The widget as painted: ``uint8 [h, w, 3]`` in logical pixels."""
    image = widget.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    image = image.scaled(widget.width(), widget.height())
    h, w = image.height(), image.width()
    bits = np.frombuffer(image.constBits(), np.uint8, image.bytesPerLine() * h)
    return bits.reshape(h, -1)[:, : 3 * w].reshape(h, w, 3).copy()


def wheel(widget, point: QPointF, delta: int) -> None:
    event = QWheelEvent(point, widget.mapToGlobal(point), QPoint(0, 0), QPoint(0, delta),
                        Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier,
                        Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)


def test_view_menu_shows_and_hides_the_slice_views(main_window, qtbot):
    dock = main_window.slice_views_dock
    view_menu = next(a.menu() for a in main_window.menuBar().actions() if a.text() == "&View")
    entries = {a.text(): a for a in view_menu.actions()}
    assert entries["Slice views"] is dock.toggleViewAction()
    assert "Slice &planes" in entries
    shown = dock.isVisible()
    dock.toggleViewAction().trigger()
    qtbot.waitUntil(lambda: dock.isVisible() != shown, timeout=5000)
    # The dock is part of the saved window layout (QMainWindow.saveState) by its name.
    assert dock.objectName() == "slice_views_dock"
    layout = main_window.saveState()
    dock.toggleViewAction().trigger()
    qtbot.waitUntil(lambda: dock.isVisible() == shown, timeout=5000)
    assert main_window.restoreState(layout)
    qtbot.waitUntil(lambda: dock.isVisible() != shown, timeout=5000)
    dock.toggleViewAction().trigger()
    qtbot.waitUntil(lambda: dock.isVisible() == shown, timeout=5000)


def test_views_keep_the_physical_aspect_of_the_voxels(window):
    dock = window.slice_views_dock
    data = window.data
    nz, ny, nx = data.array.shape[1:]
    sx, sy, sz = data.voxel_size_um  # 0.5, 0.5, 1.0: z voxels twice as long
    for name, (w_um, h_um) in {"xy": (nx * sx, ny * sy), "yz": (nz * sz, ny * sy),
                               "xz": (nx * sx, nz * sz)}.items():
        rect = dock.views[name].image_rect()
        assert rect.width() / rect.height() == pytest.approx(w_um / h_um, rel=0.02), name
        image = dock.views[name].image()
        assert image.shape[:2] == {"xy": (ny, nx), "yz": (ny, nz), "xz": (nz, nx)}[name]


def test_click_and_drag_move_the_cursor_in_um(window, qtbot):
    dock = window.slice_views_dock
    view = dock.views["xy"]
    sx, sy, sz = window.data.voxel_size_um
    z_before = dock.cursor_um()[2]
    target = view.to_widget(10 * sx, 30 * sy)  # the centre of voxel (10, 30)
    qtbot.mouseClick(view, Qt.MouseButton.LeftButton, pos=target.toPoint())
    assert window.model.cursor == pytest.approx((10 * sx, 30 * sy, z_before))
    # A drag in the xz view moves x and z and keeps y.
    xz = dock.views["xz"]
    qtbot.mousePress(xz, Qt.MouseButton.LeftButton, pos=xz.to_widget(2 * sx, 5 * sz).toPoint())
    qtbot.mouseMove(xz, xz.to_widget(7 * sx, 20 * sz).toPoint())
    qtbot.mouseRelease(xz, Qt.MouseButton.LeftButton, pos=xz.to_widget(7 * sx, 20 * sz).toPoint())
    assert window.model.cursor == pytest.approx((7 * sx, 30 * sy, 20 * sz))
    # Outside the data: clamped to the last voxel.
    far = xz.to_widget(1000.0, -1000.0)
    qtbot.mouseClick(xz, Qt.MouseButton.LeftButton,
                     pos=QPoint(min(int(far.x()), xz.width() - 1), max(int(far.y()), 0)))
    nx = window.data.array.shape[3]
    assert window.model.cursor == pytest.approx(((nx - 1) * sx, 30 * sy, 0.0))
    # Cursor moves are navigation, like the camera: no undo step, nothing unsaved.
    assert window.recorder.stack.count() == 0 and not window.has_unsaved_changes()


def test_wheel_and_page_keys_step_one_voxel(window, qtbot):
    dock = window.slice_views_dock
    sz = window.data.voxel_size_um[2]
    view = dock.views["xy"]
    k = dock.cursor_voxel()[2]
    wheel(view, view.rect().center().toPointF(), 120)
    assert window.model.cursor[2] == pytest.approx((k + 1) * sz)
    wheel(view, view.rect().center().toPointF(), -240)
    assert window.model.cursor[2] == pytest.approx((k - 1) * sz)
    view.setFocus()
    qtbot.keyClick(view, Qt.Key.Key_PageUp)
    assert dock.cursor_voxel()[2] == k
    yz = dock.views["yz"]
    i = dock.cursor_voxel()[0]
    qtbot.keyClick(yz, Qt.Key.Key_PageDown)
    assert dock.cursor_voxel()[0] == i - 1
    for _ in range(3):  # past the first slice: clamped
        wheel(yz, yz.rect().center().toPointF(), -120 * 40)
    assert dock.cursor_voxel()[0] == 0
    # A touchpad's small deltas add up: three of 40 make one notch, one slice.
    for expected in (0, 0, 1):
        wheel(yz, yz.rect().center().toPointF(), 40)
        assert dock.cursor_voxel()[0] == expected


def test_voxel_size_keeps_the_cursor_on_its_voxel(window, qtbot):
    dock = window.slice_views_dock
    sx, sy, sz = window.data.voxel_size_um
    window.model.cursor = (9 * sx, 17 * sy, 5 * sz)
    window.set_voxel_size((0.3, 0.7, 2.5))
    try:
        assert dock.cursor_voxel() == (9, 17, 5)
        assert window.model.cursor == pytest.approx((9 * 0.3, 17 * 0.7, 5 * 2.5))
        dock.refresh_now()
        assert "voxel (9, 17, 5)" in dock.readout.text()
        rect = dock.views["xz"].image_rect()  # the new aspect: x 48·0.3 µm, z 24·2.5 µm
        assert rect.width() / rect.height() == pytest.approx(48 * 0.3 / (24 * 2.5), rel=0.03)
    finally:
        window.set_voxel_size((sx, sy, sz))


def test_readout_shows_channel_names_as_text(window):
    dock = window.slice_views_dock
    window.model.channels[0].name = "<b>DAPI</b>"
    dock.refresh_now()
    assert "&lt;b&gt;DAPI&lt;/b&gt;: " in dock.readout.text()


def test_tf_colour_and_visibility_change_the_pixels(window):
    dock = window.slice_views_dock
    view = dock.views["xy"]
    tf = window.model.channels[0].tf
    lo, hi = tf.value_span
    tf.colors = [(lo, 0.0, 0.0, 0.0), (hi, 1.0, 0.0, 0.0)]  # a red ramp
    dock.refresh_now()
    red = view.image().astype(int)
    assert red[..., 0].max() > 200 and red[..., 1].max() == 0 and red[..., 2].max() == 0
    index = dock.cursor_voxel()[2]
    expected = slice_rgba(window.data, window.model, "xy", index)
    np.testing.assert_array_equal(red[..., 0], np.rint(expected[..., 0] * 255))
    tf.colors = [(lo, 0.0, 0.0, 0.0), (hi, 0.0, 0.0, 1.0)]  # blue
    dock.refresh_now()
    blue = view.image().astype(int)
    assert blue[..., 0].max() == 0 and blue[..., 2].max() > 200
    window.model.channels[0].visible = False  # channels menu → no colour at all
    dock.refresh_now()
    assert view.image()[..., :3].max() == 0
    # And on screen: the painted widget has no blue any more inside the image.
    rect = view.image_rect().toRect().adjusted(3, 3, -3, -3)
    painted = grab(view)[rect.top():rect.bottom(), rect.left():rect.right()]
    assert painted[..., 2].astype(int).max() < 120  # only the crosshair's faint blue share


def test_moving_the_cursor_in_the_model_moves_the_crosshair(window, qtbot):
    dock = window.slice_views_dock
    view = dock.views["xy"]
    sx, sy, _ = window.data.voxel_size_um
    window.model.channels[0].visible = False  # a black slice: only the lines show
    for i, j in ((5, 40), (33, 12)):
        window.model.cursor = (i * sx, j * sy, 3.0)
        dock.refresh_now()
        image = grab(view).astype(int)
        rect = view.image_rect().toRect()
        inner = image[rect.top() + 3:rect.bottom() - 3, rect.left() + 3:rect.right() - 3]
        # The vertical line marks the yz plane (red), the horizontal one the xz plane (green).
        reddish = (inner[..., 0] > 120) & (inner[..., 1] < 100)
        greenish = (inner[..., 1] > 120) & (inner[..., 0] < 100)
        column = rect.left() + 3 + int(np.argmax(reddish.sum(axis=0)))
        row = rect.top() + 3 + int(np.argmax(greenish.sum(axis=1)))
        assert reddish.sum(axis=0).max() > 0.9 * inner.shape[0]  # one full-height line
        assert greenish.sum(axis=1).max() > 0.9 * inner.shape[1]
        assert (column, row) == view.crosshair()
        expected = view.to_widget(i * sx, j * sy)  # the voxel's centre
        assert abs(column + 0.5 - expected.x()) <= 0.5 and abs(row + 0.5 - expected.y()) <= 0.5
        assert f"voxel ({i}, {j}, 3)" in dock.readout.text()


def test_a_phantoms_bright_voxel_is_at_its_pixel(main_window, qtbot, small_volume_file):
    window = main_window
    array = np.zeros((1, 6, 8, 10), dtype=np.uint16)
    array[0, 4, 3, 7] = 4000  # z 4, y 3, x 7
    window.model.cursor = (1.0, 1.0, 1.0)
    window.show_volume(VolumeData.from_array(array, (0.4, 0.4, 0.8), ["bead"]))
    try:
        assert window.model.cursor is None  # new data: the slice views start at its centre
        dock = window.slice_views_dock
        if not dock.isVisible():
            dock.toggleViewAction().trigger()
            qtbot.waitUntil(dock.isVisible, timeout=5000)
        window.resizeDocks([dock], [420], Qt.Orientation.Horizontal)
        QApplication.processEvents()
        tf = window.model.channels[0].tf
        tf.update({"colors": [(0.0, 0.0, 0.0, 0.0), (4000.0, 1.0, 1.0, 1.0)],
                   "opacity": [(0.0, 0.0), (4000.0, 1.0)]})
        window.model.cursor = (7 * 0.4, 3 * 0.4, 4 * 0.8)
        dock.refresh_now()
        for name, pixel in (("xy", (3, 7)), ("yz", (3, 4)), ("xz", (4, 7))):
            view = dock.views[name]
            lit = np.argwhere(view.image()[..., 0] > 0)
            assert [tuple(p) for p in lit] == [pixel], name
            # On screen: the voxel's square is white (but for the crosshair crossing it), and
            # the image around it is black.
            p = view.plane
            s_col, s_row = (window.data.voxel_size_um[a] for a in (p.column, p.row))
            c_um, r_um = (window.model.cursor[a] for a in (p.column, p.row))
            top_left = view.to_widget(c_um - 0.5 * s_col, r_um - 0.5 * s_row)
            bottom_right = view.to_widget(c_um + 0.5 * s_col, r_um + 0.5 * s_row)
            painted = grab(view).astype(int)
            x0, y0 = math.ceil(top_left.x()), math.ceil(top_left.y())
            x1, y1 = math.floor(bottom_right.x()), math.floor(bottom_right.y())
            line_x, line_y = view.crosshair()
            voxel = painted[y0:y1, x0:x1]
            keep = np.ones(voxel.shape[:2], bool)
            keep[line_y - y0, :] = False
            keep[:, line_x - x0] = False
            assert keep.sum() >= 2 and voxel[keep].min() > 200, name
            rect = view.image_rect().toRect().adjusted(3, 3, -3, -3)
            around = painted[rect.top():rect.bottom(), rect.left():rect.right()].copy()
            around[y0 - rect.top() - 1:y1 - rect.top() + 1,
                   x0 - rect.left() - 1:x1 - rect.left() + 1] = 0
            around[line_y - rect.top(), :] = 0
            around[:, line_x - rect.left()] = 0
            assert around.max() < 60, name
    finally:
        window.data = None  # the next test opens the module's volume again


def test_crop_box_dims_the_outside(window):
    dock = window.slice_views_dock
    view = dock.views["xy"]
    window.model.channels[0].tf.colors = [(0.0, 1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0)]  # white
    dock.refresh_now()
    sx, sy, _ = window.data.voxel_size_um
    inside_pt, outside_pt = view.to_widget(20 * sx, 20 * sy), view.to_widget(3 * sx, 20 * sy)
    before = grab(view)
    window.model.crop.x = (10 * sx, 30 * sx)
    dock.refresh_now()
    after = grab(view)
    for pt in (inside_pt, outside_pt):
        pt.setY(pt.y() + 4)  # off the horizontal crosshair
    inside = (int(inside_pt.y()), int(inside_pt.x()) + 3)
    outside = (int(outside_pt.y()), int(outside_pt.x()) + 3)
    assert after[inside].min() > 200 and before[inside].min() > 200
    assert before[outside].min() > 200 and after[outside].max() < 120
    edge = view.to_widget(10 * sx, 20 * sy)  # the outline's left edge (dashed, yellow)
    column = after[:, round(edge.x()) - 1:round(edge.x()) + 2]
    yellow = (column[..., 0] > 180) & (column[..., 1] > 140) & (column[..., 2] < 130)
    assert yellow.sum() > 10


def test_slice_planes_in_the_3d_view(window):
    action = window.view_actions.overlay_actions["slice_planes"]
    window.model.render.background = (0.0, 0.0, 0.0)
    window.viewport.render_now()
    before = window.viewport.screenshot().astype(int)
    action.trigger()
    assert window.model.overlays.slice_planes is True
    window.viewport.render_now()
    after = window.viewport.screenshot().astype(int)
    changed = np.abs(after - before).max(axis=-1) > 30
    assert changed.sum() > 100
    sx, sy, sz = window.data.voxel_size_um
    window.model.cursor = (4 * sx, 6 * sy, 2 * sz)
    corners = window.viewport.scene.overlays.plane_outlines
    np.testing.assert_allclose(corners[0, :, 0], 4 * sx)  # the yz plane at x = 4 voxels
    np.testing.assert_allclose(corners[1, :, 1], 6 * sy)
    np.testing.assert_allclose(corners[2, :, 2], 2 * sz)
    window.viewport.render_now()
    moved = window.viewport.screenshot().astype(int)
    assert (np.abs(moved - after).max(axis=-1) > 30).sum() > 50  # the outlines followed
    window.undo_action.trigger()
    assert window.model.overlays.slice_planes is False and not action.isChecked()


def test_cursor_is_saved_in_sessions(window, qtbot, tmp_path, dialogs):
    sx, sy, sz = window.data.voxel_size_um
    window.model.cursor = (12 * sx, 7 * sy, 3 * sz)
    path = window.save_session(tmp_path / "cursor")
    assert json.loads(path.read_text(encoding="utf-8"))["scene"]["cursor"] == pytest.approx(
        [12 * sx, 7 * sy, 3 * sz])
    window.model.cursor = None
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert window.model.cursor == pytest.approx((12 * sx, 7 * sy, 3 * sz))
    window.slice_views_dock.refresh_now()
    assert window.slice_views_dock.cursor_voxel() == (12, 7, 3)

    # A cursor outside the data's box is moved to the nearest voxel inside it.
    document = json.loads(path.read_text(encoding="utf-8"))
    document["scene"]["cursor"] = [-50.0, 1e6, 2 * sz]
    outside = tmp_path / "outside.vtkvol.json"
    outside.write_text(json.dumps(document), encoding="utf-8")
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(outside)
    ny = window.data.array.shape[2]
    assert window.model.cursor == pytest.approx((0.0, (ny - 1) * sy, 2 * sz))
    assert not dialogs


@pytest.mark.parametrize(("bad", "expected"), [
    ("[NaN, 1.0, 2.0]", "NaN is not a number JSON allows"),
    ("[1e999, 1.0, 2.0]", "1e999 is too large a number"),
    ("[1, 2]", "cursor"),
    ('"middle"', "cursor"),
])
def test_a_hostile_cursor_in_a_session_is_a_one_line_error(tmp_path, window, qtbot, dialogs,
                                                           bad, expected):
    path = window.save_session(tmp_path / "good")
    document = json.loads(path.read_text(encoding="utf-8"))
    document["scene"]["cursor"] = "@@"
    broken = tmp_path / "bad.vtkvol.json"
    broken.write_text(json.dumps(document).replace('"@@"', bad), encoding="utf-8")
    with pytest.raises(SessionError) as raised:
        read_session(broken)
    message = str(raised.value)
    assert expected in message and "\n" not in message, message
    # In the app: a dialog says so, and the view stays as it was.
    cursor = window.model.cursor
    with qtbot.waitSignal(window.openFailed, timeout=10_000):
        window.open_session(broken)
    assert len(dialogs) == 1 and expected in dialogs[0].informativeText()
    assert window.model.cursor == cursor


def test_a_cursor_move_renders_a_3d_frame_only_with_the_planes_shown(window, monkeypatch):
    scene = window.viewport.scene
    requests: list[int] = []
    monkeypatch.setattr(scene, "_request_render", lambda: requests.append(1))
    sx, sy, sz = window.data.voxel_size_um
    window.model.cursor = (3 * sx, 4 * sy, 5 * sz)
    assert requests == []  # only the slice views show the cursor
    window.model.overlays.slice_planes = True
    requests.clear()
    window.model.cursor = (6 * sx, 4 * sy, 5 * sz)
    assert requests
    np.testing.assert_allclose(scene.overlays.plane_outlines[0, :, 0], 6 * sx)


def test_a_drag_renders_the_3d_view_coarser_only_with_the_planes(window, qtbot):
    dock, scene = window.slice_views_dock, window.viewport.scene
    view = dock.views["xy"]
    sx, sy, _ = window.data.voxel_size_um
    start, end = view.to_widget(5 * sx, 5 * sy).toPoint(), view.to_widget(20 * sx, 9 * sy)
    qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=start)
    assert not scene.interactive  # no planes in 3-D: the drag does not touch the 3-D view
    qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=start)
    window.model.overlays.slice_planes = True
    qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=start)
    qtbot.mouseMove(view, end.toPoint())
    assert scene.interactive  # coarse while the planes move
    qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=end.toPoint())
    qtbot.waitUntil(lambda: not scene.interactive, timeout=5000)  # full quality once settled
    assert dock.cursor_voxel()[:2] == (20, 9)
    # The drags made no undo step: the only one is the overlay switched on above.
    assert window.recorder.stack.count() == 1
    assert window.undo_action.text() == "&Undo Toggle overlay"
