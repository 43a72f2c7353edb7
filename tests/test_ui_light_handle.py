"""Issue 25 §3: the light handle lay outside the view for a time-lapse's framing (a small
object framed in a large box). The handle of a directional light must lie inside the view
for every direction, after Reset view and after zooming in, and dragging it must still set
the direction from the centre it is drawn around. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from PySide6.QtCore import QPoint
from tests_support_time import write_time_lapse

pytestmark = pytest.mark.gui

#: The 26 directions of a cube's faces, edges and corners.
DIRECTIONS = [d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)]


def to_widget(viewport, world) -> QPoint:
    renderer = viewport.renderer
    renderer.SetWorldPoint(*world, 1.0)
    renderer.WorldToDisplay()
    x, y, _ = renderer.GetDisplayPoint()
    ratio = viewport.plotter.devicePixelRatioF()
    return QPoint(round(x / ratio), round(viewport.plotter.height() - y / ratio))


@pytest.fixture
def lapse_window(main_window, qtbot, tmp_path):
    """``main_window`` showing a time-lapse: a ball moving through a box 2.7× its size."""
    path = tmp_path / "lapse.tif"
    write_time_lapse(path, n_time=4)
    window = main_window
    window.time_player.pause()
    window.model.illumination.method = "local"
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(path)
    window.gizmo_action.setChecked(True)
    light = window.model.lights[0]
    light.kind = "directional"
    yield window
    window.time_player.pause()


def handles_outside(window) -> list[tuple[tuple[float, float, float], QPoint]]:
    viewport = window.viewport
    light = window.model.lights[0]
    rect = viewport.plotter.rect()
    outside = []
    for d in DIRECTIONS:
        light.direction = d
        viewport.render_now()
        assert viewport.gizmo.visible
        p = to_widget(viewport, viewport.gizmo.handle_position())
        if not rect.contains(p):
            outside.append((d, p))
    return outside


def test_the_handle_is_inside_the_time_lapse_framing_for_every_direction(lapse_window):
    window = lapse_window
    viewport = window.viewport
    window.reset_camera_action.trigger()
    # The framing is the ball's, not the box's: the box reaches well beyond the view.
    visible = viewport.scene.visible_bounds()
    box = viewport.bounds
    assert (visible[1] - visible[0]) < 0.8 * (box[1] - box[0])
    assert handles_outside(window) == []
    # Not squeezed onto the object either: the handle keeps a visible distance from it.
    light = window.model.lights[0]
    light.direction = (1.0, 0.0, 0.0)
    viewport.render_now()
    centre = to_widget(viewport, viewport.scene.renderer.GetActiveCamera().GetFocalPoint())
    handle = to_widget(viewport, viewport.gizmo.handle_position())
    size = min(viewport.plotter.width(), viewport.plotter.height())
    assert np.hypot(handle.x() - centre.x(), handle.y() - centre.y()) > 0.2 * size / 2


def test_the_handle_follows_a_zoom_into_the_view(lapse_window):
    window = lapse_window
    viewport = window.viewport
    window.reset_camera_action.trigger()
    camera = viewport.renderer.GetActiveCamera()
    camera.Zoom(3.0)
    viewport.scene.sync_camera_to_model()  # as the end of a camera drag does
    assert handles_outside(window) == []


def test_dragging_the_handle_sets_the_direction_from_its_centre(lapse_window):
    window = lapse_window
    viewport = window.viewport
    window.reset_camera_action.trigger()
    light = window.model.lights[0]
    light.direction = (0.0, 0.0, 1.0)
    viewport.render_now()
    centre = np.array(viewport.renderer.GetActiveCamera().GetFocalPoint())
    target = centre + np.array([1.0, -1.0, 0.0])  # where the handle widget moved it
    viewport._gizmo_moved(target)
    assert light.direction == pytest.approx(tuple(np.array([1.0, -1.0, 0.0]) / np.sqrt(2)))
