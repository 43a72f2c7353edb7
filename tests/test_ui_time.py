"""Time-lapse playback in the app: the time slider, stepping, Play, the time-point cache,
sessions that keep the time point, and reads that fail (pytest-qt under Xvfb)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from PySide6.QtCore import Qt
from tests_support_time import N_TIME, write_time_lapse

from vtkvol.io import VolumeReadError
from vtkvol.io.time_series import TimePointCache, format_time, time_point_count
from vtkvol.ui import time_series as time_module

pytestmark = pytest.mark.gui

@pytest.fixture
def lapse_file(tmp_path):
    path = tmp_path / "lapse.tif"
    write_time_lapse(path)
    return path


@pytest.fixture
def lapse_window(main_window, qtbot, lapse_file):
    """``main_window`` showing the 20-point stack at time point 0, local shading."""
    window = main_window
    window.time_player.pause()
    window.model.illumination.method = "local"
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(lapse_file)
    window.time_player.loop = True
    window.time_player.fps = 10.0
    yield window
    window.time_player.pause()


@pytest.fixture
def read_calls(monkeypatch):
    """Time points the player reads (its reader, wrapped)."""
    calls: list[int] = []
    real = time_module.read_volume

    def counting(path, *, time_index, **kwargs):
        calls.append(time_index)
        return real(path, time_index=time_index, **kwargs)

    monkeypatch.setattr(time_module, "read_volume", counting)
    return calls


def wait_shown(window, qtbot, index: int) -> None:
    qtbot.waitUntil(lambda: window.time_player.shown_index == index
                    and not window.time_player.pending, timeout=20_000)


def frame(window) -> np.ndarray:
    window.viewport.render_now()
    return window.viewport.screenshot().astype(np.float64)


# -- pure parts -----------------------------------------------------------------------------
def test_cache_is_lru_and_bounded_in_bytes(small_volume):
    size = small_volume.nbytes
    cache = TimePointCache(3 * size)
    for t in range(5):
        assert cache.put(t, small_volume)
        assert cache.nbytes <= cache.max_bytes
    assert list(cache) == [2, 3, 4]
    assert cache.get(2) is small_volume  # now the most recently used
    cache.put(5, small_volume)
    assert list(cache) == [4, 2, 5] and cache.nbytes == 3 * size
    cache.max_bytes = size
    assert list(cache) == [5] and cache.nbytes == size
    assert not TimePointCache(size - 1).put(0, small_volume)  # larger than the bound alone
    with pytest.raises(ValueError, match="number of bytes"):
        cache.max_bytes = -1


def test_time_axis_from_hostile_metadata():
    assert time_point_count({"time_points": 20}) == 20
    for lie in (0, -3, 2.5, float("nan"), "20", True, 10**12, None):
        assert time_point_count({"time_points": lie}) == 1
    assert format_time(3, 30.0) == "90 s"
    assert format_time(7, 30.0) == "3.5 min"
    assert format_time(3, None) == ""


def test_the_reader_reports_the_frame_interval(lapse_file):
    from vtkvol.io import read_volume

    data = read_volume(lapse_file, time_index=4)
    assert data.metadata["time_points"] == N_TIME
    assert data.metadata["time_interval_s"] == 30.0
    assert "time point: index 4 of 20 (0–19), 30 s apart" in data.describe()


# -- the app --------------------------------------------------------------------------------
def test_the_slider_appears_with_20_points_and_only_for_time_series(
        main_window, qtbot, lapse_file, small_volume_file):
    window = main_window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(small_volume_file)
    assert not window.time_toolbar.isVisible()
    assert not window.time_forward_action.isEnabled()
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(lapse_file)
    bar = window.time_bar
    assert window.time_toolbar.isVisible()
    assert (bar.slider.minimum(), bar.slider.maximum(), bar.slider.value()) == (0, 19, 0)
    assert bar.label.text() == "of 20 · 0 s"
    window.time_bar_action.setChecked(False)  # View → Time slider hides it
    assert not window.time_toolbar.isVisible()
    window.time_bar_action.setChecked(True)
    assert window.time_toolbar.isVisible()


def test_stepping_shows_the_next_time_point_and_keeps_the_view(lapse_window, qtbot):
    window = lapse_window
    model = window.model
    model.channels[0].tf.opacity = [(200.0, 0.0), (1500.0, 0.8)]
    model.crop.z = (1.0, 10.0)
    before = frame(window)
    kept = (model.channels[0].tf.copy_state(), model.camera.model_dump(),
            model.crop.model_dump(), model.lights[0].model_dump())
    window.activateWindow()
    qtbot.waitUntil(lambda: window.isActiveWindow(), timeout=3000)
    for _ in range(4):
        qtbot.keyClick(window.viewport.plotter, Qt.Key.Key_Period)  # "." = next time point
    wait_shown(window, qtbot, 4)
    after = frame(window)
    assert model.volume.time_index == 4
    assert window.data.metadata["time_index"] == 4
    assert window.time_bar.slider.value() == 4
    assert window.time_bar.label.text() == "of 20 · 2 min"
    # The ball moved 4 voxels along x: the picture changed, the view did not.
    assert np.abs(after - before).mean() > 1.0
    assert kept == (model.channels[0].tf.copy_state(), model.camera.model_dump(),
                    model.crop.model_dump(), model.lights[0].model_dump())
    qtbot.keyClick(window.viewport.plotter, Qt.Key.Key_Comma)  # "," = previous
    wait_shown(window, qtbot, 3)


def test_a_new_time_point_recomputes_the_illumination(lapse_window, qtbot):
    window = lapse_window
    window.model.illumination.method = "shadow_volume"
    window.viewport.render_now()
    technique = window.viewport.scene.illuminator.technique
    assert technique is not None and technique.NAME == "shadow_volume"
    before = technique.stats()["recomputes"]
    window.time_player.step(1)
    wait_shown(window, qtbot, 1)
    window.viewport.render_now()
    assert technique.stats()["recomputes"] == before + 1
    window.model.illumination.method = "local"


def test_stepping_back_to_a_cached_point_reads_nothing(lapse_window, qtbot, read_calls):
    window = lapse_window
    player = window.time_player
    for index in (1, 2, 3):
        player.go_to(index)
        wait_shown(window, qtbot, index)
    assert read_calls == [1, 2, 3]
    pixels_at_3 = frame(window)
    player.go_to(1)
    wait_shown(window, qtbot, 1)  # at once: no read
    player.go_to(0)
    wait_shown(window, qtbot, 0)
    player.go_to(3)
    wait_shown(window, qtbot, 3)
    assert read_calls == [1, 2, 3]
    assert player.cache.hits >= 3
    assert np.array_equal(frame(window), pixels_at_3)


def test_the_cache_stays_within_its_byte_bound(lapse_window, qtbot, read_calls):
    window = lapse_window
    player = window.time_player
    point = window.data.nbytes
    player.set_cache_bytes(3 * point + point // 2)  # room for three time points
    assert window.time_bar.cache_box.value() == player.cache.max_bytes // (1 << 20)
    for index in range(1, 9):
        player.go_to(index)
        wait_shown(window, qtbot, index)
        assert player.cache.nbytes <= player.cache.max_bytes
        assert len(player.cache) <= 3
    assert sorted(player.cache) == [6, 7, 8]
    player.go_to(2)  # pushed out: read again
    wait_shown(window, qtbot, 2)
    assert read_calls[-1] == 2 and read_calls.count(2) == 2
    player.set_cache_bytes(64 << 20)


def test_play_advances_through_the_time_points(lapse_window, qtbot):
    window = lapse_window
    player = window.time_player
    seen: set[int] = set()
    player.shown.connect(seen.add)
    window.time_bar.fps_box.setValue(30.0)
    window.time_bar.play_button.click()
    assert player.playing and window.time_bar.play_button.text() == "Pause"
    qtbot.waitUntil(lambda: len(seen) >= 8, timeout=30_000)
    assert window.time_rate_label.text().startswith("playing ")
    window.time_bar.play_button.click()
    assert not player.playing and window.time_rate_label.text() == ""
    assert window.time_bar.slider.value() == window.model.volume.time_index == player.shown_index
    # Without loop, playback stops on the last time point.
    window.time_bar.loop_box.setChecked(False)
    player.go_to(N_TIME - 3)
    wait_shown(window, qtbot, N_TIME - 3)
    player.play()
    qtbot.waitUntil(lambda: not player.playing, timeout=20_000)
    assert player.shown_index == N_TIME - 1


def test_setting_the_model_moves_the_slider(lapse_window, qtbot):
    window = lapse_window
    window.model.volume.time_index = 7
    assert window.time_bar.slider.value() == 7
    assert window.time_bar.index_box.value() == 7
    assert "reading" in window.time_bar.label.text()
    wait_shown(window, qtbot, 7)
    assert window.time_bar.label.text() == "of 20 · 3.5 min"
    assert "time point 7 of 20" in window.data_label.text()


def test_a_time_index_out_of_range_in_the_model_is_refused(lapse_window, qtbot, dialogs):
    window = lapse_window
    window.model.volume.time_index = 25
    assert window.model.volume.time_index == 0  # back to what is shown
    assert window.time_player.shown_index == 0
    assert len(dialogs) == 1
    assert "time point 25 is out of range: the file has 20 time points (0–19)" in \
        dialogs[0].informativeText()


def test_a_session_keeps_the_time_point(lapse_window, qtbot, tmp_path, small_volume_file):
    window = lapse_window
    window.time_player.go_to(5)
    wait_shown(window, qtbot, 5)
    session = window.save_session(tmp_path / "lapse.vtkvol.json")
    assert json.loads(session.read_text())["scene"]["volume"]["time_index"] == 5
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(small_volume_file)
    assert not window.time_toolbar.isVisible()
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(session)
    assert window.time_toolbar.isVisible()
    assert window.time_bar.slider.value() == 5 and window.time_player.shown_index == 5
    assert window.data.metadata["time_index"] == 5
    window.time_player.step(1)
    wait_shown(window, qtbot, 6)


def test_a_session_whose_file_lost_time_points_says_so(lapse_window, qtbot, tmp_path,
                                                        lapse_file, dialogs):
    window = lapse_window
    window.time_player.go_to(15)
    wait_shown(window, qtbot, 15)
    session = window.save_session(tmp_path / "late.vtkvol.json")
    write_time_lapse(lapse_file, n_time=10)  # the file was cut to 10 time points since
    shown = window.data
    with qtbot.waitSignal(window.openFailed, timeout=30_000) as blocker:
        window.open_session(session)
    assert "time_index 15 is out of range: the file has 10 time points (0–9)" in blocker.args[0]
    assert len(dialogs) == 1 and "lapse.tif" in dialogs[0].informativeText()
    assert window.data is shown  # the previous view stays, the app is alive
    assert window.time_player.shown_index == 15


def test_a_read_failing_during_playback_stops_it_with_a_message(
        lapse_window, qtbot, monkeypatch, dialogs):
    window = lapse_window
    player = window.time_player
    real = time_module.read_volume

    def failing(path, *, time_index, **kwargs):
        if time_index >= 3:
            raise VolumeReadError(path, f"corrupt or truncated TIFF (frame {time_index})")
        return real(path, time_index=time_index, **kwargs)

    monkeypatch.setattr(time_module, "read_volume", failing)
    player.fps = 20.0
    player.play()
    qtbot.waitUntil(lambda: not player.playing, timeout=20_000)
    assert len(dialogs) == 1
    assert "corrupt or truncated TIFF" in dialogs[0].informativeText()
    assert "lapse.tif" in window.statusBar().currentMessage()
    assert player.shown_index < 3 and window.model.volume.time_index == player.shown_index
    assert window.time_bar.play_button.text() == "Play"
    player.go_to(1)  # still alive: a readable point shows
    wait_shown(window, qtbot, 1)


def test_a_point_of_another_shape_stops_with_a_message(lapse_window, qtbot, monkeypatch,
                                                       dialogs):
    window = lapse_window
    real = time_module.read_volume

    def shrunk(path, *, time_index, **kwargs):
        data = real(path, time_index=time_index, **kwargs)
        data.array = np.ascontiguousarray(data.array[:, :6])
        return data

    monkeypatch.setattr(time_module, "read_volume", shrunk)
    window.time_player.go_to(2)
    qtbot.waitUntil(lambda: len(dialogs) == 1, timeout=20_000)
    assert "time point 2 has 1 channel(s) of 32×32×6 voxels, unlike the time point first " \
           "shown" in dialogs[0].informativeText()
    assert window.model.volume.time_index == window.time_player.shown_index == 0


def test_opening_at_a_time_point(main_window, qtbot, lapse_file):
    window = main_window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(lapse_file, time_index=12)
    assert window.data.metadata["time_index"] == 12
    assert window.model.volume.time_index == window.time_player.shown_index == 12
    assert window.time_bar.slider.value() == 12


def test_the_cache_setting_is_kept_and_a_damaged_one_ignored(main_window):
    window = main_window
    window.time_bar.cache_box.setValue(3)
    assert window.time_player.cache.max_bytes == 3 << 20
    assert int(window.settings.value("timeSeries/cacheMiB")) == 3
    assert window._time_cache_setting() == 3 << 20
    for damaged in ("lots", "-5"):
        window.settings.setValue("timeSeries/cacheMiB", damaged)
        assert window._time_cache_setting() is None  # the default
    window.time_bar.cache_box.setValue(64)


def test_open_refuses_a_negative_time(capsys):
    from vtkvol.cli import main

    assert main(["open", "cells.tif", "--time", "-2"]) == 2
    assert "--time must be a time point index >= 0, got -2" in capsys.readouterr().err
    assert main(["open", "--time", "3"]) == 2
    assert "built-in sample" in capsys.readouterr().err


def test_a_frame_interval_that_lies_is_ignored(tmp_path):
    import tifffile

    from vtkvol.io import read_volume

    stack = np.ones((3, 2, 8, 8), np.uint16)
    for name, metadata, expected in (
            ("minutes.tif", {"finterval": 0.5, "tunit": "min"}, 30.0),
            ("negative.tif", {"finterval": -4.0}, None),
            ("weird_unit.tif", {"finterval": 2.0, "tunit": "fortnight"}, None)):
        tifffile.imwrite(tmp_path / name, stack, imagej=True,
                         metadata={"axes": "TZYX", **metadata})
        data = read_volume(tmp_path / name)
        assert data.metadata.get("time_interval_s") == expected, name
    assert any("unknown time unit 'fortnight'" in n for n in data.notes)


def test_ome_zarr_time_axis_gives_the_interval(tmp_path):
    zarr = pytest.importorskip("zarr")
    writer = pytest.importorskip("ome_zarr.writer")
    ome_format = pytest.importorskip("ome_zarr.format")
    from vtkvol.io import read_volume

    fmt = ome_format.FormatV05()
    group = zarr.open_group(str(tmp_path / "lapse.zarr"), mode="w", zarr_format=fmt.zarr_format)
    writer.write_image(np.ones((3, 4, 8, 8), np.uint16), group, axes="tzyx", fmt=fmt,
                       scale_factors=(2,), scale={"t": 2.0, "z": 1.0, "y": 0.5, "x": 0.5},
                       axes_units={"t": "minute", "z": "micrometer", "y": "micrometer",
                                   "x": "micrometer"})
    data = read_volume(tmp_path / "lapse.zarr", time_index=2)
    assert data.metadata["time_points"] == 3
    assert data.metadata["time_interval_s"] == 120.0


def test_slow_reads_drop_time_points_instead_of_queueing_them(lapse_window, qtbot,
                                                             monkeypatch):
    window = lapse_window
    player = window.time_player
    real = time_module.read_volume
    reads: list[int] = []

    def slow(path, *, time_index, **kwargs):
        reads.append(time_index)
        time.sleep(0.25)  # five 20-fps frame intervals per read
        return real(path, time_index=time_index, **kwargs)

    monkeypatch.setattr(time_module, "read_volume", slow)
    shown: list[int] = []
    player.shown.connect(shown.append)
    player.fps = 20.0
    player.play()
    qtbot.waitUntil(lambda: len(shown) >= 3, timeout=30_000)
    rate = window.time_rate_label.text()
    player.pause()
    player.shown.disconnect(shown.append)
    # The clock ran on while reading: points were skipped, not read one after the other.
    # Each read spans five or more ticks, so three shown points pass at least eight others.
    assert player.skipped_points >= 8
    assert len(reads) < (len(shown) + player.skipped_points) / 2  # far from every point
    assert rate.startswith("playing ") and rate.endswith("of 20 fps (time points skipped)")


def test_set_voxels_refuses_other_geometry(lapse_window, small_volume):
    with pytest.raises(ValueError, match="do not match the shown volume"):
        lapse_window.viewport.scene.set_voxels(small_volume)


def test_a_two_channel_tczyx_series_steps_both_channels(main_window, qtbot, tmp_path):
    import tifffile

    from vtkvol.io import read_volume

    rng = np.random.default_rng(2)
    stack = rng.integers(0, 4000, size=(5, 8, 2, 16, 16), dtype=np.uint16)  # T Z C Y X
    path = tmp_path / "two.tif"
    tifffile.imwrite(path, stack, imagej=True, metadata={"axes": "TZCYX"})
    window = main_window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(path)
    tfs = [c.tf.copy_state() for c in window.model.channels]
    window.time_player.go_to(3)
    wait_shown(window, qtbot, 3)
    assert window.data.n_channels == 2
    np.testing.assert_array_equal(window.data.array, read_volume(path, time_index=3).array)
    np.testing.assert_array_equal(window.data.array[:, :, 5, 7], stack[3, :, :, 5, 7].T)
    assert [c.tf.copy_state() for c in window.model.channels] == tfs
    assert window.time_bar.label.text() == "of 5"  # the file states no frame interval
