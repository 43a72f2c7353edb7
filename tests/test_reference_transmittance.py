"""Analytic checks of the CPU transmittance and cone-transmittance references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from vtkvol.reference import (
    DirectionalLight,
    ExtinctionField,
    PointLight,
    cone_transmittance_mc,
    extinction,
    phantom_hollow_sphere,
    phantom_slab,
    transmittance,
    voxel_centres,
)


def test_extinction_matches_opacity_definition() -> None:
    # A slab unit_distance thick with extinction σ transmits exp(−σ·u) = 1 − α.
    a = np.array([0.0, 0.25, 0.5, 0.9])
    sigma = extinction(a, unit_distance=2.0)
    np.testing.assert_allclose(np.exp(-sigma * 2.0), 1.0 - a, rtol=1e-12)
    assert np.isfinite(extinction(np.array([1.0, 1.5]), 1.0)).all()  # clamped below 1
    assert extinction(np.array([-0.5]), 1.0)[0] == 0.0


def test_empty_volume_is_fully_lit() -> None:
    vol = np.zeros((6, 7, 8), dtype=np.float32)
    for light in (DirectionalLight((0.3, -0.2, 1.0)), PointLight((3.0, 2.0, 1.0))):
        t = transmittance(vol, (1.0, 1.0, 1.0), light)
        assert t.shape == vol.shape and t.dtype == np.float32
        assert np.all(t == 1.0)


@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (0.5, 0.8, 2.0)])
def test_homogeneous_volume_along_axis_and_at_45_degrees(spacing: tuple[float, ...]) -> None:
    # Constant α everywhere: σ is exactly constant inside the box, T = exp(−σ·L) with L the
    # path length from the voxel to where the ray leaves the box.
    nz, ny, nx = 10, 6, 12
    alpha = 0.3
    vol = np.full((nz, ny, nx), alpha)
    sigma = -math.log(1.0 - alpha) / min(spacing)
    pts = voxel_centres(vol.shape, spacing).reshape(nz, ny, nx, 3)
    top = (nz - 1) * spacing[2]
    right = (nx - 1) * spacing[0]

    t_axis = transmittance(vol, spacing, DirectionalLight((0.0, 0.0, 5.0)))
    np.testing.assert_allclose(t_axis, np.exp(-sigma * (top - pts[..., 2])), atol=1e-6)

    # 45° in the xz plane: path length = (distance to the first face along the axis) / cos 45°.
    t_45 = transmittance(vol, spacing, DirectionalLight((1.0, 0.0, 1.0)))
    length = np.minimum(top - pts[..., 2], right - pts[..., 0]) * math.sqrt(2.0)
    np.testing.assert_allclose(t_45, np.exp(-sigma * length), atol=1e-6)


@pytest.mark.parametrize("theta_deg", [0.0, 45.0])
def test_thin_slab_obeys_beer_lambert(theta_deg: float) -> None:
    # A slab of n_f voxel layers of opacity α₀. α (not σ) is trilinear, as the ray caster and
    # the camera path tracer sample it: inside the slab σ₀ = −ln(1 − α₀) over n_f − 1 voxels,
    # and on each side a one-voxel ramp where α rises linearly, whose optical depth is
    # ∫₀¹ −ln(1 − α₀s) ds = 1 + (1 − α₀)·ln(1 − α₀)/α₀ (less than σ₀/2: −ln(1 − α) is convex).
    # Along an oblique ray everything is divided by cos θ.
    n, layers, alpha = 40, 3, 0.4
    vol = phantom_slab(n, thickness=layers, axis="z", opacity=alpha)
    sigma0 = -math.log(1.0 - alpha)
    ramp = 1.0 + (1.0 - alpha) * math.log(1.0 - alpha) / alpha
    assert ramp < 0.93 * sigma0 / 2  # the two conventions differ by more than the tolerance
    th = math.radians(theta_deg)
    light = DirectionalLight((math.sin(th), 0.0, math.cos(th)))
    # Points below the slab, far enough from the −x/+x faces that the ray crosses the slab.
    pts = np.array([[5.0, 20.0, 3.0], [12.0, 7.0, 10.0], [8.0, 30.0, 15.0]])
    expected = math.exp(-((layers - 1) * sigma0 + 2.0 * ramp) / math.cos(th))
    np.testing.assert_allclose(
        transmittance(vol, (1, 1, 1), light, points=pts, step=0.1), expected, atol=1e-3
    )
    # Above the slab nothing is in the way.
    above = np.array([[10.0, 10.0, 25.0]])
    assert transmittance(vol, (1, 1, 1), light, points=above)[0] == 1.0


def test_extinction_field_interpolates_opacity_like_the_renderers() -> None:
    # Halfway between a clear voxel and one of α 0.9 the renderers see α 0.45, σ = −ln(0.55)
    # per unit distance (0.598), not the mean of the voxels' σ (−ln(0.1)/2 = 1.151).
    vol = np.zeros((1, 1, 2))
    vol[0, 0, 1] = 0.9
    field = ExtinctionField(vol, (1.0, 1.0, 1.0), unit_distance=2.0)
    s = field.sample(np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(s, [-math.log(0.55) / 2.0, 0.0, -math.log(0.1) / 2.0],
                               rtol=1e-12)
    assert field.majorant == pytest.approx(-math.log(0.1) / 2.0)


def _exit_distance(origin: np.ndarray, direction: np.ndarray, box_max: np.ndarray) -> float:
    t = math.inf
    for a in range(3):
        if direction[a] > 0:
            t = min(t, (box_max[a] - origin[a]) / direction[a])
        elif direction[a] < 0:
            t = min(t, -origin[a] / direction[a])
    return t


def test_random_field_matches_independent_quadrature() -> None:
    # Non-cubic, anisotropic volume: catches any x/z or spacing mix-up. The independent check
    # integrates σ of scipy's trilinear interpolation of α with a fine trapezoid rule.
    rng = np.random.default_rng(1)
    shape = (5, 7, 9)  # z, y, x
    spacing = np.array([0.7, 1.1, 1.6])  # x, y, z
    vol = rng.uniform(0.0, 0.95, shape)
    box_max = (np.array(shape[::-1]) - 1) * spacing
    light = DirectionalLight((0.4, -0.7, 0.6))
    d = np.asarray(light.unit())
    pts = rng.uniform(0.0, 1.0, (6, 3)) * box_max
    got = transmittance(vol, spacing, light, points=pts, step=0.05)
    for p, g in zip(pts, got, strict=True):
        s = np.linspace(0.0, _exit_distance(p, d, box_max), 20001)
        xyz = (p + s[:, None] * d) / spacing
        alpha = map_coordinates(vol, xyz[:, ::-1].T, order=1, mode="nearest")
        samples = extinction(alpha, spacing.min())
        assert g == pytest.approx(math.exp(-np.trapezoid(samples, s)), abs=2e-4)


def test_sphere_occluder_hard_shadow_and_point_light_inside() -> None:
    n = 32
    vol = np.zeros((n, n, n))
    zz, yy, xx = np.indices(vol.shape)
    vol[(xx - 16) ** 2 + (yy - 16) ** 2 + (zz - 20) ** 2 <= 16] = 1.0  # radius 4, opaque
    light = DirectionalLight((0.0, 0.0, 1.0))
    t = transmittance(vol, (1, 1, 1), light)
    assert t[8, 16, 16] < 1e-3  # directly below the sphere
    assert t[8, 16, 26] == 1.0  # beside it: the ray misses the sphere's support entirely
    assert t[28, 16, 16] == 1.0  # above it

    # Point light at the centre of an opaque shell: lit inside, dark outside.
    shell = phantom_hollow_sphere(n, thickness=3, opacity=0.99)
    c = (n - 1) / 2
    t = transmittance(shell, (1, 1, 1), PointLight((c, c, c)))
    assert t[16, 16, 16] == pytest.approx(1.0)
    assert t[16, 16, 20] == pytest.approx(1.0)
    assert t[16, 16, 0] < 1e-3
    assert t[0, 0, 0] < 1e-3
    # A point beyond the light sees only what lies between it and the light.
    pl = PointLight((10.0, 16.0, 16.0))
    t_pts = transmittance(
        vol, (1, 1, 1), pl, points=np.array([[2.0, 16.0, 16.0], [10.0, 16.0, 16.0]])
    )
    assert np.all(t_pts == 1.0)


def test_step_convergence_on_smooth_field() -> None:
    n = 24
    zz, yy, xx = np.indices((n, n, n)).astype(float)
    vol = 0.3 * np.exp(-((xx - 11) ** 2 + (yy - 12) ** 2 + (zz - 13) ** 2) / 30.0)
    light = DirectionalLight((0.3, 0.5, 0.8))
    coarse = transmittance(vol, (1, 1, 1), light, step=0.5)
    fine = transmittance(vol, (1, 1, 1), light, step=0.25)
    assert np.abs(coarse - fine).max() < 1e-3


def test_points_subset_matches_full_volume() -> None:
    rng = np.random.default_rng(2)
    vol = rng.uniform(0, 0.5, (6, 8, 10))
    spacing = (1.0, 0.5, 2.0)
    light = PointLight((3.0, 1.0, 4.0))
    full = transmittance(vol, spacing, light)
    idx = np.array([[0, 0, 0], [5, 7, 9], [2, 3, 4], [1, 6, 8]])  # z, y, x
    pts = idx[:, ::-1] * np.asarray(spacing)
    np.testing.assert_array_equal(
        transmittance(vol, spacing, light, points=pts), full[tuple(idx.T)]
    )


def test_min_distance_skips_self_shadowing() -> None:
    vol = np.full((8, 4, 4), 0.5)
    light = DirectionalLight((0.0, 0.0, 1.0))
    pts = np.array([[1.0, 1.0, 2.0]])
    sigma = -math.log(0.5)
    t = transmittance(vol, (1, 1, 1), light, points=pts, min_distance=1.5)
    assert t[0] == pytest.approx(math.exp(-sigma * (5.0 - 1.5)), abs=1e-6)


def test_extinction_field_is_zero_outside_the_box() -> None:
    field = ExtinctionField(np.full((3, 3, 3), 0.5), (1, 1, 1))
    s = field.sample(np.array([[1.0, 1.0, 1.0], [-0.1, 1.0, 1.0], [1.0, 2.01, 1.0]]))
    assert s[0] > 0 and s[1] == 0 and s[2] == 0


def test_cone_zero_angle_equals_transmittance() -> None:
    rng = np.random.default_rng(3)
    vol = rng.uniform(0, 0.4, (10, 12, 14))
    for light in (DirectionalLight((0.2, 0.3, 1.0)), PointLight((5.0, 20.0, 4.0))):
        hard = transmittance(vol, (1, 1, 1), light)
        cone = cone_transmittance_mc(vol, (1, 1, 1), light, half_angle_deg=0.0, n_rays=4)
        np.testing.assert_allclose(cone, hard, atol=1e-6)


def _penumbra(profile: np.ndarray) -> int:
    return int(np.count_nonzero((profile > 0.1) & (profile < 0.9)))


def test_cone_widens_the_shadow_edge() -> None:
    # An opaque half-plate (x < 16) at z = 20–21 over a receiver line at z = 5, light from +z.
    n = 32
    vol = np.zeros((n, 24, n))  # wide in y so no cone ray leaves through the y faces
    vol[20:22, :, :16] = 0.99
    xs = np.arange(4.0, 28.0, 0.25)
    pts = np.stack([xs, np.full_like(xs, 12.0), np.full_like(xs, 5.0)], axis=1)
    light = DirectionalLight((0.0, 0.0, 1.0))
    widths = []
    for angle in (0.0, 5.0, 15.0):
        t = cone_transmittance_mc(
            vol, (1, 1, 1), light, half_angle_deg=angle, n_rays=256, points=pts
        )
        widths.append(_penumbra(t))
        assert t[0] < 0.05 and t[-1] > 0.95  # deep shadow and full light far from the edge
    assert widths[0] < widths[1] < widths[2]
    # Under the plate's effective edge half the cone is blocked. σ falls linearly from x = 15 to
    # 16, so with σ₀ ≈ 4.6/µm over ~3 µm of plate the hard shadow's T = 0.5 at x ≈ 15.95.
    t15 = cone_transmittance_mc(
        vol,
        (1, 1, 1),
        light,
        half_angle_deg=15.0,
        n_rays=1024,
        points=np.array([[15.95, 12.0, 5.0]]),
    )
    assert t15[0] == pytest.approx(0.5, abs=0.06)
    # Penumbra half-width ≈ h·tan θ = 15.5 µm · tan 15° ≈ 4.2 µm: T is ~0 / ~1 beyond it.
    t15 = cone_transmittance_mc(
        vol,
        (1, 1, 1),
        light,
        half_angle_deg=15.0,
        n_rays=256,
        points=np.array([[10.0, 12.0, 5.0], [21.0, 12.0, 5.0]]),
    )
    assert t15[0] < 0.02 and t15[1] > 0.98


def test_cone_is_seeded_and_deterministic() -> None:
    rng = np.random.default_rng(4)
    vol = rng.uniform(0, 0.4, (8, 8, 8))
    light = DirectionalLight((0.0, 1.0, 1.0))
    a = cone_transmittance_mc(vol, (1, 1, 1), light, half_angle_deg=10.0, n_rays=16, seed=7)
    b = cone_transmittance_mc(vol, (1, 1, 1), light, half_angle_deg=10.0, n_rays=16, seed=7)
    c = cone_transmittance_mc(vol, (1, 1, 1), light, half_angle_deg=10.0, n_rays=16, seed=8)
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)
