"""Translucency (seed 001 eqs. 2.42–2.44): declaration, the direct term against the shadow
volume's transmittance model, the indirect term's RGB extinction on an analytic slab and its
cone blur, GPU/CPU agreement, shading through the RGB hook and the surface factor, recompute
rules and light counts."""

from __future__ import annotations

import math

import numpy as np
import pytest
import vtk

from vtkvol.engine import light_grid as sv
from vtkvol.engine.gl import compute_supported
from vtkvol.engine.illuminator import Illuminator, LightSpec
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.engine.technique import technique_class
from vtkvol.model import Light
from vtkvol.model.techniques import get_spec
from vtkvol.plugins.shadow_volume.technique import ShadowVolume
from vtkvol.plugins.translucency import cpu as tl
from vtkvol.plugins.translucency.technique import Translucency, colour_volume

TINY = (32, 32)


def _directional(d: tuple[float, float, float], size: float = 0.0) -> LightSpec:
    v = np.asarray(d, float) / np.linalg.norm(d)
    return LightSpec("directional", tuple(float(c) for c in v), (1.0, 1.0, 1.0), size=size)


def _blobs() -> np.ndarray:
    nz, ny, nx = 14, 20, 26
    z, y, x = np.mgrid[0:nz, 0:ny, 0:nx].astype(float)
    values = (np.exp(-((x - 9) ** 2 + (y - 8) ** 2 + (z - 9) ** 2) / 12.0)
              + 0.6 * np.exp(-((x - 18) ** 2 + (y - 12) ** 2 + (z - 4) ** 2) / 20.0))
    values[1:3] += 0.35
    return values.astype(np.float32)


def _coloured_scene(size=TINY):
    """Anisotropic blobs whose colour goes from orange (low values) to yellow (high)."""
    rw, ren, volume = simple_volume_scene(_blobs(), spacing=(1.0, 0.8, 2.0),
                                          opacity=[(0.0, 0.0), (1.0, 0.95)], size=size)
    ctf = volume.GetProperty().GetRGBTransferFunction(0)
    ctf.RemoveAllPoints()
    ctf.AddRGBPoint(0.0, 1.0, 0.3, 0.1)
    ctf.AddRGBPoint(1.0, 0.9, 0.8, 0.2)
    return rw, ren, volume


def _require_compute(rw: vtk.vtkRenderWindow) -> None:
    if not compute_supported(rw):
        pytest.skip("this OpenGL context has no compute shaders")


def _volumes(il: Illuminator) -> list[np.ndarray]:
    il.render_window.MakeCurrent()
    return [tex.download() for tex in il.technique.light_textures]


# ------------------------------------------------------------------------------------------------
# Declaration
# ------------------------------------------------------------------------------------------------
def test_declaration_labels_project_defaults_and_declares_rgb_surface_lighting():
    spec = get_spec("translucency")
    assert technique_class("translucency") is Translucency
    assert spec.lighting == "surface" and spec.has("rgb") and spec.has("cpu_path")
    params = {p.name: p for p in spec.parameters}
    for p in params.values():
        assert p.doc and p.label
        assert p.validate(p.default) == p.default
        if p.kind in ("float", "int"):
            assert p.range is not None and p.range[0] <= p.default <= p.range[1]
    # The document gives no values: every such default says it is the project's.
    for name in ("indirect_angle", "indirect_extinction", "tint", "gradient_low",
                 "gradient_high"):
        assert "project default" in params[name].doc.lower(), name
    assert params["indirect_angle"].unit == "°" and params["indirect_angle"].default == 15.0
    assert params["gradient_low"].applies_when == (("surface_factor", ("gradient",)),)
    assert any(b.quick for b in spec.bench) and any(b.quick for b in spec.stability)


# ------------------------------------------------------------------------------------------------
# Direct term = the shadow volume's transmittance model
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("light", [
    _directional((0.3, 0.2, 1.0)),
    _directional((1.0, -0.4, 0.3), size=math.radians(3.0)),  # penumbra from the light's size
    LightSpec("point", (40.0, -6.0, 30.0), (1.0, 1.0, 1.0), size=5.0),
])
@pytest.mark.parametrize("resolution", ["full", "half"])
def test_direct_term_is_the_shadow_volumes_transmittance(light, resolution):
    opacity = np.clip(_blobs(), 0, 1) * 0.95
    colour = np.full((*opacity.shape, 3), 0.5, np.float32)
    spacing = (1.0, 0.8, 2.0)
    vol = tl.translucency_volume_cpu(opacity, colour, spacing, light, resolution=resolution)
    grid = sv.LightGrid.for_data(opacity.shape[::-1], spacing, resolution)
    expected = sv.light_volume_cpu(
        opacity, spacing, light, model="transmittance", resolution=resolution,
        softness=sv.light_softness(light, grid, ShadowVolume.defaults()),
    )
    np.testing.assert_array_equal(vol[..., 3], expected)


# ------------------------------------------------------------------------------------------------
# Indirect term: RGB extinction (analytic slab) and the cone blur
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("angle", [0.0, 30.0])
@pytest.mark.parametrize("deg", [0.0, 35.0])
def test_indirect_term_obeys_its_rgb_extinction_on_a_slab(angle, deg):
    # A slab of uniform opacity α and colour c filling the box; light tilted deg from +z in
    # x–z. Where the ray leaves through the top face, after L = (n−1−z)/cos θ µm:
    # T_i,c = exp(−k·τ·(1 − tint·c_c)·L/u), τ = −ln(1 − α), for every cone angle: blurring a
    # laterally uniform field changes nothing where the side faces are out of reach (the
    # dependence widens by the filter radius R per slice, plus one cell for oblique crossings).
    n, alpha, k, tint, x = 32, 0.3, 0.6, 0.8, 10
    c = np.array([0.9, 0.5, 0.1])
    opacity = np.full((n, n, n), alpha, np.float32)
    colour = np.broadcast_to(c.astype(np.float32), (n, n, n, 3)).copy()
    d = (math.sin(math.radians(deg)), 0.0, math.cos(math.radians(deg)))
    vol = tl.translucency_volume_cpu(opacity, colour, (1, 1, 1), _directional(d), angle=angle,
                                     extinction=k, tint=tint)
    grid = sv.LightGrid.for_data((n, n, n), (1, 1, 1), "full")
    radius = sv.gauss_taps(tl.indirect_softness(_directional(d), grid, angle))[0]
    tau = -math.log(1 - alpha)
    j = n - 1 - np.arange(n)  # slices below the top face
    path = j / math.cos(math.radians(deg))
    reach = (x - radius * j >= 0) & (x + (radius + (deg > 0)) * j + 1 <= n - 1)
    assert reach.sum() >= 10
    for ch in range(3):
        expected = np.exp(-k * tau * (1 - tint * c[ch]) * path)
        got = vol[:, n // 2, x, ch]
        np.testing.assert_allclose(got[reach], expected[reach], rtol=1e-6, err_msg=f"ch {ch}")
    # Red passes furthest: the indirect light turns the material's colour with depth.
    assert vol[0, n // 2, x, 0] > vol[0, n // 2, x, 1] > vol[0, n // 2, x, 2]
    # The direct term is the grey Beer–Lambert law.
    np.testing.assert_allclose(vol[:, n // 2, x, 3][reach],
                               np.exp(-tau * path)[reach], rtol=1e-6)


@pytest.mark.parametrize("angle", [20.0, 45.0])
def test_indirect_shadow_spreads_by_the_cone_per_slice(angle):
    # One opaque voxel column in the top slice, light from +z: below it, 1 − T_i is the
    # occluder convolved once per slice with the cone's Gaussian, so its lateral variance grows
    # by std² = (tan θ / 2)² cells² per slice (the 2σ reach is the cone radius d·tan θ). The
    # direct shadow stays sharp.
    n = 33
    opacity = np.zeros((20, n, n), np.float32)
    opacity[-1, n // 2, n // 2] = 0.99
    colour = np.zeros((20, n, n, 3), np.float32)
    vol = tl.translucency_volume_cpu(opacity, colour, (1, 1, 1), _directional((0, 0, 1)),
                                     angle=angle, extinction=1.0, tint=0.0)

    def variance(shadow: np.ndarray) -> float:
        profile = shadow.sum(axis=0)  # marginal along x
        x = np.arange(n) - n // 2
        return float((profile * x**2).sum() / profile.sum())

    std = 0.5 * math.tan(math.radians(angle))
    v5 = variance(1 - vol[-6, ..., 0])
    v15 = variance(1 - vol[-16, ..., 0])
    assert v15 - v5 == pytest.approx(10 * std**2, rel=1e-4)  # float32 volume
    direct = 1 - vol[:-1, ..., 3]
    assert np.count_nonzero(direct > 1e-6, axis=(1, 2)).max() == 1  # one column, unblurred


def test_indirect_softness_adds_the_cone_to_the_lights_own_penumbra():
    grid = sv.LightGrid.for_data((32, 32, 32), (1, 1, 1), "full")
    ideal = _directional((0, 0, 1))
    extended = _directional((0, 0, 1), size=math.radians(2.0))
    assert tl.indirect_softness(ideal, grid, 0.0) == 0.0
    assert sv.tap_std(tl.indirect_softness(ideal, grid, 30.0)) == pytest.approx(
        0.5 * math.tan(math.radians(30.0)), rel=1e-6)
    own = sv.tap_std(tl.direct_softness(extended, grid))
    assert own > 0
    assert sv.tap_std(tl.indirect_softness(extended, grid, 30.0)) == pytest.approx(
        math.hypot(own, 0.5 * math.tan(math.radians(30.0))), rel=1e-6)


# ------------------------------------------------------------------------------------------------
# GPU path = numpy path; the direct channel = the shadow volume's GPU volume
# ------------------------------------------------------------------------------------------------
AGREEMENT_CASES = [
    ({}, [Light(direction=(0.3, 0.2, 1.0))]),
    ({"indirect_angle": 45.0, "tint": 1.0}, [Light(direction=(1.0, 1.0, 1.0), size=3.0)]),
    ({"resolution": "half"}, [Light(kind="point", position=(60.0, -10.0, 40.0), size=8.0)]),
    ({"indirect_extinction": 2.0}, [Light(direction=(0.2, -1.0, 0.1)),
                                    Light(kind="point", position=(12.3, 7.1, 13.7))]),
    ({"resolution": "quarter", "tint": 0.0},
     [Light(direction=(0, 0, 1)), Light(direction=(1, 0, 0)),
      Light(direction=(0.5, -0.5, 0.5)), Light(direction=(-0.1, 0.1, -1.0))]),
]


@pytest.mark.gl
def test_gpu_and_cpu_paths_agree():
    rw, ren, volume = _coloured_scene()
    il = Illuminator(volume, ren, method="translucency")
    try:
        for params, lights in AGREEMENT_CASES:
            il.set_parameters(**{**Translucency.defaults(), **params})
            il.set_lights(lights)
            rw.Render()
            _require_compute(rw)
            assert il.method == "translucency", il.last_error
            assert il.technique.stats()["backend"] == "gpu"
            gpu = _volumes(il)
            cpu = il.technique.light_volumes_cpu(il.parameters)
            assert len(gpu) == len(cpu) == len(lights)
            for g, c in zip(gpu, cpu, strict=True):
                np.testing.assert_allclose(g, c, atol=1e-5, err_msg=str(params))
                assert np.ptp(c[..., :3]) > 0.05  # there is an indirect shadow to compare
    finally:
        il.release()


@pytest.mark.gl
def test_direct_channel_equals_the_shadow_volume_on_the_gpu_and_in_the_image():
    rw, ren, volume = _coloured_scene(size=(96, 96))
    lights = [Light(direction=(0.4, 0.3, 1.0), size=2.0)]
    il = Illuminator(volume, ren, method="shadow_volume", lights=lights)
    try:
        shadow_image = grab(rw).astype(int)
        rw.MakeCurrent()
        shadow = il.technique.light_texture.download()
        il.set_method("translucency", {"indirect_strength": 0.0, "surface_factor": "binary"})
        image = grab(rw).astype(int)
        assert il.method == "translucency", il.last_error
        np.testing.assert_allclose(_volumes(il)[0][..., 3], shadow, atol=1e-6)
        assert np.abs(image - shadow_image).max() <= 1
    finally:
        il.release()


# ------------------------------------------------------------------------------------------------
# Shading: through vv_light_transmittance_rgb, and Kniss's surface factor
# ------------------------------------------------------------------------------------------------
@pytest.mark.gl
def test_indirect_light_adds_the_materials_colour():
    # A red, translucent blob; with tint 1 its indirect light loses blue and green on the way
    # in, so what the indirect term adds to the image is red.
    rw, ren, volume = _coloured_scene(size=(96, 96))
    ctf = volume.GetProperty().GetRGBTransferFunction(0)
    ctf.RemoveAllPoints()
    ctf.AddRGBPoint(0.0, 1.0, 0.25, 0.25)
    ctf.AddRGBPoint(1.0, 1.0, 0.25, 0.25)
    # A dim light, so that no channel saturates.
    light = Light(direction=(0, -1, 0.3)).model_copy(update={"intensity": 0.3})
    il = Illuminator(volume, ren, method="translucency", lights=[light],
                     parameters={"indirect_strength": 0.0, "tint": 1.0,
                                 "indirect_normalised": False})
    try:
        without = grab(rw).astype(float)
        il.set_parameters(indirect_strength=1.0)
        with_indirect = grab(rw).astype(float)
        assert il.technique.stats()["recomputes"] == 1  # the strength is a uniform
        added = (with_indirect - without).reshape(-1, 3)
        assert added.min() >= -1.0
        lit = added.sum(axis=1) > 10
        assert lit.sum() > 50
        r, g, b = added[lit].mean(axis=0)
        # The albedo's own ratio is 4 : 1; the indirect light's colour raises it further.
        assert r > 4.0 * g and r > 4.0 * b, (r, g, b)
    finally:
        il.release()


@pytest.mark.gl
def test_normalised_light_is_the_irradiance_once_where_nothing_occludes():
    # A nearly transparent volume: T ≈ T_i ≈ 1 everywhere. Normalised, the indirect term
    # changes nothing there (the light is the irradiance once, as with w = 0); eq. 2.44's plain
    # sum doubles the diffuse light.
    rw, ren, volume = simple_volume_scene(_blobs(), spacing=(1.0, 0.8, 2.0), size=(96, 96),
                                          opacity=[(0.0, 0.0), (1.0, 0.02)])
    light = Light(direction=(0.3, -1, 0.4)).model_copy(update={"intensity": 0.4})
    il = Illuminator(volume, ren, method="translucency", lights=[light],
                     parameters={"indirect_strength": 0.0})
    try:
        direct = grab(rw).astype(float)
        il.set_parameters(indirect_strength=1.0)
        normalised = grab(rw).astype(float)
        il.set_parameters(indirect_normalised=False)
        summed = grab(rw).astype(float)
        assert il.method == "translucency", il.last_error
        assert direct.max() > 20  # something is lit
        assert np.abs(normalised - direct).max() <= 2.0
        lit = direct > 10
        assert (summed[lit] / direct[lit]).mean() > 1.4
    finally:
        il.release()


@pytest.mark.gl
def test_surface_factor_spans_the_hosts_binary_rule_and_unoriented_lighting():
    rw, ren, volume = _coloured_scene(size=(96, 96))
    lights = [Light(direction=(1.0, -0.3, 0.2))]
    il = Illuminator(volume, ren, method="translucency", lights=lights,
                     parameters={"surface_factor": "binary"})
    try:
        binary = grab(rw).astype(int)
        # g0 = g1 = 0: S = 1 wherever the gradient is not zero, the host's rule.
        il.set_parameters(surface_factor="gradient", gradient_low=0.0, gradient_high=0.0)
        same = grab(rw).astype(int)
        rw.Render()  # VTK reports the program it built on the frame after the build
        assert il.method == "translucency", il.last_error
        assert "vtkvol<surface_factor.glsl>" in il.fragment_source
        assert np.abs(same - binary).max() <= 1
        # g0 = g1 = 1 (beyond any gradient): S = 0, every sample lit as an unoriented medium
        # (n·l := 1), never darker than with the surface's own orientation.
        il.set_parameters(gradient_low=1.0, gradient_high=1.0)
        unoriented = grab(rw).astype(int)
        assert (unoriented - binary).min() >= -1
        assert unoriented.mean() > binary.mean() + 2.0
        # The default smooth ramp lies between the two.
        il.set_parameters(gradient_low=0.05, gradient_high=0.2)
        ramp = grab(rw).astype(float).mean()
        assert binary.mean() < ramp < unoriented.mean()
        assert il.technique.stats()["recomputes"] == 1  # shading only: nothing recomputed
    finally:
        il.release()


@pytest.mark.gl
def test_up_to_four_lights_and_no_surface_shader_without_shading():
    rw, ren, volume = _coloured_scene()
    il = Illuminator(volume, ren, method="translucency",
                     lights=[Light(direction=(0, 0, 1)), Light(direction=(1, 0, 0)),
                             Light(direction=(0, 1, 0)), Light(direction=(-1, -1, 1))])
    try:
        rw.Render()
        rw.Render()
        assert il.method == "translucency", il.last_error
        assert sorted(il.bound_textures()) == [f"vv_translucency_light{i}" for i in range(4)]
        il.set_lights([Light(direction=(0.2, 0.1, 1))])
        rw.Render()
        rw.Render()
        assert il.method == "translucency", il.last_error
        assert sorted(il.bound_textures()) == ["vv_translucency_light0"]
        assert "#define VV_TL_LIGHTS 1" in il.fragment_source
        # MIP shows no illumination: the surface-factor code (VTK's shaded lighting's Exit tag)
        # is left out instead of failing.
        volume.GetMapper().SetBlendModeToMaximumIntensity()
        rw.Render()
        rw.Render()
        assert il.method == "translucency", il.last_error
        assert "vtkvol<surface_factor.glsl>" not in il.fragment_source
    finally:
        il.release()


# ------------------------------------------------------------------------------------------------
# Recompute rules
# ------------------------------------------------------------------------------------------------
@pytest.mark.gl
def test_recompute_on_light_and_transfer_function_edits_never_on_camera_moves():
    rw, ren, volume = _coloured_scene()
    il = Illuminator(volume, ren, method="translucency", lights=[Light(direction=(0.3, 0, 1))])
    try:
        rw.Render()
        tech = il.technique
        assert tech.stats()["recomputes"] == 1

        def count_after(action) -> int:
            before = tech.stats()["recomputes"]
            action()
            rw.Render()
            rw.Render()
            return tech.stats()["recomputes"] - before

        cam = ren.GetActiveCamera()
        assert count_after(lambda: cam.Azimuth(25)) == 0
        assert count_after(lambda: (cam.Elevation(10), cam.OrthogonalizeViewUp())) == 0
        assert count_after(lambda: cam.Zoom(1.3)) == 0
        assert count_after(lambda: il.set_parameters(indirect_strength=0.5, offset=2.0,
                                                     gradient_low=0.1)) == 0
        assert count_after(lambda: il.set_lights([Light(direction=(0.3, 0, 1),
                                                        color=(1, 0.5, 0.5))])) == 0
        prop = volume.GetProperty()
        before = _volumes(il)[0]
        assert count_after(lambda: prop.GetRGBTransferFunction(0).AddRGBPoint(
            0.5, 0.1, 0.9, 0.1)) == 1
        recoloured = _volumes(il)[0]
        assert np.abs(recoloured[..., :3] - before[..., :3]).max() > 0.02
        np.testing.assert_array_equal(recoloured[..., 3], before[..., 3])  # direct: grey
        assert count_after(lambda: prop.GetScalarOpacity().AddPoint(0.5, 0.2)) == 1
        assert count_after(lambda: il.set_lights([Light(direction=(-0.3, 0.1, 1))])) == 1
        assert count_after(lambda: il.set_parameters(indirect_angle=30.0)) == 1
        assert count_after(lambda: il.set_parameters(indirect_extinction=1.0)) == 1
        assert count_after(lambda: il.set_parameters(resolution="half")) == 1
        # Without tint the colour does not enter the light volume: colour edits are free.
        assert count_after(lambda: il.set_parameters(tint=0.0)) == 1
        assert count_after(lambda: prop.GetRGBTransferFunction(0).AddRGBPoint(
            0.7, 0.9, 0.1, 0.1)) == 0
        assert count_after(lambda: None) == 0
    finally:
        il.release()


@pytest.mark.gl
def test_colour_volume_follows_the_transfer_functions_without_switching_them():
    rw, ren, volume = _coloured_scene()
    il = Illuminator(volume, ren, method="translucency")
    try:
        rw.Render()
        prop = volume.GetProperty()
        assert prop.GetColorChannels(0) == 3  # asking for the colour switched nothing
        colour = colour_volume(il)
        values = np.clip(_blobs(), 0.0, 1.0)
        expected = np.stack([1.0 - 0.1 * values, 0.3 + 0.5 * values, 0.1 + 0.1 * values], -1)
        np.testing.assert_allclose(colour, expected, atol=1e-3)
    finally:
        il.release()


def test_light_visibility_cpu_is_the_direct_term_at_data_resolution():
    _rw, ren, volume = _coloured_scene()
    il = Illuminator(volume, ren, method="translucency")
    try:
        light = _directional((0.3, 0.4, 1.0), size=math.radians(2.0))
        opacity = il.opacity_volume()
        tech = Translucency(il)
        shadow = ShadowVolume(il)
        for res in ("full", "half"):
            got = tech.light_visibility_cpu(opacity, il.spacing, light, {"resolution": res})
            want = shadow.light_visibility_cpu(opacity, il.spacing, light, {"resolution": res})
            assert got.shape == opacity.shape
            np.testing.assert_array_equal(got, want)
    finally:
        il.release()


@pytest.mark.gl
def test_no_gl_leak_over_rebuilds(monkeypatch):
    # Every texture and compute program the technique creates is released with it, also the
    # ones replaced while it was alive (resolution changes reallocate every grid, light-count
    # changes add and drop light volumes).
    from tests_support_gl import GlObjects

    objects = GlObjects(monkeypatch)
    rw, ren, volume = _coloured_scene(size=(16, 16))
    try:
        for cycle in range(2):
            il = Illuminator(volume, ren, method="translucency", lights=[Light()])
            rw.Render()
            for i in range(5):
                il.set_parameters(resolution=("half", "full", "quarter")[(cycle + i) % 3])
                il.set_lights([Light(direction=(0.1 * i, 0.2, 1))] * (1 + (cycle + i) % 4))
                rw.Render()
                assert len(il.bound_textures()) == 1 + (cycle + i) % 4
            held = objects.held()
            assert any(c.kind == "texture" for c in held), "the technique holds its textures"
            il.release()
            assert objects.held() == []
            assert objects.alive_in_gl(rw, held) == []
            rw.Render()
        assert len(objects.created) - len(held) > 20, "the rebuilds really did replace textures"
    finally:
        rw.Finalize()
