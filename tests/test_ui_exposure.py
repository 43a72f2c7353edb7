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


def test_a_slow_measurement_leaves_the_frame_to_the_next_event_loop_pass(window, monkeypatch,
                                                                          qtbot):
    """Measuring frames and the frame in one paint held the event loop for both (0.65 s with
    the shadow volume on a loaded llvmpipe machine): after a measurement longer than
    SPLIT_WORK_MS the frame waits for the next pass, and events are handled in between."""
    import time

    from PySide6.QtCore import QTimer

    from vtkvol.ui.viewport import SPLIT_WORK_MS

    viewport, scene = window.viewport, window.viewport.scene
    window.model.illumination.method = "shadow_volume"
    window.model.render.auto_exposure = True
    viewport.render_now()
    events: list[str] = []
    measure = scene.update_exposure

    def slow() -> bool:
        changed = measure()
        if scene.exposure_measurement is not None and not events:
            time.sleep(2 * SPLIT_WORK_MS / 1e3)
            events.append("measured")
            QTimer.singleShot(0, lambda: events.append("event"))
        return changed

    monkeypatch.setattr(scene, "update_exposure", slow)
    viewport.frameRendered.connect(lambda *_: events.append("frame"))
    window.model.lights[0].intensity = 0.7  # the light changed: measured again
    qtbot.waitUntil(lambda: "frame" in events, timeout=60000)
    assert events[:3] == ["measured", "event", "frame"], events
