"""Issue 25 §3: 3-D measurement in the app. Points picked on the rendered surface (a click in
the 3-D view with Pick points on), markers in the 3-D view, the distance in µm, the point list,
and its CSV export with the bad paths (a missing folder, a file in the way, an existing file
replaced only when confirmed). Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt
from PySide6.QtWidgets import QMessageBox

from vtkvol.ui import errors
from vtkvol.ui.measure import MARKER_RGB, MeasuredPoint, csv_text, distance_um

pytestmark = pytest.mark.gui


@pytest.fixture
def tool(opened_window):
    tool = opened_window.measure
    tool.clear()
    tool.dock.show()
    yield tool
    tool.dock.pick_button.setChecked(False)
    tool.clear()
    tool.dock.hide()


def visible_pixels(viewport, count: int) -> list[QPoint]:
    """``count`` widget pixels, around the view's centre, where the probe finds material."""
    w, h = viewport.plotter.width(), viewport.plotter.height()
    found: list[QPoint] = []
    for dx, dy in [(0, 0), (-25, -10), (25, 10), (-15, 20), (15, -20), (-35, 5), (35, -5)]:
        p = QPoint(w // 2 + dx, h // 2 + dy)
        if viewport.probe_at(p.x(), p.y()) is not None:
            found.append(p)
        if len(found) == count:
            return found
    raise AssertionError("too few pixels show material")


def marker_pixels(viewport) -> int:
    viewport.render_now()
    image = viewport.screenshot().astype(np.float64)
    target = np.array(MARKER_RGB) * 255.0
    return int((np.abs(image - target).max(axis=-1) < 40).sum())


def test_clicks_pick_points_on_the_surface_with_markers_and_distance(tool, qtbot):
    window, viewport = tool.window, tool.viewport
    viewport.render_now()
    a, b = visible_pixels(viewport, 2)
    plotter = viewport.plotter
    # Off: a click turns nothing into a point.
    qtbot.mouseClick(plotter, Qt.MouseButton.LeftButton, pos=a)
    assert tool.points == []
    assert marker_pixels(viewport) == 0
    tool.dock.pick_button.setChecked(True)
    qtbot.mouseClick(plotter, Qt.MouseButton.LeftButton, pos=a)
    qtbot.mouseClick(plotter, Qt.MouseButton.LeftButton, pos=b)
    expected = [viewport.probe_at(p.x(), p.y()) for p in (a, b)]
    assert [p.position_um for p in tool.points] == [r.position_um for r in expected]
    assert [p.values for p in tool.points] == [r.values for r in expected]
    # The point lies inside the data's box, on material the TF shows.
    bounds = viewport.bounds
    for p in tool.points:
        for axis in range(3):
            assert bounds[2 * axis] - 1e-6 <= p.position_um[axis] <= bounds[2 * axis + 1] + 1e-6
    # Listed, measured, drawn.
    table = tool.dock.table
    assert table.rowCount() == 2
    assert [table.horizontalHeaderItem(c).text() for c in range(table.columnCount())] == [
        "x µm", "y µm", "z µm", *window.data.channel_names]
    d = math.dist(*(p.position_um for p in tool.points))
    assert tool.distance() == pytest.approx(d)
    assert tool.dock.distance_label.text() == f"Distance 1 – 2: {d:.4g} µm"
    drawn = marker_pixels(viewport)
    assert drawn > 5
    # A drag turns the camera and adds no point.
    qtbot.mousePress(plotter, Qt.MouseButton.LeftButton, pos=a)
    qtbot.mouseMove(plotter, a + QPoint(15, 0))
    qtbot.mouseMove(plotter, a + QPoint(30, 0))
    qtbot.mouseRelease(plotter, Qt.MouseButton.LeftButton, pos=a + QPoint(30, 0))
    assert len(tool.points) == 2
    # Delete a selected row, then Clear: the markers go with them.
    table.selectRow(0)
    tool.dock.delete_button.click()
    assert [p.position_um for p in tool.points] == [expected[1].position_um]
    tool.dock.clear_button.click()
    assert tool.points == [] and table.rowCount() == 0
    assert marker_pixels(viewport) == 0


def test_distance_in_um_of_the_last_two_or_the_two_selected(tool):
    names = ["ch0"]
    for xyz in [(0.0, 0.0, 0.0), (3.0, 4.0, 12.0), (3.0, 4.0, 0.0)]:
        tool.add(MeasuredPoint(xyz, (0, 0, 0), (1.0,)), names)
    assert distance_um(tool.points[0], tool.points[1]) == pytest.approx(13.0)
    assert tool.dock.distance_label.text() == "Distance 2 – 3: 12 µm"
    table = tool.dock.table
    table.selectRow(0)
    table.selectionModel().select(table.model().index(1, 0),
                                  table.selectionModel().SelectionFlag.Select
                                  | table.selectionModel().SelectionFlag.Rows)
    assert tool.distance() == pytest.approx(13.0)
    assert tool.dock.distance_label.text() == "Distance 1 – 2: 13 µm"


def test_csv_export_and_its_bad_paths(tool, tmp_path, dialogs, monkeypatch):
    names = ["nuclei", "membrane"]
    tool.add(MeasuredPoint((1.5, 2.25, 3.0), (3, 9, 1), (1200.0, 7.5)), names)
    tool.add(MeasuredPoint((4.0, 0.0, 10.5), (8, 0, 5), (0.0, 33.0)), names)
    target = tmp_path / "points.csv"
    assert tool.export(target) == target
    with target.open(newline="") as f:
        rows = list(csv.reader(f))
    assert rows == [["x_um", "y_um", "z_um", "nuclei", "membrane"],
                    ["1.5", "2.25", "3.0", "1200", "7.5"],
                    ["4.0", "0.0", "10.5", "0", "33"]]
    assert target.read_text() == csv_text(tool.points, names)
    assert dialogs == []

    # An existing file: asked first; "No" (the default) leaves it alone.
    target.write_text("keep me\n")
    assert tool.export(target) is None
    assert target.read_text() == "keep me\n"
    [box] = dialogs
    assert box.text() == "points.csv already exists."
    # "Yes" replaces it.
    monkeypatch.setattr(errors, "run_dialog", lambda box: QMessageBox.StandardButton.Yes)
    assert tool.export(target) == target
    assert target.read_text() == csv_text(tool.points, names)

    # A folder that does not exist, and a file where a folder should be: one dialog each,
    # naming the file and the reason; nothing written.
    shown: list[QMessageBox] = []
    monkeypatch.setattr(errors, "run_dialog", lambda box: shown.append(box) or 0)
    missing = tmp_path / "no-such-folder" / "points.csv"
    assert tool.export(missing) is None
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    assert tool.export(blocker / "points.csv") is None
    assert [b.text() for b in shown] == ["Could not export the points"] * 2
    assert shown[0].informativeText() == f"{missing}: No such file or directory"
    assert shown[1].informativeText() == f"{blocker / 'points.csv'}: Not a directory"
    assert not missing.parent.exists()
    assert len(tool.points) == 2  # the list stays


def test_opening_other_data_clears_the_points(tool, qtbot, small_volume_file):
    tool.add(MeasuredPoint((1.0, 1.0, 1.0), (1, 1, 1), (5.0,)), ["ch0"])
    window = tool.window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(small_volume_file)
    assert tool.points == [] and tool.dock.table.rowCount() == 0
    assert tool.markers.count == 0


def test_the_view_menu_shows_the_measure_dock(tool):
    window = tool.window
    [view] = [a.menu() for a in window.menuBar().actions() if a.text() == "&View"]
    assert tool.dock.toggleViewAction() in view.actions()


def test_points_are_kept_in_sessions(tool, qtbot, tmp_path, dialogs):
    window = tool.window
    names = list(window.data.channel_names)
    picked = [MeasuredPoint((1.5, 2.0, 3.25), (3, 4, 1), (17.0,) * len(names)),
              MeasuredPoint((10.0, 0.5, 7.0), (20, 1, 3), (250.5,) * len(names))]
    for p in picked:
        tool.add(p, names)
    path = tmp_path / "measured.vtkvol.json"
    assert window.save_session(path) == path
    stored = json.loads(path.read_text())["window"]["measure_points"]
    assert stored["channels"] == names
    assert [e["position_um"] for e in stored["points"]] == [[1.5, 2.0, 3.25], [10.0, 0.5, 7.0]]
    tool.clear()
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert tool.points == picked
    assert tool.dock.table.rowCount() == 2 and tool.markers.count == 2
    assert tool.dock.distance_label.text() == (
        f"Distance 1 – 2: {math.dist(picked[0].position_um, picked[1].position_um):.4g} µm")
    # A hand-edited section: entries that are not points are skipped, the others kept.
    document = json.loads(path.read_text())
    document["window"]["measure_points"]["points"] += [
        {"position_um": [1, 2]}, {"position_um": ["x", 0, 0], "index": [0, 0, 0], "values": []},
        "junk", {"position_um": [None, 0, 0], "index": [0, 0, 0], "values": []}]
    path.write_text(json.dumps(document))
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert tool.points == picked
    # Other data opened afterwards starts without points.
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(window.data.source)
    assert tool.points == []
