"""The slice views' colouring (vtkvol.engine.slices) against a direct numpy computation, the
cursor's clamping and validation, and the 3-D outline of the slice planes. No GL, no Qt."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vtkvol.engine.slices import (
    PLANES,
    box_um,
    cursor_index,
    default_cursor,
    slice_rgba,
    slice_values,
    snap_cursor,
    to_rgba8,
)
from vtkvol.io import VolumeData
from vtkvol.model.scene import Channel, SceneModel
from vtkvol.model.transfer_function import TransferFunction


def phantom() -> VolumeData:
    """Two channels, 5 × 6 × 7 (z, y, x) voxels of distinct values, anisotropic voxels."""
    rng = np.random.default_rng(3)
    array = rng.integers(0, 200, size=(2, 5, 6, 7)).astype(np.uint16)
    return VolumeData.from_array(array, (0.5, 0.25, 2.0), ["a", "b"])


def two_channel_model() -> SceneModel:
    return SceneModel(channels=[
        Channel(name="a", color=(1.0, 0.0, 0.0), tf=TransferFunction(
            colors=[(20.0, 0.0, 0.0, 0.0), (150.0, 1.0, 0.2, 0.0)],
            opacity=[(20.0, 0.0), (150.0, 0.6)], window=(0.0, 255.0),
            window_range=(0.0, 255.0))),
        Channel(name="b", color=(0.0, 1.0, 1.0), tf=TransferFunction(
            colors=[(0.0, 0.0, 0.0, 0.0), (100.0, 0.0, 0.9, 0.8), (200.0, 0.1, 1.0, 1.0)],
            opacity=[(50.0, 0.0), (200.0, 0.9)], window=(0.0, 255.0),
            window_range=(0.0, 255.0))),
    ])


def expected_rgba(array: np.ndarray, model: SceneModel, rows_cols) -> np.ndarray:
    """Direct per-pixel computation: ``rows_cols(c)`` is channel c's 2-D slice."""
    rgb, weight, transparency = 0.0, 0.0, 1.0
    composite = model.render.channel_mixing == "composite"
    for c, channel in enumerate(model.channels):
        if not channel.visible:
            continue
        source = channel.tf_linked_to if channel.tf_linked_to is not None else c
        tf = model.channels[source].tf
        v = rows_cols(c).astype(np.float64)
        pts = np.array(tf.colors)
        color = np.stack([np.interp(v, pts[:, 0], pts[:, k]) for k in (1, 2, 3)], -1)
        alpha = np.interp(v, *np.array(tf.opacity).T)
        rgb = rgb + (alpha[..., None] * color if composite else color)
        weight = weight + alpha
        transparency = transparency * (1.0 - alpha)
    if composite:
        w = np.asarray(weight)[..., None]
        rgb = np.where(w > 0, rgb / np.where(w > 0, w, 1.0), 0.0)
    out = np.zeros((*np.shape(transparency), 4)) if np.ndim(transparency) else None
    assert out is not None
    out[..., :3] = np.clip(rgb, 0.0, 1.0)
    out[..., 3] = 1.0 - transparency
    return out


@pytest.mark.parametrize(("plane", "index", "direct"), [
    ("xy", 3, lambda a, c, k: a[c, k, :, :]),          # rows y, columns x
    ("yz", 4, lambda a, c, i: a[c, :, :, i].T),        # rows y, columns z
    ("xz", 2, lambda a, c, j: a[c, :, j, :]),          # rows z, columns x
])
@pytest.mark.parametrize("mixing", ["additive", "composite"])
def test_slice_matches_direct_numpy(plane, index, direct, mixing):
    data, model = phantom(), two_channel_model()
    model.render.channel_mixing = mixing
    got = slice_rgba(data, model, plane, index)
    want = expected_rgba(data.array, model, lambda c: direct(data.array, c, index))
    assert got.dtype == np.float32 and got.shape == want.shape
    np.testing.assert_allclose(got, want, atol=1e-5)
    np.testing.assert_array_equal(slice_values(data.array, plane, index)[1],
                                  direct(data.array, 1, index))


def test_visibility_and_linked_tf_change_the_pixels():
    data, model = phantom(), two_channel_model()
    both = slice_rgba(data, model, "xy", 1)
    model.channels[1].visible = False
    only_a = slice_rgba(data, model, "xy", 1)
    # Channel a's colour ramp has no blue: with b hidden the slice has none either.
    assert both[..., 2].max() > 0.5 and only_a[..., 2].max() == 0.0
    np.testing.assert_allclose(only_a, expected_rgba(
        data.array, model, lambda c: data.array[c, 1]), atol=1e-5)
    model.channels[1].visible = True
    model.channels[1].tf_linked_to = 0  # b now follows a's TF: red ramp, no blue
    linked = slice_rgba(data, model, "xy", 1)
    assert linked[..., 2].max() == 0.0
    np.testing.assert_allclose(linked, expected_rgba(
        data.array, model, lambda c: data.array[c, 1]), atol=1e-5)
    model.channels[0].visible = model.channels[1].visible = False
    assert not slice_rgba(data, model, "xy", 1).any()


def test_a_bright_voxel_lands_on_its_pixel():
    array = np.zeros((1, 4, 5, 6), dtype=np.uint8)
    array[0, 2, 3, 4] = 255  # z = 2, y = 3, x = 4
    data = VolumeData.from_array(array, (1.0, 1.0, 3.0), ["c"])
    model = SceneModel(channels=[Channel(tf=TransferFunction.ramp(0.0, 255.0))])
    for plane, index, pixel in (("xy", 2, (3, 4)), ("yz", 4, (3, 2)), ("xz", 3, (2, 4))):
        image = to_rgba8(slice_rgba(data, model, plane, index))
        lit = np.argwhere(image[..., 0] > 0)
        assert [tuple(p) for p in lit] == [pixel], plane
        assert tuple(image[pixel]) == (255, 255, 255, 204)  # white, opacity 0.8


def test_slice_index_outside_is_refused():
    with pytest.raises(ValueError, match=r"slice 5 along z is outside 0…4"):
        slice_values(phantom().array, "xy", 5)


def test_cursor_index_rounds_and_clamps():
    shape, spacing = (5, 6, 7), (0.5, 0.25, 2.0)
    assert cursor_index((1.2, 0.6, 3.1), shape, spacing) == (2, 2, 2)
    assert cursor_index((-40.0, 1e9, 100.0), shape, spacing) == (0, 5, 4)  # clamped
    assert cursor_index(None, shape, spacing) == (3, 2, 2)  # the centre voxel
    assert default_cursor(shape, spacing) == (1.5, 0.5, 4.0)
    assert snap_cursor((100.0, -1.0, 2.9), shape, spacing) == (3.0, 0.0, 2.0)
    assert box_um(shape, spacing) == ((0.0, 0.0, 0.0), (3.0, 1.25, 8.0))
    with pytest.raises(ValueError, match=r"cursor \(nan, 0\.0, 0\.0\) µm must be finite"):
        cursor_index((math.nan, 0.0, 0.0), shape, spacing)


@pytest.mark.parametrize("bad", [(math.nan, 0.0, 0.0), (0.0, math.inf, 1.0)])
def test_model_refuses_a_cursor_that_is_not_finite(bad):
    model = SceneModel()
    with pytest.raises(ValueError, match=r"cursor \(.*\) must be finite"):
        model.cursor = bad
    assert model.cursor is None


def test_planes_cover_the_three_axes():
    assert sorted(p.normal for p in PLANES.values()) == [0, 1, 2]
    for p in PLANES.values():
        assert sorted((p.normal, p.column, p.row)) == [0, 1, 2]


@pytest.mark.parametrize(("dtype", "high"), [(np.uint16, 30), (np.uint16, 60000), (np.int16, 40),
                                             (np.uint8, 255), (np.float32, 30)])
def test_table_lookup_equals_evaluating_each_voxel(dtype, high):
    """Integer slices of a narrow value span go through a table of the TF; wide spans and
    floats evaluate it per voxel; both give the same pixels."""
    from vtkvol.engine.slices import _tf_lookup

    rng = np.random.default_rng(5)
    values = rng.integers(-10 if dtype is np.int16 else 0, high, size=(40, 50)).astype(dtype)
    tf = two_channel_model().channels[1].tf
    color, alpha = _tf_lookup(tf, values)
    np.testing.assert_array_equal(color, tf.color_at(values))
    np.testing.assert_array_equal(alpha, tf.opacity_at(values))
    data = VolumeData.from_array(values[None, None].astype(dtype), (1.0, 1.0, 1.0), ["v"])
    model = SceneModel(channels=[Channel(tf=tf)])
    want = expected_rgba(data.array, model, lambda c: data.array[c, 0])
    np.testing.assert_allclose(slice_rgba(data, model, "xy", 0), want, atol=1e-5)
