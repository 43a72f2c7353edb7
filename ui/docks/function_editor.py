"""The function editor shared by the transfer-function and slice-contribution docks.

A :class:`FunctionEditor` edits piecewise-linear functions y(x) with y in 0…1 over a
displayed x window (seed 002 §2.9–2.11, seed 000 §5): several named curves are drawn, one is
active and edited, in one of two modes:

* **points**: click empty space to add a node (and drag it), drag a node to move it (it
  cannot pass its neighbours), right-click a node or press Delete to remove it;
* **curve**: freehand, pressing and dragging sets the curve's value under the cursor.

The opacity curve can be shown on seed 002's logarithmic axis (:func:`opacity_to_log_axis`),
which spends most of the height on the low opacities that matter in microscopy. A histogram
(linear or log counts) is drawn behind the curves. The editor only emits edited point lists
(throttled while dragging); the docks write them into the model.

:class:`ColorBar` is the preview strip under the transfer-function editor: the colours with
their opacity over a checkerboard, aligned with the editor's x axis.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt, QTimer, Signal
from PySide6.QtGui import (
    QColor,
    QFont,
    QImage,
    QKeyEvent,
    QMouseEvent,
    QPainter,
    QPainterPath,
    QPaintEvent,
    QPen,
    QPolygonF,
)
from PySide6.QtWidgets import QSizePolicy, QWidget

from vtkvol.model.transfer_function import above

Points = list[tuple[float, float]]

#: Seed 002's "maximum settable value" d for the log opacity axis. Opacity here is a float,
#: so d sets the finest opacity the axis is designed for: 1/1000 (the 0.1 % visibility that
#: Potts & Möller say matters), giving a = ln 1000 ≈ 6.9.
LOG_OPACITY_RANGE = 1000.0
#: Edits are sent to the model at most this often while dragging (ms).
THROTTLE_MS = 60
#: Freehand (curve mode) resolution across the displayed window.
CURVE_SAMPLES = 128
#: A node is picked within this many pixels.
PICK_RADIUS = 8.0
#: Plot margins shared with :class:`ColorBar`, so the two x axes line up.
MARGIN_LEFT, MARGIN_RIGHT, MARGIN_TOP, MARGIN_BOTTOM = 44.0, 12.0, 10.0, 20.0

_BACKGROUND = QColor(30, 31, 36)
_GRID = QColor(62, 64, 72)
_HISTOGRAM = QColor(88, 92, 104)
_TEXT = QColor(190, 192, 200)


# -- seed 002's log opacity axis (pure functions; unit-tested with the worked values) -----------
def log_axis_strength(d: float) -> float:
    """``a = max(ln d, 1)`` for the maximum settable value ``d``."""
    return max(math.log(d), 1.0)


def opacity_to_log_axis(alpha: float | np.ndarray, d: float = LOG_OPACITY_RANGE):
    """Seed 002 eq. 5.1: α′ = 1 + ln((1 − e^(−a))·α + e^(−a)) / a, α in 0…1 → α′ in 0…1."""
    a = log_axis_strength(d)
    ea = math.exp(-a)
    result = 1.0 + np.log((1.0 - ea) * np.asarray(alpha, dtype=np.float64) + ea) / a
    return float(result) if np.ndim(result) == 0 else result


def log_axis_to_opacity(alpha_prime: float | np.ndarray, d: float = LOG_OPACITY_RANGE):
    """Seed 002 eq. 5.2, the inverse: α = (e^(−a(1−α′)) − e^(−a)) / (1 − e^(−a))."""
    a = log_axis_strength(d)
    ea = math.exp(-a)
    x = np.asarray(alpha_prime, dtype=np.float64)
    result = (np.exp(-a * (1.0 - x)) - ea) / (1.0 - ea)
    return float(result) if np.ndim(result) == 0 else result


def simplify(points: Points, tolerance: float) -> Points:
    """Drop nodes that lie within ``tolerance`` (in y) of the line through the nodes kept
    around them (Ramer–Douglas–Peucker on vertical distance), so a freehand stroke does not
    leave a hundred nodes behind. Points must be sorted by x."""
    if len(points) <= 2:
        return list(points)
    keep = [False] * len(points)
    keep[0] = keep[-1] = True
    stack = [(0, len(points) - 1)]
    while stack:
        i, j = stack.pop()
        (x0, y0), (x1, y1) = points[i], points[j]
        worst, worst_k = 0.0, -1
        for k in range(i + 1, j):
            x, y = points[k]
            t = (x - x0) / (x1 - x0) if x1 != x0 else 0.0
            dist = abs(y - (y0 + t * (y1 - y0)))
            if dist > worst:
                worst, worst_k = dist, k
        if worst > tolerance and worst_k > 0:
            keep[worst_k] = True
            stack.extend([(i, worst_k), (worst_k, j)])
    return [p for p, k in zip(points, keep, strict=True) if k]


def format_value(value: float) -> str:
    """Compact axis label: 4095, 0.25, 1.2e+04."""
    if value == 0:
        return "0"
    magnitude = abs(value)
    if magnitude >= 1e5 or magnitude < 1e-3:
        return f"{value:.2g}"
    if magnitude >= 100:
        return f"{value:.0f}"
    return f"{value:.3g}"


@dataclass
class Curve:
    """One editable function: ``points`` are ``(x, y)`` with y in 0…1, sorted by x."""

    name: str
    label: str
    color: QColor
    points: Points = field(default_factory=list)
    log_axis: bool = False  #: drawn on the log opacity axis when the editor's log scale is on


class FunctionEditor(QWidget):
    """Edits piecewise-linear curves over a displayed x window (see the module docstring).

    Signals
    -------
    pointsEdited(name, points)
        The active curve was edited (throttled while dragging, always once at the end).
    editStarted(), editFinished()
        A mouse gesture began / ended (the dock groups its edits into one undo step).
    """

    pointsEdited = Signal(str, object)
    editStarted = Signal()
    editFinished = Signal()

    MODES = ("points", "curve")

    def __init__(self, parent: QWidget | None = None, *, min_points: int = 2) -> None:
        super().__init__(parent)
        self._curves: dict[str, Curve] = {}
        self._active: str | None = None
        self._mode = "points"
        self._domain = (0.0, 1.0)
        self._log = False
        self._histogram: np.ndarray | None = None
        self._histogram_log = True
        self._min_points = max(1, min_points)
        self._x_format: Callable[[float], str] = format_value
        self._y_title = ""
        self._hover: QPointF | None = None
        # gesture state
        self._drag_index: int | None = None
        self._selected: int | None = None
        #: While drawing: the sample positions and values across the window, the curve's nodes
        #: before the stroke, and the first and last sample the stroke has touched.
        self._painting: tuple[list[float], list[float], Points] | None = None
        self._touched: tuple[int, int] | None = None
        self._last_sample: tuple[int, float] | None = None
        self._in_gesture = False
        self._pending: Points | None = None
        self._throttle = QTimer(self)
        self._throttle.setSingleShot(True)
        self._throttle.setInterval(THROTTLE_MS)
        self._throttle.timeout.connect(self._flush)
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.setMinimumSize(260, 120)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setToolTip(
            "Points mode: click to add a node, drag to move it, right-click or Delete to "
            "remove it.\nCurve mode: press and drag to draw the curve freehand."
        )

    def sizeHint(self) -> QSize:
        return QSize(520, 190)

    # -- configuration -------------------------------------------------------------------------
    def set_curves(self, curves: Sequence[Curve]) -> None:
        """Replace all curves; the first becomes active unless the active name remains."""
        self._curves = {c.name: c for c in curves}
        if self._active not in self._curves:
            self._active = curves[0].name if curves else None
        self._selected = None
        self.update()

    def curve(self, name: str) -> Curve:
        return self._curves[name]

    def set_points(self, name: str, points: Sequence[tuple[float, float]]) -> None:
        """Show new points for ``name``; ignored for the curve being dragged (its own state is
        newer than the model's echo of a throttled edit)."""
        if name not in self._curves or (self._in_gesture and name == self._active):
            return
        self._curves[name].points = [(float(x), float(y)) for x, y in points]
        if name == self._active:
            self._selected = None
        self.update()

    def points(self, name: str) -> Points:
        return list(self._curves[name].points)

    def set_active(self, name: str) -> None:
        if name in self._curves and name != self._active:
            self._active = name
            self._selected = None
            self.update()

    @property
    def active(self) -> str | None:
        return self._active

    def set_mode(self, mode: str) -> None:
        if mode not in self.MODES:
            raise ValueError(f"mode must be one of {self.MODES}, not {mode!r}")
        self._mode = mode
        shape = Qt.CursorShape.CrossCursor if mode == "curve" else Qt.CursorShape.ArrowCursor
        self.setCursor(shape)

    @property
    def mode(self) -> str:
        return self._mode

    def set_domain(self, lo: float, hi: float) -> None:
        """The displayed x window (data units for a TF, 0…1 for slice weights)."""
        if not hi > lo:
            hi = above(lo)
        if (lo, hi) != self._domain:
            self._domain = (float(lo), float(hi))
            self.update()

    @property
    def domain(self) -> tuple[float, float]:
        return self._domain

    def set_log_scale(self, on: bool) -> None:
        """Show curves flagged ``log_axis`` on seed 002's log opacity axis."""
        self._log = bool(on)
        self.update()

    @property
    def log_scale(self) -> bool:
        return self._log

    def set_histogram(self, counts: np.ndarray | None) -> None:
        """Counts in equal bins across the current domain (or None for no histogram)."""
        self._histogram = None if counts is None else np.asarray(counts, dtype=np.float64)
        self.update()

    def set_histogram_log(self, on: bool) -> None:
        self._histogram_log = bool(on)
        self.update()

    def set_x_formatter(self, fn: Callable[[float], str]) -> None:
        self._x_format = fn
        self.update()

    def set_y_title(self, text: str) -> None:
        self._y_title = text
        self.update()

    # -- coordinates ---------------------------------------------------------------------------
    def plot_rect(self) -> QRectF:
        return QRectF(
            MARGIN_LEFT,
            MARGIN_TOP,
            max(10.0, self.width() - MARGIN_LEFT - MARGIN_RIGHT),
            max(10.0, self.height() - MARGIN_TOP - MARGIN_BOTTOM),
        )

    def _uses_log(self, curve: Curve | None) -> bool:
        return self._log and curve is not None and curve.log_axis

    def to_pixel(self, x: float, y: float, curve: Curve | None = None) -> QPointF:
        """Widget position of the function point (x, y) on ``curve``'s axis."""
        r = self.plot_rect()
        lo, hi = self._domain
        shown = opacity_to_log_axis(y) if self._uses_log(curve) else y
        return QPointF(
            r.left() + (x - lo) / (hi - lo) * r.width(),
            r.bottom() - shown * r.height(),
        )

    def from_pixel(self, pos: QPointF, curve: Curve | None = None) -> tuple[float, float]:
        """The function point (x, y) under widget position ``pos`` (clamped to the plot)."""
        r = self.plot_rect()
        lo, hi = self._domain
        tx = min(max((pos.x() - r.left()) / r.width(), 0.0), 1.0)
        ty = min(max((r.bottom() - pos.y()) / r.height(), 0.0), 1.0)
        y = log_axis_to_opacity(ty) if self._uses_log(curve) else ty
        return lo + tx * (hi - lo), min(max(float(y), 0.0), 1.0)

    # -- painting ------------------------------------------------------------------------------
    def paintEvent(self, event: QPaintEvent) -> None:
        del event
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        r = self.plot_rect()
        p.fillRect(self.rect(), self.palette().window())
        p.fillRect(r, _BACKGROUND)
        self._paint_histogram(p, r)
        self._paint_grid(p, r)
        active = self._curves.get(self._active) if self._active else None
        for curve in self._curves.values():
            if curve is not active:
                self._paint_curve(p, curve, active=False)
        if active is not None:
            self._paint_curve(p, active, active=True)
        self._paint_readout(p, r, active)
        p.end()

    def _paint_histogram(self, p: QPainter, r: QRectF) -> None:
        counts = self._histogram
        if counts is None or counts.size == 0 or counts.max() <= 0:
            return
        heights = np.log1p(counts) / np.log1p(counts.max()) if self._histogram_log else (
            counts / counts.max()
        )
        n = len(heights)
        poly = QPolygonF()
        poly.append(QPointF(r.left(), r.bottom()))
        for i, h in enumerate(heights):
            y = r.bottom() - float(h) * r.height()
            poly.append(QPointF(r.left() + i / n * r.width(), y))
            poly.append(QPointF(r.left() + (i + 1) / n * r.width(), y))
        poly.append(QPointF(r.right(), r.bottom()))
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(_HISTOGRAM)
        p.drawPolygon(poly)

    def _paint_grid(self, p: QPainter, r: QRectF) -> None:
        font = QFont(self.font())
        font.setPointSizeF(max(7.0, font.pointSizeF() - 1.5))
        p.setFont(font)
        active = self._curves.get(self._active) if self._active else None
        if self._uses_log(active):
            ticks = [(v, f"{v:g}") for v in (0.001, 0.01, 0.1, 0.5, 1.0)]
        else:
            ticks = [(v, f"{v:g}") for v in (0.0, 0.25, 0.5, 0.75, 1.0)]
        for value, text in ticks:
            y = self.to_pixel(self._domain[0], value, active).y()
            p.setPen(QPen(_GRID, 1, Qt.PenStyle.DotLine))
            p.drawLine(QPointF(r.left(), y), QPointF(r.right(), y))
            p.setPen(_TEXT)
            p.drawText(QRectF(0, y - 8, MARGIN_LEFT - 4, 16),
                       Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter, text)
        lo, hi = self._domain
        for t in (0.0, 0.25, 0.5, 0.75, 1.0):
            x = r.left() + t * r.width()
            p.setPen(QPen(_GRID, 1, Qt.PenStyle.DotLine))
            p.drawLine(QPointF(x, r.top()), QPointF(x, r.bottom()))
            p.setPen(_TEXT)
            if t == 0.0:
                box, align = QRectF(x, r.bottom() + 2, 90, 16), Qt.AlignmentFlag.AlignLeft
            elif t == 1.0:
                box, align = QRectF(x - 90, r.bottom() + 2, 90, 16), Qt.AlignmentFlag.AlignRight
            else:
                box, align = QRectF(x - 45, r.bottom() + 2, 90, 16), Qt.AlignmentFlag.AlignHCenter
            p.drawText(box, align | Qt.AlignmentFlag.AlignTop, self._x_format(lo + t * (hi - lo)))
        if self._y_title:
            p.save()
            p.translate(10, r.center().y())
            p.rotate(-90)
            p.setPen(_TEXT)
            p.drawText(QRectF(-r.height() / 2, -8, r.height(), 16),
                       Qt.AlignmentFlag.AlignCenter, self._y_title)
            p.restore()

    def _paint_curve(self, p: QPainter, curve: Curve, *, active: bool) -> None:
        if not curve.points:
            return
        r = self.plot_rect()
        lo, hi = self._domain
        xs = np.array([pt[0] for pt in curve.points])
        ys = np.array([pt[1] for pt in curve.points])
        # Sample densely enough that the log axis shows the true (curved) shape of each
        # linear segment, and include every node inside the window.
        grid = np.linspace(lo, hi, max(64, int(r.width() // 3)))
        within = (xs > lo) & (xs < hi)
        inside = xs[within]
        if len(inside) <= len(grid):
            grid = np.union1d(grid, inside)
            trace = [(float(gx), float(gy)) for gx, gy in zip(grid, np.interp(grid, xs, ys),
                                                              strict=True)]
        else:
            # More nodes than sample columns (a function of 100 000 points, set from code):
            # each column is drawn as the range of the nodes in it, so the path stays a few
            # hundred elements (QPainter took minutes for 100 000) and fine detail shows as a
            # band instead of vanishing.
            column = np.clip(np.rint((inside - lo) / (hi - lo) * (len(grid) - 1)).astype(int),
                             0, len(grid) - 1)
            low = np.interp(grid, xs, ys)
            high = low.copy()
            np.minimum.at(low, column, ys[within])
            np.maximum.at(high, column, ys[within])
            trace = [(float(gx), float(gy)) for gx, a, b in zip(grid, low, high, strict=True)
                     for gy in (a, b)]
        path = QPainterPath()
        for i, (gx, gy) in enumerate(trace):
            pt = self.to_pixel(gx, gy, curve)
            path.moveTo(pt) if i == 0 else path.lineTo(pt)
        color = QColor(curve.color)
        if not active:
            color.setAlpha(110)
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.setPen(QPen(color, 2.2 if active else 1.2))
        p.drawPath(path)
        # Handles closer than 3 px apart would be one blob (and slow to draw): none then.
        if active and self._mode == "points" and len(inside) <= r.width() / 3:
            for i, (x, y) in enumerate(curve.points):
                if not lo <= x <= hi:
                    continue
                pt = self.to_pixel(x, y, curve)
                selected = i == self._selected or i == self._drag_index
                p.setPen(QPen(QColor(20, 20, 20), 1.2))
                p.setBrush(QColor(255, 255, 255) if selected else color)
                p.drawEllipse(pt, 5.0 if selected else 4.0, 5.0 if selected else 4.0)

    def _paint_readout(self, p: QPainter, r: QRectF, active: Curve | None) -> None:
        if self._hover is None or active is None or not r.contains(self._hover):
            return
        x, y = self.from_pixel(self._hover, active)
        value = float(np.interp(x, *zip(*active.points, strict=True))) if active.points else 0.0
        text = f"{self._x_format(x)} → {active.label.lower()} {value:.3g} (cursor {y:.3g})"
        p.setPen(_TEXT)
        align = Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop
        p.drawText(r.adjusted(6, 4, -6, -4), align, text)

    # -- mouse ---------------------------------------------------------------------------------
    def _pick(self, pos: QPointF) -> int | None:
        curve = self._curves.get(self._active) if self._active else None
        if curve is None:
            return None
        lo, hi = self._domain
        best, best_d = None, PICK_RADIUS
        for i, (x, y) in enumerate(curve.points):
            if not lo <= x <= hi:
                continue
            d = math.dist((pos.x(), pos.y()), self.to_pixel(x, y, curve).toTuple())
            if d <= best_d:
                best, best_d = i, d
        return best

    def mousePressEvent(self, event: QMouseEvent) -> None:
        curve = self._curves.get(self._active) if self._active else None
        pos = event.position()
        if curve is None or not self.plot_rect().adjusted(-6, -6, 6, 6).contains(pos):
            return
        if event.button() == Qt.MouseButton.RightButton and self._mode == "points":
            index = self._pick(pos)
            if index is not None:
                self._remove(index)
            return
        if event.button() != Qt.MouseButton.LeftButton:
            return
        self._begin_gesture()
        if self._mode == "points":
            index = self._pick(pos)
            if index is None:
                x, y = self.from_pixel(pos, curve)
                pts = curve.points
                index = int(np.searchsorted([pt[0] for pt in pts], x))
                pts.insert(index, (x, y))
                self._queue()
            self._drag_index = self._selected = index
        else:
            self._start_painting(curve)
            self._paint_at(pos, curve)
        self.update()

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        pos = event.position()
        self._hover = pos
        curve = self._curves.get(self._active) if self._active else None
        if curve is not None and self._in_gesture:
            if self._mode == "points" and self._drag_index is not None:
                self._move_node(curve, self._drag_index, *self.from_pixel(pos, curve))
            elif self._painting is not None:
                self._paint_at(pos, curve)
        self.update()

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        if event.button() != Qt.MouseButton.LeftButton or not self._in_gesture:
            return
        curve = self._curves.get(self._active) if self._active else None
        if self._painting is not None and curve is not None:
            curve.points = self._stroke_points(simplified=True)
            self._pending = list(curve.points)
        self._painting = None
        self._drag_index = None
        self._end_gesture()
        self.update()

    def leaveEvent(self, event) -> None:
        self._hover = None
        self.update()
        super().leaveEvent(event)

    def keyPressEvent(self, event: QKeyEvent) -> None:
        if event.key() in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace) and self._selected is not None:
            self._remove(self._selected)
            return
        super().keyPressEvent(event)

    # -- edits ---------------------------------------------------------------------------------
    def _move_node(self, curve: Curve, index: int, x: float, y: float) -> None:
        pts = curve.points
        # Nodes keep their order: a node cannot be dragged past its neighbours.
        span = self._domain[1] - self._domain[0]
        eps = span * 1e-6
        lo = pts[index - 1][0] + eps if index > 0 else -math.inf
        hi = pts[index + 1][0] - eps if index + 1 < len(pts) else math.inf
        pts[index] = (min(max(x, lo), hi), y)
        self._queue()

    def _remove(self, index: int) -> None:
        curve = self._curves.get(self._active) if self._active else None
        if curve is None or len(curve.points) <= self._min_points:
            return
        del curve.points[index]
        self._selected = None
        self.editStarted.emit()
        self.pointsEdited.emit(curve.name, list(curve.points))
        self.editFinished.emit()
        self.update()

    def _start_painting(self, curve: Curve) -> None:
        lo, hi = self._domain
        xs = list(np.linspace(lo, hi, CURVE_SAMPLES))
        src_x = [pt[0] for pt in curve.points]
        src_y = [pt[1] for pt in curve.points]
        ys = list(np.interp(xs, src_x, src_y)) if curve.points else [0.0] * CURVE_SAMPLES
        self._painting = ([float(v) for v in xs], [float(v) for v in ys], list(curve.points))
        self._touched = None
        self._last_sample = None

    def _stroke_points(self, *, simplified: bool) -> Points:
        """The curve with the stretch the stroke touched replaced by the drawn samples.

        Only that stretch changes: nodes left and right of it stay as they were, with a node
        on each side where the old curve meets the stroke (inside the old nodes' span only).
        Redrawing the whole window would move the end nodes to the window's edges, and with
        them the contrast limits (the TF's value span).
        """
        assert self._painting is not None
        xs, ys, original = self._painting
        if self._touched is None:
            return list(original)
        first, last = self._touched
        stroke = list(zip(xs[first:last + 1], ys[first:last + 1], strict=True))
        if simplified:
            stroke = simplify(stroke, 0.003)
        x0, x1 = xs[first], xs[last]
        left = [pt for pt in original if pt[0] < x0]
        right = [pt for pt in original if pt[0] > x1]
        if original:
            span_lo, span_hi = original[0][0], original[-1][0]
            ox = [pt[0] for pt in original]
            oy = [pt[1] for pt in original]
            before = xs[first - 1] if first > 0 else None
            after = xs[last + 1] if last + 1 < len(xs) else None
            if before is not None and span_lo <= before and (not left or left[-1][0] < before):
                left.append((before, float(np.interp(before, ox, oy))))
            if after is not None and after <= span_hi and (not right or right[0][0] > after):
                right.insert(0, (after, float(np.interp(after, ox, oy))))
        return left + stroke + right

    def _paint_at(self, pos: QPointF, curve: Curve) -> None:
        assert self._painting is not None
        _, ys, _ = self._painting
        lo, hi = self._domain
        x, y = self.from_pixel(pos, curve)
        i = min(max(round((x - lo) / (hi - lo) * (CURVE_SAMPLES - 1)), 0), CURVE_SAMPLES - 1)
        if self._last_sample is None:
            ys[i] = y
        else:
            # Fill every sample between the previous and this cursor position, so a fast
            # stroke leaves no gaps.
            j, yj = self._last_sample
            step = 1 if i >= j else -1
            for k in range(j, i + step, step):
                t = (k - j) / (i - j) if i != j else 1.0
                ys[k] = yj + t * (y - yj)
        self._last_sample = (i, y)
        touched = self._touched or (i, i)
        self._touched = (min(touched[0], i), max(touched[1], i))
        curve.points = self._stroke_points(simplified=False)
        self._queue()

    def _begin_gesture(self) -> None:
        self._in_gesture = True
        self.editStarted.emit()

    def _end_gesture(self) -> None:
        self._throttle.stop()
        self._flush()
        self._in_gesture = False
        self.editFinished.emit()

    def _queue(self) -> None:
        """Send the active curve now if nothing was sent recently, else when the throttle
        interval has passed (the latest state wins)."""
        curve = self._curves.get(self._active) if self._active else None
        if curve is None:
            return
        self._pending = list(curve.points)
        if not self._throttle.isActive():
            self._flush()
            self._throttle.start()

    def _flush(self) -> None:
        if self._pending is not None and self._active is not None:
            points, self._pending = self._pending, None
            self.pointsEdited.emit(self._active, points)


class ColorBar(QWidget):
    """The transfer function's colours and opacity over a checkerboard (seed 000 §5,
    module 3), aligned with a :class:`FunctionEditor`'s x axis.

    Double-click sets the colour at that value (``colorRequested``); right-click a colour
    marker to remove that colour node (``stopRemoveRequested``).
    """

    colorRequested = Signal(float)
    stopRemoveRequested = Signal(int)

    BAR_HEIGHT = 18
    MARKER = 6

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._colors: list[tuple[float, float, float, float]] = []
        self._opacity: Points = []
        self._domain = (0.0, 1.0)
        self.setFixedHeight(self.BAR_HEIGHT + self.MARKER + 4)
        self.setToolTip(
            "Colour and opacity preview over a checkerboard (opacity shown as transparency).\n"
            "Double-click to set the colour at a value; right-click a marker to remove it."
        )

    def set_function(
        self,
        colors: Sequence[tuple[float, float, float, float]],
        opacity: Sequence[tuple[float, float]],
        domain: tuple[float, float],
    ) -> None:
        self._colors = list(colors)
        self._opacity = list(opacity)
        self._domain = domain if domain[1] > domain[0] else (domain[0], domain[0] + 1.0)
        self.update()

    def bar_rect(self) -> QRectF:
        return QRectF(MARGIN_LEFT, 1.0, max(10.0, self.width() - MARGIN_LEFT - MARGIN_RIGHT),
                      float(self.BAR_HEIGHT))

    def value_at(self, px: float) -> float:
        r = self.bar_rect()
        lo, hi = self._domain
        t = min(max((px - r.left()) / r.width(), 0.0), 1.0)
        return lo + t * (hi - lo)

    def _x_of(self, value: float) -> float:
        r = self.bar_rect()
        lo, hi = self._domain
        return r.left() + (value - lo) / (hi - lo) * r.width()

    def rgba_image(self, width: int) -> QImage:
        """The strip as a ``width``×1 RGBA image (straight alpha)."""
        lo, hi = self._domain
        xs = np.linspace(lo, hi, max(2, width))
        rgba = np.zeros((len(xs), 4), np.float64)
        if self._colors:
            c = np.asarray(self._colors, np.float64)
            for k in range(3):
                rgba[:, k] = np.interp(xs, c[:, 0], c[:, k + 1])
        if self._opacity:
            o = np.asarray(self._opacity, np.float64)
            rgba[:, 3] = np.interp(xs, o[:, 0], o[:, 1])
        pixels = np.ascontiguousarray((np.clip(rgba, 0, 1) * 255).astype(np.uint8)[None])
        image = QImage(pixels.data, pixels.shape[1], 1, pixels.shape[1] * 4,
                       QImage.Format.Format_RGBA8888)
        return image.copy()  # own the pixels: the numpy buffer dies with this frame

    def paintEvent(self, event: QPaintEvent) -> None:
        del event
        p = QPainter(self)
        r = self.bar_rect()
        cell = 6
        light, dark = QColor(205, 205, 205), QColor(120, 120, 120)
        for row in range(math.ceil(r.height() / cell)):
            for col in range(math.ceil(r.width() / cell)):
                p.fillRect(QRectF(r.left() + col * cell, r.top() + row * cell, cell, cell)
                           .intersected(r), light if (row + col) % 2 else dark)
        p.drawImage(r, self.rgba_image(int(r.width())))
        p.setPen(QPen(QColor(60, 60, 60), 1))
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.drawRect(r)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        lo, hi = self._domain
        shown = sum(1 for point in self._colors if lo <= point[0] <= hi)
        if shown > r.width() / 3:  # markers 3 px apart would be one blob (and slow): none
            p.end()
            return
        for value, red, green, blue in self._colors:
            if not lo <= value <= hi:
                continue
            x = self._x_of(value)
            top, bottom = r.bottom() + 1, r.bottom() + 1 + self.MARKER
            tri = QPolygonF([QPointF(x, top), QPointF(x - 4, bottom), QPointF(x + 4, bottom)])
            p.setPen(QPen(QColor(230, 230, 230), 1))
            p.setBrush(QColor.fromRgbF(red, green, blue))
            p.drawPolygon(tri)
        p.end()

    def _marker_at(self, px: float) -> int | None:
        lo, hi = self._domain
        for i, (value, *_rgb) in enumerate(self._colors):
            if lo <= value <= hi and abs(self._x_of(value) - px) <= 5:
                return i
        return None

    def mouseDoubleClickEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.LeftButton:
            self.colorRequested.emit(self.value_at(event.position().x()))

    def mousePressEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.RightButton:
            index = self._marker_at(event.position().x())
            if index is not None:
                self.stopRemoveRequested.emit(index)
