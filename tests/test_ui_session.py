"""Session files in the app: the round trip restores the exact view (pixels and layout),
and every bad session shows a clear dialog while the current scene stays untouched."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest
from PySide6.QtWidgets import QMessageBox

from vtkvol.ui import errors
from vtkvol.ui.docks.lights import angles_to_direction

pytestmark = pytest.mark.gui


def shot(window) -> np.ndarray:
    return window.viewport.screenshot().astype(np.float64)


@pytest.fixture
def data_copy(tmp_path, small_volume_file):
    """The small volume in a folder of its own (so tests can move or change it)."""
    path = tmp_path / "data" / "cells.npy"
    path.parent.mkdir()
    shutil.copy(small_volume_file, path)
    return path


@pytest.fixture
def window(main_window, qtbot, data_copy):
    with qtbot.waitSignal(main_window.dataShown, timeout=30_000):
        main_window.open_path(data_copy)
    return main_window


def customise(window) -> None:
    """A view far from the defaults: TF, crop, light, camera, layout."""
    model = window.model
    lo, hi = model.channels[0].tf.value_span
    model.channels[0].tf.opacity = [(lo, 0.0), (0.5 * (lo + hi), 0.15), (hi, 0.8)]
    model.channels[0].tf.colors = [(lo, 0.1, 0.0, 0.3), (hi, 1.0, 0.8, 0.2)]
    model.crop.x = (4.0, 40.0)
    model.lights[0].direction = angles_to_direction(-70.0, 25.0)
    model.slice_weights.z = [(0.0, 0.2), (0.5, 1.0), (1.0, 1.0)]
    window.viewport.scene.orbit(40.0, 15.0)
    window.channels_dock.hide()


def scene_state(window) -> dict:
    state = window.model.copy_state()
    return {k: v for k, v in state.items() if k != "volume"}


def test_session_round_trip_restores_the_view(window, qtbot, tmp_path, dialogs):
    customise(window)
    before = shot(window)
    state = scene_state(window)
    path = window.save_session(tmp_path / "view")
    assert path == tmp_path / "view.vtkvol.json" and path.exists()
    assert window.windowTitle().startswith("view.vtkvol.json")

    # Change everything the session holds.
    window.tf_dock.apply_preset("magma")
    window.ranges_dock.reset()
    window.model.lights[0].direction = (0.0, 0.0, 1.0)
    window.viewport.reset_camera()
    window.channels_dock.show()
    assert np.abs(shot(window) - before).mean() > 2.0

    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert dialogs == []
    assert scene_state(window) == state
    assert not window.channels_dock.isVisible()  # the window layout came back too
    after = shot(window)
    assert np.abs(after - before).mean() < 1.0
    assert window.recorder.stack.count() == 0  # the loaded view is the new starting point
    window.channels_dock.show()


def _write(path, document) -> None:
    path.write_text(json.dumps(document) if not isinstance(document, str) else document)


@pytest.fixture
def saved(window, tmp_path):
    path = window.save_session(tmp_path / "good.vtkvol.json")
    return path, json.loads(path.read_text())


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("invalid_json", "not valid JSON"),
        ("out_of_range", "intensity"),
        ("newer_version", "newer"),
        ("not_a_session", "session"),
        ("wrong_type", "opacity"),
    ],
)
def test_bad_session_shows_a_dialog_and_keeps_the_scene(window, qtbot, saved, tmp_path,
                                                        dialogs, case, expected):
    _, document = saved
    bad = tmp_path / f"{case}.vtkvol.json"
    if case == "invalid_json":
        _write(bad, '{"format": "vtkvol-session", "version": 1,')
    elif case == "out_of_range":
        document["scene"]["lights"][0]["intensity"] = -2
        _write(bad, document)
    elif case == "newer_version":
        document["version"] = 999
        _write(bad, document)
    elif case == "not_a_session":
        _write(bad, [1, 2, 3])
    else:
        document["scene"]["channels"][0]["tf"]["opacity"] = "lots"
        _write(bad, document)
    data, state = window.data, scene_state(window)
    with qtbot.waitSignal(window.openFailed, timeout=10_000):
        window.open_session(bad)
    assert len(dialogs) == 1
    assert dialogs[0].text() == "Could not open the session"
    text = dialogs[0].informativeText()
    assert bad.name in text and expected.lower() in text.lower(), text
    assert dialogs[0].detailedText() == ""
    assert window.data is data and scene_state(window) == state


def test_missing_data_offers_locate_and_retries(window, qtbot, saved, tmp_path, monkeypatch,
                                                data_copy):
    path, _ = saved
    moved = tmp_path / "elsewhere" / "cells.npy"
    moved.parent.mkdir()
    shutil.move(data_copy, moved)
    asked = []

    def click_locate(box: QMessageBox) -> int:
        asked.append(box.informativeText())
        next(b for b in box.buttons() if b.text() == "Locate…").click()
        return 0

    monkeypatch.setattr(errors, "run_dialog", click_locate)
    monkeypatch.setattr(window, "_locate_data", lambda exc: str(moved))
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert len(asked) == 1 and "cells.npy" in asked[0]
    assert window.data.source == str(moved)
    assert window.model.volume.path == str(moved)


def test_missing_data_cancelled_keeps_the_scene(window, qtbot, saved, monkeypatch, data_copy):
    path, _ = saved
    data_copy.unlink()
    data, state = window.data, scene_state(window)
    monkeypatch.setattr(errors, "run_dialog", lambda box: 0)  # Cancel: nothing clicked
    with qtbot.waitSignal(window.openFailed, timeout=10_000):
        window.open_session(path)
    assert window.data is data and scene_state(window) == state


def test_changed_data_shape_is_refused(window, qtbot, saved, dialogs, data_copy):
    path, _ = saved
    # Replace the file (new inode) rather than rewrite it: the view memory-maps the old one.
    replacement = data_copy.with_name("new.npy")
    np.save(replacement, np.zeros((8, 16, 16), np.uint16))
    os.replace(replacement, data_copy)
    data = window.data
    with qtbot.waitSignal(window.openFailed, timeout=10_000):
        window.open_session(path)
    assert "no longer matches" in dialogs[0].informativeText()
    assert window.data is data


def test_session_of_the_sample(main_window, qtbot, tmp_path, dialogs):
    window = main_window
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_sample(shape_zyx=(12, 24, 24), voxel_size_um=(1.0, 1.0, 2.0))
    window.model.crop.z = (2.0, 12.0)
    path = window.save_session(tmp_path / "sample")
    window.model.crop.z = None
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert window.model.crop.z == (2.0, 12.0)
    assert window.data.shape_zyx == (12, 24, 24) and dialogs == []
