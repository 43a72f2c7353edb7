"""Issue 23: the two truths at seeded pixels — the camera path tracer against the object-space
reference evaluated without its grid (docs/benchmarks.md, "The two truths at seeded pixels").

Per bench phantom scene, light count (1, 3) and mode (single, multiple scattering):

* the GPU camera path tracer (:mod:`vtkvol.engine.renderers.path_tracer`), runs A and B of
  seeds 7 and 8 with ``--paths`` paths per pixel each, read back as float radiance (exposure
  applied, no 8-bit rounding, no clamp); M = (A + B)/2;
* ``--pixels`` pixels drawn (seeded) among those the camera sees the medium in (coverage > 2 %);
* at each, :func:`vtkvol.reference.medium_pixels.medium_radiance`, twice (seeds ``--seed`` and
  the next, for its noise): the medium model integrated along ``--rays``² stratified camera
  rays through the pixel, with each light's transmittance
  (over its extent) and the Monte-Carlo in-scattered light evaluated at ``--points`` points per
  ray, on the medium the path tracer draws (the scalar interpolated, then classified);
* the comparison in levels (255 × radiance × exposure): PSNR(M, pointwise), the camera's noise
  (MSE(A, B)/4), the pointwise reference's (a quarter of its two halves' squared difference),
  the combined floor and ``ratio`` = MSE / combined noise (1 for two unbiased estimates;
  ``agree``: PSNR ≥ combined floor − 1 dB, i.e. ratio ≤ 1.26);
* beside it, at the same pixels, the bench's reference image (grid, VTK's ray caster; with
  ``--refined`` also :mod:`vtkvol.bench.refine`'s refined one) against M clamped to 0…255.

Run: ``python benchmarks/two_truths_pixels.py [--size 24] [--image 64] [--paths 1024]
[--pixels 256] [--rays 3] [--points 8] [--scatter-paths 32] [--scenes ...] [--lights 1,3]
[--modes single,multiple] [--refined]``; one JSON line per setting on stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

import numpy as np

from vtkvol.bench.convergence import with_lights
from vtkvol.bench.measure import Rig, VtkErrors
from vtkvol.bench.reference_technique import MEDIUM_NAME, ReferenceVolume, registered
from vtkvol.bench.references import MediumReference, ReferenceBudget, ReferenceCache
from vtkvol.bench.refine import RefinedReferences, Refinement, render_refined
from vtkvol.bench.scenes import Scene, phantom_scenes
from vtkvol.engine.renderers import set_renderer
from vtkvol.reference.medium_pixels import medium_radiance, pixel_rays, reference_lights
from vtkvol.reference.raymarch import ExtinctionField

SEEDS = (7, 8)


def psnr(mse: float) -> float:
    """PSNR (dB, peak 255) of a mean squared error in levels²."""
    return math.inf if mse <= 0 else 10.0 * math.log10(255.0 ** 2 / mse)


def camera_runs(rig: Rig, mode: str, paths: int) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The path tracer's two float images (h, w, 4: radiance × exposure, coverage; bottom row
    first) and what the reference needs of the set-up (uniforms, lights, shading)."""
    host = rig.illuminator
    images = []
    setup: dict[str, Any] = {}
    for seed in SEEDS:
        rig.reset_view()
        pt = set_renderer(host, "path_tracer", scattering=mode, samples=paths, seed=seed)
        host.converge(max_frames=paths + 8)
        if pt.iteration != paths or pt.last_error is not None:
            raise RuntimeError(f"the path tracer stopped at {pt.iteration}: {pt.last_error}")
        images.append(pt.read_result().astype(np.float64))
        setup = {
            "uniforms": pt._uniform_base(rig.rw),
            "post": pt.classification_reason is None,
            "lights": [(s.kind, s.vector, s.color, s.size, s.falloff_distance)
                       for s in host.light_specs()],
            "ambient": float(rig.volume.GetProperty().GetAmbient(0)) + host.fill,
            "exposure": float(host.exposure), "albedo": float(host.albedo),
            "g": float(host.phase_g), "opacity": host.opacity_volume(),
        }
        set_renderer(host, "raycast")
    return images, setup


def grid_images(rig: Rig, cache: ReferenceCache, scene: Scene, refined: bool
                ) -> dict[str, dict[str, np.ndarray]]:
    """The bench's reference images (uint8, top row first) per mode, and the refined ones."""
    out: dict[str, dict[str, np.ndarray]] = {}
    rig.volume.GetMapper().SetSampleDistance(0.5 * scene.unit_distance)
    wanted = {"single": MediumReference(orders="single", seeds=(0,)),
              "multiple": MediumReference(orders="multiple", seeds=(0, 1))}
    for mode, ref in wanted.items():
        ReferenceVolume.use(ref.volumes(cache, scene))
        rig.set_method(MEDIUM_NAME, {})
        out.setdefault("bench", {})[mode] = rig.image().astype(np.float64)
    if refined:
        fine = RefinedReferences(cache, scene, Refinement())
        imgs = render_refined(fine, rig.rw.GetSize()[0],
                              {"ss": wanted["single"], "ms": wanted["multiple"]})
        fine.release()
        out["refined"] = {"single": imgs["ss"], "multiple": imgs["ms"]}
    return out


def study(scene: Scene, args: argparse.Namespace, cache: ReferenceCache
          ) -> list[dict[str, Any]]:
    """Every mode's comparison for one (lit) scene."""
    out = []
    rig = Rig(args.image)
    try:
        rig.rw.Render()
        rig.load(scene)
        grids = grid_images(rig, cache, scene, args.refined)
        for mode in args.modes:
            t0 = time.perf_counter()
            (a, b), setup = camera_runs(rig, mode, args.paths)
            camera_seconds = time.perf_counter() - t0
            m = (a + b) / 2.0
            u = setup["uniforms"]
            h, w = m.shape[:2]
            rng = np.random.default_rng(args.seed)
            seen = np.argwhere(m[..., 3] > 0.02)  # (y, x), bottom row first
            pick = seen[rng.choice(len(seen), size=min(args.pixels, len(seen)), replace=False)]
            pixels = pick[:, ::-1]
            if setup["post"]:
                field = ExtinctionField(scene.data, scene.spacing, scene.unit_distance,
                                        transfer=scene.opacity_points)
            else:
                field = ExtinctionField(setup["opacity"], scene.spacing, scene.unit_distance)
            t0 = time.perf_counter()
            origin = u["dOrigin"]
            halves = []
            for seed in (args.seed, args.seed + 1):
                o, d = pixel_rays(u["ndcToData"], (w, h), pixels, args.rays,
                                  np.random.default_rng(seed), origin)
                radiance = medium_radiance(
                    field, o, d, reference_lights(setup["lights"], origin),
                    albedo=setup["albedo"], phase_g=setup["g"], ambient=setup["ambient"],
                    orders=mode, emission_points=args.points,
                    scatter_paths=args.scatter_paths, seed=seed)
                halves.append(255.0 * setup["exposure"]
                              * radiance.reshape(len(pixels), args.rays ** 2, 3).mean(axis=1))
            ref_seconds = time.perf_counter() - t0
            # Two independent halves (the rays are stratified, so their spread would overstate
            # the noise): the mean of two has a quarter of their squared difference.
            ref = (halves[0] + halves[1]) / 2.0
            ref_var = (halves[0] - halves[1]) ** 2 / 4.0
            y, x = pick[:, 0], pick[:, 1]
            cam = 255.0 * m[y, x, :3]
            cam_var = (255.0 * (a[y, x, :3] - b[y, x, :3])) ** 2 / 4.0
            err = float(np.mean((cam - ref) ** 2))
            noise = float(np.mean(cam_var)) + float(np.mean(ref_var))
            rec: dict[str, Any] = {
                "scene": scene.name, "lights": len(scene.lights), "mode": mode,
                "paths": args.paths, "pixels": len(pixels),
                "psnr": round(psnr(err), 2),
                "camera_floor": round(psnr(float(np.mean(cam_var))), 2),
                "reference_floor": round(psnr(float(np.mean(ref_var))), 2),
                "combined_floor": round(psnr(noise), 2),
                "ratio": round(err / noise, 3),
                "agree": bool(psnr(err) >= psnr(noise) - 1.0),
                "mean_difference": round(float(np.mean(cam - ref)), 3),
                "mean_difference_se": round(float(np.sqrt(np.sum(cam_var + ref_var)
                                                          / 3.0)) / len(pixels), 3),
                "mean_level": round(float(np.mean(ref)), 2),
                "camera_seconds": round(camera_seconds, 1),
                "reference_seconds": round(ref_seconds, 1),
            }
            clipped = np.clip(cam, 0.0, 255.0)
            for name, images in grids.items():
                img = images[mode][h - 1 - y, x]
                rec[f"psnr_{name}"] = round(psnr(float(np.mean((clipped - img) ** 2))), 2)
            rec["psnr_pointwise_clipped"] = round(psnr(float(np.mean(
                (clipped - np.clip(ref, 0.0, 255.0)) ** 2))), 2)
            out.append(rec)
    finally:
        rig.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=24)
    parser.add_argument("--image", type=int, default=64)
    parser.add_argument("--paths", type=int, default=1024)
    parser.add_argument("--pixels", type=int, default=256)
    parser.add_argument("--rays", type=int, default=3, help="stratified rays per pixel side")
    parser.add_argument("--points", type=int, default=8, help="emission points per ray")
    parser.add_argument("--scatter-paths", type=int, default=32,
                        help="Monte-Carlo paths per emission point")
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--scenes", default="sphere_over_slab,hollow_sphere,cells")
    parser.add_argument("--lights", default="1,3")
    parser.add_argument("--modes", default="single,multiple")
    parser.add_argument("--refined", action="store_true",
                        help="also compare the refined grid reference at the same pixels")
    args = parser.parse_args()
    args.modes = args.modes.split(",")
    if not set(args.modes) <= {"single", "multiple"}:
        raise SystemExit(f"vtkvol: --modes: {args.modes} must be single and/or multiple")
    for name, value in (("--paths", args.paths), ("--pixels", args.pixels),
                        ("--rays", args.rays), ("--points", args.points),
                        ("--scatter-paths", args.scatter_paths)):
        if value < 1:
            raise SystemExit(f"vtkvol: {name}: {value} must be at least 1")
    cache = ReferenceCache(ReferenceBudget(step=0.5, light_rays=32, scatter_paths=32))
    names = args.scenes.split(",")
    with VtkErrors(), registered():
        for base in phantom_scenes(args.size):
            if base.name not in names:
                continue
            for count in (int(c) for c in args.lights.split(",")):
                for rec in study(with_lights(base, count), args, cache):
                    print(json.dumps(rec), flush=True)


if __name__ == "__main__":
    main()
