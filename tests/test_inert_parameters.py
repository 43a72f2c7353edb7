"""Parameters that do nothing say so: setting a parameter whose ``applies_when`` is false
warns once, naming the parameter that would enable it (review 2, §6: the README's own example
``softness=1.5`` has no effect under the default ``softness_from="light size"``)."""

from __future__ import annotations

import warnings

import pytest

from vtkvol.model.techniques import get_spec


def test_inert_reason_names_the_enabling_parameter() -> None:
    softness = get_spec("shadow_volume").parameter("softness")
    defaults = get_spec("shadow_volume").defaults()
    assert softness.inert_reason(defaults) == (
        "softness has no effect while softness_from is 'light size'; "
        "set softness_from='custom'")
    assert softness.inert_reason({**defaults, "softness_from": "custom"}) is None
    assert get_spec("shadow_volume").parameter("model").inert_reason(defaults) is None


@pytest.mark.gl
def test_setting_an_inert_parameter_warns_once() -> None:
    from vtkvol.engine.api import offscreen_view
    from vtkvol.io import confocal_phantom

    data = confocal_phantom((16, 24, 24), voxel_size_um=(0.5, 0.5, 1.0))
    with offscreen_view(data, size=(48, 48), method="shadow_volume") as (_rw, scene, _):
        il = scene.illuminator
        assert il is not None
        with pytest.warns(UserWarning, match=r"shadow_volume: softness has no effect while "
                          r"softness_from is 'light size'; set softness_from='custom'"):
            il.set_parameters(softness=0.5)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            il.set_parameters(softness=0.7)  # once per parameter
            il.set_parameters(softness_from="custom", softness=1.5)  # now it applies
            il.set_parameters(model="transmittance")  # no applies_when: never warns
