"""File → Export movie…: keyframes from the view, export to PNG/TIFF, Cancel, keyframe files,
a missing MP4 encoder. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from PySide6.QtWidgets import QPushButton

from vtkvol import movie
from vtkvol.model.keyframes import read_keyframes

pytestmark = pytest.mark.gui


@pytest.fixture
def dialog(opened_window, dialogs):
    window = opened_window
    window.viewport.reset_camera()
    dlg = window.show_movie_dialog()
    dlg.keyframes.clear()
    dlg._refresh_table()
    dlg.width_.setValue(32)
    dlg.height_.setValue(32)
    yield dlg
    dlg.hide()


def _png(path) -> np.ndarray:
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    reader = vtk.vtkPNGReader()
    reader.SetFileName(str(path))
    reader.Update()
    w, h, _ = reader.GetOutput().GetDimensions()
    return vtk_to_numpy(reader.GetOutput().GetPointData().GetScalars()).reshape(h, w, -1)


def _two_keyframes(dlg):
    window = dlg.window_
    dlg.add_keyframe()
    window.viewport.scene.orbit(90.0, 0.0)  # the user turns the view
    window.model.lights[0].intensity = 2.5  # and brightens the light
    dlg.add_keyframe()
    return window


def test_two_keyframes_export_four_pngs(dialog, tmp_path, dialogs):
    dlg = dialog
    assert dlg.window_.movie_action.isEnabled()
    window = _two_keyframes(dlg)
    assert [k.time for k in dlg.keyframes] == [0.0, 2.0]
    assert dlg.keyframes[1].lights[0].intensity == 2.5 and dlg.keyframes[0].lights[0].intensity == 1
    assert dlg.keyframes[0].time_index is None  # the file has one time point
    assert dlg.table.rowCount() == 2
    dlg.tabs.setCurrentIndex(1)
    dlg.fps.setValue(1.5)  # 2 s at 1.5 fps: 4 frames
    assert dlg.summary.text() == "4 frames, 2.67 s at 1.5 fps"
    dlg.output.setText(str(tmp_path / "spin.png"))
    written = dlg.export()
    assert dialogs == []
    assert [p.name for p in written] == [f"spin_000{i}.png" for i in range(4)]
    assert sorted(p.name for p in tmp_path.iterdir()) == [p.name for p in written]
    images = [_png(p).astype(float) for p in written]
    assert images[0].shape == (32, 32, 3)
    assert all(np.abs(images[i + 1] - images[i]).mean() > 0.5 for i in range(3))
    assert "Wrote spin_0000.png … spin_0003.png (4 frames, 32×32" in (
        window.statusBar().currentMessage())
    # the view itself was left as the user had it
    assert window.model.lights[0].intensity == 2.5


def test_move_remove_duration_and_keyframe_files(dialog, tmp_path, dialogs):
    dlg = dialog
    _two_keyframes(dlg)
    first, second = dlg.keyframes
    dlg.table.selectRow(1)
    dlg.move_keyframe(-1)  # the views swap, the times stay
    assert [k.time for k in dlg.keyframes] == [0.0, 2.0]
    assert dlg.keyframes[0].camera == second.camera and dlg.keyframes[1].camera == first.camera
    dlg.duration.setValue(5.0)
    assert [k.time for k in dlg.keyframes] == [0.0, 5.0]
    dlg.set_keyframe_time(1, -3.0)  # kept after the keyframe before it
    assert dlg.keyframes[1].time == pytest.approx(0.01)
    dlg.set_keyframe_time(1, 4.0)
    saved = dlg.save_keyframes(tmp_path / "anim")
    assert saved.name == "anim.keyframes.json"
    assert read_keyframes(saved).keyframes == tuple(dlg.keyframes)
    # double-click shows a keyframe's camera; Replace takes the view as it is now
    dlg.show_keyframe(1)
    assert tuple(dlg.window_.model.camera.position) == pytest.approx(first.camera.position)
    dlg.window_.viewport.scene.orbit(0.0, 30.0)
    dlg.table.selectRow(1)
    dlg.replace_keyframe()
    assert dlg.keyframes[1].time == 4.0
    assert dlg.keyframes[1].camera.position != pytest.approx(first.camera.position)
    assert read_keyframes(saved).keyframes[1].camera == first.camera  # the file keeps its own
    dlg.table.selectRow(0)
    dlg.remove_keyframe()
    assert len(dlg.keyframes) == 1
    assert dlg.load_keyframes(saved) and [k.time for k in dlg.keyframes] == [0.0, 4.0]
    bad = tmp_path / "bad.keyframes.json"
    bad.write_text('{"format": "vtkvol-keyframes", "version": 7, "keyframes": []}')
    assert not dlg.load_keyframes(bad)
    assert len(dialogs) == 1 and "version 7, newer than this vtkvol reads" in (
        dialogs[0].informativeText())
    assert [k.time for k in dlg.keyframes] == [0.0, 4.0]  # unchanged


def test_cancel_leaves_no_files(dialog, tmp_path, dialogs):
    dlg = dialog
    window = _two_keyframes(dlg)
    dlg.tabs.setCurrentIndex(1)
    dlg.fps.setValue(3.0)  # 7 frames
    dlg.output.setText(str(tmp_path / "stack.tif"))
    seen = []

    def on_frame(done, total):
        seen.append(done)
        if done == 2:
            [cancel] = dlg.progress.findChildren(QPushButton)
            assert cancel.text() == "Cancel" and dlg.progress.isVisible()
            cancel.click()

    dlg.frameWritten.connect(on_frame)
    try:
        assert dlg.export() is None
    finally:
        dlg.frameWritten.disconnect(on_frame)
    assert seen == [1, 2]
    assert list(tmp_path.iterdir()) == []
    assert "cancelled; nothing was written" in window.statusBar().currentMessage()
    assert dialogs == []


def test_turntable_to_tiff_and_a_missing_encoder(dialog, tmp_path, dialogs, monkeypatch):
    dlg = dialog
    dlg.tabs.setCurrentIndex(0)
    dlg.frames.setValue(3)
    dlg.degrees.setValue(90.0)
    dlg.output.setText(str(tmp_path / "turn.tif"))
    [written] = dlg.export()
    stack = tifffile.imread(written)
    assert stack.shape == (3, 32, 32, 3)
    assert np.abs(stack[2].astype(float) - stack[0]).mean() > 1.0

    monkeypatch.setattr(movie, "has_video_encoder", lambda: False)
    dlg.output.setText(str(tmp_path / "turn.mp4"))
    assert dlg.export() is None
    assert len(dialogs) == 1
    assert "pip install 'vtkvol[movie]'" in dialogs[0].informativeText()
    assert not (tmp_path / "turn.mp4").exists()
    assert dlg.window_.data is not None and dlg.window_.viewport.screenshot().std() > 1.0


def test_existing_output_is_replaced_only_when_confirmed(dialog, tmp_path, dialogs):
    dlg = dialog
    dlg.tabs.setCurrentIndex(0)
    dlg.frames.setValue(2)
    target = tmp_path / "keep.tif"
    target.write_bytes(b"keep")
    dlg.output.setText(str(target))
    assert dlg.export() is None  # the recorded dialog answers "No"
    assert len(dialogs) == 1 and "keep.tif already exist" in dialogs[0].text()
    assert target.read_bytes() == b"keep"


def test_turntable_turns_about_the_sample_axis_and_frames_the_turn(dialog, tmp_path,
                                                                   monkeypatch):
    """Issue 25: the dialog turned about the tilted view-up and let the object leave the
    frame. By default it asks for the sample's axis and the whole turn in frame; the other
    axis stays on offer."""
    dlg = dialog
    dlg.tabs.setCurrentIndex(0)
    dlg.frames.setValue(2)
    asked = []
    real = movie.turntable_frames

    def record(data, **kwargs):
        asked.append(kwargs)
        return real(data, **kwargs)

    monkeypatch.setattr(movie, "turntable_frames", record)
    dlg.output.setText(str(tmp_path / "turn.tif"))
    assert dlg.export()
    assert asked[-1]["axis"] == "sample" and asked[-1]["frame_all"] is True
    dlg.turn_axis.setCurrentIndex(dlg.turn_axis.findData("view"))
    dlg.frame_all.setChecked(False)
    dlg.output.setText(str(tmp_path / "turn2.tif"))
    assert dlg.export()
    assert asked[-1]["axis"] == "view" and asked[-1]["frame_all"] is False
