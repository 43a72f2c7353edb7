"""App building blocks without a 3-D view: the log opacity axis, the function editor, the
binding helpers, undo/redo, generated parameter widgets, error dialogs, TF files."""

from __future__ import annotations

import json
import sys

import numpy as np
import PySide6
import pytest
from PySide6.QtCore import QPoint, Qt
from PySide6.QtWidgets import QCheckBox, QComboBox, QLabel, QMessageBox, QSpinBox

from vtkvol.engine.gl import GLUnavailableError
from vtkvol.io import VolumeReadError
from vtkvol.model import Invalidates, Param, SceneModel, TransferFunction
from vtkvol.model.session import MissingDataError
from vtkvol.ui import compat, errors
from vtkvol.ui.binding import Bindings, signals_blocked
from vtkvol.ui.docks.function_editor import (
    Curve,
    FunctionEditor,
    log_axis_to_opacity,
    opacity_to_log_axis,
    simplify,
)
from vtkvol.ui.docks.lights import (
    FloatParamWidget,
    angles_to_direction,
    direction_to_angles,
    make_param_widget,
    param_label,
)
from vtkvol.ui.docks.transfer_function import merge_color_curve, read_tf_file, write_tf_file
from vtkvol.ui.undo import UndoRecorder, apply_state

pytestmark = pytest.mark.gui


# -- seed 002's log opacity axis ---------------------------------------------------------------
@pytest.mark.parametrize(
    ("d", "alpha", "expected"),
    [
        (255, 0.001, 0.0408),
        (255, 0.01, 0.2281),
        (255, 0.05, 0.4723),
        (255, 0.5, 0.8756),
        (4095, 0.001, 0.1957),
        (4095, 0.05, 0.6404),
    ],
)
def test_log_opacity_worked_values(d, alpha, expected):
    """The worked values of 002_summary §2.10 (a = max(ln d, 1))."""
    assert opacity_to_log_axis(alpha, d) == pytest.approx(expected, abs=5e-5)
    assert log_axis_to_opacity(expected, d) == pytest.approx(alpha, rel=2e-3)


@pytest.mark.parametrize("d", [2.0, 255.0, 1000.0, 4095.0])
def test_log_opacity_is_a_bijection_of_0_1(d):
    alpha = np.linspace(0.0, 1.0, 101)
    shown = opacity_to_log_axis(alpha, d)
    assert shown[0] == pytest.approx(0.0, abs=1e-12)
    assert shown[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(shown) > 0)
    np.testing.assert_allclose(log_axis_to_opacity(shown, d), alpha, atol=1e-12)


def test_simplify_drops_collinear_nodes_only():
    line = [(x, 0.5 * x) for x in np.linspace(0, 1, 50)]
    assert simplify(line, 1e-6) == [line[0], line[-1]]
    bent = [(0.0, 0.0), (0.5, 1.0), (1.0, 0.0)]
    assert simplify(bent, 1e-3) == bent


# -- function editor -------------------------------------------------------------------------
@pytest.fixture
def editor(qtbot):
    widget = FunctionEditor()
    widget.resize(400, 200)
    widget.set_curves([Curve("opacity", "Opacity", Qt.GlobalColor.white, log_axis=True),
                       Curve("red", "Red", Qt.GlobalColor.red)])
    widget.set_domain(0.0, 100.0)
    widget.set_points("opacity", [(0.0, 0.0), (100.0, 1.0)])
    widget.set_points("red", [(0.0, 1.0), (100.0, 1.0)])
    qtbot.addWidget(widget)
    widget.show()
    qtbot.waitExposed(widget)
    return widget


def _pixel(editor, x, y, curve="opacity"):
    return editor.to_pixel(x, y, editor.curve(curve)).toPoint()


def test_editor_click_adds_a_node_and_drag_moves_it(editor, qtbot):
    edits = []
    editor.pointsEdited.connect(lambda name, pts: edits.append((name, pts)))
    with qtbot.waitSignal(editor.editFinished):
        qtbot.mousePress(editor, Qt.MouseButton.LeftButton, pos=_pixel(editor, 50, 0.2))
        qtbot.mouseMove(editor, _pixel(editor, 60, 0.8))
        qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, pos=_pixel(editor, 60, 0.8))
    name, points = edits[-1]
    assert name == "opacity"
    assert len(points) == 3
    x, y = points[1]
    assert x == pytest.approx(60, abs=1.0)
    assert y == pytest.approx(0.8, abs=0.02)


def test_editor_node_cannot_pass_its_neighbours(editor, qtbot):
    editor.set_points("opacity", [(0.0, 0.0), (50.0, 0.5), (100.0, 1.0)])
    edits = []
    editor.pointsEdited.connect(lambda name, pts: edits.append(pts))
    qtbot.mousePress(editor, Qt.MouseButton.LeftButton, pos=_pixel(editor, 50, 0.5))
    qtbot.mouseMove(editor, _pixel(editor, 99.9, 0.5))
    qtbot.mouseMove(editor, QPoint(editor.width() + 50, 10))
    qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, pos=QPoint(editor.width() + 50, 10))
    xs = [p[0] for p in edits[-1]]
    assert xs == sorted(xs) and len(xs) == 3 and xs[1] < 100.0


def test_editor_right_click_deletes_a_node_but_keeps_two(editor, qtbot):
    editor.set_points("opacity", [(0.0, 0.0), (50.0, 0.5), (100.0, 1.0)])
    edits = []
    editor.pointsEdited.connect(lambda name, pts: edits.append(pts))
    qtbot.mouseClick(editor, Qt.MouseButton.RightButton, pos=_pixel(editor, 50, 0.5))
    assert edits[-1] == [(0.0, 0.0), (100.0, 1.0)]
    qtbot.mouseClick(editor, Qt.MouseButton.RightButton, pos=_pixel(editor, 100, 1.0))
    assert len(edits) == 1  # two nodes remain: the last delete was refused


def test_editor_curve_mode_draws_freehand(editor, qtbot):
    editor.set_mode("curve")
    edits = []
    editor.pointsEdited.connect(lambda name, pts: edits.append(pts))
    qtbot.mousePress(editor, Qt.MouseButton.LeftButton, pos=_pixel(editor, 0, 0.0))
    for x in range(0, 101, 10):
        qtbot.mouseMove(editor, _pixel(editor, x, 0.0))
    qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, pos=_pixel(editor, 100, 0.0))
    final = edits[-1]
    assert max(y for _, y in final) < 0.01
    assert len(final) <= 4  # the flat stroke was simplified to a few nodes


def test_editor_log_axis_maps_pixels_through_seed_002(editor):
    editor.set_log_scale(True)
    r = editor.plot_rect()
    y_pixel = editor.to_pixel(0.0, 0.01, editor.curve("opacity")).y()
    assert (r.bottom() - y_pixel) / r.height() == pytest.approx(opacity_to_log_axis(0.01), abs=1e-9)
    # The colour curve is not on the log axis.
    y_red = editor.to_pixel(0.0, 0.5, editor.curve("red")).y()
    assert (r.bottom() - y_red) / r.height() == pytest.approx(0.5)


def test_merge_color_curve_keeps_the_other_components_exact():
    colors = [(0.0, 0.0, 0.2, 0.4), (100.0, 1.0, 0.6, 0.8)]
    merged = merge_color_curve(colors, 0, [(0.0, 0.0), (30.0, 0.9), (100.0, 1.0)])
    xs = np.linspace(0, 100, 21)
    m = np.array(merged)
    np.testing.assert_allclose(np.interp(xs, m[:, 0], m[:, 2]), np.interp(xs, [0, 100], [0.2, 0.6]))
    np.testing.assert_allclose(np.interp(xs, m[:, 0], m[:, 3]), np.interp(xs, [0, 100], [0.4, 0.8]))
    assert np.interp(30.0, m[:, 0], m[:, 1]) == pytest.approx(0.9)
    # Nothing is added where all three are straight: the original two nodes stay two.
    assert len(merge_color_curve(colors, 1, [(0.0, 0.2), (100.0, 0.6)])) == 2


# -- binding helpers ---------------------------------------------------------------------------
def test_binding_is_two_way_without_echo_and_cleans_up(qtbot):
    model = SceneModel()
    box = QCheckBox()
    qtbot.addWidget(box)
    bindings = Bindings()
    events = []
    model.channels[0].changed.connect(events.append)
    bindings.bind(model.channels[0], "visible", box, box.toggled, box.setChecked)
    assert box.isChecked()
    model.channels[0].visible = False  # model → widget
    assert not box.isChecked()
    box.setChecked(True)  # widget → model
    assert model.channels[0].visible is True
    assert events == [frozenset({"visible"}), frozenset({"visible"})]  # no echo
    bindings.clear()
    assert len(bindings) == 0
    box.setChecked(False)
    assert model.channels[0].visible is True
    model.channels[0].visible = False
    assert box.isChecked() is False  # the widget was left alone


def test_binding_reverts_a_refused_value(qtbot):
    model = SceneModel()
    combo = QComboBox()
    combo.addItems(["composite", "not-a-mode"])
    qtbot.addWidget(combo)
    bindings = Bindings()
    bindings.bind(model.render, "blend_mode", combo, combo.currentTextChanged,
                  lambda v: combo.setCurrentText(v))
    combo.setCurrentText("not-a-mode")
    assert model.render.blend_mode == "composite"
    assert combo.currentText() == "composite"


# -- undo / redo ---------------------------------------------------------------------------------
def test_undo_redo_restores_edits_in_place(qtbot):
    model = SceneModel()
    recorder = UndoRecorder(model)
    tf = model.channels[0].tf
    tf.opacity = [(0.0, 0.0), (255.0, 0.2)]
    model.crop.x = (1.0, 5.0)
    assert recorder.stack.count() == 2
    assert recorder.stack.undoText() == "Change crop ranges"
    recorder.stack.undo()
    assert model.crop.x is None
    recorder.stack.undo()
    assert tf.opacity == [(0.0, 0.0), (255.0, 1.0)]
    assert model.channels[0].tf is tf  # updated in place: bound views stay bound
    recorder.stack.redo()
    recorder.stack.redo()
    assert tf.opacity == [(0.0, 0.0), (255.0, 0.2)] and model.crop.x == (1.0, 5.0)
    model.camera.view_angle = 40.0  # the camera is view state, not an edit
    assert recorder.stack.count() == 2
    recorder.close()


def test_undo_merges_a_gesture_and_quick_repeats(qtbot):
    model = SceneModel()
    recorder = UndoRecorder(model)
    tf = model.channels[0].tf
    with recorder.gesture():
        for alpha in (0.1, 0.2, 0.3):
            tf.opacity = [(0.0, 0.0), (255.0, alpha)]
            model.crop.y = (0.0, 10.0 * alpha)
    assert recorder.stack.count() == 1
    for i in range(5):  # spin-box steps in quick succession
        model.render.ambient = 0.1 * i
    assert recorder.stack.count() == 2
    recorder.stack.undo()
    assert model.render.ambient == 0.3
    recorder.stack.undo()
    assert tf.opacity[-1] == (255.0, 1.0) and model.crop.y is None
    recorder.close()


def test_apply_state_replaces_lists_of_other_length():
    model = SceneModel()
    state = model.copy_state()
    state["lights"] = state["lights"] * 2
    apply_state(model, {"lights": state["lights"]})
    assert len(model.lights) == 2


# -- parameter widgets generated from declarations ----------------------------------------------
PARAMS = (
    Param("reach", 24.0, "Reach", "How far occluders count.", range=(1.0, 1024.0), step=1.0,
          unit="voxel", scale="log", invalidates=Invalidates.ILLUMINATION),
    Param("angle", 5.0, "Cone angle", "Half-angle of the cone.", range=(0.0, 90.0), step=0.5,
          unit="°"),
    Param("cones", 6, "Cones", "Number of cones.", kind="int", range=(1, 12), step=1),
    Param("shadows", True, "Shadows", "Trace shadow cones.", kind="bool"),
    Param("mode", "fast", "Mode", "fast or exact.", kind="choice", choices=("fast", "exact")),
)


def test_parameter_widgets_follow_the_declaration(qtbot):
    reach, angle, cones, shadows, mode = (make_param_widget(p) for p in PARAMS)
    assert param_label(PARAMS[0]) == "Reach (voxel)"
    assert isinstance(reach[0], FloatParamWidget)
    assert reach[0].spin.minimum() == 1.0 and reach[0].spin.maximum() == 1024.0
    assert "How far occluders count." in reach[0].toolTip()
    assert "1…1024 voxel" in reach[0].toolTip() and "Logarithmic" in reach[0].toolTip()
    reach[0].slider.setValue(500)  # the middle of a log slider is the geometric mean
    assert reach[0].value() == pytest.approx(32.0, abs=1.0)
    assert angle[0].spin.suffix() == " °" and angle[0].spin.singleStep() == 0.5
    assert isinstance(cones[0], QSpinBox) and cones[0].maximum() == 12
    assert isinstance(shadows[0], QCheckBox)
    assert isinstance(mode[0], QComboBox) and mode[0].count() == 2
    seen = []
    angle[1].connect(seen.append)
    angle[0].spin.setValue(12.5)
    assert seen == [12.5]
    for widget, *_ in (reach, angle, cones, shadows, mode):
        qtbot.addWidget(widget)


@pytest.mark.parametrize(("az", "el"), [(0, 0), (59, 53.9), (-120, -30), (179, 10)])
def test_light_angles_round_trip(az, el):
    assert direction_to_angles(angles_to_direction(az, el)) == pytest.approx((az, el))


# -- error dialogs ---------------------------------------------------------------------------
def test_expected_errors_show_no_traceback(qtbot):
    box = errors.make_error_box(None, VolumeReadError("a.tif", "every voxel is NaN"),
                                action="Could not open a.tif")
    qtbot.addWidget(box)
    assert box.text() == "Could not open a.tif"
    assert box.informativeText() == "a.tif: every voxel is NaN"
    assert box.detailedText() == "" and box.icon() == QMessageBox.Icon.Warning


def test_unexpected_errors_show_details(qtbot):
    try:
        raise KeyError("boom")
    except KeyError as exc:
        box = errors.make_error_box(None, exc, action="Something went wrong")
    qtbot.addWidget(box)
    assert "KeyError" in box.informativeText()
    assert "Traceback" in box.detailedText() and box.icon() == QMessageBox.Icon.Critical


def test_gl_failures_mention_the_driver(qtbot):
    box = errors.make_error_box(None, GLUnavailableError("no compute shaders"), action="x")
    qtbot.addWidget(box)
    assert "driver" in box.informativeText() and box.detailedText() == ""


def test_locate_dialog_offers_locate(qtbot, monkeypatch, tmp_path):
    shown = []

    def click_locate(box):
        shown.append(box)
        box.buttons()[0].click()  # "Locate…" is added first
        return 0

    monkeypatch.setattr(errors, "run_dialog", click_locate)
    exc = MissingDataError(tmp_path / "v.vtkvol.json", tmp_path / "gone.tif")
    assert errors.ask_locate(None, exc) is True
    assert "gone.tif" in shown[0].informativeText()


# -- transfer-function files -------------------------------------------------------------------
def test_tf_file_round_trip_and_bad_files(tmp_path):
    tf = TransferFunction.ramp(10.0, 900.0, (0.2, 0.9, 0.3), value_range=(0.0, 1000.0))
    path = write_tf_file(tmp_path / "green.tf.json", tf)
    assert read_tf_file(path) == tf
    assert [p.name for p in tmp_path.iterdir()] == ["green.tf.json"]  # no temporary left
    (tmp_path / "bad.tf.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        read_tf_file(tmp_path / "bad.tf.json")
    document = json.loads(path.read_text())
    document["opacity"] = [[0.0, 2.0]]
    (tmp_path / "range.tf.json").write_text(json.dumps(document))
    with pytest.raises(ValueError, match="alpha must lie in 0…1"):
        read_tf_file(tmp_path / "range.tf.json")


# -- the PySide6 6.12 None-reference workaround --------------------------------------------
def test_none_survives_many_void_calls(qtbot):
    assert compat.affected("6.12.0", (3, 11)) and not compat.affected("6.12.0", (3, 12))
    assert not compat.affected("6.11.2", (3, 11))
    label = QLabel()
    qtbot.addWidget(label)
    before = sys.getrefcount(None)
    for _ in range(20_000):
        label.setText("x")  # a void method: leaks one reference on the affected versions
    if compat.affected(PySide6.__version__):
        assert sys.getrefcount(None) > compat.MARGIN // 2  # protected: far from zero
    else:
        assert abs(sys.getrefcount(None) - before) < 1000


def test_signals_blocked_silences_pushes_and_restores_each_widgets_previous_state(qtbot):
    first, second = QSpinBox(), QSpinBox()
    qtbot.addWidget(first)
    qtbot.addWidget(second)
    seen: list[int] = []
    first.valueChanged.connect(seen.append)
    second.valueChanged.connect(seen.append)
    second.blockSignals(True)  # already blocked by an outer push: must stay blocked after
    with signals_blocked(first, second):
        with signals_blocked(first):
            first.setValue(3)
        first.setValue(4)  # the inner block ended; the outer one still holds
        second.setValue(5)
    assert seen == []
    assert not first.signalsBlocked() and second.signalsBlocked()
    first.setValue(6)
    assert seen == [6]


def test_amending_folds_an_engine_correction_into_the_users_step(qtbot):
    model = SceneModel()
    recorder = UndoRecorder(model)
    with recorder.amending():  # nothing to amend yet: absorbed, not a step
        model.illumination.method = "shadow_volume"
    assert recorder.stack.count() == 0
    model.illumination.method = "cone_traced"  # the user's choice
    with recorder.amending():  # the engine sets it back
        model.illumination.method = "local"
    assert recorder.stack.count() == 1
    recorder.stack.undo()
    assert model.illumination.method == "shadow_volume"
    recorder.stack.redo()
    assert model.illumination.method == "local"
    recorder.close()
