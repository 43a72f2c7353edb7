"""Half-angle slicing (vtkvol.engine.renderers.half_angle): GPU against its numpy twin for both
slice orders and a point light, the slice-spacing correction, jitter, opaque geometry, crop /
clipping / slice weights, channels, and the refusals (MIP, more than one light).

Small scenes (≤ 32³, ≤ 64² images) on llvmpipe; tolerances are stated at each assertion.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_renderers import _modifiers, ball, exact_over_sphere, needs_compute, scene, sphere_actor

import vtkvol
from vtkvol.engine.offscreen import grab, image_from_array, simple_volume_scene
from vtkvol.engine.renderers import set_renderer
from vtkvol.engine.renderers.base import colour_volume
from vtkvol.engine.renderers.half_angle import frame_jitter, slice_angle, slicing_geometry
from vtkvol.model.renderers import unsupported_reason
from vtkvol.reference.half_angle import half_angle_pixels

#: The test scene's view direction (camera azimuth 30°, elevation 20°) is (−0.47, 0.81, −0.34)
#: in dataset space; the lights below are chosen against it (directions towards the light).
FROM_VIEWER = (0.7, -0.5, 0.5)       # behind the camera: cos 0.91 with the view's reverse
TOWARDS_VIEWER = (-0.2, 0.9, -0.5)   # behind the volume, shining at the camera: cos 0.94


def half_angle_scene(direction=FROM_VIEWER, size=48, n=24, light=None, **kw):
    rw, ren, vol, host = scene(n=n, size=size, lights=[light or vtkvol.Light(
        direction=direction)], **kw)
    needs_compute(rw)
    host.set_material(albedo=0.9, phase_g=0.3)
    vol.GetProperty().SetAmbient(0.2)
    return rw, ren, vol, host


def twin(r, host, pixels, size):
    """The numpy twin's RGBA at ``pixels`` for the renderer's last frame."""
    if r.classification_reason is None:
        med = {"scalars": r.post_scalars, "table": r.post_table}
    else:
        med = {"alpha": host.opacity_volume(), "colour": colour_volume(host.volume, host.image)}
    med.update(spacing=host.spacing, origin=host.image.GetOrigin(),
               unit_distance=host.unit_distance)
    u = r._uniform_base(r.renderer.GetRenderWindow())
    return half_angle_pixels(med, r.geometry, u["ndcToData"], (size, size), pixels, slice_angle)


# -- the model's and the engine's refusals -------------------------------------------------------
def test_half_angle_refusals_are_one_sentence():
    assert unsupported_reason("half_angle", method="shadow_volume") is None
    assert unsupported_reason("half_angle", lights=2) == (
        "the half_angle renderer slices along the half vector of one light and the view, so it "
        "takes exactly one enabled light, not 2")
    assert unsupported_reason("half_angle", lights=0).endswith("not 0")
    assert unsupported_reason("half_angle", blend_mode="mip") == (
        "the half_angle renderer composites emission and absorption only; blend mode 'mip' "
        "needs the raycast renderer")
    _rw, _ren, vol, host = scene(lights=[vtkvol.Light(direction=(1, 0, 0)),
                                         vtkvol.Light(direction=(0, 1, 0))])
    with pytest.raises(ValueError, match=r"^vtkvol: the half_angle renderer slices along the "
                                         r"half vector of one light and the view, so it takes "
                                         r"exactly one enabled light, not 2$"):
        set_renderer(host, "half_angle")
    host.set_lights([vtkvol.Light(direction=(1, 0, 0))])
    vol.GetMapper().SetBlendModeToMaximumIntensity()
    with pytest.raises(ValueError, match=r"^vtkvol: the half_angle renderer composites"):
        set_renderer(host, "half_angle")
    assert host.beside is None and vol.GetVisibility() == 1
    host.release()


def test_slicing_geometry_flips_with_the_light():
    """Half vector of the view and the light's propagation; under (front to back) when the
    light shines from the viewer's side, over (back to front) when it shines at the viewer."""
    v = np.array([0.0, 0.0, -1.0])
    lit = np.array([0.0, -0.6, -0.8])
    s, under = slicing_geometry(v, lit)
    assert under and np.allclose(s, (v + lit) / np.linalg.norm(v + lit))
    s, under = slicing_geometry(v, np.array([0.0, -0.6, 0.8]))
    assert not under and np.allclose(s, [0, -0.6, 1.8] / np.linalg.norm([0, -0.6, 1.8]))
    assert [frame_jitter(f) for f in range(3)] == pytest.approx([0.5, 0.118034, 0.736068],
                                                                abs=1e-6)


# -- GPU = numpy twin ------------------------------------------------------------------------------
@pytest.mark.parametrize(("light", "under", "classification"), [
    ("from_viewer", True, "post"), ("towards_viewer", False, "post"),
    ("point", True, "pre")])
def test_half_angle_gpu_equals_numpy_twin(light, under, classification):
    """One frame (no accumulation), 64² light buffer, RGB colour, g = 0.3, ambient 0.2, at 10
    seeded pixels: every channel and the coverage within 2e-3 (float32 on the GPU against
    float64; a wrong slice order, operator, light-buffer step or blur moves them by ≥ 1e-2).
    The twin composites each pixel's samples sorted along the ray, so the back-to-front case
    checks the over operator independently. Pre-classified: a clipping plane that removes
    nothing switches to the host's opacity texture; the point light has inverse-square
    fall-off."""
    spec = {"from_viewer": vtkvol.Light(direction=FROM_VIEWER),
            "towards_viewer": vtkvol.Light(direction=TOWARDS_VIEWER),
            "point": vtkvol.Light(kind="point", position=(30.0, -10.0, 30.0),
                                  falloff="inverse_square", color=(0.6, 0.8, 1.0))}[light]
    rw, _ren, vol, host = half_angle_scene(light=spec, opacity=((0.0, 0.0), (1.0, 0.6)))
    if classification == "pre":
        import vtk

        plane = vtk.vtkPlane()
        plane.SetOrigin(-100, 0, 0)
        plane.SetNormal(1, 0, 0)
        vol.GetMapper().AddClippingPlane(plane)
    r = set_renderer(host, "half_angle", samples=1, light_resolution=64)
    rw.Render()
    assert r.last_error is None and r.under is under
    assert (r.classification_reason is None) == (classification == "post")
    res = r.read_result()
    covered = np.argwhere(res[..., 3] > 0.2)  # (y, x) where the ball is seen
    assert len(covered) > 200
    pick = np.random.default_rng(3).choice(len(covered), 10, replace=False)
    pixels = [(int(covered[i, 1]), int(covered[i, 0])) for i in pick]
    cpu = twin(r, host, pixels, 48)
    gpu = np.array([res[y, x] for x, y in pixels])
    assert np.abs(gpu - cpu).max() < 2e-3, np.abs(gpu - cpu).max()
    host.release()


def test_light_behind_the_volume_darkens_its_visible_side():
    """The same dense ball lit from behind the camera and from behind the volume (the
    back-to-front case): seen from the camera, the lit side faces away in the second, so the
    image is darker (isotropic phase, no ambient: less than 0.6 of the brightness)."""
    means = []
    for direction in (FROM_VIEWER, TOWARDS_VIEWER):
        rw, _ren, vol, host = half_angle_scene(direction, opacity=((0.0, 0.0), (1.0, 0.9)))
        host.set_material(albedo=0.9, phase_g=0.0)
        vol.GetProperty().SetAmbient(0.0)
        r = set_renderer(host, "half_angle", samples=1)
        rw.Render()
        res = r.read_result()
        means.append(float(res[..., :3].sum() / max(res[..., 3].sum(), 1e-9)))
        host.release()
    assert means[1] < 0.6 * means[0], means


def test_direct_light_agrees_with_the_camera_path_tracer():
    """The independent truth: with the indirect term off (w = 0) half-angle slicing renders the
    direct light of the medium model, which the camera path tracer estimates in single
    scattering (256 paths). Over the pixels the ball covers the mean signed difference of
    the red channel (the brightest) falls from ~3 levels at 1 slice per voxel to within 1.25
    levels at 4 (measured 3.0 → 0.7; the path tracer's noise leaves ~0.2 on the mean), and
    the coverage agrees within 0.5 levels on average."""
    _rw, _ren, _vol, host = half_angle_scene(opacity=((0.0, 0.0), (1.0, 0.6)))
    pt = set_renderer(host, "path_tracer", scattering="single", samples=256, seed=3)
    host.converge(max_frames=300)
    truth = pt.read_result()
    covered = truth[..., 3] > 0.05
    assert covered.sum() > 300
    bias = {}
    for spv in (1, 4):
        ha = set_renderer(host, "half_angle", samples=8, slices_per_voxel=spv,
                          indirect_strength=0.0)
        host.converge(max_frames=20)
        diff = (ha.read_result() - truth)[covered] * 255
        bias[spv] = float(diff[:, 0].mean())
        assert abs(float(diff[:, 3].mean())) < 0.5, diff[:, 3].mean()
    assert abs(bias[4]) < 1.25 and abs(bias[1]) > 2 * abs(bias[4]), bias
    host.release()


def test_host_exposure_and_fill_are_honoured():
    """As the path tracer: the exposure scales the radiance (×2 → ×2, coverage unchanged) and
    the sky fill F adds to the ambient k_a (k_a 0.2 with F 0.3 renders as k_a 0.5 without
    fill), to 1e-5."""
    rw, _ren, vol, host = half_angle_scene()
    host.set_exposure(1.0, 0.0)

    def frame():
        r = set_renderer(host, "half_angle", samples=1)
        rw.Render()
        return r.read_result()

    base = frame()
    host.set_exposure(2.0, 0.0)
    brighter = frame()
    assert base[..., :3].max() > 0.1
    np.testing.assert_allclose(brighter[..., :3], 2 * base[..., :3], atol=1e-5)
    np.testing.assert_allclose(brighter[..., 3], base[..., 3], atol=1e-6)
    host.set_exposure(1.0, 0.3)
    filled = frame()
    host.set_exposure(1.0, 0.0)
    vol.GetProperty().SetAmbient(0.5)
    np.testing.assert_allclose(filled, frame(), atol=1e-5)
    assert (filled[..., 0] - base[..., 0]).max() > 0.05
    host.release()


# -- slice spacing, jitter -------------------------------------------------------------------------
def test_opacity_is_corrected_for_the_slice_spacing_along_each_ray():
    """With the light at right angles to the view the slices meet the camera rays at ≈ 45°:
    the coverage (1 − T) equals the exact integral along each ray (0.02 µm numpy march) within
    0.01 at 1 and 0.5 slices per voxel. Without Δ = d / cos θ the optical depth would be
    ≈ 30 % short (errors > 0.05)."""
    _rw, ren, _vol, host = half_angle_scene(opacity=((0.0, 0.0), (1.0, 0.4)))
    cam = ren.GetActiveCamera()
    dop = np.array(cam.GetDirectionOfProjection())
    side = np.cross(dop, cam.GetViewUp())
    host.set_lights([vtkvol.Light(direction=tuple(side / np.linalg.norm(side)))])
    for spv in (1.0, 0.5):
        r = set_renderer(host, "half_angle", samples=4, slices_per_voxel=spv)
        host.converge(max_frames=10)
        s_dot_v = float(np.asarray(r.geometry["axis"]) @ (dop / np.linalg.norm(dop)))
        assert 0.6 < s_dot_v < 0.8  # ≈ cos 45°
        cov = r.read_result()[..., 3]
        errors = []
        for x, y in [(16, 20), (24, 24), (30, 18), (20, 30), (27, 27)]:
            _front, exact = exact_over_sphere(r, host, (x, y), (1e6, 0, 0), 1.0, 48)
            errors.append(abs(cov[y, x] - exact))
        assert max(errors) < 0.01, (spv, errors)
    host.release()


def test_jittered_frames_remove_the_slice_pattern():
    """Coarse slices (0.5 per voxel) leave a slice pattern: the high-pass part (image minus
    its 5 × 5 box mean) of the difference to a fine-sliced image (4 per voxel). Averaging 16
    jittered frames cuts its RMS to below 0.7 of one frame's (measured 0.55; without jitter
    the frames would be equal and the ratio 1). The low-frequency bias of coarse slices stays
    (the per-slice blur and light steps depend on the spacing). Convergence is reported after
    the 16 frames, and a repaint after it adds none."""
    from scipy.ndimage import uniform_filter

    rw, _ren, _vol, host = half_angle_scene(opacity=((0.0, 0.0), (0.5, 0.8), (1.0, 0.8)))
    fine = set_renderer(host, "half_angle", samples=1, slices_per_voxel=4)
    rw.Render()
    ref = fine.read_result()
    coarse = set_renderer(host, "half_angle", samples=16, slices_per_voxel=0.5)
    rw.Render()
    one = coarse.read_result()
    assert host.converge(max_frames=30) == 15
    assert coarse.iteration == 16 and coarse.converged
    avg = coarse.read_result()
    rw.Render()
    assert coarse.iteration == 16

    def pattern(x):
        d = x - ref
        return float(np.sqrt(((d - uniform_filter(d, size=(5, 5, 1))) ** 2).mean()))

    assert pattern(avg) < 0.7 * pattern(one), (pattern(one), pattern(avg))
    host.release()


# -- opaque geometry, crop / clip / weights, channels ---------------------------------------------
def test_opaque_sphere_through_the_volume_occludes_half_angle():
    """A sphere half inside the volume: at 12 sphere pixels the coverage is the volume in front
    of it (numpy march to the analytic sphere) within 0.02; the volume behind the sphere adds
    more than 0.1 there, so ignoring VTK's depth fails."""
    size = 64
    centre, radius = (15.5, 8.0, 15.5), 6.0
    rw, ren, vol, host = half_angle_scene(n=32, size=size, opacity=((0.0, 0.0), (1.0, 0.3)))
    ren.AddActor(sphere_actor(centre, radius))
    ren.ResetCamera()
    vol.VisibilityOff()
    only = grab(rw).astype(float)
    vol.VisibilityOn()
    sphere = np.abs(only - only[0, 0]).max(-1) > 30
    sphere[1:] &= sphere[:-1]
    sphere[:-1] &= sphere[1:]
    sphere[:, 1:] &= sphere[:, :-1]
    sphere[:, :-1] &= sphere[:, 1:]
    assert sphere.sum() > 100
    r = set_renderer(host, "half_angle", samples=4, slices_per_voxel=2)
    host.converge(max_frames=10)
    cov = r.read_result()[..., 3]
    ys, xs = np.nonzero(sphere)
    errors, behind = [], []
    for k in range(0, len(ys), max(1, len(ys) // 12)):
        x, y = int(xs[k]), int(size - 1 - ys[k])
        a_front, a_all = exact_over_sphere(r, host, (x, y), centre, radius, size)
        behind.append(a_all - a_front)
        errors.append(abs(cov[y, x] - a_front))
    assert min(behind) > 0.1
    assert max(errors) < 0.02, errors
    host.release()


def test_half_angle_honours_crop_clip_and_weights():
    """Cropping, a clipping plane, zero slice weights each remove the data's half x > 11.5 µm:
    the coverage drops by > 0.25 exactly where the ray caster's pixel changed (none where it
    changed ≤ 8 levels, all where it changed > 100; each within 1 % of the image)."""
    rw, _ren, vol, host = half_angle_scene()
    set_renderer(host, "raycast")
    ray_full = grab(rw).astype(int)
    r = set_renderer(host, "half_angle", samples=1)
    rw.Render()
    full = r.read_result()[::-1, :, 3]
    for name, apply, undo in _modifiers(vol, host):
        apply()
        set_renderer(host, "raycast")
        change = np.abs(grab(rw).astype(int) - ray_full).max(-1)
        r = set_renderer(host, "half_angle", samples=1)
        rw.Render()
        gone = (full - r.read_result()[::-1, :, 3]) > 0.25
        assert (change > 8).mean() > 0.1, name
        assert (gone & ~(change > 8)).mean() < 0.01, name
        assert ((change > 100) & ~gone).mean() < 0.01, name
        undo()
    host.release()


@pytest.mark.parametrize("channels", [2, 3, 4])
def test_half_angle_mixes_independent_channels(channels):
    """1 channel is every test above; 2–4 independent channels, each with its own colour:
    where only channel 0 is present the image is red (G, B < 0.05 of R), where only channel 1
    is, green; GPU = twin within 2e-3 at 4 pixels (the opacity-weighted colour volume)."""
    base = ball(16)
    data = np.stack([np.roll(base, (-4 if c == 0 else 4 if c == 1 else 0), axis=2) * (
        1.0 if c < 2 else 0.3) for c in range(channels)], axis=-1)
    rw, ren, vol = simple_volume_scene(data[..., 0], size=(32, 32))
    needs_compute(rw)
    img = image_from_array(data)
    vol.GetMapper().SetInputData(img)
    prop = vol.GetProperty()
    prop.IndependentComponentsOn()
    import vtk

    for c in range(channels):
        rgb = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0)][c]
        ctf = vtk.vtkColorTransferFunction()
        ctf.AddRGBPoint(0, *rgb)
        ctf.AddRGBPoint(1, *rgb)
        prop.SetColor(c, ctf)
        otf = vtk.vtkPiecewiseFunction()
        otf.AddPoint(0, 0)
        otf.AddPoint(1, 0.5)
        prop.SetScalarOpacity(c, otf)
    host = vtkvol.illuminate(vol, ren, method="local",
                             lights=[vtkvol.Light(direction=(0.0, 0.0, 1.0))])
    r = set_renderer(host, "half_angle", samples=1, light_resolution=32)
    rw.Render()
    assert r.last_error is None and r.classification_reason == "more than one channel"
    res = r.read_result()
    cov = res[..., 3] > 0.05
    red = cov & (res[..., 0] > 20 * np.maximum(res[..., 1], res[..., 2]))
    green = cov & (res[..., 1] > 20 * np.maximum(res[..., 0], res[..., 2]))
    if channels == 2:
        assert red.sum() > 10 and green.sum() > 10
    pixels = [(8, 16), (16, 16), (24, 16), (16, 10)]
    cpu = twin(r, host, pixels, 32)
    gpu = np.array([res[y, x] for x, y in pixels])
    assert np.abs(gpu - cpu).max() < 2e-3
    host.release()


def test_cli_renders_with_half_angle(tmp_path, capsys):
    from PIL import Image

    from vtkvol.cli import main

    out = tmp_path / "ha.png"
    assert main(["render", "sample", "-o", str(out), "--size", "48", "48", "--renderer",
                 "half_angle", "--iterations", "2"]) == 0
    assert np.asarray(Image.open(out), float).std() > 5
    capsys.readouterr()
