"""Issue 15's responsiveness in the app: dock drags render at the interactive quality and
settle to full quality, long precomputation runs in chunks behind a progress dialog whose
Cancel leaves local shading, repaints that change nothing render no frame, and a cancelled
tiled screenshot writes nothing. Needs X (pytest-xvfb) and GL; no timing is asserted (the
stall measurements are in benchmarks/app_responsiveness.py and docs/app.md)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import QApplication, QMessageBox

from vtkvol.model.scene import SceneModel
from vtkvol.ui.progress import ChunkProgress
from vtkvol.ui.undo import apply_state
from vtkvol.ui.viewport import SETTLE_MS

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def pristine() -> dict[str, Any]:
    return {}


@pytest.fixture
def window(opened_window, pristine, qtbot):
    """The module's window with the small volume, reset to its opened state after each test."""
    if not pristine:
        pristine.update(opened_window.model.model_dump())
    viewport = opened_window.viewport
    factory = viewport.progress_factory
    yield opened_window
    viewport.progress_factory = factory
    QApplication.processEvents()
    apply_state(opened_window.model, pristine)
    opened_window.recorder.reset()
    opened_window.document.unsaved_data_edit = False
    settle(opened_window, qtbot)


def settle(window, qtbot) -> None:
    """Run the event loop until the view is idle: no render and no settle pending."""
    viewport = window.viewport
    qtbot.waitUntil(lambda: not viewport._render_timer.isActive()
                    and not viewport._settle_timer.isActive() and not viewport.busy,
                    timeout=60_000)
    qtbot.wait(SETTLE_MS + 50)
    qtbot.waitUntil(lambda: not viewport._render_timer.isActive()
                    and not viewport._settle_timer.isActive(), timeout=60_000)
    QApplication.processEvents()


def mouse(widget, kind, pos: QPoint, button, buttons) -> None:
    event = QMouseEvent(kind, QPointF(pos), QPointF(widget.mapToGlobal(pos)), button, buttons,
                        Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(widget, event)  # through the application's event filters


class FrameLog:
    """Every frame's sample distance (µm) and whether it had the reduced image size."""

    def __init__(self, viewport) -> None:
        self.viewport = viewport
        self.frames: list[tuple[float, float]] = []
        viewport.frameRendered.connect(self._on_frame)

    def _on_frame(self, *_: Any) -> None:
        mapper = self.viewport.scene.mapper
        self.frames.append((mapper.GetSampleDistance(), mapper.GetImageSampleDistance()))

    def close(self) -> None:
        self.viewport.frameRendered.disconnect(self._on_frame)


class CancellingProgress(ChunkProgress):
    """Shows its dialog at once and presses its Cancel button at call ``cancel_at``."""

    instances: ClassVar[list[CancellingProgress]] = []

    def __init__(self, parent, label: str, cancel_at: int | None) -> None:
        super().__init__(parent, label, show_after_s=0.0)
        self.cancel_at = cancel_at
        self.fractions: list[float] = []
        self.dialog_seen = False
        CancellingProgress.instances.append(self)

    def __call__(self, fraction: float, text: str | None = None) -> bool:
        self.fractions.append(fraction)
        answer = super().__call__(fraction, text)
        if self.dialog is not None and self.dialog.isVisible():
            self.dialog_seen = True
            if self.cancel_at is not None and len(self.fractions) >= self.cancel_at:
                # What the user's click does: the dialog's own Cancel.
                self.dialog.cancel()
                return False
        return answer


def use_progress(viewport, cancel_at: int | None) -> list[CancellingProgress]:
    CancellingProgress.instances = []
    viewport.progress_factory = lambda label: CancellingProgress(viewport.window(), label,
                                                                 cancel_at)
    return CancellingProgress.instances


def drag_tf(window, qtbot, moves: int = 3) -> None:
    """Press in the TF editor, move ``moves`` times (each move lets a frame render)."""
    window.tf_dock.raise_()
    editor = window.tf_dock.editor
    rect = editor.plot_rect()
    x = round(rect.left() + 0.5 * rect.width())
    left, none = Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton
    mouse(editor, QMouseEvent.Type.MouseButtonPress,
          QPoint(x, round(rect.top() + 0.7 * rect.height())), left, left)
    for i in range(moves):
        y = round(rect.top() + (0.5 - 0.1 * i) * rect.height())
        mouse(editor, QMouseEvent.Type.MouseMove, QPoint(x, y), none, left)
        qtbot.wait(120)  # the editor's 60 ms throttle, then the coalesced frame


def release_tf(window) -> None:
    editor = window.tf_dock.editor
    rect = editor.plot_rect()
    mouse(editor, QMouseEvent.Type.MouseButtonRelease,
          QPoint(round(rect.center().x()), round(rect.center().y())),
          Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton)


# -- dock drags ----------------------------------------------------------------------------------
def test_tf_drag_renders_interactive_frames_then_one_full_quality_frame(window, qtbot):
    model: SceneModel = window.model
    model.illumination.method = "local"
    settle(window, qtbot)
    viewport = window.viewport
    spacing = min(window.data.voxel_size_um)
    interactive = model.render.interactive_sample_distance * spacing
    full = model.render.sample_distance * spacing
    assert interactive > full  # the two qualities can be told apart
    opacity_before = list(model.channels[0].tf.opacity)
    log = FrameLog(viewport)
    try:
        drag_tf(window, qtbot)
        qtbot.waitUntil(lambda: len(log.frames) >= 1, timeout=30_000)
        assert viewport.editing
        during = list(log.frames)
        assert model.channels[0].tf.opacity != opacity_before  # the drag edited the TF
        assert all(d == pytest.approx(interactive) for d, _ in during), during
        assert all(f == model.render.interactive_image_factor for _, f in during), during
        release_tf(window)  # may send the stroke's last edit: one more reduced frame
        assert not viewport.editing
        qtbot.waitUntil(lambda: log.frames[-1][1] == 1.0, timeout=30_000)
        settle(window, qtbot)
        # Reduced frames until the edit settled, then exactly one full-quality frame.
        *reduced, last = log.frames
        assert all(d == pytest.approx(interactive) for d, _ in reduced), log.frames
        assert last == (pytest.approx(full), 1.0), log.frames
    finally:
        log.close()


def test_a_press_in_a_dock_that_changes_nothing_renders_nothing(window, qtbot):
    settle(window, qtbot)
    viewport = window.viewport
    count = viewport.frame_count
    label = window.channels_dock.widget()
    left, none = Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton
    mouse(label, QMouseEvent.Type.MouseButtonPress, QPoint(2, 2), left, left)
    assert viewport.editing
    mouse(label, QMouseEvent.Type.MouseButtonRelease, QPoint(2, 2), left, none)
    assert not viewport.editing
    settle(window, qtbot)
    assert viewport.frame_count == count


def test_shadow_volume_waits_during_a_drag_and_recomputes_once_it_settles(window, qtbot):
    model = window.model
    model.illumination.method = "shadow_volume"
    use_progress(window.viewport, cancel_at=None)
    settle(window, qtbot)
    illuminator = window.viewport.scene.illuminator
    assert illuminator.method == "shadow_volume"
    recomputes = illuminator.technique.stats()["recomputes"]
    log = FrameLog(window.viewport)
    try:
        drag_tf(window, qtbot, moves=2)
        qtbot.waitUntil(lambda: len(log.frames) >= 1, timeout=30_000)
        # Frames of the drag keep the previous light volume.
        assert illuminator.technique.stats()["recomputes"] == recomputes
        assert illuminator.defer_precompute and illuminator.has_pending_changes
        release_tf(window)
        qtbot.waitUntil(lambda: illuminator.technique.stats()["recomputes"] == recomputes + 1,
                        timeout=60_000)
        settle(window, qtbot)
        assert not illuminator.defer_precompute and not illuminator.has_pending_changes
        assert illuminator.technique.stats()["recomputes"] == recomputes + 1
    finally:
        log.close()


# -- long precomputation -------------------------------------------------------------------------
def test_precompute_runs_in_chunks_behind_a_progress_dialog(window, qtbot):
    window.model.illumination.method = "local"
    settle(window, qtbot)
    runs = use_progress(window.viewport, cancel_at=None)
    window.model.illumination.method = "shadow_volume"
    qtbot.waitUntil(lambda: any(r.fractions for r in runs), timeout=30_000)
    settle(window, qtbot)
    run = next(r for r in runs if r.fractions)
    assert run.dialog_seen and run.dialog is None  # shown while it ran, gone after
    assert len(run.fractions) >= 3  # more than one chunk: the event loop ran in between
    assert run.fractions == sorted(run.fractions) and run.fractions[-1] == pytest.approx(1.0)
    technique = window.viewport.scene.illuminator.technique
    assert technique.NAME == "shadow_volume" and technique.stats()["recomputes"] == 1


def test_cancel_shows_local_shading_and_says_so(window, qtbot):
    model = window.model
    model.illumination.method = "local"
    settle(window, qtbot)
    viewport = window.viewport
    viewport.render_now()
    local = viewport.screenshot().astype(np.float64)
    runs = use_progress(viewport, cancel_at=2)
    model.illumination.method = "shadow_volume"
    qtbot.waitUntil(lambda: model.illumination.method == "local", timeout=30_000)
    settle(window, qtbot)
    run = next(r for r in runs if r.fractions)
    assert run.dialog_seen and run.fractions[-1] < 1.0  # cancelled half-way
    illuminator = viewport.scene.illuminator
    assert illuminator.method == "local" and illuminator.cancelled_method == "shadow_volume"
    assert illuminator.bound_textures() == {}  # nothing of the cancelled technique is left
    assert window.lights_dock.method.currentData() == "local"
    assert "Precomputed shadow volume cancelled" in window.statusBar().currentMessage()
    # The view is local shading again, exactly.
    viewport.progress_factory = lambda label: ChunkProgress(viewport.window(), label)
    viewport.render_now()
    after = viewport.screenshot().astype(np.float64)
    assert np.abs(after - local).max() <= 2.0
    # Choosing the method again computes it.
    model.illumination.method = "shadow_volume"
    qtbot.waitUntil(lambda: illuminator.technique is not None
                    and illuminator.technique.NAME == "shadow_volume"
                    and illuminator.technique.stats()["recomputes"] == 1, timeout=60_000)


# -- nothing renders that did not change ---------------------------------------------------------
def test_menus_dialogs_and_repaints_render_no_frame(window, qtbot):
    settle(window, qtbot)
    viewport = window.viewport
    count = viewport.frame_count
    menu = window.menuBar().actions()[0].menu()
    menu.popup(viewport.mapToGlobal(QPoint(20, 20)))  # over the 3-D view
    qtbot.waitUntil(menu.isVisible, timeout=5_000)
    qtbot.wait(150)
    menu.close()
    qtbot.wait(150)
    box = QMessageBox(QMessageBox.Icon.Information, "vtkvol", "A dialog over the view",
                      QMessageBox.StandardButton.Ok, window)
    box.show()
    qtbot.wait(150)
    box.close()
    viewport.plotter.update()  # a repaint nobody asked a frame for
    viewport.plotter.repaint()
    qtbot.wait(150)
    assert viewport.frame_count == count
    # ... while a real request still renders one frame.
    viewport.request_render()
    qtbot.waitUntil(lambda: viewport.frame_count == count + 1, timeout=30_000)
    settle(window, qtbot)
    assert viewport.frame_count == count + 1


# -- tiled screenshots ---------------------------------------------------------------------------
def test_tiled_screenshot_reports_each_tile(window, qtbot, tmp_path):
    settle(window, qtbot)
    runs = use_progress(window.viewport, cancel_at=None)
    target = tmp_path / "view2x.png"
    assert window.save_screenshot(target, scale=2) == target
    run = next(r for r in runs if "screenshot" in r._label)
    assert run.fractions[:4] == pytest.approx([0.25, 0.5, 0.75, 1.0])
    assert target.stat().st_size > 0


def test_cancelled_tiled_screenshot_writes_nothing(window, qtbot, tmp_path):
    settle(window, qtbot)
    viewport = window.viewport
    volume = viewport.scene.volume
    existing = tmp_path / "kept.png"
    existing.write_bytes(b"the user's earlier picture")
    runs = use_progress(viewport, cancel_at=1)
    assert window.save_screenshot(existing, scale=2) is None
    assert existing.read_bytes() == b"the user's earlier picture"
    fresh = tmp_path / "new.png"
    assert window.save_screenshot(fresh, scale=4) is None
    assert not fresh.exists()
    assert list(tmp_path.iterdir()) == [existing]  # no temporary file left either
    assert "Screenshot cancelled" in window.statusBar().currentMessage()
    assert any(r.dialog_seen for r in runs)
    assert volume.GetVisibility()  # the view shows the volume again
    settle(window, qtbot)


def test_closing_the_window_during_a_precompute_stops_it_cleanly(qapp, qtbot, tmp_path,
                                                                  small_volume):
    from PySide6.QtCore import QSettings

    from vtkvol.ui.app import MainWindow

    other = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    other.resize(600, 500)
    other.viewport.setMaximumSize(128, 128)
    other.show()
    other.show_volume(small_volume)
    scene = other.viewport.scene
    illuminator = scene.illuminator
    qtbot.waitUntil(lambda: illuminator.render_window is not None, timeout=30_000)  # a frame
    calls: list[float] = []

    def close_at_first_chunk(label: str) -> ChunkProgress:
        class Closing(ChunkProgress):
            def __call__(self, fraction: float, text: str | None = None) -> bool:
                calls.append(fraction)
                if len(calls) == 1:
                    other.close()  # what the window's close button does meanwhile
                return super().__call__(fraction, text)

        return Closing(other, label)

    other.viewport.progress_factory = close_at_first_chunk
    other.model.illumination.method = "shadow_volume"
    qtbot.waitUntil(lambda: other.viewport.closed, timeout=30_000)
    qtbot.wait(50)
    assert len(calls) == 1  # no chunk ran after the close
    assert illuminator.closed and not illuminator.precomputing
    assert not other.viewport.busy


def test_crop_slider_drag_renders_interactive_frames_then_one_full_quality_frame(window, qtbot):
    model: SceneModel = window.model
    model.illumination.method = "local"
    window.ranges_dock.raise_()
    settle(window, qtbot)
    viewport = window.viewport
    spacing = min(window.data.voxel_size_um)
    interactive = model.render.interactive_sample_distance * spacing
    full = model.render.sample_distance * spacing
    slider = window.ranges_dock.sliders["x"]
    left, none = Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton
    y = slider.height() // 2
    log = FrameLog(viewport)
    try:
        # The lower handle sits at the left end: drag it to the right.
        mouse(slider, QMouseEvent.Type.MouseButtonPress, QPoint(3, y), left, left)
        assert viewport.editing
        for x in (slider.width() // 5, slider.width() // 3):
            mouse(slider, QMouseEvent.Type.MouseMove, QPoint(x, y), none, left)
            qtbot.wait(60)
        qtbot.waitUntil(lambda: len(log.frames) >= 1, timeout=30_000)
        assert model.crop.x is not None and model.crop.x[0] > 0  # the drag cropped
        assert all(d == pytest.approx(interactive) for d, _ in log.frames), log.frames
        mouse(slider, QMouseEvent.Type.MouseButtonRelease, QPoint(slider.width() // 3, y),
              left, none)
        assert not viewport.editing
        qtbot.waitUntil(lambda: log.frames[-1][1] == 1.0, timeout=30_000)
        settle(window, qtbot)
        *reduced, last = log.frames
        assert all(d == pytest.approx(interactive) for d, _ in reduced), log.frames
        assert last == (pytest.approx(full), 1.0), log.frames
    finally:
        log.close()
