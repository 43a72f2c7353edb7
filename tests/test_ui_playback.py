"""Issue 25 §1 playback: never a step backwards, "every point" and "real time" modes, a true
rate, and one frame (not two) for a step to a time point not read yet. Needs X and GL; the
player's clock and the view's readiness are driven by the tests, no timing is asserted."""

from __future__ import annotations

import itertools
import time

import pytest
from tests_support_time import write_time_lapse

from vtkvol.ui import time_series as time_module

pytestmark = pytest.mark.gui

N_POINTS = 5


@pytest.fixture
def lapse_window(main_window, qtbot, tmp_path):
    """``main_window`` showing a 5-point stack at time point 0, local shading, looping."""
    path = tmp_path / "lapse5.tif"
    write_time_lapse(path, N_POINTS)
    window = main_window
    window.time_player.pause()
    window.model.illumination.method = "local"
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(path)
    window.time_player.loop = True
    yield window
    window.time_player.pause()
    window.time_player.every_point = False


def read_all(window, qtbot) -> None:
    """Every time point into the cache (then only the clock decides what is shown)."""
    player = window.time_player
    for index in range(1, N_POINTS):
        player.go_to(index)
        qtbot.waitUntil(lambda i=index: player.shown_index == i and not player.pending,
                        timeout=20_000)
    player.go_to(0)
    qtbot.waitUntil(lambda: player.shown_index == 0, timeout=20_000)


def tick(window, qtbot) -> None:
    """One playback tick once the view has drawn the last point, then until it is read."""
    player = window.time_player
    qtbot.waitUntil(lambda: not window.viewport.frame_pending, timeout=20_000)
    player._tick()
    qtbot.waitUntil(lambda: not player.pending, timeout=20_000)


class FakeClock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch):
    fake = FakeClock()
    monkeypatch.setattr(time_module.time, "perf_counter", fake)
    return fake


def test_a_slow_view_never_makes_playback_step_backwards(lapse_window, qtbot, clock):
    """At 5 fps with 0.8 s between ticks (the frames were that slow), the clock passes four
    of the five points between two ticks (it showed 0 → 4 → 3 → 2: backwards, as the issue
    saw); the point shown only moves forward, wrapping only past the last point."""
    window = lapse_window
    player = window.time_player
    read_all(window, qtbot)
    player.fps = 5.0
    player.play()
    player._timer.stop()  # the test ticks
    shown = [player.shown_index]
    for _ in range(12):
        clock.now += 0.8
        tick(window, qtbot)
        shown.append(player.shown_index)
    player.pause()
    steps = list(itertools.pairwise(shown))
    assert all(b > a or (b < a and a == N_POINTS - 1) for a, b in steps), shown


def test_every_point_mode_shows_each_point_once_in_order(lapse_window, qtbot, clock):
    window = lapse_window
    player = window.time_player
    read_all(window, qtbot)
    window.time_bar.every_point_box.setChecked(True)
    assert player.every_point
    player.fps = 5.0
    player.play()
    player._timer.stop()
    shown = [player.shown_index]
    for _ in range(7):
        clock.now += 3.0  # far slower than 5 fps: real time would skip points
        tick(window, qtbot)
        shown.append(player.shown_index)
    player.pause()
    assert shown == [0, 1, 2, 3, 4, 0, 1, 2]
    assert player.skipped_points == 0


def test_every_point_waits_for_the_view_to_draw_the_point(lapse_window, qtbot, clock):
    window = lapse_window
    player = window.time_player
    read_all(window, qtbot)
    player.every_point = True
    player.fps = 5.0
    ready = {"value": False}
    player.view_ready = lambda: ready["value"]
    try:
        player.play()
        player._timer.stop()
        clock.now += 0.2
        player._tick()
        assert player.shown_index == 0  # the view has not drawn point 0 yet
        ready["value"] = True
        player._tick()
        assert player.shown_index == 1
    finally:
        player.view_ready = None
        player.pause()


def test_the_rate_is_the_points_shown_per_second(lapse_window, qtbot, clock):
    """Points shown 2.5 s apart: 0.4 points/s (the label said 0.0 once frames took longer
    than its 2-second window)."""
    window = lapse_window
    player = window.time_player
    read_all(window, qtbot)
    player.every_point = True
    player.fps = 0.1  # the timer stays quiet (it must run: the rate is reported while playing)
    rates: list[float] = []
    player.rateChanged.connect(rates.append)
    player.play()
    for _ in range(4):
        clock.now += 2.5
        tick(window, qtbot)
    player.rateChanged.disconnect(rates.append)
    player.pause()
    assert rates[-1] == pytest.approx(0.4)
    assert window.time_rate_label.text() == ""  # paused: no rate shown


def test_a_step_to_a_point_not_read_yet_renders_one_frame(lapse_window, qtbot, monkeypatch):
    """The step used to render the old point again at once, then the new one once read."""
    real = time_module.read_volume

    def slow(path, *, time_index, **kwargs):
        time.sleep(0.5)  # a read as slow as a real stack's
        return real(path, time_index=time_index, **kwargs)

    monkeypatch.setattr(time_module, "read_volume", slow)
    window = lapse_window
    player = window.time_player
    viewport = window.viewport
    qtbot.waitUntil(lambda: not viewport._render_timer.isActive(), timeout=20_000)
    qtbot.wait(300)
    before = viewport.frame_count
    player.step(1)
    qtbot.waitUntil(lambda: player.shown_index == 1 and not player.pending, timeout=20_000)
    qtbot.waitUntil(lambda: not viewport._render_timer.isActive(), timeout=20_000)
    qtbot.wait(300)
    assert viewport.frame_count - before == 1
