"""Development study of the precomputed shadow volume (not part of the installed library):
recompute times per backend and resolution, frame-time ratios, accuracy against the exact
transmittance. ``vtkvol bench`` measures every technique generically; these tables go deeper
into this one technique for docs/shadow-volume.md.

Run from the checkout: ``python benchmarks/shadow_volume_timing.py`` prints every table as
markdown. Functions return plain rows (lists of dicts).

* :func:`recompute_times`: light-volume recompute after a light move and after a transfer-
  function edit, GPU (compute shader) and numpy paths, per resolution.
* :func:`frame_ratios`: frame time with shadows ÷ local shading only ÷ VTK's built-in volumetric
  shadows (``SetVolumetricScatteringBlending(1)``, ``SetGlobalIlluminationReach(1)``), same
  view, measured interleaved in the same run.
* :func:`accuracy`: the CPU light volume (the same algorithm as the GPU path, which matches it
  to 1e-6 in the tests) against :func:`vtkvol.reference.transmittance`, a dense ray march.

Scenes are :func:`vtkvol.reference.phantom_sphere_over_slab` with 1 µm voxels (so voxels = µm),
rendered from 8-bit data with the opacity transfer function α = value / 255; accuracy uses the
float phantom directly.
"""

from __future__ import annotations

import itertools
import math
import os
import statistics
import time
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from vtkvol.engine.light_grid import LightGrid, light_volume_cpu
from vtkvol.plugins.shadow_volume.technique import ShadowVolume

Row = dict[str, Any]

#: Light used for timing (world, towards the light).
LIGHT = (0.35, 0.2, 1.0)
#: Camera azimuth step between timed frames (degrees): the view changes, the lighting does not.
AZIMUTH_STEP = 2.0


def _tilted(deg: float) -> tuple[float, float, float]:
    """Unit direction tilted ``deg`` degrees from +z towards +x."""
    return (math.sin(math.radians(deg)), 0.0, math.cos(math.radians(deg)))


def _scene(n: int, size: int, elevation: float = 30.0) -> tuple[Any, Any, Any]:
    """The phantom as 8-bit data (like most microscopy data, so a TF edit takes the host's
    lookup-table path) with the opacity TF α = value / 255."""
    from vtkvol.engine.offscreen import simple_volume_scene
    from vtkvol.reference import phantom_sphere_over_slab

    data = np.round(phantom_sphere_over_slab(n) * 255.0).astype(np.uint8)
    return simple_volume_scene(data, size=(size, size), elevation=elevation,
                               opacity=[(0.0, 0.0), (255.0, 1.0)])


# ------------------------------------------------------------------------------------------------
# Recompute times
# ------------------------------------------------------------------------------------------------
def recompute_times(
    sizes: Sequence[int] = (128, 256),
    *,
    resolutions: Sequence[str] = ("full", "half", "quarter"),
    models: Sequence[str] = ("transmittance",),
    repeats: int = 5,
    cpu_max_size: int = 128,
    kernels: Sequence[str] = ("current",),
) -> list[Row]:
    """Light-volume recompute times (ms) per size, resolution, model and path.

    ``light_ms``: median after a light move (propagation only); ``tf_ms``: median after a
    transfer-function edit (the host's CPU opacity volume, upload, prefilter and propagation);
    ``min`` columns are the fastest of the repeats (the least disturbed by other load). The
    numpy path is measured up to ``cpu_max_size``. ``kernels``: GPU propagation designs
    measured back to back per configuration (:data:`KERNEL_DESIGNS`; "before" is the design
    this study replaced, for before/after tables from one run).
    """
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.model import Light

    rows: list[Row] = []
    for n in sizes:
        rw, ren, volume = _scene(n, 32)
        il = Illuminator(volume, ren, method="shadow_volume", lights=[Light(direction=LIGHT)])
        il.profiling = True  # GPU times from timer queries, read after a glFinish below
        otf = volume.GetProperty().GetScalarOpacity()
        try:
            backends = ["auto"] + (["cpu"] if n <= cpu_max_size else [])
            for backend in backends:
                for model, res in itertools.product(models, resolutions):
                    designs = kernels if backend == "auto" else ("current",)
                    times: dict[str, tuple[list[float], list[float]]] = {
                        k: ([], []) for k in designs}
                    reps = repeats if backend == "auto" else max(2, repeats // 2)
                    # Designs interleaved one light move and one TF edit at a time, so slow
                    # phases of a shared machine hit them alike.
                    for i in range(reps):
                        for d, kernel in enumerate(designs):
                            step = i * len(designs) + d  # a new light and TF every time
                            _use_kernel_design(kernel)
                            il.set_parameters(backend=backend, model=model, resolution=res)
                            if i == 0:
                                il.set_lights([Light(direction=LIGHT)])
                                rw.Render()  # compile, allocate, first computation
                            tech = il.technique
                            assert isinstance(tech, ShadowVolume)
                            light_ms, tf_ms = times[kernel]
                            light_ms += _light_moves(il, rw, tech, 1, step)
                            if i < max(2, reps // 2):
                                otf.AddPoint(128.0, 0.5 + 0.01 * (step % 2))  # a real TF edit
                                count = _recomputes(tech)
                                rw.Render()
                                if _recomputes(tech) > count:
                                    tf_ms.append(_recompute_ms(rw, tech))
                    grid = il.technique.grid
                    assert grid is not None
                    cells = grid.dims[0] * grid.dims[1] * grid.dims[2]
                    for kernel, (light_ms, tf_ms) in times.items():
                        rows.append({
                            "size": n, "model": model, "resolution": res, "kernel": kernel,
                            "backend": il.technique.stats().get("backend", ""),
                            "grid": "×".join(str(d) for d in grid.dims),
                            "light_ms": statistics.median(light_ms),
                            "light_min_ms": min(light_ms),
                            "tf_ms": statistics.median(tf_ms) if tf_ms else math.nan,
                            "tf_min_ms": min(tf_ms) if tf_ms else math.nan,
                            "mcells_per_s": cells / min(light_ms) / 1e3,
                            "light_volume_mib": grid.nbytes_per_light() / 2**20,
                        })
        finally:
            _use_kernel_design("current")
            il.release()
            rw.Finalize()
    return rows


#: Directional-light propagation designs of plugins/shadow_volume/gpu.py (its module
#: constants): "current" as shipped; "before": one kernel that also carries the side-face arm
#: (every cell paid for it on llvmpipe), 4 cells per invocation.
KERNEL_DESIGNS: dict[str, dict[str, Any]] = {
    "current": {},
    "before": {"EDGE_STRIPS_MIN_CELLS": None},
}
_SHIPPED: dict[str, Any] = {}


def _use_kernel_design(name: str) -> None:
    from vtkvol.engine import light_grid_gpu as gpu

    if not _SHIPPED:
        _SHIPPED.update(BLOCK=gpu.BLOCK, SPLIT_BLOCK=gpu.SPLIT_BLOCK,
                        EDGE_STRIPS_MIN_CELLS=gpu.EDGE_STRIPS_MIN_CELLS)
    for key, value in {**_SHIPPED, **KERNEL_DESIGNS[name]}.items():
        setattr(gpu, key, value)


def _light_moves(il: Any, rw: Any, tech: ShadowVolume, repeats: int,
                 first: int = 0) -> list[float]:
    from vtkvol.model import Light

    out: list[float] = []
    for i in range(first, first + repeats):
        angle = math.radians(3.0 * (i + 1) * (-1) ** i)  # small moves about z
        c, s = math.cos(angle), math.sin(angle)
        x, y, z = LIGHT
        il.set_lights([Light(direction=(c * x - s * y, s * x + c * y, z))])
        count = _recomputes(tech)
        rw.Render()
        if _recomputes(tech) > count:
            out.append(_recompute_ms(rw, tech))
    return out


def _recomputes(tech: Any) -> int:
    """How many precomputations the technique has run (its ``stats()``)."""
    return int(tech.stats().get("recomputes", 0))


def _recompute_ms(rw: Any, tech: Any) -> float:
    """The last recompute's time: GPU time of its timer query once the GPU is done."""
    from vtkvol.engine.gl import gl

    gl(rw).glFinish()
    return float(tech.stats()["recompute_ms"])


# ------------------------------------------------------------------------------------------------
# Frame-time ratios
# ------------------------------------------------------------------------------------------------
def frame_ratios(
    size: int = 128,
    *,
    image: int = 256,
    frames: int = 6,
    rounds: int = 3,
    lights: int = 1,
    parameters: dict[str, Any] | None = None,
) -> list[Row]:
    """Median frame times (ms) of local shading, the shadow volume and VTK's built-in
    volumetric shadows at the same view, and their ratios.

    Three windows hold the three configurations; their frames are timed interleaved, one frame
    of each in turn (``rounds`` × ``frames`` frames each, 2° camera azimuth per frame,
    ``glFinish`` inside the interval), so slow phases of a shared machine hit all three alike.
    ``lights`` directional lights (the first is :data:`LIGHT`); VTK's built-in gets the same
    ones as scene lights.
    Wall-clock and process CPU time are both reported (``frame_ms``, ``frame_cpu_ms``).
    """
    import vtk

    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.model import Light

    dirs = [LIGHT, (-0.6, 0.3, 0.8), (0.2, -0.7, 0.7), (0.8, 0.5, 0.3)][:lights]
    model_lights = [Light(direction=d, intensity=1.0 / lights) for d in dirs]
    configs: dict[str, tuple[Any, Any, Any, Any]] = {}
    for name in ("local", "shadow_volume", "vtk_volumetric"):
        rw, ren, volume = _scene(size, image)
        il = None
        if name == "vtk_volumetric":
            ren.AutomaticLightCreationOff()
            ren.RemoveAllLights()
            centre = np.array(volume.GetCenter())
            for d in dirs:
                u = np.asarray(d, float) / np.linalg.norm(d)
                light = vtk.vtkLight()
                light.SetLightTypeToSceneLight()
                light.SetPositional(False)
                light.SetFocalPoint(*centre)
                light.SetPosition(*(centre + 10.0 * size * u))
                light.SetIntensity(1.0 / lights)
                ren.AddLight(light)
            mapper = volume.GetMapper()
            mapper.SetVolumetricScatteringBlending(1.0)
            mapper.SetGlobalIlluminationReach(1.0)
        else:
            il = Illuminator(volume, ren, method=name, lights=model_lights,
                             parameters=parameters if name == "shadow_volume" else None)
        for _ in range(2):  # warm up: shader build, uploads, light volume
            rw.Render()
        configs[name] = (rw, ren, volume, il)
    samples: dict[str, list[float]] = {name: [] for name in configs}
    cpu: dict[str, list[float]] = {name: [] for name in configs}
    recomputes = 0
    try:
        sv = configs["shadow_volume"][3].technique
        before = _recomputes(sv)
        for _ in range(rounds * frames):
            for name, (rw, ren, _volume, _il) in configs.items():
                ren.GetActiveCamera().Azimuth(AZIMUTH_STEP)
                c0, t0 = time.process_time(), time.perf_counter()
                rw.Render()
                rw.WaitForCompletion()
                samples[name].append((time.perf_counter() - t0) * 1e3)
                cpu[name].append((time.process_time() - c0) * 1e3)
        recomputes = _recomputes(sv) - before
    finally:
        for rw, _ren, _volume, il in configs.values():
            if il is not None:
                il.release()
            rw.Finalize()
    med = {name: statistics.median(v) for name, v in samples.items()}
    med_cpu = {name: statistics.median(v) for name, v in cpu.items()}
    rows = []
    for name, v in samples.items():
        q = statistics.quantiles(v, n=4) if len(v) > 1 else [v[0], v[0], v[0]]
        rows.append({
            "method": name, "size": size, "image": image, "lights": lights,
            "frame_ms": med[name], "frame_iqr_ms": q[2] - q[0], "frame_min_ms": min(v),
            "ratio_vs_local": med[name] / med["local"],
            "ratio_vs_vtk": med[name] / med["vtk_volumetric"],
            # llvmpipe renders on this process's threads: CPU time is the work done, less
            # disturbed than wall time when other processes share the cores.
            "frame_cpu_ms": med_cpu[name],
            "cpu_ratio_vs_local": med_cpu[name] / med_cpu["local"],
            "cpu_ratio_vs_vtk": med_cpu[name] / med_cpu["vtk_volumetric"],
            "recomputes_during_timing": recomputes if name == "shadow_volume" else 0,
        })
    return rows


#: The lookup's per-sample reference formula (plugins/shadow_volume/shaders/): "before" in
#: :func:`lookup_frame_ratios`.
PER_SAMPLE_SHADER = "per_sample_lookup.glsl"
#: :func:`lookup_frame_ratios`' configurations: label, method, parameters, per-sample lookup.
LOOKUP_CONFIGS: tuple[tuple[str, str, dict[str, Any], bool], ...] = (
    ("local", "local", {}, False),
    ("shadow_volume full, per-sample lookup (before)", "shadow_volume", {}, True),
    ("shadow_volume full", "shadow_volume", {}, False),
    ("shadow_volume ½, per-sample lookup (before)", "shadow_volume", {"resolution": "half"}, True),
    ("shadow_volume ½", "shadow_volume", {"resolution": "half"}, False),
    ("cone_traced shadows", "cone_traced", {"ao_mode": "off"}, False),
    ("cone_traced shadows + baked AO 6 (default)", "cone_traced", {}, False),
)


def lookup_frame_ratios(
    scenes: Sequence[Any], *, image: int = 256, frames: int = 8, warmup: int = 2,
    lights: int = 1,
) -> list[Row]:
    """Frame time ÷ local shading per bench scene (:mod:`vtkvol.bench.scenes`) for the shadow
    volume with the per-sample lookup (before) and the shipped one (after), at full and ½
    light-grid resolution, and for the cone tracer (shadows; shadows + baked AO).

    Each configuration has its own window (:class:`vtkvol.bench.measure.Rig`: the scene's
    light, view, sample distance); after ``warmup`` frames each, one frame of each in turn,
    ``frames`` times, 2° camera azimuth per frame, ``glFinish`` inside the interval; medians
    of wall and process CPU time. ``lights`` > 1 adds the extra directions of
    :func:`frame_ratios` (intensity 1/lights each). ``max_diff_levels``: the largest pixel
    difference (8-bit) between before and after at the scene's view.
    """
    from vtkvol.bench.measure import Rig, _frame_ms
    from vtkvol.model import Light

    rows: list[Row] = []
    for scene in scenes:
        rigs: dict[str, Any] = {}
        load = [os.getloadavg()[0]]
        try:
            for label, method, params, per_sample in LOOKUP_CONFIGS:
                rig = Rig(image)
                rigs[label] = rig
                rig.load(scene)
                if lights > 1:
                    dirs = [scene.lights[0], (-0.6, 0.3, 0.8), (0.2, -0.7, 0.7), (0.8, 0.5, 0.3)]
                    rig.illuminator.set_lights([
                        Light(direction=d, intensity=1.0 / lights, size=scene.light_size_deg)
                        for d in dirs[:lights]])
                rig.set_method(method, params)
                rig.rw.Render()
                if per_sample:
                    rig.illuminator.technique.SHADER = PER_SAMPLE_SHADER
                rig.reset_view()
                for _ in range(warmup):
                    _frame_ms(rig.rw)
            wall: dict[str, list[float]] = {label: [] for label in rigs}
            cpu: dict[str, list[float]] = {label: [] for label in rigs}
            for _ in range(frames):
                for label, rig in rigs.items():
                    rig.renderer.GetActiveCamera().Azimuth(AZIMUTH_STEP)
                    w, c = _frame_ms(rig.rw)
                    wall[label].append(w)
                    cpu[label].append(c)
            images = {label: rig.image().astype(int) for label, rig in rigs.items()}
        finally:
            for rig in rigs.values():
                rig.close()
        load.append(os.getloadavg()[0])
        local_w, local_c = statistics.median(wall["local"]), statistics.median(cpu["local"])
        for label, method, _params, per_sample in LOOKUP_CONFIGS:
            after = label.replace(", per-sample lookup (before)", "")
            diff = (int(np.abs(images[label] - images[after]).max())
                    if per_sample else None)
            rows.append({
                "scene": scene.name, "shape": "×".join(str(d) for d in scene.data.shape[::-1]),
                "lights": lights, "config": label, "method": method,
                "frame_ms": statistics.median(wall[label]),
                "frame_cpu_ms": statistics.median(cpu[label]),
                "ratio_vs_local": statistics.median(wall[label]) / local_w,
                "cpu_ratio_vs_local": statistics.median(cpu[label]) / local_c,
                "max_diff_levels": diff, "load": f"{load[0]:.1f}–{load[1]:.1f}",
            })
    return rows


# ------------------------------------------------------------------------------------------------
# Accuracy
# ------------------------------------------------------------------------------------------------
def accuracy(
    n: int = 64,
    *,
    degrees: Iterable[float] = (0.0, 22.5, 45.0),
    models: Iterable[str] = ("transmittance", "seed000"),
    softness: Iterable[float] = (0.0, 0.5),
    resolutions: Iterable[str] = ("full",),
) -> list[Row]:
    """RMSE and max error of the light volume against the exact transmittance, per light
    angle (tilted from +z towards +x; 45° puts the ray between cell centres, the case slice
    propagation finds hardest), model, softness and resolution.

    ``rmse``/``max_abs`` over all voxels; ``*_shaded`` only where α > 0.05 (where the renderer
    applies shading). seed000 has a fixed blur; it is measured once per angle.
    """
    from vtkvol.engine.illuminator import LightSpec
    from vtkvol.reference import (
        DirectionalLight,
        phantom_sphere_over_slab,
        transmittance,
        volume_metrics,
    )

    opacity = phantom_sphere_over_slab(n)
    mask = opacity > 0.05
    spacing = (1.0, 1.0, 1.0)
    rows: list[Row] = []
    for deg in degrees:
        d = _tilted(deg)
        ref = transmittance(opacity, spacing, DirectionalLight(d), step=0.25)
        spec = LightSpec("directional", d, (1.0, 1.0, 1.0))
        for model in models:
            for soft in softness if model == "transmittance" else (1.0,):
                for res in resolutions:
                    t0 = time.perf_counter()
                    vis = light_volume_cpu(opacity, spacing, spec, model=model, resolution=res,
                                           softness=soft)
                    ms = (time.perf_counter() - t0) * 1e3
                    vis = LightGrid.for_data(opacity.shape[::-1], spacing, res).to_data(vis)
                    m_all = volume_metrics(vis, ref)
                    m_sh = volume_metrics(vis, ref, mask)
                    rows.append({
                        "n": n, "degrees": deg, "model": model, "softness": soft,
                        "resolution": res, "rmse": m_all["rmse"], "max_abs": m_all["max_abs"],
                        "bias": m_all["bias"], "rmse_shaded": m_sh["rmse"],
                        "max_abs_shaded": m_sh["max_abs"], "cpu_ms": ms,
                    })
    return rows


# ------------------------------------------------------------------------------------------------
# Command line
# ------------------------------------------------------------------------------------------------
def _markdown(rows: Sequence[Row], columns: Sequence[str]) -> str:
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.4f}" if abs(v) < 1 else f"{v:.1f}"
        return str(v)

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(fmt(r.get(c, "")) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def main_lookup(argv: Sequence[str]) -> None:
    """``lookup [--size N] [--frames F] [--lights L] [--phantom NAME]… [--data FILE]…``:
    :func:`lookup_frame_ratios` on the bench phantoms at N³ (default 128: all three) and the
    given files (resampled to ≤ N)."""
    import argparse

    from vtkvol.bench.scenes import file_scenes, phantom_scenes

    parser = argparse.ArgumentParser(prog="shadow_volume_timing.py lookup")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--lights", type=int, default=1)
    parser.add_argument("--data", action="append", default=[])
    parser.add_argument("--phantom", action="append", default=None,
                        help="only these phantoms (sphere_over_slab, hollow_sphere, cells); "
                             "'none' for none")
    args = parser.parse_args(argv)
    scenes = [s for s in phantom_scenes(args.size)
              if args.phantom is None or s.name in args.phantom]
    scenes += file_scenes(args.data, args.size)
    for scene in scenes:
        print(f"\n### {scene.name} ({scene.description})\n", flush=True)
        rows = lookup_frame_ratios([scene], frames=args.frames, lights=args.lights)
        shown = [{
            "config": r["config"], "frame ms": f"{r['frame_ms']:.0f}",
            "× local": f"{r['ratio_vs_local']:.2f}", "CPU ms": f"{r['frame_cpu_ms']:.0f}",
            "× local (CPU)": f"{r['cpu_ratio_vs_local']:.2f}",
            "max Δ before/after (8-bit)": "" if r["max_diff_levels"] is None
            else str(r["max_diff_levels"]),
            "load": r["load"],
        } for r in rows]
        print(_markdown(shown, list(shown[0])), flush=True)


def main() -> None:
    import sys

    if sys.argv[1:2] == ["lookup"]:
        main_lookup(sys.argv[2:])
        return
    print("## Accuracy (phantom_sphere_over_slab(64), CPU path)\n")
    print(_markdown(accuracy(64), ["degrees", "model", "softness", "rmse", "max_abs",
                                   "rmse_shaded", "max_abs_shaded", "bias"]))
    print("\n## Recompute times (ms)\n")
    print(_markdown(recompute_times(), ["size", "model", "resolution", "backend", "grid",
                                        "light_ms", "light_min_ms", "tf_ms", "mcells_per_s",
                                        "light_volume_mib"]))
    print("\n## Frame times (128³, 256² image)\n")
    for lights in (1, 4):
        print(_markdown(frame_ratios(128, lights=lights),
                        ["method", "lights", "frame_ms", "frame_iqr_ms", "ratio_vs_local",
                         "ratio_vs_vtk", "frame_cpu_ms", "cpu_ratio_vs_local",
                         "cpu_ratio_vs_vtk", "recomputes_during_timing"]))
        print()


if __name__ == "__main__":
    main()
