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
