"""2-D transfer functions (value × gradient magnitude): the pure model and its session form."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from vtkvol.model import Channel, SceneModel, TransferFunction
from vtkvol.model.session import SessionError, read_session
from vtkvol.model.transfer_function import (
    MAX_PRIMITIVES,
    TFPrimitive,
    TransferFunction2D,
    table_axes,
    table_from_1d,
)


def test_rectangle_soft_edge_is_a_linear_ramp_over_its_fraction_of_the_half_width() -> None:
    rect = TFPrimitive(value_range=(10.0, 20.0), gradient_range=(0.0, 100.0), soft_edge=0.4)
    # half-width 5, soft edge 0.4 → ramps over 2 data units at each side
    cov = rect.coverage(np.array([9.0, 10.0, 11.0, 12.0, 15.0, 18.0, 19.0, 20.0, 21.0]), 50.0)
    np.testing.assert_allclose(cov, [0, 0, 0.5, 1, 1, 1, 0.5, 0, 0])
    # the bottom border on the gradient origin does not fade; the top one does
    np.testing.assert_allclose(rect.coverage(15.0, np.array([0.0, 10.0, 90.0, 100.0])),
                               [1, 1, 0.5, 0])


def test_hard_rectangle_and_triangle_cover_their_shapes() -> None:
    rect = TFPrimitive(value_range=(10.0, 20.0), gradient_range=(5.0, 8.0))
    assert rect.coverage(15.0, 4.9) == 0 and rect.coverage(15.0, 6.0) == 1
    tri = TFPrimitive(kind="triangle", value_range=(10.0, 20.0), gradient_range=(0.0, 10.0))
    # apex at (15, 0), base from 10 to 20 at gradient 10: half-width = gradient / 2
    assert tri.coverage(15.0, 1.0) == 1
    assert tri.coverage(17.0, 3.0) == 0 and tri.coverage(17.0, 5.0) == 1
    assert tri.coverage(15.0, 10.5) == 0 and tri.coverage(15.0, 0.0) == 0


def test_overlaps_combine_as_absorbers_with_weighted_colour() -> None:
    red = TFPrimitive(value_range=(0.0, 10.0), gradient_range=(0.0, 10.0), color=(1, 0, 0),
                      opacity=0.5)
    blue = TFPrimitive(value_range=(5.0, 15.0), gradient_range=(0.0, 10.0), color=(0, 0, 1),
                       opacity=0.25)
    tf = TransferFunction2D(primitives=[red, blue])
    rgba = tf.evaluate(np.array([2.0, 7.0, 12.0, 20.0]), 1.0)
    np.testing.assert_allclose(rgba[:, 3], [0.5, 1 - 0.5 * 0.75, 0.25, 0.0], atol=1e-7)
    np.testing.assert_allclose(rgba[1, :3], [0.5 / 0.75, 0, 0.25 / 0.75], atol=1e-6)
    np.testing.assert_allclose(rgba[3], 0.0)


def test_table_samples_texel_centres_with_rows_along_the_gradient() -> None:
    rect = TFPrimitive(value_range=(0.0, 50.0), gradient_range=(0.0, 2.0), opacity=1.0)
    tf = TransferFunction2D(primitives=[rect])
    table = tf.table((0.0, 100.0), (0.0, 4.0), (4, 10))
    assert table.shape == (4, 10, 4) and table.dtype == np.float32
    values, gradients = table_axes((0.0, 100.0), (0.0, 4.0), (4, 10))
    np.testing.assert_allclose(values, np.arange(10) * 10 + 5)
    np.testing.assert_allclose(gradients, [0.5, 1.5, 2.5, 3.5])
    assert (table[:2, :5, 3] == 1).all() and (table[2:, :, 3] == 0).all()
    assert (table[:, 5:, 3] == 0).all()


def test_1d_table_is_constant_along_the_gradient_and_equals_the_1d_tf() -> None:
    tf = TransferFunction(colors=[(0, 0, 0, 0), (100, 1, 0.5, 0)], opacity=[(0, 0), (100, 0.8)],
                          window=(0, 100), window_range=(0, 100))
    table = table_from_1d(tf, (0.0, 100.0), (3, 8))
    values, _ = table_axes((0.0, 100.0), (0.0, 1.0), (3, 8))
    np.testing.assert_allclose(table[0, :, 3], tf.opacity_at(values))
    np.testing.assert_allclose(table[0, :, :3], tf.color_at(values))
    assert (table == table[:1]).all()


def test_events_are_fine_grained_and_the_model_round_trips() -> None:
    model = SceneModel(channels=[Channel(), Channel()])
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    model.channels[1].tf_mode = "2d"
    model.channels[1].tf2d.primitives = [TFPrimitive()]
    model.channels[1].tf2d.primitives[0].opacity = 0.9
    assert seen == [frozenset({"channels[1].tf_mode"}), frozenset({"channels[1].tf2d.primitives"}),
                    frozenset({"channels[1].tf2d.primitives[0].opacity"})]
    again = SceneModel.model_validate(json.loads(model.model_dump_json()))
    assert again == model


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"value_range": (20.0, 10.0)}, "value range (20.0, 10.0) must be increasing"),
        ({"gradient_range": (1.0, 1.0)}, "gradient range (1.0, 1.0) must be increasing"),
        ({"value_range": (math.nan, 1.0)}, "value range (nan, 1.0) must be finite"),
        ({"gradient_range": (0.0, math.inf)}, "gradient range (0.0, inf) must be finite"),
        ({"value_range": (0.0, 1e300)}, "out of range"),
        ({"opacity": math.nan}, "opacity"),
        ({"opacity": 1.5}, "opacity"),
        ({"soft_edge": -0.1}, "soft_edge"),
        ({"color": (1.0, 2.0, 0.0)}, "r, g, b must lie in 0…1"),
        ({"kind": "circle"}, "kind"),
    ],
)
def test_hostile_primitives_are_rejected(kwargs: dict, message: str) -> None:
    with pytest.raises(ValidationError, match=message.replace("(", r"\(").replace(")", r"\)")):
        TFPrimitive(**kwargs)


def test_hostile_tables_and_lists_are_rejected() -> None:
    tf = TransferFunction2D()
    with pytest.raises(ValueError, match="table shape"):
        tf.table((0.0, 1.0), (0.0, 1.0), (100_000, 100_000))
    with pytest.raises(ValueError, match="table shape"):
        tf.table((0.0, 1.0), (0.0, 1.0), (0, 16))
    with pytest.raises(ValueError, match="value range"):
        tf.table((1.0, 1.0), (0.0, 1.0), (4, 4))
    with pytest.raises(ValueError, match="gradient range"):
        tf.table((0.0, 1.0), (0.0, math.nan), (4, 4))
    with pytest.raises(ValidationError, match="at most"):
        TransferFunction2D(primitives=[TFPrimitive()] * (MAX_PRIMITIVES + 1))
    with pytest.raises(ValidationError, match="gradient_max"):
        TransferFunction2D(gradient_max=-1.0)


def test_hostile_session_value_gives_one_line_message(tmp_path: Path) -> None:
    path = tmp_path / "bad.vtkvol.json"
    path.write_text(json.dumps({
        "format": "vtkvol-session", "version": 6, "data": {"path": None},
        "scene": {"channels": [{"name": "a", "tf_mode": "2d", "tf2d": {"primitives": [
            {"value_range": [50.0, 10.0]}]}}]},
    }), encoding="utf-8")
    with pytest.raises(SessionError) as info:
        read_session(path)
    text = str(info.value)
    assert "\n" not in text
    assert "channels[0].tf2d.primitives[0].value_range" in text
    assert "must be increasing" in text


def test_table_rasterises_each_primitive_inside_its_box_only_with_the_same_result() -> None:
    from vtkvol.model.transfer_function import rasterise

    rng = np.random.default_rng(3)
    prims = [TFPrimitive(kind=str(rng.choice(["rectangle", "triangle"])),
                         value_range=tuple(sorted(rng.uniform(-10, 300, 2))),
                         gradient_range=tuple(sorted(rng.uniform(0, 60, 2))),
                         soft_edge=float(rng.uniform()), opacity=float(rng.uniform()),
                         color=tuple(rng.uniform(size=3))) for _ in range(12)]
    # and edges exactly on texel centres
    prims.append(TFPrimitive(value_range=(5.0, 45.0), gradient_range=(12.5, 37.5)))
    tf = TransferFunction2D(primitives=prims)
    np.testing.assert_array_equal(tf.table((0, 100), (0, 50), (20, 10)),
                                  rasterise(tf.evaluate, (0, 100), (0, 50), (20, 10)))
    np.testing.assert_array_equal(tf.table((0, 255), (0, 50), (64, 128)),
                                  rasterise(tf.evaluate, (0, 255), (0, 50), (64, 128)))
