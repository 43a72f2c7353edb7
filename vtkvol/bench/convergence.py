"""How the progressive (multiple-scattering) techniques converge: seed 003's Figs. 3–6 and
Table 1, measured here (``vtkvol bench --scattering``).

For every scene, with one and with three lights, each progressive ``medium`` technique (KD,
HD) restarts and refines; at iterations 1, 2, 4, … and at its own end the view is rendered and
compared with three reference images of the same view, shaded by the same host medium model
(:mod:`vtkvol.bench.references`, :class:`~vtkvol.bench.references.MediumReference`):

* ``ss``: single scattering, the exact direct light only (transmittance over the light's size);
* ``ms``: multiple scattering, the direct light plus Monte-Carlo in-scattered light of every
  order, the mean of two independent estimates (seeds 0 and 1);
* the two estimates on their own, whose difference is the reference's own noise: with two
  independent estimates A and B of variance v, MSE(A, B) = 2v and the mean's error is v/2, so
  the ``ms`` reference's **noise floor** is PSNR(A, B) + 6.02 dB. A technique cannot be
  shown closer to the truth than that.

The camera path tracer (``camera_path_tracer``, :func:`study_camera_paths`) is measured the same
way: the second, independent estimator of the ``ms`` image. It runs first, twice with different
seeds (A and B, ``camera_paths`` paths per pixel each): their mean M is the camera truth, and
PSNR(A, B) + 6.02 dB is *its* noise floor. **The two truths agree** when PSNR(M, ms) reaches
the reference's noise floor − 1 dB (the acceptance of issue 23); since M has noise of its
own, the record also holds the combined floor of the two (MSE of M's noise plus the
reference's: −10·log10 of their sum), the most any unbiased pair can reach. Every technique's
checkpoint is also compared with M (``psnr_pt``): the medium techniques and, charted beside
them, :data:`ALSO_CHARTED` (translucency, the surface model's look of scattered light).
With ``StudyConfig.refined_reference`` (on by default) the two truths are compared against
the **refined** ``ms`` reference of :mod:`vtkvol.bench.refine` (light grid 2× per axis, ray
cast at 0.125 unit distances, 4× pixel box filter; the bench's in-scattered light upsampled,
recomputed on the fine grid within one voxel of a box face), which removes most of the bench
reference's discretisation bias (docs/benchmarks.md, "The two truths with a refined
reference"); the bench's own reference stays what every technique is measured against,
and its two-truths PSNR is kept as ``psnr_two_truths_bench``.
With ``StudyConfig.pointwise`` (on by default, 128 pixels) the camera runs' float results are
also compared at seeded pixels with the reference evaluated without any grid
(:mod:`vtkvol.bench.pointwise`): the same light estimators at each camera ray's own points.
That comparison has no discretisation on either side, so it tests the two estimators
themselves; its fields are ``pointwise_*`` (``pointwise_agree``: PSNR ≥ their combined floor
− 1 dB).
Half-angle slicing (``half_angle_slicing``, :func:`study_half_angle`) is measured the same
way with one light only (it refuses more): its jittered frames are its iterations.

Time is the wall-clock time of the iterations alone (frames with the volume hidden, as the
recompute timing does, then ``glFinish``): what refining costs on this renderer, without the
comparison renders. ``iterations_per_s`` of the last checkpoint is the Table 1 analogue;
``texture_bytes`` (the technique's ``stats()``) gives the memory per voxel.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from vtkvol.bench import report
from vtkvol.bench.pointwise import PointwiseBudget, camera_setup, compare
from vtkvol.bench.references import MediumReference, ReferenceCache
from vtkvol.bench.refine import RefinedReferences, Refinement, render_refined
from vtkvol.bench.report import summary  # noqa: F401  (the study's summary, kept importable here)
from vtkvol.bench.scenes import DEFAULT_LIGHT, Scene, Vec3
from vtkvol.reference import image_metrics

#: The three lights of the three-light runs: the scenes' own light and two more from other
#: sides (world directions towards the lights), so that each lights what the others shadow.
THREE_LIGHTS: tuple[Vec3, Vec3, Vec3] = (DEFAULT_LIGHT, (-0.6, 0.3, 0.75), (0.2, 0.8, -0.55))

#: dB between the noise floor of a mean of two estimates and PSNR(A, B): 10·log10(4).
TWO_ESTIMATE_FLOOR_DB = 10.0 * math.log10(4.0)

#: Techniques of another lighting model measured against the camera path tracer beside the
#: medium ones (issue 23): translucency approximates the look of scattered light on a light
#: volume. Not progressive: one checkpoint.
ALSO_CHARTED: tuple[str, ...] = ("translucency",)

#: Seeds of the camera path tracer's two runs (A, B); the references use 0 and 1.
CAMERA_SEEDS = (7, 8)


@dataclass(frozen=True)
class StudyConfig:
    """Sizes of a convergence study: ``size`` voxels per axis, square ``image_size``,
    ``light_counts`` to run, ``max_seconds`` of refinement per technique and light count
    (the study stops there even if the technique has not ended)."""

    mode: str = "default"
    size: int = 48
    image_size: int = 192
    light_counts: tuple[int, ...] = (1, 3)
    max_seconds: float = 120.0
    #: Paths per pixel of the camera path tracer (the second, independent truth); 0: not run.
    camera_paths: int = 256
    #: Jittered frames of half-angle slicing (one-light runs only); 0: not run.
    half_angle_frames: int = 8
    #: Each technique that declares ``diffusion_model`` runs once per model listed here
    #: (issue 24: the new default beside seed 003's published model, on one chart).
    diffusion_models: tuple[str, ...] = ("source", "published")
    #: The reference the two truths are compared against (issue 23): refined as given
    #: (:class:`~vtkvol.bench.refine.Refinement`), or None for the bench's own reference.
    #: Only the two-truths comparison uses it; every technique is measured against the
    #: bench's reference either way.
    refined_reference: Refinement | None = field(default_factory=Refinement)
    #: The two truths also at seeded pixels against the reference without its grid
    #: (:mod:`vtkvol.bench.pointwise`, issue 23), or None.
    pointwise: PointwiseBudget | None = field(default_factory=lambda: PointwiseBudget(128))


def checkpoints(limit: int) -> list[int]:
    """1, 2, 4, … below ``limit``, then ``limit`` itself."""
    out, k = [], 1
    while k < limit:
        out.append(k)
        k *= 2
    return [*out, int(limit)]


def with_lights(scene: Scene, count: int) -> Scene:
    """``scene`` lit by its first ``count`` of :data:`THREE_LIGHTS` (1: its own light), each of
    intensity 1/count: the same total light, so images do not saturate."""
    if count == 1:
        return scene
    return replace(scene, lights=list(THREE_LIGHTS[:count]), light_intensity=1.0 / count)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    m = image_metrics(a, b)
    return float(m["psnr"]) if m["psnr"] is not None else math.inf


def _mse(a: np.ndarray, b: np.ndarray) -> float:
    """Mean squared difference of two images in levels² (0…255)."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return float(np.mean(d * d))


def _psnr_of_mse(mse: float) -> float:
    """PSNR (dB, peak 255) of a mean squared error in levels²; ``inf`` for 0."""
    return math.inf if mse <= 0.0 else 10.0 * math.log10(255.0 ** 2 / mse)


def two_truths(camera_a: np.ndarray, camera_b: np.ndarray, refs: dict[str, np.ndarray]
               ) -> tuple[np.ndarray, dict[str, Any]]:
    """The camera truth M = (A + B)/2 (uint8, rounded) and how it compares with the
    multiple-scattering reference: ``psnr_two_truths`` = PSNR(M, ms); ``floor_psnr`` (the
    reference's noise floor, PSNR(ms_a, ms_b) + 6.02 dB), ``camera_floor_psnr`` (M's, the same
    from A and B) and ``combined_floor_psnr`` (M's noise and the reference's together: the mean
    of two estimates has a quarter of their squared difference as its error, so the combined
    error is (MSE(A, B) + MSE(ms_a, ms_b))/4); ``agree``: PSNR(M, ms) ≥ floor_psnr − 1 dB.
    With ``refs["ms_refined"]`` (the refined reference, :mod:`vtkvol.bench.refine`) the
    PSNR and both verdicts are against it, and ``psnr_two_truths_bench`` is PSNR(M, ms)."""
    a = np.asarray(camera_a, np.float64)
    b = np.asarray(camera_b, np.float64)
    mean = np.clip(np.rint((a + b) / 2.0), 0, 255).astype(np.uint8)
    cam_noise = _mse(a, b) / 4.0
    ref_noise = _mse(refs["ms_a"], refs["ms_b"]) / 4.0
    out = {
        "psnr_two_truths": _psnr(mean, refs["ms"]),
        "floor_psnr": _psnr_of_mse(ref_noise),
        "camera_floor_psnr": _psnr_of_mse(cam_noise),
        "combined_floor_psnr": _psnr_of_mse(cam_noise + ref_noise),
    }
    out["agree"] = bool(out["psnr_two_truths"] >= out["floor_psnr"] - 1.0)
    out["agree_combined"] = bool(out["psnr_two_truths"] >= out["combined_floor_psnr"] - 1.0)
    if "ms_refined" in refs:
        # The refined reference has the bench's in-scattered light (the same noise): the
        # floors stay; the bench's own PSNR is kept beside it (before → after).
        out["psnr_two_truths_bench"] = out["psnr_two_truths"]
        out["psnr_two_truths"] = _psnr(mean, refs["ms_refined"])
        out["agree"] = bool(out["psnr_two_truths"] >= out["floor_psnr"] - 1.0)
        out["agree_combined"] = bool(out["psnr_two_truths"]
                                     >= out["combined_floor_psnr"] - 1.0)
    return mean, out


def _iteration_limit(rig: Any) -> int:
    """The active technique's own end: its declared default ``max_iterations``, or, where that
    is 0 (automatic, KD), what the technique computes for the loaded grid."""
    tech = rig.illuminator.technique
    limit = int(tech.defaults().get("max_iterations") or 0)
    if limit > 0:
        return limit
    automatic = getattr(tech, "automatic_iterations", None)
    if callable(automatic):
        return int(automatic())
    raise RuntimeError(f"{rig.illuminator.method} states no iteration limit")


def _run_to(rig: Any, target: int) -> float:
    """Iterate the active technique up to ``target`` iterations with the volume hidden;
    seconds spent (wall clock, GPU work finished)."""
    from vtkvol.engine.gl import gl

    ill = rig.illuminator
    ill.set_parameters(max_iterations=target)
    t0 = time.perf_counter()
    rig.volume.VisibilityOff()
    try:
        restart = True  # after an invalidation the first frame restarts from iteration 0
        while restart or ill.technique is None or ill.technique.iteration < target:
            restart = False
            before = ill.technique.iteration if ill.technique is not None else -1
            rig.rw.Render()
            if ill.technique is None or ill.failed_method is not None:
                raise RuntimeError(f"{ill.method} failed while refining")
            if ill.technique.iteration == before and ill.technique.converged:
                break  # ended below the target (its own limit)
    finally:
        rig.volume.VisibilityOn()
    gl(rig.rw).glFinish()
    return time.perf_counter() - t0


def reference_images(render: Any) -> dict[str, np.ndarray]:
    """The ``ss``, ``ms``, ``ms_a`` and ``ms_b`` reference images of the loaded scene;
    ``render(reference)`` renders one reference object's image."""
    return {
        "ss": render(MediumReference(orders="single")),
        "ms_a": render(MediumReference(seeds=(0,))),
        "ms_b": render(MediumReference(seeds=(1,))),
        "ms": render(MediumReference(seeds=(0, 1))),
    }


def study_scene(rig: Any, cache: ReferenceCache, scene: Scene, methods: Sequence[str],
                config: StudyConfig, render: Any, base: dict[str, Any],
                stream: Any = None) -> list[dict[str, Any]]:
    """Every method × light count on one scene: one record per checkpoint. A method that fails
    is named on ``stream`` and left out; the others go on."""
    records: list[dict[str, Any]] = []
    for count in config.light_counts:
        lit = with_lights(scene, count)
        rig.load(lit)
        refs = reference_images(render)
        refined_seconds = None
        if config.camera_paths and config.refined_reference is not None:
            t0 = time.perf_counter()
            fine = RefinedReferences(cache, lit, config.refined_reference)
            try:
                refs["ms_refined"] = render_refined(
                    fine, config.image_size, {"ms": MediumReference(seeds=(0, 1))})["ms"]
            finally:
                fine.release()
            refined_seconds = time.perf_counter() - t0
        common = {
            **base, "scene": scene.name, "scene_kind": scene.kind, "size": lit.size_label,
            "lights": count, "albedo": lit.albedo, "phase_g": lit.phase_g,
            "floor_psnr": _psnr(refs["ms_a"], refs["ms_b"]) + TWO_ESTIMATE_FLOOR_DB,
            # how much the scattered light shows in the image at all
            "single_vs_multiple_psnr": _psnr(refs["ss"], refs["ms"]),
        }
        camera_extra = ({"two_truths_reference": config.refined_reference.label,
                         "refined_reference_s": refined_seconds}
                        if refined_seconds is not None else {})
        camera = None
        if config.camera_paths:
            try:
                camera_records, camera = study_camera_paths(rig, refs, config,
                                                            {**common, **camera_extra})
                records += camera_records
            except Exception as exc:
                if stream is not None:
                    print(f"vtkvol bench --scattering: the camera path tracer on {scene.name} "
                          f"({count} lights) failed: {exc}", file=stream)
        for method in methods:
            for variant, parameters in _variants(method, config):
                try:
                    records += _study_method(rig, method, refs, config, common,
                                             voxels=int(np.prod(lit.shape)), camera=camera,
                                             parameters=parameters, variant=variant)
                except Exception as exc:  # one failing method must not end the study
                    if stream is not None:
                        print(f"vtkvol bench --scattering: {variant} on {scene.name} "
                              f"({count} lights) failed: {exc}", file=stream)
        if config.half_angle_frames and count == 1:
            try:
                records += study_half_angle(rig, refs, config, common, camera)
            except Exception as exc:
                if stream is not None:
                    print(f"vtkvol bench --scattering: half-angle slicing on {scene.name} "
                          f"failed: {exc}", file=stream)
        cache.clear_scene(lit)
    return records


def _vs_camera(image: np.ndarray, camera: np.ndarray | None) -> float | None:
    """PSNR (dB) of ``image`` against the camera truth, None without one."""
    return None if camera is None else _psnr(image, camera)


def _study_once(rig: Any, method: str, refs: dict[str, np.ndarray], common: dict[str, Any],
                voxels: int, camera: np.ndarray | None) -> list[dict[str, Any]]:
    """A technique that is not progressive: its first declared bench setting, one frame with
    the volume hidden after a restart (its whole precomputation), one checkpoint."""
    from vtkvol.engine.gl import gl
    from vtkvol.engine.technique import installed_techniques

    spec = installed_techniques()[method].SPEC
    setting = spec.bench[0] if spec.bench else None
    rig.set_method(method, dict(setting.values) if setting is not None else {})
    rig.rw.Render()  # build: shaders, textures
    rig.illuminator.invalidate()
    t0 = time.perf_counter()
    rig.volume.VisibilityOff()
    try:
        rig.rw.Render()
    finally:
        rig.volume.VisibilityOn()
    gl(rig.rw).glFinish()
    spent = time.perf_counter() - t0
    if rig.illuminator.failed_method is not None:
        raise RuntimeError(f"{method} failed")
    image = rig.image()
    ms = image_metrics(image, refs["ms"])
    ss = image_metrics(image, refs["ss"])
    tech = rig.illuminator.technique
    texture_bytes = tech.stats().get("texture_bytes") if tech is not None else None
    return [{
        **common, "method": method, "short": setting.label if setting else method,
        "iteration": 1, "seconds": spent, "iterations_per_s": 1.0 / spent if spent > 0 else None,
        "rmse_ms": ms["rmse"], "psnr_ms": ms["psnr"], "rmse_ss": ss["rmse"],
        "psnr_ss": ss["psnr"], "psnr_pt": _vs_camera(image, camera),
        "texture_bytes": texture_bytes,
        "bytes_per_voxel": texture_bytes / voxels if texture_bytes else None, "final": True,
    }]


def _variants(method: str, config: StudyConfig) -> list[tuple[str, dict[str, Any]]]:
    """The runs of ``method`` in the study, as (record name, parameters): one per model of
    :attr:`StudyConfig.diffusion_models` for a technique that declares ``diffusion_model``
    (the declared default keeps the plain name, another model is ``method/model``), else
    one."""
    from vtkvol.engine.technique import installed_techniques

    spec = installed_techniques()[method].SPEC
    if "diffusion_model" not in spec.defaults() or not config.diffusion_models:
        return [(method, {})]
    default = spec.defaults()["diffusion_model"]
    return [(method if model == default else f"{method}/{model}", {"diffusion_model": model})
            for model in config.diffusion_models]


def _study_method(rig: Any, method: str, refs: dict[str, np.ndarray], config: StudyConfig,
                  common: dict[str, Any], voxels: int, camera: np.ndarray | None = None,
                  parameters: dict[str, Any] | None = None, variant: str | None = None
                  ) -> list[dict[str, Any]]:
    """Restart ``method`` with ``parameters`` and record every checkpoint up to its end (or
    the time limit) under the name ``variant`` (default ``method``); ``camera``: the camera
    truth, each checkpoint's ``psnr_pt`` (None without one)."""
    from vtkvol.engine.technique import installed_techniques

    if not installed_techniques()[method].SPEC.has("progressive"):
        return _study_once(rig, method, refs, common, voxels, camera)
    parameters = dict(parameters or {})
    rig.set_method(method, {**parameters, "max_iterations": 1})
    rig.rw.Render()  # build: shaders, textures, first iteration
    limit = _iteration_limit(rig)
    spec = rig.illuminator.spec  # the declared short name (first bench setting's label)
    short = spec.bench[0].label if spec.bench else method
    if variant is not None and variant != method:
        short = f"{short} {variant.split('/', 1)[1]}"
    name = variant or method
    rig.illuminator.invalidate()  # restart: the timed run starts from nothing
    records: list[dict[str, Any]] = []
    spent = 0.0
    for target in checkpoints(limit):
        spent += _run_to(rig, target)
        tech = rig.illuminator.technique
        image = rig.image()
        ms = image_metrics(image, refs["ms"])
        ss = image_metrics(image, refs["ss"])
        texture_bytes = tech.stats().get("texture_bytes")
        records.append({
            **common, "method": name, "short": short, "iteration": int(tech.iteration),
            **({"diffusion_model": parameters["diffusion_model"]}
               if "diffusion_model" in parameters else {}),
            "seconds": spent, "iterations_per_s": tech.iteration / spent if spent > 0 else None,
            "rmse_ms": ms["rmse"], "psnr_ms": ms["psnr"], "rmse_ss": ss["rmse"],
            "psnr_ss": ss["psnr"], "psnr_pt": _vs_camera(image, camera),
            "texture_bytes": texture_bytes,
            "bytes_per_voxel": texture_bytes / voxels if texture_bytes else None,
            "final": target == limit or spent > config.max_seconds,
        })
        if spent > config.max_seconds:
            break
    return records


#: The camera path tracer's name in the study's records (not a technique: a renderer).
CAMERA_PATHS = "camera_path_tracer"


def study_camera_paths(rig: Any, refs: dict[str, np.ndarray], config: StudyConfig,
                       common: dict[str, Any]) -> tuple[list[dict[str, Any]], np.ndarray]:
    """The camera path tracer (:mod:`vtkvol.engine.renderers.path_tracer`, multiple
    scattering, the scene's material and lights) drawn beside the ray caster: run A (seed
    :data:`CAMERA_SEEDS` [0]) is compared with the references at 1, 2, 4, … paths per pixel up
    to ``config.camera_paths`` (one record each), run B (the other seed) to the same count
    gives the camera truth's own noise. The last record carries :func:`two_truths`'s fields.
    ``config.max_seconds`` does not stop it: a truth cut short is a noisier truth.
    Returns the records and the camera truth M (uint8 image). Time: whole frames of run A
    (one path per pixel each, the composite included), ``glFinish`` before the clock stops."""
    from vtkvol.engine.gl import gl
    from vtkvol.engine.renderers import set_renderer

    limit = int(config.camera_paths)
    records: list[dict[str, Any]] = []
    finals: list[np.ndarray] = []
    radiance: list[np.ndarray] = []  # the runs' float results, for the pointwise comparison
    setup: dict[str, Any] = {}
    try:
        for run_index, seed in enumerate(CAMERA_SEEDS):
            rig.reset_view()
            pt = set_renderer(rig.illuminator, "path_tracer", scattering="multiple",
                              samples=limit, seed=seed)
            spent = 0.0
            image = None
            for target in checkpoints(limit) if run_index == 0 else [limit]:
                t0 = time.perf_counter()
                while pt.iteration < target - 1:
                    rig.rw.Render()
                gl(rig.rw).glFinish()
                spent += time.perf_counter() - t0
                image = rig.image()  # renders the target-th path (the camera is the scene's)
                if pt.last_error is not None:
                    raise RuntimeError(pt.last_error)
                if run_index:
                    continue
                ms = image_metrics(image, refs["ms"])
                ss = image_metrics(image, refs["ss"])
                records.append({
                    **common, "method": CAMERA_PATHS, "short": "camera PT",
                    "iteration": int(pt.iteration), "seconds": spent,
                    "iterations_per_s": pt.iteration / spent if spent > 0 else None,
                    "rmse_ms": ms["rmse"], "psnr_ms": ms["psnr"], "rmse_ss": ss["rmse"],
                    "psnr_ss": ss["psnr"], "psnr_pt": None, "texture_bytes": None,
                    "bytes_per_voxel": None, "final": target == limit,
                })
            assert image is not None
            finals.append(image)
            if config.pointwise is not None:
                radiance.append(pt.read_result())
                if run_index == len(CAMERA_SEEDS) - 1:  # the same set-up for both runs
                    setup = camera_setup(rig, pt)
            set_renderer(rig.illuminator, "raycast")
    finally:
        set_renderer(rig.illuminator, "raycast")
    mean, agreement = two_truths(finals[0], finals[1], refs)
    records[-1].update(agreement, final=True)
    if config.pointwise is not None and rig.scene is not None:
        fields, _pixels = compare(rig.scene, setup, radiance[0], radiance[1], "multiple",
                                  config.pointwise)
        records[-1].update({f"pointwise_{k}": v for k, v in fields.items()})
    return records, mean


#: Half-angle slicing's name in the study's records (a renderer, not a technique).
HALF_ANGLE = "half_angle_slicing"


def study_half_angle(rig: Any, refs: dict[str, np.ndarray], config: StudyConfig,
                     common: dict[str, Any], camera: np.ndarray | None = None,
                     ) -> list[dict[str, Any]]:
    """Half-angle slicing (:mod:`vtkvol.engine.renderers.half_angle`, its defaults, the
    scene's material and light) compared with the references (and the camera truth
    ``camera``: ``psnr_pt``) after 1, 2, 4, … jittered frames up to
    ``config.half_angle_frames``. Time: whole frames, ``glFinish`` before the clock stops."""
    from vtkvol.engine.gl import gl
    from vtkvol.engine.renderers import set_renderer

    limit = int(config.half_angle_frames)
    rig.reset_view()
    ha = set_renderer(rig.illuminator, "half_angle", samples=limit)
    records: list[dict[str, Any]] = []
    spent = 0.0
    try:
        for target in checkpoints(limit):
            t0 = time.perf_counter()
            while ha.iteration < target - 1:
                rig.rw.Render()
            gl(rig.rw).glFinish()
            spent += time.perf_counter() - t0
            image = rig.image()  # renders the target-th frame
            if ha.last_error is not None:
                raise RuntimeError(ha.last_error)
            ms = image_metrics(image, refs["ms"])
            ss = image_metrics(image, refs["ss"])
            records.append({
                **common, "method": HALF_ANGLE, "short": "half-angle",
                "iteration": int(ha.iteration), "seconds": spent,
                "iterations_per_s": ha.iteration / spent if spent > 0 else None,
                "rmse_ms": ms["rmse"], "psnr_ms": ms["psnr"], "rmse_ss": ss["rmse"],
                "psnr_ss": ss["psnr"], "psnr_pt": _vs_camera(image, camera),
                "texture_bytes": None, "bytes_per_voxel": None, "final": target == limit,
            })
    finally:
        set_renderer(rig.illuminator, "raycast")
    return records


def run(config: StudyConfig, out_dir: Any, scenes: Sequence[Scene],
        methods: Sequence[str] | None = None, *, budget: Any = None,
        command: str = "vtkvol bench --scattering", stream: Any = None) -> dict[str, Any]:
    """Run the study on ``scenes`` for the medium techniques and :data:`ALSO_CHARTED` (or
    ``methods``) and
    merge it into ``out_dir/benchmarks.json`` (regenerating the Markdown and charts). Returns
    the run's metadata with ``records`` and ``paths``."""
    import datetime as _dt
    import sys
    from pathlib import Path

    from vtkvol.bench.measure import Rig, VtkErrors, machine_info
    from vtkvol.bench.reference_technique import MEDIUM_NAME, ReferenceVolume, registered
    from vtkvol.bench.references import FULL_BUDGET
    from vtkvol.engine.technique import installed_techniques

    stream = stream if stream is not None else sys.stderr
    techniques = installed_techniques()
    names = [n for n, c in sorted(techniques.items())
             if (c.SPEC.lighting == "medium" or n in ALSO_CHARTED)
             and (methods is None or n in methods)]
    if not names:
        raise ValueError("no medium technique is installed (or selected)")
    cache = ReferenceCache(budget or FULL_BUDGET)
    date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    t_start = time.perf_counter()
    records: list[dict[str, Any]] = []
    with VtkErrors() as errors, registered():
        rig = Rig(config.image_size)
        try:
            rig.rw.Render()
            info = machine_info(rig.rw)

            def render(reference: MediumReference) -> np.ndarray:
                assert rig.scene is not None
                ReferenceVolume.use(reference.volumes(cache, rig.scene))
                rig.set_method(MEDIUM_NAME, {})
                image = rig.image()
                problem = errors.new_errors()
                if problem:
                    raise RuntimeError(f"the reference shader failed: {problem}")
                return image

            base = {"renderer": info["renderer"], "mode": config.mode, "date": date}
            for scene in scenes:
                print(f"vtkvol bench --scattering: {scene.name} ({scene.size_label})",
                      file=stream, flush=True)
                records += study_scene(rig, cache, scene, names, config, render, base, stream)
        finally:
            rig.close()
    run_info = {
        **info, "mode": config.mode, "date": date, "command": command,
        "duration_s": time.perf_counter() - t_start, "reference_seconds": cache.seconds,
        "size": config.size, "image_size": config.image_size,
        "reference_budget": vars(cache.budget).copy(), "methods": names,
        "scenes": [{"name": s.name, "size": s.size_label, "kind": s.kind,
                    "description": s.description} for s in scenes],
    }
    paths = report.write_scattering(Path(out_dir), run_info, records)
    return {**run_info, "records": records, "paths": paths}
