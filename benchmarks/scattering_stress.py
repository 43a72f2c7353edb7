"""Where the diffusion approximation of KD and HD breaks (docs/stability.md, "Multiple
scattering"): their numpy paths against the exact transmittance and the Monte-Carlo in-scattered
light, voxel by voxel, on small volumes built to stress them.

Cases: a homogeneous sphere over a sweep of opacities (dense media), an optically thin slab, a
one-voxel sheet lit at 45°, a point light inside the sphere, and the sphere with voxels three
times longer in z. Per case and method: the direct light's RMSE against the exact
transmittance, the in-scattered light's mean as a fraction of the reference's (1 = right amount
of scattered light) and its RMSE relative to the reference's mean, and the total light's relative
RMSE. Only voxels with opacity > 0.01 count; the reference is evaluated at up to 600 of them
(``inscattered_mc``, 256 paths each: standard error ≲ 2 %).

Since issue 24 both methods run their default ``source`` diffusion model here (the figures in
docs/stability.md were measured with the diffusion before it).

Run: ``python benchmarks/scattering_stress.py`` (a few minutes on two cores; prints Markdown).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from vtkvol.engine import diffusion as D
from vtkvol.plugins.convection_diffusion import cpu as kd
from vtkvol.plugins.hybrid_diffusion import cpu as hd
from vtkvol.reference import DirectionalLight, PointLight, inscattered_mc, transmittance

ALBEDO = 0.9
N = 24
HD_ITERATIONS = 128


def sphere(alpha: float, spacing: Sequence[float] = (1.0, 1.0, 1.0)) -> np.ndarray:
    """A ball of radius 8 µm and opacity ``alpha`` per µm in a 24 µm box."""
    shape = [round(N / s) for s in spacing[::-1]]
    z, y, x = np.mgrid[: shape[0], : shape[1], : shape[2]].astype(np.float64)
    cz, cy, cx = ((n - 1) * s / 2 for n, s in zip(shape, spacing[::-1], strict=True))
    r2 = (x * spacing[0] - cx) ** 2 + (y * spacing[1] - cy) ** 2 + (z * spacing[2] - cz) ** 2
    return (r2 <= 64.0).astype(np.float32) * np.float32(alpha)


def run_case(alpha: np.ndarray, spacing: Sequence[float], light: object, *,
             n_points: int = 600, n_paths: int = 256,
             hd_iterations: int = HD_ITERATIONS) -> dict[str, dict]:
    """KD and HD against the references for one volume and light (a reference light object),
    at up to ``n_points`` voxels with ``n_paths`` reference paths each."""
    grid = kd.Grid(alpha.shape, tuple(spacing))
    unit = float(min(spacing))
    sigma_t = kd.extinction(alpha, unit)
    if isinstance(light, DirectionalLight):
        source = kd.LightSource("directional", tuple(light.direction))
    else:
        source = kd.LightSource("point", tuple(light.position))
    sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=ALBEDO, mapping="matched",
                                          convection_extinction="total", unit_distance=unit)
    lam = kd.diffusion_rate(sigma_t, grid, ALBEDO)
    # The default ("source") diffusion model of both techniques, run to its residual tolerance.
    coefficients = kd.source_coefficients(sigma_t, grid, ALBEDO)
    # With σ_t the direct light is ray-marched, as the technique's source model computes it.
    transport = kd.Transport(grid, [source], [(1.0, 1.0, 1.0)], sigma_a, lam, diffusion_steps=1,
                             model="source", coefficients=coefficients, sigma_t=sigma_t,
                             unit_distance=unit)
    while transport.residual > 1e-4:
        transport.step(16)
    kd_direct = transport.rho[0]
    kd_scattered = transport.rho_s[..., 0]

    rho_d = np.zeros((*alpha.shape, 3), np.float32)
    for k in range(hd_iterations):
        sample = hd.direct_sample(sigma_t, grid, [source], [(1.0, 1.0, 1.0)], iteration=k,
                                  seed=0, estimator="ratio", light_sampling="one")
        rho_d += (sample - rho_d) / np.float32(k + 1)
    q = kd.source_term(coefficients, np.moveaxis(rho_d, -1, 0),
                       ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), [1.0] * 3)
    rho_s, _ = D.solve_source(q, coefficients, grid, tolerance=1e-4)

    mask = alpha > 0.01
    zyx = np.argwhere(mask)
    zyx = zyx[:: max(1, len(zyx) // n_points)]
    pts = zyx[:, ::-1] * np.asarray(spacing)
    idx = tuple(zyx.T)
    exact = transmittance(alpha, spacing, light, unit_distance=unit)[idx]
    indirect = inscattered_mc(alpha, spacing, light, albedo=ALBEDO, n_paths=n_paths, points=pts,
                              unit_distance=unit, max_bounces=48)
    out = {}
    for name, direct, scattered in (("KD", kd_direct, kd_scattered),
                                    ("HD", rho_d[..., 0], rho_s[..., 0])):
        d, s = direct[idx], scattered[idx]
        total_ref = exact + indirect
        out[name] = {
            "direct_rmse": float(np.sqrt(np.mean((d - exact) ** 2))),
            "scattered_ratio": float(s.mean() / indirect.mean()),
            "scattered_rel_rmse": float(np.sqrt(np.mean((s - indirect) ** 2)) / indirect.mean()),
            "total_rel_rmse": float(np.sqrt(np.mean((d + s - total_ref) ** 2)) / total_ref.mean()),
            "reference_scattered_mean": float(indirect.mean()),
        }
    return out


def cases() -> list[tuple[str, np.ndarray, tuple[float, float, float], object]]:
    top = DirectionalLight((0.0, 0.0, 1.0))
    out = [(f"sphere, α {a:g}", sphere(a), (1.0, 1.0, 1.0), top)
           for a in (0.05, 0.2, 0.5, 0.67, 0.8, 0.95)]
    slab = np.zeros((12, N, N), np.float32)
    slab[2:10] = 1.0 - math.exp(-0.05)
    out.append(("thin slab (τ 0.4)", slab, (1.0, 1.0, 1.0), top))
    sheet = np.zeros((N, N, N), np.float32)
    sheet[12] = 0.5
    out.append(("1-voxel sheet, light at 45°", sheet, (1.0, 1.0, 1.0),
                DirectionalLight((1.0, 0.0, 1.0))))
    out.append(("sphere α 0.3, point light at its centre", sphere(0.3), (1.0, 1.0, 1.0),
                PointLight((N / 2 - 0.5, N / 2 - 0.5, N / 2 - 0.5))))
    out.append(("sphere α 0.3, z voxel 3×", sphere(0.3, (1.0, 1.0, 3.0)), (1.0, 1.0, 3.0), top))
    out.append(("sphere α 0.3, isotropic (same ball)", sphere(0.3), (1.0, 1.0, 1.0), top))
    return out


def main() -> None:
    print("| case | method | direct RMSE | scattered ÷ reference | scattered rel. RMSE "
          "| total rel. RMSE |\n|---|---|---|---|---|---|")
    for name, alpha, spacing, light in cases():
        result = run_case(alpha, spacing, light)
        for method, r in result.items():
            print(f"| {name} | {method} | {r['direct_rmse']:.3f} | "
                  f"{r['scattered_ratio']:.2f} | {r['scattered_rel_rmse']:.2f} | "
                  f"{r['total_rel_rmse']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
