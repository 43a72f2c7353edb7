"""The intensity probe: the first visible voxel under a point of the view, and its values."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

from vtkvol.engine.offscreen import grab, make_render_window
from vtkvol.engine.probe import probe
from vtkvol.engine.scene import VolumeScene
from vtkvol.io import VolumeData
from vtkvol.model.defaults import scene_for


def two_channel_cube() -> VolumeData:
    arr = np.zeros((2, 24, 24, 24), np.uint16)
    arr[0, 8:16, 8:16, 8:16] = 1000
    arr[1, 8:16, 8:16, 8:16] = 7
    arr[0, 11, 11, 11] = 1234  # one marked voxel, inside
    return VolumeData.from_array(arr, (1.0, 1.0, 2.0), ["DAPI", "GFP"])


@pytest.mark.gl
def test_probe_reports_the_first_visible_voxel_not_the_empty_box_in_front():
    data = two_channel_cube()
    rw = make_render_window((96, 96))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    scene = VolumeScene(ren, scene_for(data), data, request_render=lambda: None)
    scene.reset_camera(azimuth=30.0, elevation=20.0)
    grab(rw)
    hit = probe(ren, scene.volume, data, 48, 48)
    assert hit is not None
    i, j, k = hit.index
    assert 8 <= i < 16 and 8 <= j < 16 and 8 <= k < 16  # inside the cube, on its near face
    assert hit.values == (1000.0, 7.0) and hit.names == ("DAPI", "GFP")
    # the position is in µm: z voxels are 2 µm
    assert 16.0 - 2.5 <= hit.position_um[2] <= 32.0 + 2.5
    assert hit.text().endswith("DAPI 1000 · GFP 7") and " µm · voxel (" in hit.text()
    assert probe(ren, scene.volume, data, 2, 2) is None  # background: nothing visible
    scene.close()
    rw.Finalize()


@pytest.mark.gui
def test_the_app_shows_the_probe_in_the_status_bar(opened_window, qtbot):
    from PySide6.QtCore import QPointF, Qt
    from PySide6.QtGui import QMouseEvent
    from PySide6.QtWidgets import QApplication

    window = opened_window
    viewport = window.viewport
    viewport.render_now()
    widget = viewport.plotter

    def move(x: float, y: float) -> None:
        pos = QPointF(x, y)
        event = QMouseEvent(QMouseEvent.Type.MouseMove, pos, widget.mapToGlobal(pos),
                            Qt.MouseButton.NoButton, Qt.MouseButton.NoButton,
                            Qt.KeyboardModifier.NoModifier)
        QApplication.sendEvent(widget, event)

    # the centre of the view shows the data: the label names a voxel and a value
    with qtbot.waitSignal(viewport.probed, timeout=5000) as blocker:
        move(widget.width() / 2, widget.height() / 2)
    text = blocker.args[0]
    assert " µm · voxel (" in text and window.probe_label.text() == text
    expected = viewport.probe_at(widget.width() / 2, widget.height() / 2)
    assert expected is not None and text == expected.text()
    value = expected.values[0]
    i, j, k = expected.index
    assert value == float(window.data.array[0, k, j, i])
    # a corner shows background: the label empties
    with qtbot.waitSignal(viewport.probed, timeout=5000) as blocker:
        move(1, 1)
    assert blocker.args[0] == "" and window.probe_label.text() == ""
