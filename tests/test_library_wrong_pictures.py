"""Issue 26, "wrong pictures, no message" (library part): PyVista's smart mapper illuminated
before the first render, the user's own shader replacements, PyVista's mapper API after the
call, multi-volumes, and a second ``illuminate`` on the same volume (GL)."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

import vtkvol
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene

pv = pytest.importorskip("pyvista")
pytestmark = pytest.mark.gl


def blob_grid(shift: float = 0.0) -> object:
    """A 32³ Gaussian blob (values 0…255) as PyVista image data, centred at x = 15.5 + shift."""
    z, y, x = np.mgrid[:32, :32, :32].astype(np.float32)
    grid = pv.ImageData(dimensions=(32, 32, 32))
    grid.point_data["values"] = (
        np.exp(-((x - 15.5 - shift) ** 2 + (y - 15.5) ** 2 + (z - 15.5) ** 2) / 80.0) * 255
    ).ravel()
    return grid


def foreground(image: np.ndarray) -> int:
    """Pixels brighter than the (black) background."""
    return int((image[..., :3].max(axis=2) > 10).sum())


def smart_plotter(**kwargs) -> tuple[object, object]:
    plotter = pv.Plotter(off_screen=True, window_size=(128, 128), **kwargs)
    plotter.set_background("black")
    actor = plotter.add_volume(blob_grid(), cmap="bone", opacity="sigmoid",
                               show_scalar_bar=False)  # PyVista's default: the smart mapper
    return plotter, actor


def reference_foreground() -> int:
    plotter, actor = smart_plotter()
    assert isinstance(actor.mapper, vtk.vtkSmartVolumeMapper)
    count = foreground(plotter.screenshot(return_img=True))
    plotter.close()
    return count


@pytest.mark.parametrize("method", ["local", "shadow_volume"])
@pytest.mark.parametrize("call", ["function", "component"])
def test_smart_mapper_illuminated_before_the_first_render_shows_the_volume(method, call):
    """Before: 0 foreground pixels (the stand-in GPU mapper got the smart mapper's unresolved
    sample distance, -1)."""
    expected = reference_foreground()
    assert expected > 1000
    plotter, actor = smart_plotter()
    if call == "function":
        il = vtkvol.illuminate(actor, plotter, method=method)
    else:
        il = plotter.vtkvol.illuminate(method=method)
    errors: list[str] = []
    il.on_error = errors.append
    image = plotter.screenshot(return_img=True)
    assert errors == []
    # local shading shows what the smart mapper showed; shadows darken some of the faint rim
    # below the threshold
    low = 0.95 if method == "local" else 0.75
    assert low * expected < foreground(image) < 1.05 * expected
    plotter.close()


def test_two_smart_volumes_in_one_renderer_and_in_two_linked_renderers():
    # one renderer, two volumes side by side
    plotter = pv.Plotter(off_screen=True, window_size=(192, 128))
    plotter.set_background("black")
    actors = [plotter.add_volume(blob_grid(shift), cmap="bone", opacity="sigmoid",
                                 show_scalar_bar=False) for shift in (-8.0, 8.0)]
    plotter.view_xy()
    before = foreground(plotter.screenshot(return_img=True))
    plotter.close()
    plotter = pv.Plotter(off_screen=True, window_size=(192, 128))
    plotter.set_background("black")
    actors = [plotter.add_volume(blob_grid(shift), cmap="bone", opacity="sigmoid",
                                 show_scalar_bar=False) for shift in (-8.0, 8.0)]
    plotter.view_xy()
    for actor in actors:
        vtkvol.illuminate(actor, plotter, method="shadow_volume")
    lit = foreground(plotter.screenshot(return_img=True))
    assert before > 1000 and 0.75 * before < lit < 1.05 * before
    plotter.close()

    # two renderers with linked cameras, one volume each, illuminated before the first render
    plotter = pv.Plotter(off_screen=True, window_size=(256, 128), shape=(1, 2))
    plotter.set_background("black")
    for col in (0, 1):
        plotter.subplot(0, col)
        actor = plotter.add_volume(blob_grid(), cmap="bone", opacity="sigmoid",
                                   show_scalar_bar=False)
        plotter.vtkvol.illuminate(actor, method="shadow_volume" if col else "local")
    plotter.link_views()
    image = plotter.screenshot(return_img=True)
    halves = [foreground(image[:, :128]), foreground(image[:, 128:])]
    assert min(halves) > 0.75 * reference_foreground(), halves
    plotter.close()


USER_REPLACEMENTS = (
    # (tag, pre, text): the user's own shader code, as a VTK user writes it
    ("//VTK::ComputeLighting::Dec", True,
     "//VTK::ComputeLighting::Dec\nvec3 userTint() { return vec3(1.0, 0.5, 0.25); }"),
    ("//VTK::Base::Dec", True, "//VTK::Base::Dec\nfloat userGain;"),
    ("//VTK::Base::Init", True, "//VTK::Base::Init\n  userGain = 1.0;"),
    ("//VTK::Shading::Exit", True,
     "//VTK::Shading::Exit\n  g_fragColor.rgb *= userTint() * userGain;"),
)


def replacements_of(sp: vtk.vtkShaderProperty) -> list[tuple]:
    out = []
    for i in range(sp.GetNumberOfShaderReplacements()):
        refs = [vtk.reference(""), vtk.reference(False), vtk.reference(""), vtk.reference(False)]
        sp.GetNthShaderReplacement(i, *refs)
        out.append((sp.GetNthShaderReplacementTypeAsString(i), *(r.get() for r in refs)))
    return sorted(out)


@pytest.mark.parametrize("method", ["local", "shadow_volume", "convection_diffusion"])
def test_user_shader_replacements_are_composed_and_release_restores_the_exact_image(method):
    """Before: ours replaced the user's at the tags both use (their userTint() vanished, the
    shader did not compile: a black or garbage frame), and release() cleared the user's."""
    z, y, x = np.mgrid[:32, :32, :32]
    data = np.exp(-((x - 15.5) ** 2 + (y - 15.5) ** 2 + (z - 15.5) ** 2) / 60.0)
    rw, ren, volume = simple_volume_scene(data.astype(np.float32), size=(96, 96))
    volume.GetProperty().ShadeOn()
    sp = volume.GetShaderProperty()
    for tag, pre, text in USER_REPLACEMENTS:
        sp.AddFragmentShaderReplacement(tag, pre, text, False)
    users = replacements_of(sp)
    grab(rw)
    plain = grab(rw)
    assert foreground(plain) > 1000
    il = vtkvol.illuminate(volume, ren, method=method)
    errors: list[str] = []
    il.on_error = errors.append
    for _ in range(3):
        lit = grab(rw)
    assert errors == [] and il.failed_method is None
    assert 0.8 * foreground(plain) < foreground(lit) < 1.25 * foreground(plain)
    # the user's tint still applies: red twice green, green twice blue where it is lit
    lit_px = lit[lit.max(axis=2) > 40].astype(float)
    assert len(lit_px) > 200
    assert np.median(lit_px[:, 0] / np.maximum(lit_px[:, 1], 1)) == pytest.approx(2.0, abs=0.2)
    assert "userTint" in il.fragment_source
    il.release()
    assert replacements_of(sp) == users
    after = grab(rw)
    assert int(np.abs(after.astype(int) - plain.astype(int)).max()) == 0
    rw.Finalize()


def test_a_user_replacement_that_removes_a_tag_we_replace_is_refused_at_the_call():
    rw, ren, volume = simple_volume_scene(np.ones((8, 8, 8), np.float32), size=(32, 32))
    sp = volume.GetShaderProperty()
    sp.AddFragmentShaderReplacement("//VTK::ComputeLighting::Exit", False, "  // gone", False)
    users = replacements_of(sp)
    with pytest.raises(ValueError, match=r"^vtkvol: .*//VTK::ComputeLighting::Exit"):
        vtkvol.illuminate(volume, ren, method="shadow_volume")
    assert replacements_of(sp) == users
    rw.Finalize()


def test_a_conflicting_user_replacement_added_later_makes_the_illuminator_stand_aside():
    rw, ren, volume = simple_volume_scene(np.ones((8, 8, 8), np.float32), size=(32, 32))
    volume.GetProperty().ShadeOn()
    plain = grab(rw)
    il = vtkvol.illuminate(volume, ren, method="shadow_volume")
    errors: list[str] = []
    il.on_error = errors.append
    grab(rw)
    sp = volume.GetShaderProperty()
    sp.AddFragmentShaderReplacement("//VTK::ComputeLighting::Exit", False, "  // gone", False)
    grab(rw)
    image = grab(rw)
    assert len(errors) == 1 and "//VTK::ComputeLighting::Exit" in errors[0]
    assert not errors[0].startswith("vtkvol: vtkvol")
    assert replacements_of(sp) == [("Fragment", "//VTK::ComputeLighting::Exit", False,
                                    "  // gone", False)]  # only the user's is left
    assert image.max() > 30 and volume.GetProperty().GetShade(0) == 1
    il.release()
    sp.ClearFragmentShaderReplacement("//VTK::ComputeLighting::Exit", False)
    assert np.array_equal(grab(rw), plain)
    rw.Finalize()


def test_smart_mapper_picture_is_the_smart_mappers_and_vector_mode_is_refused():
    plotter, actor = smart_plotter()
    plain = plotter.screenshot(return_img=True)
    plotter.close()
    plotter, actor = smart_plotter()
    il = vtkvol.illuminate(actor, plotter)  # local lighting, the renderer's lights
    lit = plotter.screenshot(return_img=True)
    assert int(np.abs(lit.astype(int) - plain.astype(int)).max()) <= 3
    assert actor.mapper.GetSampleDistance() == pytest.approx(0.5)  # the spacing's, not -1
    il.release()
    plotter.close()
    plotter, actor = smart_plotter()
    actor.mapper.SetVectorMode(vtk.vtkSmartVolumeMapper.MAGNITUDE)
    with pytest.raises(TypeError, match=r"^vtkvol: .*vector mode"):
        vtkvol.illuminate(actor, plotter)
    assert isinstance(actor.mapper, vtk.vtkSmartVolumeMapper)  # untouched
    actor.mapper.SetVectorMode(vtk.vtkSmartVolumeMapper.DISABLED)
    with pytest.raises(ValueError, match="softness"):  # any refused call: nothing swapped
        vtkvol.illuminate(actor, plotter, method="shadow_volume", softness=-5.0)
    assert isinstance(actor.mapper, vtk.vtkSmartVolumeMapper)
    plotter.close()


def test_pyvista_mapper_api_keeps_working_after_illuminate():
    """Before: actor.mapper became a plain vtkOpenGLGPUVolumeRayCastMapper, and
    ``actor.mapper.blend_mode = "maximum"`` raised a TypeError."""
    plotter, actor = smart_plotter()
    user_mapper = actor.mapper
    lut = user_mapper.lookup_table
    il = plotter.vtkvol.illuminate(method="local")
    composite = plotter.screenshot(return_img=True)
    mapper = actor.mapper
    assert mapper.lookup_table is lut and mapper.scalar_range == user_mapper.scalar_range
    assert mapper.blend_mode == "composite"
    mapper.blend_mode = "maximum"
    assert mapper.blend_mode == "maximum"
    plotter.render()
    mip = plotter.screenshot(return_img=True)
    assert int(np.abs(mip.astype(int) - composite.astype(int)).max()) > 30
    # the object the user held from before the call keeps working too
    user_mapper.blend_mode = "composite"
    plotter.render()
    again = plotter.screenshot(return_img=True)
    assert actor.mapper.blend_mode == "composite"
    assert int(np.abs(again.astype(int) - composite.astype(int)).max()) <= 2
    actor.mapper.scalar_range = (0.0, 100.0)
    assert lut.scalar_range == (0.0, 100.0)
    actor.mapper.blend_mode = "maximum"
    il.release()
    assert actor.mapper is user_mapper  # the user's smart mapper, with the edits made since
    assert user_mapper.blend_mode == "maximum" and user_mapper.scalar_range == (0.0, 100.0)
    plotter.close()


def multi_volume_scene():
    from vtkvol.engine.offscreen import image_from_array, make_render_window

    rw = make_render_window((48, 48))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
    multi = vtk.vtkMultiVolume()
    multi.SetMapper(mapper)
    members = []
    for port in range(2):
        image = image_from_array(np.ones((8, 8, 8), np.float32))
        mapper.SetInputDataObject(port, image)
        member = vtk.vtkVolume()
        member.SetProperty(vtk.vtkVolumeProperty())
        multi.SetVolume(member, port)
        members.append(member)
    ren.AddVolume(multi)
    return rw, ren, multi, members


def test_multi_volumes_are_refused_by_name():
    rw, ren, multi, members = multi_volume_scene()
    with pytest.raises(TypeError, match=r"^vtkvol: .*multi-volume.*vtkMultiVolume"):
        vtkvol.illuminate(multi, ren)
    with pytest.raises(TypeError, match=r"^vtkvol: .*multi-volume.*vtkMultiVolume"):
        vtkvol.illuminate(members[1], ren)
    assert multi.GetShaderProperty().GetNumberOfShaderReplacements() == 0
    rw.Finalize()


def test_a_second_illuminate_returns_the_first_switched_to_the_new_method():
    rw, ren, volume = simple_volume_scene(np.ones((8, 8, 8), np.float32), size=(32, 32))
    plain = grab(rw)
    first = vtkvol.illuminate(volume, ren, method="local")
    grab(rw)
    second = vtkvol.illuminate(volume, ren, method="shadow_volume", softness=1.5)
    assert second is first and first.method == "shadow_volume"
    assert first.parameters["softness"] == 1.5
    grab(rw)
    with pytest.raises(ValueError, match=r"^vtkvol: this volume is already illuminated"):
        Illuminator(volume, ren)  # the engine's constructor refuses to stack a second one
    third = vtkvol.illuminate(volume, ren, method="cone_traced",
                              lights=[vtkvol.Light(direction=(0.0, 1.0, 0.0))])
    assert third is first and first.method == "cone_traced"
    assert first.lights[0].direction == pytest.approx((0.0, 1.0, 0.0))
    other = vtk.vtkRenderer()
    with pytest.raises(ValueError, match=r"^vtkvol: .*already illuminated"):
        vtkvol.illuminate(volume, other)
    grab(rw)
    first.release()  # one illuminator: releasing it leaves nothing of ours behind
    assert volume.GetShaderProperty().GetNumberOfShaderReplacements() == 0
    assert np.array_equal(grab(rw), plain)
    fresh = vtkvol.illuminate(volume, ren)  # released: a new illuminator
    assert fresh is not first and fresh.method == "local"
    fresh.release()
    rw.Finalize()
