"""The source model's scattered light on reduced-resolution grids (issue 24): full, ½ and ¼ per
axis (:mod:`vtkvol.engine.coarse_diffusion`), against the full-resolution solve and against the
Monte-Carlo reference, on the scenes of ``benchmarks/diffusion_models.py`` (balls of radius 8 in
24³, opacity 0.1/0.5/0.9 per µm, and the 20×20×12 slab; albedo 0.9, one oblique light).

The direct light is KD's warm start (one propagation pass, total-extinction convection as the
technique's default); q = σ_s·E_direct; φ is solved to a relative residual of 10⁻⁴ on each grid
and prolonged trilinearly. Metrics over the medium voxels: PSNR (dB) of the scattered light
against the full-resolution φ (peak = its maximum) and against the Monte-Carlo in-scattered
light (peak = its maximum); PSNR of the total light (KD's direct + φ; KD's convected direct
light is itself ≈ 0.07 RMSE from the exact transmittance on these balls) against the reference
(exact transmittance + ``inscattered_mc``, ``PATHS`` paths at up to ``POINTS`` medium voxels;
peak = the reference's maximum); and the scattered texture's bytes
(RGBA float32 texels of the grid it is solved on).

Run: ``python benchmarks/coarse_scattering.py`` (numpy only, a few minutes on two cores;
prints Markdown).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from vtkvol.engine import coarse_diffusion as C
from vtkvol.engine import diffusion as D
from vtkvol.plugins.convection_diffusion import cpu as kd
from vtkvol.reference import DirectionalLight, inscattered_mc, transmittance

sys.path.insert(0, str(Path(__file__).resolve().parent))
from diffusion_models import TOWARDS, scenes

ALBEDO = 0.9
PATHS = 96
POINTS = 400
WHITE = ((1.0, 1.0, 1.0),)


def psnr(x: np.ndarray, ref: np.ndarray) -> float:
    """PSNR (dB) of ``x`` against ``ref``, peak = the reference's maximum."""
    mse = float(np.mean((x.astype(np.float64) - ref) ** 2))
    return 10.0 * math.log10(float(ref.max()) ** 2 / max(mse, 1e-30))


def main() -> None:
    print("| scene | grid | scattered texture bytes | PSNR scattered vs full (dB) "
          "| PSNR scattered vs MC (dB) | PSNR total vs reference (dB) |\n|---|---|---|---|---|---|")
    started = time.perf_counter()
    for name, alpha in scenes():
        grid = D.Grid(alpha.shape, (1.0, 1.0, 1.0))
        sigma_t = D.extinction(alpha, 1.0)
        light = D.LightSource(
            "directional", tuple(float(v) for v in np.asarray(TOWARDS) / np.linalg.norm(TOWARDS)))
        sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=ALBEDO, mapping="matched",
                                              convection_extinction="total", unit_distance=1.0)
        k = D.source_coefficients(sigma_t, grid, ALBEDO)
        t = kd.Transport(grid, [light], WHITE, sigma_a, D.diffusion_rate(sigma_t, grid, ALBEDO),
                         model="source", coefficients=k)
        direct = t.rho[0]
        q = D.source_term(k, direct[None], WHITE, [1.0])
        mask = alpha > 0.01
        zyx = np.argwhere(mask)
        zyx = zyx[:: max(1, len(zyx) // POINTS)]
        idx = tuple(zyx.T)
        ref_light = DirectionalLight(TOWARDS)
        exact = transmittance(alpha, (1.0, 1.0, 1.0), ref_light, unit_distance=1.0)[idx]
        indirect = inscattered_mc(alpha, (1.0, 1.0, 1.0), ref_light, albedo=ALBEDO,
                                  n_paths=PATHS, points=zyx[:, ::-1].astype(np.float64),
                                  unit_distance=1.0, max_bounces=64)
        reference = exact + indirect
        full = None
        for res, factor in C.FACTORS.items():
            phi, phi_c = C.solve_source_coarse(q, sigma_t, grid, ALBEDO, factor, tolerance=1e-4)
            if full is None:
                full = phi
            texels = int(np.prod(phi_c.shape[:3]))
            print(f"| {name} | {res} {'×'.join(map(str, phi_c.shape[2::-1]))} | {texels * 16} | "
                  f"{psnr(phi[mask][:, 0], full[mask][:, 0]):.1f} | "
                  f"{psnr(phi[idx][:, 0], indirect):.1f} | "
                  f"{psnr(direct[idx] + phi[idx][:, 0], reference):.1f} |", flush=True)
    print(f"\n{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
