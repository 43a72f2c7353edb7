"""Negative scattered light in the stability suite's stress cases (issue 24): KD and HD, both
diffusion models, on the numpy paths (the GPU shaders mirror them operation by operation).

The cases are ``vtkvol bench``'s stability sweeps (:func:`vtkvol.bench.scenes.stability_cases`,
quick set, at ``--n`` voxels per edge; the ``resolution`` parameter sweep is skipped because
neither technique declares that parameter). Per case, technique and model: the scattered-light
field is run to its stopping point and its negative voxels are counted (any value < 0, RGB
channels counted per voxel once), with the most negative value.

* KD ``source``: warm-started direct light, two traced orders (``--hd-samples`` paths per
  voxel) and Jacobi sweeps of φ from σ_s·E_2 until the relative residual < 1e-4 (at most 4000
  sweeps); the scattered field counted is what is shown, the traced light + φ.
* KD ``published``: one field (convection then the explicit diffusion step),
  2 × :func:`~vtkvol.engine.diffusion.iterations_to_cross` iterations; the field is counted
  (it holds direct and scattered light together).
* HD: ``--hd-samples`` ratio-tracked direct samples averaged (ρ_d), then ``source``: as many
  paths of two traced orders, :func:`~vtkvol.engine.diffusion.solve_source` from σ_s·E_2, the
  traced light + φ counted; ``published`` (from ρ_d, no traced orders): the explicit step
  ρ_s ← ρ_s + λ∇²(ρ_d + ρ_s) in its own volume, 2 × iterations_to_cross steps; ρ_s is counted.

Albedo 0.9, σ_t from the opacity per unit of the smallest voxel edge, as the techniques do.
Run: ``python benchmarks/scattering_stability.py [--n 24]`` (prints Markdown).
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

import numpy as np

from vtkvol.bench.scenes import stability_cases
from vtkvol.engine import diffusion as D
from vtkvol.engine.traced_orders import traced_orders_sample
from vtkvol.plugins.convection_diffusion import cpu as kd
from vtkvol.plugins.hybrid_diffusion import cpu as hd

ALBEDO = 0.9
#: Traced orders in the source rows (positivity holds for any number: every path scores ≥ 0).
ORDERS = 2
MAX_SWEEPS = 4000
WHITE = ((1.0, 1.0, 1.0),)


def negatives(field: np.ndarray) -> tuple[int, float]:
    """(voxels with any channel < 0, the minimum value) of a ``[z, y, x]`` or ``[z, y, x, c]``
    field."""
    neg = field < 0
    if neg.ndim == 4:
        neg = neg.any(axis=-1)
    return int(neg.sum()), float(field.min())


def run(alpha: np.ndarray, spacing: tuple[float, float, float], direction: tuple[float, ...],
        hd_samples: int) -> dict[str, tuple[int, float]]:
    """Negative-voxel counts for the four technique × model pairs on one volume and light."""
    grid = kd.Grid(alpha.shape, tuple(float(s) for s in spacing))
    unit = float(min(spacing))
    sigma_t = kd.extinction(alpha, unit)
    light = kd.LightSource("directional", tuple(float(v) for v in direction))
    lam = kd.diffusion_rate(sigma_t, grid, ALBEDO)
    coefficients = kd.source_coefficients(sigma_t, grid, ALBEDO)
    steps = 2 * D.iterations_to_cross(grid)
    out: dict[str, tuple[int, float]] = {}

    # KD, source: the default (total extinction convection, as the technique's default).
    sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=ALBEDO, mapping="matched",
                                          convection_extinction="total", unit_distance=unit)
    t = kd.Transport(grid, [light], WHITE, sigma_a, lam, model="source",
                     coefficients=coefficients, sigma_t=sigma_t, unit_distance=unit,
                     orders=ORDERS, albedo=ALBEDO, traced_paths=hd_samples)
    while (t.residual > 1e-4 or t.samples < hd_samples) and t.iteration < MAX_SWEEPS:
        t.step(16)
    assert t.traced is not None
    out["KD source"] = negatives(t.traced + t.rho_s)  # the traced orders and φ, as shown

    # KD, published: absorption-only convection (eq. 8) and the explicit diffusion of one field.
    sigma_a = kd.absorption_per_iteration(sigma_t, grid, albedo=ALBEDO, mapping="matched",
                                          convection_extinction="absorption", unit_distance=unit)
    t = kd.Transport(grid, [light], WHITE, sigma_a, lam, model="published")
    t.step(steps)
    out["KD published"] = negatives(t.rho[0])

    rho_d = np.zeros(alpha.shape, np.float32)
    for k in range(hd_samples):
        sample = hd.direct_sample(sigma_t, grid, [light], WHITE, iteration=k, seed=0,
                                  estimator="ratio", light_sampling="one")
        rho_d += (sample[..., 0] - rho_d) / np.float32(k + 1)
    setup = SimpleNamespace(grid=grid, sigma_t=sigma_t, lights=[light], colors=WHITE,
                            unit_distance=unit, bricks=None, orders=ORDERS, albedo=ALBEDO,
                            phase_g=0.0)
    traced = np.zeros((*alpha.shape, 3), np.float32)
    last = np.zeros_like(traced)
    for k in range(hd_samples):
        t_k, l_k = traced_orders_sample(setup, (0, alpha.shape[0], 0, alpha.shape[1]), k, 0)
        traced += (t_k - traced) / np.float32(k + 1)
        last += (l_k - last) / np.float32(k + 1)
    q = kd.source_term(coefficients, last[None, ..., 0], WHITE, [1.0])
    phi, _ = D.solve_source(q, coefficients, grid, tolerance=1e-4)
    out["HD source"] = negatives(traced[..., 0:1] + phi)  # the traced orders and φ, as shown
    rho_s = np.zeros_like(rho_d)
    for _ in range(steps):
        rho_s = D.diffusion_step(rho_d + rho_s, rho_s, lam, grid)
    out["HD published"] = negatives(rho_s)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=24, help="voxels per edge of the scenes")
    parser.add_argument("--hd-samples", type=int, default=16, help="HD direct samples")
    args = parser.parse_args()
    pairs = ("KD source", "KD published", "HD source", "HD published")
    totals = dict.fromkeys(pairs, 0)
    minima = dict.fromkeys(pairs, 0.0)
    print("| sweep | case | " + " | ".join(f"{p}: neg. voxels (min)" for p in pairs) + " |")
    print("|---|---|" + "---|" * len(pairs))
    started = time.perf_counter()
    cases = 0
    for case in stability_cases(args.n, quick=True):
        if case.parameter_sweep is not None:
            continue
        scene = case.scene
        alpha = scene.opacity()
        for direction in scene.lights:
            result = run(alpha, scene.spacing, direction, args.hd_samples)
            cases += 1
            cells = []
            for p in pairs:
                count, low = result[p]
                totals[p] += int(count > 0)
                minima[p] = min(minima[p], low)
                cells.append(f"{count} ({low:.3g})")
            print(f"| {case.sweep} | {case.value_label} | " + " | ".join(cells) + " |",
                  flush=True)
    print(f"\n{cases} scene × light cases, n = {args.n}, "
          f"{time.perf_counter() - started:.0f} s. Cases with negative voxels: "
          + ", ".join(f"{p} {totals[p]} (min {minima[p]:.3g})" for p in pairs))


if __name__ == "__main__":
    main()
