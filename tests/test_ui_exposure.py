"""Issue 25 §2 in the app: the lights dock's exposure controls edit the model, and a full
frame with shadows on measures the automatic exposure before it renders (not while the view
moves). Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import pytest
from PySide6.QtWidgets import QApplication

from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


@pytest.fixture
def window(opened_window, qtbot):
    pristine = opened_window.model.model_dump()
    yield opened_window
    apply_state(opened_window.model, pristine)
    opened_window.recorder.reset()
    QApplication.processEvents()


def test_dock_edits_exposure_auto_and_fill(window):
    dock, render = window.lights_dock, window.model.render
    dock.exposure.setValue(1.5)
    dock.fill.setValue(0.4)
    dock.auto_exposure.setChecked(False)
    assert (render.exposure, render.fill, render.auto_exposure) == (1.5, 0.4, False)
    render.exposure = 0.8
    assert dock.exposure.value() == pytest.approx(0.8)


def test_a_full_frame_with_shadows_measures_the_exposure(window):
    scene, viewport = window.viewport.scene, window.viewport
    window.model.illumination.method = "shadow_volume"
    window.model.render.auto_exposure = True
    viewport.render_now()
    measurement = scene.exposure_measurement
    assert measurement is not None and measurement.pixels > 0
    assert measurement.local_mean > measurement.method_mean  # the shadows took light away
    assert scene.auto_exposure_factor == pytest.approx(measurement.factor)
    assert scene.illuminator.exposure == pytest.approx(window.model.render.exposure
                                                       * measurement.factor)
    # Turning the view does not measure again; switching automatic off drops the factor.
    scene.orbit(30.0, 0.0)
    viewport.render_now()
    assert scene.exposure_measurement is measurement
    window.model.render.auto_exposure = False
    assert scene.illuminator.exposure == pytest.approx(window.model.render.exposure)


def test_measuring_frames_are_not_the_views_frames(window, monkeypatch):
    """The two coarse measuring frames neither take the planned strip nor count as frames
    (the refiner learns its cost per row from the view's frames only)."""
    viewport, scene = window.viewport, window.viewport.scene
    window.model.illumination.method = "shadow_volume"
    window.model.render.auto_exposure = True
    seen = []
    measure = scene.update_exposure

    def counted() -> bool:
        before = (viewport.frame_count, len(viewport.refiner.__dict__))
        changed = measure()
        seen.append((before[0], viewport.frame_count, scene.exposure_measurement))
        return changed

    monkeypatch.setattr(scene, "update_exposure", counted)
    window.model.lights[0].intensity = 0.9  # the light changed: measured again
    viewport.render_now()
    measured = [s for s in seen if s[2] is not None]
    assert measured, "no measurement ran before the full frame"
    assert all(before == after for before, after, _ in measured)
