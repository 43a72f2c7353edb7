"""Issue 25 §3: the slice views show the 3-D view's classification, so what the 3-D view hides
is absent from them: the slice-contribution weights, the clipping plane and a channel's 2-D
transfer function (its colours and the regions it leaves out). Pure numpy (no GL, no Qt)."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.engine.slices import PLANES, slice_rgba, slice_values, slice_weight
from vtkvol.engine.tf2d import lookup
from vtkvol.io import VolumeData
from vtkvol.model.gradient import gradient_axis_max, normalised_gradient
from vtkvol.model.scene import Channel, ClipPlane, SceneModel, SliceWeights
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction, TransferFunction2D


def ball() -> VolumeData:
    """Two channels, 16 × 20 × 24 (z, y, x): a bright ball (flat inside, a steep rim) in
    channel 0, a ramp along x in channel 1; anisotropic voxels."""
    z, y, x = np.mgrid[0:16, 0:20, 0:24].astype(np.float64)
    r = np.sqrt(((x - 12) / 1.0) ** 2 + ((y - 10) / 1.0) ** 2 + ((z - 8) / 1.0) ** 2)
    a = np.where(r < 5.0, 1000.0, np.where(r < 7.0, 1000.0 * (7.0 - r) / 2.0, 0.0))
    b = np.broadcast_to(40.0 * x, a.shape)
    array = np.stack([a, b]).astype(np.uint16)
    return VolumeData.from_array(array, (0.5, 0.5, 0.8), ["ball", "ramp"])


def tf(lo: float, hi: float, rgb: tuple[float, float, float]) -> TransferFunction:
    return TransferFunction(colors=[(lo, 0.0, 0.0, 0.0), (hi, *rgb)],
                            opacity=[(lo, 0.0), (hi, 0.8)], window=(0.0, 1000.0),
                            window_range=(0.0, 1000.0))


def model() -> SceneModel:
    return SceneModel(channels=[
        Channel(name="ball", color=(1.0, 0.0, 0.0), tf=tf(10.0, 900.0, (1.0, 0.0, 0.0))),
        Channel(name="ramp", color=(0.0, 0.0, 1.0), tf=tf(0.0, 1000.0, (0.0, 0.0, 1.0))),
    ])


@pytest.mark.parametrize("plane", ["xy", "yz", "xz"])
def test_a_region_weighted_zero_is_absent(plane):
    data, m = ball(), model()
    before = slice_rgba(data, m, plane, 6)
    m.slice_weights = SliceWeights(x=[(0.0, 0.0), (0.5, 0.0), (0.51, 1.0), (1.0, 1.0)])
    after = slice_rgba(data, m, plane, 6)
    p = PLANES[plane]
    nx = 24
    xs = np.arange(nx) / (nx - 1)
    w = np.interp(xs, [0.0, 0.5, 0.51, 1.0], [0.0, 0.0, 1.0, 1.0])
    if p.column == 0:  # x runs across the image
        hidden = (slice(None), w == 0.0)
        kept = (slice(None), w == 1.0)
    else:  # the yz plane at x index 6: all of it lies where x weighs 0
        assert p.normal == 0
        hidden, kept = (slice(None), slice(None)), None
    assert before[hidden][..., 3].max() > 0.1  # something was visible there
    assert np.all(after[hidden] == 0.0)  # colour and opacity gone, as in the 3-D view
    if kept is not None:
        np.testing.assert_array_equal(after[kept], before[kept])


def test_weights_scale_colour_and_opacity_as_the_renderer():
    data, m = ball(), model()
    before = slice_rgba(data, m, "xy", 8)
    m.slice_weights = SliceWeights(z=[(0.0, 0.5), (1.0, 0.5)])
    factor = slice_weight(data, m, "xy", 8)
    assert factor is not None and np.allclose(factor, 0.5)
    after = slice_rgba(data, m, "xy", 8)
    # Each channel's RGBA is halved before mixing: the additive colour halves; the combined
    # opacity is 1 − Π(1 − αᵢ/2), below the unweighted one wherever something shows.
    np.testing.assert_allclose(after[..., :3], np.clip(before[..., :3], 0, 1) * 0.5, atol=1e-6)
    shown = before[..., 3] > 0.05
    assert np.all(after[..., 3][shown] < before[..., 3][shown])


def test_the_clipping_planes_cut_side_is_absent():
    data, m = ball(), model()
    before = slice_rgba(data, m, "xy", 8)
    # Keep x ≥ 6 µm (voxel 12 and beyond): the normal points to the kept side.
    m.clip_plane = ClipPlane(enabled=True, origin=(6.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0))
    after = slice_rgba(data, m, "xy", 8)
    x_um = np.arange(24) * 0.5
    cut, kept = x_um < 6.0, x_um >= 6.0
    assert before[:, cut, 3].max() > 0.5
    assert np.all(after[:, cut] == 0.0)
    np.testing.assert_array_equal(after[:, kept], before[:, kept])
    # An oblique plane: the kept side is where (p − origin)·n ≥ 0, voxel centres in µm.
    m.clip_plane = ClipPlane(enabled=True, origin=(6.0, 5.0, 6.4), normal=(1.0, -1.0, 0.0))
    after = slice_rgba(data, m, "xy", 8)
    y_um = np.arange(20)[:, None] * 0.5
    side = (x_um[None, :] - 6.0) - (y_um - 5.0)
    assert np.all(after[side < 0] == 0.0)
    np.testing.assert_array_equal(after[side >= 0], before[side >= 0])


def tf2d_model(prim: TFPrimitive) -> SceneModel:
    m = model()
    m.channels[1].visible = False
    m.channels[0].tf_mode = "2d"
    m.channels[0].tf2d = TransferFunction2D(primitives=[prim])
    return m


def test_a_region_the_2d_tf_leaves_out_is_absent_and_its_colours_show():
    data = ball()
    spacing = tuple(data.voxel_size_um)
    top = gradient_axis_max((0.0, 1000.0), spacing)
    # Bright and flat only (the ball's inside): the steep rim and the background are left out.
    flat = TFPrimitive(kind="rectangle", value_range=(900.0, 1000.0),
                       gradient_range=(0.0, 0.05 * top), color=(0.0, 1.0, 0.0), opacity=0.7,
                       soft_edge=0.0)
    m = tf2d_model(flat)
    one_d = model()
    one_d.channels[1].visible = False
    rgba_1d = slice_rgba(data, one_d, "xy", 8)
    rgba = slice_rgba(data, m, "xy", 8)
    values = slice_values(data.array, "xy", 8)[0]
    t = normalised_gradient(data.array[0], spacing, (0.0, 1000.0))[8]
    rim = (values > 100) & (t > 0.2)
    inside = (values == 1000) & (t == 0.0)
    assert rim.sum() > 10 and inside.sum() > 10
    assert rgba_1d[rim][:, 3].min() > 0.05  # the 1-D TF showed the rim…
    assert np.all(rgba[rim][:, 3] == 0.0)  # …the 2-D TF hides it, and the slice with it
    assert np.all(rgba[values < 890][:, 3] == 0.0)  # (below the texel next to 900)
    # Inside: the region's colour (green), not the 1-D TF's red.
    np.testing.assert_allclose(rgba[inside][:, :3], [[0.0, 1.0, 0.0]] * int(inside.sum()),
                               atol=1e-6)
    np.testing.assert_allclose(rgba[inside][:, 3], 0.7, atol=1e-6)
    assert rgba_1d[inside][:, 0].min() > 0.9


@pytest.mark.parametrize(("channel", "plane", "index"), [
    (0, "xy", 8), (0, "yz", 12), (0, "xz", 3),
    (1, "yz", 0), (1, "yz", 23), (1, "xy", 0), (1, "xz", 19),  # the ramp: borders too
])
def test_2d_classification_equals_the_whole_volumes(channel, plane, index):
    """The slab of three slices gives each voxel the gradient of the whole volume (VTK's, edge
    voxels repeated at the border), and the table is looked up as the renderer's, over the
    component's value range."""
    data = ball()
    spacing = tuple(data.voxel_size_um)
    values = data.array[channel]
    value_range = (float(values.min()), float(values.max()))
    top = gradient_axis_max(value_range, spacing)
    # Soft edges: the opacity varies with both the value and the gradient.
    lo, hi = value_range
    rim = TFPrimitive(kind="rectangle", value_range=(lo - 0.5 * (hi - lo), hi + 0.3 * (hi - lo)),
                      gradient_range=(0.0, 2.0 * top), color=(0.2, 0.6, 1.0), opacity=0.5,
                      soft_edge=0.6)
    m = model()
    m.channels[1 - channel].visible = False
    m.channels[channel].tf_mode = "2d"
    m.channels[channel].tf2d = TransferFunction2D(primitives=[rim])
    got = slice_rgba(data, m, plane, index)
    table = m.channels[channel].tf2d.table(value_range, (0.0, top), (256, 256))
    s = (values.astype(np.float64) - value_range[0]) / (value_range[1] - value_range[0])
    t = normalised_gradient(values, spacing, value_range)
    whole = lookup(table, s.astype(np.float32), t)  # [z, y, x, 4]
    expected = slice_values(np.moveaxis(whole, -1, 0), plane, index)  # [4, rows, cols]
    expected = np.moveaxis(expected, 0, -1)
    assert expected[..., 3].max() > 0.1
    np.testing.assert_allclose(got[..., :3], np.clip(expected[..., :3], 0, 1), atol=1e-5)
    np.testing.assert_allclose(got[..., 3], expected[..., 3], atol=1e-5)
