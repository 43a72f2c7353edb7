"""The 2-D transfer-function editor in the TF dock, both directions, with rendered pixels
and undo (needs X through pytest-xvfb, and GL)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D
from vtkvol.ui.docks import base as dock_base
from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


def shot(window) -> np.ndarray:
    return window.viewport.screenshot().astype(np.float64)


def drawn(image: np.ndarray, window) -> float:
    """Fraction of pixels clearly not the background."""
    bg = np.array(window.model.render.background) * 255.0
    return float((np.abs(image - bg).max(axis=-1) > 12).mean())


@pytest.fixture(scope="module")
def pristine() -> dict[str, Any]:
    return {}


@pytest.fixture
def window(opened_window, pristine):
    """The shared window reset to the state it first showed, with an empty undo history."""
    model = opened_window.model
    if not pristine:
        pristine.update(model.copy_state())
    apply_state(model, pristine)
    opened_window.recorder.reset()
    yield opened_window
    apply_state(model, pristine)
    opened_window.recorder.reset()


def drag(qtbot, widget, start: QPoint, end: QPoint) -> None:
    qtbot.mousePress(widget, Qt.MouseButton.LeftButton, pos=start)
    for t in np.linspace(0.0, 1.0, 6)[1:]:
        qtbot.mouseMove(widget, QPoint(round(start.x() + t * (end.x() - start.x())),
                                       round(start.y() + t * (end.y() - start.y()))))
    qtbot.mouseRelease(widget, Qt.MouseButton.LeftButton, pos=end)


def test_widget_to_model_to_pixels_and_undo(window, qtbot) -> None:
    dock, channel = window.tf_dock, window.model.channels[0]
    before = shot(window)
    assert drawn(before, window) > 0.03

    dock.dimension_combo.setCurrentIndex(1)  # "Value × gradient (2-D)"
    assert channel.tf_mode == "2d" and dock.pages.currentIndex() == 1
    assert not dock.mode_points.isVisible()  # the 1-D controls make way
    assert dock.editor_2d._histogram is not None
    # Issue 25: the channel used to vanish until a region was added. It starts from the
    # 1-D TF's equivalent (a painted layer constant along the gradient axis) instead.
    assert channel.tf2d.paint is not None and not channel.tf2d.paint.empty
    assert not channel.tf2d.primitives
    same = shot(window)
    assert np.abs(same - before).mean() < 2.0, np.abs(same - before).mean()
    window.undo_action.trigger()  # one step: back to 1-D, with no paint
    assert channel.tf_mode == "1d" and channel.tf2d.paint is None
    window.redo_action.trigger()
    assert channel.tf_mode == "2d" and channel.tf2d.paint is not None
    dock.clear_paint.click()
    empty = shot(window)
    assert drawn(empty, window) < 0.002  # no region, no paint: nothing is classified visible

    dock.add_rectangle.click()
    prim = channel.tf2d.primitives[0]
    assert dock.editor_2d.selected == 0 and prim.kind == "rectangle"
    dock.primitive_opacity.setValue(0.9)
    dock.primitive_soft.setValue(0.0)
    assert channel.tf2d.primitives[0].opacity == 0.9

    # Stretch it over every value and gradient by dragging two corner handles.
    editor = dock.editor_2d
    (v0, v1), (g0, g1) = editor.axes
    handles = editor.handle_points(channel.tf2d.primitives[0])
    drag(qtbot, editor, handles["v0g1"].toPoint(), editor.to_pixel(v0, g1).toPoint())
    handles = editor.handle_points(channel.tf2d.primitives[0])
    drag(qtbot, editor, handles["v1g0"].toPoint(), editor.to_pixel(v1, g0).toPoint())
    rect = channel.tf2d.primitives[0]
    assert rect.value_range[0] == pytest.approx(v0, abs=0.02 * (v1 - v0))
    assert rect.value_range[1] == pytest.approx(v1, abs=0.02 * (v1 - v0))
    assert rect.gradient_range[1] == pytest.approx(g1, abs=0.02 * (g1 - g0))
    full = shot(window)
    assert drawn(full, window) > 0.03

    # Move it above every gradient but the steepest: most of the object disappears.
    middle = editor.to_pixel(0.5 * (v0 + v1), 0.5 * (g0 + g1)).toPoint()
    drag(qtbot, editor, middle, editor.to_pixel(0.5 * (v0 + v1), g1 * 1.45).toPoint())
    assert channel.tf2d.primitives[0].gradient_range[0] > 0.3 * g1
    steep_only = shot(window)
    assert drawn(steep_only, window) < 0.7 * drawn(full, window)

    # One drag is one undo step: undo returns to the full rectangle's pixels.
    window.undo_action.trigger()
    assert channel.tf2d.primitives[0].gradient_range[0] == pytest.approx(0.0, abs=1e-9)
    assert np.abs(shot(window) - full).mean() < 1.0

    # Back to 1-D: the 2-D regions are kept, the 1-D image comes back.
    dock.dimension_combo.setCurrentIndex(0)
    assert channel.tf_mode == "1d" and len(channel.tf2d.primitives) == 1
    assert np.abs(shot(window) - before).mean() < 1.0


def test_model_to_widget(window) -> None:
    dock, channel = window.tf_dock, window.model.channels[0]
    channel.tf2d = TransferFunction2D(primitives=[
        TFPrimitive(value_range=(100.0, 900.0), gradient_range=(0.0, 50.0), opacity=0.4,
                    color=(0.0, 1.0, 0.0)),
        TFPrimitive(kind="triangle", value_range=(500.0, 1500.0), gradient_range=(10.0, 300.0),
                    soft_edge=0.5)])
    channel.tf_mode = "2d"
    assert dock.dimension_combo.currentIndex() == 1 and dock.pages.currentIndex() == 1
    assert dock.editor_2d._tf is channel.tf2d
    dock.editor_2d.select(0)
    assert dock.primitive_opacity.value() == pytest.approx(0.4)
    assert dock.primitive_color.rgb() == (0.0, 1.0, 0.0)
    channel.tf2d.primitives[0].opacity = 0.75
    assert dock.primitive_opacity.value() == pytest.approx(0.75)
    poly = dock.editor_2d.primitive_polygon(channel.tf2d.primitives[1])
    assert poly.size() == 3  # drawn as a triangle
    channel.tf2d.primitives = channel.tf2d.primitives[1:]
    assert dock.editor_2d.selected in (-1, 0) and len(dock.editor_2d._tf.primitives) == 1
    full_top = dock.editor_2d.axes[1][1]
    assert dock.gradient_top.value() == pytest.approx(full_top, rel=1e-3)
    assert not dock.gradient_full.isEnabled()
    channel.tf2d.gradient_max = 100.0  # zoom the gradient axis from the model …
    assert dock.editor_2d.axes[1] == (0.0, 100.0) and dock.gradient_top.value() == 100.0
    dock.gradient_full.click()  # … and back from the widget
    assert channel.tf2d.gradient_max is None
    assert dock.editor_2d.axes[1][1] == pytest.approx(full_top)
    dock.gradient_top.setValue(50.0)
    assert channel.tf2d.gradient_max == 50.0
    channel.tf_mode = "1d"
    assert dock.dimension_combo.currentIndex() == 0 and dock.pages.currentIndex() == 0


def test_colour_delete_and_proposed_classes_are_undoable(window, monkeypatch) -> None:
    dock, channel = window.tf_dock, window.model.channels[0]
    dock.dimension_combo.setCurrentIndex(1)
    dock.add_triangle.click()
    monkeypatch.setattr(dock_base, "pick_color", lambda parent, initial, title: (1.0, 0.0, 0.5))
    dock.primitive_color.click()
    assert channel.tf2d.primitives[0].color == (1.0, 0.0, 0.5)
    dock.delete_primitive.click()
    assert channel.tf2d.primitives == []

    count = window.recorder.stack.count()
    dock.stf_radius.setValue(0.1)
    dock.stf_opacity.setValue(2.0)
    dock.propose_button.click()
    proposed = channel.tf2d.primitives
    assert len(proposed) > 0 and len({p.color for p in proposed}) >= 2
    assert len(proposed) == len({p.color for p in proposed})  # one region per class
    assert max(p.opacity for p in proposed) > min(p.opacity for p in proposed)
    assert drawn(shot(window), window) > 0.01
    assert window.recorder.stack.count() == count + 1
    window.undo_action.trigger()
    assert channel.tf2d.primitives == []


def test_paint_stroke_to_model_to_pixels_erase_and_undo(window, qtbot, monkeypatch) -> None:
    dock, channel = window.tf_dock, window.model.channels[0]
    dock.dimension_combo.setCurrentIndex(1)
    dock.clear_paint.click()  # the 1-D TF's equivalent it starts from
    empty = shot(window)
    assert drawn(empty, window) < 0.002
    editor = dock.editor_2d
    (v0, v1), (g0, g1) = editor.axes
    dock.tool_group.button(1).click()
    assert editor.tool == "paint"
    monkeypatch.setattr(dock_base, "pick_color", lambda parent, initial, title: (1.0, 0.0, 0.0))
    dock.brush_color.click()
    dock.brush_opacity.setValue(0.9)
    dock.brush_size.setValue(20.0)
    count = window.recorder.stack.count()
    start = editor.to_pixel(v0 + 0.3 * (v1 - v0), g0 + 0.08 * (g1 - g0)).toPoint()
    end = editor.to_pixel(v0 + 0.9 * (v1 - v0), g0 + 0.08 * (g1 - g0)).toPoint()
    drag(qtbot, editor, start, end)
    paint = channel.tf2d.paint
    assert paint is not None
    assert paint.value_range == (v0, v1) and paint.gradient_range == (g0, g1)  # the axes
    assert window.recorder.stack.count() == count + 1  # the throttled stroke: one step
    pixels = paint.pixels().copy()
    x, y = paint.pixel_coords(v0 + 0.6 * (v1 - v0), g0 + 0.08 * (g1 - g0))
    assert pixels[round(float(y)), round(float(x))].tolist() == [255, 0, 0, round(0.9 * 255)]
    assert pixels[40:, :, 3].max() == 0 and pixels[:, :15, 3].max() == 0  # away from it
    painted = shot(window)
    assert drawn(painted, window) > 0.01
    changed = np.abs(painted - empty).max(axis=-1) > 12
    red, green = painted[..., 0][changed], painted[..., 1][changed]
    assert red.mean() > 2 * green.mean()  # the brush's colour

    # The eraser along the same path, wider: the layer is blank again, the image as before.
    dock.tool_group.button(2).click()
    dock.brush_size.setValue(30.0)
    drag(qtbot, editor, start, end)
    assert channel.tf2d.paint.pixels().max() == 0
    assert np.abs(shot(window) - empty).max() == 0
    # Undo: one step back to the painted pixels exactly, one more to no layer at all.
    window.undo_action.trigger()
    np.testing.assert_array_equal(channel.tf2d.paint.pixels(), pixels)
    window.undo_action.trigger()
    assert channel.tf2d.paint is None
    assert not dock.clear_paint.isEnabled()


def test_model_paint_shows_in_the_editor(window) -> None:
    from vtkvol.model.tf_paint import TFPaintLayer, apply_stroke, stroke_mask

    dock, channel = window.tf_dock, window.model.channels[0]
    channel.tf_mode = "2d"
    editor = dock.editor_2d
    (v0, v1), (g0, g1) = editor.axes
    layer = TFPaintLayer.blank((v0, v1), (g0, g1))
    layer = layer.with_pixels(apply_stroke(layer.pixels(), stroke_mask(layer.shape, [(64, 64)],
                                                                        10.0), (1, 0, 0), 0.9))
    channel.tf2d.paint = layer
    assert editor._tf.paint is layer and dock.clear_paint.isEnabled()
    image = editor.grab().toImage()
    centre = editor.to_pixel(0.5 * (v0 + v1), 0.5 * (g0 + g1)).toPoint()
    far = editor.to_pixel(v0 + 0.1 * (v1 - v0), g0 + 0.9 * (g1 - g0)).toPoint()
    dpr = image.devicePixelRatio()
    inside = image.pixelColor(round(centre.x() * dpr), round(centre.y() * dpr))
    outside = image.pixelColor(round(far.x() * dpr), round(far.y() * dpr))
    assert inside.red() > 150 and inside.green() < 90 and inside.blue() < 90
    assert not (outside.red() > 150 and outside.green() < 90)
    dock.clear_paint.click()
    assert channel.tf2d.paint is None and editor._tf.paint is None
