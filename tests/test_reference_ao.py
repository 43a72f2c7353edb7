"""Analytic checks of the Monte-Carlo ambient-occlusion reference."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import quad

from vtkvol.reference import ambient_occlusion_mc, phantom_hollow_sphere, voxel_centres


def test_empty_volume_has_no_occlusion() -> None:
    ao = ambient_occlusion_mc(np.zeros((6, 6, 6)), (1, 1, 1), max_distance=5.0, n_rays=8)
    assert ao.shape == (6, 6, 6) and ao.dtype == np.float32
    assert np.all(ao == 0.0)


def test_inside_an_opaque_hollow_sphere_is_fully_occluded() -> None:
    n = 32
    vol = phantom_hollow_sphere(n, thickness=3, opacity=0.99)
    c = (n - 1) / 2
    centre = np.array([[c, c, c], [c + 3.0, c - 2.0, c + 1.0]])
    # Outer radius 0.4·31 = 12.4 µm: with max_distance beyond it every ray crosses the shell
    # (τ ≈ 3 µm · 4.6/µm ≈ 14, T ≈ 1e-6).
    ao = ambient_occlusion_mc(vol, (1, 1, 1), max_distance=16.0, n_rays=64, points=centre)
    assert np.all(ao > 0.999)
    # σ > 0 only from r ≈ 8.9 − √3 ≈ 7.2 µm (anti-aliased inner face, then trilinear
    # interpolation): a 3 µm neighbourhood of points within r < 3.8 sees nothing.
    ao = ambient_occlusion_mc(vol, (1, 1, 1), max_distance=3.0, n_rays=64, points=centre)
    assert np.all(ao == 0.0)


def _half_space_tau(mu: float, sigma0: float, d: float) -> float:
    """Optical depth of a ray leaving z = 12 downwards at cos θ = mu into the half-space z ≤ 11.

    Between z = 12 and 11 the trilinear α ramps linearly from 0 to α₀ = 1 − e^{−σ₀}, so after
    s µm of the ray (depth u = μ·s into the ramp) τ = F(μ·s)/μ with
    F(x) = ∫₀ˣ −ln(1 − α₀u) du = x + (1 − α₀x)·ln(1 − α₀x)/α₀; below z = 11 σ is σ₀. Only the
    first d µm count.
    """
    a = 1.0 - math.exp(-sigma0)

    def ramp(x: float) -> float:
        return x + (1.0 - a * x) * math.log(1.0 - a * x) / a

    if mu * d <= 1.0:
        return ramp(mu * d) / mu
    return ramp(1.0) / mu + sigma0 * (d - 1.0 / mu)


def _half_space_setup() -> tuple[np.ndarray, np.ndarray, float, float]:
    alpha0, d = 0.9, 4.0
    vol = np.zeros((24, 24, 24))
    vol[:12] = alpha0  # solid for z ≤ 11, its face at z = 11; empty above
    xy = np.arange(7.0, 17.0)
    gx, gy = np.meshgrid(xy, xy)
    # Points one voxel above the face, far enough from the box's sides for rays of length d.
    pts = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, 12.0)], axis=1)
    return vol, pts, -math.log(1.0 - alpha0), d


def test_flat_face_of_half_space_uniform_sphere() -> None:
    # Uniform sphere sampling: upward rays see nothing, downward rays see the solid, so the
    # occlusion is (1/2)∫₀¹ (1 − e^{−τ(μ)}) dμ, slightly below 0.5 because rays grazing the
    # face within d·μ < 1 stay in the thin ramp. For α₀ = 0.9, d = 4 µm this is 0.4481.
    vol, pts, sigma0, d = _half_space_setup()
    expected = 0.5 * quad(lambda mu: 1 - math.exp(-_half_space_tau(mu, sigma0, d)), 0, 1)[0]
    assert 0.44 < expected < 0.455
    ao = ambient_occlusion_mc(vol, (1, 1, 1), max_distance=d, n_rays=256, step=0.25, points=pts)
    # 100 points × 256 rays: standard error of the mean ≤ 0.5/160 ≈ 0.003.
    assert abs(ao.mean() - expected) < 0.012
    assert np.all(np.abs(ao - expected) < 0.15)


def test_flat_face_of_half_space_cosine_hemisphere() -> None:
    vol, pts, sigma0, d = _half_space_setup()
    up = np.tile([0.0, 0.0, 1.0], (pts.shape[0], 1))
    ao_up = ambient_occlusion_mc(vol, (1, 1, 1), max_distance=d, n_rays=64, points=pts, normals=up)
    assert np.all(ao_up == 0.0)  # the open hemisphere: no absorber at z ≥ 12
    # Facing the solid: (1/π)∫ (1 − T) cos θ dω = ∫₀¹ (1 − e^{−τ(μ)}) 2μ dμ.
    expected = quad(lambda mu: (1 - math.exp(-_half_space_tau(mu, sigma0, d))) * 2 * mu, 0, 1)[0]
    down = -3.0 * up  # normals need not be unit length
    ao = ambient_occlusion_mc(
        vol, (1, 1, 1), max_distance=d, n_rays=128, step=0.25, points=pts, normals=down
    )
    assert abs(ao.mean() - expected) < 0.01


def test_only_occluders_within_max_distance_count() -> None:
    vol = np.zeros((24, 16, 16))
    vol[14:16] = 0.9  # σ > 0 from z = 13 on
    pt = np.array([[7.5, 7.5, 8.0]])  # 5 µm below the slab's support
    assert ambient_occlusion_mc(vol, (1, 1, 1), max_distance=4.9, n_rays=64, points=pt)[0] == 0.0
    assert ambient_occlusion_mc(vol, (1, 1, 1), max_distance=10.0, n_rays=64, points=pt)[0] > 0.05


def test_seeded_determinism_and_subset_consistency() -> None:
    rng = np.random.default_rng(5)
    vol = rng.uniform(0, 0.5, (8, 9, 10))
    spacing = (1.0, 0.8, 1.2)
    a = ambient_occlusion_mc(vol, spacing, max_distance=3.0, n_rays=16, seed=11)
    b = ambient_occlusion_mc(vol, spacing, max_distance=3.0, n_rays=16, seed=11)
    c = ambient_occlusion_mc(vol, spacing, max_distance=3.0, n_rays=16, seed=12)
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)
    assert np.all((a >= 0) & (a <= 1))
    # A voxel gets the same estimate when evaluated alone via points=.
    flat = np.array([0, 17, 301, 719])
    pts = voxel_centres(vol.shape, spacing)[flat]
    sub = ambient_occlusion_mc(vol, spacing, max_distance=3.0, n_rays=16, seed=11, points=pts)
    np.testing.assert_array_equal(sub, a.ravel()[flat])


def test_normals_field_shape_and_zero_normal_fallback() -> None:
    rng = np.random.default_rng(6)
    vol = rng.uniform(0, 0.5, (5, 6, 7))
    normals = np.zeros((5, 6, 7, 3))
    uniform = ambient_occlusion_mc(vol, (1, 1, 1), max_distance=2.0, n_rays=8)
    with_zero = ambient_occlusion_mc(vol, (1, 1, 1), max_distance=2.0, n_rays=8, normals=normals)
    np.testing.assert_array_equal(uniform, with_zero)
