"""Analytic checks of the extended-light reference: transmittance averaged over a light's size."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vtkvol.reference import (
    DirectionalLight,
    PointLight,
    extended_transmittance,
    transmittance,
)


def _cloud(seed: int = 3) -> np.ndarray:
    """A smooth random absorber, 12 × 14 × 16 voxels (z, y, x)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, 0.4, size=(12, 14, 16)).astype(np.float32)


@pytest.mark.parametrize("light", [DirectionalLight((0.3, -0.2, 1.0)),
                                   PointLight((4.0, 20.0, 30.0))])
def test_size_zero_is_the_exact_transmittance(light: DirectionalLight | PointLight) -> None:
    alpha = _cloud()
    spacing = (1.0, 1.5, 2.0)
    exact = transmittance(alpha, spacing, light, step=0.5)
    np.testing.assert_array_equal(
        extended_transmittance(alpha, spacing, light, size=0.0, step=0.5), exact)


def test_samples_are_seeded_and_independent_of_batching() -> None:
    alpha = _cloud()
    light = DirectionalLight((0.0, 0.4, 1.0))
    pts = np.array([[3.0, 4.0, 2.0], [10.0, 2.0, 1.0], [7.5, 6.0, 3.0]])
    together = extended_transmittance(alpha, (1, 1, 1), light, size=10.0, points=pts)
    alone = extended_transmittance(alpha, (1, 1, 1), light, size=10.0, points=pts[1:2])
    assert together[1] == alone[0]
    again = extended_transmittance(alpha, (1, 1, 1), light, size=10.0, points=pts)
    np.testing.assert_array_equal(together, again)
    other = extended_transmittance(alpha, (1, 1, 1), light, size=10.0, points=pts, seed=1)
    assert not np.array_equal(together, other)


def test_slab_average_over_the_cone_matches_the_numeric_integral() -> None:
    # Uniform extinction filling a wide box: from a point d µm below the top, a ray at θ from
    # the vertical leaves through the top after d/cos θ µm, so T(θ) = exp(−σ·d/cos θ). Averaged
    # uniformly in solid angle over a cone of radius ρ, cos θ is uniform on [cos ρ, 1].
    alpha = np.full((17, 48, 48), 0.15, np.float32)
    spacing = (1.0, 1.0, 1.0)
    light = DirectionalLight((0.0, 0.0, 1.0))
    pt = np.array([[23.5, 23.5, 2.0]])
    tau0 = -math.log(float(transmittance(alpha, spacing, light, step=0.25, points=pt)[0]))
    for radius in (5.0, 20.0):
        cos_max = math.cos(math.radians(radius))
        c = np.linspace(cos_max, 1.0, 20001)
        expected = float(np.trapezoid(np.exp(-tau0 / c), c) / (1.0 - cos_max))
        got = float(extended_transmittance(alpha, spacing, light, size=radius, n_rays=64,
                                           step=0.25, points=pt)[0])
        # Stratified samples: the error is far below Monte Carlo's 0.5/√64 = 0.06.
        assert got == pytest.approx(expected, abs=2e-3)
        assert got < float(np.exp(-tau0))  # slanted rays cross more absorber


def _disc_fraction(s: np.ndarray) -> np.ndarray:
    """Fraction of a unit disc on the far side of a line at signed distance −s from its centre
    (s > 0: the centre is past the edge, more than half the disc uncovered)."""
    s = np.clip(s, -1.0, 1.0)
    return 0.5 + (s * np.sqrt(1.0 - s * s) + np.arcsin(s)) / math.pi


def _crossing(xs: np.ndarray, values: np.ndarray, level: float) -> float:
    """x where the rising profile ``values`` first reaches ``level`` (linear between samples;
    np.interp needs strictly increasing values, and a shadow profile has flat tails)."""
    i = int(np.argmax(values >= level))
    assert i > 0, "the profile starts above the level"
    v0, v1 = float(values[i - 1]), float(values[i])
    return float(xs[i - 1] + (level - v0) / (v1 - v0) * (xs[i] - xs[i - 1]))


def test_penumbra_behind_an_edge_widens_with_distance_times_tan_radius() -> None:
    # An opaque half-plane (x < 47.5 µm, three voxel layers at z = 59–61 µm: one layer of α
    # 0.999 with interpolated α on both sides transmits 13 %), the light straight above
    # with angular radius ρ. At depth D below it the light's disc, seen from the point, is cut
    # by the edge; its projection on the plane has radius r = D·tan ρ, so T(x) is the disc's
    # uncovered fraction at (x − edge)/r: the penumbra is 2·D·tan ρ wide.
    nz, nx, z_edge = 64, 96, 60
    alpha = np.zeros((nz, 24, nx), np.float32)
    alpha[z_edge - 1:z_edge + 2, :, :48] = 0.999
    light = DirectionalLight((0.0, 0.0, 1.0))
    xs = np.arange(24.0, 72.0, 0.25)

    def row(depth: float) -> np.ndarray:
        return np.stack([xs, np.full_like(xs, 11.5), np.full_like(xs, z_edge - depth)], 1)

    hard = transmittance(alpha, (1, 1, 1), light, step=0.25, points=row(30.0))
    edge = _crossing(xs, hard, 0.5)  # where the voxel grid puts the hard edge
    assert edge == pytest.approx(47.5, abs=0.5)
    widths = {}
    for radius_deg, depth in ((12.0, 20.0), (12.0, 40.0), (24.0, 20.0)):
        got = extended_transmittance(alpha, (1, 1, 1), light, size=radius_deg, n_rays=128,
                                     step=0.25, points=row(depth))
        r = depth * math.tan(math.radians(radius_deg))
        # The grid blurs the edge by about a voxel, small against r ≥ 4 µm.
        np.testing.assert_allclose(got, _disc_fraction((xs - edge) / r), atol=0.05)
        lo, hi = _crossing(xs, got, 0.1), _crossing(xs, got, 0.9)
        widths[(radius_deg, depth)] = hi - lo
    assert widths[(12.0, 40.0)] / widths[(12.0, 20.0)] == pytest.approx(2.0, rel=0.1)
    ratio_tan = math.tan(math.radians(24.0)) / math.tan(math.radians(12.0))
    assert widths[(24.0, 20.0)] / widths[(12.0, 20.0)] == pytest.approx(ratio_tan, rel=0.1)


def test_point_light_disc_softens_and_keeps_the_unoccluded_value() -> None:
    # Empty volume: every point of the disc is visible, T = 1 whatever the size.
    empty = np.zeros((8, 8, 8), np.float32)
    light = PointLight((3.5, 3.5, 30.0))
    np.testing.assert_array_equal(
        extended_transmittance(empty, (1, 1, 1), light, size=4.0, n_rays=16), 1.0)
    # A point on the axis straight under a small opaque blocker: hard shadow 0; a disc light
    # much larger than the blocker is seen past it, so T rises towards 1.
    alpha = np.zeros((16, 16, 16), np.float32)
    alpha[10:12, 7:9, 7:9] = 0.999
    light = PointLight((7.5, 7.5, 15.0))
    pt = np.array([[7.5, 7.5, 2.0]])
    assert transmittance(alpha, (1, 1, 1), light, points=pt)[0] < 1e-3
    soft = extended_transmittance(alpha, (1, 1, 1), light, size=12.0, n_rays=256, points=pt)[0]
    assert 0.6 < soft < 1.0


def test_bad_size_is_refused() -> None:
    with pytest.raises(ValueError, match="light size"):
        extended_transmittance(np.zeros((2, 2, 2), np.float32), (1, 1, 1),
                               DirectionalLight((0, 0, 1)), size=-1.0)
