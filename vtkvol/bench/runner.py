"""``vtkvol bench``: scenes × methods × settings, timed and compared against references.

For every scene (:mod:`vtkvol.bench.scenes`) and every setting of every installed technique
(``installed_techniques()`` of every lighting model the bench has a reference for, settings
from each declaration's ``bench``/``stability`` lists or its parameters), plus VTK's built-in
volumetric scattering (measured as a surface method):

1. the scene's reference image per lighting model: the same view rendered by the
   ``bench_reference`` technique, i.e. the same host shading with the CPU reference volumes
   (:mod:`~vtkvol.bench.references`: one physical truth per scene and lighting model);
2. warm-up frames, then timed frames (median and IQR), the comparison image, recompute times;
3. image metrics against the reference (RMSE, PSNR, SSIM) and, where the technique has a
   per-voxel light volume (``light_visibility_cpu``), per-voxel metrics of light 0.

Then the stability sweeps (:func:`~vtkvol.bench.scenes.stability_cases`) with every
technique's stability setting, and finally ``benchmarks.json`` (merged), CSV, Markdown and
charts (:mod:`vtkvol.bench.report`). A progress bar goes to stderr.
"""

from __future__ import annotations

import datetime as _dt
import itertools
import math
import os
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from vtkvol.bench import report
from vtkvol.bench.reference_technique import MEDIUM_NAME as MEDIUM_REFERENCE
from vtkvol.bench.reference_technique import NAME as REFERENCE
from vtkvol.bench.reference_technique import ReferenceVolume, registered
from vtkvol.bench.references import (
    FULL_BUDGET,
    LIGHTING_REFERENCES,
    QUICK_BUDGET,
    LightingReference,
    ReferenceBudget,
    ReferenceCache,
    SurfaceReference,
    reference_for,
)
from vtkvol.bench.scenes import Scene, StabilityCase, bench_scenes, stability_cases
from vtkvol.engine.technique import Technique, installed_techniques
from vtkvol.reference import image_metrics, volume_metrics

VTK_METHOD = "vtk_scattering"


# ------------------------------------------------------------------------------------------
# Configuration
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BenchConfig:
    """Everything that sizes a run.

    ``size``: scene voxels per axis; ``image_size``: square image (pixels); ``warmup`` and
    ``frames``: untimed and timed frames per setting; ``recompute_repeats``: forced recomputes
    per trigger; ``stability_size``: voxels of the stability scenes; ``vtk_settings``:
    (blending, reach) pairs of VTK's volumetric scattering, the first being the one ratios use;
    ``refine_seconds``: the most a progressive technique refines before it is measured.
    """

    mode: str
    size: int
    image_size: int
    warmup: int
    frames: int
    recompute_repeats: int
    stability_size: int
    stability_image_size: int
    budget: ReferenceBudget
    vtk_settings: tuple[tuple[float, float], ...]
    voxel_metric_seconds: float = 1.5  #: above this, a method's CPU light path runs once/scene
    refine_seconds: float = 60.0


QUICK = BenchConfig("quick", 64, 256, 2, 3, 1, 32, 160, QUICK_BUDGET, ((1.0, 1.0),))
FULL = BenchConfig("full", 128, 256, 2, 10, 3, 48, 192, FULL_BUDGET,
                   ((1.0, 1.0), (2.0, 1.0), (0.0, 1.0)), voxel_metric_seconds=60.0)


@dataclass(frozen=True)
class Setting:
    """One configuration of one method: full parameter ``values``, a long ``label`` for tables
    and a ``short`` one for chart annotations."""

    method: str
    values: Mapping[str, Any]
    label: str
    short: str


_LABEL_KEYS = frozenset({"label", "short"})


def _label(overrides: Mapping[str, Any], keys: Sequence[str]) -> tuple[str, str]:
    if not keys:
        return "default", "default"
    long = ", ".join(f"{k}={overrides[k]}" for k in keys if k in overrides) or "default"
    short = "/".join(str(overrides[k]) for k in keys if k in overrides) or "default"
    return long, short


def _settings_from(
    name: str, cls: type[Technique], overrides: list[dict[str, Any]]
) -> list[Setting]:
    """Validated settings from override dicts (unknown/invalid overrides raise ValueError);
    labels name the parameters the list varies, in declaration order. The optional keys
    ``label`` and ``short`` replace the generated table and chart labels."""
    from vtkvol.model.params import validate_values

    declared = [p.name for p in cls.PARAMETERS]
    varied = {k for o in overrides for k in o if k not in _LABEL_KEYS}
    keys = [k for k in declared if k in varied]
    out = []
    for o in overrides:
        params = {k: v for k, v in o.items() if k not in _LABEL_KEYS}
        values = validate_values(cls.PARAMETERS, {**cls.defaults(), **params})
        long, short = _label(params, keys)
        out.append(Setting(name, values, str(o.get("label", long)), str(o.get("short", short))))
    return out


def one_at_a_time(cls: type[Technique]) -> list[dict[str, Any]]:
    """Defaults, then every other choice of every ``choice`` parameter and the flip of every
    ``bool`` parameter, one at a time (the generic matrix for techniques the bench does not
    know)."""
    overrides: list[dict[str, Any]] = [{}]
    for p in cls.PARAMETERS:
        if p.kind == "choice":
            overrides += [{p.name: c} for c in p.choices if c != p.default]
        elif p.kind == "bool":
            overrides.append({p.name: not p.default})
    return overrides


def technique_settings(name: str, cls: type[Technique], *, quick: bool,
                       stability: bool = False) -> list[Setting]:
    """The settings a run measures for technique ``name``: its declaration's ``bench`` (or
    ``stability``) settings — in a quick run the ones marked ``quick`` —, else the defaults plus
    one-at-a-time variations (matrix) or the defaults alone (stability)."""
    declared = cls.SPEC.stability if stability else cls.SPEC.bench
    chosen = [b for b in declared if b.quick or not quick]
    if chosen:
        overrides = [{**b.values, "short": b.label or "default", "label": b.label or "default"}
                     for b in chosen]
    else:
        overrides = [{}] if stability or not cls.PARAMETERS else one_at_a_time(cls)
    return _settings_from(name, cls, overrides)


def vtk_setting(blending: float, reach: float) -> Setting:
    values = {"blending": blending, "reach": reach}
    return Setting(VTK_METHOD, values, f"blend={blending:g}, reach={reach:g}",
                   f"b{blending:g} r{reach:g}")


# ------------------------------------------------------------------------------------------
# Progress
# ------------------------------------------------------------------------------------------
class Progress:
    """A plain-text progress bar on stderr: ``[#####.....] 12/80 1:02 (~2:40 left) label``.

    On a terminal it redraws one line; otherwise it prints one line per step (for logs).
    """

    def __init__(self, total: int, stream: TextIO | None = None, enabled: bool = True) -> None:
        self.total = max(1, total)
        self.done = 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def step(self, label: str) -> None:
        """Announce the unit of work about to run (``done`` counts the finished ones)."""
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.t0
        left = elapsed / self.done * (self.total - self.done) if self.done else math.nan
        width = 24
        filled = int(width * self.done / self.total)
        bar = "#" * filled + "." * (width - filled)
        eta = f" (~{_mmss(left)} left)" if math.isfinite(left) else ""
        text = f"[{bar}] {self.done}/{self.total} {_mmss(elapsed)}{eta} {label}"
        if self.tty:
            self.stream.write("\r" + text[:150].ljust(150))
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def advance(self) -> None:
        self.done += 1

    def finish(self) -> None:
        if self.enabled:
            self.done = self.total
            self.step("done")
            if self.tty:
                self.stream.write("\n")
            self.stream.flush()


def _mmss(seconds: float) -> str:
    m, s = divmod(int(seconds), 60)
    return f"{m}:{s:02d}"


# ------------------------------------------------------------------------------------------
# Measuring
# ------------------------------------------------------------------------------------------
@dataclass
class Context:
    """State shared by every measurement of a run."""

    config: BenchConfig
    rig: Any  #: vtkvol.bench.measure.Rig
    vtk_rig: Any  #: vtkvol.bench.measure.VtkScatteringRig
    errors: Any  #: vtkvol.bench.measure.VtkErrors
    cache: ReferenceCache
    techniques: dict[str, type[Technique]]
    progress: Progress
    renderer: str = ""
    date: str = ""
    slow_cpu_paths: set[str] = field(default_factory=set)
    reference_images: dict[tuple, np.ndarray] = field(default_factory=dict)
    #: recompute times per (scene, method, ILLUMINATION parameter values): settings that differ
    #: only in frame or shader parameters share one precomputation, so it is timed once.
    recompute_cache: dict[tuple, tuple[list[float], list[float]]] = field(default_factory=dict)
    #: methods seen not to recompute after a light move (their light-move frame is skipped).
    light_independent: set[str] = field(default_factory=set)


def _lighting_reference(ctx: Context, method: str) -> LightingReference:
    """The reference ``method`` is measured against: its lighting model's (VTK's scattering
    shades surfaces from the scene's lights, so it is measured as a surface method)."""
    cls = ctx.techniques.get(method)
    return reference_for(cls.SPEC.lighting) if cls is not None else SurfaceReference()


def _reference_image(ctx: Context, scene: Scene, reference: LightingReference) -> np.ndarray:
    """The scene's reference image of ``reference``'s lighting model (rendered once)."""
    spec = reference.spec(scene, ctx.cache.budget)
    key = (scene.name, id(scene.data), tuple(map(tuple, scene.lights)), reference.lighting, spec)
    if key not in ctx.reference_images:
        ReferenceVolume.use(reference.volumes(ctx.cache, scene))
        ctx.rig.set_method(MEDIUM_REFERENCE if reference.lighting == "medium" else REFERENCE, {})
        image = ctx.rig.image()  # correct on the build frame: textures are bound before it
        problem = ctx.errors.new_errors()
        if problem:
            raise RuntimeError(f"the reference shader failed on {scene.name}: {problem}")
        ctx.reference_images[key] = image
    return ctx.reference_images[key]


def _light_spec(scene: Scene) -> Any:
    from vtkvol.engine.illuminator import LightSpec

    d = np.asarray(scene.lights[0], dtype=np.float64)
    d = d / np.linalg.norm(d)
    return LightSpec("directional", (float(d[0]), float(d[1]), float(d[2])), (1.0, 1.0, 1.0))


def _voxel_metrics(ctx: Context, scene: Scene, setting: Setting, opacity: np.ndarray, *,
                   force: bool) -> tuple[dict[str, float], str]:
    """Per-voxel metrics of light 0 of the technique's CPU light path against the reference
    (mask: α > 0.05), and a problem description ("" when the volume is finite and in [0, 1]).
    Methods whose CPU path took longer than the configured time run it only when ``force``."""
    cls = ctx.techniques.get(setting.method)
    if cls is None or (setting.method in ctx.slow_cpu_paths and not force):
        return {}, ""
    tech = cls(ctx.rig.illuminator)
    values = {**setting.values, **cls.SPEC.cpu_path_values}
    t0 = time.perf_counter()
    vis = tech.light_visibility_cpu(opacity, scene.spacing, _light_spec(scene), values)
    if vis is None:
        return {}, ""
    if time.perf_counter() - t0 > ctx.config.voxel_metric_seconds:
        ctx.slow_cpu_paths.add(setting.method)
    vis = np.asarray(vis, dtype=np.float64)
    from vtkvol.bench.measure import volume_checks

    problem = volume_checks({"light_visibility_cpu": vis}, unit_range=("light_visibility_cpu",))
    if problem:
        return {}, problem
    ref = _lighting_reference(ctx, setting.method).light_visibility(ctx.cache, scene, opacity)
    mask = opacity > 0.05
    if not mask.any():
        return {}, ""
    m = volume_metrics(vis, ref, mask)
    return {"vol_rmse": m["rmse"], "vol_max_abs": m["max_abs"], "vol_bias": m["bias"]}, ""


def _base_record(
    ctx: Context, scene: Scene, setting: Setting, reference: LightingReference
) -> dict[str, Any]:
    label = (ctx.techniques[setting.method].LABEL if setting.method in ctx.techniques
             else "VTK built-in volumetric scattering")
    spec = reference.spec(scene, ctx.cache.budget)
    return {
        "scene": scene.name, "method": setting.method, "setting": setting.label,
        "renderer": ctx.renderer, "date": ctx.date, "mode": ctx.config.mode,
        "scene_kind": scene.kind, "size": scene.size_label, "spacing": list(scene.spacing),
        "image_size": ctx.config.image_size, "method_label": label, "short": setting.short,
        "parameters": dict(setting.values), "lighting": reference.lighting,
        "reference": spec.label, "frame_ms": None, "recompute_ms": None, "rmse": None,
        "psnr": None, "ssim": None,
        "vol_rmse": None, "vol_max_abs": None, "vol_bias": None, "ok": False, "error": None,
        "iterations": None, "refine_s": None,
    }


def _recompute(ctx: Context, scene: Scene, setting: Setting) -> tuple[list[float], list[float]]:
    """Recompute times of the active setting, measured once per distinct set of its
    technique's ILLUMINATION-invalidating parameter values on this scene."""
    from vtkvol.model.params import Invalidates

    cls = ctx.techniques.get(setting.method)
    params = cls.PARAMETERS if cls is not None else ()
    key = (scene.name, id(scene.data), setting.method,
           tuple((p.name, setting.values.get(p.name)) for p in params
                 if p.invalidates & Invalidates.ILLUMINATION))
    if key not in ctx.recompute_cache:
        light = setting.method not in ctx.light_independent
        light_ms, tf_ms = ctx.rig.recompute_times(ctx.config.recompute_repeats, light=light)
        if light and not light_ms and tf_ms:
            ctx.light_independent.add(setting.method)  # recomputes, but not for light moves
        ctx.recompute_cache[key] = (light_ms, tf_ms)
    return ctx.recompute_cache[key]


def measure_setting(ctx: Context, scene: Scene, setting: Setting, opacity: np.ndarray,
                    first_of_method: bool) -> dict[str, Any]:
    """One record: timing, image metrics and per-voxel metrics of ``setting`` on ``scene``."""
    cfg = ctx.config
    reference = _lighting_reference(ctx, setting.method)
    record = _base_record(ctx, scene, setting, reference)
    try:
        ref_img = _reference_image(ctx, scene, reference)
        ctx.rig.set_method(setting.method, setting.values)
        iterations, refine_s = ctx.rig.refine(cfg.refine_seconds)
        timing = ctx.rig.time_frames(cfg.warmup, cfg.frames)
        image = ctx.rig.image()
        problem = ctx.errors.new_errors()
        if problem:
            raise RuntimeError(problem)
        if not ctx.rig.shader_installed():
            raise RuntimeError("the technique's shader code is missing from the built program")
        light_ms, tf_ms = _recompute(ctx, scene, setting)
        metrics = image_metrics(image, ref_img)
        vox, vproblem = _voxel_metrics(ctx, scene, setting, opacity, force=first_of_method)
        if vproblem:
            raise RuntimeError(vproblem)
        light = float(np.median(light_ms)) if light_ms else None
        tf = float(np.median(tf_ms)) if tf_ms else None
        record.update(
            frame_ms=timing.median, frame_iqr_ms=timing.iqr, frame_cpu_ms=timing.cpu_median,
            frame_min_ms=min(timing.samples), frame_max_ms=max(timing.samples),
            n_frames=len(timing.samples), recompute_light_ms=light, recompute_tf_ms=tf,
            recompute_ms=max([v for v in (light, tf) if v is not None], default=0.0),
            rmse=metrics["rmse"], psnr=metrics["psnr"], ssim=metrics["ssim"],
            max_abs=metrics["max_abs"], ok=True, iterations=iterations or None,
            refine_s=refine_s if iterations else None, **vox,
        )
    except Exception as exc:  # one failing setting must not end the run: record it
        record["error"] = f"{type(exc).__name__}: {exc}"[:500]
    return record


def measure_vtk(ctx: Context, scene: Scene, setting: Setting) -> dict[str, Any]:
    """One record for VTK's built-in scattering, compared with the scene's reference."""
    cfg = ctx.config
    reference = SurfaceReference()
    record = _base_record(ctx, scene, setting, reference)
    try:
        ref_img = _reference_image(ctx, scene, reference)
        ctx.vtk_rig.set_setting(setting.values["blending"], setting.values["reach"])
        timing = ctx.vtk_rig.time_frames(cfg.warmup, cfg.frames)
        image = ctx.vtk_rig.image()
        problem = ctx.errors.new_errors()
        if problem:
            raise RuntimeError(problem)
        metrics = image_metrics(image, ref_img)
        record.update(
            frame_ms=timing.median, frame_iqr_ms=timing.iqr, frame_cpu_ms=timing.cpu_median,
            frame_min_ms=min(timing.samples), frame_max_ms=max(timing.samples),
            n_frames=len(timing.samples), recompute_ms=0.0, recompute_light_ms=None,
            recompute_tf_ms=None, rmse=metrics["rmse"], psnr=metrics["psnr"],
            ssim=metrics["ssim"], max_abs=metrics["max_abs"], ok=True,
        )
    except Exception as exc:
        record["error"] = f"{type(exc).__name__}: {exc}"[:500]
    return record


def _references_of(ctx: Context, settings: Sequence[Setting]) -> list[LightingReference]:
    """The lighting references ``settings`` need (the surface one always: VTK's scattering and
    the stability images use it), in a stable order."""
    out: dict[str, LightingReference] = {"surface": SurfaceReference()}
    for setting in settings:
        ref = _lighting_reference(ctx, setting.method)
        out.setdefault(ref.lighting, ref)
    return list(out.values())


def run_scene(ctx: Context, scene: Scene, settings: Sequence[Setting],
              vtk_settings: Sequence[Setting]) -> list[dict[str, Any]]:
    """Every setting on one scene (references first, then the methods, then VTK's)."""
    opacity = scene.opacity()
    ctx.rig.load(scene)
    records = []
    for reference in _references_of(ctx, settings):
        label = reference.spec(scene, ctx.cache.budget).label
        ctx.progress.step(f"{scene.name}: {reference.lighting} reference {label}")
        try:
            _reference_image(ctx, scene, reference)
        except Exception as exc:  # recorded per setting below (the lookup raises again)
            print(f"\nvtkvol bench: reference {label} on {scene.name} failed: {exc}",
                  file=sys.stderr)
        ctx.progress.advance()
    seen: set[str] = set()
    for setting in settings:
        ctx.progress.step(f"{scene.name}: {setting.method} {setting.label}")
        records.append(measure_setting(ctx, scene, setting, opacity,
                                       first_of_method=setting.method not in seen))
        seen.add(setting.method)
        ctx.progress.advance()
    if vtk_settings:
        ctx.vtk_rig.load(scene)
    for setting in vtk_settings:
        ctx.progress.step(f"{scene.name}: VTK scattering {setting.label}")
        records.append(measure_vtk(ctx, scene, setting))
        ctx.progress.advance()
    ctx.cache.clear_scene(scene)
    ctx.reference_images.clear()
    ctx.recompute_cache.clear()
    return records


# ------------------------------------------------------------------------------------------
# Stability
# ------------------------------------------------------------------------------------------
def stability_settings(techniques: Mapping[str, type[Technique]], *, quick: bool) -> list[Setting]:
    """The settings every stability case runs: each technique's stability settings."""
    out: list[Setting] = []
    for name, cls in techniques.items():
        out += technique_settings(name, cls, quick=quick, stability=True)
    return out


def run_stability_case(ctx: Context, case: StabilityCase, settings: Sequence[Setting],
                       vtk_settings: Sequence[Setting]) -> list[dict[str, Any]]:
    """One sweep point for every stability setting: image error against the reference,
    finite/bounded checks on the image, the GPU volumes and the CPU light volume, and whether
    the shader built. Parameter sweeps run only for techniques declaring that parameter."""
    from vtkvol.bench.measure import FLAT_SPREAD_LIMIT, flat_spread, image_ok, volume_checks

    scene = case.scene
    opacity = scene.opacity()
    ctx.rig.load(scene)
    out = []
    for setting in settings:
        values = dict(setting.values)
        label = setting.label
        if case.parameter_sweep is not None:
            pname, choice = case.parameter_sweep
            param = next((p for p in ctx.techniques[setting.method].PARAMETERS
                          if p.name == pname), None)
            if param is None or (param.choices and choice not in param.choices):
                continue
            values[pname] = choice
        ctx.progress.step(f"stability {case.sweep}={case.value_label}: {setting.method} "
                          f"{label}")
        reference = _lighting_reference(ctx, setting.method)
        rec: dict[str, Any] = {
            "sweep": case.sweep, "value": case.value, "value_label": case.value_label,
            "unit": case.unit, "scene": scene.name, "method": setting.method,
            "setting": label, "renderer": ctx.renderer, "mode": ctx.config.mode,
            "date": ctx.date, "lighting": reference.lighting,
            "reference": reference.spec(scene, ctx.cache.budget).label, "rmse": None,
            "psnr": None, "ssim": None, "max_abs": None, "vol_rmse": None, "vol_max_abs": None,
            "flat_spread": None, "image_ok": False, "volumes_ok": False, "shader_ok": False,
            "ok": False, "error": None,
        }
        try:
            ref_img = _reference_image(ctx, scene, reference)
            ctx.rig.set_method(setting.method, values)
            ctx.rig.image()  # build frame (shader, textures, precomputation)
            ctx.rig.refine(ctx.config.refine_seconds)
            image = ctx.rig.image()
            shader_problem = ctx.errors.new_errors()
            rec["shader_ok"] = not shader_problem and ctx.rig.shader_installed()
            gpu = ctx.rig.gpu_volumes()
            gpu_problem = volume_checks(gpu)
            vox, cpu_problem = _voxel_metrics(
                ctx, scene, Setting(setting.method, values, label, label), opacity, force=True)
            rec["volumes_ok"] = not gpu_problem and not cpu_problem
            rec["image_ok"] = image_ok(image, ref_img)
            m = image_metrics(image, ref_img)
            rec.update(rmse=m["rmse"], psnr=m["psnr"], ssim=m["ssim"], max_abs=m["max_abs"],
                       vol_rmse=vox.get("vol_rmse"), vol_max_abs=vox.get("vol_max_abs"))
            problems = [p for p in (shader_problem, gpu_problem, cpu_problem) if p]
            if scene.flat_region is not None:
                # A flat scene (one surface, one light): a trend across the image is an error
                # whatever the reference says (the reference samples the same ray lattice).
                # Progressive methods are noisy by design, so only recorded.
                rec["flat_spread"] = flat_spread(image, scene.flat_region)
                progressive = "progressive" in ctx.techniques[setting.method].SPEC.capabilities
                if rec["flat_spread"] > FLAT_SPREAD_LIMIT and not progressive:
                    problems.append(f"image not flat on a flat scene: spread "
                                    f"{rec['flat_spread']:.3f} > {FLAT_SPREAD_LIMIT}")
            if not rec["shader_ok"] and not shader_problem:
                problems.append("technique shader code missing from the built program")
            if not rec["image_ok"]:
                problems.append("blank or malformed image")
            rec["ok"] = not problems
            rec["error"] = "; ".join(problems)[:500] or None
        except Exception as exc:
            rec["error"] = f"{type(exc).__name__}: {exc}"[:500]
        out.append(rec)
        ctx.progress.advance()
    if case.parameter_sweep is None and vtk_settings:
        ctx.vtk_rig.load(scene)
        for setting in vtk_settings:
            ctx.progress.step(f"stability {case.sweep}={case.value_label}: VTK scattering")
            r = measure_vtk_image(ctx, scene, setting)
            image = r.pop("image", None)
            r["flat_spread"] = (flat_spread(image, scene.flat_region)
                                if scene.flat_region is not None and image is not None else None)
            out.append({
                "sweep": case.sweep, "value": case.value, "value_label": case.value_label,
                "unit": case.unit, "scene": scene.name, "date": ctx.date,
                "mode": ctx.config.mode, "renderer": ctx.renderer, **r})
            ctx.progress.advance()
    ctx.cache.clear_scene(scene)
    ctx.reference_images.clear()
    return out


def measure_vtk_image(ctx: Context, scene: Scene, setting: Setting) -> dict[str, Any]:
    """Image metrics (no timing) of VTK's scattering against the scene's reference."""
    from vtkvol.bench.measure import image_ok

    reference = SurfaceReference()
    rec: dict[str, Any] = {"method": VTK_METHOD, "setting": setting.label,
                           "lighting": reference.lighting,
                           "reference": reference.spec(scene, ctx.cache.budget).label,
                           "vol_rmse": None, "vol_max_abs": None, "volumes_ok": True}
    try:
        ref_img = _reference_image(ctx, scene, reference)
        ctx.vtk_rig.set_setting(setting.values["blending"], setting.values["reach"])
        image = ctx.vtk_rig.image()
        rec["image"] = image  # for the caller's flatness record; popped before it is stored
        problem = ctx.errors.new_errors()
        m = image_metrics(image, ref_img)
        rec.update(rmse=m["rmse"], psnr=m["psnr"], ssim=m["ssim"], max_abs=m["max_abs"],
                   shader_ok=not problem, image_ok=image_ok(image, ref_img))
        rec["ok"] = rec["shader_ok"] and rec["image_ok"]
        rec["error"] = problem or (None if rec["image_ok"] else "blank or malformed image")
    except Exception as exc:
        rec.update(rmse=None, psnr=None, ssim=None, max_abs=None, shader_ok=False,
                   image_ok=False, ok=False, error=f"{type(exc).__name__}: {exc}"[:500])
    return rec


# ------------------------------------------------------------------------------------------
# Entry points
# ------------------------------------------------------------------------------------------
def run(config: BenchConfig, out_dir: Path, *, scenes: Sequence[Scene] | None = None,
        cases: Sequence[StabilityCase] | None = None,
        methods: Sequence[str] | None = None, progress: bool = True,
        command: str | None = None, stream: TextIO | None = None) -> dict[str, Any]:
    """Run a benchmark and write its outputs into ``out_dir``; returns the run's metadata
    with ``records``, ``stability`` and ``paths`` added.

    ``scenes``/``cases`` default to the configuration's; ``methods`` restricts the techniques
    (``"vtk_scattering"`` included by name); ``stream`` receives the progress bar (stderr).
    """
    from vtkvol.bench.measure import Rig, VtkErrors, VtkScatteringRig, machine_info

    t_start = time.perf_counter()
    cpu_start = time.process_time()
    load_start = _load_average()
    files_start = source_files()
    quick = config.mode == "quick"
    # Only lighting models with a reference can be measured (see vtkvol.bench.references);
    # the others are named in the run's notes rather than silently left out.
    installed = {n: c for n, c in installed_techniques().items()
                 if n not in (REFERENCE, MEDIUM_REFERENCE)}
    techniques = {n: c for n, c in installed.items() if c.SPEC.lighting in LIGHTING_REFERENCES}
    unmeasured = sorted(n for n in installed if n not in techniques)
    if methods is not None:
        techniques = {n: c for n, c in techniques.items() if n in methods}
    use_vtk = methods is None or VTK_METHOD in methods
    # local first: every ratio is to it, and the first timed method absorbs any cold start.
    order = sorted(techniques, key=lambda n: (n != "local", n))
    settings = [s for n in order for s in technique_settings(n, techniques[n], quick=quick)]
    vtk_settings = [vtk_setting(b, r) for b, r in config.vtk_settings] if use_vtk else []
    scene_list = list(scenes) if scenes is not None else bench_scenes(config.size, quick=quick)
    case_list = (list(cases) if cases is not None
                 else stability_cases(config.stability_size, quick=quick))
    stab_settings = stability_settings({n: techniques[n] for n in order}, quick=quick)
    stab_vtk = vtk_settings[:1]
    # one reference per scene and lighting model
    total = len(scene_list) * len({c.SPEC.lighting for c in techniques.values()} | {"surface"})
    total += len(scene_list) * (len(settings) + len(vtk_settings))
    for case in case_list:
        if case.parameter_sweep is None:
            total += len(stab_settings) + len(stab_vtk)
        else:
            total += sum(any(p.name == case.parameter_sweep[0]
                             for p in techniques[s.method].PARAMETERS) for s in stab_settings)
    bar = Progress(total, stream=stream, enabled=progress)
    date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    records: list[dict[str, Any]] = []
    stability: list[dict[str, Any]] = []
    cache = ReferenceCache(config.budget)
    with VtkErrors() as errors, registered():
        rig = Rig(config.image_size)
        vtk_rig = VtkScatteringRig(config.image_size)
        loaded = {m for m in sys.modules if m.startswith("vtkvol")}  # imported before it runs
        try:
            rig.rw.Render()  # create the context before asking it what it is
            info = machine_info(rig.rw)
            ctx = Context(config, rig, vtk_rig, errors, cache, techniques, bar,
                          renderer=info["renderer"], date=date)
            for scene in scene_list:
                records += run_scene(ctx, scene, settings, vtk_settings)
            if case_list:
                rig.rw.SetSize(config.stability_image_size, config.stability_image_size)
                vtk_rig.rw.SetSize(config.stability_image_size, config.stability_image_size)
                for case in case_list:
                    stability += run_stability_case(ctx, case, stab_settings, stab_vtk)
        finally:
            rig.close()
            vtk_rig.close()
    load = _time_load()
    bar.finish()
    report.add_derived(records)
    run_info: dict[str, Any] = {
        "load_seconds": load,
        "mode": config.mode, "date": date,
        "command": command or "vtkvol bench" + (" --quick" if quick else ""),
        "duration_s": time.perf_counter() - t_start,
        "cpu_seconds": time.process_time() - cpu_start,
        "reference_seconds": cache.seconds,
        "size": config.size, "image_size": config.image_size, "warmup": config.warmup,
        "frames": config.frames, "recompute_repeats": config.recompute_repeats,
        "stability_size": config.stability_size,
        "stability_image_size": config.stability_image_size,
        "reference_budget": vars(config.budget).copy(),
        "load_average_start": load_start, "load_average_end": _load_average(),
        "source_digest": source_digest(files_start),
        "techniques": {n: techniques[n].LABEL for n in order},
        "scenes": [{"name": s.name, "size": s.size_label, "spacing": list(s.spacing),
                    "kind": s.kind, "description": s.description} for s in scene_list],
        "unmeasured": unmeasured,
        **info,
    }
    changed, affecting = affecting_changes(files_start, source_files(), loaded)
    run_info.update(source_changes=changed, source_changed=bool(affecting),
                    source_changes_affecting=affecting)
    run_info["notes"] = _notes(run_info, records, stability)
    paths = report.write_all(out_dir, run_info, records, stability)
    return {**run_info, "records": records, "stability": stability, "paths": paths}


#: Packages whose files can change what a run measures: techniques, shaders, engine, bench.
_SOURCE_PACKAGES = ("vtkvol.plugins", "vtkvol.resources", "vtkvol.engine", "vtkvol.bench")


def source_files() -> dict[str, str]:
    """Hash (16 hex digits) of every file of the code that renders, by package path
    (``vtkvol/plugins/<name>/technique.py``): read through the installed packages, so
    it works from a wheel as from a checkout."""
    import hashlib
    from importlib import resources

    out: dict[str, str] = {}

    def walk(node: Any, prefix: str) -> None:
        for child in sorted(node.iterdir(), key=lambda c: c.name):
            if child.is_dir():
                if child.name != "__pycache__":
                    walk(child, f"{prefix}/{child.name}")
            elif child.name.endswith((".py", ".glsl")):
                out[f"{prefix}/{child.name}"] = hashlib.sha256(
                    child.read_bytes()).hexdigest()[:16]

    for package in _SOURCE_PACKAGES:
        walk(resources.files(package), package.replace(".", "/"))
    return out


def source_digest(files: Mapping[str, str]) -> str:
    """One hash over :func:`source_files`."""
    import hashlib

    return hashlib.sha256(repr(sorted(files.items())).encode()).hexdigest()[:16]


def affecting_changes(start: Mapping[str, str], end: Mapping[str, str],
                      loaded: set[str]) -> tuple[list[str], list[str]]:
    """``(changed, affecting)`` package paths between two :func:`source_files` snapshots.

    A changed Python module that was already imported when the run started (``loaded``:
    module names) cannot affect it, Python keeps the imported code; shader files are read
    whenever a program is built, and modules imported later load the new code, so those do.
    """
    changed = sorted(p for p in set(start) | set(end) if start.get(p) != end.get(p))
    affecting = []
    for path in changed:
        if path.endswith(".py"):
            parts = path[:-3].split("/")
            if parts[-1] == "__init__":
                parts = parts[:-1]
            module = ".".join(parts)
            if module in loaded:
                continue
        affecting.append(path)
    return changed, affecting


def _load_average() -> float | None:
    try:
        return round(os.getloadavg()[0], 2)
    except (OSError, AttributeError):
        return None


def _notes(run: Mapping[str, Any], records: Sequence[Mapping[str, Any]],
           stability: Sequence[Mapping[str, Any]]) -> str:
    """Facts a reader needs next to the numbers (machine load, failures)."""
    notes = []
    if run.get("source_changed"):
        files = ", ".join(run.get("source_changes_affecting") or [])
        notes.append(f"**source files the run reads changed while it was going ({files}): its "
                     "results may mix two versions of the code; re-run it**")
    elif run.get("source_changes"):
        notes.append(f"source files changed during the run but were already loaded, so the run "
                     f"used one version throughout ({', '.join(run['source_changes'])})")
    cores = run.get("cores") or 1
    load = max(v for v in (run.get("load_average_start"), run.get("load_average_end"), 0.0)
               if v is not None)
    if load > cores:
        notes.append(f"the machine was shared (1-min load average up to {load:.1f} on "
                     f"{cores} cores): absolute times are inflated, ratios measured side by "
                     "side are more reliable")
    if run.get("unmeasured"):
        notes.append(f"not measured (no reference for their lighting model yet): "
                     f"{', '.join(run['unmeasured'])}")
    failed = [f"{r['scene']}/{r['method']} {r['setting']}" for r in records if not r.get("ok")]
    if failed:
        notes.append(f"{len(failed)} failed setting(s): {', '.join(failed[:6])}")
    bad = [f"{c['sweep']}={c['value_label']} {c['method']}" for c in stability
           if not c.get("ok")]
    if bad:
        notes.append(f"{len(bad)} failed stability check(s): {', '.join(bad[:6])}")
    return "; ".join(notes)


def _time_load() -> dict[str, Any]:
    """Median time of ``read_volume`` on a generated 512×512×128×2-channel uint16 ImageJ TIFF
    (the foundation's load-time goal: ≤ 1 s), in a temporary folder removed afterwards."""
    import tempfile

    from vtkvol.bench.loadbench import time_load

    with tempfile.TemporaryDirectory(prefix="vtkvol-loadbench-") as tmp:
        result = time_load(tmp)
    return {"median_s": result["median_s"], "runs_s": result["runs_s"],
            "shape_czyx": list(result["shape_czyx"]), "file_bytes": result["file_bytes"]}


#: Largest ``--size`` of the benchmark scenes (voxels per side): 512³ float phantoms and their
#: references already take minutes and gigabytes.
MAX_SIZE = 512


def check_size(size: int | None) -> None:
    """``--size``: 16 to :data:`MAX_SIZE` voxels (``ValueError`` naming the value)."""
    if size is not None and size < 16:
        raise ValueError(f"--size must be at least 16 voxels, got {size}")
    if size is not None and size > MAX_SIZE:
        raise ValueError(f"--size must be at most {MAX_SIZE} voxels, got {size}")


def bench_command(mode_flag: str, quick: bool, size: int | None, out: str,
                  data: Sequence[str]) -> str:
    """The command line a run records (``mode_flag``: "", " --scattering", " --empty-space");
    data files by name only, so results from different machines compare."""
    return ("vtkvol bench" + mode_flag + (" --quick" if quick else "")
            + (f" --size {size}" if size is not None else "") + f" -o {out}"
            + "".join(f" --data {Path(d).name}" for d in data))


def main_scattering(quick: bool = False, out: str = "vtkvol-bench", size: int | None = None,
                    data: Sequence[str] = ()) -> int:
    """``vtkvol bench --scattering -o DIR [--quick] [--size N] [--data FILE]…``: the convergence
    study of the multiple-scattering techniques (:mod:`vtkvol.bench.convergence`), merged into
    ``DIR/benchmarks.*``. The phantoms and every ``--data`` file, with 1 and 3 lights."""
    from vtkvol.bench.convergence import StudyConfig
    from vtkvol.bench.convergence import run as run_study
    from vtkvol.bench.scenes import file_scenes, phantom_scenes
    from vtkvol.io import VolumeReadError

    config = StudyConfig(mode="quick", size=32, image_size=128, max_seconds=90.0) if quick \
        else StudyConfig()
    check_size(size)
    if size is not None:
        config = replace(config, size=int(size))
    command = bench_command(" --scattering", quick, size, out, data)
    try:
        scenes = phantom_scenes(config.size) + file_scenes(data, max_size=config.size)
    except VolumeReadError as exc:
        print(f"vtkvol: {exc}", file=sys.stderr)
        return 1
    Path(out).mkdir(parents=True, exist_ok=True)
    budget = QUICK_BUDGET if quick else FULL_BUDGET
    result = run_study(config, Path(out), scenes, budget=budget, command=command)
    print(f"vtkvol bench --scattering ({config.mode}): {len(result['records'])} checkpoints in "
          f"{result['duration_s'] / 60:.1f} min on {result['renderer']}", file=sys.stderr)
    for kind in ("json", "md", "scattering"):
        if kind in result["paths"]:
            print(f"  {kind}: {result['paths'][kind]}", file=sys.stderr)
    return 0


def main(quick: bool = False, out: str = "vtkvol-bench", size: int | None = None,
         data: Sequence[str] = ()) -> int:
    """``vtkvol bench -o DIR [--quick] [--size N] [--data FILE]…``: run and write
    ``DIR/benchmarks.*``.

    Returns 0 when every setting and stability check passed, 1 when some failed (the results
    are written either way).
    """
    config = QUICK if quick else FULL
    check_size(size)
    if size is not None:
        config = replace(config, size=int(size), stability_size=min(int(size),
                                                                      config.stability_size))
    command = bench_command("", quick, size, out, data)
    from vtkvol.io import VolumeReadError

    try:
        scenes = bench_scenes(config.size, quick=quick, data=data)
    except VolumeReadError as exc:
        print(f"vtkvol: {exc}", file=sys.stderr)
        return 1
    Path(out).mkdir(parents=True, exist_ok=True)
    result = run(config, Path(out), scenes=scenes, command=command)
    failed = [r for r in itertools.chain(result["records"], result["stability"])
              if not r.get("ok")]
    paths = result["paths"]
    print(f"vtkvol bench ({config.mode}): {len(result['records'])} records, "
          f"{len(result['stability'])} stability cases in {result['duration_s'] / 60:.1f} min "
          f"on {result['renderer']}", file=sys.stderr)
    for kind in ("json", "csv", "md", "pareto", "stability"):
        if kind in paths:
            print(f"  {kind}: {paths[kind]}", file=sys.stderr)
    if failed:
        print(f"  {len(failed)} failed (see the tables)", file=sys.stderr)
    return 1 if failed else 0
