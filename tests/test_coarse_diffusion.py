"""The source model's scattered light on ½ and ¼ grids (vtkvol.engine.coarse_diffusion, the
``scatter_grid`` parameter of convection_diffusion and hybrid_diffusion)."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.engine import coarse_diffusion as C
from vtkvol.engine import diffusion as D

WHITE = ((1.0, 1.0, 1.0),)


def _smooth_scene(n: int = 24) -> tuple[D.Grid, np.ndarray, np.ndarray]:
    """A Gaussian blob of σ_t (peak 0.5/µm) lit uniformly: (grid, σ_t, q)."""
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float64)
    r2 = (x - 11.5) ** 2 + (y - 11.5) ** 2 + (z - 11.5) ** 2
    sigma_t = (0.5 * np.exp(-r2 / (2 * 6.0**2))).astype(np.float32)
    grid = D.Grid((n, n, n), (1.0, 1.0, 1.0))
    k = D.source_coefficients(sigma_t, grid, 0.9)
    q = D.source_term(k, np.ones((1, n, n, n), np.float32), WHITE, [1.0])
    return grid, sigma_t, q


def test_coarse_grid_spans_the_data_point_bounds() -> None:
    g = C.coarse_grid(D.Grid((24, 13, 9), (1.0, 1.0, 2.0), (5.0, 0.0, -1.0)), 4)
    assert g.shape_zyx == (6, 4, 3)  # ⌈n/4⌉ points per axis
    # First and last points on the first and last voxel centres: (n − 1)h/(m − 1).
    assert g.spacing == pytest.approx((4.0, 4.0, 2.0 * 23 / 5))
    assert g.origin == (5.0, 0.0, -1.0)
    assert C.coarse_grid(D.Grid((2, 1, 5), (1.0, 1.0, 1.0)), 4).shape_zyx == (2, 1, 2)
    s = C.ScatterGrid(D.Grid((24, 13, 9), (1.0, 1.0, 1.0)), 2)
    assert s.dims_xyz == (5.0, 7.0, 12.0)
    assert s.ratios_xyz == pytest.approx((4 / 8, 6 / 12, 11 / 23))


def test_restriction_and_prolongation_keep_constants_and_linear_fields() -> None:
    s = C.ScatterGrid(D.Grid((9, 10, 13), (1.0, 1.0, 1.0)), 2)
    ones = np.full((9, 10, 13, 3), 2.0, np.float32)
    np.testing.assert_allclose(s.restrict(ones), 2.0, rtol=1e-6)
    np.testing.assert_allclose(s.prolong(s.restrict(ones)), 2.0, rtol=1e-6)
    # A field linear in the position is reproduced exactly by the texture lookup (trilinear
    # over the same point bounds); full weighting keeps it at interior points to within the
    # asymmetry of the hat windows where (n − 1)/(m − 1) is not a whole number (measured
    # 0.0125 for a slope of 1 per voxel).
    z, y, x = np.mgrid[:9, :10, :13].astype(np.float64)
    lin = (0.5 * x + 0.25 * y - z).astype(np.float32)
    cz, cy, cx = (np.arange(m) * (n - 1) / (m - 1) for n, m in
                  zip((9, 10, 13), s.grid.shape_zyx, strict=True))
    coarse_lin = (0.5 * cx[None, None, :] + 0.25 * cy[None, :, None] - cz[:, None, None])
    np.testing.assert_allclose(s.prolong(coarse_lin), lin, atol=1e-5)
    np.testing.assert_allclose(s.restrict(lin)[1:-1, 1:-1, 1:-1],
                               coarse_lin[1:-1, 1:-1, 1:-1], atol=0.02)


def test_reduced_grids_stay_within_their_measured_error_and_take_fewer_sweeps() -> None:
    grid, sigma_t, q = _smooth_scene()
    full, full_sweeps = D.solve_source(q, D.source_coefficients(sigma_t, grid, 0.9), grid,
                                       tolerance=1e-5)
    half, half_c, half_sweeps = C.solve_source_coarse(q, sigma_t, grid, 0.9, 2, tolerance=1e-5)
    quarter, quarter_c, quarter_sweeps = C.solve_source_coarse(q, sigma_t, grid, 0.9, 4,
                                                               tolerance=1e-5)
    inside = sigma_t * 1.0 > D.EMPTY_OPTICAL_THICKNESS
    rel = (np.sqrt(np.mean((half - full)[inside] ** 2)) / full[inside].mean())
    rel_q = (np.sqrt(np.mean((quarter - full)[inside] ** 2)) / full[inside].mean())
    # Measured: 0.079 (half), 0.115 (quarter) relative RMSE of φ over the medium.
    assert rel < 0.09, rel
    assert rel < rel_q < 0.13, rel_q
    assert half.min() >= 0.0 and quarter.min() >= 0.0
    # The scattered texture (the coarse φ) is 8× and 64× smaller …
    assert full.nbytes / half_c.nbytes == 8
    assert full.nbytes / quarter_c.nbytes == 64
    # … and converges in fewer sweeps (measured 2017, 632, 173), each 8× / 64× cheaper.
    assert half_sweeps < 0.4 * full_sweeps and quarter_sweeps < 0.4 * half_sweeps


@pytest.mark.gl
@pytest.mark.parametrize("factor", [2, 4])
def test_gpu_restriction_and_sweeps_match_numpy(factor: int) -> None:
    """GpuSourceDiffusion on a reduced grid = ScatterGrid.restrict of source_term + Jacobi
    sweeps, on axes that are not multiples of the factor, with a falling-off point light."""
    from vtkvol.engine.gl import Texture3D
    from vtkvol.engine.offscreen import simple_volume_scene

    shape = (14, 18, 21)
    rng = np.random.default_rng(3)
    sigma_t = (0.4 * rng.random(shape)).astype(np.float32)
    sigma_t[:3] = 0.0  # empty voxels: no unknowns there on the data grid
    direct = rng.random((*shape, 2)).astype(np.float32)
    grid = D.Grid(shape, (1.0, 1.5, 0.8), (2.0, -1.0, 0.5))
    lights = [D.LightSource("directional", (0.0, 0.0, 1.0)),
              D.LightSource("point", (30.0, 8.0, 6.0), falloff_distance=12.0)]
    colors = [(1.0, 0.8, 0.6), (0.3, 0.5, 1.0)]
    fine = D.source_coefficients(sigma_t, grid, 0.8)
    scatter = C.ScatterGrid(grid, factor)
    coarse = scatter.coefficients(sigma_t, 0.8)
    q = scatter.restrict(D.source_term(fine, np.moveaxis(direct, -1, 0), colors,
                                       [D.falloff(grid, light) for light in lights]))
    phi = np.zeros_like(q)
    for _ in range(12):
        phi, r2, q2 = D.jacobi_sweep(phi, q, coarse, scatter.grid)

    rw, _ren, _vol = simple_volume_scene(np.zeros((4, 4, 4), np.float32), size=(16, 16))
    rw.Render()
    rw.MakeCurrent()
    gpu = D.GpuSourceDiffusion(rw)
    gpu.reset(grid, coarse, 2, lights, scatter, fine_sigma_s=fine[..., 2])
    tex = Texture3D(rw, shape, channels=2, data=direct)
    tex.tex.Deactivate()
    gpu.run(tex, colors, 12)
    got = gpu.phi.download()[..., :3]
    residual = D.relative_residual(*gpu.residual())
    tex.release()
    gpu.release()
    rw.Finalize()
    assert got.shape == (*scatter.grid.shape_zyx, 3) and phi.max() > 1e-3
    # float32 restriction in another summation order than numpy's float64 full weighting.
    np.testing.assert_allclose(got, phi, atol=1e-5 * float(phi.max()))
    assert residual == pytest.approx(D.relative_residual(r2, q2), rel=1e-3)


def test_scatter_grid_round_trips_through_a_session(tmp_path) -> None:
    """Technique parameters are saved generically: both techniques' ``scatter_grid`` come
    back as saved, and an undeclared value is refused naming the parameter."""
    import json

    from vtkvol.model import SceneModel
    from vtkvol.model.session import SessionError, read_session, save_session

    model = SceneModel()
    model.illumination.method = "hybrid_diffusion"
    model.illumination.set_value("scatter_grid", "quarter", method="convection_diffusion")
    model.illumination.set_value("scatter_grid", "half", method="hybrid_diffusion")
    path = save_session(tmp_path / "v", model)
    again = read_session(path).model.illumination.parameters
    assert again["convection_diffusion"]["scatter_grid"] == "quarter"
    assert again["hybrid_diffusion"]["scatter_grid"] == "half"
    doc = json.loads(path.read_text())
    doc["scene"]["illumination"]["parameters"]["hybrid_diffusion"]["scatter_grid"] = "eighth"
    path.write_text(json.dumps(doc))
    with pytest.raises(SessionError, match="scatter_grid must be one of full, half, quarter"):
        read_session(path)
