"""The app's labels mode: a label image opens in categorical colours with nearest sampling
and a notice; the Labels dock hides labels and turns the mode off; the cursor read-out names
the id; refusals (float ids) are one line in the dock; gamma in the channels dock; sessions
keep all of it."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from PySide6.QtCore import Qt

pytest.importorskip("cmap")
pytest.importorskip("pytestqt")

from vtkvol.model.labels import label_colors


def seg_stack(path, dtype=np.uint16):
    """Four boxes with ids 3, 7, 12, 300 in a 16 × 32 × 32 stack."""
    arr = np.zeros((16, 32, 32), dtype)
    for n, label in enumerate((3, 7, 12, 300)):
        arr[4:12, 4:28, 2 + 7 * n: 8 + 7 * n] = label
    tifffile.imwrite(path, arr, imagej=True, metadata={"axes": "ZYX"})
    return path


def open_and_wait(window, qtbot, path):
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(path)


def test_a_label_image_opens_as_labels(main_window, qtbot, tmp_path):
    window = main_window
    open_and_wait(window, qtbot, seg_stack(tmp_path / "seg.tif"))
    channel = window.model.channels[0]
    assert channel.labels is not None and channel.labels.hidden == []
    assert window.model.render.interpolation == "nearest"
    assert np.allclose(channel.tf.color_at(np.array([3.0, 7.0, 12.0, 300.0])),
                       label_colors([3, 7, 12, 300]), atol=1e-6)
    assert "shown as labels" in window.statusBar().currentMessage()
    dock = window.labels_dock
    assert dock.enabled.isChecked()
    assert [dock.list.item(i).text() for i in range(dock.list.count())] == [
        "label 3", "label 7", "label 12", "label 300"]
    assert dock.message.text() == "4 labels, 4 shown."

    # Hide id 7 in the list: its opacity is 0, and the model records it.
    dock.list.item(1).setCheckState(Qt.CheckState.Unchecked)
    assert channel.labels.hidden == [7]
    assert channel.tf.opacity_at(np.array([3.0, 7.0])) == pytest.approx([1.0, 0.0])
    assert dock.message.text() == "4 labels, 3 shown."
    window.recorder.stack.undo()
    assert window.model.channels[0].labels.hidden == []

    # The read-out names the id under the cursor.
    window.viewport.reset_camera()
    qtbot.wait(50)
    widget = window.viewport.plotter
    result = window.viewport.probe_at(widget.width() / 2, widget.height() / 2)
    assert result is not None and result.labels == (True,)
    label = int(result.values[0])
    assert label in (3, 7, 12, 300)  # the probe stops at visible material: a label
    assert result.text().endswith(f" label {label}")

    # Off: a grey ramp again, trilinear; on again: the labels.
    dock.enabled.setChecked(False)
    assert window.model.channels[0].labels is None
    assert window.model.render.interpolation == "trilinear"
    row = window.channels_dock.rows[0]
    assert row.gamma.isEnabled() and row.minimum.isEnabled()
    dock.enabled.setChecked(True)
    assert window.model.channels[0].labels is not None


def test_labels_and_gamma_survive_a_session(main_window, qtbot, tmp_path):
    window = main_window
    open_and_wait(window, qtbot, seg_stack(tmp_path / "seg.tif"))
    window.labels_dock.set_hidden([12])
    window.labels_dock.opacity.setValue(0.4)
    row = window.channels_dock.rows[0]
    # Gamma and contrast limits are not for categories; a new tint leaves the ids' colours.
    assert not row.gamma.isEnabled() and not row.minimum.isEnabled()
    colors = list(window.model.channels[0].tf.colors)
    row._on_color((1.0, 0.0, 0.0))
    assert window.model.channels[0].tf.colors == colors
    path = window.save_session(tmp_path / "labels.vtkvol.json")
    window.labels_dock.set_hidden([])
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    labels = window.model.channels[0].labels
    assert labels is not None and labels.hidden == [12] and labels.opacity == pytest.approx(0.4)
    assert window.model.render.interpolation == "nearest"
    assert window.labels_dock.list.item(2).checkState() == Qt.CheckState.Unchecked


def test_float_ids_are_refused_in_the_dock_and_gamma_edits_the_channel(
        main_window, qtbot, tmp_path):
    window = main_window
    open_and_wait(window, qtbot, seg_stack(tmp_path / "segf.tif", dtype=np.float32))
    assert window.model.channels[0].labels is None  # floats: not detected as labels
    assert window.model.render.interpolation == "trilinear"
    dock = window.labels_dock
    dock.enabled.setChecked(True)
    assert not dock.enabled.isChecked() and window.model.channels[0].labels is None
    assert dock.message.text() == ("Cannot show as labels: segf.tif holds float32 values; "
                                   "label ids are integers.")
    row = window.channels_dock.rows[0]
    assert row.gamma.isEnabled()
    row.gamma.setValue(0.5)
    assert window.model.channels[0].gamma == pytest.approx(0.5)


def test_a_segmentation_channel_over_raw_data(main_window, qtbot, tmp_path):
    """A two-channel file, raw intensities and a segmentation: the segmentation opens as
    labels (the dock shows it), the raw channel keeps its ramp and its gamma; the labels'
    opacity is their own."""
    from vtkvol.io import confocal_phantom

    raw = confocal_phantom((16, 32, 32)).array[0]
    seg = np.zeros((16, 32, 32), np.uint16)
    for n, label in enumerate((3, 7, 12, 300)):
        seg[4:12, 4:28, 2 + 7 * n: 8 + 7 * n] = label
    path = tmp_path / "raw_and_seg.tif"
    tifffile.imwrite(path, np.stack([raw, seg], axis=1), imagej=True,
                     metadata={"axes": "ZCYX"})
    window = main_window
    open_and_wait(window, qtbot, path)
    raw_channel, seg_channel = window.model.channels
    assert raw_channel.labels is None and seg_channel.labels is not None
    assert window.labels_dock.index == 1 and window.labels_dock.list.count() == 4
    raw_tf = raw_channel.tf.model_dump()
    window.labels_dock.opacity.setValue(0.3)
    assert seg_channel.tf.opacity_at(np.array([3.0, 300.0])) == pytest.approx([0.3, 0.3])
    assert raw_channel.tf.model_dump() == raw_tf  # the raw channel's own opacity stays
    window.channels_dock.rows[0].gamma.setValue(0.7)
    assert raw_channel.gamma == pytest.approx(0.7) and seg_channel.gamma == 1.0
