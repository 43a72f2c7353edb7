"""Issue 23: the two truths compared at seeded pixels, with the object-space reference evaluated
without its grid (:mod:`vtkvol.reference.medium_pixels`; docs/benchmarks.md, "The two truths
at seeded pixels").

The camera path tracer's two runs A and B (float radiance read back from its accumulation
buffer: exposure applied, no 8-bit rounding, no clamp) against the medium model integrated
along stratified rays through the same pixels, in two independent halves. Both sides are
unbiased estimates of the same pixel, so the mean squared difference should equal the sum of
their noises: ``ratio`` = MSE / (camera noise + reference noise) is 1 for an unbiased pair,
and ``agree`` (issue 23's criterion, PSNR ≥ combined floor − 1 dB) is ratio ≤ 1.26. Levels
are 255 × radiance (the display's scale, unclamped).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from vtkvol.bench.scenes import Scene
from vtkvol.reference.medium_pixels import medium_radiance, pixel_rays, reference_lights
from vtkvol.reference.raymarch import ExtinctionField


@dataclass(frozen=True)
class PointwiseBudget:
    """``pixels`` seeded among those the camera sees the medium in (coverage > 2 %);
    ``rays``² stratified rays per pixel in each of two halves; ``points`` emission points per
    ray; ``scatter_paths`` Monte-Carlo paths per point (multiple scattering)."""

    pixels: int = 256
    rays: int = 3
    points: int = 8
    scatter_paths: int = 32
    seed: int = 11

    def __post_init__(self) -> None:
        for name in ("pixels", "rays", "points", "scatter_paths"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, not {getattr(self, name)}")


def camera_setup(rig: Any, pt: Any) -> dict[str, Any]:
    """What the pointwise reference needs of the path tracer ``pt`` running on ``rig``: its
    camera (NDC → dataset µm), lights, shading and whether it classifies after interpolation."""
    host = rig.illuminator
    return {
        "uniforms": pt._uniform_base(rig.rw),
        "post": pt.classification_reason is None,
        "lights": [(s.kind, s.vector, s.color, s.size, s.falloff_distance)
                   for s in host.light_specs()],
        "ambient": float(rig.volume.GetProperty().GetAmbient(0)) + host.fill,
        "exposure": float(host.exposure), "albedo": float(host.albedo),
        "g": float(host.phase_g), "opacity": host.opacity_volume(),
    }


def medium_field(scene: Scene, setup: dict[str, Any]) -> ExtinctionField:
    """The medium the path tracer draws: the scene's data classified after interpolation where
    it does so, else the host's classified opacity interpolated."""
    if setup["post"]:
        return ExtinctionField(scene.data, scene.spacing, scene.unit_distance,
                               transfer=scene.opacity_points)
    return ExtinctionField(setup["opacity"], scene.spacing, scene.unit_distance)


def _psnr(mse: float) -> float:
    return math.inf if mse <= 0 else 10.0 * math.log10(255.0 ** 2 / mse)


def compare(scene: Scene, setup: dict[str, Any], camera_a: np.ndarray, camera_b: np.ndarray,
            orders: str, budget: PointwiseBudget = PointwiseBudget()
            ) -> tuple[dict[str, Any], np.ndarray]:
    """The two truths at ``budget.pixels`` seeded pixels: ``camera_a``/``camera_b`` are the
    path tracer's results (h, w, 4, bottom row first) of ``orders`` ("single" / "multiple").
    Returns the fields (PSNRs in dB, noises as floors, ``ratio``, ``agree``, the mean signed
    difference camera − reference in levels and its standard error, seconds) and the pixels
    as (y, x) rows, bottom row first."""
    a = np.asarray(camera_a, np.float64)
    b = np.asarray(camera_b, np.float64)
    h, w = a.shape[:2]
    mean = (a + b) / 2.0
    seen = np.argwhere(mean[..., 3] > 0.02)
    if len(seen) == 0:
        raise ValueError("the camera sees no medium: no pixel to compare")
    rng = np.random.default_rng(budget.seed)
    pick = seen[rng.choice(len(seen), size=min(budget.pixels, len(seen)), replace=False)]
    u = setup["uniforms"]
    field = medium_field(scene, setup)
    lights = reference_lights(setup["lights"], u["dOrigin"])
    t0 = time.perf_counter()
    halves = []
    for seed in (budget.seed, budget.seed + 1):
        o, d = pixel_rays(u["ndcToData"], (w, h), pick[:, ::-1], budget.rays,
                          np.random.default_rng(seed), u["dOrigin"])
        radiance = medium_radiance(
            field, o, d, lights, albedo=setup["albedo"], phase_g=setup["g"],
            ambient=setup["ambient"], orders=orders, emission_points=budget.points,
            scatter_paths=budget.scatter_paths, seed=seed)
        halves.append(255.0 * setup["exposure"]
                      * radiance.reshape(len(pick), budget.rays ** 2, 3).mean(axis=1))
    seconds = time.perf_counter() - t0
    # Two independent halves (the rays are stratified, so their spread would overstate the
    # noise): the mean of two estimates has a quarter of their squared difference.
    ref = (halves[0] + halves[1]) / 2.0
    ref_var = (halves[0] - halves[1]) ** 2 / 4.0
    y, x = pick[:, 0], pick[:, 1]
    cam = 255.0 * mean[y, x, :3]
    cam_var = (255.0 * (a[y, x, :3] - b[y, x, :3])) ** 2 / 4.0
    err = float(np.mean((cam - ref) ** 2))
    noise = float(np.mean(cam_var)) + float(np.mean(ref_var))
    clipped = float(np.mean((np.clip(cam, 0, 255) - np.clip(ref, 0, 255)) ** 2))
    fields = {
        "pixels": len(pick), "psnr": _psnr(err),
        "camera_floor": _psnr(float(np.mean(cam_var))),
        "reference_floor": _psnr(float(np.mean(ref_var))),
        "combined_floor": _psnr(noise), "ratio": err / noise if noise > 0 else math.inf,
        "agree": bool(_psnr(err) >= _psnr(noise) - 1.0),
        # channels are one estimate each (white scenes): the pixel is the unit of noise
        "mean_difference": float(np.mean(cam - ref)),
        "mean_difference_se": float(np.sqrt(np.sum(cam_var + ref_var) / 3.0)) / len(pick),
        "mean_level": float(np.mean(ref)), "psnr_clipped": _psnr(clipped),
        "seconds": seconds,
    }
    return fields, pick
