"""Shared multi-channel lighting (``RenderSettings.multichannel_lighting = "shared"``,
resources/shaders/host_multichannel_lighting.glsl, issue 11): channels classified unlit, mixed,
and lit once per sample with the opacity-weighted normal and material.

Measured on these scenes (96² images; docs/benchmarks.md, "Multi-channel frames"): the
confocal phantom (nuclei and membranes barely overlap) differs from per-channel lighting by at
most 3 8-bit levels with every surface technique and by 0 (diffusion) to 3 (path tracing's
Monte Carlo sums, a few pixels) with the medium ones; two overlapping copies of the nuclei
(different normals where they overlap) by PSNR 36.6–42.0 dB, SSIM ≥ 0.990 (max 43–67 levels
on a few edge pixels), while leaving the lighting out entirely would give PSNR 14.7–16.8 dB;
a second, empty channel changes nothing (0 levels)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from test_empty_space import sparse_phantom

from vtkvol.engine.api import offscreen_view
from vtkvol.engine.offscreen import grab
from vtkvol.io import VolumeData, confocal_phantom
from vtkvol.model.defaults import scene_for
from vtkvol.model.scene import Light, RenderSettings, SceneModel
from vtkvol.reference import image_metrics

SHARE_CALL = "vtkvol<host_multichannel_lighting.glsl>"  # the shared sections, built in
SURFACE = ["local", "shadow_volume", "cone_traced", "translucency"]
MEDIUM = ["convection_diffusion", "hybrid_diffusion", "path_traced"]


@pytest.fixture(scope="module")
def phantom() -> VolumeData:
    return confocal_phantom((24, 40, 40), voxel_size_um=(0.5, 0.5, 1.0))


@pytest.fixture(scope="module")
def overlapping(phantom) -> VolumeData:
    """The nuclei and a shifted copy: overlapping blobs whose normals differ."""
    nuclei = phantom.array[0]
    shifted = np.roll(nuclei, (0, 3, 4), axis=(0, 1, 2))
    return VolumeData.from_array(np.ascontiguousarray(np.stack([nuclei, shifted])),
                                 phantom.voxel_size_um, ["a", "b"])


def render(data: VolumeData, method: str, lighting: str, edit: Callable | None = None
           ) -> tuple[np.ndarray, str, str]:
    """The image (int RGBA), the fragment shader and what the host did with the lighting."""
    model = scene_for(data)
    model.render.multichannel_lighting = lighting
    if edit is not None:
        edit(model)
    with offscreen_view(data, model=model, size=(96, 96), method=method) as (rw, scene, _):
        il = scene.illuminator
        assert il is not None
        if il.spec.has("progressive"):
            # Both images from the same number of iterations, whatever the machine's load.
            il.set_parameters(max_iterations=8)
            # bounded by iterations, not time: a loaded machine must not compare 5 with 8
            il.converge(iterations=8, max_seconds=900)
            assert il.technique is not None and il.technique.iteration >= 8
        grab(rw)
        image = grab(rw).astype(int)
        return image, il.fragment_source, il.multichannel_lighting_state


def both(data: VolumeData, method: str, edit: Callable | None = None
         ) -> tuple[np.ndarray, np.ndarray]:
    per_channel, per_source, per_state = render(data, method, "per_channel", edit)
    shared, shared_source, shared_state = render(data, method, "shared", edit)
    # The shared path is really in the shader (and only there)…
    assert per_state == "per_channel" and SHARE_CALL not in per_source
    assert shared_state == "shared", shared_state
    assert SHARE_CALL in shared_source and "vv_mcUnlit" in shared_source
    assert per_channel.max() > 60  # something is drawn
    return per_channel, shared


def metrics(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    return image_metrics(a[..., :3].astype(np.uint8), b[..., :3].astype(np.uint8))


# -- image ------------------------------------------------------------------------------------
@pytest.mark.gl
@pytest.mark.parametrize("method", SURFACE + MEDIUM)
def test_every_technique_lights_once_close_to_per_channel(phantom, method):
    per_channel, shared = both(phantom, method)
    diff = np.abs(per_channel - shared)
    assert diff.max() <= 4
    if method in MEDIUM:
        # No normal and equal materials: the same light (path tracing's Monte Carlo sums may
        # round a level apart on a few pixels).
        assert (diff.max(axis=-1) > 1).mean() < 0.01


@pytest.mark.gl
@pytest.mark.parametrize("method", ["local", "shadow_volume"])
def test_overlapping_channels_stay_close_and_are_really_lit(overlapping, method):
    per_channel, shared = both(overlapping, method)
    close = metrics(shared, per_channel)
    assert close["psnr"] >= 33.0 and close["ssim"] >= 0.98, close
    # The bound is one a missing lighting would fail by far: unlit is ~16 dB away.
    unlit, _, _ = render(overlapping, method, "per_channel",
                         lambda m: setattr(m.render, "shade", False))
    assert metrics(unlit, per_channel)["psnr"] < 25.0
    # Moving the light moves the shading of the shared image.
    moved, _, _ = render(overlapping, method, "shared",
                         lambda m: setattr(m, "lights", [Light(direction=(1.0, 0.3, 0.2))]))
    assert int((np.abs(moved - shared).max(axis=-1) > 10).sum()) > 500


@pytest.mark.gl
def test_shadows_still_darken_with_shared_lighting(overlapping):
    """The shadow volume darkens the same pixels under shared lighting as per channel."""
    local_per, local_shared = both(overlapping, "local")
    shadow_per, shadow_shared = both(overlapping, "shadow_volume")
    darker_per = (local_per - shadow_per)[..., :3].max(axis=-1) > 20
    darker_shared = (local_shared - shadow_shared)[..., :3].max(axis=-1) > 20
    assert darker_per.sum() > 200
    overlap = (darker_per & darker_shared).sum() / darker_per.sum()
    assert overlap > 0.9 and abs(int(darker_shared.sum()) - int(darker_per.sum())) < (
        0.1 * darker_per.sum())


@pytest.mark.gl
@pytest.mark.parametrize("method", ["local", "cone_traced"])
def test_an_empty_channel_leaves_the_other_channels_lighting(phantom, method):
    """Where one channel is visible the normal and the material are that channel's own."""
    nuclei = phantom.array[0]
    data = VolumeData.from_array(np.ascontiguousarray(np.stack([nuclei, np.zeros_like(nuclei)])),
                                 phantom.voxel_size_um, ["nuclei", "empty"])
    per_channel, shared = both(data, method)
    assert np.abs(per_channel - shared).max() <= 1


@pytest.mark.gl
def test_one_channel_is_unchanged(phantom):
    one = VolumeData.from_array(np.ascontiguousarray(phantom.array[:1]), phantom.voxel_size_um,
                                ["nuclei"])
    for method in ("local", "shadow_volume"):
        per_channel, per_source, _ = render(one, method, "per_channel")
        shared, shared_source, state = render(one, method, "shared")
        assert np.array_equal(per_channel, shared)
        assert per_source == shared_source and "vv_mcShareLighting" not in shared_source
        assert state == "per_channel"  # nothing to share: not even a reason to give


@pytest.mark.gl
def test_per_channel_is_still_vtks_image(phantom):
    """The default keeps the host's sample, identical to VTK's per-component loop."""
    images = []
    for host_sample in (True, False):
        model = scene_for(phantom)
        assert model.render.multichannel_lighting == "per_channel"
        with offscreen_view(phantom, model=model, size=(96, 96), method="local") as (rw, s, _):
            assert s.illuminator is not None
            s.illuminator.multichannel_sample = host_sample
            grab(rw)
            images.append(grab(rw).astype(int))
            assert SHARE_CALL not in s.illuminator.fragment_source
    assert np.abs(images[0] - images[1]).max() <= 1


def _everything(model: SceneModel) -> None:
    model.render.channel_mixing = "composite"
    model.render.interpolation = "corrected"
    model.render.empty_space_skipping = True
    model.slice_weights.z = [(0.0, 0.2), (0.5, 1.0), (1.0, 0.4)]
    model.crop.x = (2.0, 17.0)
    model.clip_plane.enabled = True
    model.clip_plane.normal = (0.3, 0.2, 0.9)


@pytest.mark.gl
def test_with_slice_weights_crop_clip_plane_corrected_filter_and_skipping(overlapping):
    per_channel, shared = both(overlapping, "local", _everything)
    close = metrics(shared, per_channel)
    assert close["psnr"] >= 33.0 and close["ssim"] >= 0.98, close
    _, source, _ = render(overlapping, "local", "shared", _everything)
    # The corrected filter shares its six fetches: the channels' gradients come from them.
    assert "#define VV_MC_CHANNEL_GRADIENT vv_ipGradient" in source


@pytest.mark.gl
def test_empty_space_skipping_stays_exact():
    """Sparse beads in two channels: skipping is active and changes no shared image."""
    beads = np.stack([sparse_phantom(32, seed=1), sparse_phantom(32, seed=2)])
    data = VolumeData.from_array(beads, (0.5, 0.5, 1.0), ["a", "b"])

    def no_skipping(model: SceneModel) -> None:
        model.render.empty_space_skipping = False

    skipped, source, state = render(data, "shadow_volume", "shared")
    assert state == "shared" and "vtkvol<host_empty_space.glsl>" in source
    full, _, _ = render(data, "shadow_volume", "shared", no_skipping)
    assert skipped.max() > 60 and np.abs(skipped - full).max() <= 1


@pytest.mark.gl
def test_unshaded_rendering_is_left_alone(phantom):
    def unshaded(model: SceneModel) -> None:
        model.render.shade = False

    per_channel, _, _ = render(phantom, "local", "per_channel", unshaded)
    shared, source, state = render(phantom, "local", "shared", unshaded)
    assert np.array_equal(per_channel, shared) and SHARE_CALL not in source
    assert state.startswith("per_channel (unshaded")


# -- settings and plumbing ----------------------------------------------------------------------
def test_the_setting_is_declared_and_validated():
    assert RenderSettings().multichannel_lighting == "per_channel"
    assert RenderSettings(multichannel_lighting="shared").multichannel_lighting == "shared"
    for bad in ("Shared", "one", "", None, 1):
        with pytest.raises(ValueError, match="multichannel_lighting") as info:
            RenderSettings(multichannel_lighting=bad)
        assert "'per_channel' or 'shared'" in str(info.value)


@pytest.mark.gl
def test_scene_and_library_follow_the_setting(phantom):
    import vtk

    from vtkvol.engine.api import illuminate
    from vtkvol.engine.offscreen import make_render_window
    from vtkvol.engine.scene import VolumeScene

    model = scene_for(phantom)
    rw = make_render_window((64, 64))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    scene = VolumeScene(ren, model, phantom, request_render=lambda: None)
    try:
        il = scene.illuminator
        assert il is not None and il.multichannel_lighting == "per_channel"
        model.render.multichannel_lighting = "shared"
        assert il.multichannel_lighting == "shared"
        grab(rw)
        grab(rw)
        assert SHARE_CALL in il.fragment_source
        with pytest.raises(ValueError, match="'per_channel' or 'shared', not 'all'"):
            il.set_multichannel_lighting("all")
        # The library call takes it too, and refuses a bad value before touching the volume.
        with pytest.raises(ValueError, match="multichannel_lighting must be"):
            illuminate(scene.volume, ren, multichannel_lighting="both")
    finally:
        scene.close()
        rw.Finalize()


def _dock(qapp: Any, model: SceneModel) -> Any:
    from vtkvol.ui.docks.channels import ChannelsDock

    return ChannelsDock(model)


@pytest.mark.gui
def test_channels_dock_control(qapp, phantom):
    model = scene_for(phantom)
    dock = _dock(qapp, model)
    dock.show()
    try:
        combo = dock.channel_lighting
        assert combo.objectName() == "render_multichannel_lighting"
        assert combo.isVisible() and combo.currentData() == "per_channel"
        combo.setCurrentIndex(combo.findData("shared"))
        assert model.render.multichannel_lighting == "shared"
        model.render.multichannel_lighting = "per_channel"
        assert combo.currentData() == "per_channel"
        assert "medium" not in combo.toolTip()
        model.illumination.method = "hybrid_diffusion"
        assert "scattering medium" in combo.toolTip()  # what shared means there
        model.render.blend_mode = "mip"
        assert not combo.isEnabled()  # only composite blending is lit
        model.channels = model.channels[:1]
        assert not combo.isVisible()  # nothing to share with one channel
    finally:
        dock.deleteLater()


@pytest.mark.gl
def test_gradient_opacity_keeps_per_channel_lighting(phantom):
    """VTK's gradient-opacity variant takes its gradients per channel: shared lighting stands
    aside (and says why) rather than light with a normal it cannot share."""
    import vtk

    images = {}
    for lighting in ("per_channel", "shared"):
        model = scene_for(phantom)
        model.render.multichannel_lighting = lighting
        with offscreen_view(phantom, model=model, size=(96, 96), method="local") as (rw, s, _):
            ramp = vtk.vtkPiecewiseFunction()
            ramp.AddPoint(0.0, 0.2)
            ramp.AddPoint(50.0, 1.0)
            s.volume.GetProperty().SetGradientOpacity(0, ramp)
            grab(rw)
            images[lighting] = grab(rw).astype(int)
            il = s.illuminator
            assert il is not None and SHARE_CALL not in il.fragment_source
            state = il.multichannel_lighting_state
    assert state == ("per_channel (gradient opacity or volumetric scattering take gradients "
                     "per channel)")
    assert np.array_equal(images["per_channel"], images["shared"])


# -- the library path (issue 26) --------------------------------------------------------------
def _host_build(source: str) -> set[str]:
    """What the host put in a fragment shader: its section markers and ``VV_`` defines."""
    return {line.strip() for line in source.splitlines()
            if line.strip().startswith(("// vtkvol<", "#define VV_"))}


def _library_source(data: VolumeData, method: str, lighting: str) -> tuple[str, str]:
    """The fragment shader and state of a plain VTK pipeline given ``illuminate()``: two
    independent components, per-component TFs, ``ShadeOn()`` (VTK: component 0 only), the
    mapper's default (automatic) sample distance, the renderer's headlight."""
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    from vtkvol import illuminate
    from vtkvol.engine.offscreen import make_render_window

    n, nz, ny, nx = data.array.shape
    img = vtk.vtkImageData()
    img.SetDimensions(nx, ny, nz)
    img.SetSpacing(*data.voxel_size_um)
    img.GetPointData().SetScalars(numpy_to_vtk(
        np.ascontiguousarray(np.moveaxis(data.array, 0, -1)).reshape(-1, n), deep=True))
    prop = vtk.vtkVolumeProperty()
    prop.IndependentComponentsOn()
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOn()
    for c, channel in enumerate(scene_for(data).channels):
        ctf, otf = vtk.vtkColorTransferFunction(), vtk.vtkPiecewiseFunction()
        for value, r, g, b in channel.tf.colors:
            ctf.AddRGBPoint(value, r, g, b)
        for value, alpha in channel.tf.opacity:
            otf.AddPoint(value, alpha)
        prop.SetColor(c, ctf)
        prop.SetScalarOpacity(c, otf)
    mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
    mapper.SetInputData(img)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    rw = make_render_window((64, 64))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    ren.AddVolume(volume)
    ren.ResetCamera()
    il = illuminate(volume, ren, method=method, multichannel_lighting=lighting)
    try:
        grab(rw)
        grab(rw)  # the source is captured on the frame after a build
        return il.fragment_source, il.multichannel_lighting_state
    finally:
        il.release()
        rw.Finalize()


@pytest.mark.gl
@pytest.mark.parametrize("method", ["local", "shadow_volume", "translucency"])
@pytest.mark.parametrize("lighting", ["per_channel", "shared"])
def test_library_pipeline_builds_the_scenes_multichannel_shader(phantom, method, lighting):
    """Issue 26: a plain VTK pipeline given illuminate() gets the host's multi-channel sample
    and, asked for, the shared lighting: the same host sections and defines as the app's scene
    path, so a frame costs what it costs there (docs/benchmarks.md, "Shared lighting")."""
    library, state = _library_source(phantom, method, lighting)
    _image, scene_source, scene_state = render(phantom, method, lighting)
    assert state == scene_state == lighting
    assert "vv_mcClassify(" in library  # the host's sample, not VTK's per-component loop
    assert (SHARE_CALL in library) == (lighting == "shared")
    assert _host_build(library) == _host_build(scene_source)


@pytest.mark.gl
def test_per_channel_lighting_already_shares_what_local_and_shadows_cost(phantom):
    """Why shared lighting saves nothing measurable with local shading and the shadow volume
    (docs/benchmarks.md): per-channel lighting already takes the six gradient fetches and the
    transmittance towards each light once per sample (vv_mcLights), so the second channel's
    lighting is arithmetic only. Translucency's shading looks its transmittance up per call,
    i.e. per channel: there shared lighting removes a texture lookup per sample and light."""
    for method in ("local", "shadow_volume"):
        source, state = _library_source(phantom, method, "per_channel")
        assert state == "per_channel"
        assert "#define VV_MC_SHARE_GRADIENT 1" in source
        assert "#define VV_MC_SHARE_LIGHT 1" in source
        assert "  vv_mcLights();" in source
        assert "vec3 transmittance = vv_mcTransmittance[i];" in source
    source, _state = _library_source(phantom, "translucency", "per_channel")
    assert "#define VV_MC_SHARE_GRADIENT 1" in source
    assert ("vec3 transmittance = probe ? vec3(1.0) : vv_light_transmittance_rgb(i, g_dataPos, l);"
            in source)
