"""Model: evented state, validation, parameters, presets (no VTK, no Qt)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from pydantic import ValidationError

from vtkvol.model import (
    Channel,
    CropBox,
    Illumination,
    Invalidates,
    Light,
    Param,
    SceneModel,
    SliceWeights,
    TransferFunction,
)
from vtkvol.model.params import invalidations, validate_values
from vtkvol.model.presets import apply_preset, preset_names


def test_model_imports_neither_vtk_nor_qt():
    code = (
        "import sys, vtkvol.model, vtkvol.model.presets, vtkvol.model.defaults;"
        "bad=[m for m in sys.modules"
        " if m == 'vtk' or m.startswith(('vtkmodules','PySide6','pyvista'))];"
        "print(bad); sys.exit(1 if bad else 0)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_change_events_carry_dotted_paths_and_only_real_changes():
    model = SceneModel()
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    model.crop.x = (0.0, 10.0)
    model.crop.x = (0.0, 10.0)  # same value: no event
    model.channels[0].tf.opacity = [(0.0, 0.0), (100.0, 0.5)]
    assert seen == [frozenset({"crop.x"}), frozenset({"channels[0].tf.opacity"})]


def test_list_elements_announce_their_index_and_replacing_the_list_does_not():
    from vtkvol.model.evented import fields_of, indices, touches

    model = SceneModel(channels=[Channel(name="a"), Channel(name="b"), Channel(name="c")])
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    model.channels[2].tf.opacity = [(0.0, 0.0), (10.0, 1.0)]
    model.channels[1].name = "membrane"
    model.channels = [model.channels[0], model.channels[2]]  # removing "membrane"
    model.channels[1].visible = False  # what was channels[2] is now index 1
    assert seen == [frozenset({"channels[2].tf.opacity"}), frozenset({"channels[1].name"}),
                    frozenset({"channels"}), frozenset({"channels[1].visible"})]
    assert fields_of("channels[2].tf.opacity") == ["channels", "tf", "opacity"]
    assert indices(seen[0] | seen[1], "channels") == {1, 2}
    assert indices(seen[2], "channels") is None
    assert touches(seen[0], "channels", "tf") and not touches(seen[1], "channels", "tf")
    assert touches({"channels"}, "channels", "tf")  # a replaced list may contain anything
    assert not touches({"crop.x"}, "channels")


def test_an_appended_element_announces_its_own_index_and_a_removed_one_is_silent():
    from vtkvol.model.evented import element_fields, subfields

    model = SceneModel(channels=[Channel(name="a"), Channel(name="b")])
    removed = model.channels[1]
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    model.channels = [*model.channels, Channel(name="c")]
    model.channels[2].tf.opacity = [(0.0, 0.0), (10.0, 1.0)]
    model.lights = [*model.lights, Light(direction=(0.0, 0.0, 1.0))]
    model.lights[1].intensity = 0.5
    model.channels = [model.channels[0], model.channels[2]]
    removed.name = "gone"  # no longer in the model: nothing to announce
    model.channels[1].tf.opacity = [(0.0, 0.0), (20.0, 1.0)]
    assert seen == [frozenset({"channels"}), frozenset({"channels[2].tf.opacity"}),
                    frozenset({"lights"}), frozenset({"lights[1].intensity"}),
                    frozenset({"channels"}), frozenset({"channels[1].tf.opacity"})]
    with model.batch():
        model.channels[0].name = "first"
        model.channels[1].tf.opacity = [(0.0, 0.0), (30.0, 1.0)]
        model.channels[1].visible = False
        model.render.jitter = not model.render.jitter
    assert seen[-1] == {"channels[0].name", "channels[1].tf.opacity", "channels[1].visible",
                        "render.jitter"}
    assert element_fields(seen[-1], "channels") == {0: {"name"}, 1: {"tf", "visible"}}
    assert element_fields(seen[0], "channels") is None
    assert element_fields(seen[-1], "lights") == {}
    assert subfields(seen[-1], "render") == {"jitter"}
    assert subfields({"render"}, "render") is None


def test_batch_emits_once_with_all_paths():
    model = SceneModel()
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    with model.batch():
        model.render.jitter = False
        model.lights[0].intensity = 2.0
        model.illumination.method = "shadow_volume"
    assert seen == [frozenset({"render.jitter", "lights[0].intensity", "illumination.method"})]


def test_update_keeps_nested_objects_bound():
    model = SceneModel()
    crop = model.crop
    other = SceneModel()
    other.crop.z = (1.0, 2.0)
    other.render.sample_distance = 1.0
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    model.update(other)
    assert model.crop is crop and crop.z == (1.0, 2.0)
    assert model == other
    assert len(seen) == 1 and {"crop.z", "render.sample_distance"} <= seen[0]


def test_json_round_trip_is_exact():
    model = SceneModel()
    model.lights = [Light(kind="point", position=(1.0, 2.0, 3.0)), Light(direction=(0, 0, 1))]
    model.slice_weights.z = [(0.0, 0.0), (0.2, 1.0), (1.0, 1.0)]
    again = SceneModel.model_validate_json(json.dumps(model.copy_state()))
    assert again == model


@pytest.mark.parametrize(
    ("factory", "message"),
    [
        (lambda: Light(intensity=-1.0), "greater than or equal"),
        (lambda: Light(direction=(0.0, 0.0, 0.0)), "zero vector"),
        (lambda: Light(direction=(float("nan"), 0.0, 1.0)), "finite"),
        (lambda: TransferFunction(opacity=[(0.0, 1.5)]), "alpha must lie in 0…1"),
        (lambda: TransferFunction(window=(5.0, 1.0)), "increasing"),
        (lambda: CropBox(x=(3.0, 1.0)), "increasing"),
        (lambda: SliceWeights(x=[(0.5, 2.0)]), "0…1"),
        (lambda: SceneModel(channels=[Channel()] * 5), "1 to 4 channels"),
        (lambda: Channel(color=(2.0, 0.0, 0.0)), "0…1"),
    ],
)
def test_invalid_values_are_rejected_with_clear_messages(factory, message):
    with pytest.raises(ValidationError, match=message):
        factory()


def test_assignment_is_validated():
    light = Light()
    with pytest.raises(ValidationError):
        light.intensity = -3.0
    assert light.intensity == 1.0


def test_transfer_function_evaluation_and_rescale():
    tf = TransferFunction(
        colors=[(0.0, 0.0, 0.0, 0.0), (100.0, 1.0, 0.5, 0.0)],
        opacity=[(0.0, 0.0), (100.0, 1.0)],
        window=(0.0, 100.0),
        window_range=(0.0, 100.0),
    )
    opacity = tf.opacity_at(np.array([-5.0, 25.0, 50.0, 200.0]))
    np.testing.assert_allclose(opacity, [0, 0.25, 0.5, 1])
    np.testing.assert_allclose(tf.color_at(np.array([50.0]))[0], [0.5, 0.25, 0.0])
    tf.rescale(1000.0, 2000.0)
    assert tf.value_span == (1000.0, 2000.0)
    assert tf.window_range[1] >= 2000.0
    np.testing.assert_allclose(tf.opacity_at(np.array([1500.0])), [0.5])


def test_presets_stretch_over_limits_and_colormaps_work():
    tf = TransferFunction()
    apply_preset(tf, "ct-bone", limits=(0.0, 1000.0))
    assert tf.opacity[0][0] == 0.0 and tf.opacity[-1][0] == 1000.0
    apply_preset(tf, "viridis", limits=(10.0, 20.0), tint=(1.0, 0.0, 0.0))
    assert tf.value_span == (10.0, 20.0) and len(tf.colors) > 2
    assert {"linear", "ct-bone", "fluorescence-soft"} <= set(preset_names())
    with pytest.raises(ValueError, match="unknown preset 'nope'"):
        apply_preset(tf, "nope")


PARAMS = (
    Param("strength", 0.8, "Strength", "How much", range=(0.0, 1.0)),
    Param("count", 6, "Cones", "Number of cones", kind="int", range=(1, 12),
          invalidates=Invalidates.SHADER),
    Param("model", "a", "Model", "Which", kind="choice", choices=("a", "b"),
          invalidates=Invalidates.ILLUMINATION),
    Param("on", True, "On", "Switch", kind="bool"),
)


def test_parameter_validation():
    assert validate_values(PARAMS, {}) == {"strength": 0.8, "count": 6, "model": "a", "on": True}
    assert validate_values(PARAMS, {"count": 3.0})["count"] == 3
    for bad, message in [
        ({"strength": 2.0}, "outside its range 0…1"),
        ({"count": 2.5}, "whole number"),
        ({"model": "c"}, "one of a, b"),
        ({"on": 1}, "true or false"),
        ({"strength": float("inf")}, "finite"),
        ({"bogus": 1}, "unknown parameter"),
    ]:
        with pytest.raises(ValueError, match=message):
            validate_values(PARAMS, bad)
    expected = Invalidates.SHADER | Invalidates.ILLUMINATION
    assert invalidations(PARAMS, ["count", "model"]) == expected


def test_illumination_set_value_emits_and_keeps_other_methods():
    illum = Illumination()
    seen: list[frozenset[str]] = []
    illum.changed.connect(seen.append)
    illum.set_value("softness", 1.5, method="shadow_volume")
    illum.set_value("h0", 3.0, method="cone_traced")
    assert illum.values_for("shadow_volume") == {"softness": 1.5}
    assert illum.values_for("cone_traced") == {"h0": 3.0}
    assert seen == [frozenset({"parameters"})] * 2


def test_equal_but_new_child_objects_still_forward_changes():
    model = SceneModel()
    seen: list[frozenset[str]] = []
    model.changed.connect(seen.append)
    model.lights = [Light()]  # equal to the default list: no event, but a new object
    assert seen == []
    model.lights[0].intensity = 3.0
    assert seen == [frozenset({"lights[0].intensity"})]
