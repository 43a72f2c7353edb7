"""3-D measurement: points picked on the rendered surface, their distance, a CSV export.

With **Pick points** on (the Measure dock, View → Measure), a click in the 3-D view (a press
and release less than :data:`CLICK_SLOP_PX` apart: a drag still turns the camera) adds the
point the intensity probe finds under the pointer (:func:`vtkvol.engine.probe.probe`: the
first material the transfer functions make visible, not the first voxel of the box), with
every channel's raw value at its voxel. The points are listed in the dock, drawn in the 3-D
view as small spheres joined by a line in the order picked, and the dock shows the distance
between the last two points picked (or the two rows selected) in µm. **Export CSV…** writes
``x_um,y_um,z_um`` and one column per channel (named by the channels) per point.

Coordinates: world µm (the data's voxel centres at (i·sx, j·sy, k·sz)), so distances are
physical whatever the voxel size. The points belong to the data shown: opening other data
clears them. A session keeps them in its app-owned ``window`` section (key
:data:`SESSION_KEY`, see :meth:`MeasureTool.window_state`), so no session format change is
needed; entries that are not well-formed points are skipped on reopening, as a damaged window
layout is. They are not undo steps. A time-lapse keeps them across time points; each point's
values are those of the time point it was picked at.

Writing the CSV never replaces a file silently: an existing file is replaced only after the
user confirms, and a file that cannot be written (a missing or read-only folder, a full disk)
gets a one-line dialog naming the file and the reason; the list stays as it was.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import vtk
from PySide6.QtCore import QEvent, QObject, Qt, SignalInstance
from PySide6.QtWidgets import (
    QAbstractItemView,
    QDockWidget,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from vtkvol.engine.probe import ProbeResult
from vtkvol.io.atomic import write_atomic
from vtkvol.ui import errors
from vtkvol.ui.viewport import Viewport

#: A press and release this close (logical px) are a click (a pick), farther apart a drag.
CLICK_SLOP_PX = 4.0
#: Marker sphere radius as a share of the data box's diagonal.
MARKER_SHARE = 0.012
#: Colour of the markers and of the line joining them (a yellow that reads on most TFs).
MARKER_RGB = (1.0, 0.85, 0.1)
#: Key of the points in a session's ``window`` section.
SESSION_KEY = "measure_points"
#: Columns of the point list before the channels' values.
POSITION_COLUMNS = ("x µm", "y µm", "z µm")


@dataclass(frozen=True)
class MeasuredPoint:
    """One picked point: ``position_um`` world µm (x, y, z) where the view ray met visible
    material, ``index`` (i, j, k) of its voxel, ``values`` the channels' raw values there."""

    position_um: tuple[float, float, float]
    index: tuple[int, int, int]
    values: tuple[float, ...]

    @classmethod
    def from_probe(cls, result: ProbeResult) -> MeasuredPoint:
        return cls(result.position_um, result.index, result.values)


def distance_um(a: MeasuredPoint, b: MeasuredPoint) -> float:
    """Euclidean distance between two points, µm (world coordinates are µm)."""
    return math.dist(a.position_um, b.position_um)


def csv_text(points: Sequence[MeasuredPoint], channel_names: Sequence[str]) -> str:
    """The points as CSV: a header ``x_um,y_um,z_um,<channel names>`` and one row per point
    (positions in µm with full float precision, raw channel values)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["x_um", "y_um", "z_um", *channel_names])
    for p in points:
        writer.writerow([repr(float(v)) for v in p.position_um]
                        + [_value_text(v) for v in p.values])
    return out.getvalue()


def _value_text(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _format_um(value: float) -> str:
    return f"{value:.4g}"


class MarkerLayer:
    """The points in the 3-D view: a sphere per point (glyphs), a polyline through them in
    the order picked. Not pickable, so the probe and the handles ignore them."""

    def __init__(self, renderer: vtk.vtkRenderer) -> None:
        self._renderer = renderer
        self._points = vtk.vtkPoints()
        self._poly = vtk.vtkPolyData()
        self._poly.SetPoints(self._points)
        self._sphere = vtk.vtkSphereSource()
        self._sphere.SetThetaResolution(16)
        self._sphere.SetPhiResolution(12)
        glyphs = vtk.vtkGlyph3D()
        glyphs.SetInputData(self._poly)
        glyphs.SetSourceConnection(self._sphere.GetOutputPort())
        glyphs.ScalingOff()
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputConnection(glyphs.GetOutputPort())
        self.sphere_actor = vtk.vtkActor()
        self.sphere_actor.SetMapper(mapper)
        self.sphere_actor.GetProperty().SetColor(*MARKER_RGB)
        self.sphere_actor.PickableOff()
        self._line = vtk.vtkPolyData()
        line_mapper = vtk.vtkPolyDataMapper()
        line_mapper.SetInputData(self._line)
        self.line_actor = vtk.vtkActor()
        self.line_actor.SetMapper(line_mapper)
        self.line_actor.GetProperty().SetColor(*MARKER_RGB)
        self.line_actor.GetProperty().SetLineWidth(2.0)
        self.line_actor.GetProperty().LightingOff()
        self.line_actor.PickableOff()
        self._shown = False

    def set_points(self, positions_um: Sequence[tuple[float, float, float]],
                   radius_um: float) -> None:
        """Show spheres of ``radius_um`` at ``positions_um`` (world µm), joined in order."""
        self._points.Reset()
        for p in positions_um:
            self._points.InsertNextPoint(*p)
        self._points.Modified()
        self._poly.Modified()
        self._sphere.SetRadius(float(radius_um))
        line = vtk.vtkPolyData()
        line.SetPoints(self._points)
        if len(positions_um) >= 2:
            cells = vtk.vtkCellArray()
            cells.InsertNextCell(len(positions_um), list(range(len(positions_um))))
            line.SetLines(cells)
        self._line.DeepCopy(line)
        show = len(positions_um) > 0
        if show != self._shown:
            for actor in (self.sphere_actor, self.line_actor):
                if show:
                    self._renderer.AddActor(actor)
                else:
                    self._renderer.RemoveActor(actor)
            self._shown = show

    @property
    def count(self) -> int:
        return int(self._points.GetNumberOfPoints()) if self._shown else 0

    def close(self) -> None:
        self.set_points([], 1.0)


class MeasureDock(QDockWidget):
    """The point list: Pick points, the table, the distance, Delete, Clear, Export CSV…"""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Measure", parent)
        self.setObjectName("measure_dock")
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.setSpacing(4)
        self.pick_button = QPushButton("Pick points")
        self.pick_button.setObjectName("measure_pick")
        self.pick_button.setCheckable(True)
        self.pick_button.setToolTip("While on, a click in the 3-D view adds the first visible "
                                    "material under the pointer to the list")
        layout.addWidget(self.pick_button)
        self.table = QTableWidget(0, len(POSITION_COLUMNS))
        self.table.setObjectName("measure_table")
        self.table.setHorizontalHeaderLabels(list(POSITION_COLUMNS))
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.verticalHeader().setDefaultSectionSize(20)
        layout.addWidget(self.table, 1)
        self.distance_label = QLabel("")
        self.distance_label.setObjectName("measure_distance")
        self.distance_label.setWordWrap(True)
        layout.addWidget(self.distance_label)
        row = QHBoxLayout()
        row.setSpacing(4)
        self.delete_button = QPushButton("Delete")
        self.delete_button.setObjectName("measure_delete")
        self.delete_button.setToolTip("Remove the selected points")
        self.clear_button = QPushButton("Clear")
        self.clear_button.setObjectName("measure_clear")
        self.export_button = QPushButton("Export CSV…")
        self.export_button.setObjectName("measure_export")
        self.export_button.setToolTip("Write x_um, y_um, z_um and each channel's value per "
                                      "point to a CSV file")
        for button in (self.delete_button, self.clear_button, self.export_button):
            row.addWidget(button)
        layout.addLayout(row)
        self.setWidget(body)


class MeasureTool(QObject):
    """Picks, lists, draws and exports the measured points of one main window.

    ``window`` gets the dock (and its View-menu entry), ``viewport`` is its 3-D view,
    ``data_shown`` the signal that other data is on screen (the points are cleared), and
    ``start_dir`` gives the folder the export dialog opens in."""

    def __init__(self, window: QMainWindow, viewport: Viewport, data_shown: SignalInstance,
                 start_dir: Callable[[], str]) -> None:
        super().__init__(window)
        self.window = window
        self.viewport = viewport
        self._start_dir = start_dir
        self.points: list[MeasuredPoint] = []
        self._channel_names: list[str] = []
        self._press: tuple[float, float] | None = None
        self.markers = MarkerLayer(self.viewport.renderer)
        self.dock = MeasureDock(window)
        window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, self.dock)
        self.dock.hide()
        self.dock.pick_button.toggled.connect(self._on_pick_toggled)
        self.dock.delete_button.clicked.connect(self.delete_selected)
        self.dock.clear_button.clicked.connect(self.clear)
        self.dock.export_button.clicked.connect(self.export_interactive)
        self.dock.table.itemSelectionChanged.connect(self._show_distance)
        self.viewport.plotter.installEventFilter(self)
        #: Points of a session being opened, shown once its data is (window_state/restore).
        self._pending: tuple[list[MeasuredPoint], list[str]] | None = None
        data_shown.connect(self._on_data_shown)
        self._add_to_view_menu()
        self._refresh()

    def _add_to_view_menu(self) -> None:
        for action in self.window.menuBar().actions():
            menu = action.menu()
            if menu is not None and action.text().replace("&", "") == "View":
                menu.addAction(self.dock.toggleViewAction())
                return

    # -- picking --------------------------------------------------------------------------------
    @property
    def picking(self) -> bool:
        return self.dock.pick_button.isChecked()

    def _on_pick_toggled(self, on: bool) -> None:
        self.viewport.plotter.setCursor(Qt.CursorShape.CrossCursor if on
                                        else Qt.CursorShape.ArrowCursor)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        """A left click (not a drag) in the 3-D view picks a point while picking is on; the
        events go on to the camera either way."""
        if watched is self.viewport.plotter and self.picking:
            kind = event.type()
            if kind == QEvent.Type.MouseButtonPress and (
                    event.button() == Qt.MouseButton.LeftButton):  # type: ignore[attr-defined]
                pos = event.position()  # type: ignore[attr-defined]
                self._press = (float(pos.x()), float(pos.y()))
            elif kind == QEvent.Type.MouseButtonRelease and self._press is not None and (
                    event.button() == Qt.MouseButton.LeftButton):  # type: ignore[attr-defined]
                pos = event.position()  # type: ignore[attr-defined]
                x, y = float(pos.x()), float(pos.y())
                if math.hypot(x - self._press[0], y - self._press[1]) <= CLICK_SLOP_PX:
                    self.pick_at(x, y)
                self._press = None
        return super().eventFilter(watched, event)

    def pick_at(self, x: float, y: float) -> MeasuredPoint | None:
        """Add the first visible material under widget pixel (x, y) (Qt logical pixels from
        the top-left of the 3-D view); None (nothing added) when the ray meets none."""
        result = self.viewport.probe_at(x, y)
        if result is None:
            self.window.statusBar().showMessage("Nothing visible under the pointer to measure",
                                                4000)
            return None
        self._channel_names = list(result.names)
        point = MeasuredPoint.from_probe(result)
        self.points.append(point)
        self._refresh()
        return point

    def add(self, point: MeasuredPoint, channel_names: Sequence[str]) -> None:
        """Add a point (scripts and tests; the view adds through :meth:`pick_at`)."""
        self._channel_names = list(channel_names)
        self.points.append(point)
        self._refresh()

    def delete_selected(self) -> None:
        rows = {index.row() for index in self.dock.table.selectionModel().selectedRows()}
        if rows:
            self.points = [p for i, p in enumerate(self.points) if i not in rows]
            self._refresh()

    def clear(self) -> None:
        self.points = []
        self._refresh()

    # -- what is shown --------------------------------------------------------------------------
    def distance(self) -> float | None:
        """µm between the two selected points, or else the last two picked; None with fewer."""
        rows = sorted(index.row() for index in self.dock.table.selectionModel().selectedRows())
        if len(rows) == 2:
            return distance_um(self.points[rows[0]], self.points[rows[1]])
        if len(self.points) >= 2:
            return distance_um(self.points[-2], self.points[-1])
        return None

    def _show_distance(self) -> None:
        rows = sorted(index.row() for index in self.dock.table.selectionModel().selectedRows())
        d = self.distance()
        if d is None:
            text = ("Turn on Pick points and click the object in the 3-D view: the distance "
                    "between two points shows here" if not self.points else
                    "Pick a second point for a distance")
        elif len(rows) == 2:
            text = f"Distance {rows[0] + 1} – {rows[1] + 1}: {_format_um(d)} µm"
        else:
            n = len(self.points)
            text = f"Distance {n - 1} – {n}: {_format_um(d)} µm"
        self.dock.distance_label.setText(text)
        self.dock.delete_button.setEnabled(bool(rows))

    def _refresh(self) -> None:
        table = self.dock.table
        names = self._channel_names
        table.setColumnCount(len(POSITION_COLUMNS) + len(names))
        table.setHorizontalHeaderLabels([*POSITION_COLUMNS, *names])
        table.setRowCount(len(self.points))
        for r, p in enumerate(self.points):
            cells = [_format_um(v) for v in p.position_um] + [_value_text(v) for v in p.values]
            for c, text in enumerate(cells):
                table.setItem(r, c, QTableWidgetItem(text))
        table.clearSelection()
        self.dock.clear_button.setEnabled(bool(self.points))
        self.dock.export_button.setEnabled(bool(self.points))
        self._show_distance()
        b = self.viewport.bounds
        diagonal = float(np.linalg.norm([b[1] - b[0], b[3] - b[2], b[5] - b[4]])) or 1.0
        self.markers.set_points([p.position_um for p in self.points], MARKER_SHARE * diagonal)
        self.viewport.request_render()

    # -- sessions -------------------------------------------------------------------------------
    def window_state(self) -> dict[str, object]:
        """The points for a session's ``window`` section: ``{SESSION_KEY: {"channels": [...],
        "points": [{"position_um": [x, y, z], "index": [i, j, k], "values": [...]}]}}``
        (µm, voxel index, raw values); empty without points."""
        if not self.points:
            return {}
        return {SESSION_KEY: {
            "channels": list(self._channel_names),
            "points": [{"position_um": list(p.position_um), "index": list(p.index),
                        "values": list(p.values)} for p in self.points]}}

    def restore(self, window: dict[str, object]) -> None:
        """Keep the points of a session's ``window`` section to show with its data (the data
        arrives after the window is restored, and new data clears the list)."""
        self._pending = _read_points(window.get(SESSION_KEY))

    def _on_data_shown(self) -> None:
        pending, self._pending = self._pending, None
        self.points = []
        if pending is not None:
            self.points, self._channel_names = pending
        self._refresh()

    # -- export ---------------------------------------------------------------------------------
    def export_interactive(self) -> None:
        if not self.points:
            return
        start = Path(self._start_dir()) / "points.csv"
        chosen, _ = QFileDialog.getSaveFileName(
            self.window, "Export points", str(start), "CSV (*.csv)",
            options=QFileDialog.Option.DontConfirmOverwrite)  # asked below, testably
        if chosen:
            self.export(chosen)

    def export(self, path: str | Path) -> Path | None:
        """Write the points to ``path`` as CSV (:func:`csv_text`). An existing file is
        replaced only if the user confirms; a write that fails shows a dialog naming the
        file and why. Returns the path written, None when nothing was."""
        target = Path(path)
        text = csv_text(self.points, self._channel_names)
        try:
            try:
                written = write_atomic(target, text, replace=False)
            except FileExistsError:
                if not self._confirm_overwrite(target):
                    return None
                written = write_atomic(target, text, replace=True)
        except OSError as exc:
            errors.show_error(self.window, exc, action="Could not export the points")
            return None
        self.window.statusBar().showMessage(f"Exported {len(self.points)} points to {written}",
                                            6000)
        return written

    def _confirm_overwrite(self, path: Path) -> bool:
        box = QMessageBox(self.window)
        box.setWindowTitle(errors.APP_NAME)
        box.setIcon(QMessageBox.Icon.Question)
        box.setText(f"{path.name} already exists.")
        box.setInformativeText("Do you want to replace it?")
        box.setStandardButtons(QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No)
        box.setDefaultButton(QMessageBox.StandardButton.No)
        return errors.run_dialog(box) == QMessageBox.StandardButton.Yes


def _read_points(stored: object) -> tuple[list[MeasuredPoint], list[str]] | None:
    """The points of :meth:`MeasureTool.window_state`'s section; entries that are not three
    finite coordinates, three integers and numbers are skipped (None: no section)."""
    if not isinstance(stored, dict):
        return None
    names = stored.get("channels")
    names = [str(n) for n in names] if isinstance(names, list) else []
    points: list[MeasuredPoint] = []
    for entry in stored.get("points") or []:
        try:
            position = tuple(float(v) for v in entry["position_um"])
            index = tuple(int(v) for v in entry["index"])
            values = tuple(float(v) for v in entry["values"])
        except (KeyError, TypeError, ValueError):
            continue
        if len(position) == 3 and len(index) == 3 and all(map(math.isfinite, position)):
            points.append(MeasuredPoint(position, index, values))  # type: ignore[arg-type]
    return points, names
