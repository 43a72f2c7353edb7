"""Development study of the translucency technique (not part of the installed library): how far
its indirect term (Kniss's blurred, chromatically attenuated transmittance, seed 001 eq. 2.44)
is from multiply scattered light computed by the Monte-Carlo reference with a forward-peaked
Henyey–Greenstein phase function and an RGB albedo. For docs/translucency.md.

Run from the checkout: ``python benchmarks/translucency_vs_scattering.py`` prints the tables as
markdown (about 3 minutes on two cores).

What is compared, per voxel centre where the TF opacity exceeds 0.05, per colour channel c, for
one directional light of unit irradiance:

* the heuristic: direct T (the shadow volume's transmittance) and indirect T_i,c, from
  :func:`~vtkvol.plugins.translucency.cpu.translucency_volume_cpu` (the technique's numpy path,
  equal to its GPU path to ~1e-6);
* the physics: the exact direct transmittance (:func:`~vtkvol.reference.transmittance`) and the
  in-scattered fluence E_c of every scattering order ≥ 1
  (:func:`~vtkvol.reference.scattering.inscattered_mc`, phase g, albedo a_c), in units of the
  light's irradiance.

The heuristic has no scattering albedo or phase function; two parameter choices are measured:
the project defaults (k = 0.5, tint 0.75, θ = 15°, colour = the albedo) and a mapping from the
physics (τ_i,c = τ·(1 − g·a_c), i.e. k = 1, tint = g, colour = a: the extinction of
forward-scattered light that stays in the beam, as in similarity scaling; θ = arccos g, the
angle of the phase function's mean cosine). Reported: means of T_i and E, the RMSE of the total
light T + T_i against T + E (what the surface model multiplies the colour by with the weight w =
1, without and with the default normalisation by 1 + w), the weight w* that fits w·T_i to E best
(least squares) with the RMSE left after it, and the correlation of T_i with E (shape agreement
regardless of scale). The last two columns read T_i alone as the *total* light (direct +
scattered), the reading under which a lower extinction for forward-scattered light is physically
motivated (similarity scaling: light scattered forward stays in the beam, so the beam decays
with τ·(1 − g·a)).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from vtkvol.engine.illuminator import LightSpec
from vtkvol.plugins.translucency.cpu import translucency_volume_cpu
from vtkvol.reference import phantom_slab, phantom_sphere_over_slab, transmittance
from vtkvol.reference.lights import DirectionalLight
from vtkvol.reference.scattering import inscattered_mc

Row = dict[str, Any]

#: Light (world, towards the light), mostly from +z; phantoms have 1 µm voxels.
LIGHT = (0.3, 0.2, 1.0)
#: A tissue-like RGB single-scattering albedo: red scatters most, blue is absorbed most.
ALBEDO = (0.95, 0.8, 0.5)
N = 32
PATHS = 128
MAX_BOUNCES = 16


def phantoms(n: int = N) -> dict[str, np.ndarray]:
    """The scenes: a sphere over a slab (α 0.3 / 0.2 per voxel) and a thick homogeneous slab."""
    return {
        "sphere over slab": phantom_sphere_over_slab(n, sphere_opacity=0.3, slab_opacity=0.2),
        "slab 12 µm": phantom_slab(n, thickness=12, opacity=0.15),
    }


def heuristic(opacity: np.ndarray, *, k: float, tint: float, angle: float) -> np.ndarray:
    """The technique's light volume ``[z, y, x, 4]`` (RGB indirect, A direct) with the colour
    set to the albedo everywhere."""
    colour = np.broadcast_to(np.asarray(ALBEDO, np.float32), (*opacity.shape, 3)).copy()
    d = np.asarray(LIGHT, float) / np.linalg.norm(LIGHT)
    spec = LightSpec("directional", (float(d[0]), float(d[1]), float(d[2])), (1.0, 1.0, 1.0))
    return translucency_volume_cpu(opacity.astype(np.float32), colour, (1.0, 1.0, 1.0), spec,
                                   angle=angle, extinction=k, tint=tint)


def compare(name: str, opacity: np.ndarray, g: float, scattered: np.ndarray,
            direct: np.ndarray) -> list[Row]:
    mask = opacity > 0.05
    rows = []
    mapped = (1.0, g, math.degrees(math.acos(g)))
    for label, (k, tint, angle) in (("project defaults", (0.5, 0.75, 15.0)),
                                    ("mapped from a, g", mapped)):
        vol = heuristic(opacity, k=k, tint=tint, angle=angle)
        t_direct = vol[..., 3][mask].astype(np.float64)
        for c, channel in enumerate("RGB"):
            ti = vol[..., c][mask].astype(np.float64)
            e = scattered[..., c][mask].astype(np.float64)
            w = float((ti * e).sum() / max((ti * ti).sum(), 1e-30))
            rows.append({
                "scene": name, "g": g, "setting": f"{label} (k {k:g}, tint {tint:g}, "
                                                  f"θ {angle:.0f}°)",
                "ch": channel,
                "mean T_i": float(ti.mean()), "mean E": float(e.mean()),
                "RMSE T+T_i vs T+E": float(np.sqrt(np.mean((t_direct + ti - direct[mask] - e)
                                                           ** 2))),
                "RMSE (T+T_i)/2 vs T+E": float(np.sqrt(np.mean(
                    (0.5 * (t_direct + ti) - direct[mask] - e) ** 2))),
                "w*": w,
                "RMSE w*·T_i vs E": float(np.sqrt(np.mean((w * ti - e) ** 2))),
                "corr(T_i, E)": _corr(ti, e),
                "RMSE T_i vs T+E": float(np.sqrt(np.mean((ti - direct[mask] - e) ** 2))),
                "corr(T_i, T+E)": _corr(ti, direct[mask] + e),
            })
    return rows


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1]) if a.std() > 0 and b.std() > 0 else float("nan")


def direct_error(name: str, opacity: np.ndarray, exact: np.ndarray) -> Row:
    vol = heuristic(opacity, k=0.5, tint=0.75, angle=15.0)
    mask = opacity > 0.05
    diff = vol[..., 3][mask] - exact[mask]
    return {"scene": name, "RMSE T": float(np.sqrt(np.mean(diff**2))),
            "max |ΔT|": float(np.abs(diff).max())}


def table(rows: Sequence[Row]) -> str:
    keys = list(rows[0])
    out = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        out.append("| " + " | ".join(f"{v:.3f}" if isinstance(v, float) else str(v)
                                     for v in r.values()) + " |")
    return "\n".join(out)


def main() -> None:
    t0 = time.perf_counter()
    rows: list[Row] = []
    direct_rows: list[Row] = []
    light = DirectionalLight(LIGHT)
    for name, opacity in phantoms().items():
        exact = transmittance(opacity, (1.0, 1.0, 1.0), light)
        direct_rows.append(direct_error(name, opacity, exact))
        for g in (0.5, 0.8):
            scattered = inscattered_mc(opacity, (1.0, 1.0, 1.0), light, albedo=ALBEDO,
                                       phase_g=g, n_paths=PATHS, max_bounces=MAX_BOUNCES)
            rows += compare(name, opacity, g, scattered, exact)
    print(f"## Translucency vs multiple scattering ({N}³, {PATHS} paths, ≤ {MAX_BOUNCES} "
          f"bounces, albedo {ALBEDO}, light {LIGHT}; {time.perf_counter() - t0:.0f} s)\n")
    print(table(direct_rows) + "\n")
    print(table(rows))


if __name__ == "__main__":
    main()
