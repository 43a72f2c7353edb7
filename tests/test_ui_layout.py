"""The main window's layout at the default 1280 × 820 and at 1024 × 700 (issue 25): no widget
cut by its dock or overlapping a sibling, no horizontal scroll bar in a dock, the status bar's
labels side by side. Geometry, not pixels. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import pytest
from PySide6.QtCore import QPoint, QRect
from PySide6.QtWidgets import (
    QAbstractButton,
    QAbstractScrollArea,
    QAbstractSpinBox,
    QComboBox,
    QDockWidget,
    QLabel,
    QScrollArea,
    QWidget,
)

pytestmark = pytest.mark.gui

LEAVES = (QLabel, QAbstractButton, QAbstractSpinBox, QComboBox)


def _global_rect(widget: QWidget) -> QRect:
    # QWidget's own methods: a dock may name an attribute "size".
    return QRect(QWidget.mapToGlobal(widget, QPoint(0, 0)), QWidget.size(widget))


def _clip_rect(widget: QWidget, top: QWidget) -> QRect:
    """The part of the screen where ``widget`` can show: its ancestors' rectangles up to
    ``top`` intersected (a scroll area's viewport clips what scrolls inside it)."""
    rect = _global_rect(top)
    parent = widget.parentWidget()
    while parent is not None and parent is not top:
        if not isinstance(parent, QScrollArea):
            rect = rect.intersected(_global_rect(parent))
        parent = parent.parentWidget()
    return rect


def layout_problems(window) -> list[str]:
    """Every clipped or overlapping control in the visible docks and the status bar."""
    problems: list[str] = []
    for dock in window.findChildren(QDockWidget):
        if not dock.isVisible() or dock.visibleRegion().isEmpty():
            continue  # a tab behind another
        name = dock.windowTitle()
        for area in dock.findChildren(QAbstractScrollArea):
            if area.isVisible() and isinstance(area, QScrollArea) and \
                    area.horizontalScrollBar().isVisible():
                problems.append(f"{name}: horizontal scroll bar")
        for leaf in dock.findChildren(QWidget):
            if not isinstance(leaf, LEAVES) or not leaf.isVisible():
                continue
            if any(isinstance(p, QAbstractScrollArea) and not isinstance(p, QScrollArea)
                   for p in _ancestors(leaf, dock)):
                continue  # parts of a list or table, which scroll
            scroller = next((p for p in _ancestors(leaf, dock) if isinstance(p, QScrollArea)),
                            None)
            rect = _global_rect(leaf)
            if scroller is not None:
                # Inside a scroll area: only the width must fit (it scrolls vertically).
                view = _global_rect(scroller.viewport())
                if rect.left() < view.left() - 1 or rect.right() > view.right() + 1:
                    problems.append(f"{name}: {_label(leaf)} wider than its dock")
                continue
            if not _clip_rect(leaf, dock).contains(rect):
                problems.append(f"{name}: {_label(leaf)} clipped ({rect} outside "
                                f"{_clip_rect(leaf, dock)})")
            elif leaf.height() < leaf.minimumSizeHint().height() - 1:
                problems.append(f"{name}: {_label(leaf)} squeezed to {leaf.height()} px")
    status = window.statusBar()
    shown = [w for w in status.findChildren(QWidget) if isinstance(w, LEAVES) and
             w.isVisible() and w.parentWidget() is status]
    for i, a in enumerate(shown):
        if not _global_rect(status).contains(_global_rect(a)):
            problems.append(f"status bar: {_label(a)} outside the bar")
        for b in shown[i + 1:]:
            if _global_rect(a).intersects(_global_rect(b)):
                problems.append(f"status bar: {_label(a)} overlaps {_label(b)}")
    return problems


def _ancestors(widget: QWidget, top: QWidget):
    parent = widget.parentWidget()
    while parent is not None and parent is not top:
        yield parent
        parent = parent.parentWidget()


def _label(widget: QWidget) -> str:
    text = widget.text() if hasattr(widget, "text") else ""
    return f"{type(widget).__name__} {widget.objectName() or text[:30]!r}"


@pytest.mark.parametrize("size", [(1280, 820), (1024, 700)])
def test_no_clipped_or_overlapping_widgets(qapp, qtbot, tmp_path, small_volume_file, size):
    from PySide6.QtCore import QSettings

    from vtkvol.ui.app import MainWindow, configure_gl_platform

    configure_gl_platform(qapp)
    window = MainWindow(settings=QSettings(str(tmp_path / "s.ini"),
                                           QSettings.Format.IniFormat))
    window.model.render.sample_distance = 1.0
    window.resize(*size)
    window.show()
    qtbot.waitExposed(window)
    with qtbot.waitSignal(window.dataShown, timeout=60_000):
        window.open_path(small_volume_file)
    qtbot.wait(200)
    problems = []
    for dock in window.findChildren(QDockWidget):
        dock.raise_()  # each tab in turn
        qtbot.wait(20)
        problems += [p for p in layout_problems(window) if p.startswith(dock.windowTitle())]
    tf = window.tf_dock
    tf.raise_()
    tf.dimension_combo.setCurrentIndex(1)  # the 2-D editor's rows
    qtbot.wait(50)
    problems += layout_problems(window)
    window.close()
    assert not sorted(set(problems)), "\n".join(sorted(set(problems)))


def test_status_bar_leaves_room_for_messages(opened_window):
    """Issue 25: the data label's long line ran into the frame label and truncated the
    messages. It asks for at most 420 px and draws the rest as "…"; text() and the tooltip
    keep it whole."""
    window = opened_window
    window.resize(1024, 700)
    label = window.data_label
    label.setText("a-very-long-file-name-" * 12 + " — 64×64×64, uint16, voxel 1×1×1 µm")
    window.statusBar().showMessage("Opened with notes")
    QWidget.adjustSize(window.statusBar())
    assert label.sizeHint().width() <= 420
    assert label.elided_text().endswith("…") and label.text().endswith("µm")
    window._show_data_info()
    assert "nuclei.npy" in label.text()
