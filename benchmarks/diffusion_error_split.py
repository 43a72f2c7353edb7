"""Where the grid-diffusion techniques lose in the image (issue 24): the image error split into
the direct and the scattered term.

For each phantom scene, technique (KD ``convection_diffusion``, HD ``hybrid_diffusion``) and
``diffusion_model``, the technique refines to its own end on the bench rig (as the convergence
study does, :mod:`vtkvol.bench.convergence`); then its two shown textures — the direct light
and the scattered light — are read back and rendered through the bench's medium reference
technique (:class:`~vtkvol.bench.reference_technique.MediumReferenceVolume`, the same host
medium shading), mixed with the reference's own volumes (exact transmittance over the light's
extent, Monte-Carlo in-scattered light, :class:`~vtkvol.bench.references.ReferenceCache`):

* ``image``: the technique's own image vs the multiple-scattering reference ``ms`` (what the
  convergence study reports);
* ``(a) direct``: the technique's direct light only vs the single-scattering reference ``ss``;
* ``(b) total``: technique direct + technique scattered (re-rendered) vs ``ms`` — equal to
  ``image`` up to the GPU's rounding, which checks the read-back;
* ``(c) T.d + R.s``: technique direct + the reference's scattered light vs ``ms``: the error
  the direct term alone leaves;
* ``(d) R.d + T.s``: the reference's direct light + the technique's scattered light vs ``ms``:
  the error the scattered term alone leaves.

PSNR in dB (peak 255, 8-bit images). The scattered light must be on the data grid
(``scatter_grid="full"``, the default) so that both terms share the reference's grid. HD's
direct light is RGB irradiance (its shader adds it to the in-scattered light, phase function
isotropic for these scenes), so it is rendered as irradiance with zero visibility.

Run: ``nice -n 19 python benchmarks/diffusion_error_split.py [--size 20] [--image 64]
[--lights 1] [--scenes sphere_over_slab,...] [--traced-orders K] [--label before]`` (prints
Markdown). ``--label``
only names the rows; run it once with ``PYTHONPATH`` pointing at another checkout to get that
code's figures in the same table.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

import numpy as np

from vtkvol.bench.convergence import with_lights
from vtkvol.bench.measure import Rig, VtkErrors
from vtkvol.bench.reference_technique import (
    MEDIUM_NAME,
    ReferenceVolume,
    ReferenceVolumes,
    registered,
)
from vtkvol.bench.references import (
    FULL_BUDGET,
    MediumReference,
    ReferenceBudget,
    ReferenceCache,
)
from vtkvol.bench.scenes import phantom_scenes
from vtkvol.engine.technique import technique_class
from vtkvol.reference import image_metrics

TECHNIQUES = (("KD", "convection_diffusion"), ("HD", "hybrid_diffusion"))
MODELS = ("source", "published")


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    m = image_metrics(a, b)
    return float(m["psnr"]) if m["psnr"] is not None else math.inf


def shown_fields(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """The active technique's (direct, scattered) light read back: ``[z, y, x, c]``; the
    scattered light includes HD's traced orders (``traced_orders``) where it has them."""
    tech: Any = rig.illuminator.technique
    gpu = tech._gpu
    direct, scattered = gpu.shown if gpu is not None else (tech._direct, tech._scattered)
    traced = (getattr(gpu, "traced", None) if gpu is not None
              else getattr(tech, "_traced_texture", None))
    d, s = direct.download(), scattered.download()[..., :3]
    if traced is not None:
        s = s + traced.download()[..., :3]
    if d.ndim == 3:
        d = d[..., None]
    return d, s


def technique_volumes(short: str, direct: np.ndarray, scattered: np.ndarray | None,
                      lights: int, shape: tuple[int, ...]) -> ReferenceVolumes:
    """The technique's fields as reference volumes (``scattered`` None: direct only)."""
    if short == "KD":
        vis = tuple(np.clip(direct[..., i], 0.0, 1.0).astype(np.float32)
                    for i in range(lights))
        irr = None if scattered is None else np.maximum(scattered, 0.0).astype(np.float32)
        return ReferenceVolumes(vis, None, irr)
    zero = tuple(np.zeros(shape, np.float32) for _ in range(lights))
    irr = np.maximum(direct[..., :3], 0.0)
    if scattered is not None:
        irr = irr + np.maximum(scattered, 0.0)
    return ReferenceVolumes(zero, None, irr.astype(np.float32))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=20)
    ap.add_argument("--image", type=int, default=64)
    ap.add_argument("--lights", type=int, default=1)
    ap.add_argument("--paths", type=int, default=32)
    ap.add_argument("--max-seconds", type=float, default=60.0)
    ap.add_argument("--label", default="")
    ap.add_argument("--techniques", default="KD,HD")
    ap.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    ap.add_argument("--traced-orders", type=int, default=None,
                    help="the source model's traced_orders where the technique has it "
                         "(default: the technique's default; 0: the diffusion from the direct "
                         "light alone, the code before traced orders)")
    args = ap.parse_args(argv)
    budget = ReferenceBudget(step=0.5, light_rays=8, scatter_paths=args.paths,
                             scatter_bounces=FULL_BUDGET.scatter_bounces)
    cache = ReferenceCache(budget)
    wanted = set(args.techniques.split(","))
    print("| code | scene | lights | technique | model | iterations | image | (a) direct vs ss | "
          "(b) total | (c) T.d + R.s | (d) R.d + T.s | ss vs ms | floor |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    with VtkErrors(), registered():
        rig = Rig(args.image)
        try:
            rig.rw.Render()

            def render(volumes: ReferenceVolumes) -> np.ndarray:
                ReferenceVolume.use(volumes)
                rig.set_method(MEDIUM_NAME, {})
                return rig.image()

            for scene in phantom_scenes(args.size):
                if args.scenes and scene.name not in args.scenes.split(","):
                    continue
                lit = with_lights(scene, args.lights)
                rig.load(lit)
                ms_vol = MediumReference(seeds=(0, 1)).volumes(cache, lit)
                ss_vol = MediumReference(orders="single").volumes(cache, lit)
                ms = render(ms_vol)
                ss = render(ss_vol)
                floor = psnr(render(MediumReference(seeds=(0,)).volumes(cache, lit)),
                             render(MediumReference(seeds=(1,)).volumes(cache, lit))) + 6.02
                assert ms_vol.irradiance is not None
                ref_s = ms_vol.irradiance
                ref_s = ref_s[..., None].repeat(3, -1) if ref_s.ndim == 3 else ref_s
                for short, method in TECHNIQUES:
                    if short not in wanted:
                        continue
                    for model in MODELS:
                        t0 = time.perf_counter()
                        values: dict[str, Any] = {"diffusion_model": model}
                        if (args.traced_orders is not None and model == "source"
                                and "traced_orders" in technique_class(method).defaults()):
                            values["traced_orders"] = args.traced_orders
                        rig.set_method(method, values)
                        iterations, _ = rig.refine(args.max_seconds)
                        image = rig.image()
                        direct, scattered = shown_fields(rig)
                        if scattered.shape[:3] != direct.shape[:3]:
                            raise SystemExit("vtkvol: diffusion_error_split needs "
                                             "scatter_grid='full'")
                        n = len(lit.lights)
                        shape = direct.shape[:3]
                        row = {
                            "image": psnr(image, ms),
                            "a": psnr(render(technique_volumes(short, direct, None, n, shape)),
                                      ss),
                            "b": psnr(render(technique_volumes(short, direct, scattered, n,
                                                               shape)), ms),
                            "c": psnr(render(technique_volumes(short, direct, ref_s, n,
                                                               shape)), ms),
                            "d": psnr(render(ReferenceVolumes(
                                ss_vol.visibility, None,
                                np.maximum(scattered, 0.0).astype(np.float32))), ms),
                        }
                        print(f"| {args.label} | {scene.name} | {args.lights} | {short} | "
                              f"{model} | {iterations} | {row['image']:.1f} | {row['a']:.1f} | "
                              f"{row['b']:.1f} | {row['c']:.1f} | {row['d']:.1f} | "
                              f"{psnr(ss, ms):.1f} | {floor:.1f} |", flush=True)
                        print(f"  ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
                cache.clear_scene(lit)
        finally:
            rig.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
