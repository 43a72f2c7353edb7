"""Translucency's tint in 2-D mode: the colour volume that sets the chromatic indirect
extinction is classified by the 2-D table, at the same (value, gradient) coordinates as the
host's opacity volume (docs/translucency.md, docs/transfer-functions-2d.md) (GL)."""

from __future__ import annotations

import numpy as np
import pytest
import vtk
from test_tf2d_engine import ramp_1d, sphere_and_slab

from vtkvol.engine import tf2d
from vtkvol.engine.offscreen import make_render_window
from vtkvol.engine.scene import VolumeScene
from vtkvol.io.volume_data import VolumeData
from vtkvol.model import Light, SceneModel, TransferFunction
from vtkvol.model.defaults import scene_for
from vtkvol.model.gradient import gradient_magnitude
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D
from vtkvol.plugins.translucency.technique import colour_volume

pytestmark = pytest.mark.gl
RED = (1.0, 0.15, 0.1)
LO, HI, ALPHA = 99.5, 149.5, 0.6  # knots between integers: exact on uint8 data


class TranslucentView:
    """A VolumeScene with the translucency technique, read through its numpy light path."""

    def __init__(self, data: VolumeData, model: SceneModel) -> None:
        self.model = model
        model.render.jitter = False
        model.illumination.method = "translucency"
        model.lights = [Light(direction=(1.0, -0.2, 0.3))]
        self.rw = make_render_window((48, 48))
        self.renderer = vtk.vtkRenderer()
        self.rw.AddRenderer(self.renderer)
        self.scene = VolumeScene(self.renderer, model, data, request_render=lambda: None)
        self.scene.reset_camera(azimuth=0.0, elevation=0.0)
        self.rw.Render()

    @property
    def il(self):
        il = self.scene.illuminator
        assert il is not None and il.method == "translucency", il.failed_method
        return il

    def light(self) -> np.ndarray:
        self.rw.Render()
        return self.il.technique.light_volumes_cpu({})[0]

    def close(self) -> None:
        self.scene.close()
        self.rw.Finalize()


@pytest.fixture
def views():
    made: list[TranslucentView] = []

    def make(data: VolumeData, model: SceneModel) -> TranslucentView:
        made.append(TranslucentView(data, model))
        return made[-1]

    yield make
    for v in made:
        v.close()


def coloured_ramp(color) -> TransferFunction:
    tf = ramp_1d(LO, HI, ALPHA)
    tf.colors = [(0, *color), (255, *color)]
    return tf


def constant_2d(color) -> TransferFunction2D:
    """The 1-D ramp as one rectangle over every gradient (test_tf2d_engine's construction)."""
    half = (300.0 - LO) / 2
    return TransferFunction2D(primitives=[TFPrimitive(
        value_range=(LO, 300.0), gradient_range=(0.0, 1e6), opacity=ALPHA, color=color,
        soft_edge=(HI - LO) / half)])


def test_2d_red_region_tints_the_indirect_light_as_the_equivalent_1d_tf(views) -> None:
    data = sphere_and_slab()
    one = scene_for(data)
    one.channels[0].tf = coloured_ramp(RED)
    v1 = views(data, one)
    colour_1d, light_1d = colour_volume(v1.il), v1.light()
    opacity = v1.il.opacity_volume()

    two = scene_for(data)
    two.channels[0].tf = coloured_ramp((1.0, 1.0, 1.0))  # the 1-D TF is white: not read
    v2 = views(data, two)
    white_1d = v2.light()
    two.channels[0].tf2d = constant_2d(RED)
    two.channels[0].tf_mode = "2d"
    colour_2d, light_2d = colour_volume(v2.il), v2.light()

    seen = opacity > 0
    assert seen.mean() > 0.2
    np.testing.assert_allclose(v2.il.opacity_volume(), opacity, atol=1e-6)
    np.testing.assert_allclose(colour_2d[seen], colour_1d[seen], atol=1e-6)
    np.testing.assert_allclose(light_2d, light_1d, atol=1e-5)
    # The indirect light is red where the sphere shadows, and was grey with a white TF.
    shadowed = light_2d[..., 3] < 0.5
    assert shadowed.mean() > 0.05
    red, green = light_2d[..., 0][shadowed], light_2d[..., 1][shadowed]
    assert (red - green).mean() > 0.1
    np.testing.assert_allclose(white_1d[..., 0], white_1d[..., 1], atol=1e-6)


def test_high_gradient_colour_change_alters_only_those_voxels_colour(views) -> None:
    data = sphere_and_slab()
    cut = 10.0  # data units per µm: the sphere's flanks lie above, interiors and slab below
    model = scene_for(data)
    model.channels[0].tf2d = TransferFunction2D(primitives=[
        TFPrimitive(value_range=(LO, 300.0), gradient_range=(0.0, cut), opacity=ALPHA),
        TFPrimitive(value_range=(LO, 300.0), gradient_range=(cut, 1e6), opacity=ALPHA)])
    model.channels[0].tf_mode = "2d"
    v = views(data, model)
    before, opacity, light_before = colour_volume(v.il), v.il.opacity_volume().copy(), v.light()

    model.channels[0].tf2d.primitives = [
        model.channels[0].tf2d.primitives[0],
        model.channels[0].tf2d.primitives[1].model_copy(update={"color": RED})]
    after, light_after = colour_volume(v.il), v.light()

    np.testing.assert_array_equal(v.il.opacity_volume(), opacity)  # a colour edit only
    grad = gradient_magnitude(data.array[0], tuple(data.voxel_size_um))
    _, (_, g_top) = v.scene.tf2d_axes(0)
    row = g_top / tf2d.TABLE_SHAPE[0]  # one texel: the bilinear lookup reaches that far
    changed = np.abs(after - before).max(axis=-1) > 0
    seen = opacity > 0
    assert (changed & seen).sum() > 100
    assert grad[changed].min() >= cut - row
    low = grad < cut - row
    assert (low & seen).sum() > 1000
    np.testing.assert_array_equal(after[low], before[low])
    steep = seen & (grad > cut + row)
    np.testing.assert_allclose(after[steep], np.broadcast_to(RED, after[steep].shape),
                               atol=1e-6)
    # and the indirect light, recomputed from the new colour, turns red there
    assert np.abs(light_after[..., :3] - light_before[..., :3]).max() > 0.01
    np.testing.assert_array_equal(light_after[..., 3], light_before[..., 3])
