"""The 2-D transfer-function editor: primitives and paint over the (value, |∇I|) histogram.

A view of one :class:`~vtkvol.model.transfer_function.TransferFunction2D`: the channel's 2-D
histogram (log counts, grey) with the rasterised TF (primitives and painted layer) over it,
each primitive's outline in its colour and the painted layer's box dotted; the selected
primitive has four corner handles. With the ``"regions"`` tool, press inside a primitive to
select and move it, drag a handle of the selected one to resize it. Several regions can be
selected together (issue 25): Shift- or Ctrl-click adds or removes one, a drag from empty
space selects every region its rubber band touches (with Shift/Ctrl: adds them), and Delete
or Backspace asks to delete the selection (``deleteRequested``; the dock does it, one undo
step). With ``"paint"`` or
``"erase"``, a drag is a brush stroke (a circle of the brush's size follows the pointer).
The widget only reports gestures (``selectionChanged``, ``primitiveMoved``, ``strokeMoved``,
``editStarted``/``editFinished``); the dock writes the model. Moves and strokes are throttled
like the 1-D editor's, so a drag re-rasterises at most every :data:`THROTTLE_MS`.

Coordinates: values in data units along x, gradient magnitude |∇I| in data units per µm
along y (0 at the bottom).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt, QTimer, Signal
from PySide6.QtGui import (
    QColor,
    QImage,
    QKeyEvent,
    QMouseEvent,
    QPainter,
    QPaintEvent,
    QPen,
    QPolygonF,
)
from PySide6.QtWidgets import QSizePolicy, QWidget

from vtkvol.model.tf_paint import PAINT_SHAPE
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D
from vtkvol.ui.docks.function_editor import format_value

THROTTLE_MS = 60
HANDLE_PX = 7  #: how close (px) to a corner a press grabs the handle
_MARGINS = (46, 8, 8, 22)  #: left, top, right, bottom (px)
_OVERLAY_SHAPE = (96, 192)  #: rows × columns of the TF preview drawn over the histogram
Range = tuple[float, float]
#: The editor's tools: move/resize primitives, or brush into the painted layer.
TOOLS = ("regions", "paint", "erase")


class TF2DEditor(QWidget):
    """Edits primitives in (value, gradient) space; see the module docstring."""

    selectionChanged = Signal(int)  #: index of the selected primitive, −1 for none
    #: Delete or Backspace with regions selected (the dock deletes ``selected_indices``).
    deleteRequested = Signal()
    primitiveMoved = Signal(int, object, object)  #: index, value range, gradient range
    #: The stroke so far (paint/erase tools): a list of (value, gradient) points, data units
    #: and data units per µm; emitted throttled during the drag and once at its end.
    strokeMoved = Signal(object)
    editStarted = Signal()
    editFinished = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(260, 160)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setMouseTracking(True)
        self._values: Range = (0.0, 1.0)
        self._gradients: Range = (0.0, 1.0)
        self._tf = TransferFunction2D()
        self._histogram: QImage | None = None
        self._overlay: QImage | None = None
        self._selected = -1
        #: Every selected primitive (``_selected``, the one with handles, among them).
        self._selection: list[int] = []
        #: Rubber band in progress: (press point, current point, selection before it), px.
        self._band: tuple[QPointF, QPointF, list[int]] | None = None
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)  # Delete reaches the editor
        self._drag: tuple[str, int, QPointF, Range, Range] | None = None
        self._pending: tuple[int, Range, Range] | None = None
        self._throttle = QTimer(self)
        self._throttle.setSingleShot(True)
        self._throttle.setInterval(THROTTLE_MS)
        self._throttle.timeout.connect(self._flush)
        self._tool = "regions"
        self._brush_radius = 4.0  # layer pixels
        self._stroke: list[tuple[float, float]] | None = None
        self._stroke_dirty = False
        self._pointer: QPointF | None = None

    def sizeHint(self) -> QSize:
        return QSize(420, 220)

    # -- state ----------------------------------------------------------------------------------
    @property
    def axes(self) -> tuple[Range, Range]:
        return self._values, self._gradients

    @property
    def selected(self) -> int:
        return self._selected

    @property
    def selected_indices(self) -> tuple[int, ...]:
        """Every selected primitive, in ascending order (empty: none)."""
        return tuple(sorted(self._selection))

    @property
    def dragging(self) -> bool:
        return self._drag is not None

    @property
    def tool(self) -> str:
        return self._tool

    def set_tool(self, tool: str) -> None:
        """``"regions"`` (move and resize primitives), ``"paint"`` or ``"erase"``."""
        if tool not in TOOLS:
            raise ValueError(f"unknown 2-D editor tool {tool!r} (one of {', '.join(TOOLS)})")
        self._tool = tool
        self.setCursor(Qt.CursorShape.CrossCursor if tool != "regions"
                       else Qt.CursorShape.ArrowCursor)
        self.update()

    def set_brush_radius(self, radius: float) -> None:
        """Brush radius in pixels of the painted layer (drawn as the pointer's circle)."""
        self._brush_radius = float(radius)
        self.update()

    def brush_radii_px(self) -> tuple[float, float]:
        """The brush's half-width and half-height on screen (px): layer pixels over the
        layer's box (or, before anything is painted, the box a first stroke creates)."""
        r = self.plot_rect()
        paint = self._tf.paint
        (v0, v1), (g0, g1) = self._values, self._gradients
        if paint is not None:
            (pv0, pv1), (pg0, pg1) = paint.value_range, paint.gradient_range
            h, w = paint.shape
        else:
            (pv0, pv1), (pg0, pg1), (h, w) = (v0, v1), (g0, g1), PAINT_SHAPE
        return (self._brush_radius * (pv1 - pv0) / w / (v1 - v0) * r.width(),
                self._brush_radius * (pg1 - pg0) / h / (g1 - g0) * r.height())

    def set_axes(self, values: Range, gradients: Range) -> None:
        """Data units along x, data units per µm along y."""
        if values[1] <= values[0]:
            values = (values[0], values[0] + 1.0)
        if gradients[1] <= gradients[0]:
            gradients = (gradients[0], gradients[0] + 1.0)
        if (values, gradients) != (self._values, self._gradients):
            self._values, self._gradients = values, gradients
            self._render_overlay()
            self.update()

    def set_histogram(self, counts: np.ndarray | None) -> None:
        """Counts ``(gradient bins, value bins)`` over the axes, shown as log(1 + n)."""
        if counts is None or counts.size == 0:
            self._histogram = None
        else:
            level = np.log1p(np.asarray(counts, dtype=np.float64))
            top = level.max() or 1.0
            grey = (40 + 170 * level / top).astype(np.uint8)[::-1]  # row 0 = top of image
            grey = np.ascontiguousarray(grey)
            h, w = grey.shape
            self._histogram = QImage(grey.data, w, h, w, QImage.Format.Format_Grayscale8).copy()
        self.update()

    def set_function(self, tf: TransferFunction2D) -> None:
        self._tf = tf
        if self._selected >= len(tf.primitives):
            self._selected = -1
        self._selection = [i for i in self._selection if i < len(tf.primitives)]
        if self._drag is None:
            self._render_overlay()
        self.update()

    def select(self, index: int) -> None:
        """Select primitive ``index`` alone (−1: nothing)."""
        index = index if 0 <= index < len(self._tf.primitives) else -1
        self.set_selection([index] if index >= 0 else [])

    def set_selection(self, indices: list[int] | tuple[int, ...], current: int | None = None
                      ) -> None:
        """Select ``indices`` (out-of-range ones are ignored); ``current`` (default: the last
        of them) gets the handles and the dock's colour/opacity controls."""
        count = len(self._tf.primitives)
        chosen = list(dict.fromkeys(i for i in indices if 0 <= i < count))
        if current is None or current not in chosen:
            current = chosen[-1] if chosen else -1
        changed = current != self._selected or sorted(chosen) != sorted(self._selection)
        self._selection = chosen
        self._selected = current
        if changed:
            self.selectionChanged.emit(current)
            self.update()

    def _band_rect(self) -> QRectF:
        assert self._band is not None
        a, b = self._band[0], self._band[1]
        return QRectF(a, b).normalized()

    def _touched_by_band(self) -> list[int]:
        """The primitives whose outline's box meets the rubber band."""
        band = self._band_rect()
        return [i for i, prim in enumerate(self._tf.primitives)
                if self.primitive_polygon(prim).boundingRect().intersects(band)]

    def _render_overlay(self) -> None:
        if not self._tf.primitives and self._tf.paint is None:
            self._overlay = None
            return
        table = self._tf.table(self._values, self._gradients, _OVERLAY_SHAPE)
        rgba = np.empty((*table.shape[:2], 4), np.uint8)
        rgba[..., :3] = np.clip(table[..., :3] * 255, 0, 255)
        # Low opacities matter (microscopy): show α^½ so that 0.05 is still visible.
        rgba[..., 3] = np.clip(np.sqrt(table[..., 3]) * 200, 0, 255)
        rgba = np.ascontiguousarray(rgba[::-1])
        h, w = rgba.shape[:2]
        self._overlay = QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy()

    # -- geometry -------------------------------------------------------------------------------
    def plot_rect(self) -> QRectF:
        left, top, right, bottom = _MARGINS
        return QRectF(left, top, max(1, self.width() - left - right),
                      max(1, self.height() - top - bottom))

    def to_pixel(self, value: float, gradient: float) -> QPointF:
        r = self.plot_rect()
        (v0, v1), (g0, g1) = self._values, self._gradients
        return QPointF(r.left() + (value - v0) / (v1 - v0) * r.width(),
                       r.bottom() - (gradient - g0) / (g1 - g0) * r.height())

    def from_pixel(self, point: QPointF) -> tuple[float, float]:
        r = self.plot_rect()
        (v0, v1), (g0, g1) = self._values, self._gradients
        value = v0 + (point.x() - r.left()) / r.width() * (v1 - v0)
        gradient = g0 + (r.bottom() - point.y()) / r.height() * (g1 - g0)
        return value, gradient

    def primitive_polygon(self, prim: TFPrimitive) -> QPolygonF:
        (v0, v1), (g0, g1) = prim.value_range, prim.gradient_range
        if prim.kind == "triangle":
            pts = [((v0 + v1) / 2, g0), (v1, g1), (v0, g1)]
        else:
            pts = [(v0, g0), (v1, g0), (v1, g1), (v0, g1)]
        return QPolygonF([self.to_pixel(v, g) for v, g in pts])

    def handle_points(self, prim: TFPrimitive) -> dict[str, QPointF]:
        """Corner handles of a primitive's box, by name (``"v0g0"`` … ``"v1g1"``)."""
        (v0, v1), (g0, g1) = prim.value_range, prim.gradient_range
        return {f"v{i}g{j}": self.to_pixel(v, g)
                for i, v in enumerate((v0, v1)) for j, g in enumerate((g0, g1))}

    def _hit(self, pos: QPointF) -> tuple[str, int]:
        """("handle:<name>", i), ("move", i) or ("none", −1) under ``pos``."""
        prims = self._tf.primitives
        if 0 <= self._selected < len(prims):
            for name, p in self.handle_points(prims[self._selected]).items():
                if abs(p.x() - pos.x()) <= HANDLE_PX and abs(p.y() - pos.y()) <= HANDLE_PX:
                    return f"handle:{name}", self._selected
        for i in range(len(prims) - 1, -1, -1):  # the topmost (last drawn) first
            poly = self.primitive_polygon(prims[i])
            if poly.boundingRect().adjusted(-2, -2, 2, 2).contains(pos) and (
                    poly.containsPoint(pos, Qt.FillRule.OddEvenFill)
                    or prims[i].kind == "rectangle"):
                return "move", i
        return "none", -1

    # -- painting -------------------------------------------------------------------------------
    def paintEvent(self, event: QPaintEvent) -> None:
        painter = QPainter(self)
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        painter.fillRect(self.rect(), self.palette().window())
        r = self.plot_rect()
        painter.fillRect(r, QColor(20, 20, 24))
        if self._histogram is not None:
            painter.drawImage(r, self._histogram)
        if self._overlay is not None:
            painter.drawImage(r, self._overlay)
        painter.setClipRect(r)
        for i, prim in enumerate(self._tf.primitives):
            color = QColor.fromRgbF(*prim.color)
            chosen = i in self._selection
            pen = QPen(color, 2.0 if chosen else 1.2)
            if not chosen:
                pen.setStyle(Qt.PenStyle.DashLine)
            painter.setPen(pen)
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.drawPolygon(self.primitive_polygon(prim))
        if self._tf.paint is not None:  # the painted layer's box: strokes reach no further
            (pv0, pv1), (pg0, pg1) = self._tf.paint.value_range, self._tf.paint.gradient_range
            pen = QPen(QColor(200, 200, 200), 1.0)
            pen.setStyle(Qt.PenStyle.DotLine)
            painter.setPen(pen)
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.drawRect(QRectF(self.to_pixel(pv0, pg1), self.to_pixel(pv1, pg0)))
        if self._tool != "regions" and self._pointer is not None:
            rx, ry = self.brush_radii_px()
            painter.setPen(QPen(QColor(255, 255, 255), 1.0))
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.drawEllipse(self._pointer, rx, ry)
        if self._band is not None:
            pen = QPen(QColor(255, 255, 255), 1.0)
            pen.setStyle(Qt.PenStyle.DashLine)
            painter.setPen(pen)
            painter.setBrush(QColor(255, 255, 255, 40))
            painter.drawRect(self._band_rect())
        if 0 <= self._selected < len(self._tf.primitives):
            painter.setPen(QPen(QColor(255, 255, 255), 1.0))
            painter.setBrush(QColor(255, 255, 255, 200))
            for p in self.handle_points(self._tf.primitives[self._selected]).values():
                painter.drawRect(QRectF(p.x() - 3, p.y() - 3, 6, 6))
        painter.setClipping(False)
        painter.setPen(QPen(self.palette().windowText().color(), 1.0))
        painter.setBrush(Qt.BrushStyle.NoBrush)
        painter.drawRect(r)
        (v0, v1), (g0, g1) = self._values, self._gradients
        fm = painter.fontMetrics()
        painter.drawText(QPointF(r.left(), r.bottom() + fm.ascent() + 3), format_value(v0))
        text = format_value(v1)
        painter.drawText(QPointF(r.right() - fm.horizontalAdvance(text),
                                 r.bottom() + fm.ascent() + 3), text)
        title = "value"
        painter.drawText(QPointF(r.center().x() - fm.horizontalAdvance(title) / 2,
                                 r.bottom() + fm.ascent() + 3), title)
        top = format_value(g1)
        painter.drawText(QPointF(r.left() - 4 - fm.horizontalAdvance(top),
                                 r.top() + fm.ascent()), top)
        bottom = format_value(g0)
        painter.drawText(QPointF(r.left() - 4 - fm.horizontalAdvance(bottom), r.bottom()),
                         bottom)
        painter.save()
        painter.translate(r.left() - 8, r.center().y())
        painter.rotate(-90)
        label = "|∇I| /µm"
        painter.drawText(QPointF(-fm.horizontalAdvance(label) / 2, 0), label)
        painter.restore()
        painter.end()

    # -- mouse ----------------------------------------------------------------------------------
    def mousePressEvent(self, event: QMouseEvent) -> None:
        if event.button() != Qt.MouseButton.LeftButton:
            return
        pos = event.position()
        if self._tool != "regions":
            self._stroke = [self.from_pixel(pos)]
            self._stroke_dirty = True
            self.editStarted.emit()
            self._flush()  # a click paints one dab at once
            return
        kind, index = self._hit(pos)
        extend = bool(event.modifiers() & (Qt.KeyboardModifier.ShiftModifier
                                           | Qt.KeyboardModifier.ControlModifier))
        if index < 0:  # empty space: a rubber band (adding to the selection with a modifier)
            before = list(self._selection) if extend else []
            self._band = (pos, pos, before)
            self.set_selection(before)
            return
        if extend:  # add or remove one region; no drag
            if index in self._selection:
                self.set_selection([i for i in self._selection if i != index])
            else:
                self.set_selection([*self._selection, index], current=index)
            return
        self.select(index)
        prim = self._tf.primitives[index]
        self._drag = (kind, index, pos, prim.value_range, prim.gradient_range)
        self.editStarted.emit()

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        if self._tool != "regions":
            self._pointer = event.position()
            self.update()
            if self._stroke is not None:
                self._stroke.append(self.from_pixel(event.position()))
                self._stroke_dirty = True
                if not self._throttle.isActive():
                    self._throttle.start()
            return
        if self._band is not None:
            start, _, before = self._band
            self._band = (start, event.position(), before)
            self.set_selection([*before, *self._touched_by_band()])
            self.update()
            return
        if self._drag is None:
            kind, _ = self._hit(event.position())
            self.setCursor(Qt.CursorShape.SizeFDiagCursor if kind.startswith("handle")
                           else Qt.CursorShape.SizeAllCursor if kind == "move"
                           else Qt.CursorShape.ArrowCursor)
            return
        kind, index, start, (v0, v1), (g0, g1) = self._drag
        a = self.from_pixel(start)
        b = self.from_pixel(event.position())
        dv, dg = b[0] - a[0], b[1] - a[1]
        if kind == "move":
            dg = max(dg, -g0) if g0 >= 0 else dg  # do not push a box below |∇I| = 0
            values, gradients = (v0 + dv, v1 + dv), (g0 + dg, g1 + dg)
        else:
            name = kind.split(":", 1)[1]
            vs, gs = [v0, v1], [g0, g1]
            vs[int(name[1])] += dv
            gs[int(name[3])] += dg
            values = (min(vs), max(vs))
            gradients = (max(0.0, min(gs)), max(gs))
            span_v = 1e-3 * (self._values[1] - self._values[0])
            span_g = 1e-3 * (self._gradients[1] - self._gradients[0])
            if values[1] - values[0] < span_v or gradients[1] - gradients[0] < span_g:
                return  # a primitive keeps a size
        self._pending = (index, values, gradients)
        if not self._throttle.isActive():
            self._throttle.start()

    def leaveEvent(self, event) -> None:
        self._pointer = None
        self.update()
        super().leaveEvent(event)

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.LeftButton and self._stroke is not None:
            self.mouseMoveEvent(event)
            self._throttle.stop()
            self._flush()
            self._stroke = None
            self.editFinished.emit()
            return
        if event.button() == Qt.MouseButton.LeftButton and self._band is not None:
            self.mouseMoveEvent(event)
            self._band = None
            self.update()
            return
        if event.button() != Qt.MouseButton.LeftButton or self._drag is None:
            return
        self.mouseMoveEvent(event)
        self._throttle.stop()
        self._flush()
        self._drag = None
        self._render_overlay()
        self.update()
        self.editFinished.emit()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        if event.key() in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace) and self._selection:
            self.deleteRequested.emit()
            return
        super().keyPressEvent(event)

    def _flush(self) -> None:
        if self._stroke is not None and self._stroke_dirty:
            self._stroke_dirty = False
            self.strokeMoved.emit(list(self._stroke))
        if self._pending is not None:
            index, values, gradients = self._pending
            self._pending = None
            self.primitiveMoved.emit(index, values, gradients)
