"""The shadow volume's lookup (shadow_volume.glsl): its once-per-fragment affine map and
per-light offsets give the image of the per-sample formula they replace.

The reference, shaders/per_sample_lookup.glsl, is the lookup as first written
(docs/shadow-volume.md, "Frame time"): per sample and light, the near end of the sample's ray
segment (one step back along the ray), the direction towards the light converted to texture
units, the offset of h0 light-grid cells along it, then VTK's texture coordinate → 0..1 over
the point bounds → the light grid. Both are rendered in the same scene and compared pixel by
pixel (8-bit levels)."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model import Light
from vtkvol.reference import phantom_sphere_over_slab

#: The per-sample reference formula (the lookup as first written), a shader of the plugin.
PER_SAMPLE = "per_sample_lookup.glsl"

CASES = {
    "directional": ({}, [Light(direction=(0.35, 0.2, 1.0))], (1.0, 1.0, 1.0)),
    "anisotropic_half": ({"resolution": "half"}, [Light(direction=(-0.5, 0.3, 1.0))],
                         (0.8, 0.8, 2.0)),
    "quarter_big_offset": ({"resolution": "quarter", "offset": 3.0},
                           [Light(direction=(0.2, -0.4, 1.0))], (1.0, 1.0, 1.0)),
    "point": ({}, [Light(kind="point", position=(40.0, 10.0, 60.0))], (1.0, 1.0, 1.0)),
    "point_anisotropic_half": ({"resolution": "half"},
                               [Light(kind="point", position=(-5.0, 30.0, 45.0))],
                               (1.0, 1.5, 1.25)),
    "four_mixed": ({}, [Light(direction=(0.3, 0.2, 1.0), intensity=0.3),
                        Light(kind="point", position=(30.0, -10.0, 50.0), intensity=0.3),
                        Light(direction=(-0.7, 0.3, 0.6), intensity=0.3),
                        Light(direction=(0.1, 0.8, 0.5), intensity=0.3)], (1.0, 1.0, 1.5)),
    "offset_0": ({"offset": 0.0, "softness": 0.0}, [Light(direction=(0.6, 0.0, 1.0))],
                 (1.0, 1.0, 1.0)),
}


def _render_pair(params, lights, spacing, origin=(0.0, 0.0, 0.0)):
    """(shipped lookup, per-sample reference, local shading) images of one scene."""
    data = phantom_sphere_over_slab(40, sphere_opacity=0.9, slab_opacity=0.7)
    rw, ren, volume = simple_volume_scene(data, spacing=spacing, size=(96, 96), elevation=35,
                                          azimuth=20, opacity=[(0.0, 0.0), (1.0, 1.0)])
    volume.GetMapper().GetInput().SetOrigin(*origin)
    ren.ResetCamera()
    il = Illuminator(volume, ren, method="local", lights=lights)
    try:
        local = grab(rw)
        il.set_method("shadow_volume", params)
        shipped = grab(rw)
        grab(rw)  # the build is captured on the frame after it
        source = il.fragment_source
        il.technique.SHADER = PER_SAMPLE  # the instance's shader from the next frame on
        reference = grab(rw)
        grab(rw)
        assert "vv_sv_setup" not in il.fragment_source  # the reference really was built
    finally:
        il.release()
        rw.Finalize()
    return shipped, reference, local, source


@pytest.mark.gl
@pytest.mark.parametrize("name", list(CASES))
def test_lookup_matches_the_per_sample_formula(name):
    params, lights, spacing = CASES[name]
    origin = (3.0, -7.5, 11.0) if "point" in name else (0.0, 0.0, 0.0)
    shipped, reference, local, source = _render_pair(params, lights, spacing, origin)
    assert "vv_sv_setup();" in source
    assert ("#define VV_SV_POINT_LIGHTS 1" in source) == any(lt.kind == "point" for lt in lights)
    diff = np.abs(shipped.astype(int) - reference.astype(int))
    # Measured: 0 levels in every case (the same arithmetic, reassociated).
    assert diff.max() <= 1, (name, int(diff.max()), int((diff > 0).sum()))
    # Not vacuous: the shadow is there (darker than local shading, visibly).
    darkening = local.astype(float).mean() - shipped.astype(float).mean()
    assert darkening > 1.0, darkening


@pytest.mark.gl
def test_changing_a_light_to_a_point_light_rebuilds_the_lookup():
    # The point-light code is compiled in only while a light is one (VV_SV_POINT_LIGHTS): a
    # light changed in place must switch it, and the image must then match the reference.
    data = phantom_sphere_over_slab(32, sphere_opacity=0.9, slab_opacity=0.7)
    rw, ren, volume = simple_volume_scene(data, size=(64, 64), elevation=35,
                                          opacity=[(0.0, 0.0), (1.0, 1.0)])
    il = Illuminator(volume, ren, method="shadow_volume", lights=[Light(direction=(0.3, 0, 1))])
    try:
        grab(rw)
        grab(rw)
        assert "#define VV_SV_POINT_LIGHTS 0" in il.fragment_source
        il.set_lights([Light(kind="point", position=(20.0, 8.0, 45.0))])
        shipped = grab(rw)
        grab(rw)
        assert "#define VV_SV_POINT_LIGHTS 1" in il.fragment_source
        il.technique.SHADER = PER_SAMPLE
        reference = grab(rw)
        il.set_lights([Light(direction=(0.3, 0, 1))])
        il.technique.SHADER = type(il.technique).SHADER
        grab(rw)
        grab(rw)
        assert "#define VV_SV_POINT_LIGHTS 0" in il.fragment_source
    finally:
        il.release()
        rw.Finalize()
    assert np.abs(shipped.astype(int) - reference.astype(int)).max() <= 1
