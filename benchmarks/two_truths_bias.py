"""Issue 23: is the gap between the two truths noise or bias? (docs/benchmarks.md, "The two
truths: noise or bias").

The camera path tracer (GPU, :mod:`vtkvol.engine.renderers.path_tracer`, runs A and B with
seeds 7 and 8) against the object-space reference (:class:`vtkvol.bench.references.MediumReference`
shaded by VTK's ray caster, as ``vtkvol bench --scattering`` does) on the bench's phantom
scenes, at 1, 2, 4, … up to ``--paths`` camera paths per pixel. Per checkpoint: PSNR(M, ref)
of the camera mean M = (A + B)/2 against the reference, and the combined noise floor (the
camera's MSE(A, B)/4 plus, for multiple scattering, the reference's MSE(ms_a, ms_b)/4). An
unbiased pair gains ~3 dB per doubling of the paths until the floor; a plateau below the
floor is a bias. ``single`` compares the path tracer's single-scattering mode with the
direct-light (``ss``) reference, ``multiple`` the full estimator with the ``ms`` reference.
Per region (background; the object's pixels below / above the median of the ``ss`` image:
"shadowed" / "lit") the mean signed difference M − ref in levels (0…255) and its standard
error from A − B.

Localisation switches: ``--pad N`` surrounds the volume with N empty voxels (no medium at the
box faces); ``--refine`` computes the reference on a grid refined 2× per axis (2n − 1 points
covering the same box; the data are the trilinear α resampled there, which is the same
medium, the unit distance is kept); ``--supersample K`` also renders the reference at K× the
image size and box-filters it, as the path tracer's jittered pixel does.

``--refined`` also computes, in the same run, the refined reference of
:mod:`vtkvol.bench.refine` (light grid ``--factor``× per axis, step ``--refined-step``,
``--refined-supersample``× pixel box; the in-scattered light of the bench's reference
upsampled) and adds ``psnr_refined`` (PSNR(M, refined reference)) and the refined region means
to every checkpoint: the bench's reference and the refined one against the same camera runs.
``--variants 4:0.125:4,2:0.0625:8:0`` adds more refined references (grid factor : step in
unit distances : supersampling [: face_voxels, where the in-scattered light is recomputed on
the fine grid; default 1]), each as ``psnr_<variant>``, to locate what remains.

Run (one scene and light count takes 1–4 minutes on a 2-core llvmpipe machine at the
defaults): ``python benchmarks/two_truths_bias.py [--size 24] [--image 64] [--paths 1024]
[--ref-paths 32] [--scenes sphere_over_slab,hollow_sphere,cells] [--lights 1,3]
[--modes multiple,single] [--pad 0] [--refine] [--supersample 1] [--refined --factor 2]``;
one JSON line per checkpoint on stdout.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from typing import Any

import numpy as np

from vtkvol.bench.convergence import checkpoints, with_lights
from vtkvol.bench.measure import Rig, VtkErrors
from vtkvol.bench.reference_technique import MEDIUM_NAME, ReferenceVolume, registered
from vtkvol.bench.references import MediumReference, ReferenceBudget, ReferenceCache
from vtkvol.bench.refine import (
    RefinedReferences,
    Refinement,
    box_filter,
    refined_scene,
    render_refined,
)
from vtkvol.bench.scenes import Scene, phantom_scenes
from vtkvol.engine.renderers import set_renderer

SEEDS = (7, 8)


def mse(a: np.ndarray, b: np.ndarray) -> float:
    """Mean squared difference in levels²."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return float(np.mean(d * d))


def psnr(err: float) -> float:
    """PSNR (dB, peak 255) of a mean squared error in levels²."""
    return float("inf") if err <= 0 else 10.0 * np.log10(255.0 ** 2 / err)


def regions(ss: np.ndarray) -> dict[str, np.ndarray]:
    """Pixel masks from the direct-light reference image: background, and the object split at
    its median luminance into shadowed and lit."""
    lum = ss.astype(np.float64).mean(axis=2)
    bg = lum <= lum.min() + 0.5
    med = np.median(lum[~bg]) if (~bg).any() else 0.0
    return {"background": bg, "shadowed": ~bg & (lum < med), "lit": ~bg & (lum >= med)}


def reference_image(rig: Rig, cache: ReferenceCache, orders: str, seeds: tuple[int, ...],
                    step: float) -> np.ndarray:
    """The reference of ``orders`` ("single" / "multiple") for the loaded scene, ray cast at
    ``step`` × the unit distance."""
    assert rig.scene is not None
    rig.volume.GetMapper().SetSampleDistance(step * rig.scene.unit_distance)
    ReferenceVolume.use(MediumReference(orders=orders, seeds=seeds).volumes(cache, rig.scene))
    rig.set_method(MEDIUM_NAME, {})
    return rig.image().astype(np.float64)


def study(scene: Scene, args: argparse.Namespace, cache: ReferenceCache) -> list[dict[str, Any]]:
    """Every mode's checkpoints for one (lit) scene."""
    out: list[dict[str, Any]] = []
    rig = Rig(args.image)
    try:
        rig.rw.Render()
        rig.load(scene)
        t0 = time.perf_counter()
        refs = {"ss": reference_image(rig, cache, "single", (0,), args.step)}
        if "multiple" in args.modes:
            for name, seeds in (("ms_a", (0,)), ("ms_b", (1,)), ("ms", (0, 1))):
                refs[name] = reference_image(rig, cache, "multiple", seeds, args.step)
        ref_seconds = time.perf_counter() - t0
        reg = regions(refs["ss"])
        images: dict[tuple[str, int, int], np.ndarray] = {}
        for mode in args.modes:
            for seed in SEEDS:
                rig.reset_view()
                pt = set_renderer(rig.illuminator, "path_tracer", scattering=mode,
                                  samples=args.paths, seed=seed)
                for target in checkpoints(args.paths):
                    while pt.iteration < target - 1:
                        rig.rw.Render()
                    images[(mode, seed, target)] = rig.image().astype(np.float64)
                set_renderer(rig.illuminator, "raycast")
    finally:
        rig.close()
    if args.supersample > 1:
        k = args.supersample
        big = Rig(args.image * k)
        try:
            big.rw.Render()
            big.load(scene)
            for name, orders, seeds in (("ss", "single", (0,)), ("ms", "multiple", (0, 1))):
                if name in refs:
                    img = reference_image(big, cache, orders, seeds, args.step)
                    refs[name] = box_filter(img, k)
        finally:
            big.close()
    refined: dict[str, np.ndarray] = {}
    refined_seconds = 0.0
    if args.refined:
        t0 = time.perf_counter()
        fine = RefinedReferences(cache, scene, Refinement(args.factor, args.refined_step,
                                                          args.refined_supersample,
                                                          args.face_voxels))
        wanted = {"ss": MediumReference(orders="single", seeds=(0,))}
        if "multiple" in args.modes:
            wanted["ms"] = MediumReference(orders="multiple", seeds=(0, 1))
        refined = render_refined(fine, args.image, wanted)
        fine.release()
        refined_seconds = time.perf_counter() - t0
    variants: dict[str, dict[str, np.ndarray]] = {}
    for text, refinement in args.refinements.items():
        fine = RefinedReferences(cache, scene, refinement)
        wanted = {"ss": MediumReference(orders="single", seeds=(0,))}
        if "multiple" in args.modes:
            wanted["ms"] = MediumReference(orders="multiple", seeds=(0, 1))
        variants[text] = render_refined(fine, args.image, wanted)
        fine.release()
    ref_noise = mse(refs["ms_a"], refs["ms_b"]) / 4.0 if "ms_a" in refs else 0.0
    for mode in args.modes:
        ref = refs["ms" if mode == "multiple" else "ss"]
        for target in checkpoints(args.paths):
            a, b = images[(mode, SEEDS[0], target)], images[(mode, SEEDS[1], target)]
            m = (a + b) / 2.0
            cam = mse(a, b) / 4.0
            rec: dict[str, Any] = {
                "scene": scene.name, "lights": len(scene.lights), "mode": mode,
                "paths": target, "psnr": round(psnr(mse(m, ref)), 2),
                "camera_floor": round(psnr(cam), 2),
                "combined_floor": round(psnr(cam + (ref_noise if mode == "multiple" else 0.0)),
                                        2),
                "reference_floor": round(psnr(ref_noise), 2) if mode == "multiple" else None,
                "reference_seconds": round(ref_seconds, 1),
            }
            if refined:
                fine_ref = refined["ms" if mode == "multiple" else "ss"]
                rec["psnr_refined"] = round(psnr(mse(m, fine_ref)), 2)
                rec["refined_seconds"] = round(refined_seconds, 1)
                for name, mask in reg.items():
                    if mask.any():
                        rec[name + "_refined"] = round(float((m - fine_ref)[mask].mean()), 3)
            for text, variant in variants.items():
                rec["psnr_" + text] = round(psnr(mse(m, variant["ms" if mode == "multiple"
                                                              else "ss"])), 2)
            for name, mask in reg.items():
                if mask.any():
                    rec[name] = round(float((m - ref)[mask].mean()), 3)
                    rec[name + "_se"] = round(float(np.sqrt(
                        ((a - b)[mask] ** 2).mean() / 4.0 / mask.sum())), 3)
            out.append(rec)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=24)
    parser.add_argument("--image", type=int, default=64)
    parser.add_argument("--paths", type=int, default=1024)
    parser.add_argument("--ref-paths", type=int, default=32)
    parser.add_argument("--scenes", default="sphere_over_slab,hollow_sphere,cells")
    parser.add_argument("--lights", default="1,3")
    parser.add_argument("--modes", default="multiple,single")
    parser.add_argument("--step", type=float, default=0.5,
                        help="the reference's ray-caster step (unit distances)")
    parser.add_argument("--pad", type=int, default=0)
    parser.add_argument("--refine", action="store_true")
    parser.add_argument("--supersample", type=int, default=1)
    parser.add_argument("--refined", action="store_true",
                        help="also compare with vtkvol.bench.refine's refined reference")
    parser.add_argument("--factor", type=int, default=2, help="the refined light grid's factor")
    parser.add_argument("--refined-step", type=float, default=0.125)
    parser.add_argument("--refined-supersample", type=int, default=4)
    parser.add_argument("--face-voxels", type=float, default=1.0,
                        help="in-scattered light recomputed this close to a box face")
    parser.add_argument("--variants", default="",
                        help="more refined references, factor:step:supersample[:face_voxels],"
                             "... (each adds psnr_<variant>)")
    args = parser.parse_args()
    args.modes = args.modes.split(",")
    if not set(args.modes) <= {"single", "multiple"}:
        raise SystemExit(f"vtkvol: --modes: {args.modes} must be single and/or multiple")
    args.refinements = {}
    for text in filter(None, args.variants.split(",")):
        try:
            factor, step, supersample, *faces = text.split(":")
            if len(faces) > 1:
                raise ValueError("too many fields")
            args.refinements[text] = Refinement(int(factor), float(step), int(supersample),
                                                float(faces[0]) if faces else 1.0)
        except ValueError as exc:
            raise SystemExit(f"vtkvol: --variants: {text!r} is not "
                             f"factor:step:supersample[:face_voxels] ({exc})") from None
    cache = ReferenceCache(ReferenceBudget(step=0.5, light_rays=32, scatter_paths=args.ref_paths))
    names = args.scenes.split(",")
    with VtkErrors(), registered():
        for base in phantom_scenes(args.size):
            if base.name not in names:
                continue
            if args.pad:
                base = dataclasses.replace(base, data=np.pad(base.data, args.pad))
            if args.refine:
                try:
                    base = refined_scene(base)
                except ValueError as exc:
                    raise SystemExit(f"vtkvol: --refine: {exc}") from None
            for count in (int(c) for c in args.lights.split(",")):
                for rec in study(with_lights(base, count), args, cache):
                    print(json.dumps(rec), flush=True)


if __name__ == "__main__":
    main()
