"""Issue 24's before → after, in one run: KD and HD with the diffusion this project ran before
issue 24 ("before": ρ_s ← ρ_s + λ∇²(direct + ρ_s), no source, no absorption, in a separate
volume), with seed 003's ``published`` model and with the ``source`` model, against the
Monte-Carlo multiple-scattering reference, voxel by voxel, on small homogeneous scenes.

Scenes: balls of radius 8 voxels in a 24³ box (opacity 0.1, 0.5, 0.9 per µm, unit distance
1 µm) and a 20×20×12 slab of opacity 0.5, one oblique directional light, albedo 0.5 and 0.9
(the seed audit's scenes, ``../shared/reference/seed-audit/diffusion.md``). Reference: exact
transmittance (``vtkvol.reference.transmittance``) + in-scattered light
(``inscattered_mc``, ``PATHS`` paths of ≤ 64 bounces per voxel) on every medium voxel.

Metric: PSNR (dB) of the total received light (direct + scattered) over the medium voxels,
peak = the reference's maximum; the reference's own floor is the PSNR of a second, independent
reference (another seed). "Iteration": KD before/published, one convection step + one diffusion
step; KD source, one Jacobi sweep (the direct light is converged at the start); HD, one
tracked sample + one sweep/step. Each method runs to its end: before/published, four times the
front's crossing (KD) or 256 samples (HD, as the defaults); source, until the relative residual
is below 10⁻⁴ (HD: after its 64 samples). "Rise" is the largest PSNR drop after the first
10 % of the iterations (checkpoints at every 2^k and the end).

Run: ``python benchmarks/diffusion_models.py`` (numpy only, ≈ 10–20 min on two shared cores;
prints Markdown).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from vtkvol.engine import diffusion as D
from vtkvol.plugins.convection_diffusion import cpu as kd
from vtkvol.plugins.hybrid_diffusion import cpu as hd
from vtkvol.reference import DirectionalLight, inscattered_mc, transmittance

N = 24
PATHS = 96
TOWARDS = (0.3, 0.2, 1.0)
HD_SAMPLES = {"before": 64, "published": 64, "source": 64}
TOLERANCE = 1e-4
RGB = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def scenes() -> list[tuple[str, np.ndarray]]:
    z, y, x = np.mgrid[:N, :N, :N]
    r = np.sqrt((x - 11.5) ** 2 + (y - 11.5) ** 2 + (z - 11.5) ** 2)
    out = [(f"ball α {a}", np.where(r <= 8.0, a, 0.0).astype(np.float32)) for a in (0.1, 0.5,
                                                                                     0.9)]
    slab = np.zeros((N, N, N), np.float32)
    slab[6:18, 2:22, 2:22] = 0.5
    return [*out, ("slab α 0.5", slab)]


def psnr(x: np.ndarray, ref: np.ndarray) -> float:
    mse = float(np.mean((x.astype(np.float64) - ref) ** 2))
    return 10.0 * math.log10(float(ref.max()) ** 2 / max(mse, 1e-30))


def checkpoints(end: int) -> list[int]:
    points = sorted({2 ** k for k in range(int(math.log2(max(end, 1))) + 1)} | {end})
    return [p for p in points if 1 <= p <= end]


def run_kd(model: str, opacity: np.ndarray, albedo: float, medium: np.ndarray,
           ref: np.ndarray) -> tuple[list[tuple[int, float]], float]:
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    light = D.LightSource("directional", tuple(np.asarray(TOWARDS) / np.linalg.norm(TOWARDS)))
    sigma_a = kd.absorption_per_iteration(
        sigma_t, grid, albedo=albedo, mapping="matched",
        convection_extinction="paper" if model == "published" else "total", unit_distance=1.0)
    lam = D.diffusion_rate(sigma_t, grid, albedo)
    t0 = time.perf_counter()
    t = kd.Transport(grid, [light], [(1.0, 1.0, 1.0)], sigma_a, lam,
                     model="source" if model == "source" else "published",
                     coefficients=D.source_coefficients(sigma_t, grid, albedo),
                     # the source model's direct light is ray-marched, as the technique's
                     sigma_t=sigma_t if model == "source" else None, unit_distance=1.0)
    u = D.propagation(grid, light)
    curve = []
    end = 4 * kd.iterations_to_cross(grid)
    it = 0
    while True:
        it += 1
        if model == "before":  # the diffusion before issue 24, as the engine's diffusion_step
            t.rho[0] = kd.convection_step(t.rho[0], sigma_a, u, grid)
            t.rho_s = D.diffusion_step(t.direct_rgb() + t.rho_s, t.rho_s, lam, grid)
        else:
            t.step()
        total = t.rho[0] + t.rho_s[..., 0]
        done = (t.residual < TOLERANCE) if model == "source" else it >= end
        if it in checkpoints(10 ** 6) or done:
            curve.append((it, psnr(total[medium], ref)))
        if done:
            return curve, time.perf_counter() - t0


def run_hd(model: str, opacity: np.ndarray, albedo: float, medium: np.ndarray,
           ref: np.ndarray) -> tuple[list[tuple[int, float]], float]:
    grid = D.Grid(opacity.shape, (1.0, 1.0, 1.0))
    sigma_t = D.extinction(opacity, 1.0)
    light = D.LightSource("directional", tuple(hd.unit(TOWARDS).tolist()))
    lam = D.diffusion_rate(sigma_t, grid, albedo)
    k = D.source_coefficients(sigma_t, grid, albedo)
    rho_d = np.zeros((*opacity.shape, 3), np.float32)
    rho_s = np.zeros_like(rho_d)
    samples = HD_SAMPLES[model]
    residual = math.inf
    curve = []
    t0 = time.perf_counter()
    it = 0
    while True:
        if it < samples:
            draw = hd.direct_sample(sigma_t, grid, [light], [(1.0, 1.0, 1.0)], iteration=it,
                                    seed=0, estimator="ratio", light_sampling="all")
            rho_d += (draw - rho_d) / np.float32(it + 1)
        it += 1
        if model == "source":
            q = D.source_term(k, np.moveaxis(rho_d, -1, 0), RGB, [1.0] * 3)
            rho_s, r2, q2 = D.jacobi_sweep(rho_s, q, k, grid)
            residual = D.relative_residual(r2, q2)
            done = it >= samples and residual < TOLERANCE
        else:  # before and published HD: the same separate-volume explicit step
            rho_s = D.diffusion_step(rho_d + rho_s, rho_s, lam, grid)
            done = it >= samples
        total = rho_d[..., 0] + rho_s[..., 0]
        if it in checkpoints(10 ** 6) or done:
            curve.append((it, psnr(total[medium], ref)))
        if done:
            return curve, time.perf_counter() - t0


def rise(curve: list[tuple[int, float]]) -> float:
    """Largest PSNR drop (dB) between checkpoints after the first 10 % of the iterations."""
    end = curve[-1][0]
    later = [p for i, p in curve if i >= 0.1 * end]
    best, drop = -math.inf, 0.0
    for p in later:
        best = max(best, p)
        drop = max(drop, best - p)
    return drop


def main() -> int:
    print("| scene | albedo | floor | method | model | iterations | PSNR end | best | rise | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, opacity in scenes():
        medium = opacity > 0.01
        pts = np.argwhere(medium)[:, ::-1].astype(float)
        light = DirectionalLight(TOWARDS)
        direct = transmittance(opacity, (1.0, 1.0, 1.0), light, unit_distance=1.0)[medium]
        mc = [inscattered_mc(opacity, (1.0, 1.0, 1.0), light, albedo=(0.5, 0.9, 0.9),
                             n_paths=PATHS, max_bounces=64, seed=s, unit_distance=1.0,
                             points=pts) for s in (3, 4)]
        for col, albedo in ((0, 0.5), (1, 0.9)):
            ref = direct + mc[0][:, col]
            floor = psnr(direct + mc[1][:, col], ref)
            for method, runner in (("KD", run_kd), ("HD", run_hd)):
                for model in ("before", "published", "source"):
                    if method == "HD" and model == "published":
                        continue  # HD published is the "before" step (§3.3's separate volume)
                    curve, seconds = runner(model, opacity, albedo, medium, ref)
                    print(f"| {name} | {albedo} | {floor:.1f} | {method} | {model} | "
                          f"{curve[-1][0]} | {curve[-1][1]:.1f} | "
                          f"{max(p for _, p in curve):.1f} | {rise(curve):.2f} | {seconds:.1f} |")
                    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
