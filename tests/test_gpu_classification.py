"""Classification on the GPU (``Illuminator.opacity_texture``, host_classify.comp.glsl): the
texture read back equals the numpy reference ``opacity_volume()`` for every classification
input, techniques render the same with either backend, a TF edit uploads no volume, and a
GPU failure falls back to numpy with one warning (docs/architecture.md)."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import vtk

from vtkvol.engine import classify
from vtkvol.engine.gl import GLUnavailableError
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model.scene import Light

pytestmark = pytest.mark.gl

#: Integer data read exact table entries (measured difference ≤ 6e-7: float32 rounding of the
#: combination); float data a 16384-entry linear table (at most |Δslope|·h/4 from numpy at a
#: node; measured 1.6e-5 here, gradient-opacity tables 1.2e-5); 2-D lookups, crop, clipping
#: and weights ≤ 6e-8.
INTEGER_ATOL = 1e-6
FLOAT_ATOL = 5e-5


def blob(n: int = 24, dtype=np.uint8, top: float = 200.0, seed: int = 0) -> np.ndarray:
    """A smooth sphere plus noise (every value, a range of gradients), ``[z, y, x]``."""
    rng = np.random.default_rng(seed)
    z, y, x = np.indices((n, n + 2, n + 4))
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2)
    arr = top / (1 + np.exp((r - n / 4) / 2.0)) + rng.random(r.shape) * top * 0.2
    return arr.astype(dtype)


def compare(il: Illuminator, rw: vtk.vtkRenderWindow) -> tuple[np.ndarray, np.ndarray]:
    """(GPU texture read back, numpy reference) after a frame."""
    rw.Render()
    rw.MakeCurrent()
    got = il.opacity_texture().download()
    assert il.classification_stats()["backend"] == "gpu", il.classification_stats()
    ref = il.opacity_volume()
    assert ref.max() > 0.1 and (ref < ref.max()).any()  # a real, non-constant classification
    return got, ref


def scene(arr: np.ndarray, **kw):
    top = float(np.max(arr))
    kw.setdefault("opacity", [(0, 0), (0.3 * top, 0.15), (0.55 * top, 0.8), (top, 0.35)])
    rw, ren, volume = simple_volume_scene(arr, size=(32, 32), **kw)
    return rw, ren, volume, Illuminator(volume, ren, method="local")


@pytest.fixture
def made():
    windows: list[tuple[vtk.vtkRenderWindow, Illuminator]] = []
    yield windows
    for rw, il in windows:
        il.release()
        rw.Finalize()


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.float32])
def test_one_component_equals_numpy_for_every_data_type(made, dtype):
    arr = blob(dtype=dtype, top=200.0 if dtype != np.float32 else 3.7)
    rw, _ren, _volume, il = scene(arr, spacing=(1.0, 0.8, 1.6))
    made.append((rw, il))
    got, ref = compare(il, rw)
    atol = FLOAT_ATOL if dtype == np.float32 else INTEGER_ATOL
    np.testing.assert_allclose(got, ref, atol=atol)


def test_three_components_with_weights_and_unit_distances_equal_numpy(made):
    arr = np.stack([blob(seed=s) for s in range(3)], axis=-1)
    arr[..., 1] = arr[..., 1][::-1]  # the components differ
    rw, _ren, volume, il = scene(arr[..., 0])
    made.append((rw, il))
    from vtkvol.engine.offscreen import image_from_array

    volume.GetMapper().SetInputData(image_from_array(arr))
    prop = volume.GetProperty()
    prop.IndependentComponentsOn()
    for c, (weight, unit) in enumerate([(1.0, 1.0), (0.6, 2.5), (0.0, 1.0)]):
        otf = vtk.vtkPiecewiseFunction()
        otf.AddPoint(0, 0.0)
        otf.AddPoint(60 + 40 * c, 0.9)
        otf.AddPoint(255, 0.5)
        prop.SetScalarOpacity(c, otf)
        ctf = vtk.vtkColorTransferFunction()
        ctf.AddRGBPoint(0, 1, 1, 1)
        prop.SetColor(c, ctf)
        prop.SetComponentWeight(c, weight)
        prop.SetScalarOpacityUnitDistance(c, unit)
    got, ref = compare(il, rw)
    np.testing.assert_allclose(got, ref, atol=INTEGER_ATOL)
    # the weight-0 component adds nothing; the 2.5 µm unit distance matters
    prop.SetComponentWeight(2, 1.0)
    assert not np.allclose(il.opacity_volume(), ref, atol=1e-3)
    rw.Render()
    rw.MakeCurrent()
    np.testing.assert_allclose(il.opacity_texture().download(), il.opacity_volume(),
                               atol=INTEGER_ATOL)


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_gradient_opacity_equals_numpy(made, dtype):
    arr = blob(dtype=dtype, top=1000.0 if dtype == np.uint16 else 1.0)
    rw, _ren, volume, il = scene(arr, spacing=(0.7, 1.0, 2.0))
    made.append((rw, il))
    top = float(arr.max()) - float(arr.min())
    gof = vtk.vtkPiecewiseFunction()
    gof.AddPoint(0.0, 0.05)
    gof.AddPoint(0.02 * top, 1.0)
    gof.AddPoint(0.2 * top, 0.3)
    volume.GetProperty().SetGradientOpacity(gof)
    got, ref = compare(il, rw)
    np.testing.assert_allclose(got, ref, atol=FLOAT_ATOL)


def test_crop_regions_clipping_plane_and_slice_weights_equal_numpy(made):
    arr = blob(n=28)
    rw, _ren, volume, il = scene(arr)
    made.append((rw, il))
    mapper = volume.GetMapper()
    mapper.CroppingOn()
    mapper.SetCroppingRegionPlanes(6.0, 19.5, 5.0, 22.0, 8.2, 20.0)
    mapper.SetCroppingRegionFlags(0b101001110010110110011010101)  # odd regions, not a box
    plane = vtk.vtkPlane()
    plane.SetOrigin(14.3, 10.1, 9.7)
    plane.SetNormal(0.3, -0.5, 0.81)
    planes = vtk.vtkPlaneCollection()
    planes.AddItem(plane)
    mapper.SetClippingPlanes(planes)
    volume.SetPosition(3.0, -2.0, 1.0)  # clipping is in world space
    il.set_slice_weights(np.stack([np.linspace(0.2, 1.0, 9), np.linspace(1.0, 0.5, 9),
                                   np.linspace(0.0, 1.0, 9) ** 0.5]))
    got, ref = compare(il, rw)
    assert (ref == 0).mean() > 0.3  # the crop and the plane cut a lot
    np.testing.assert_allclose(got, ref, atol=INTEGER_ATOL)


def test_2d_transfer_function_with_painted_layer_equals_numpy():
    from test_tf2d_engine import View
    from test_tf2d_paint import blob as paint_blob
    from test_tf2d_paint import interiors_scene

    from vtkvol.model.tf_paint import TFPaintLayer

    data, model = interiors_scene()
    view = View(data, model)
    try:
        (v0, v1), (g0, g1) = view.scene.tf2d_axes(0)
        layer = TFPaintLayer.blank((v0, v1), (g0, g1))
        centre = tuple(float(c) for c in layer.pixel_coords(70.0, 29.0))
        model.channels[0].tf2d.paint = paint_blob(layer, centre, 14.0, opacity=0.9)
        il = view.scene.illuminator
        got, ref = compare(il, view.rw)
        np.testing.assert_allclose(got, ref, atol=INTEGER_ATOL)
    finally:
        view.close()


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
def test_a_constant_volume_classifies_without_nan(made, dtype):
    arr = np.full((12, 14, 16), 7, dtype)
    rw, _ren, volume, il = scene(arr, opacity=[(0, 0.1), (10, 0.9)])
    made.append((rw, il))
    gof = vtk.vtkPiecewiseFunction()
    gof.AddPoint(0.0, 0.5)
    gof.AddPoint(1.0, 1.0)
    volume.GetProperty().SetGradientOpacity(gof)
    rw.Render()
    rw.MakeCurrent()
    got = il.opacity_texture().download()
    ref = il.opacity_volume()
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, ref, atol=INTEGER_ATOL)
    assert ref[0, 0, 0] == pytest.approx(0.5 * (0.1 + 0.8 * 0.7), abs=1e-6)


def test_a_tf_edit_classifies_on_the_gpu_and_uploads_no_volume(made):
    arr = blob()
    rw, _ren, volume, il = scene(arr)
    made.append((rw, il))
    il.set_method("shadow_volume")
    rw.Render()
    before = il.classification_stats()
    assert before["backend"] == "gpu" and before["scalar_uploads"] == 1
    assert before["scalar_bytes"] == arr.nbytes  # uint8 stays one byte a voxel
    otf = volume.GetProperty().GetScalarOpacity()
    otf.AddPoint(120.0, 0.05)
    rw.Render()
    after = il.classification_stats()
    assert after["gpu_classifications"] == before["gpu_classifications"] + 1
    assert after["scalar_uploads"] == 1 and after["opacity_uploads"] == 0
    assert after["cpu_classifications"] == 0
    rw.MakeCurrent()
    np.testing.assert_allclose(il.opacity_texture().download(), il.opacity_volume(),
                               atol=INTEGER_ATOL)
    # new data: uploaded once, classified anew
    volume.GetMapper().GetInput().GetPointData().GetScalars().Modified()
    rw.Render()
    assert il.classification_stats()["scalar_uploads"] == 2


@pytest.mark.parametrize(("method", "params"), [
    ("shadow_volume", {"resolution": "full"}),
    ("shadow_volume", {"resolution": "half"}),
    ("cone_traced", {}),
])
def test_technique_images_agree_with_cpu_classification(made, method, params):
    arr = blob(n=32)
    rw, _ren, _volume, il = scene(arr)
    made.append((rw, il))
    il.set_method(method, params)
    il.set_lights([Light(direction=(0.6, -0.3, 0.75))])
    il.classification = "cpu"
    cpu = grab(rw).astype(np.int16)
    assert il.classification_stats()["backend"] == "cpu"
    il.classification = "gpu"
    il.invalidate()
    gpu = grab(rw).astype(np.int16)
    assert il.classification_stats()["backend"] == "gpu"
    assert il.failed_method is None
    assert np.abs(cpu - 13).max() > 40  # something is drawn
    assert np.abs(gpu - cpu).max() <= 1


def test_a_compile_failure_falls_back_to_numpy_with_one_warning(made, monkeypatch, caplog):
    def broken(self, defines):
        raise GLUnavailableError("compute shader 'host classification' failed to build:\nx")

    monkeypatch.setattr(classify.GpuClassifier, "program", broken)
    arr = blob()
    rw, _ren, volume, il = scene(arr)
    made.append((rw, il))
    il.set_method("shadow_volume")
    with caplog.at_level(logging.WARNING, logger="vtkvol.engine.illuminator"):
        rw.Render()
        volume.GetProperty().GetScalarOpacity().AddPoint(100.0, 0.3)
        rw.Render()
    warnings = [r.getMessage() for r in caplog.records if "classif" in r.getMessage()]
    assert warnings == ["vtkvol: GPU classification unavailable, classifying with numpy "
                        "(compute shader 'host classification' failed to build:)"]
    stats = il.classification_stats()
    assert stats["backend"] == "cpu" and stats["cpu_classifications"] == 2
    assert "failed to build" in stats["reason"]
    assert il.failed_method is None  # the technique keeps working
    rw.MakeCurrent()
    np.testing.assert_array_equal(il.opacity_texture().download(), il.opacity_volume())


def test_dependent_components_stay_on_numpy_and_gpu_forced_says_why(made):
    from vtkvol.engine.offscreen import image_from_array

    arr = np.stack([blob(seed=s) for s in range(4)], axis=-1)
    rw, _ren, volume, il = scene(arr[..., 0])
    made.append((rw, il))
    volume.GetMapper().SetInputData(image_from_array(arr))
    volume.GetProperty().IndependentComponentsOff()
    rw.Render()
    rw.MakeCurrent()
    np.testing.assert_array_equal(il.opacity_texture().download(), il.opacity_volume())
    assert "dependent components" in il.classification_stats()["reason"]
    il.classification = "gpu"
    with pytest.raises(GLUnavailableError, match="dependent components"):
        il.opacity_texture()
    with pytest.raises(ValueError, match="'auto', 'gpu' or 'cpu'"):
        il.classification = "fast"


def test_slabs_and_chunked_precompute_classify_the_same(made, monkeypatch):
    arr = blob(n=20)
    rw, _ren, volume, il = scene(arr, spacing=(1.0, 1.0, 1.3))
    made.append((rw, il))
    gof = vtk.vtkPiecewiseFunction()  # the gradient reads across slab boundaries
    gof.AddPoint(0.0, 0.2)
    gof.AddPoint(30.0, 1.0)
    volume.GetProperty().SetGradientOpacity(gof)
    monkeypatch.setattr(classify, "SLAB_VOXELS", 3 * 22 * 24)  # three z slices per slab
    il.set_method("shadow_volume")
    rw.Render()
    volume.GetProperty().GetScalarOpacity().AddPoint(90.0, 0.6)
    chunks: list[float] = []
    steps = il.opacity_texture_steps

    def counted(quantity: str = "alpha"):
        inner = steps(quantity)
        while True:
            try:
                chunks.append(next(inner))
            except StopIteration as stop:
                return stop.value
            yield chunks[-1]

    monkeypatch.setattr(il, "opacity_texture_steps", counted)
    assert il.precompute(lambda f: True)
    assert il.failed_method is None
    assert chunks == pytest.approx([3 * k / 20 for k in range(1, 7)] + [1.0])  # one a slab
    rw.MakeCurrent()
    np.testing.assert_allclose(il.opacity_texture("optical_depth").download(),
                               classify.optical_depth(il.opacity_volume()), atol=1e-5)
    assert il.classification_stats()["backend"] == "gpu"


def test_optical_depth_output_equals_the_converted_numpy_opacity(made):
    arr = blob()
    rw, _ren, _volume, il = scene(arr, opacity=[(0, 0), (100, 1.0), (255, 1.0)])  # α = 1 clamps
    made.append((rw, il))
    rw.Render()
    rw.MakeCurrent()
    alpha = il.opacity_volume()
    assert (alpha == 1.0).any()
    depth = il.opacity_texture("optical_depth").download()
    expected = classify.optical_depth(alpha)
    assert np.isfinite(depth).all() and depth.max() == pytest.approx(-np.log(1e-6), rel=1e-3)
    np.testing.assert_allclose(depth, expected, rtol=1e-5, atol=1e-6)
    il.classification = "cpu"
    np.testing.assert_allclose(il.opacity_texture("optical_depth").download(), expected,
                               rtol=1e-6)
    with pytest.raises(ValueError, match="quantity must be one of"):
        il.opacity_texture("sigma")


def test_two_channels_one_in_2d_mode_equal_numpy():
    from test_tf2d_engine import View, ramp_1d

    from vtkvol.io.volume_data import VolumeData
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D

    arr = np.stack([blob(n=20, seed=1), blob(n=20, seed=2)[::-1]])
    data = VolumeData.from_array(arr, (1.0, 1.0, 1.5), ["a", "b"])
    model = scene_for(data)
    model.illumination.method = "shadow_volume"
    for channel, (lo, hi) in zip(model.channels, [(40.5, 140.5), (60.5, 90.5)], strict=True):
        channel.tf = ramp_1d(lo, hi, 0.6)
    view = View(data, model)
    try:
        model.channels[0].tf2d = TransferFunction2D(primitives=[TFPrimitive(
            value_range=(80.0, 256.0), gradient_range=(2.0, 40.0), opacity=0.7)])
        model.channels[0].tf_mode = "2d"
        view.scene.property.SetComponentWeight(1, 0.5)
        got, ref = compare(view.scene.illuminator, view.rw)
        np.testing.assert_allclose(got, ref, atol=INTEGER_ATOL)
    finally:
        view.close()


def test_local_shading_holds_none_of_the_classifications_gl_objects(made, monkeypatch):
    from tests_support_gl import GlObjects

    from vtkvol.engine import gl as vgl

    objects = GlObjects(monkeypatch)
    buffers: list[vgl.StorageBuffer] = []
    buffer_init = vgl.StorageBuffer.__init__

    def record_buffer(obj, *args, **kwargs):
        buffer_init(obj, *args, **kwargs)
        buffers.append(obj)

    monkeypatch.setattr(vgl.StorageBuffer, "__init__", record_buffer)
    rw, _ren, _volume, il = scene(blob())
    made.append((rw, il))
    il.set_method("shadow_volume")
    rw.Render()
    assert il.classification_stats()["backend"] == "gpu" and len(buffers) == 3
    handles = [b.handle for b in buffers]
    il.set_method("local")
    rw.Render()
    assert all(b.handle is None for b in buffers)  # scalars, tables, output slab
    assert objects.held() == []  # the opacity texture and the programs too
    GL = vgl.gl(rw)
    rw.MakeCurrent()
    assert not any(GL.glIsBuffer(h) for h in handles)
