"""The object-space reference without its grid (vtkvol.reference.medium_pixels) and the
post-classified extinction field it samples (vtkvol.reference.raymarch.ExtinctionField with a
transfer function): exact answers where the integral is known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vtkvol.reference import DirectionalLight, transmittance
from vtkvol.reference.medium_pixels import medium_radiance, pixel_rays, reference_lights
from vtkvol.reference.raymarch import ExtinctionField


def test_post_classified_field_classifies_after_interpolating():
    """Data 0 | 1 along x and a TF that is 0 up to 0.4 and 0.8 from 0.6 on: at a quarter of the
    way (data 0.25) α = TF(0.25) = 0 where the classified α interpolated gives 0.2, halfway
    both give 0.4, at three quarters TF gives 0.8 against 0.6. The majorant bounds σ
    everywhere; a TF out of order is refused."""
    data = np.zeros((2, 2, 2))
    data[:, :, 1] = 1.0
    tf = [(0.0, 0.0), (0.4, 0.0), (0.6, 0.8), (1.0, 0.8)]
    post = ExtinctionField(data, (1.0, 1.0, 1.0), 1.0, transfer=tf)
    pre = ExtinctionField(post.alpha, (1.0, 1.0, 1.0), 1.0)
    pts = np.array([[0.25, 0.5, 0.5], [0.5, 0.5, 0.5], [0.75, 0.5, 0.5]])
    want = [0.0, -math.log(0.6), -math.log(0.2)]
    assert np.allclose(post.sample(pts), want, atol=1e-12)
    assert pre.sample(pts)[0] == pytest.approx(-math.log(0.8))
    many = np.random.default_rng(0).random((2000, 3))
    assert post.sample(many).max() <= post.majorant + 1e-12
    assert post.majorant == pytest.approx(-math.log(0.2))
    with pytest.raises(ValueError, match="increasing value"):
        ExtinctionField(data, (1.0, 1.0, 1.0), 1.0, transfer=[(1.0, 0.5), (0.0, 0.1)])


def test_a_post_classified_field_goes_through_the_reference_functions():
    """transmittance() takes a prepared field: a homogeneous post-classified cube (data 0.5,
    TF 0.5 → α 0.3) transmits (0.7)^distance towards +x, exactly (the midpoint rule is exact
    for a constant σ)."""
    field = ExtinctionField(np.full((6, 6, 6), 0.5), (1.0, 1.0, 1.0), 1.0,
                            transfer=[(0.0, 0.0), (1.0, 0.6)])
    pts = np.array([[1.0, 2.0, 3.0], [4.0, 1.0, 1.0]])
    t = transmittance(field, (1.0, 1.0, 1.0), DirectionalLight((1.0, 0.0, 0.0)), points=pts)
    assert np.allclose(t, 0.7 ** (5.0 - pts[:, 0]), rtol=1e-6)


def test_medium_radiance_is_exact_where_the_shading_is_constant_along_the_ray():
    """A homogeneous cube of α 0.4 per voxel, rays parallel to z, a light from +x: along each
    ray the shading a·(k_a + T(x)) is constant, so the stratified estimate equals
    a·(k_a + T(x))·(1 − 0.6^length) for any random draw (to the marched τ's rounding)."""
    n = 9
    field = ExtinctionField(np.full((n, n, n), 0.4), (1.0, 1.0, 1.0), 1.0)
    xs = np.array([0.5, 3.25, 7.9])
    o = np.c_[xs, np.full(3, 4.0), np.full(3, -5.0)]
    d = np.tile([0.0, 0.0, 1.0], (3, 1))
    lights = reference_lights([("directional", (1.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.0, 0.0)])
    got = medium_radiance(field, o, d, lights, albedo=0.8, ambient=0.3, orders="single",
                          seed=3)
    T = 0.6 ** (n - 1 - xs)
    want = 0.8 * (0.3 + T) * (1.0 - 0.6 ** (n - 1))
    assert np.allclose(got, want[:, None], rtol=1e-5), (got[:, 0], want)


def test_medium_radiance_along_the_light_matches_the_closed_form():
    """Camera ray and light both travel +z through a cube of σ per unit length, entering at
    the same face: at depth s the light's transmittance and the camera's are both e^{−σ s},
    so
    L = a·∫₀^ℓ σ e^{−2σs} ds = a·(1 − e^{−2σℓ})/2. The estimator samples a non-constant
    shading here; 64 points per ray on 32 rays bring it within 0.3 %."""
    n = 9
    field = ExtinctionField(np.full((n, n, n), 0.4), (1.0, 1.0, 1.0), 1.0)
    o = np.tile([4.0, 4.0, -3.0], (32, 1))
    d = np.tile([0.0, 0.0, 1.0], (32, 1))
    lights = reference_lights([("directional", (0.0, 0.0, -1.0), (1.0, 1.0, 1.0), 0.0, 0.0)])
    got = medium_radiance(field, o, d, lights, albedo=1.0, orders="single",
                          emission_points=64, seed=1).mean(axis=0)
    sigma = -math.log(0.6)
    want = (1.0 - math.exp(-2.0 * sigma * (n - 1))) / 2.0
    assert np.allclose(got, want, rtol=3e-3), (got, want)


def test_pixel_rays_are_stratified_in_the_pixel():
    """Orthographic NDC → data (x, y scaled by 10): 3 × 3 rays per pixel land one in each
    third of the pixel, parallel, and with the requested origin subtracted."""
    m = np.diag([10.0, 10.0, 10.0, 1.0])
    o, d = pixel_rays(m, (4, 4), np.array([[1, 2]]), 3, np.random.default_rng(0),
                      origin=(1.0, 0.0, 0.0))
    assert o.shape == (9, 3) and np.allclose(d, [0.0, 0.0, 1.0])
    frag = (o[:, :2] + [1.0, 0.0]) / 10.0 * 2.0 + 2.0  # back to window pixels (w = h = 4)
    cells = np.floor((frag - [1.0, 2.0]) * 3).astype(int)
    assert sorted(map(tuple, cells)) == [(i, j) for i in range(3) for j in range(3)]


def test_bad_inputs_of_the_pointwise_reference_are_refused_in_one_sentence():
    """Non-finite data under a TF, an unknown order, a budget count below 1 and a camera that
    sees no medium: each a ValueError naming what is wrong."""
    from vtkvol.bench.pointwise import PointwiseBudget, compare

    data = np.zeros((2, 2, 2))
    data[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="the data must be finite"):
        ExtinctionField(data, (1.0, 1.0, 1.0), 1.0, transfer=[(0.0, 0.0), (1.0, 0.5)])
    field = ExtinctionField(np.full((3, 3, 3), 0.2), (1.0, 1.0, 1.0), 1.0)
    with pytest.raises(ValueError, match="orders 'double'"):
        medium_radiance(field, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), [],
                        albedo=0.5, orders="double")
    with pytest.raises(ValueError, match="rays must be at least 1, not 0"):
        PointwiseBudget(rays=0)
    empty = np.zeros((4, 4, 4))
    with pytest.raises(ValueError, match="the camera sees no medium"):
        compare(None, {}, empty, empty, "single")  # type: ignore[arg-type]
