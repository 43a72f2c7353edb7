"""What VTK and PyVista users bring to ``vtkvol.illuminate``: cropping modes, clipping planes,
cell data, the smart mapper, the renderer's own lights (GL)."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene

pytestmark = pytest.mark.gl


def test_every_cropping_mode_shapes_the_opacity_techniques_read():
    rw, ren, volume = simple_volume_scene(np.ones((8, 8, 8), np.float32), size=(32, 32))
    mapper = volume.GetMapper()
    il = Illuminator(volume, ren)
    mapper.CroppingOn()
    mapper.SetCroppingRegionPlanes(1.5, 5.5, 1.5, 5.5, 1.5, 5.5)
    mapper.SetCroppingRegionFlagsToSubVolume()
    sub = il.opacity_volume()
    assert sub[2:6, 2:6, 2:6].min() > 0 and sub.sum() == pytest.approx(64 * sub.max())
    mapper.SetCroppingRegionFlags(0x7FFFFFF & ~0x2000)  # every region but the centre
    inverted = il.opacity_volume()
    assert inverted[2:6, 2:6, 2:6].max() == 0 and inverted[0, 0, 0] > 0
    assert np.count_nonzero(inverted) == 8**3 - 64
    mapper.SetCroppingRegionFlagsToCross()  # the centre and its six face neighbours
    cross = il.opacity_volume()
    assert cross[3, 3, 0] > 0 and cross[3, 0, 0] == 0 and cross[0, 0, 0] == 0
    il.release()
    rw.Finalize()


def test_clipping_planes_remove_what_they_clip_from_the_shadows():
    rw, ren, volume = simple_volume_scene(np.ones((8, 8, 8), np.float32), size=(32, 32))
    il = Illuminator(volume, ren)
    full = il.opacity_volume().copy()
    plane = vtk.vtkPlane()
    plane.SetOrigin(3.5, 0.0, 0.0)
    plane.SetNormal(1.0, 0.0, 0.0)  # VTK keeps x ≥ 3.5
    volume.GetMapper().AddClippingPlane(plane)
    clipped = il.opacity_volume()
    assert clipped[:, :, :4].max() == 0 and np.array_equal(clipped[:, :, 4:], full[:, :, 4:])
    plane.SetNormal(-1.0, 0.0, 0.0)  # moving the plane is seen too
    assert il.opacity_volume()[:, :, 4:].max() == 0
    il.release()
    rw.Finalize()


def image_with(cell_data: bool) -> vtk.vtkImageData:
    from vtk.util.numpy_support import numpy_to_vtk

    img = vtk.vtkImageData()
    img.SetDimensions(9, 9, 9)
    values = np.ones(8**3 if cell_data else 9**3, np.float32)
    array = numpy_to_vtk(values, deep=True)
    array.SetName("density")
    (img.GetCellData() if cell_data else img.GetPointData()).SetScalars(array)
    return img


def plain_scene(mapper: vtk.vtkVolumeMapper, image: vtk.vtkImageData):
    from vtkvol.engine.offscreen import make_render_window

    mapper.SetInputData(image)
    prop = vtk.vtkVolumeProperty()
    otf = vtk.vtkPiecewiseFunction()
    otf.AddPoint(0.0, 0.0)
    otf.AddPoint(1.0, 0.8)
    prop.SetScalarOpacity(otf)
    ctf = vtk.vtkColorTransferFunction()
    ctf.AddRGBPoint(0.0, 1.0, 1.0, 1.0)
    ctf.AddRGBPoint(1.0, 1.0, 1.0, 1.0)
    prop.SetColor(ctf)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    rw = make_render_window((48, 48))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    ren.AddVolume(volume)
    ren.ResetCamera()
    return rw, ren, volume


def test_cell_data_is_refused_at_the_call_with_what_to_do():
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(True))
    with pytest.raises(ValueError, match=r"cell data.*cell_data_to_point_data"):
        vtkvol.illuminate(volume, ren)
    rw.Finalize()


def test_cell_data_arriving_later_is_reported_once_and_the_view_keeps_rendering():
    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    il = Illuminator(volume, ren, method="shadow_volume")
    errors: list[str] = []
    il.on_error = errors.append
    grab(rw)
    volume.GetMapper().SetInputData(image_with(True))
    for _ in range(3):
        image = grab(rw)
    assert len(errors) == 1 and "cell data" in errors[0]
    assert image.max() > 30  # VTK's own rendering of the cell data, without our replacements
    assert il._replacements.installed == {}
    il.release()
    rw.Finalize()


def test_smart_mapper_is_rendered_through_a_gpu_mapper_and_given_back():
    import vtkvol

    smart = vtk.vtkSmartVolumeMapper()
    smart.SetBlendModeToComposite()
    rw, ren, volume = plain_scene(smart, image_with(False))
    il = vtkvol.illuminate(volume, ren, method="shadow_volume")
    assert isinstance(volume.GetMapper(), vtk.vtkOpenGLGPUVolumeRayCastMapper)
    assert volume.GetMapper().GetInput() is smart.GetInput()
    image = grab(rw)
    assert image.max() > 30 and il.technique.stats()["recomputes"] == 1
    il.release()
    assert volume.GetMapper() is smart
    rw.Finalize()


def test_other_mappers_are_refused_with_what_to_do():
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkFixedPointVolumeRayCastMapper(), image_with(False))
    with pytest.raises(TypeError, match=r'add_volume\(\.\.\., mapper="gpu"\)'):
        vtkvol.illuminate(volume, ren)
    rw.Finalize()


def test_illuminate_follows_the_renderers_own_lights_when_asked():
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    light = vtk.vtkLight()
    light.SetLightTypeToSceneLight()
    light.SetPosition(100.0, 4.0, 4.0)
    light.SetFocalPoint(4.0, 4.0, 4.0)
    light.SetDiffuseColor(1.0, 0.5, 0.25)
    light.SetIntensity(0.8)
    ren.AddLight(light)
    il = vtkvol.illuminate(volume, ren, lights="renderer")
    grab(rw)
    (spec,) = il.light_specs()
    assert spec.kind == "directional"
    assert spec.vector == pytest.approx((1.0, 0.0, 0.0))
    assert spec.color == pytest.approx((0.8, 0.4, 0.2))
    light.SetPosition(4.0, 4.0, 100.0)  # the renderer's light moved: so does ours
    grab(rw)
    assert il.light_specs()[0].vector == pytest.approx((0.0, 0.0, 1.0))
    il.set_lights([vtkvol.Light(direction=(0.0, 1.0, 0.0))])  # explicit lights win from now on
    grab(rw)
    assert il.light_specs()[0].vector == pytest.approx((0.0, 1.0, 0.0))
    il.release()
    rw.Finalize()


def test_by_default_the_renderers_lights_are_taken_once_and_stay_in_the_world():
    """A library user's default: VTK's headlight at the first frame becomes a world-fixed key
    light above and beside the view; a camera move then moves no light and recomputes no
    shadow volume (following the headlight recomputed it at every move)."""
    import vtkvol
    from vtkvol.engine.illuminator import key_light_direction

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    il = vtkvol.illuminate(volume, ren, method="shadow_volume")
    camera = ren.GetActiveCamera()
    expected = key_light_direction(camera)
    grab(rw)
    (spec,) = il.light_specs()
    assert spec.kind == "directional"
    assert spec.vector == pytest.approx(expected)
    to_camera = np.subtract(camera.GetPosition(), camera.GetFocalPoint())
    to_camera /= np.linalg.norm(to_camera)
    angle = np.degrees(np.arccos(np.dot(spec.vector, to_camera)))
    assert angle == pytest.approx(np.degrees(np.arccos(np.cos(np.radians(50))
                                                        * np.cos(np.radians(10)))), abs=0.01)
    prepared: list = []
    technique = il.technique
    original = technique.prepare
    technique.prepare = lambda changes, values: (prepared.append(changes), original(changes,
                                                                                    values))[1]
    for _ in range(3):
        camera.Azimuth(40.0)
        ren.ResetCameraClippingRange()
        grab(rw)
    assert il.light_specs()[0].vector == pytest.approx(expected)  # fixed in the world
    assert [c for c in prepared if c.lights] == []  # no recomputation of the light
    il.release()
    rw.Finalize()


def test_following_the_headlight_recomputes_at_every_camera_move():
    """The opt-in ``lights="renderer"``: the headlight turns with the camera, and so does
    the shadow volume's light (what the default avoids)."""
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    il = vtkvol.illuminate(volume, ren, method="shadow_volume", lights="renderer")
    grab(rw)
    first = il.light_specs()[0].vector
    prepared: list = []
    technique = il.technique
    original = technique.prepare
    technique.prepare = lambda changes, values: (prepared.append(changes), original(changes,
                                                                                    values))[1]
    ren.GetActiveCamera().Azimuth(40.0)
    grab(rw)
    assert il.light_specs()[0].vector != pytest.approx(first)
    assert [c.lights for c in prepared] == [True]
    il.release()
    rw.Finalize()


def test_a_second_illuminate_can_switch_to_following_the_renderers_lights():
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    il = vtkvol.illuminate(volume, ren, method="shadow_volume")
    grab(rw)
    fixed = il.light_specs()[0].vector
    assert vtkvol.illuminate(volume, ren, method="shadow_volume", lights="renderer") is il
    grab(rw)
    to_camera = np.subtract(ren.GetActiveCamera().GetPosition(),
                            ren.GetActiveCamera().GetFocalPoint())
    assert il.light_specs()[0].vector == pytest.approx(tuple(to_camera
                                                             / np.linalg.norm(to_camera)))
    assert il.light_specs()[0].vector != pytest.approx(fixed)
    il.release()
    rw.Finalize()


def test_a_light_kit_is_kept_as_it_was_at_the_first_frame():
    """Several renderer lights (PyVista's light kit): all taken, none replaced, then fixed."""
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    kit = vtk.vtkLightKit()
    kit.AddLightsToRenderer(ren)
    il = vtkvol.illuminate(volume, ren, method="shadow_volume")
    grab(rw)
    taken = [s.vector for s in il.light_specs()]
    switched_on = [light for light in ren.GetLights() if light.GetSwitch()]
    assert len(taken) == min(len(switched_on), 4)
    for spec_vector, light in zip(taken, switched_on, strict=False):
        d = np.subtract(light.GetTransformedPosition(), light.GetTransformedFocalPoint())
        assert spec_vector == pytest.approx(tuple(d / np.linalg.norm(d)))
    ren.GetActiveCamera().Elevation(30.0)
    ren.GetActiveCamera().OrthogonalizeViewUp()
    grab(rw)
    np.testing.assert_allclose([s.vector for s in il.light_specs()], taken, atol=1e-9)
    with pytest.raises(ValueError, match="'renderer', not 'camera'"):
        vtkvol.illuminate(volume, ren, lights="camera")
    il.release()
    rw.Finalize()


def eight_volume_scene(method: str, n: int = 8):
    """``n`` small cubes side by side in one renderer, each lit by its own illuminator."""
    import vtkvol
    from vtkvol.engine.offscreen import image_from_array, make_render_window

    rw = make_render_window((32 * n, 32))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    cube = np.zeros((8, 8, 8), np.float32)
    cube[2:6, 2:6, 2:6] = 1.0
    illuminators = []
    for i in range(n):
        image = image_from_array(cube)
        image.SetOrigin(10.0 * i, 0.0, 0.0)
        mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
        mapper.SetInputData(image)
        prop = vtk.vtkVolumeProperty()
        otf = vtk.vtkPiecewiseFunction()
        otf.AddPoint(0.0, 0.0)
        otf.AddPoint(1.0, 0.8)
        prop.SetScalarOpacity(otf)
        prop.ShadeOn()
        volume = vtk.vtkVolume()
        volume.SetMapper(mapper)
        volume.SetProperty(prop)
        ren.AddVolume(volume)
        # lit from the camera's side (+z), as VTK's headlight lights them
        illuminators.append(vtkvol.illuminate(volume, ren, method=method,
                                              lights=[vtkvol.Light(direction=(0.0, 0.0, 1.0))]))
    ren.ResetCamera()
    camera = ren.GetActiveCamera()
    camera.ParallelProjectionOn()
    camera.SetParallelScale(6.0)  # 12 units high, 96 wide: every cube in view
    return rw, ren, illuminators


def brightest_at_each_volume(ren: vtk.vtkRenderer, image: np.ndarray, n: int) -> list[int]:
    height = image.shape[0]
    out = []
    for i in range(n):
        ren.SetWorldPoint(10.0 * i + 3.5, 3.5, 3.5, 1.0)
        ren.WorldToDisplay()
        x, y, _ = ren.GetDisplayPoint()
        row, col = height - 1 - round(y), round(x)
        out.append(int(image[max(row - 3, 0) : row + 4, max(col - 3, 0) : col + 4].max()))
    return out


@pytest.mark.parametrize("method", ["shadow_volume", "cone_traced"])
def test_eight_illuminated_volumes_in_one_renderer_all_render(method):
    """Texture units are a shared budget (32 on llvmpipe): a technique's textures hold a unit
    only while its own volume draws, so eight volumes do not exhaust them (before: with
    cone_traced every volume went black, VTK only logging 'Hardware does not support the
    number of textures defined')."""
    rw, ren, illuminators = eight_volume_scene(method)
    errors: list[str] = []
    for il in illuminators:
        il.on_error = errors.append
    grab(rw)
    image = grab(rw)
    assert errors == [] and all(il.failed_method is None for il in illuminators)
    manager = rw.GetTextureUnitManager()
    held = sum(manager.IsAllocated(u) for u in range(manager.GetNumberOfTextureUnits()))
    assert held <= len(illuminators)  # between frames: at most a private scratch texture each
    brightness = brightest_at_each_volume(ren, image, len(illuminators))
    assert min(brightness) > 20, brightness
    for il in illuminators:
        il.release()
    rw.Finalize()


def test_illuminate_does_not_force_shading_on_for_local_lighting():
    """The default call (local lighting, the renderer's lights) leaves an unshaded volume as
    VTK showed it; a shadow technique needs VTK's shaded variant and switches shading on until
    release()."""
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    prop = volume.GetProperty()
    prop.ShadeOff()  # PyVista's add_volume default
    before = grab(rw)
    il = vtkvol.illuminate(volume, ren)
    assert [prop.GetShade(c) for c in range(4)] == [0, 0, 0, 0]
    assert np.array_equal(grab(rw), before)
    il.set_method("shadow_volume")
    assert prop.GetShade(0) == 1
    il.set_method("local")
    assert prop.GetShade(0) == 0
    il.release()
    shadows = vtkvol.illuminate(volume, ren, method="shadow_volume")
    assert prop.GetShade(0) == 1
    shadows.release()
    assert prop.GetShade(0) == 0
    rw.Finalize()


def test_illuminate_leaves_the_renderers_lights_as_they_were():
    """Following the renderer's lights reads them: none is added, removed, switched or
    changed, neither by illuminate() nor by release()."""
    import vtkvol

    rw, ren, volume = plain_scene(vtk.vtkOpenGLGPUVolumeRayCastMapper(), image_with(False))
    kit = vtk.vtkLightKit()
    kit.AddLightsToRenderer(ren)

    def state():
        lights = ren.GetLights()
        return [(light.GetSwitch(), light.GetIntensity(), light.GetPosition(),
                 light.GetDiffuseColor()) for light in
                (lights.GetItemAsObject(i) for i in range(lights.GetNumberOfItems()))]

    grab(rw)  # camera lights take their world positions at a render
    before = state()
    il = vtkvol.illuminate(volume, ren, method="shadow_volume")
    grab(rw)
    assert state() == before and len(il.light_specs()) == min(len(before), 4)
    il.release()
    grab(rw)
    assert state() == before
    rw.Finalize()
