"""One mechanism per concept (issue 21): the GPU-or-numpy choice is the ``backend`` parameter
read through ``ComputePath`` in every technique with both paths; compute-shader uniforms are set
through one checked setter; image units are detached after dispatches; statistics are typed."""

from __future__ import annotations

import ast
import ctypes
import pathlib
import re

import numpy as np
import pytest

from vtkvol.model.params import Invalidates, backend_param
from vtkvol.model.techniques import technique_specs

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: Techniques with a GPU and a numpy path.
BOTH_PATHS = ("cone_traced", "convection_diffusion", "hybrid_diffusion", "shadow_volume",
              "translucency")


@pytest.mark.parametrize("name", BOTH_PATHS)
def test_every_technique_with_two_paths_declares_the_one_backend_parameter(name: str) -> None:
    declared = technique_specs()[name].parameter("backend")
    shared = backend_param(Invalidates(0))
    assert (declared.choices, declared.choice_labels, declared.default, declared.doc) == (
        shared.choices, shared.choice_labels, shared.default, shared.doc)


@pytest.mark.parametrize("name", BOTH_PATHS)
def test_no_plugin_hand_rolls_the_gpu_choice(name: str) -> None:
    """No class constant, no own 'failed' flag: the choice is ComputePath's."""
    source = (ROOT / "plugins" / name / "technique.py").read_text(encoding="utf-8")
    names = {n.attr for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Attribute)}
    names |= {n.id for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Name)}
    assert not names & {"BACKEND", "_gpu_failed", "compute_supported", "_disable_gpu"}
    assert any(base in source for base in ("ComputePath", "GridScattering", "LightGridTechnique"))


def test_technique_stats_are_typed_and_read_as_a_mapping() -> None:
    from vtkvol.engine.technique import TechniqueStats

    stats = TechniqueStats(recomputes=2, recompute_ms=1.5, backend="gpu", texture_bytes=64,
                           extra={"bakes": 1})
    assert stats.recomputes == 2 and stats["bakes"] == 1
    assert dict(stats) == {"recomputes": 2, "recompute_ms": 1.5, "backend": "gpu",
                           "texture_bytes": 64, "bakes": 1}
    assert "iterations" not in stats and stats.get("iterations") is None
    assert dict(TechniqueStats()) == {}  # local shading: nothing to count
    with pytest.raises(KeyError):
        stats["residual"]


def test_compute_uniform_setters_live_in_one_place() -> None:
    """Outside engine/gl.py no code looks compute uniforms up itself or keeps a location cache
    (the four policies of review 2, §5)."""
    offenders = []
    for folder in ("vtkvol", "plugins"):
        for path in (ROOT / folder).rglob("*.py"):
            if path.name == "gl.py":
                continue
            text = path.read_text(encoding="utf-8")
            for needle in ("glGetUniformLocation", "def unbind_images", "def _unbind_images"):
                if needle in text:
                    offenders.append(f"{path.relative_to(ROOT)}: {needle}")
            # a location cache: an attribute or a name ``_locations`` (not, say, importlib's
            # ``submodule_search_locations``)
            if re.search(r"(?<![A-Za-z0-9])_locations\b", text):
                offenders.append(f"{path.relative_to(ROOT)}: _locations")
    assert offenders == []


@pytest.mark.gl
def test_compute_program_set_uniform_names_program_and_uniform() -> None:
    from vtkvol.engine.gl import ComputeProgram, GLUnavailableError, compute_supported, gl
    from vtkvol.engine.offscreen import make_render_window

    rw = make_render_window((16, 16))
    try:
        rw.Render()
        rw.MakeCurrent()
        if not compute_supported(rw):
            pytest.skip("no compute shaders in this context")
        source = ("#version 430\nlayout(local_size_x = 1) in;\n"
                  "layout(std430, binding = 0) buffer Out { float v[]; };\n"
                  "uniform float vv_scale;\nuniform int vv_sizes[3];\n"
                  "void main() { v[0] = vv_scale * float(vv_sizes[2]); }\n")
        prog = ComputeProgram(rw, source, "probe")
        prog.use()
        prog.set_uniform("vv_scale", 2.5, kind="f")
        prog.set_uniform_array("vv_sizes", [1, 2, 3], kind="i")
        handle = int(prog.prog.GetHandle())
        GL = gl(rw)
        out = np.zeros(1, np.float32)
        GL.glGetUniformfv(handle, prog.location("vv_scale"), out)
        assert out[0] == 2.5
        ints = np.zeros(1, np.int32)
        GL.glGetUniformiv(handle, GL.glGetUniformLocation(handle, "vv_sizes[2]"), ints)
        assert ints[0] == 3
        with pytest.raises(GLUnavailableError,
                           match="compute shader 'probe' has no uniform 'vv_missing'"):
            prog.set_uniform("vv_missing", 1)
        prog.set_uniform("vv_missing", 1, optional=True)  # a variant that does not read it
        prog.done()
        prog.release()
    finally:
        rw.Finalize()


@pytest.mark.gl
def test_cone_traced_gpu_filter_and_bake_leave_no_image_bound() -> None:
    """The cone tracer's compute passes detach their image units (they never did: a texture
    left bound there stays referenced and writable by the next dispatch)."""
    from vtkvol.engine.gl import compute_supported, gl
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import simple_volume_scene
    from vtkvol.reference.phantoms import phantom_sphere_over_slab

    rw, ren, volume = simple_volume_scene(phantom_sphere_over_slab(20), size=(32, 32))
    il = Illuminator(volume, ren, method="cone_traced")
    try:
        rw.Render()
        if not compute_supported(rw):
            pytest.skip("no compute shaders in this context")
        assert il.technique is not None
        stats = il.technique.stats()
        assert stats.backend == "gpu" and stats["bake_backend"] == "gpu"
        rw.MakeCurrent()
        GL = gl(rw)
        # PyOpenGL's wrapper has no output size for this query: the raw entry point.
        from OpenGL.raw.GL.VERSION.GL_3_0 import glGetIntegeri_v

        bound = []
        for unit in range(2):
            name = ctypes.c_int(-1)
            glGetIntegeri_v(GL.GL_IMAGE_BINDING_NAME, unit, ctypes.byref(name))
            bound.append(name.value)
        assert bound == [0, 0]
    finally:
        il.release()
        rw.Finalize()
