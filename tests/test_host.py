"""The technique host's contract (GL): ownership, hooks, lighting models, progressive and
view-dependent techniques, failures. Techniques here are registered for the test only."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, ClassVar

import numpy as np
import pytest

from vtkvol.engine import shaders
from vtkvol.engine.illuminator import Changes, Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.engine.technique import Technique
from vtkvol.model.params import Invalidates, Param
from vtkvol.model.scene import Light
from vtkvol.model.techniques import TechniqueSpec, register

pytestmark = pytest.mark.gl


def cube(n: int = 24, lo: int = 6, hi: int = 18) -> np.ndarray:
    arr = np.zeros((n, n, n), np.float32)
    arr[lo:hi, lo:hi, lo:hi] = 1.0
    return arr


def inline(name: str, glsl: str, **fields: Any) -> type[Technique]:
    """A technique whose GLSL is ``glsl`` (sectioned text), registered as ``name``."""
    spec = TechniqueSpec(name=name, label=name.title(), engine=f"{__name__}:{name}", **fields)

    class Inline(Technique):
        SPEC = spec
        SHADER: ClassVar[str] = f"{name}.glsl"

        def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
            return shaders.parse(glsl, f"{name}.glsl")

    globals()[name] = Inline
    return Inline


def scene(array: np.ndarray | None = None, **kw: Any):
    return simple_volume_scene(cube() if array is None else array, size=(64, 64), **kw)


# -- ownership ------------------------------------------------------------------------------
def uniform_names(volume) -> set[str]:
    fu = volume.GetShaderProperty().GetFragmentCustomUniforms()
    return {fu.GetNthUniformName(i) for i in range(fu.GetNumberOfUniforms())}


def test_no_uniform_or_texture_of_a_technique_survives_a_switch():
    rw, ren, volume = scene()
    il = Illuminator(volume, ren, method="shadow_volume")
    grab(rw)
    assert any(n.startswith("vv_shadow_volume_") for n in uniform_names(volume))
    assert "vv_shadow_volume_tex" in il._textures
    il.set_method("local")
    image = grab(rw)
    assert not any(n.startswith("vv_shadow_volume_") for n in uniform_names(volume))
    assert il.bound_textures() == {}
    # Only the host's own binding may stay (the empty-space grid, where skipping applies).
    assert set(il._textures) <= {"vv_essOccupancy"}
    assert image.max() > 50
    il.release()
    assert uniform_names(volume) == set()
    rw.Finalize()


# -- hooks and lighting models ----------------------------------------------------------------
RED_LIGHT = """
//@inject //VTK::ComputeLighting::Dec pre before
vec3 vv_light_transmittance_rgb(int light, vec3 texPos, vec3 dirDS) { return vec3(1.0, 0.0, 0.0); }
"""


def test_rgb_transmittance_colours_the_light_and_other_hooks_default():
    inline("red_light", RED_LIGHT, capabilities={"rgb"})
    with register(red_light.SPEC):  # noqa: F821 - defined by inline()
        rw, ren, volume = scene()
        volume.GetProperty().SetAmbient(0.0)
        il = Illuminator(volume, ren, method="red_light")
        grab(rw)
        image = grab(rw).astype(float)
        lit = image[..., 0] > 20
        assert lit.sum() > 50
        assert image[lit, 1].max() < 3 and image[lit, 2].max() < 3  # no green, no blue light
        assert il.last_error is None
        il.set_method("local")
        white = grab(rw).astype(float)
        assert abs(white[..., 1].mean() - white[..., 0].mean()) < 1
        il.release()
        rw.Finalize()


IRRADIANCE = """
//@inject //VTK::ComputeLighting::Dec pre before
vec3 vv_irradiance(vec3 texPos) { return vec3(vv_glow_level); }
"""


def test_medium_model_adds_irradiance_linearly_without_gradients():
    cls = inline("glow", IRRADIANCE, lighting="medium",
                 parameters=(Param("level", 0.5, "Level", "Irradiance.", range=(0.0, 2.0)),))
    with register(cls.SPEC):
        rw, ren, volume = scene(np.full((16, 16, 16), 1.0, np.float32),
                                opacity=[(0.0, 0.02), (1.0, 0.02)])
        volume.GetProperty().SetAmbient(0.0)
        il = Illuminator(volume, ren, method="glow", lights=[])
        assert volume.GetProperty().GetShade(0) == 0  # medium: VTK computes no gradient
        grab(rw)
        half = grab(rw).astype(float)
        il.set_parameters(level=1.0)
        full = grab(rw).astype(float)
        centre = (slice(24, 40), slice(24, 40), 0)
        assert half[centre].mean() > 10
        assert full[centre].mean() / half[centre].mean() == pytest.approx(2.0, rel=0.06)
        il.release()
        assert volume.GetProperty().GetShade(0) == 1  # the user's setting is back
        rw.Finalize()


def test_medium_henyey_greenstein_scatters_forward():
    cls = inline("clear_medium", "", lighting="medium")
    with register(cls.SPEC):
        rw, ren, volume = scene(np.full((16, 16, 16), 1.0, np.float32),
                                opacity=[(0.0, 0.01), (1.0, 0.01)])
        volume.GetProperty().SetAmbient(0.0)
        # The camera looks along +y: a light at -y is behind the viewer, at +y in front.
        behind_viewer = [Light(direction=(0.0, -1.0, 0.0))]
        facing_viewer = [Light(direction=(0.0, 1.0, 0.0))]
        il = Illuminator(volume, ren, method="clear_medium", lights=behind_viewer)

        def brightness(lights: list[Light], g: float) -> float:
            il.set_lights(lights)
            il.set_material(phase_g=g)
            grab(rw)
            return float(grab(rw)[24:40, 24:40, 0].mean())

        iso_back, iso_front = brightness(behind_viewer, 0.0), brightness(facing_viewer, 0.0)
        assert iso_back == pytest.approx(iso_front, abs=1.0)
        forward, backward = brightness(facing_viewer, 0.7), brightness(behind_viewer, 0.7)
        assert forward > 3 * backward
        with pytest.raises(ValueError, match="phase_g must lie"):
            il.set_material(phase_g=1.5)
        il.release()
        rw.Finalize()


def test_point_light_size_and_inverse_square_falloff_reach_techniques():
    rw, ren, volume = scene()
    light = Light(kind="point", position=(11.5, 11.5, 100.0), size=3.0, falloff="inverse_square")
    il = Illuminator(volume, ren, lights=[light, Light(size=2.0)])
    point, sun = il.light_specs()
    assert point.size == pytest.approx(3.0)
    assert point.falloff_distance == pytest.approx(100.0 - 11.5)
    assert sun.size == pytest.approx(np.radians(2.0)) and sun.falloff_distance == 0.0
    il.release()
    rw.Finalize()


# -- progressive and view-dependent techniques -------------------------------------------------
class Recorder(Technique):
    """Counts iterations like a progressive technique and records every ``Changes``."""

    SHADER: ClassVar[str] = ""
    seen: ClassVar[list[Changes]] = []

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        return []

    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        type(self).seen.append(changes)
        if self.SPEC.has("progressive"):
            self.iteration = 1 if changes.reset_accumulation else self.iteration + 1
            self.converged = self.iteration >= 4


PROGRESSIVE = TechniqueSpec(
    name="refining", label="Refining", engine=f"{__name__}:Refining",
    capabilities={"progressive"},
    parameters=(Param("quality", 1.0, "Quality", "q", range=(0, 2), uniform=False,
                      invalidates=Invalidates.ACCUMULATION),),
)
VIEWER = TechniqueSpec(name="viewer", label="Viewer", engine=f"{__name__}:Viewer",
                       capabilities={"view_dependent"})


class Refining(Recorder):
    SPEC = PROGRESSIVE


class Viewer(Recorder):
    SPEC = VIEWER


@pytest.fixture
def recorded() -> Iterator[list[Changes]]:
    Recorder.seen = []
    with register(PROGRESSIVE), register(VIEWER):
        yield Recorder.seen


def test_progressive_technique_refines_until_converged_and_never_restarts_on_camera(recorded):
    rw, ren, volume = scene()
    il = Illuminator(volume, ren, method="refining")
    progress: list[tuple[int, bool]] = []
    il.on_progress = lambda i, done: progress.append((i, done))
    assert il.wants_frame
    assert il.converge(max_frames=20) == 4
    assert not il.wants_frame and progress[-1] == (4, True)
    ren.GetActiveCamera().Azimuth(40)
    il.converge()
    assert il.technique.iteration == 5  # the camera moved: no restart
    il.set_lights([Light(direction=(1.0, 0.0, 0.0))])
    assert il.converge() == 4  # the light moved: restart
    il.set_parameters(quality=0.5)
    assert il.converge(max_frames=2) == 2 and il.wants_frame
    assert il.converge(max_seconds=0.0) == 1
    il.set_lights([Light(direction=(1.0, 0.0, 0.0), intensity=2.0)])
    il.converge()
    assert recorded[-4].light_colors and not recorded[-4].lights
    il.release()
    rw.Finalize()


def test_only_view_dependent_techniques_hear_about_the_camera(recorded):
    rw, ren, volume = scene()
    il = Illuminator(volume, ren, method="viewer")
    grab(rw)
    grab(rw)
    assert [c.view for c in recorded] == [True, False]
    ren.GetActiveCamera().Elevation(30)
    grab(rw)
    assert recorded[-1].view
    il.set_method("refining")
    start = len(recorded)
    il.converge()
    ren.GetActiveCamera().Elevation(-30)
    grab(rw)
    assert len(recorded) > start + 1 and not any(c.view for c in recorded[start:])
    il.release()
    rw.Finalize()


# -- failures ---------------------------------------------------------------------------------
MISSING_TAG = """
//@inject //VTK::NoSuchTag::Dec pre before
float vv_unused_helper() { return 1.0; }
"""
UNUSED_UNIFORM = """
//@inject //VTK::ComputeLighting::Dec pre before
float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }
"""


@pytest.mark.parametrize(
    ("glsl", "parameters", "message"),
    [
        (MISSING_TAG, (), "targets a VTK shader tag this VTK does not have "
                          "(vtkvol<misfit.glsl> at NoSuchTag::Dec)"),
        (UNUSED_UNIFORM, (Param("strength", 1.0, "S", "s", range=(0, 1)),),
         "sets uniforms its shader never reads (vv_misfit_strength)"),
    ],
)
def test_a_technique_that_does_not_fit_the_template_fails_loudly_once(glsl, parameters, message):
    cls = inline("misfit", glsl, parameters=parameters)
    with register(cls.SPEC):
        rw, ren, volume = scene()
        il = Illuminator(volume, ren, method="misfit")
        errors: list[str] = []
        il.on_error = errors.append
        for _ in range(4):
            image = grab(rw)
        assert len(errors) == 1 and message in errors[0] and "local shading" in errors[0]
        assert il.method == "local" and il.failed_method == "misfit"
        assert image.max() > 50
        il.set_method("misfit")  # the user asks again: it is tried again
        assert il.failed_method is None
        il.release()
        rw.Finalize()


def test_render_image_refines_a_progressive_technique_to_the_end(recorded, small_volume):
    from vtkvol.engine.api import render_image

    image = render_image(small_volume, method="refining", size=(64, 64))
    iterations = [c.reset_accumulation for c in recorded]
    assert iterations[0] and iterations.count(True) == 1 and len(iterations) == 4
    assert image.shape == (64, 64, 3) and image.max() > 50


class Exploding(Technique):
    SPEC = TechniqueSpec(name="exploding", label="Exploding", engine=f"{__name__}:Exploding")
    SHADER: ClassVar[str] = ""

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        return []

    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        raise RuntimeError("out of texture memory")


def test_a_technique_that_raises_falls_back_in_the_same_frame():
    with register(Exploding.SPEC):
        rw, ren, volume = scene()
        il = Illuminator(volume, ren, method="exploding")
        errors: list[str] = []
        il.on_error = errors.append
        image = grab(rw)
        assert il.method == "local" and image.max() > 50
        assert errors == ["The 'Exploding' illumination failed (RuntimeError: out of texture "
                          "memory); showing local shading instead."]
        il.release()
        rw.Finalize()


def test_rgb_capability_and_rgb_hook_go_together():
    cls = inline("undeclared_rgb", RED_LIGHT)  # defines the hook without declaring "rgb"
    with register(cls.SPEC):
        rw, ren, volume = scene()
        il = Illuminator(volume, ren, method="undeclared_rgb")
        errors: list[str] = []
        il.on_error = errors.append
        grab(rw)
        assert il.method == "local" and "'rgb' capability" in errors[0]
        il.release()
        rw.Finalize()


def test_multichannel_texture_round_trips_and_checks_shapes():
    from vtkvol.engine.gl import Texture3D

    rw, _ren, _volume = scene()
    rw.Render()
    data = np.random.default_rng(0).random((3, 4, 5, 4)).astype(np.float32)
    tex = Texture3D(rw, (3, 4, 5), data=data, channels=4)
    assert np.array_equal(tex.download(), data) and tex.nbytes == 3 * 4 * 5 * 4 * 4
    tex.upload(2 * data)
    assert np.array_equal(tex.download(), 2 * data)
    with pytest.raises(ValueError, match=r"texture data shape \(3, 4, 5\) != \(3, 4, 5, 4\)"):
        tex.upload(data[..., 0])
    with pytest.raises(ValueError, match="channels must be 1, 2 or 4"):
        Texture3D(rw, (3, 4, 5), channels=3)
    tex.release()
    rw.Finalize()


@pytest.mark.parametrize("profiling", [False, True])
def test_gpu_timing_only_when_profiling_and_never_a_stall(profiling, monkeypatch):
    from vtkvol.engine import gl as gl_module

    created: list[object] = []
    real = gl_module.GpuTimer

    class Counting(real):  # type: ignore[misc, valid-type]
        def __init__(self, *args: Any) -> None:
            super().__init__(*args)
            created.append(self)

    monkeypatch.setattr(gl_module, "GpuTimer", Counting)
    finishes: list[int] = []
    GL = gl_module.gl()
    monkeypatch.setattr(GL, "glFinish", lambda: finishes.append(1))  # production must not wait
    rw, ren, volume = scene()
    il = Illuminator(volume, ren, method="shadow_volume")
    il.profiling = profiling
    grab(rw)
    grab(rw)
    stats = il.technique.stats()
    assert stats["recomputes"] == 1 and stats["recompute_ms"] > 0
    assert finishes == []
    assert len(created) == (1 if profiling else 0)
    if profiling:  # read on a later frame, from the timer query
        assert created[0].result_ms() is not None
        assert stats["recompute_ms"] == pytest.approx(created[0].result_ms())
    il.release()
    rw.Finalize()


def test_bound_textures_lists_the_techniques_not_the_hosts():
    rw, ren, volume = scene()
    il = Illuminator(volume, ren, method="shadow_volume")
    il.set_slice_weights(np.stack([np.linspace(0.2, 1.0, 16)] * 3).astype(np.float32))
    grab(rw)
    assert set(il.bound_textures()) == {"vv_shadow_volume_tex"}
    assert "vv_sliceWeights" in il._textures  # the host's own binding exists, but is not listed
    il.release()
    rw.Finalize()
