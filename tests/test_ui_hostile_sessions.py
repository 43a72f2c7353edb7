"""The app's Open session with hostile sessions (issue 28): a camera or light that cannot
describe a view shows a dialog and leaves the current view untouched; a degenerate view-up is
repaired with a note; a transfer function of 100 000 points opens in bounded time, reduced,
and the TF editor shows the reduced function."""

from __future__ import annotations

import json
import shutil
import time

import numpy as np
import pytest

from vtkvol.model.transfer_function import MAX_POINTS

pytestmark = pytest.mark.gui


@pytest.fixture
def window(main_window, qtbot, tmp_path, small_volume_file):
    path = tmp_path / "data" / "cells.npy"
    path.parent.mkdir()
    shutil.copy(small_volume_file, path)
    with qtbot.waitSignal(main_window.dataShown, timeout=30_000):
        main_window.open_path(path)
    main_window.viewport.scene.orbit(25.0, 10.0)  # a placed camera, saved in the session
    return main_window


@pytest.fixture
def document(window, tmp_path) -> dict:
    path = window.save_session(tmp_path / "good.vtkvol.json")
    return json.loads(path.read_text(encoding="utf-8"))


def scene_state(window) -> dict:
    return {k: v for k, v in window.model.copy_state().items() if k != "volume"}


def write(tmp_path, document, name, edit):
    doc = json.loads(json.dumps(document))
    edit(doc["scene"])
    path = tmp_path / f"{name}.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("name", "field"),
    [("far_camera", "camera.position"), ("at_focal_point", "camera.position"),
     ("light_overflow", "lights[0].direction"), ("far_light", "lights[0].position")],
)
def test_an_impossible_session_shows_a_dialog_and_keeps_the_view(window, qtbot, tmp_path,
                                                                  document, dialogs, name, field):
    def edit(scene):
        cam = scene["camera"]
        if name == "far_camera":
            cam["position"] = [1e308, -1e308, 1e308]
        elif name == "at_focal_point":
            cam["position"], cam["view_up"] = list(cam["focal_point"]), [0, 0, 0]
        elif name == "light_overflow":
            scene["lights"][0]["direction"] = [1e200, 1e200, 1e200]
        else:
            scene["lights"][0].update(kind="point", position=[0, 0, 1e300])

    bad = write(tmp_path, document, name, edit)
    data, state = window.data, scene_state(window)
    before = window.viewport.screenshot().astype(float)
    with qtbot.waitSignal(window.openFailed, timeout=10_000):
        window.open_session(bad)
    assert len(dialogs) == 1 and dialogs[0].text() == "Could not open the session"
    text = dialogs[0].informativeText()
    assert text.startswith(f"{bad.name}: {field}"), text
    assert "\n" not in text and dialogs[0].detailedText() == ""
    assert window.data is data and scene_state(window) == state
    assert np.abs(window.viewport.screenshot().astype(float) - before).mean() < 0.5


def test_a_zero_view_up_opens_repaired_with_a_note(window, qtbot, tmp_path, document, dialogs):
    good_shot = window.viewport.screenshot().astype(float)
    up = tuple(window.model.camera.view_up)
    path = write(tmp_path, document, "zero_up",
                 lambda scene: scene["camera"].update(view_up=[0, 0, 0]))
    window.viewport.reset_camera()
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert len(dialogs) == 1
    assert dialogs[0].text() == "zero_up.vtkvol.json was opened with notes:"
    assert "camera.view_up = [0.0, 0.0, 0.0] is zero; replaced by" in dialogs[0].informativeText()
    got = np.asarray(window.model.camera.view_up)
    assert np.linalg.norm(got) == pytest.approx(1.0)
    forward = np.subtract(window.model.camera.focal_point, window.model.camera.position)
    assert abs(got @ forward) < 1e-6 * np.linalg.norm(forward)
    shot = window.viewport.screenshot().astype(float)
    assert np.abs(shot - shot[0, 0]).max() > 30  # the data is drawn, not a blank view
    # The replacement is the default up made perpendicular; the saved up was near it.
    if abs(up[1]) > 0.95:
        assert np.abs(shot - good_shot).mean() < 8.0


def test_a_transfer_function_of_100000_points_opens_reduced_and_editable(
        window, qtbot, tmp_path, document, dialogs):
    lo, hi = window.model.channels[0].tf.value_span
    xs = np.linspace(lo, hi, 100_000)

    def edit(scene):
        scene["channels"][0]["tf"]["colors"] = [[float(x), 1.0, 0.6, 0.2] for x in xs]
        scene["channels"][0]["tf"]["opacity"] = [[float(x), float(i % 2)]
                                                 for i, x in enumerate(xs)]

    path = write(tmp_path, document, "big_tf", edit)
    t0 = time.perf_counter()
    with qtbot.waitSignal(window.dataShown, timeout=120_000):
        window.open_session(path)
    qtbot.wait(50)  # the editor's repaint
    seconds = time.perf_counter() - t0
    assert seconds < 60, seconds
    tf = window.model.channels[0].tf
    assert len(tf.colors) == MAX_POINTS and len(tf.opacity) == MAX_POINTS
    assert "100000 colour and 100000 opacity points reduced to 1024" in \
        dialogs[0].informativeText()
    editor = window.tf_dock.editor
    assert len(editor.points("opacity")) == MAX_POINTS
    t0 = time.perf_counter()
    editor.repaint()
    assert time.perf_counter() - t0 < 5.0


def test_the_tf_editor_copes_with_100000_points_set_from_code(window, qtbot):
    """A library user (or a TF file) may set such a function directly: the view renders it
    reduced (the engine's MAX_POINTS) and the editor draws it in bounded time."""
    from vtkvol.model.transfer_function import TransferFunction

    tf = window.model.channels[0].tf
    xs = np.linspace(*tf.value_span, 100_000)
    t0 = time.perf_counter()
    window.model.channels[0].tf = TransferFunction(
        colors=[(float(x), 0.9, 0.5, 0.1) for x in xs],
        opacity=[(float(x), float(i % 2)) for i, x in enumerate(xs)],
        window=tf.window, window_range=tf.window_range)
    window.viewport.screenshot()
    editor = window.tf_dock.editor
    editor.repaint()
    seconds = time.perf_counter() - t0
    assert len(editor.points("opacity")) == 100_000
    assert seconds < 20, seconds  # 150 s before: QPainter drew a path of every point
