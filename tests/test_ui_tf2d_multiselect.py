"""Issue 25 §3: the 2-D TF editor selects several regions (Shift/Ctrl-click, rubber band) and
deletes them together, in one undo step (needs X through pytest-xvfb, and GL)."""

from __future__ import annotations

from typing import Any

import pytest
from PySide6.QtCore import QPoint, Qt

from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D
from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


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


def four_regions(window) -> list[TFPrimitive]:
    """Channel 0 in 2-D mode with four small rectangles in the four quarters of the editor's
    axes (two in the left half, two in the right half)."""
    dock, channel = window.tf_dock, window.model.channels[0]
    dock.dimension_combo.setCurrentIndex(1)
    (v0, v1), (g0, g1) = dock.axes_2d()
    dv, dg = (v1 - v0) / 10.0, (g1 - g0) / 10.0
    prims = [TFPrimitive(kind="rectangle", value_range=(v0 + a * dv, v0 + (a + 2) * dv),
                         gradient_range=(g0 + b * dg, g0 + (b + 2) * dg), color=color,
                         opacity=0.3)
             for (a, b), color in zip([(1, 1), (1, 6), (6, 1), (6, 6)],
                                      [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0),
                                       (1.0, 1.0, 0.0)], strict=True)]
    channel.tf2d = TransferFunction2D(primitives=prims)
    window.recorder.reset()
    return prims


def centre(editor, prim: TFPrimitive) -> QPoint:
    return editor.primitive_polygon(prim).boundingRect().center().toPoint()


def test_shift_and_ctrl_click_select_several_and_delete_removes_them_in_one_step(window, qtbot):
    dock, channel = window.tf_dock, window.model.channels[0]
    prims = four_regions(window)
    editor = dock.editor_2d
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton, pos=centre(editor, prims[0]))
    assert editor.selected_indices == (0,)
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.ShiftModifier,
                     pos=centre(editor, prims[3]))
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.ControlModifier,
                     pos=centre(editor, prims[2]))
    assert editor.selected_indices == (0, 2, 3)
    assert editor.selected == 2  # the last clicked gets the handles and the controls
    # Ctrl-click on a selected region takes it out again.
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.ControlModifier,
                     pos=centre(editor, prims[2]))
    assert editor.selected_indices == (0, 3)
    assert dock.delete_primitive.isEnabled()
    count = window.recorder.stack.count()
    dock.delete_primitive.click()
    assert [p.color for p in channel.tf2d.primitives] == [prims[1].color, prims[2].color]
    assert editor.selected_indices == ()
    assert window.recorder.stack.count() == count + 1  # one undo step for both
    window.undo_action.trigger()
    assert [p.color for p in channel.tf2d.primitives] == [p.color for p in prims]


def test_rubber_band_selects_what_it_touches_and_the_delete_key_removes_it(window, qtbot):
    dock, channel = window.tf_dock, window.model.channels[0]
    prims = four_regions(window)
    editor = dock.editor_2d
    plot = editor.plot_rect()
    # A band over the left half (from empty space at the top left): regions 0 and 1.
    start = QPoint(round(plot.left() + 3), round(plot.top() + 3))
    end = QPoint(round(plot.center().x()), round(plot.bottom() - 3))
    qtbot.mousePress(editor, Qt.MouseButton.LeftButton, pos=start)
    qtbot.mouseMove(editor, QPoint((start.x() + end.x()) // 2, (start.y() + end.y()) // 2))
    qtbot.mouseMove(editor, end)
    qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, pos=end)
    assert editor.selected_indices == (0, 1)
    assert [p.value_range for p in channel.tf2d.primitives] == [p.value_range for p in prims]
    # Shift adds a second band's regions (the top right one) to the selection.
    start2 = QPoint(round(plot.right() - 3), round(plot.top() + 3))
    end2 = QPoint(round(plot.center().x() + 5), round(plot.center().y() - 5))
    qtbot.mousePress(editor, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.ShiftModifier,
                     pos=start2)
    qtbot.mouseMove(editor, end2)
    qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.ShiftModifier,
                       pos=end2)
    assert editor.selected_indices == (0, 1, 3)
    count = window.recorder.stack.count()
    editor.setFocus()
    qtbot.keyClick(editor, Qt.Key.Key_Delete)
    assert [p.color for p in channel.tf2d.primitives] == [prims[2].color]
    assert window.recorder.stack.count() == count + 1
    window.undo_action.trigger()
    assert len(channel.tf2d.primitives) == 4
    # A plain click in empty space clears the selection; Delete then deletes nothing.
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton, pos=start)
    assert editor.selected_indices == ()
    qtbot.keyClick(editor, Qt.Key.Key_Delete)
    assert len(channel.tf2d.primitives) == 4
