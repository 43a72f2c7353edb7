"""Development study of the cone-traced technique (not part of the installed library):
accuracy against the CPU references, the opacity-vs-intensity averaging question, precompute
times and frame-time ratios. ``vtkvol bench`` measures every technique generically; these
tables go deeper into this one technique for docs/cone-tracing.md.

Run from the checkout: ``python benchmarks/cone_traced_timing.py`` prints every table as
markdown. Functions return plain rows (lists of dicts).

Accuracy is per point: the CPU cone tracer
(:func:`~vtkvol.plugins.cone_traced.cpu.cone_trace_cpu`, the shader's algorithm) against
independent Monte-Carlo references (:mod:`vtkvol.reference`) at the points the renderer shades (TF
opacity above the threshold; for AO also a defined normal): voxel centres, and for AO also random
off-grid positions ("samples", where a ray sample lands), which is where baked AO
(:func:`~vtkvol.plugins.cone_traced.cpu.baked_ao_cpu`, the bake's algorithm, then one
trilinear fetch: :func:`~vtkvol.plugins.cone_traced.cpu.sample_grid`) pays for its
interpolation. Phantoms are 1 µm voxels, so voxels = µm.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from vtkvol.plugins.cone_traced.cpu import (
    ambient_occlusion_cpu,
    baked_ao_cpu,
    blur_level,
    cone_trace_cpu,
    filtered_pyramid_cpu,
    gaussian_weights,
    gradient_normals,
    mip_level_count,
    optical_depth,
    sample_grid,
    source_pyramid,
    voxel_normals,
)
from vtkvol.plugins.cone_traced.technique import ConeTraced

Row = dict[str, Any]

#: Light used for the shadow measurements (world, towards the light): mostly from +z.
SHADOW_LIGHT = (0.35, 0.2, 1.0)
#: Towards the viewer for the view-cone AO measurements: looking down onto the phantoms' tops.
VIEW_DIRECTION = (0.0, 0.0, 1.0)


# ------------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------------
def _select_points(mask: np.ndarray, n_points: int, seed: int) -> np.ndarray:
    """Up to ``n_points`` voxel index coordinates (x, y, z) drawn from ``mask`` (seeded)."""
    zyx = np.argwhere(mask)
    if len(zyx) > n_points:
        zyx = zyx[np.random.default_rng(seed).choice(len(zyx), n_points, replace=False)]
    return zyx[:, ::-1].astype(np.float64)


def shaded_sample_points(
    alpha: np.ndarray, spacing: Sequence[float], n_points: int, threshold: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``n_points`` random off-grid positions (voxel coordinates x, y, z; seeded) where the
    trilinear opacity exceeds ``threshold`` and its gradient is defined, with the outward normals
    −∇α there (central differences of the trilinear α): where the ray caster's samples land."""
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(seed)
    hi = np.array(alpha.shape[::-1], dtype=np.float64) - 1.0
    pts_out: list[np.ndarray] = []
    nrm_out: list[np.ndarray] = []
    found = 0
    for _ in range(64):
        cand = rng.random((20 * n_points, 3)) * hi
        a = map_coordinates(alpha, cand[:, ::-1].T, order=1)
        nrm, defined = gradient_normals(optical_depth(alpha), spacing, cand)  # −∇α
        keep = np.nonzero((a > threshold) & defined)[0][: n_points - found]
        pts_out.append(cand[keep])
        nrm_out.append(nrm[keep])
        found += keep.size
        if found >= n_points:
            break
    return np.concatenate(pts_out), np.concatenate(nrm_out)


def _metrics(values: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    from vtkvol.reference import volume_metrics

    return volume_metrics(np.asarray(values), np.asarray(reference))


def pyramid_variant(
    values: np.ndarray,
    transfer: Callable[[np.ndarray], np.ndarray],
    average: str,
    sigma: float = 1.0,
    span: float = 3.0,
) -> list[np.ndarray]:
    """The optical-depth pyramid D_L built three ways from intensities ``values`` and a TF.

    * ``"opacity"`` (vtkvol): α = TF(values), then mean opacities per level, blur, −ln(1 − F);
    * ``"intensity"`` (thesis): mean *intensities* per level, TF applied per level, blur,
      −ln(1 − F);
    * ``"extinction"``: mean of −ln(1 − α) per level and blur (the optical depth itself).
    """
    levels = mip_level_count(values.shape)
    if average == "opacity":
        return filtered_pyramid_cpu(transfer(values), sigma, span, levels)
    if average == "intensity":
        alpha = [transfer(v) for v in source_pyramid(values, levels)]
        return filtered_pyramid_cpu(alpha[0], sigma, span, levels, alpha_levels=alpha)
    if average == "extinction":
        d = -np.log1p(-np.clip(transfer(values), 0.0, 1.0 - 1e-6))
        w = gaussian_weights(sigma, span)
        return [blur_level(s, w).astype(np.float32) for s in source_pyramid(d, levels)]
    raise ValueError(f"unknown averaging {average!r}")


# ------------------------------------------------------------------------------------------------
# Accuracy
# ------------------------------------------------------------------------------------------------
def ao_accuracy(
    *,
    n: int = 48,
    n_points: int = 1200,
    n_rays: int = 256,
    max_distance: float = 16.0,
    settings: Sequence[tuple[str, int]] = (
        ("view_cone", 1), ("hemisphere", 1), ("hemisphere", 3), ("hemisphere", 6),
        ("hemisphere", 12), ("baked_hemisphere", 6),
    ),
    ao_resolutions: Sequence[str] = ("full", "half"),
    where: Sequence[str] = ("voxels", "samples"),
    h0_values: Sequence[float] = (3.0,),
    lod_widths: Sequence[float] = (2.0, 4.0),
    threshold: float = 0.05,
    seed: int = 0,
) -> list[Row]:
    """Per-point AO RMSE against :func:`vtkvol.reference.ambient_occlusion_mc` (cosine-weighted
    hemisphere about the same normals, same maximum distance, ``min_distance`` = 0 and = h0).

    Scenes: V-groove, hollow sphere (3-voxel shell), sphere over slab. Points (``where``):
    ``"voxels"``, shaded voxel centres with a defined normal (np.gradient); ``"samples"``,
    random off-grid shaded positions (:func:`shaded_sample_points`). Per-sample modes trace their
    cones at the point; ``baked_hemisphere`` bakes the grid once per ``ao_resolutions`` entry
    (:func:`baked_ao_cpu`) and interpolates it at the point (the fragment shader's fetch).
    One row per (scene, where, AO setting, resolution, h0, LOD switch width, reference).
    """
    from vtkvol.reference import (
        ambient_occlusion_mc,
        phantom_groove,
        phantom_hollow_sphere,
        phantom_sphere_over_slab,
    )

    scenes = {
        "groove": phantom_groove(n),
        "hollow_sphere": phantom_hollow_sphere(n, 3),
        "sphere_over_slab": phantom_sphere_over_slab(n),
    }
    spacing = (1.0, 1.0, 1.0)
    rows: list[Row] = []
    for name, alpha in scenes.items():
        pyramid = filtered_pyramid_cpu(alpha)
        baked: dict[tuple[float, float, str, int], np.ndarray] = {}
        for place in where:
            if place == "voxels":
                normals = voxel_normals(alpha, spacing)
                has_normal = np.linalg.norm(normals, axis=-1) > 0
                pts = _select_points((alpha > threshold) & has_normal, n_points, seed)
                idx = pts.astype(int)
                nrm = normals[idx[:, 2], idx[:, 1], idx[:, 0]]
            elif place == "samples":
                pts, nrm = shaded_sample_points(alpha, spacing, n_points, threshold, seed)
            else:
                raise ValueError(f"unknown evaluation points {place!r}")
            refs = {
                d_min: ambient_occlusion_mc(
                    alpha, spacing, max_distance=max_distance, n_rays=n_rays, seed=seed,
                    points=pts, normals=nrm, min_distance=d_min,
                )
                for d_min in {0.0, *h0_values}
            }
            for h0 in h0_values:
                for lod_width in lod_widths:
                    for mode, cones in settings:
                        variants: list[tuple[str, np.ndarray]] = []
                        if mode == "baked_hemisphere":
                            for res in ao_resolutions:
                                key = (h0, lod_width, res, cones)
                                if key not in baked:
                                    baked[key] = baked_ao_cpu(
                                        alpha, spacing, resolution=res, cones=cones,
                                        max_distance_um=max_distance, h0=h0,
                                        lod_width=lod_width, pyramid=pyramid,
                                    )
                                variants.append(
                                    (res, sample_grid(baked[key], alpha.shape[::-1], pts))
                                )
                        else:
                            variants.append(("", ambient_occlusion_cpu(
                                pyramid, spacing, pts, nrm, VIEW_DIRECTION, mode=mode,
                                cones=cones, max_distance_um=max_distance, h0=h0,
                                lod_width=lod_width,
                            )))
                        for res, occ in variants:
                            for d_min, ref in sorted(refs.items()):
                                if d_min not in (0.0, h0):
                                    continue
                                rows.append({
                                    "scene": name, "where": place, "mode": mode,
                                    "cones": cones, "resolution": res, "h0": h0,
                                    "lod_width": lod_width, "ref_min_distance": d_min,
                                    "points": len(pts), "mean_ref": float(np.mean(ref)),
                                    "mean": float(np.mean(occ)), **_metrics(occ, ref),
                                })
    return rows


def shadow_accuracy(
    *,
    n: int = 48,
    n_points: int = 1500,
    n_rays: int = 128,
    angles: Sequence[float] = (1.0, 2.5, 5.0, 10.0, 20.0, 45.0),
    h0: float = 3.0,
    lod_widths: Sequence[float] = (2.0, 4.0),
    h_values: Sequence[float] = (2.5,),
    threshold: float = 0.05,
    seed: int = 0,
) -> list[Row]:
    """Per-voxel shadow (transmittance) RMSE on the sphere-over-slab phantom against the exact
    hard-shadow transmittance and the Monte-Carlo cone transmittance of the same half-angle,
    both with ``min_distance`` = h0 (the cone's self-occlusion offset) and 0. One row per
    (reference offset, angle, level-0 step h, LOD switch width, reference)."""
    from vtkvol.reference import (
        DirectionalLight,
        cone_transmittance_mc,
        phantom_sphere_over_slab,
        transmittance,
    )

    alpha = phantom_sphere_over_slab(n)
    spacing = (1.0, 1.0, 1.0)
    light = DirectionalLight(SHADOW_LIGHT)
    pts = _select_points(alpha > threshold, n_points, seed)
    dirs = np.broadcast_to(light.unit(), pts.shape)
    pyramid = filtered_pyramid_cpu(alpha)
    rows: list[Row] = []
    for d_min in (h0, 0.0):
        hard = transmittance(alpha, spacing, light, points=pts, min_distance=d_min)
        for angle in angles:
            soft = cone_transmittance_mc(
                alpha, spacing, light, half_angle_deg=angle, n_rays=n_rays, seed=seed,
                points=pts, min_distance=d_min,
            )
            for h in h_values:
                for lod_width in lod_widths:
                    t = cone_trace_cpu(pyramid, spacing, pts, dirs, h0=h0, h=h,
                                       lod_width=lod_width,
                                       sin_angle=math.sin(math.radians(angle)))
                    for ref_name, ref in (("cone_mc", soft), ("hard", hard)):
                        rows.append({
                            "scene": "sphere_over_slab", "angle": angle, "h0": h0, "h": h,
                            "lod_width": lod_width, "reference": ref_name,
                            "ref_min_distance": d_min, "points": len(pts),
                            "mean_ref": float(np.mean(ref)), "mean": float(np.mean(t)),
                            **_metrics(t, ref),
                        })
    return rows


def averaging_study(
    *,
    n: int = 64,
    n_points: int = 1500,
    n_rays: int = 256,
    angles: Sequence[float] = (5.0, 15.0, 30.0),
    ao_cones: int = 6,
    max_distance: float = 16.0,
    seed: int = 0,
) -> list[Row]:
    """Opacity vs intensity vs extinction averaging of the coarse levels (thesis §2.6.1).

    Intensity data: a sphere (value 1.0) over a slab (value 0.55, 3 voxels thick) under a thin
    perforated plate (value 0.55, 1 voxel thick, covering half the width, 50 % holes), with a
    steep TF α = 0.95·clip((v − 0.3)/0.2, 0, 1): averaging intensities before the TF makes thin
    structures vanish from the coarse levels. Shadows against the MC cone reference; AO
    (hemisphere) against the MC AO reference; both with ``min_distance`` = h0.
    """
    from vtkvol.reference import (
        DirectionalLight,
        ambient_occlusion_mc,
        cone_transmittance_mc,
    )

    def tf(v: np.ndarray) -> np.ndarray:
        return (0.95 * np.clip((np.asarray(v) - 0.3) / 0.2, 0.0, 1.0)).astype(np.float32)

    c = np.arange(n, dtype=np.float64)
    z, y, x = c[:, None, None], c[None, :, None], c[None, None, :]
    m = n - 1
    r = np.sqrt((x - m / 2) ** 2 + (y - m / 2) ** 2 + (z - 0.45 * m) ** 2)
    values = np.clip(0.12 * n + 0.5 - r, 0, 1)
    slab = (np.abs(z - 0.12 * m) <= 1.0) + 0 * (x + y)
    plate = (np.abs(z - 0.85 * m) < 0.5) & (x < m / 2) & (((x // 2) + (y // 2)) % 2 == 0)
    values = np.maximum(values, 0.55 * slab)
    values = np.maximum(values, 0.55 * plate)
    alpha = tf(values)
    spacing = (1.0, 1.0, 1.0)
    h0 = 3.0
    light = DirectionalLight(SHADOW_LIGHT)
    pts = _select_points(alpha > 0.05, n_points, seed)
    dirs = np.broadcast_to(light.unit(), pts.shape)
    normals = voxel_normals(alpha, spacing)
    nrm = normals[pts[:, 2].astype(int), pts[:, 1].astype(int), pts[:, 0].astype(int)]
    ao_ref = ambient_occlusion_mc(alpha, spacing, max_distance=max_distance, n_rays=256,
                                  seed=seed, points=pts, normals=nrm, min_distance=h0)
    soft = {a: cone_transmittance_mc(alpha, spacing, light, half_angle_deg=a, n_rays=n_rays,
                                     seed=seed, points=pts, min_distance=h0) for a in angles}
    rows: list[Row] = []
    for average in ("intensity", "opacity", "extinction"):
        pyramid = pyramid_variant(values, tf, average)
        for a in angles:
            t = cone_trace_cpu(pyramid, spacing, pts, dirs, sin_angle=math.sin(math.radians(a)),
                               h0=h0)
            rows.append({"average": average, "quantity": f"shadow {a:g}°",
                         **_metrics(t, soft[a])})
        occ = ambient_occlusion_cpu(pyramid, spacing, pts, nrm, VIEW_DIRECTION,
                                    cones=ao_cones, max_distance_um=max_distance, h0=h0)
        rows.append({"average": average, "quantity": f"AO {ao_cones} cones",
                     **_metrics(occ, ao_ref)})
    return rows


def _timing_volume(n: int) -> np.ndarray:
    """A bonsai-like test volume of intensities 0…1: slab, sphere and smooth noise."""
    from vtkvol.reference import phantom_sphere_over_slab

    base = phantom_sphere_over_slab(n)
    rng = np.random.default_rng(1)
    noise = rng.random((max(2, n // 8),) * 3)
    from scipy.ndimage import zoom

    blob = zoom(noise, n / noise.shape[0], order=1)[:n, :n, :n]
    return np.maximum(base, 0.6 * (blob > 0.75)).astype(np.float32)


def precompute_times(
    sizes: Iterable[int] = (128, 256), repeats: int = 3, *,
    ao_resolutions: Sequence[str] = ("full", "half"), cpu_bake_max: int = 128,
) -> list[Row]:
    """Filtered-pyramid and AO-bake precompute times per volume size (ms, median of
    ``repeats``).

    ``gpu_ms``: upload of the opacity volume + compute-shader pyramid (+ glFinish), the part
    that repeats on every TF edit; ``tf_edit_ms``: a whole TF edit as the app sees it (the
    host's CPU opacity volume + the above), without AO baking; ``cpu_ms``: the numpy/scipy
    pyramid; ``bake_<res>_ms``: the GPU AO bake (baked_hemisphere, 6 cones, defaults) on the
    ``res`` grid, which a TF edit adds in that mode; ``bake_<res>_cpu_ms``: :func:`baked_ao_cpu`
    (sizes ≤ ``cpu_bake_max`` only, once).
    """
    import vtk

    from vtkvol.engine.gl import gl
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import simple_volume_scene

    rows: list[Row] = []
    for n in sizes:
        vol = _timing_volume(n)
        rw, ren, volume = simple_volume_scene(vol, size=(64, 64))
        il = Illuminator(volume, ren, method="cone_traced",
                         parameters={"shadows": False, "ao_mode": "off"})
        il.profiling = True  # GPU times from timer queries, read after a glFinish below
        try:
            rw.Render()
            tech = il.technique
            assert isinstance(tech, ConeTraced)
            gpu, edit = [], []
            otf = volume.GetProperty().GetScalarOpacity()
            for i in range(repeats):
                il.invalidate()
                rw.Render()
                gl(rw).glFinish()
                gpu.append(float(tech.stats().get("recompute_ms", math.nan)))
                otf.AddPoint(0.5, 0.4 + 0.01 * i)  # a real TF edit: new opacity volume
                rw.Render()
                edit.append(il.last_prepare_ms)
            cpu = []
            opacity = il.opacity_volume()
            for _ in range(max(1, repeats - 1)):
                t0 = time.perf_counter()
                filtered_pyramid_cpu(opacity)
                cpu.append((time.perf_counter() - t0) * 1e3)
            row: Row = {
                "size": n, "voxels": n**3, "backend": tech.stats()["backend"],
                "levels": tech.filtered.mip_levels if tech.filtered else 0,
                "gpu_ms": statistics.median(gpu), "tf_edit_ms": statistics.median(edit),
                "cpu_ms": statistics.median(cpu),
                "mvox_per_s": n**3 / statistics.median(gpu) / 1e3,
            }
            values = il.parameters
            for res in ao_resolutions:
                il.set_parameters(ao_mode="baked_hemisphere", ao_resolution=res)
                rw.Render()  # compiles the bake program on the first pass
                bake = []
                for _ in range(repeats):
                    il.set_parameters(h0=3.25)  # a bake parameter: re-bake, keep the pyramid
                    rw.Render()
                    il.set_parameters(h0=3.0)
                    rw.Render()
                    gl(rw).glFinish()
                    bake.append(float(tech.stats().get("bake_ms", math.nan)))
                row[f"bake_{res}_ms"] = statistics.median(bake)
                row["bake_backend"] = tech.stats()["bake_backend"]
                if n <= cpu_bake_max:
                    t0 = time.perf_counter()
                    baked_ao_cpu(opacity, il.spacing, resolution=res, cones=6,
                                 max_distance_um=values["max_distance"] * min(il.spacing),
                                 unit_distance=il.unit_distance)
                    row[f"bake_{res}_cpu_ms"] = (time.perf_counter() - t0) * 1e3
            rows.append(row)
        finally:
            il.release()
            rw.Finalize()
        del rw, ren, volume
        vtk.vtkObject.GlobalWarningDisplayOff()
    return rows


def frame_ratios(
    size: int = 128,
    *,
    image: int = 256,
    frames: int = 6,
    configs: Mapping[str, Mapping[str, Any]] | None = None,
) -> list[Row]:
    """Median frame time of cone-traced configurations ÷ local shading, same scene and run.

    One offscreen window per configuration (local shading included), all showing the same
    ``size``³ volume at ``image``² pixels with one directional light; frames are rendered
    round-robin (one frame of each window per round, the camera orbiting 2° per round), so
    drifting machine load affects every configuration alike. The first two rounds (shader
    build, precompute) are not timed. Default configs: shadows only, AO only (per-sample
    hemisphere 6 cones, baked hemisphere at full and half resolution, view cone), shadows + AO
    (the same four), and shadows + per-sample AO with the opacity gate closed (the cost of the
    shader code when no cone is traced).
    """
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import simple_volume_scene
    from vtkvol.model import Light

    configs = dict(configs or {
        "shadows": {"shadows": True, "ao_mode": "off"},
        "ao_hemisphere6": {"shadows": False, "ao_mode": "hemisphere", "ao_cones": "6"},
        "ao_baked6": {"shadows": False, "ao_mode": "baked_hemisphere", "ao_cones": "6"},
        "ao_baked6_half": {"shadows": False, "ao_mode": "baked_hemisphere", "ao_cones": "6",
                           "ao_resolution": "half"},
        "ao_view_cone": {"shadows": False, "ao_mode": "view_cone"},
        "shadows+ao6": {"shadows": True, "ao_mode": "hemisphere", "ao_cones": "6"},
        "shadows+ao_baked6": {"shadows": True, "ao_mode": "baked_hemisphere", "ao_cones": "6"},
        "shadows+ao_baked6_half": {"shadows": True, "ao_mode": "baked_hemisphere",
                                   "ao_cones": "6", "ao_resolution": "half"},
        "shadows+ao_view": {"shadows": True, "ao_mode": "view_cone"},
        # Same shader as shadows+ao6 but no sample passes the gate: the cost of the code alone.
        "shadows+ao6, no cone traced": {"shadows": True, "ao_mode": "hemisphere",
                                         "ao_cones": "6", "opacity_threshold": 1.0},
    })
    vol = _timing_volume(size)
    scenes = {}
    for name, params in {"local": None, **configs}.items():
        rw, ren, volume = simple_volume_scene(vol, size=(image, image), elevation=25.0,
                                              sample_distance=0.5)
        il = Illuminator(volume, ren, method="local" if params is None else "cone_traced",
                         lights=[Light(direction=SHADOW_LIGHT)], parameters=params)
        scenes[name] = (rw, ren, il)
    times: dict[str, list[float]] = {name: [] for name in scenes}
    try:
        for round_ in range(frames + 2):
            for name, (rw, ren, _il) in scenes.items():
                ren.GetActiveCamera().Azimuth(2.0)
                rw.MakeCurrent()
                t0 = time.perf_counter()
                rw.Render()
                _finish(rw)
                if round_ >= 2:
                    times[name].append((time.perf_counter() - t0) * 1e3)
    finally:
        for rw, _ren, il in scenes.values():
            rw.MakeCurrent()
            il.release()
            rw.Finalize()
    local_ms = statistics.median(times["local"])
    return [
        {"config": name, "size": size, "image": image, "ms": statistics.median(ts),
         "ratio": statistics.median(ts) / local_ms, "frames": len(ts)}
        for name, ts in times.items()
    ]


def _finish(rw: Any) -> None:
    from vtkvol.engine.gl import gl

    gl(rw).glFinish()


# ------------------------------------------------------------------------------------------------
# Markdown
# ------------------------------------------------------------------------------------------------
def markdown(rows: Sequence[Row], columns: Sequence[str]) -> str:
    """A markdown table of ``columns`` of ``rows`` (floats with 3–4 significant digits)."""
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.0f}"
        return str(v)

    head = "| " + " | ".join(columns) + " |\n|" + "---|" * len(columns) + "\n"
    return head + "".join("| " + " | ".join(fmt(r.get(c, "")) for c in columns) + " |\n"
                          for r in rows)


def main() -> None:
    print("## AO accuracy\n")
    print(markdown(ao_accuracy(), ["scene", "where", "mode", "cones", "resolution",
                                   "lod_width", "ref_min_distance", "rmse", "bias", "mean_ref",
                                   "mean"]))
    print("## Shadow accuracy\n")
    print(markdown(shadow_accuracy(), ["angle", "h", "lod_width", "reference",
                                       "ref_min_distance", "rmse", "bias", "mean_ref",
                                       "mean"]))
    print("## Averaging\n")
    print(markdown(averaging_study(), ["average", "quantity", "rmse", "bias", "max_abs"]))
    print("## Precompute\n")
    print(markdown(precompute_times(), ["size", "backend", "levels", "gpu_ms", "tf_edit_ms",
                                        "cpu_ms", "mvox_per_s", "bake_full_ms",
                                        "bake_half_ms", "bake_full_cpu_ms",
                                        "bake_half_cpu_ms"]))
    print("## Frame ratios\n")
    for size in (128, 256):
        print(markdown(frame_ratios(size), ["config", "size", "image", "ms", "ratio", "frames"]))


if __name__ == "__main__":
    main()
