"""Issue 25 §3 in the app: the slice views follow the slice-contribution weights, the clipping
plane and the 2-D TF as the 3-D view does; what is weighted 0, cut away or left out by the
2-D TF is absent from the slice view's image. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication

from vtkvol.engine.slices import slice_rgba
from vtkvol.model.scene import ClipPlane, SliceWeights
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D
from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def pristine() -> dict:
    return {}


@pytest.fixture
def window(opened_window, pristine, qtbot):
    """The small volume with the slice views shown; the model is reset after each test."""
    if not pristine:
        pristine.update(opened_window.model.model_dump())
    dock = opened_window.slice_views_dock
    if not dock.isVisible():
        dock.toggleViewAction().trigger()
        qtbot.waitUntil(dock.isVisible, timeout=5000)
    opened_window.resizeDocks([dock], [420], Qt.Orientation.Horizontal)
    QApplication.processEvents()
    dock.refresh_now()
    yield opened_window
    QApplication.processEvents()
    apply_state(opened_window.model, pristine)
    opened_window.recorder.reset()
    opened_window._unsaved_data_edit = False


def shown(window) -> np.ndarray:
    """The xy view's colours (uint8 RGB, drawn opaque over black) after the model's edits
    have reached the dock."""
    dock = window.slice_views_dock
    dock.refresh_now()
    return dock.views["xy"].image()[..., :3].astype(int)


def test_columns_weighted_zero_are_absent_from_the_slice_view(window):
    before = shown(window)
    nx = before.shape[1]
    window.model.slice_weights = SliceWeights(x=[(0.0, 0.0), (0.5, 0.0), (0.55, 1.0),
                                                 (1.0, 1.0)])
    after = shown(window)
    hidden = np.arange(nx) / (nx - 1) <= 0.5
    assert before[:, hidden].max() > 100  # there was something to hide
    assert after[:, hidden].max() == 0
    kept = np.arange(nx) / (nx - 1) >= 0.55
    np.testing.assert_array_equal(after[:, kept], before[:, kept])


def test_the_clipping_planes_cut_side_is_absent_from_the_slice_view(window):
    before = shown(window)
    nx = before.shape[1]
    sx = window.data.voxel_size_um[0]
    middle = (nx - 1) * sx / 2
    window.model.clip_plane = ClipPlane(enabled=True, origin=(middle, 0.0, 0.0),
                                        normal=(-1.0, 0.0, 0.0))  # keeps x ≤ middle
    after = shown(window)
    cut = np.arange(nx) * sx > middle
    assert before[:, cut].max() > 100
    assert after[:, cut].max() == 0
    np.testing.assert_array_equal(after[:, ~cut], before[:, ~cut])


def test_a_region_the_2d_tf_leaves_out_is_absent_and_its_colour_shows(window):
    model, data = window.model, window.data
    before = shown(window)
    lo, hi = data.channel_range(0)
    # Only the brightest half of the values, any gradient, in green.
    region = TFPrimitive(kind="rectangle", value_range=(lo + 0.5 * (hi - lo), hi + 1.0),
                         gradient_range=(0.0, 1e9), color=(0.0, 1.0, 0.0), opacity=0.6,
                         soft_edge=0.0)
    channel = model.channels[0]
    channel.tf2d = TransferFunction2D(primitives=[region])
    channel.tf_mode = "2d"
    after = shown(window)
    index = window.slice_views_dock.cursor_voxel()[2]
    values = data.array[0, index]
    dim = values < lo + 0.45 * (hi - lo)
    assert before[dim].max() > 30  # the 1-D TF showed the dim voxels
    assert after[dim].max() == 0
    bright = values > lo + 0.55 * (hi - lo)
    assert bright.sum() > 5
    assert after[bright][:, 1].min() > 200 and after[bright][:, [0, 2]].max() == 0
    expected = slice_rgba(data, model, "xy", index)
    np.testing.assert_array_equal(after, np.rint(np.clip(expected[..., :3], 0, 1) * 255))
