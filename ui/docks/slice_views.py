"""The slice views: three orthogonal 2-D slices (xy, yz, xz) through the cursor, beside the
3-D view, as Fiji's orthogonal views, napari's and Imaris's slice views show them.

Each view is a plain Qt widget painting a ``QImage``; the pixels come from the library's
:func:`vtkvol.engine.slices.slice_rgba` (the 3-D view's classification: the channels' 1-D or
2-D TF colours mixed as the 3-D view mixes them, the slice weights and the clipping plane), so
nothing here touches VTK. The cursor is model state (``SceneModel.cursor``, world
µm): a click or a drag in a view moves it (to the nearest voxel centre), the mouse wheel and
PageUp/PageDown step the view's slice by one voxel, and every view follows the model.

Layout (Fiji's): xy top left with y downwards; yz to its right with z across, sharing the xy
view's rows; xz below it with z downwards, sharing the xy view's columns; the cursor's
position and the channels' values there in the fourth corner. Each view keeps the physical
aspect of its voxels (µm), draws crosshair lines where the other two planes cut it (in the
colour of their normal axis: x red, y green, z blue), outlines the crop box and dims what
lies outside it.
"""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt, QTimer
from PySide6.QtGui import (
    QColor,
    QImage,
    QKeyEvent,
    QMouseEvent,
    QPainter,
    QPainterPath,
    QPaintEvent,
    QPen,
    QWheelEvent,
)
from PySide6.QtWidgets import QGridLayout, QLabel, QSizePolicy, QWidget

from vtkvol.engine.slices import (
    AXES,
    PLANE_COLORS,
    PLANES,
    Plane,
    cursor_index,
    index_to_um,
    slice_rgba,
    to_rgba8,
)
from vtkvol.model.evented import subfields, touches
from vtkvol.model.scene import SceneModel
from vtkvol.ui.docks.base import ModelDock, format_um

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: Room around the image for the title (top) and the axis labels (left, bottom), pixels.
MARGIN_TOP, MARGIN_LEFT, MARGIN_BOTTOM, MARGIN_RIGHT = 18, 16, 16, 4
#: Darkening of what lies outside the crop box (alpha of black painted over it, 0…255).
OUTSIDE_CROP_DIM = 150
#: One wheel notch (Qt's angle delta of a classic mouse wheel), eighths of a degree.
WHEEL_NOTCH = 120


def _qcolor(rgb: tuple[float, float, float], alpha: int = 255) -> QColor:
    return QColor(round(255 * rgb[0]), round(255 * rgb[1]), round(255 * rgb[2]), alpha)


class SliceView(QWidget):
    """One orthogonal slice of the dock's data through the model's cursor (see the module
    docstring). Widget coordinates are Qt's logical pixels from the top-left corner."""

    def __init__(self, dock: SliceViewsDock, plane: Plane) -> None:
        super().__init__()
        self.dock = dock
        self.plane = plane
        self.setObjectName(f"slice_view_{plane.name}")
        self.setMinimumSize(90, 70)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)  # PageUp/PageDown
        self.setMouseTracking(False)
        self.setCursor(Qt.CursorShape.CrossCursor)
        self._rgba8: np.ndarray | None = None  # keeps the QImage's buffer alive
        self._qimage: QImage | None = None
        self._wheel = 0  # wheel movement not yet turned into slices (eighths of a degree)
        axis = AXES[plane.normal]
        self.setToolTip(f"The {plane.name} slice through the cursor. Click or drag: move the "
                        f"cursor · wheel, PageUp/PageDown: next {axis} slice")

    def sizeHint(self) -> QSize:
        return QSize(200, 200)

    # -- image ----------------------------------------------------------------------------------
    def set_image(self, rgba: np.ndarray | None) -> None:
        """Show a float RGBA slice (``[rows, columns, 4]`` in 0…1), opaque; None: nothing."""
        if rgba is None:
            self._rgba8, self._qimage = None, None
        else:
            image = to_rgba8(rgba)
            image[..., 3] = 255  # the colours are what the slice shows; over black
            rows, columns = image.shape[:2]
            self._rgba8 = image
            self._qimage = QImage(image.data, columns, rows, 4 * columns,
                                  QImage.Format.Format_RGBA8888)
        self.update()

    def image(self) -> np.ndarray | None:
        """The shown slice as ``uint8 [rows, columns, 4]`` (tests read it)."""
        return self._rgba8

    # -- geometry -------------------------------------------------------------------------------
    def _extent(self) -> tuple[int, int, float, float] | None:
        """(columns, rows, µm per column, µm per row) of the data's slice, or None."""
        data = self.dock.data
        if data is None:
            return None
        nz, ny, nx = data.array.shape[1:]
        n = (nx, ny, nz)
        s = data.voxel_size_um
        p = self.plane
        return n[p.column], n[p.row], float(s[p.column]), float(s[p.row])

    def image_rect(self) -> QRectF:
        """Where the slice is drawn: the largest rectangle of the slice's physical aspect
        (columns·s_column : rows·s_row µm) inside the margins, centred."""
        extent = self._extent()
        area = QRectF(MARGIN_LEFT, MARGIN_TOP, max(self.width() - MARGIN_LEFT - MARGIN_RIGHT, 1),
                      max(self.height() - MARGIN_TOP - MARGIN_BOTTOM, 1))
        if extent is None:
            return area
        columns, rows, s_col, s_row = extent
        width_um, height_um = columns * s_col, rows * s_row
        scale = min(area.width() / width_um, area.height() / height_um)
        w, h = width_um * scale, height_um * scale
        return QRectF(area.left() + (area.width() - w) / 2, area.top() + (area.height() - h) / 2,
                      w, h)

    def to_widget(self, column_um: float, row_um: float) -> QPointF:
        """Widget point of world µm ``column_um`` / ``row_um`` along the plane's column and
        row axes (voxel centres lie half a voxel inside the image's edges)."""
        extent = self._extent()
        rect = self.image_rect()
        if extent is None:
            return rect.center()
        columns, rows, s_col, s_row = extent
        return QPointF(rect.left() + (column_um / s_col + 0.5) * rect.width() / columns,
                       rect.top() + (row_um / s_row + 0.5) * rect.height() / rows)

    def to_um(self, point: QPointF) -> tuple[float, float] | None:
        """World µm (column axis, row axis) under widget ``point`` (the inverse of
        :meth:`to_widget`), or None without data."""
        extent = self._extent()
        if extent is None:
            return None
        columns, rows, s_col, s_row = extent
        rect = self.image_rect()
        column = (point.x() - rect.left()) * columns / rect.width() - 0.5
        row = (point.y() - rect.top()) * rows / rect.height() - 0.5
        return column * s_col, row * s_row

    def crosshair(self) -> tuple[int, int]:
        """The widget pixel column and row of the crosshair's lines: the pixels holding the
        cursor's voxel centre."""
        cursor = self.dock.cursor_um()
        centre = self.to_widget(cursor[self.plane.column], cursor[self.plane.row])
        return int(centre.x()), int(centre.y())

    # -- painting -------------------------------------------------------------------------------
    def paintEvent(self, event: QPaintEvent) -> None:
        painter = QPainter(self)
        try:
            self._paint(painter)
        finally:
            painter.end()

    def _paint(self, painter: QPainter) -> None:
        painter.fillRect(self.rect(), QColor(24, 24, 28))
        p, dock = self.plane, self.dock
        ink = QColor(225, 225, 225)
        painter.setPen(ink)
        if self._qimage is None or dock.data is None:
            painter.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter, "No data")
            return
        rect = self.image_rect()
        painter.drawImage(rect, self._qimage)  # nearest neighbour: voxels stay voxels
        cursor = dock.cursor_um()
        index = dock.cursor_voxel()
        spacing = dock.data.voxel_size_um
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)

        # The crop box: what lies outside is dimmed, its edge outlined.
        lo, hi = dock.crop_box()
        inside = lo[p.normal] <= cursor[p.normal] <= hi[p.normal]
        # Whole pixels, so that the outline is one crisp pixel wide.
        crop_rect = QRectF(self.to_widget(lo[p.column], lo[p.row]),
                           self.to_widget(hi[p.column], hi[p.row])).normalized().toRect()
        outside = QPainterPath()
        outside.addRect(rect)
        if inside:
            keep = QPainterPath()
            keep.addRect(crop_rect)
            outside = outside.subtracted(keep)
        painter.fillPath(outside, QColor(0, 0, 0, OUTSIDE_CROP_DIM))
        if dock.is_cropped() and inside:
            painter.setRenderHint(QPainter.RenderHint.Antialiasing, False)
            painter.setPen(QPen(QColor(255, 210, 80), 0, Qt.PenStyle.DashLine))
            painter.drawRect(crop_rect)

        # Crosshair: where the other two planes cut this one, in their normal axis's colour;
        # one crisp pixel wide (on the pixel holding the voxel centre), not smeared over two.
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, False)
        x, y = self.crosshair()
        painter.setPen(QPen(_qcolor(PLANE_COLORS[p.column], 210), 0))
        painter.drawLine(QPointF(x + 0.5, rect.top()), QPointF(x + 0.5, rect.bottom()))
        painter.setPen(QPen(_qcolor(PLANE_COLORS[p.row], 210), 0))
        painter.drawLine(QPointF(rect.left(), y + 0.5), QPointF(rect.right(), y + 0.5))
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)
        # The frame in this plane's own colour (its normal axis), as its outline in 3-D.
        painter.setPen(QPen(_qcolor(PLANE_COLORS[p.normal]), 1.5))
        painter.drawRect(rect)

        # Title: the plane and its position along the normal, in µm and as a voxel index.
        painter.setRenderHint(QPainter.RenderHint.Antialiasing, False)
        painter.setPen(ink)
        axis = AXES[p.normal]
        limit = (dock.data.array.shape[3], dock.data.array.shape[2],
                 dock.data.array.shape[1])[p.normal] - 1
        title = (f"{p.name}  {axis} {format_um(cursor[p.normal], spacing[p.normal])} "
                 f"· slice {index[p.normal]}/{limit}")
        title = painter.fontMetrics().elidedText(title, Qt.TextElideMode.ElideRight,
                                                 self.width() - 4)
        painter.drawText(QRectF(2, 0, self.width() - 4, MARGIN_TOP),
                         Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, title)
        # Axis labels: the column axis under the image's right end, the row axis left of its
        # top, with arrows pointing the way the index grows.
        painter.drawText(QRectF(rect.right() - 40, rect.bottom() + 1, 40, MARGIN_BOTTOM - 1),
                         Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop,
                         f"{AXES[p.column]} →")
        painter.drawText(QRectF(0, rect.top(), MARGIN_LEFT, 30),
                         Qt.AlignmentFlag.AlignHCenter | Qt.AlignmentFlag.AlignTop,
                         f"{AXES[p.row]}\n↓")

    # -- input ----------------------------------------------------------------------------------
    def mousePressEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.LeftButton:
            self.dock.gestureStarted.emit()  # a drag: the 3-D view may render coarser
            self._move_to(event.position())
            event.accept()
        else:
            super().mousePressEvent(event)

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.LeftButton:
            self.dock.gestureFinished.emit()
            event.accept()
        else:
            super().mouseReleaseEvent(event)

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        if event.buttons() & Qt.MouseButton.LeftButton:
            self._move_to(event.position())
            event.accept()
        else:
            super().mouseMoveEvent(event)

    def _move_to(self, point: QPointF) -> None:
        um = self.to_um(point)
        if um is not None:
            self.dock.move_cursor(self.plane, *um)

    def wheelEvent(self, event: QWheelEvent) -> None:
        # A notch is one slice; touchpads send many small deltas, which add up to notches.
        self._wheel += event.angleDelta().y()
        steps = int(self._wheel / WHEEL_NOTCH)
        self._wheel -= steps * WHEEL_NOTCH
        if steps:
            self.dock.step(self.plane, steps)
        event.accept()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        key = event.key()
        if key == Qt.Key.Key_PageUp:
            self.dock.step(self.plane, 1)
        elif key == Qt.Key.Key_PageDown:
            self.dock.step(self.plane, -1)
        else:
            super().keyPressEvent(event)
            return
        event.accept()


class SliceViewsDock(ModelDock):
    """The three slice views and the cursor's read-out (see the module docstring).

    Slices are recomputed only for what changed (a cursor step redraws one plane's slice; a
    TF, visibility or channel-mixing edit all three), coalesced to once per event-loop pass,
    and only while the dock is shown.

    Signals (ModelDock's): ``gestureStarted`` / ``gestureFinished`` bracket a click or drag
    in a view; the window renders the 3-D view coarser meanwhile when it shows the planes.
    """

    TITLE = "Slice views"
    OBJECT_NAME = "slice_views_dock"

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(model, parent)
        body = QWidget()
        self.grid = QGridLayout(body)
        self.grid.setContentsMargins(2, 2, 2, 2)
        self.grid.setSpacing(3)
        self.views: dict[str, SliceView] = {name: SliceView(self, plane)
                                            for name, plane in PLANES.items()}
        self.grid.addWidget(self.views["xy"], 0, 0)
        self.grid.addWidget(self.views["yz"], 0, 1)
        self.grid.addWidget(self.views["xz"], 1, 0)
        self.readout = QLabel("")
        self.readout.setObjectName("slice_readout")
        self.readout.setWordWrap(True)
        self.readout.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self.readout.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.readout.setToolTip("The cursor: its position in µm, its voxel (x, y, z) and every "
                                "channel's raw value there")
        self.grid.addWidget(self.readout, 1, 1)
        self.setWidget(body)
        self._index: tuple[int, int, int] | None = None  # the voxel each slice shows
        self._dirty: set[str] = set(PLANES)
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(0)
        self.bindings.connect_qt(self._timer.timeout, self._update_slices)
        self.bindings.connect_qt(self.visibilityChanged, self._on_visibility)
        self.bindings.connect_model(model, self._on_model_changed)

    # -- model and data -------------------------------------------------------------------------
    def set_data(self, data: VolumeData | None) -> None:
        self.data = data
        self._index = None
        if data is not None:
            self._clamp_model_cursor()
            self._layout_for(data)
        self._mark(set(PLANES))

    def _layout_for(self, data: VolumeData) -> None:
        """Share the dock's width and height by physical size (x and z across, y and z
        down), so the views line up as Fiji's do."""
        nz, ny, nx = data.array.shape[1:]
        sx, sy, sz = data.voxel_size_um
        w_x, w_y, w_z = nx * sx, ny * sy, nz * sz
        total_w, total_h = w_x + w_z, w_y + w_z
        self.grid.setColumnStretch(0, max(1, round(1000 * w_x / total_w)))
        self.grid.setColumnStretch(1, max(1, round(1000 * w_z / total_w)))
        self.grid.setRowStretch(0, max(1, round(1000 * w_y / total_h)))
        self.grid.setRowStretch(1, max(1, round(1000 * w_z / total_h)))

    def _clamp_model_cursor(self) -> None:
        """A cursor outside the data (a session of other data, a hand-edited file) is moved
        to the nearest voxel inside it."""
        data, cursor = self.data, self.model.cursor
        if data is None or cursor is None:
            return
        spacing = tuple(data.voxel_size_um)
        index = cursor_index(cursor, data.array.shape, spacing)  # type: ignore[arg-type]
        high = [(n - 1) * s for n, s in zip(data.array.shape[:0:-1], spacing, strict=True)]
        if any(not 0.0 <= c <= h for c, h in zip(cursor, high, strict=True)):
            self.model.cursor = index_to_um(index, spacing)  # type: ignore[arg-type]

    def cursor_voxel(self) -> tuple[int, int, int]:
        """The voxel (i, j, k) the views pass through (the model's cursor, clamped)."""
        if self.data is None:
            return (0, 0, 0)
        return cursor_index(self.model.cursor, self.data.array.shape,
                            tuple(self.data.voxel_size_um))  # type: ignore[arg-type]

    def cursor_um(self) -> tuple[float, float, float]:
        """World µm of the voxel centre the views pass through."""
        if self.data is None:
            return (0.0, 0.0, 0.0)
        return index_to_um(self.cursor_voxel(), tuple(self.data.voxel_size_um))  # type: ignore

    def crop_box(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The crop box's (low, high) corners in world µm (the whole box when not cropped)."""
        assert self.data is not None
        nz, ny, nx = self.data.array.shape[1:]
        sx, sy, sz = self.data.voxel_size_um
        b = self.model.crop.as_bounds((0.0, (nx - 1) * sx, 0.0, (ny - 1) * sy, 0.0,
                                       (nz - 1) * sz))
        return (b[0], b[2], b[4]), (b[1], b[3], b[5])

    def is_cropped(self) -> bool:
        crop = self.model.crop
        return not (crop.x is None and crop.y is None and crop.z is None)

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "channels") or touches(paths, "slice_weights") or touches(
                paths, "clip_plane"):
            # The slices show the 3-D view's classification (weights, clipping plane too).
            self._mark(set(PLANES))
        elif touches(paths, "render"):
            names = subfields(paths, "render")
            if names is None or "channel_mixing" in names:
                self._mark(set(PLANES))
        if touches(paths, "cursor"):
            self._mark(self._moved_planes())
        if touches(paths, "crop") or touches(paths, "cursor"):
            self._repaint()

    def _moved_planes(self) -> set[str]:
        """The planes whose slice index differs from the shown one."""
        if self._index is None or self.data is None:
            return set(PLANES)
        new = self.cursor_voxel()
        return {name for name, p in PLANES.items() if new[p.normal] != self._index[p.normal]}

    def _mark(self, planes: set[str]) -> None:
        self._dirty |= planes
        self._timer.start()

    def _on_visibility(self, visible: bool) -> None:
        if visible and self._dirty:
            self._timer.start()

    def _update_slices(self) -> None:
        """Recompute the dirty slices (only while shown) and the read-out."""
        if self.data is None:
            for view in self.views.values():
                view.set_image(None)
            self.readout.setText("")
            return
        if not self.isVisible():
            return  # done when shown (visibilityChanged)
        index = self.cursor_voxel()
        for name in sorted(self._dirty):
            plane = PLANES[name]
            self.views[name].set_image(slice_rgba(self.data, self.model, plane,
                                                  index[plane.normal]))
        self._dirty.clear()
        self._index = index
        self._show_readout()
        self._repaint()

    def refresh_now(self) -> None:
        """Bring the views up to date at once (tests and screenshots; normal updates are
        coalesced to the next event-loop pass)."""
        self._timer.stop()
        self._update_slices()

    def _show_readout(self) -> None:
        data = self.data
        assert data is not None
        i, j, k = index = self.cursor_voxel()
        position = self.cursor_um()
        spacing = data.voxel_size_um
        where = "<br>".join(f"{AXES[a]} {format_um(position[a], spacing[a])}" for a in range(3))
        channels = self.model.channels
        names = [channels[c].name if c < len(channels) else name
                 for c, name in enumerate(data.channel_names)]
        values = "<br>".join(f"{html.escape(name)}: {_number(float(data.array[c, k, j, i]))}"
                             for c, name in enumerate(names))
        self.readout.setText(f"<b>Cursor</b><br>{where}<br>voxel {index}<br>{values}")

    def _repaint(self) -> None:
        for view in self.views.values():
            view.update()

    # -- edits from the views -------------------------------------------------------------------
    def move_cursor(self, plane: Plane, column_um: float, row_um: float) -> None:
        """Move the cursor within ``plane`` to (column, row) world µm, snapped to the nearest
        voxel centre inside the data; the position along the plane's normal stays."""
        if self.data is None:
            return
        point = list(self.cursor_um())
        point[plane.column], point[plane.row] = column_um, row_um
        spacing = tuple(self.data.voxel_size_um)
        index = cursor_index(tuple(point), self.data.array.shape, spacing)  # type: ignore
        self.model.cursor = index_to_um(index, spacing)  # type: ignore[arg-type]

    def step(self, plane: Plane, steps: int) -> None:
        """Move ``plane``'s slice ``steps`` voxels along its normal (clamped to the data)."""
        if self.data is None:
            return
        index = list(self.cursor_voxel())
        limit = self.data.array.shape[3 - plane.normal] - 1
        index[plane.normal] = min(max(index[plane.normal] + int(steps), 0), limit)
        self.model.cursor = index_to_um(tuple(index), tuple(self.data.voxel_size_um))  # type: ignore


def _number(value: float) -> str:
    return str(int(value)) if value.is_integer() else f"{value:.4g}"
