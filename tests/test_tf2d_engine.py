"""2-D transfer functions in the engine: VTK's 2-D mode, and the opacity every illumination
technique reads classifying each voxel exactly as VTK's shader does (GL)."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

from vtkvol.engine import tf2d
from vtkvol.engine.offscreen import grab, make_render_window
from vtkvol.engine.scene import VolumeScene
from vtkvol.io.volume_data import VolumeData
from vtkvol.model import Light, SceneModel, TransferFunction
from vtkvol.model.defaults import scene_for
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D

pytestmark = pytest.mark.gl
SIZE = (96, 96)
BACKGROUND = np.array([0.08, 0.08, 0.1]) * 255


class View:
    """An offscreen window with a VolumeScene, parallel camera along +y (x right, z up)."""

    def __init__(self, data: VolumeData, model: SceneModel) -> None:
        self.model = model
        model.camera.parallel_projection = True
        model.render.jitter = False
        self.rw = make_render_window(SIZE)
        self.renderer = vtk.vtkRenderer()
        self.rw.AddRenderer(self.renderer)
        self.scene = VolumeScene(self.renderer, model, data, request_render=lambda: None)
        self.scene.reset_camera(azimuth=0.0, elevation=0.0)

    def image(self) -> np.ndarray:
        return grab(self.rw).astype(np.float64)

    def light_volume(self) -> np.ndarray:
        il = self.scene.illuminator
        self.rw.Render()
        assert il is not None and il.method == "shadow_volume", il.failed_method
        self.rw.MakeCurrent()
        return il.technique.light_texture.download()

    def close(self) -> None:
        self.scene.close()
        self.rw.Finalize()


@pytest.fixture
def views():
    made: list[View] = []

    def make(data: VolumeData, model: SceneModel) -> View:
        made.append(View(data, model))
        return made[-1]

    yield make
    for v in made:
        v.close()


def sphere_and_slab() -> VolumeData:
    """A soft sphere (values up to 200, a wide range of gradients) beside a flat slab of 120
    (gradient 0 inside); anisotropic voxels so the spacing handling matters."""
    n = 36
    z, y, x = np.indices((n, n, n))
    r = np.sqrt((x - 22) ** 2 + (y - 18) ** 2 + ((z - 18) * 1.5) ** 2)
    arr = (200 / (1 + np.exp((r - 9) / 1.5))).astype(np.uint8)
    arr[:, :, :7] = 120
    return VolumeData.from_array(arr[None], (1.0, 1.0, 1.5), ["a"])


def ramp_1d(lo: float, hi: float, alpha: float) -> TransferFunction:
    return TransferFunction(colors=[(0, 1, 1, 1), (255, 1, 1, 1)],
                            opacity=[(0, 0), (lo, 0), (hi, alpha), (255, alpha)],
                            window=(0, 255), window_range=(0, 255))


def shadowed_model(data: VolumeData) -> SceneModel:
    model = scene_for(data)
    model.illumination.method = "shadow_volume"
    model.lights = [Light(direction=(1.0, -0.2, 0.3))]
    # Images are compared level by level with the tolerances measured before exposure and
    # fill existed: the automatic exposure is measured on coarse frames (two classifications
    # a few table samples apart may measure a factor apart), and both scale the table
    # sampling's differences.
    model.render.auto_exposure = False
    model.render.fill = 0.0
    return model


def test_constant_2d_tf_reproduces_the_1d_opacity_light_volume_and_image(views) -> None:
    data = sphere_and_slab()
    lo, hi, alpha = 99.5, 149.5, 0.6  # knots between integers: both are exact on uint8 data

    one = shadowed_model(data)
    one.channels[0].tf = ramp_1d(lo, hi, alpha)
    v1 = views(data, one)
    image_1d = v1.image()
    opacity_1d = v1.scene.illuminator.opacity_volume().copy()
    light_1d = v1.light_volume()

    two = shadowed_model(data)
    two.channels[0].tf = ramp_1d(lo, hi, alpha)
    v2 = views(data, two)
    # The same ramp as one rectangle spanning every gradient: linear soft edge of 50 units
    # on the left, the right edge beyond the data's range.
    half = (300.0 - lo) / 2
    two.channels[0].tf2d = TransferFunction2D(primitives=[TFPrimitive(
        value_range=(lo, 300.0), gradient_range=(0.0, 1e6), opacity=alpha,
        soft_edge=(hi - lo) / half)])
    two.channels[0].tf_mode = "2d"
    assert v2.scene.property.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D
    image_2d = v2.image()
    opacity_2d = v2.scene.illuminator.opacity_volume()
    light_2d = v2.light_volume()

    assert opacity_1d.max() > 0.5 and (opacity_1d == 0).mean() > 0.3
    np.testing.assert_allclose(opacity_2d, opacity_1d, atol=1e-6)
    assert light_1d.min() < 0.5  # the sphere does shadow something
    np.testing.assert_allclose(light_2d, light_1d, atol=1e-5)
    # The GPU samples VTK's 1-D table (1024 samples, ends included) in one image and the
    # 2-D table (texel centres) in the other: a few levels at most, almost nowhere.
    diff = np.abs(image_2d - image_1d)
    assert np.abs(image_1d - BACKGROUND).sum(axis=2).mean() > 10  # something is drawn
    assert diff.mean() < 0.2 and diff.max() <= 12


def plate_and_block(with_block: bool = True) -> VolumeData:
    """A 2-voxel plate of 200 at x = 24…25 (every voxel is a boundary: high gradient) and,
    optionally, a thick block of 200 at x = 3…14 (gradient 0 inside)."""
    arr = np.zeros((24, 24, 32), np.uint8)
    arr[4:20, 4:20, 24:26] = 200
    if with_block:
        arr[4:20, 4:20, 3:15] = 200
    return VolumeData.from_array(arr[None], (1.0, 1.0, 1.0), ["a"])


def low_gradient_only(model: SceneModel, cut: float) -> None:
    """Show values 100…255 only where |∇I| < ``cut`` (data units per µm)."""
    model.channels[0].tf2d = TransferFunction2D(primitives=[TFPrimitive(
        value_range=(100.0, 256.0), gradient_range=(0.0, cut), opacity=0.9)])
    model.channels[0].tf_mode = "2d"


def test_2d_tf_removes_high_gradient_voxels_from_image_and_shadow(views) -> None:
    data = plate_and_block()
    models = []
    for _ in range(2):
        m = scene_for(data)
        m.illumination.method = "shadow_volume"
        m.lights = [Light(direction=(1.0, 0.0, 0.0))]  # from +x: the plate shades the block
        m.channels[0].tf = ramp_1d(99.5, 100.5, 0.9)
        models.append(m)
    v1 = views(data, models[0])
    v2 = views(data, models[1])
    _, (g0, gmax) = v2.scene.tf2d_axes(0)
    assert g0 == 0.0
    assert gmax == pytest.approx(0.25 * 200 / 1.0)  # VTK's axis: ¼ of the range per voxel
    low_gradient_only(models[1], 0.3 * gmax)

    # The opacity volume: the CPU gradient is VTK's, so the cut falls where VTK's does.
    values = data.array[0]
    t = tf2d.normalised_gradient(values, (1.0, 1.0, 1.0), (0.0, 200.0))
    op1, op2 = v1.scene.illuminator.opacity_volume(), v2.scene.illuminator.opacity_volume()
    assert (op1[4:20, 4:20, 24:26] > 0.8).all()  # the plate is there in 1-D …
    assert (op2[t > 0.31] == 0).all() and (op2[:, :, 24:26] == 0).all()  # … not in 2-D
    assert (op2[(t < 0.29) & (values >= 101)] > 0.8).all()  # the block's inside stays

    # The shadow volume: the block's first inner voxels (x = 13) are lit only when the
    # plate (and the block's own boundary layer, x = 14) no longer absorb; then only their
    # own half voxel does: √(1 − 0.9).
    l1, l2 = v1.light_volume(), v2.light_volume()
    assert l1[8:16, 8:16, 13].max() < 0.05
    np.testing.assert_allclose(l2[8:16, 8:16, 13], np.sqrt(0.1), rtol=1e-3)

    # The image: the plate's columns go dark, the block's stay bright.
    plate_only = views(plate_and_block(with_block=False), scene_for(data))
    plate_only.model.channels[0].tf = ramp_1d(99.5, 100.5, 0.9)
    plate_cols = np.abs(plate_only.image() - BACKGROUND).sum(axis=2).max(axis=0) > 30
    assert 0 < plate_cols.sum() < SIZE[0] // 4
    fg1 = np.abs(v1.image() - BACKGROUND).sum(axis=2)
    fg2 = np.abs(v2.image() - BACKGROUND).sum(axis=2)
    assert fg1[:, plate_cols].max() > 30 and fg2[:, plate_cols].max() < 3
    assert fg2[:, :SIZE[0] // 2].max() > 30  # the block is still drawn


def test_two_channels_render_with_vtk_2d_tables(views) -> None:
    """VTK 9.7 does not compile its own 2-D shader for two components; with the engine's
    replacements both channels draw, each in its own colour."""
    arr = np.zeros((2, 20, 20, 20), np.uint8)
    arr[0, 5:15, 5:15, 2:9] = 200
    arr[1, 5:15, 5:15, 11:18] = 200
    data = VolumeData.from_array(arr, (1.0, 1.0, 1.0), ["a", "b"])
    model = scene_for(data)
    model.render.shade = True
    view = views(data, model)
    for c, color in enumerate([(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]):
        model.channels[c].tf2d = TransferFunction2D(primitives=[TFPrimitive(
            value_range=(100.0, 256.0), gradient_range=(0.0, 1e3), color=color, opacity=0.9)])
        model.channels[c].tf_mode = "2d"
    image = view.image()
    left, right = image[:, : SIZE[0] // 2], image[:, SIZE[0] // 2:]
    assert left[..., 0].max() > 100 and left[..., 1].max() < 60
    assert right[..., 1].max() > 100 and right[..., 0].max() < 60
    assert view.scene.illuminator.failed_method is None


def test_switching_back_to_1d_restores_vtk_1d_mode_and_the_image(views) -> None:
    data = sphere_and_slab()
    model = scene_for(data)
    model.channels[0].tf = ramp_1d(99.5, 149.5, 0.6)
    view = views(data, model)
    before = view.image()
    low_gradient_only(model, 1.0)
    changed = view.image()
    assert np.abs(changed - before).max() > 30
    model.channels[0].tf_mode = "1d"
    assert view.scene.property.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_1D
    np.testing.assert_array_equal(view.image(), before)


def test_interaction_step_changes_the_table_alpha_not_the_light(views) -> None:
    data = sphere_and_slab()
    model = shadowed_model(data)
    view = views(data, model)
    low_gradient_only(model, 20.0)
    view.image()
    signature = view.scene.illuminator._opacity_signature()
    table = view.scene._tables[0]
    fine = table._rgba[:, 3].max()
    view.scene.set_interactive(True)  # 4 × the step: more opacity per step, same per unit
    coarse = table._rgba[:, 3].max()
    assert coarse == pytest.approx(1 - (1 - 0.9) ** (4 * np.log(1 - fine) / np.log(0.1)),
                                   rel=1e-4)
    assert coarse > fine
    assert view.scene.illuminator._opacity_signature() == signature


def test_gradient_opacity_is_part_of_the_opacity_volume(views) -> None:
    data = plate_and_block()
    model = scene_for(data)
    model.channels[0].tf = ramp_1d(99.5, 100.5, 0.9)
    view = views(data, model)
    prop = view.scene.property
    go = vtk.vtkPiecewiseFunction()
    go.AddPoint(0.0, 1.0)
    go.AddPoint(10.0, 1.0)
    go.AddPoint(20.0, 0.0)  # |g| in VTK's units (data units × mean spacing)
    prop.SetGradientOpacity(0, go)
    opacity = view.scene.illuminator.opacity_volume()
    t = tf2d.normalised_gradient(data.array[0], (1.0, 1.0, 1.0), (0.0, 200.0))
    g = t * 0.25 * 200
    inside = data.array[0] >= 101
    assert (opacity[inside & (g >= 20)] == 0).all()
    np.testing.assert_allclose(opacity[inside & (g <= 10)], 0.9, rtol=1e-6)


def test_vtk_gradient_matches_the_shader_formula() -> None:
    values = np.zeros((3, 4, 5), np.float32)
    values[:, :, 2] = 10.0
    g = tf2d.vtk_gradient(values, (1.0, 2.0, 3.0))
    # x: (I[x+1] - I[x-1]) / (2·sx/mean), mean spacing 2
    assert g[1, 1, 1, 0] == pytest.approx(10.0 / (2 * 1.0 / 2.0))
    assert g[1, 1, 3, 0] == pytest.approx(-10.0)
    assert g[0, 0, 0, 0] == 0.0  # edge repeated: (I[1] - I[0]) / … = 0 here
    assert g[1, 1, 2, 0] == 0.0
    edge = np.zeros((1, 1, 3), np.float32)
    edge[..., 0] = 4.0  # the border voxel: clamped texture repeats it, one-sided / 2h
    assert tf2d.vtk_gradient(edge, (1.0, 1.0, 1.0))[0, 0, 0, 0] == pytest.approx(-2.0)
    t = tf2d.normalised_gradient(values, (1.0, 2.0, 3.0), (0.0, 10.0))
    assert t.max() == 1.0 and t[1, 1, 2] == 0.0


def test_lookup_is_an_opengl_linear_filter() -> None:
    table = np.array([[0.0, 1.0, 2.0, 3.0]], np.float32)
    s = np.array([0.0, 0.125, 0.25, 0.5, 0.875, 1.0])
    np.testing.assert_allclose(tf2d.lookup(table, s, np.zeros_like(s)),
                               [0.0, 0.0, 0.5, 1.5, 3.0, 3.0])


def test_nan_voxels_and_degenerate_ranges_classify_without_failing() -> None:
    values = np.full((4, 4, 4), 5.0, np.float32)
    values[1, 1, 1] = np.nan
    s = tf2d.normalised_values(values, (0.0, 10.0))
    t = tf2d.normalised_gradient(values, (1.0, 1.0, 1.0), (0.0, 10.0))
    assert np.isfinite(s).all() and np.isfinite(t).all()
    assert s[1, 1, 1] == 0.0 and t[1, 1, 2] == 0.0
    assert (tf2d.normalised_values(values, (3.0, 3.0)) == 0).all()
    assert np.isfinite(tf2d.normalised_gradient(values, (1.0, 1.0, 1.0), (0.0, np.inf))).all()
    table = np.linspace(0, 1, 16, dtype=np.float32).reshape(4, 4)
    assert np.isfinite(tf2d.lookup(table, s, t)).all()


def test_a_1d_channel_beside_a_2d_channel_follows_its_1d_edits(views) -> None:
    arr = np.zeros((2, 16, 16, 16), np.uint8)
    arr[0, 4:12, 4:12, 2:7] = 200
    arr[1, 4:12, 4:12, 9:14] = 200
    data = VolumeData.from_array(arr, (1.0, 1.0, 1.0), ["a", "b"])
    model = scene_for(data)
    for channel in model.channels:
        channel.tf = ramp_1d(99.5, 100.5, 0.5)
    view = views(data, model)
    model.channels[0].tf2d = TransferFunction2D(primitives=[TFPrimitive(
        value_range=(100.0, 256.0), gradient_range=(0.0, 1e3), opacity=0.5)])
    model.channels[0].tf_mode = "2d"
    il = view.scene.illuminator
    before = il.opacity_volume().copy()
    np.testing.assert_allclose(before[8, 8, 10], 0.5, rtol=1e-6)  # channel 1 through its table
    model.channels[1].tf = ramp_1d(99.5, 100.5, 0.2)
    after = il.opacity_volume()
    np.testing.assert_allclose(after[8, 8, 10], 0.2, rtol=1e-6)
    np.testing.assert_array_equal(after[..., :8], before[..., :8])  # channel 0 untouched
    # A channel linked to the 2-D one follows its mode and its regions.
    model.channels[1].tf_linked_to = 0
    linked = il.opacity_volume()
    np.testing.assert_allclose(linked[8, 8, 10], 0.5, rtol=1e-6)


def test_the_editor_axis_zoom_does_not_rebuild_the_tables(views) -> None:
    data = sphere_and_slab()
    model = scene_for(data)
    view = views(data, model)
    low_gradient_only(model, 20.0)
    array = view.scene._tables[0].image.GetPointData().GetArray(tf2d.UNIT_ALPHA_ARRAY)
    stamp = array.GetMTime()
    model.channels[0].tf2d.gradient_max = 5.0  # the editor's axis only
    assert array.GetMTime() == stamp
    model.channels[0].tf2d.primitives[0].opacity = 0.5
    assert array.GetMTime() > stamp


def test_2d_mode_on_dependent_components_falls_back_with_one_message() -> None:
    import vtkvol
    from vtkvol.engine.offscreen import image_from_array

    arr = np.zeros((16, 16, 16, 4), np.uint8)
    arr[4:12, 4:12, 4:12] = 200
    prop = vtk.vtkVolumeProperty()
    prop.SetIndependentComponents(0)
    table = vtk.vtkImageData()
    table.SetDimensions(8, 8, 1)
    table.AllocateScalars(vtk.VTK_FLOAT, 4)
    table.GetPointData().GetScalars().Fill(0.5)
    prop.SetTransferFunction2D(table)
    prop.SetTransferFunctionModeTo2D()
    mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
    mapper.SetInputData(image_from_array(arr))
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    rw = make_render_window((48, 48))
    renderer = vtk.vtkRenderer()
    rw.AddRenderer(renderer)
    renderer.AddVolume(volume)
    renderer.ResetCamera()
    il = vtkvol.illuminate(volume, renderer, method="shadow_volume")
    messages: list[str] = []
    il.on_error = messages.append
    try:
        rw.Render()
        assert il.failed_method == "shadow_volume"
        assert len(messages) == 1
        assert "2-D transfer functions need independent components" in messages[0]
    finally:
        il.release()
        rw.Finalize()
