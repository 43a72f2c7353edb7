"""Half-angle slicing against the ``translucency`` technique, both against the camera path
tracer, on the bench's phantom scenes (for docs/translucency.md §3 and docs/benchmarks.md).

Run from the checkout: ``python benchmarks/half_angle_vs_translucency.py [--size N]
[--image N] [--paths N]`` prints a markdown table (about 5 minutes on two llvmpipe cores at the
defaults: 32³ scenes, 96² images, 512 + 512 paths per pixel).

**Truths.** The camera path tracer (:mod:`vtkvol.engine.renderers.path_tracer`) renders the
scene's medium material (albedo a, isotropic phase, the scene's light, exposure 1, no fill):

* multiple scattering (``PT MS``) is the truth for *direct + blurred indirect* light: the
  indirect term of eq. 2.44 stands in for light scattered more than once, which the single
  scattering image does not contain at all;
* single scattering (``PT SS``) is the truth for the *direct* term alone (indirect strength
  w = 0), where both candidates claim to be exact up to discretisation.

Each truth is the mean of two independent runs (seeds 1 and 2); their own noise floor is
PSNR(A, B) + 6.02 dB (as the bench's medium reference).

**Candidates** (the same view, light, data and transfer function; exposure 1, fill 0):

* ``half_angle``: its defaults (θ = 15°, k = 0.5, tint 0.75, w = 1, normalised), 1 slice per
  voxel, its default light buffer (64² at 32³), 8 jittered frames; and w = 0 (direct only). It
  shades the medium model itself (a·colour·(E·L + k_a)).
* ``translucency`` on the ray caster: its own surface model; to light the medium as the path
  tracer does, the surface factor is switched off (g₀ = g₁ = 1: every sample unoriented, S = 0)
  and the property's diffuse is a, ambient a·k_a, specular 0, so that its colour is
  colour·(k_a·a + a·E·L), the medium model's form. ``translucency (default look)`` keeps its
  surface shading (Blinn–Phong at gradients), which the truth does not have. w = 0 (direct
  only) against PT SS as for half-angle.

Times: wall clock with ``glFinish``; half-angle: the 8 frames (each frame re-slices the whole
volume with its light: a light or camera move costs the same as any frame); translucency:
one frame after the light volume exists, and the light-volume recompute after a light move
(what a moving light costs; camera moves are free).
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

from vtkvol.bench.measure import Rig
from vtkvol.bench.scenes import phantom_scenes
from vtkvol.engine.gl import gl
from vtkvol.engine.renderers import set_renderer
from vtkvol.reference import image_metrics

FLOOR_DB = 10 * math.log10(4.0)


def timed(rig: Rig, fn: Any) -> float:
    t0 = time.perf_counter()
    fn()
    gl(rig.rw).glFinish()
    return time.perf_counter() - t0


def path_traced(rig: Rig, scattering: str, paths: int, seed: int) -> np.ndarray:
    pt = set_renderer(rig.illuminator, "path_tracer", scattering=scattering, samples=paths,
                      seed=seed)
    rig.reset_view()
    rig.illuminator.converge(max_frames=paths + 5)
    assert pt.iteration == paths, pt.iteration
    img = rig.image()
    set_renderer(rig.illuminator, "raycast")
    return img


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(image_metrics(a, b)["psnr"])


def run(size: int, image: int, paths: int) -> list[dict[str, Any]]:
    rig = Rig(image)
    rows: list[dict[str, Any]] = []
    try:
        for scene in phantom_scenes(size):
            rig.load(scene)
            ill = rig.illuminator
            ill.set_exposure(1.0, 0.0)
            ill.set_material(albedo=scene.albedo, phase_g=0.0)
            prop = rig.volume.GetProperty()
            ka, kd, ks = prop.GetAmbient(0), prop.GetDiffuse(0), prop.GetSpecular(0)
            a = scene.albedo
            truths: dict[str, tuple[np.ndarray, float, float]] = {}
            for mode in ("multiple", "single"):
                t0 = time.perf_counter()
                img_a = path_traced(rig, mode, paths, 1)
                img_b = path_traced(rig, mode, paths, 2)
                secs = time.perf_counter() - t0
                mean = ((img_a.astype(float) + img_b) / 2).round().astype(np.uint8)
                truths[mode] = (mean, psnr(img_a, img_b) + FLOOR_DB, secs)

            def record(name: str, img: np.ndarray, truth: str, seconds: float,
                       note: str, scene: Any = scene, truths: Any = truths) -> None:
                ref, floor, _ = truths[truth]
                rows.append({"scene": scene.name, "candidate": name, "truth": truth,
                             "psnr": psnr(img, ref), "floor": floor, "seconds": seconds,
                             "note": note})

            # -- half-angle slicing
            for w, truth in ((1.0, "multiple"), (0.0, "single")):
                ill.set_method("local")
                ha = set_renderer(ill, "half_angle", indirect_strength=w, samples=8)
                rig.reset_view()
                secs = timed(rig, lambda ill=ill: ill.converge(max_frames=20))
                assert ha.iteration == 8 and ha.last_error is None, ha.last_error
                img = rig.image()
                record(f"half_angle w={w:g}", img, truth, secs,
                       f"8 frames, {ha.slices} slices/frame, "
                       f"{1e3 * secs / 8:.0f} ms/frame")
                set_renderer(ill, "raycast")
            # -- translucency on the ray caster
            for label, w, look in (("translucency (medium-matched)", 1.0, "medium"),
                                   ("translucency direct only (medium-matched)", 0.0, "medium"),
                                   ("translucency (default look)", 1.0, "default")):
                if look == "medium":
                    prop.SetAmbient(ka * a)
                    prop.SetDiffuse(a)
                    prop.SetSpecular(0.0)
                    params = {"indirect_strength": w, "gradient_low": 1.0,
                              "gradient_high": 1.0}
                else:
                    params = {"indirect_strength": w}
                rig.set_method("translucency", params)
                rig.reset_view()
                first = timed(rig, rig.rw.Render)
                frame = timed(rig, rig.rw.Render)
                ill.set_lights([])  # force a light-volume recompute with the same light
                rig.load(scene)
                ill.set_exposure(1.0, 0.0)
                ill.set_material(albedo=scene.albedo, phase_g=0.0)
                recompute = timed(rig, rig.rw.Render)
                img = rig.image()
                record(label, img, "multiple" if w > 0 else "single", frame,
                       f"first frame {1e3 * first:.0f} ms, light move {1e3 * recompute:.0f} ms")
                prop.SetAmbient(ka)
                prop.SetDiffuse(kd)
                prop.SetSpecular(ks)
            for mode in ("multiple", "single"):
                rows.append({"scene": scene.name, "candidate": f"PT {mode} ({paths}+{paths})",
                             "truth": mode, "psnr": math.nan, "floor": truths[mode][1],
                             "seconds": truths[mode][2], "note": "the truth itself"})
    finally:
        rig.close()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--image", type=int, default=96)
    ap.add_argument("--paths", type=int, default=512)
    args = ap.parse_args()
    rows = run(args.size, args.image, args.paths)
    print("| scene | candidate | truth | PSNR (dB) | truth's floor (dB) | time (s) | note |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        p = "–" if math.isnan(r["psnr"]) else f"{r['psnr']:.1f}"
        print(f"| {r['scene']} | {r['candidate']} | PT {r['truth'][:1].upper()}S | {p} | "
              f"{r['floor']:.1f} | {r['seconds']:.2f} | {r['note']} |")


if __name__ == "__main__":
    main()
