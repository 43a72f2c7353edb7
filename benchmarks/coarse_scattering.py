"""The source model's scattered light on reduced-resolution grids (issue 24, ``scatter_grid``):
full, ½ and ¼ points per axis, for both techniques (KD and HD, their numpy paths), against
the full-resolution result and the Monte-Carlo reference, in one run, on the scenes of
``benchmarks/diffusion_models.py`` (balls of radius 8 in 24³, opacity 0.1/0.5/0.9 per µm, and
the 20×20×12 slab; albedo 0.9, one oblique directional light, unit distance 1 µm).

KD: the technique's own ``Setup``/``Transport`` (warm-start direct light, ``diffusion_steps``
1), Jacobi sweeps until the relative residual is below 10⁻⁴. HD: the technique's ``Setup`` and
the numpy path's iteration (one tracked ratio-tracking sample, then q restricted to the scatter
grid and one sweep), 64 samples, then sweeps until 10⁻⁴; the samples are drawn once per scene
and shared by the three grids, so the grids differ only in the scattered part. "sweeps" counts
Jacobi sweeps; "scattered s" is the wall time of the scattered part only (restriction +
sweeps; the direct light is the same for every grid).

Metrics over the medium voxels (φ prolonged to the data voxels as the ray caster's texture
lookup does): PSNR (dB) of the scattered light against the same technique's full-grid φ
(peak = its maximum); against the Monte-Carlo in-scattered light (peak = its maximum); and of
the total light (direct + φ) against the reference (exact transmittance + ``inscattered_mc``,
``PATHS`` paths of ≤ 64 bounces at up to ``POINTS`` medium voxels; peak = its maximum); and
the scattered texture's bytes (RGBA float32 texels of the grid it is solved on).

Second table (``--gl``, also run by default): both techniques end to end through the host
(``Illuminator``, ``backend`` auto = the compute-shader path) on a ``GL_N``³ ball of opacity 0.5
(radius 0.35·``GL_N``), one oblique light, albedo 0.9, a 64² window: wall seconds from the
restart to convergence (KD: sweeps to 10⁻⁴; HD: ``GL_HD_SAMPLES`` samples then sweeps to 10⁻⁴),
the iterations, the technique's texture bytes, and the PSNR of the shown scattered light
(prolonged) against the same technique's full-grid result.

Run: ``python benchmarks/coarse_scattering.py`` (numpy, then GL; a few minutes on two cores;
prints Markdown). ``--numpy`` or ``--gl`` runs one table only.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from vtkvol.engine import coarse_diffusion as C
from vtkvol.engine import diffusion as D
from vtkvol.plugins.convection_diffusion import technique as kd_technique
from vtkvol.plugins.hybrid_diffusion import cpu as hd
from vtkvol.plugins.hybrid_diffusion import technique as hd_technique
from vtkvol.reference import DirectionalLight, inscattered_mc, transmittance

sys.path.insert(0, str(Path(__file__).resolve().parent))
from diffusion_models import TOWARDS, scenes

ALBEDO = 0.9
PATHS = 96
POINTS = 400
TOLERANCE = 1e-4
HD_SAMPLES = 64
GRIDS = tuple(C.FACTORS)
RGB = hd_technique.RGB_AS_LIGHTS


def psnr(x: np.ndarray, ref: np.ndarray) -> float:
    """PSNR (dB) of ``x`` against ``ref``, peak = the reference's maximum."""
    mse = float(np.mean((x.astype(np.float64) - ref) ** 2))
    return 10.0 * math.log10(float(ref.max()) ** 2 / max(mse, 1e-30))


def light_spec() -> SimpleNamespace:
    """The oblique directional light as the techniques' ``Setup.build`` reads a LightSpec."""
    return SimpleNamespace(kind="directional", vector=tuple(float(v) for v in TOWARDS),
                           color=(1.0, 1.0, 1.0), falloff_distance=0.0, size=0.0)


def run_kd(grid: D.Grid, sigma_t: np.ndarray, res: str) -> tuple[np.ndarray, np.ndarray,
                                                                    C.ScatterGrid, int, float]:
    """(direct, coarse φ, scatter grid, sweeps, scattered seconds) of KD's numpy path."""
    values = {"diffusion_model": "source", "absorption_mapping": "matched", "scatter_grid": res}
    setup = kd_technique.Setup.build(grid, sigma_t, [light_spec()], values, ALBEDO, 1.0)
    transport = setup.transport(diffusion_steps=1)  # warm start: the same for every grid
    restrict_s = 0.0
    if setup.scatter.coarse:  # Transport restricted q at its start: timed here on its own
        q = D.source_term(setup.coefficients, transport.rho[:1], [(1.0, 1.0, 1.0)], [1.0])
        t1 = time.perf_counter()
        setup.scatter.restrict(q)
        restrict_s = time.perf_counter() - t1
    t2 = time.perf_counter()
    while transport.residual >= TOLERANCE:
        transport.step(1)
    seconds = time.perf_counter() - t2 + restrict_s
    return transport.rho[0], transport.rho_s, setup.scatter, transport.iteration, seconds


def hd_samples(grid: D.Grid, sigma_t: np.ndarray) -> list[np.ndarray]:
    """HD's running mean ρ_d after each of its samples (ratio tracking, bricks, seed 0)."""
    light = D.LightSource("directional", tuple(hd.unit(TOWARDS).tolist()))
    bricks = hd.brick_majorants(sigma_t)
    mean = np.zeros((*grid.shape_zyx, 3), np.float32)
    out = []
    for k in range(HD_SAMPLES):
        draw = hd.direct_sample(sigma_t, grid, [light], [(1.0, 1.0, 1.0)], iteration=k, seed=0,
                                estimator="ratio", light_sampling="one", bricks=bricks)
        mean = mean + (draw - mean) / np.float32(k + 1)
        out.append(mean)
    return out


def run_hd(grid: D.Grid, sigma_t: np.ndarray, means: list[np.ndarray], res: str
           ) -> tuple[np.ndarray, C.ScatterGrid, int, float]:
    """(coarse φ, scatter grid, sweeps, scattered seconds) of HD's numpy iteration."""
    setup = hd_technique.Setup.build(grid, sigma_t, [light_spec()], ALBEDO, "source", 0.0,
                                     "bricks", res)
    assert setup.coefficients is not None
    solve_grid, coefficients = setup.solve
    rho_s = np.zeros((*solve_grid.shape_zyx, 3), np.float32)
    residual = math.inf
    sweeps = 0
    t0 = time.perf_counter()
    q = None
    while sweeps < len(means) or residual >= TOLERANCE:
        if sweeps < len(means) or q is None:
            rho_d = means[min(sweeps, len(means) - 1)]
            q = setup.scatter.restrict(D.source_term(setup.coefficients,
                                                     np.moveaxis(rho_d, -1, 0), RGB, [1.0] * 3))
        rho_s, r2, q2 = D.jacobi_sweep(rho_s, q, coefficients, solve_grid)
        residual = D.relative_residual(r2, q2)
        sweeps += 1
    return rho_s, setup.scatter, sweeps, time.perf_counter() - t0


GL_N = 64
GL_HD_SAMPLES = 16


def gl_table() -> None:
    """The techniques through the host on the GPU path (see the module docstring)."""
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import grab, simple_volume_scene
    from vtkvol.model.scene import Light

    z, y, x = np.mgrid[:GL_N, :GL_N, :GL_N]
    c = (GL_N - 1) / 2
    r = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2)
    ball = np.where(r <= 0.35 * GL_N, 1.0, 0.0).astype(np.float32)
    print(f"\n| technique | grid ({GL_N}³ ball, GPU path) | seconds to converge | iterations "
          "| texture bytes | PSNR scattered vs full (dB) |\n|---|---|---|---|---|---|")
    for method, extra in (("convection_diffusion", {"iterations_per_frame": 32}),
                          ("hybrid_diffusion", {"iterations_per_frame": 8,
                                                "max_iterations": GL_HD_SAMPLES})):
        full = None
        for res in GRIDS:
            rw, _ren, volume = simple_volume_scene(ball, size=(64, 64),
                                                   opacity=[(0.0, 0.0), (1.0, 0.5)])
            il = Illuminator(volume, _ren, method=method,
                             lights=[Light(direction=TOWARDS)],
                             parameters={"scatter_grid": res, **extra})
            il.set_material(albedo=ALBEDO)
            t0 = time.perf_counter()
            il.converge(max_seconds=600)
            grab(rw)
            seconds = time.perf_counter() - t0
            tech = il.technique
            stats = tech.stats()
            rw.MakeCurrent()
            scattered = tech._gpu.download()[1][..., :3]
            setup = tech.setup
            phi = setup.scatter.prolong(scattered)[..., 0]
            if full is None:
                full = phi
            mask = ball > 0
            print(f"| {method} | {res} {'×'.join(map(str, scattered.shape[2::-1]))} | "
                  f"{seconds:.1f} | {stats['iterations']} | {stats['texture_bytes']} | "
                  f"{psnr(phi[mask], full[mask]):.1f} |", flush=True)
            il.release()
            rw.Finalize()


def main() -> None:
    if "--gl" not in sys.argv:
        numpy_table()
    if "--numpy" not in sys.argv:
        gl_table()


def numpy_table() -> None:
    print("| scene | technique | grid | scattered texture bytes | sweeps | scattered s "
          "| PSNR scattered vs full (dB) | PSNR scattered vs MC (dB) "
          "| PSNR total vs reference (dB) |\n|---|---|---|---|---|---|---|---|---|")
    started = time.perf_counter()
    for name, alpha in scenes():
        grid = D.Grid(alpha.shape, (1.0, 1.0, 1.0))
        sigma_t = D.extinction(alpha, 1.0)
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
        means = hd_samples(grid, sigma_t)
        for technique in ("KD", "HD"):
            full = None
            for res in GRIDS:
                if technique == "KD":
                    direct, phi_c, scatter, sweeps, seconds = run_kd(grid, sigma_t, res)
                else:
                    phi_c, scatter, sweeps, seconds = run_hd(grid, sigma_t, means, res)
                    direct = means[-1][..., 0]
                phi = scatter.prolong(phi_c)[..., 0]
                if full is None:
                    full = phi
                dims = "×".join(map(str, phi_c.shape[2::-1]))
                print(f"| {name} | {technique} | {res} {dims} | "
                      f"{C.texture_bytes(phi_c.shape)} | {sweeps} | {seconds:.2f} | "
                      f"{psnr(phi[mask], full[mask]):.1f} | {psnr(phi[idx], indirect):.1f} | "
                      f"{psnr(direct[idx] + phi[idx], reference):.1f} |", flush=True)
    print(f"\n{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
