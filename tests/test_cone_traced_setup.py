"""Cone-traced shadows: each directional light's cone axis and sine are set up once per fragment
(cone_traced.glsl, vv_ct_setup) and give the image of the per-sample formula they replace.

The reference (``ConeTraced.per_sample_setup``, technique.PER_SAMPLE_SETUP) is the same shader
with those two values computed per sample again, as they were before (the axis from the
sample's direction to the light through the texture–dataset matrix, the sine of the light's
angular radius or the custom cone's); both are rendered in the same scene and compared pixel by
pixel (8-bit levels)."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model import Light
from vtkvol.reference import phantom_sphere_over_slab

CASES = {
    "light_size": ({"ao_mode": "off"}, [Light(direction=(0.3, 0.2, 1.0), size=4.0)],
                   (1.0, 1.0, 1.0)),
    "custom_cone_anisotropic": ({"ao_mode": "off", "shadow_cone": "custom",
                                 "shadow_angle": 8.0},
                                [Light(direction=(-0.4, 0.3, 1.0))], (0.8, 1.0, 1.6)),
    "baked_ao_two_lights": ({}, [Light(direction=(0.3, 0.2, 1.0), intensity=0.5, size=2.0),
                                 Light(direction=(-0.6, 0.1, 0.8), intensity=0.5, size=6.0)],
                            (1.0, 1.0, 1.0)),
    "mixed_point": ({"ao_mode": "off"},
                    [Light(direction=(0.3, 0.2, 1.0), intensity=0.5, size=3.0),
                     Light(kind="point", position=(30.0, 10.0, 55.0), intensity=0.5, size=2.0)],
                    (1.0, 1.0, 1.0)),
}


@pytest.mark.gl
@pytest.mark.parametrize("name", list(CASES))
def test_per_fragment_cone_setup_matches_the_per_sample_formula(name):
    params, lights, spacing = CASES[name]
    data = phantom_sphere_over_slab(36, sphere_opacity=0.9, slab_opacity=0.7)
    rw, ren, volume = simple_volume_scene(data, spacing=spacing, size=(96, 96), elevation=40,
                                          azimuth=15, opacity=[(0.0, 0.0), (1.0, 1.0)])
    il = Illuminator(volume, ren, method="local", lights=lights)
    try:
        local = grab(rw)
        il.set_method("cone_traced", params)
        shipped = grab(rw)
        grab(rw)  # the build is captured on the frame after it
        source = il.fragment_source
        il.technique.per_sample_setup = True  # PER_SAMPLE_SETUP from the next frame on
        reference = grab(rw)
        grab(rw)
        reference_source = il.fragment_source
        assert il.method == "cone_traced", il.last_error  # no fallback to local shading
    finally:
        il.release()
        rw.Finalize()
    assert "vv_ct_setup();" in source and "vv_ct_lightVox[light]" in source
    assert "vv_ct_lightVox[light]" not in reference_source  # the reference really was built
    assert ("#define VV_CT_POINT_LIGHTS 1" in source) == any(lt.kind == "point" for lt in lights)
    diff = np.abs(shipped.astype(int) - reference.astype(int))
    # Measured: 0 levels in every case.
    assert diff.max() <= 1, (name, int(diff.max()), int((diff > 0).sum()))
    # Not vacuous: the shadows are there.
    assert local.astype(float).mean() - shipped.astype(float).mean() > 1.0
