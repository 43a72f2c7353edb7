"""GL failures: a technique whose shader does not compile falls back with a clear message."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

from vtkvol.engine import shaders
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.engine.technique import Technique
from vtkvol.model.techniques import TechniqueSpec, register

pytestmark = pytest.mark.gl

BROKEN_GLSL = """
//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS) { return this_does_not_exist; }
float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }
"""


BROKEN = TechniqueSpec(name="broken", label="Broken on purpose",
                       engine=f"{__name__}:BrokenTechnique")


class BrokenTechnique(Technique):
    SPEC = BROKEN
    SHADER: ClassVar[str] = "broken.glsl"

    def sections(self, values):
        return shaders.parse(BROKEN_GLSL, "broken.glsl")


@pytest.fixture
def broken_registered():
    with register(BROKEN):
        yield


def test_shader_compile_failure_falls_back_to_local_and_reports(broken_registered):
    arr = np.zeros((16, 16, 16), np.float32)
    arr[4:12, 4:12, 4:12] = 1.0
    rw, ren, volume = simple_volume_scene(arr, size=(64, 64))
    il = Illuminator(volume, ren, method="broken")
    messages: list[str] = []
    il.on_error = messages.append
    grab(rw)  # fails to compile: black frame, error reported
    image = grab(rw)  # next frame: local shading
    assert il.method == "local"
    assert messages and "'Broken on purpose'" in messages[0] and "local shading" in messages[0]
    assert image.max() > 50, "the fallback frame shows the volume again"
    il.release()
    rw.Finalize()


def test_render_image_of_a_broken_technique_shows_local_shading(broken_registered, small_volume):
    from vtkvol.engine.api import render_image

    broken = render_image(small_volume, method="broken", size=(64, 64))
    local = render_image(small_volume, method="local", size=(64, 64))
    assert np.abs(broken.astype(int) - local.astype(int)).max() <= 2
    assert local.max() > 50
