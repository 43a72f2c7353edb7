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
``--chart OUT.png --records RUN.jsonl`` draws a finished run's records instead.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

import numpy as np

from vtkvol.bench.convergence import CAMERA_SEEDS, with_lights
from vtkvol.bench.measure import Rig, VtkErrors
from vtkvol.bench.pointwise import PointwiseBudget, camera_setup, compare
from vtkvol.bench.reference_technique import MEDIUM_NAME, ReferenceVolume, registered
from vtkvol.bench.references import MediumReference, ReferenceBudget, ReferenceCache
from vtkvol.bench.refine import RefinedReferences, Refinement, render_refined
from vtkvol.bench.scenes import Scene, phantom_scenes
from vtkvol.engine.renderers import set_renderer


def psnr(mse: float) -> float:
    """PSNR (dB, peak 255) of a mean squared error in levels²."""
    return math.inf if mse <= 0 else 10.0 * math.log10(255.0 ** 2 / mse)


def camera_runs(rig: Rig, mode: str, paths: int) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The path tracer's two float images (h, w, 4: radiance × exposure, coverage; bottom row
    first) and what the reference needs of the set-up."""
    host = rig.illuminator
    images = []
    setup: dict[str, Any] = {}
    for seed in CAMERA_SEEDS:
        rig.reset_view()
        pt = set_renderer(host, "path_tracer", scattering=mode, samples=paths, seed=seed)
        host.converge(max_frames=paths + 8)
        if pt.iteration != paths or pt.last_error is not None:
            raise RuntimeError(f"the path tracer stopped at {pt.iteration}: {pt.last_error}")
        images.append(pt.read_result().astype(np.float64))
        if seed == CAMERA_SEEDS[-1]:  # the same set-up for both runs
            setup = camera_setup(rig, pt)
        set_renderer(host, "raycast")
    return images, setup


def grid_images(rig: Rig, cache: ReferenceCache, scene: Scene, refined: bool,
                modes: list[str]) -> dict[str, dict[str, np.ndarray]]:
    """The bench's reference images (uint8, top row first) of ``modes``, and the refined ones."""
    out: dict[str, dict[str, np.ndarray]] = {}
    rig.volume.GetMapper().SetSampleDistance(0.5 * scene.unit_distance)
    wanted = {mode: MediumReference(orders=mode, seeds=(0,) if mode == "single" else (0, 1))
              for mode in modes}
    for mode, ref in wanted.items():
        ReferenceVolume.use(ref.volumes(cache, scene))
        rig.set_method(MEDIUM_NAME, {})
        out.setdefault("bench", {})[mode] = rig.image().astype(np.float64)
    if refined:
        fine = RefinedReferences(cache, scene, Refinement())
        imgs = render_refined(fine, rig.rw.GetSize()[0], wanted)
        fine.release()
        out["refined"] = imgs
    return out


def study(scene: Scene, args: argparse.Namespace, cache: ReferenceCache
          ) -> list[dict[str, Any]]:
    """Every mode's comparison for one (lit) scene."""
    out = []
    budget = PointwiseBudget(args.pixels, args.rays, args.points, args.scatter_paths, args.seed)
    rig = Rig(args.image)
    try:
        rig.rw.Render()
        rig.load(scene)
        grids = grid_images(rig, cache, scene, args.refined, args.modes)
        for mode in args.modes:
            t0 = time.perf_counter()
            (a, b), setup = camera_runs(rig, mode, args.paths)
            camera_seconds = time.perf_counter() - t0
            fields, pick = compare(scene, setup, a, b, mode, budget)
            rec: dict[str, Any] = {"scene": scene.name, "lights": len(scene.lights),
                                   "mode": mode, "paths": args.paths}
            rec.update({k: round(v, 3) if isinstance(v, float) else v
                        for k, v in fields.items()})
            rec["camera_seconds"] = round(camera_seconds, 1)
            h = a.shape[0]
            y, x = pick[:, 0], pick[:, 1]
            clipped = np.clip(255.0 * (a[y, x, :3] + b[y, x, :3]) / 2.0, 0.0, 255.0)
            for name, images in grids.items():
                img = images[mode][h - 1 - y, x]
                rec[f"psnr_{name}"] = round(psnr(float(np.mean((clipped - img) ** 2))), 2)
            out.append(rec)
    finally:
        rig.close()
    return out


def chart(path: str, records: list[dict[str, Any]]) -> None:
    """Two panels per setting: left, PSNR(M, pointwise) against the combined floor − 1 dB
    (radiance, unclamped: the estimators' agreement); right, the display levels (clamped) at
    the same pixels for the bench's grid reference, the refined one and the pointwise one."""
    from vtkvol.bench.report_charts import _pyplot

    plt = _pyplot()
    labels = [f"{r['scene'].replace('_', ' ')}\n{r['lights']} light{'s' if r['lights'] > 1 else ''}"
              f", {r['mode']}" for r in records]
    x = np.arange(len(records))
    fig, (left, right) = plt.subplots(1, 2, figsize=(14, 4.8), sharey=False)
    left.bar(x, [r["psnr"] for r in records], 0.6, label="PSNR(camera, pointwise)",
             color="#4c72b0")
    left.plot(x, [r["combined_floor"] - 1.0 for r in records], "k_", markersize=22,
              markeredgewidth=2, label="combined floor − 1 dB")
    left.set_ylim(min(r["psnr"] for r in records) - 5,
                  max(max(r["psnr"], r["combined_floor"]) for r in records) + 6)
    left.set_title("the two truths, radiance (agree: bar reaches the line)")
    right_series = [("psnr_bench", "bench's grid reference", "#dd8452"),
                    ("psnr_refined", "refined grid reference", "#55a868"),
                    ("psnr_clipped", "pointwise reference", "#4c72b0")]
    shown = [s for s in right_series if all(s[0] in r for r in records)]
    width = 0.8 / max(1, len(shown))
    for i, (key, label, colour) in enumerate(shown):
        right.bar(x + (i - (len(shown) - 1) / 2) * width, [r[key] for r in records], width,
                  label=label, color=colour)
    right.set_ylim(min(r[k] for r in records for k, _l, _c in shown) - 5,
                   max(r[k] for r in records for k, _l, _c in shown) + 6)
    right.set_title("against the camera path tracer, display levels, same pixels")
    for ax in (left, right):
        ax.set_xticks(x, labels, rotation=60, ha="right", fontsize=7)
        ax.set_ylabel("PSNR (dB)")
        ax.legend(fontsize=8, loc="upper center", ncol=3)
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
    parser.add_argument("--chart", help="draw the records of --records into this PNG")
    parser.add_argument("--records", help="a finished run's JSON lines (with --chart)")
    args = parser.parse_args()
    if args.chart:
        if not args.records:
            raise SystemExit("vtkvol: --chart needs --records RUN.jsonl")
        try:
            with open(args.records, encoding="utf-8") as fh:
                records = [json.loads(line) for line in fh if line.strip()]
        except (OSError, ValueError) as exc:
            raise SystemExit(f"vtkvol: --records {args.records}: {exc}") from None
        if not records:
            raise SystemExit(f"vtkvol: --records {args.records}: no records")
        chart(args.chart, records)
        return
    args.modes = args.modes.split(",")
    if not set(args.modes) <= {"single", "multiple"}:
        raise SystemExit(f"vtkvol: --modes: {args.modes} must be single and/or multiple")
    if args.paths < 1:
        raise SystemExit(f"vtkvol: --paths: {args.paths} must be at least 1")
    try:
        PointwiseBudget(args.pixels, args.rays, args.points, args.scatter_paths, args.seed)
    except ValueError as exc:
        raise SystemExit(f"vtkvol: {exc}") from None
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
