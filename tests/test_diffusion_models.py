"""The two diffusion models of the grid-diffusion techniques (issue 24): the source model
against the Monte-Carlo multiple-scattering reference, positivity, monotone convergence, the
warm start of KD's direct light and point-light fall-off."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.engine import diffusion as D
from vtkvol.plugins.convection_diffusion import cpu as kd
from vtkvol.plugins.hybrid_diffusion import cpu as hd

N = 20
LIGHT_TOWARDS = (0.3, 0.2, 1.0)  # oblique: no axis-aligned shortcut for the convection
RGB_AS_LIGHTS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def ball(alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """A homogeneous ball of radius 7 voxels (1 µm) in a 20³ box: (opacity, inside mask)."""
    z, y, x = np.mgrid[:N, :N, :N]
    inside = np.sqrt((x - 9.5) ** 2 + (y - 9.5) ** 2 + (z - 9.5) ** 2) <= 7.0
    return np.where(inside, alpha, 0.0).astype(np.float32), inside


def light() -> D.LightSource:
    d = np.asarray(LIGHT_TOWARDS) / np.linalg.norm(LIGHT_TOWARDS)
    return D.LightSource("directional", tuple(float(c) for c in d))


def kd_scattered(opacity: np.ndarray, albedo: float, tolerance: float = 1e-5) -> np.ndarray:
    """KD source model (numpy path) run to ``tolerance``: ρ_s (R channel)."""
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=albedo, mapping="matched",
                                          convection_extinction="total", unit_distance=1.0)
    t = kd.Transport(grid, [light()], [(1.0, 1.0, 1.0)], sigma_a,
                     D.diffusion_rate(sigma_t, grid, albedo), model="source",
                     coefficients=D.source_coefficients(sigma_t, grid, albedo))
    while t.residual > tolerance:
        t.step()
    return t.rho_s[..., 0]


_DIRECT: dict[tuple[bytes, int, int], np.ndarray] = {}


def hd_direct(opacity: np.ndarray, samples: int, seed: int = 0) -> np.ndarray:
    """HD's running mean of ``samples`` ratio-tracking samples, ``[z, y, x, 3]`` (cached: the
    numpy tracker is the slow part of these tests)."""
    key = (opacity.tobytes(), samples, seed)
    if key in _DIRECT:
        return _DIRECT[key]
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    mean = np.zeros((*opacity.shape, 3), np.float32)
    for k in range(samples):
        draw = hd.direct_sample(sigma_t, grid, [light()], [(1.0, 1.0, 1.0)], iteration=k,
                                seed=seed, estimator="ratio", light_sampling="all")
        mean += (draw - mean) / np.float32(k + 1)
    _DIRECT[key] = mean
    return mean


def hd_scattered(opacity: np.ndarray, albedo: float, samples: int = 16) -> np.ndarray:
    """HD source model: the solve from the tracked direct light (R channel)."""
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    k = D.source_coefficients(D.extinction(opacity, 1.0), grid, albedo)
    q = D.source_term(k, np.moveaxis(hd_direct(opacity, samples), -1, 0), RGB_AS_LIGHTS,
                      [1.0] * 3)
    phi, _ = D.solve_source(q, k, grid, tolerance=1e-5)
    return phi[..., 0]


@pytest.fixture(scope="module")
def reference() -> dict[float, tuple[np.ndarray, np.ndarray]]:
    """Per ball opacity: (sample voxels [n, 3] zyx, MC in-scattered light at albedo 0.5 and 0.9
    [n, 2]) — 160 voxels, 96 paths of up to 64 bounces each (the audit's reference setting)."""
    from vtkvol.reference import inscattered_mc
    from vtkvol.reference.lights import DirectionalLight

    out = {}
    for alpha in (0.5, 0.75):  # 0.75 = twice the extinction of 0.5
        opacity, inside = ball(alpha)
        voxels = np.argwhere(inside)
        voxels = voxels[np.random.default_rng(1).choice(len(voxels), 160, replace=False)]
        mc = inscattered_mc(opacity, (1.0, 1.0, 1.0), DirectionalLight(LIGHT_TOWARDS),
                            albedo=(0.5, 0.9, 0.9), n_paths=96, max_bounces=64, seed=3,
                            unit_distance=1.0, points=voxels[:, ::-1].astype(float))
        out[alpha] = (voxels, mc[:, :2].astype(np.float64))
    return out


METHODS = {"KD": kd_scattered, "HD": hd_scattered}


@pytest.mark.parametrize("method", sorted(METHODS))
def test_the_albedo_ratio_of_scattered_light_matches_the_reference(method, reference):
    voxels, mc = reference[0.5]
    opacity, _ = ball(0.5)
    at = {a: METHODS[method](opacity, a)[tuple(voxels.T)].mean() for a in (0.5, 0.9)}
    ref_ratio = mc[:, 1].mean() / mc[:, 0].mean()  # about 4.3
    assert at[0.9] / at[0.5] == pytest.approx(ref_ratio, rel=0.2)
    # and the level itself is the reference's within 35 % (the diffusion approximation's and,
    # for KD, the convected direct light's error)
    assert at[0.5] == pytest.approx(mc[:, 0].mean(), rel=0.35)
    assert at[0.9] == pytest.approx(mc[:, 1].mean(), rel=0.35)


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("albedo", [0.5, 0.9])
def test_doubling_the_extinction_changes_scattered_light_as_the_reference_does(method, albedo,
                                                                             reference):
    column = 0 if albedo == 0.5 else 1
    ratios = {}
    for alpha in (0.5, 0.75):
        voxels, mc = reference[alpha]
        value = METHODS[method](ball(alpha)[0], albedo)[tuple(voxels.T)].mean()
        ratios[alpha] = (value, mc[:, column].mean())
    method_ratio = ratios[0.75][0] / ratios[0.5][0]
    ref_ratio = ratios[0.75][1] / ratios[0.5][1]  # 0.63 at albedo 0.5
    assert ref_ratio < 0.75 and method_ratio < 0.75  # denser: less scattered light reaches in
    # HD (exact direct light) follows the reference within 15 %; KD within 35 %: its convected
    # direct light smears the oblique beam more in the denser ball. Both grids hold σ per
    # voxel; the reference's medium interpolates α as the renderers draw it, thinner in the
    # hard-edged ball's outer shell (measured at albedo 0.5: reference 0.625, HD 0.542 = −13 %,
    # KD 0.427 = −32 %; against the σ-interpolated reference they were within 10 % / 30 %).
    assert method_ratio == pytest.approx(ref_ratio, rel=0.15 if method == "HD" else 0.35)


def test_source_sweeps_rise_monotonically_to_the_solution_and_stop_on_the_residual():
    opacity, inside = ball(0.5)
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    k = D.source_coefficients(D.extinction(opacity, 1.0), grid, 0.9)
    q = D.source_term(k, np.moveaxis(hd_direct(opacity, 4), -1, 0), RGB_AS_LIGHTS, [1.0] * 3)
    solution, sweeps = D.solve_source(q, k, grid, tolerance=1e-6)
    phi = np.zeros_like(q)
    errors = []
    for _ in range(sweeps):
        new, r2, q2 = D.jacobi_sweep(phi, q, k, grid)
        assert np.all(new >= phi - 1e-7)  # every voxel rises towards its limit
        phi = new
        errors.append(np.sqrt(((phi - solution)[inside] ** 2).mean()))
    assert np.all(np.diff(errors) <= 1e-7)  # the error never rises
    loose, loose_sweeps = D.solve_source(q, k, grid, tolerance=1e-2)
    assert 0 < loose_sweeps < sweeps / 3  # the tolerance, not a count, ends the solve
    _, r2, q2 = D.jacobi_sweep(loose, q, k, grid)
    assert D.relative_residual(r2, q2) < 1e-2


def stress_cases() -> list[tuple[str, np.ndarray, tuple[float, float, float], D.LightSource]]:
    """Cases where the old scattered light went negative: a point light inside the medium,
    noisy opacity, anisotropic voxels, an opaque block lit along the diagonal."""
    rng = np.random.default_rng(7)
    opacity, _ = ball(0.5)
    noisy = np.clip(opacity * (1.0 + 0.6 * rng.standard_normal(opacity.shape)), 0, 0.99)
    block = np.zeros((12, 12, 12), np.float32)
    block[3:9, 3:9, 3:9] = 0.999
    return [
        ("point light inside", opacity, (1.0, 1.0, 1.0), D.LightSource("point", (9.5, 9.5, 9.5))),
        ("noisy opacity", noisy.astype(np.float32), (1.0, 1.0, 1.0), light()),
        ("anisotropic z 10x", opacity, (1.0, 1.0, 10.0), light()),
        ("opaque block, diagonal", block, (1.0, 1.0, 1.0),
         D.LightSource("directional", (0.577, 0.577, 0.577))),
    ]


@pytest.mark.parametrize("case", range(4), ids=[c[0] for c in stress_cases()])
@pytest.mark.parametrize("model", ["source", "published"])
def test_kd_scattered_light_is_never_negative(case, model):
    _name, opacity, spacing, source = stress_cases()[case]
    grid = D.Grid(opacity.shape, spacing)
    sigma_t = D.extinction(opacity, 1.0)
    sigma_a = kd.absorption_per_iteration(
        sigma_t, grid, albedo=0.9, mapping="matched",
        convection_extinction="total" if model == "source" else "paper", unit_distance=1.0)
    t = kd.Transport(grid, [source], [(1.0, 1.0, 1.0)], sigma_a,
                     D.diffusion_rate(sigma_t, grid, 0.9), model=model,
                     coefficients=D.source_coefficients(sigma_t, grid, 0.9))
    for _ in range(8):
        t.step(16)
        assert t.rho_s.min() >= 0.0 and t.rho.min() >= 0.0
    assert t.rho.max() > 0.1  # light arrived


@pytest.mark.parametrize("case", range(4), ids=[c[0] for c in stress_cases()])
def test_hd_source_scattered_light_is_never_negative_even_from_few_noisy_samples(case):
    _name, opacity, spacing, source = stress_cases()[case]
    grid = D.Grid(opacity.shape, spacing)
    sigma_t = D.extinction(opacity, 1.0)
    k = D.source_coefficients(sigma_t, grid, 0.9)
    mean = np.zeros((*opacity.shape, 3), np.float32)
    phi = np.zeros_like(mean)
    for it in range(4):  # HD's loop: one sample, then sweeps from the running mean
        draw = hd.direct_sample(sigma_t, grid, [source], [(1.0, 1.0, 1.0)], iteration=it,
                                seed=0, estimator="delta", light_sampling="all")
        mean += (draw - mean) / np.float32(it + 1)
        q = D.source_term(k, np.moveaxis(mean, -1, 0), RGB_AS_LIGHTS, [1.0] * 3)
        for _ in range(8):
            phi, _, _ = D.jacobi_sweep(phi, q, k, grid)
            assert phi.min() >= 0.0
    assert phi.max() > 1e-3


def test_point_light_falloff_scales_hd_direct_light_and_the_source_term():
    from vtkvol.reference import transmittance
    from vtkvol.reference.lights import PointLight

    opacity, _ = ball(0.3)
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    position, d0 = (9.5, 9.5, 30.0), 20.5  # above the box; d0 = distance to the centre
    lamp = D.LightSource("point", position, falloff_distance=d0)
    bare = D.LightSource("point", position)
    means = {}
    for source in (lamp, bare):
        mean = np.zeros((*opacity.shape, 3), np.float32)
        for k in range(16):
            draw = hd.direct_sample(sigma_t, grid, [source], [(1.0, 1.0, 1.0)], iteration=k,
                                    seed=1, estimator="ratio", light_sampling="all")
            mean += (draw - mean) / np.float32(k + 1)
        means[source] = mean[..., 0]
    f = D.falloff(grid, lamp)
    assert isinstance(f, np.ndarray) and f.max() / f.min() > 3.0  # a real fall-off here
    # Same random streams: the fall-off is exactly a factor (d0/r)² on every sample.
    np.testing.assert_allclose(means[lamp], means[bare] * f, rtol=1e-5, atol=1e-7)
    # and the estimate is the exact transmittance × fall-off (unbiased: the mean ratio over the
    # lit voxels is 1 within the noise of 16 samples)
    exact = transmittance(opacity, (1.0, 1.0, 1.0), PointLight(position), unit_distance=1.0)
    lit = exact > 0.2
    assert np.mean(means[lamp][lit] / (exact * f)[lit]) == pytest.approx(1.0, abs=0.02)
    # KD: the direct light is the host's visibility (the host applies the fall-off when it
    # shades); the scattered light's source carries it: q = σ_s·F·ρ.
    k = D.source_coefficients(sigma_t, grid, 0.8)
    rho = np.ones((1, *opacity.shape), np.float32)
    q = D.source_term(k, rho, [(1.0, 1.0, 1.0)], [f])
    np.testing.assert_allclose(q[..., 1], k[..., 2] * f, rtol=1e-6)


@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (1.0, 0.5, 2.0)])
def test_one_propagation_pass_is_the_converged_convection(spacing):
    """KD's warm start: nx + ny + nz steady sweeps equal the time-stepped convection run to
    convergence (directional and point light)."""
    opacity, _ = ball(0.6)
    grid = D.Grid(opacity.shape, spacing)
    sigma_t = D.extinction(opacity, 1.0)
    sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=0.5, mapping="matched",
                                          convection_extinction="total", unit_distance=1.0)
    for source in (light(), D.LightSource("point", (6.0, 4.0, 12.0))):
        u = D.propagation(grid, source)
        mask = D.source_mask(grid, source)
        warm = np.zeros(grid.shape_zyx, np.float32)
        for _ in range(D.propagation_sweeps(grid)):
            warm = D.steady_convection_sweep(warm, sigma_a, u, grid, mask)
        stepped = np.zeros_like(warm)
        for _ in range(12 * kd.iterations_to_cross(grid)):
            stepped = kd.convection_step(stepped, sigma_a, u, grid, mask)
        np.testing.assert_allclose(warm, stepped, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("kind", ["directional", "point"])
def test_kd_direct_light_of_a_sized_light_follows_the_exact_average_over_its_extent(kind):
    """KD (source model) with a sized light against the exact transmittance averaged over the
    light's extent (48 ideal lights spread uniformly over the cone / sphere): as close as KD's
    ideal light is to the exact ideal transmittance, while the sized and ideal truths differ by
    more than that — a KD that ignored the size would fail."""
    from vtkvol.reference import transmittance
    from vtkvol.reference.lights import DirectionalLight, PointLight

    opacity, _ = ball(0.5)
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=0.5, mapping="matched",
                                          convection_extinction="total", unit_distance=1.0)
    rng = np.random.default_rng(0)
    n = 48
    u1 = (np.arange(n) + rng.random(n)) / n
    phi = 2 * np.pi * rng.random(n)
    if kind == "directional":
        axis, size = np.asarray(light().vector), 0.45
        dirs = hd.around(axis.astype(np.float32),
                         (1.0 - u1 * (1.0 - np.cos(size))).astype(np.float32),
                         phi.astype(np.float32)).T.astype(np.float64)
        ideal_truth = [DirectionalLight(tuple(axis))]
        sized_truth = [DirectionalLight(tuple(d)) for d in dirs]
        vector = tuple(float(c) for c in axis)
    else:
        centre, size = np.array([9.5, 9.5, 26.0]), 6.0
        offsets = hd.around(np.array([0, 0, 1], np.float32), (1.0 - 2.0 * u1).astype(np.float32),
                            phi.astype(np.float32)).T.astype(np.float64)
        ideal_truth = [PointLight(tuple(centre))]
        sized_truth = [PointLight(tuple(centre + size * o)) for o in offsets]
        vector = tuple(float(c) for c in centre)

    def exact(lights) -> np.ndarray:
        return np.mean([transmittance(opacity, (1.0, 1.0, 1.0), lt, unit_distance=1.0)
                        for lt in lights], axis=0)

    def kd_direct(s: float) -> np.ndarray:
        t = kd.Transport(grid, [D.LightSource(kind, vector, size=s)], [(1.0, 1.0, 1.0)],
                         sigma_a, D.diffusion_rate(sigma_t, grid, 0.5), model="source",
                         coefficients=D.source_coefficients(sigma_t, grid, 0.5))
        return t.rho[0]

    ideal_ref, sized_ref = exact(ideal_truth), exact(sized_truth)
    # KD's upwind convection has an error of its own against the exact ideal transmittance (a
    # bias and a blur along the light: ~0.04 mean here, as large as the size's effect), so the
    # size is compared as a change: KD(sized) − KD(ideal) against the truth's change. Measured
    # (directional / point): correlation 0.68 / 0.71, KD's change 0.55 / 0.48× the truth's —
    # its convection already blurs ideal shadows part of the way.
    kd_change = kd_direct(size) - kd_direct(0.0)
    true_change = sized_ref - ideal_ref
    correlation = np.corrcoef(kd_change.ravel(), true_change.ravel())[0, 1]
    ratio = np.abs(kd_change).mean() / np.abs(true_change).mean()
    assert np.abs(true_change).max() > 0.05  # the size matters in this scene
    assert correlation > 0.6
    assert 0.4 < ratio < 1.25


@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (1.0, 0.5, 2.0)])
def test_kd_source_direct_light_is_the_exact_transmittance_at_oblique_faces(spacing):
    """Issue 24's error split: KD's direct light was the upwind convection's steady state,
    smeared across shadow edges oblique to the grid (max error 0.24 here, 4–8 dB of KD's image
    error). The source model ray-marches it: within 0.02 of the exact transmittance (a fine
    march of the same interpolated opacity) at every voxel of a ball lit obliquely, directional
    and point light, anisotropic voxels included."""
    from vtkvol.plugins.convection_diffusion.technique import Setup
    from vtkvol.reference import transmittance
    from vtkvol.reference.lights import DirectionalLight, PointLight

    opacity, _ = ball(0.5)
    grid = D.Grid(opacity.shape, spacing)
    sigma_t = D.extinction(opacity, 1.0)
    d = light().vector
    for source, truth in ((light(), DirectionalLight(d)),
                          (D.LightSource("point", (26.0, 4.0, 30.0)),
                           PointLight((26.0, 4.0, 30.0)))):
        setup = Setup.build(grid, sigma_t, [source], {
            "diffusion_model": "source", "absorption_mapping": "matched",
            "scatter_grid": "full"}, albedo=0.9, unit_distance=1.0)
        direct = setup.transport(diffusion_steps=0).rho[0]
        exact = transmittance(opacity, spacing, truth, unit_distance=1.0, step=0.1)
        assert exact.min() < 0.1  # a deep shadow
        assert np.abs(direct - exact).max() < 0.02


def test_scattered_light_beside_the_medium_is_the_surface_value_not_zero():
    """Issue 24's error split: the scattered light was 0 in the empty voxels beside the
    medium, so the renderer's trilinear fetch in the medium's outer half voxel blended towards
    0 and every surface darkened (0.7–5 dB of the image error). The source model's sweep now
    carries φ one voxel out (the mean of the medium neighbours): there it is within a factor
    of two of the Monte-Carlo reference's in-scattered light (mean over 120 such voxels of a
    ball; measured 1.6×: beside a convex surface the true fluence falls below the surface's
    value — a Marshak-weighted fill matched this ball better but lost 2.4 dB on the hollow
    sphere's image, whose cavity the surface value describes better); farther out it stays 0."""
    from scipy.ndimage import binary_dilation

    from vtkvol.reference import inscattered_mc
    from vtkvol.reference.lights import DirectionalLight

    opacity, _ = ball(0.5)
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    k = D.source_coefficients(sigma_t, grid, 0.9)
    direct = D.marched_transmittance(sigma_t, grid, light(), 1.0)
    q = D.source_term(k, direct[None], [(1.0, 1.0, 1.0)], [1.0])
    phi, _ = D.solve_source(q, k, grid, tolerance=1e-6)
    medium = k[..., 0] > 0
    beside = binary_dilation(medium, np.ones((3, 3, 3), bool)) & ~medium
    voxels = np.argwhere(beside)
    voxels = voxels[np.random.default_rng(2).choice(len(voxels), 120, replace=False)]
    mc = inscattered_mc(opacity, (1.0, 1.0, 1.0), DirectionalLight(LIGHT_TOWARDS),
                        albedo=0.9, n_paths=96, max_bounces=64, seed=5, unit_distance=1.0,
                        points=voxels[:, ::-1].astype(float))
    ours = phi[..., 0][tuple(voxels.T)]
    assert float(np.asarray(mc).mean()) > 0.05  # the reference has light there
    assert 0.5 < ours.mean() / float(np.asarray(mc).mean()) < 2.0
    # the fill is the mean of the medium neighbours' φ, nothing farther out
    np.testing.assert_allclose(phi[~medium & ~beside], 0.0)
    np.testing.assert_allclose(D.surface_fill(phi, medium)[beside], phi[beside], rtol=1e-4)
