"""The host's multi-channel sample (resources/shaders/host_multichannel.glsl, issue 11): VTK's
per-component classification and shading with constant component indices, one set of gradient
fetches and one transmittance per light for every component. It must render VTK's own
per-component image (``Illuminator.multichannel_sample = False``) — measured identical, tested
to ≤ 1 8-bit level — with every host wrapper of the loop (slice weights, corrected trilinear
filter, absorber channel mixing), for two to four channels. Speed is in docs/benchmarks.md."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from vtkvol.engine.api import offscreen_view
from vtkvol.engine.offscreen import grab
from vtkvol.io import VolumeData, confocal_phantom
from vtkvol.model.defaults import scene_for

pytestmark = pytest.mark.gl

CALL = "vv_mcClassify(scalar, color, totalAlpha);"
VTK_LOOP_LINE = "color[i] = computeColor(scalar, color[i][3], i);"
#: Stated tolerance between the two paths (8-bit levels): the arithmetic is the same, so only a
#: compiler's different rounding could differ (measured: 0 everywhere, docs/benchmarks.md).
TOLERANCE = 1


@pytest.fixture(scope="module")
def two_channels() -> VolumeData:
    return confocal_phantom((24, 40, 40), voxel_size_um=(0.5, 0.5, 1.0))


def render(data: VolumeData, method: str, *, host_sample: bool,
           edit: Any = None) -> tuple[np.ndarray, str]:
    model = scene_for(data)
    if edit is not None:
        edit(model)
    with offscreen_view(data, model=model, size=(96, 96), method=method) as (rw, scene, _):
        assert scene.illuminator is not None
        scene.illuminator.multichannel_sample = host_sample
        grab(rw)
        image = grab(rw).astype(int)
        return image, scene.illuminator.fragment_source


def compare(data: VolumeData, method: str, edit: Any = None) -> np.ndarray:
    fast, fast_source = render(data, method, host_sample=True, edit=edit)
    vtk_image, vtk_source = render(data, method, host_sample=False, edit=edit)
    # The host's sample is really in the shader, and VTK's loop body is gone from it…
    assert CALL in fast_source and VTK_LOOP_LINE not in fast_source
    assert CALL not in vtk_source and VTK_LOOP_LINE in vtk_source
    # … and the image is VTK's per-component image.
    assert np.abs(fast - vtk_image).max() <= TOLERANCE
    assert fast.max() > 40  # something is drawn (a black image would match trivially)
    return fast


@pytest.mark.parametrize("method", ["local", "shadow_volume"])
def test_two_channels_render_vtks_per_component_image(two_channels, method):
    image = compare(two_channels, method)
    # Both channels are in it: hiding the membranes changes the image.
    def hide_membranes(model):
        model.channels[1].visible = False

    nuclei_only, _ = render(two_channels, method, host_sample=True, edit=hide_membranes)
    assert np.abs(image - nuclei_only).max() > 30


def test_host_wrappers_of_the_loop_keep_the_same_image(two_channels):
    """Slice weights and the corrected filter wrap computeOpacity/computeColor, absorber mixing
    rewrites VTK's compositing loop: with all three the two paths still agree."""
    def everything(model):
        model.render.channel_mixing = "composite"
        model.render.interpolation = "corrected"
        model.slice_weights.z = [(0.0, 0.2), (0.5, 1.0), (1.0, 0.4)]

    compare(two_channels, "local", everything)


def test_three_and_four_channels(two_channels):
    arr = two_channels.array
    for extra in (1, 2):
        stacked = np.concatenate([arr, arr[:extra, :, ::-1, :]], axis=0)
        data = VolumeData.from_array(np.ascontiguousarray(stacked), two_channels.voxel_size_um,
                                     [f"c{i}" for i in range(stacked.shape[0])])
        compare(data, "local")


def test_one_channel_keeps_vtks_single_component_path(two_channels):
    one = VolumeData.from_array(np.ascontiguousarray(two_channels.array[:1]),
                                two_channels.voxel_size_um, ["nuclei"])
    _, source = render(one, "local", host_sample=True)
    assert "vv_mcClassify" not in source


def test_other_blend_modes_keep_vtks_loop(two_channels):
    def mip(model):
        model.render.blend_mode = "mip"

    _, source = render(two_channels, "local", host_sample=True, edit=mip)
    assert CALL not in source


def test_a_vtk_that_spells_the_loop_differently_fails_the_build(two_channels, monkeypatch):
    """The literal VTK-line replacements are part of the build check (engine/shader_builder.py):
    with the loop's lines renamed, as a VTK that spells them differently would have them, the
    replacement cannot apply. Before the check this rendered the per-component path silently
    (no failed method, no error: review 2, §2); now the technique fails, naming the line."""
    from vtkvol.engine import shader_builder

    renamed = {line.replace("totalAlpha", "total_alpha"): text.replace("totalAlpha",
                                                                           "total_alpha")
               for line, text in shader_builder._MULTICHANNEL_LINES.items()}
    monkeypatch.setattr(shader_builder, "_MULTICHANNEL_LINES", renamed)
    model = scene_for(two_channels)
    with offscreen_view(two_channels, model=model, size=(64, 64),
                        method="shadow_volume") as (rw, scene, _):
        il = scene.illuminator
        assert il is not None
        grab(rw)
        grab(rw)
        assert il.failed_method == "shadow_volume"
        assert il.last_error is not None
        assert "spells differently" in il.last_error
        assert "vv_mcClassify(scalar, color, total_alpha);" in il.last_error


def test_verify_names_every_kind_of_miss() -> None:
    """``verify`` reports a missing marker, a missing replaced line, a removed line still
    present and an unread uniform, each with its own sentence."""
    from vtkvol.engine.shader_builder import ShaderBuild, verify

    def build(**kw: Any) -> ShaderBuild:
        base = {"replacements": {}, "expected_markers": frozenset(),
                "expected_lines": frozenset(), "absent_lines": frozenset(),
                "expected_uniforms": frozenset()}
        return ShaderBuild(**{**base, **kw})

    source = "//vv-section a\nuniform float vv_x;\nfloat y = vv_x;\nold line;\n"
    assert verify(build(expected_markers=frozenset({"//vv-section a"})), source) is None
    assert "shader tag" in verify(build(expected_markers=frozenset({"//vv-section b"})), source)
    assert "spells differently (new line;)" in verify(
        build(expected_lines=frozenset({"new line;"})), source)
    assert "spells differently (old line;)" in verify(
        build(absent_lines=frozenset({"old line;"})), source)
    assert "never reads (vv_z)" in verify(build(expected_uniforms=frozenset({"vv_z"})),
                                          source + "uniform float vv_z;\n")
    assert verify(build(expected_uniforms=frozenset({"vv_x"})), source) is None
