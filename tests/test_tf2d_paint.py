"""The painted layer of 2-D transfer functions: the brush, the raster's combination with the
primitives, its compact serialised form and hostile values, and the opacity volume and image
that follow it (docs/transfer-functions-2d.md)."""

from __future__ import annotations

import base64
import json
import math
import zlib
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError
from test_tf2d_engine import BACKGROUND, View, sphere_and_slab

from vtkvol.model.defaults import scene_for
from vtkvol.model.gradient import gradient_magnitude
from vtkvol.model.migrations import VERSION
from vtkvol.model.session import SessionError, read_session
from vtkvol.model.tf_paint import (
    MAX_PAINT_SIZE,
    PAINT_SHAPE,
    TFPaintLayer,
    apply_stroke,
    encode_pixels,
    stroke_mask,
)
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D, rasterise


def blob(layer: TFPaintLayer, centre: tuple[float, float], radius: float,
         color=(1.0, 0.0, 0.0), opacity: float = 0.9) -> TFPaintLayer:
    return layer.with_pixels(apply_stroke(layer.pixels(), stroke_mask(layer.shape, [centre],
                                                                      radius), color, opacity))


# -- the brush ---------------------------------------------------------------------------------
def interiors_scene() -> tuple[np.ndarray, object]:
    """The sphere over a slab with shadows and a 2-D TF that classifies interiors only (low
    gradients): the sphere's flanks are left for a painted layer to add."""
    data = sphere_and_slab()
    model = scene_for(data)
    model.illumination.method = "shadow_volume"
    model.channels[0].tf2d = TransferFunction2D(primitives=[TFPrimitive(
        value_range=(150.0, 300.0), gradient_range=(0.0, 4.0), opacity=0.5)])
    model.channels[0].tf_mode = "2d"
    return data, model


def test_stroke_mask_covers_the_segments_within_the_radius_with_a_one_pixel_edge() -> None:
    mask = stroke_mask((32, 48), [(10.0, 8.0), (30.0, 8.0)], 3.0)
    assert mask[8, 10:31].min() == 1.0 and mask[10, 20] == 1.0  # on and 2 px off the line
    assert mask[11, 20] == pytest.approx(0.5) and mask[12, 20] == 0.0  # the antialiased edge
    assert mask[8, 34] == 0.0 and mask[8, 33] == pytest.approx(0.5)  # round cap at the end
    # A pixel crossed twice is covered once: a stroke does not pile up.
    again = stroke_mask((32, 48), [(10.0, 8.0), (30.0, 8.0), (10.0, 8.0)], 3.0)
    np.testing.assert_array_equal(again, mask)
    # NaN points are skipped; a lone point is a dab.
    dab = stroke_mask((32, 48), [(math.nan, 1.0), (5.0, 5.0)], 2.0)
    assert dab[5, 5] == 1.0 and dab.sum() == pytest.approx(np.pi * 2.0**2, rel=0.1)


def test_apply_stroke_paints_premultiplied_and_erase_restores_exactly() -> None:
    base = np.zeros((16, 16, 4), np.uint8)
    mask = stroke_mask((16, 16), [(8.0, 8.0)], 3.0)
    red = apply_stroke(base, mask, (1.0, 0.0, 0.0), 0.8)
    assert red[8, 8].tolist() == [255, 0, 0, 204]
    edge = red[8, 11]  # half covered: half the alpha, the full colour (not darker)
    assert edge[3] == 102 and edge[0] == 255
    assert red[0, 0].tolist() == [0, 0, 0, 0]
    # over red, blue at full coverage replaces it; at half coverage mixes premultiplied
    both = apply_stroke(red, stroke_mask((16, 16), [(12.0, 8.0)], 0.5), (0.0, 0.0, 1.0), 0.8)
    assert both[8, 12].tolist() == [0, 0, 255, 204]
    # the eraser where it covers fully gives exact zeros, untouched pixels keep their bytes
    erased = apply_stroke(both, stroke_mask((16, 16), [(8.0, 8.0)], 6.0), (1, 1, 1), 1.0,
                          erase=True)
    np.testing.assert_array_equal(erased, base)
    partial = apply_stroke(red, stroke_mask((16, 16), [(2.0, 8.0)], 1.0), (1, 1, 1), 1.0,
                           erase=True)
    far = stroke_mask((16, 16), [(2.0, 8.0)], 1.0) == 0
    np.testing.assert_array_equal(partial[far], red[far])


# -- the layer in the 2-D TF -------------------------------------------------------------------
def test_paint_combines_with_primitives_as_independent_absorbers() -> None:
    layer = TFPaintLayer.blank((0.0, 128.0), (0.0, 64.0), shape=(64, 128))
    uniform = np.zeros((64, 128, 4), np.uint8)
    uniform[..., 1] = 255
    uniform[..., 3] = 102  # α = 0.4
    layer = layer.with_pixels(uniform)
    prim = TFPrimitive(value_range=(0.0, 256.0), gradient_range=(0.0, 100.0), opacity=0.5,
                       color=(1.0, 0.0, 0.0))
    tf = TransferFunction2D(primitives=[prim], paint=layer)
    rgba = tf.evaluate(np.array([20.0, 100.0, 200.0]), 30.0)
    a_p = 102 / 255
    # inside the layer's box both absorb; outside (value 200) only the rectangle
    np.testing.assert_allclose(rgba[:2, 3], 1 - (1 - 0.5) * (1 - a_p), atol=1e-6)
    np.testing.assert_allclose(rgba[:2, :3], [[0.5 / (0.5 + a_p), a_p / (0.5 + a_p), 0]] * 2,
                               atol=1e-6)
    np.testing.assert_allclose(rgba[2], [1.0, 0.0, 0.0, 0.5], atol=1e-6)


def test_paint_is_bilinear_between_pixel_centres_and_clamped_inside_its_box() -> None:
    layer = TFPaintLayer.blank((0.0, 4.0), (0.0, 2.0), shape=(2, 4))
    pixels = np.zeros((2, 4, 4), np.uint8)
    pixels[:, 1] = (255, 255, 255, 255)  # column 1 (value centre 1.5) fully opaque white
    layer = layer.with_pixels(pixels)
    alpha, premult = layer.sample(np.array([0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 4.0, 4.01]), 1.0)
    np.testing.assert_allclose(alpha, [0, 0, 0.5, 1, 0.5, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(premult[:, 0], alpha, atol=1e-12)  # white premultiplied
    # A table over the renderer's axes equals evaluate at texel centres.
    tf = TransferFunction2D(paint=blob(TFPaintLayer.blank((10.0, 90.0), (0.0, 30.0)),
                                       (60.0, 40.0), 12.0),
                            primitives=[TFPrimitive(value_range=(0, 50), gradient_range=(5, 9))])
    np.testing.assert_allclose(tf.table((0, 100), (0, 40), (96, 80)),
                               rasterise(tf.evaluate, (0, 100), (0, 40), (96, 80)), atol=1e-6)


def test_the_layer_is_compact_and_round_trips_through_json() -> None:
    layer = blob(TFPaintLayer.blank((0.0, 255.0), (0.0, 50.0)), (40.0, 30.0), 8.0)
    assert layer.shape == PAINT_SHAPE
    assert len(layer.rgba) < 2000  # 64 KiB of pixels, mostly empty
    again = TransferFunction2D.model_validate(json.loads(
        TransferFunction2D(paint=layer).model_dump_json()))
    np.testing.assert_array_equal(again.paint.pixels(), layer.pixels())
    assert again.paint.value_range == (0.0, 255.0)


def test_restoring_a_state_replaces_the_layer_whole_whatever_its_shape() -> None:
    """Undo and opening a session assign states field by field; the layer's shape and
    pixels must change together (a layer is an immutable value)."""
    from vtkvol.model import Channel, SceneModel
    from vtkvol.ui.undo import apply_state

    small = SceneModel(channels=[Channel()])
    small.channels[0].tf2d.paint = blob(TFPaintLayer.blank((0.0, 1.0), (0.0, 1.0), (6, 8)),
                                        (3.0, 2.0), 1.5)
    large = SceneModel(channels=[Channel()])
    large.channels[0].tf2d.paint = blob(TFPaintLayer.blank((0.0, 9.0), (0.0, 2.0)),
                                        (64.0, 64.0), 5.0)
    seen: list[frozenset[str]] = []
    small.changed.connect(seen.append)
    apply_state(small, large.copy_state())
    assert small.channels[0].tf2d.paint == large.channels[0].tf2d.paint
    assert seen == [frozenset({"channels[0].tf2d.paint"})]
    with pytest.raises(ValidationError, match="frozen"):
        small.channels[0].tf2d.paint.shape = (6, 8)  # type: ignore[misc]


def _packed(array: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(array.tobytes())).decode()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"shape": (3, 3), "rgba": encode_pixels(np.zeros((4, 4, 4), np.uint8))},
         "holds more than 36 bytes, expected height × width × 4 = 3 × 3 × 4 = 36"),
        ({"shape": (4, 4), "rgba": encode_pixels(np.zeros((3, 3, 4), np.uint8))},
         "holds 36 bytes, expected height × width × 4 = 4 × 4 × 4 = 64"),
        ({"rgba": "not base64!"}, "rgba is not valid base64"),
        ({"rgba": base64.b64encode(b"plain bytes, not zlib").decode()},
         "is not zlib-compressed pixel data"),
        ({"shape": (2, 2), "rgba": _packed(np.zeros(16, np.uint8))[:-8] + "AAAAAAA="},
         "rgba"),
        ({"shape": (10**6, 10**6)}, "shape (1000000, 1000000) must lie within 2…512"),
        ({"shape": (1, 8)}, "must lie within 2…512"),
        ({"shape": (4, 4), "rgba": "A" * 10_000_000}, "too long for 4 × 4 pixels"),
        ({"value_range": (math.nan, 1.0)}, "paint layer value range (nan, 1.0) must be finite"),
        ({"gradient_range": (5.0, 1.0)}, "paint layer gradient range (5.0, 1.0) must be "
                                         "increasing"),
        ({"value_range": (0.0, 1e300)}, "out of range"),
    ],
)
def test_hostile_layers_are_rejected_with_one_line(kwargs: dict, message: str) -> None:
    with pytest.raises(ValidationError) as info:
        TFPaintLayer(**kwargs)
    text = str(info.value.errors()[0]["msg"])
    assert message in text and "\n" not in text


def test_a_zip_bomb_is_not_inflated_past_the_stated_size() -> None:
    bomb = base64.b64encode(zlib.compress(bytes(50_000_000))).decode()  # ~50 KB of text
    with pytest.raises(ValidationError, match="holds more than 65536 bytes"):
        TFPaintLayer(shape=(128, 128), rgba=bomb)
    assert MAX_PAINT_SIZE == 512


def test_hostile_paint_in_a_session_gives_one_line_with_its_path(tmp_path: Path) -> None:
    path = tmp_path / "bad.vtkvol.json"
    path.write_text(json.dumps({
        "format": "vtkvol-session", "version": VERSION, "data": {"path": None},
        "scene": {"channels": [{"name": "a", "tf_mode": "2d", "tf2d": {
            "primitives": [], "paint": {"value_range": [0, 255], "gradient_range": [0, 9],
                                        "shape": [128, 128], "rgba": "%%%"}}}]},
    }), encoding="utf-8")
    with pytest.raises(SessionError) as info:
        read_session(path)
    text = str(info.value)
    assert "\n" not in text
    assert "channels[0].tf2d.paint" in text and "not valid base64" in text


# -- engine: the opacity volume and the image follow the paint (GL) ----------------------------
@pytest.mark.gl
def test_painted_blob_adds_opacity_to_its_voxels_and_the_eraser_restores_them() -> None:
    data, model = interiors_scene()
    view = View(data, model)
    try:
        image0 = view.image()
        opacity0 = view.scene.illuminator.opacity_volume().copy()
        (v0, v1), (g0, g1) = view.scene.tf2d_axes(0)
        layer = TFPaintLayer.blank((v0, v1), (g0, g1))
        # A blob over the flanks: values around 70, gradients around 29 per µm.
        centre = tuple(float(c) for c in layer.pixel_coords(70.0, 29.0))
        radius = 14.0
        model.channels[0].tf2d.paint = blob(layer, centre, radius, opacity=0.9)
        opacity1 = view.scene.illuminator.opacity_volume().copy()
        image1 = view.image()

        values = data.array[0].astype(np.float64)
        px, py = layer.pixel_coords(values, gradient_magnitude(data.array[0],
                                                               tuple(data.voxel_size_um)))
        dist = np.hypot(px - centre[0], py - centre[1])
        core = dist < radius - 0.5 - 1.5  # every pixel the bilinear reads is fully painted
        outside = dist > radius + 2.5  # every pixel it reads is blank
        assert core.sum() > 200
        a = round(0.9 * 255) / 255
        np.testing.assert_allclose(opacity1[core], 1 - (1 - opacity0[core]) * (1 - a),
                                   atol=1e-5)
        assert (opacity1[core] > opacity0[core] + 0.5).all()
        np.testing.assert_array_equal(opacity1[outside], opacity0[outside])
        # the flanks now show in the image: more pixels drawn, red
        bg = BACKGROUND
        drawn0 = (np.abs(image0 - bg).max(axis=-1) > 12).mean()
        drawn1 = (np.abs(image1 - bg).max(axis=-1) > 12).mean()
        assert drawn1 > drawn0 + 0.02
        gained = np.abs(image1 - image0).max(axis=-1) > 12
        assert image1[..., 0][gained].mean() > 2 * image1[..., 1][gained].mean()

        # The eraser over the blob: the pixels, the opacity and the image as before.
        painted = model.channels[0].tf2d.paint
        model.channels[0].tf2d.paint = painted.with_pixels(apply_stroke(
            painted.pixels(), stroke_mask(painted.shape, [centre], radius + 3), (0, 0, 0), 1.0,
            erase=True))
        assert model.channels[0].tf2d.paint.empty
        np.testing.assert_array_equal(view.scene.illuminator.opacity_volume(), opacity0)
        np.testing.assert_array_equal(view.image(), image0)
    finally:
        view.close()


def test_paint_from_1d_classifies_as_the_1d_tf():
    """The layer a channel switching to 2-D starts from (issue 25) evaluates as the 1-D TF at
    every gradient inside the axis, to 8-bit rounding."""
    from vtkvol.model.transfer_function import (
        TransferFunction,
        TransferFunction2D,
        paint_from_1d,
    )

    tf = TransferFunction(colors=[(0.0, 0.0, 0.0, 1.0), (500.0, 1.0, 0.5, 0.0),
                                  (1000.0, 1.0, 1.0, 1.0)],
                          opacity=[(100.0, 0.0), (600.0, 0.8), (1000.0, 0.3)],
                          window=(0.0, 1000.0), window_range=(0.0, 1000.0))
    layer = paint_from_1d(tf, (0.0, 1000.0), (0.0, 40.0))
    values = np.linspace(0.0, 1000.0, 301)
    two_d = TransferFunction2D(paint=layer)
    for g in (0.0, 7.3, 39.9):
        rgba = two_d.evaluate(values, np.full_like(values, g))
        np.testing.assert_allclose(rgba[:, 3], tf.opacity_at(values), atol=0.01)
        lit = rgba[:, 3] > 0.05  # colour only means something where there is opacity
        np.testing.assert_allclose(rgba[lit, :3], tf.color_at(values)[lit], atol=0.02)
