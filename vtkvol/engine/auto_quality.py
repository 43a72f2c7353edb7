"""``auto`` quality: the cheapest illumination setting that meets an error budget for a scene.

Product code: the app's Auto (``ui/auto_quality.py``) uses it, and it imports nothing of the
benchmark (``vtkvol.bench`` re-exports :func:`choose` and :class:`Choice`).

"Model no more than a scene needs." :func:`choose` takes the scene's opacity volume, voxel size
and lights, walks a list of candidate settings from cheapest to most expensive and returns the
first whose *predicted* image error meets the budget (default SSIM ≥ 0.98 against the
reference), saying what it picked and why::

    from vtkvol.engine.auto_quality import choose
    choice = choose(illuminator.opacity_volume(), illuminator.spacing,
                    [light.direction for light in lights])
    illuminator.set_method(choice.method, choice.parameters)
    print(choice.reason)

Candidates come from the techniques' declarations (:func:`spec_candidates`): every installed
``surface`` technique's ``bench`` settings marked ``quick`` (its defaults when it declares
none). Cost comes from a results file the caller names (``timings``: the ``benchmarks.json``
that ``vtkvol bench -o DIR`` wrote, this machine's renderer preferred): for each candidate the
median over the benchmark's scenes of frame time + recompute time, i.e. the time to the first
correct frame after a light or transfer-function change, with the recompute part scaled by the
scene's voxel count. Candidates are tried in order of cost; costs within about 15 % of each
other count as equal and keep the listed order. Without measurements for every candidate an
explicit ``candidates`` list is tried in its own order (``cost_ms`` is then NaN); the declared
settings carry no cost order of their own, so choosing among them needs a results file (the
CPU light paths are no proxy: at small sizes their times are equal within noise).

Predicted error comes from cheap CPU measurements on the scene itself, no GPU needed:

1. the scene's one reference: the transmittance towards each light averaged over its extent
   (:func:`vtkvol.reference.extended_transmittance`, the light's ``size``; hard for an ideal
   light or a bare direction);
2. each candidate's own per-voxel light visibility, from its technique's CPU path
   (``Technique.light_visibility_cpu``: the same algorithm, resolution and filtering as its
   GPU path; 1 everywhere for techniques without shadows, such as local shading);
3. a proxy rendering of both on the CPU: front-to-back emission–absorption compositing of
   ``ka · A + kd · V · |n·l|`` (the host's shading formula, white albedo, ambient 0.3, diffuse
   0.7, normals from the opacity gradient) along each of the three axes, in both directions,
   where A is the ambient light's visibility: 1, or for a technique that occludes the ambient
   light its own CPU twin (``Technique.ambient_visibility_cpu``, per view) against the
   reference's Monte-Carlo AO (:data:`AO_DISTANCE_VOXELS`, :data:`AO_RAYS`), so that each
   ambient-occlusion variant gets its own prediction;
4. predicted SSIM = the worst SSIM of the six candidate/reference proxy image pairs.

Only the candidates up to the first that passes are evaluated, so a smooth scene that a
quarter-resolution light volume serves costs one or two cheap CPU passes.

For callers without a results file of their own (the app's Auto), :func:`default_timings`
names the cost source: the ``benchmarks.json`` in ``$VTKVOL_BENCHMARKS``, else the timings
shipped with vtkvol (``vtkvol/resources/auto_quality/timings.json``: the frame and recompute
times of the project's ``docs/benchmarks.json``, a quick run on llvmpipe). The cost *order*
of the settings is what matters, and it is the same on a GPU for the candidates that matter
(local < light volume at quarter/half/full resolution < cone tracing), only the gaps differ.
:func:`choose_measured` then chooses among the declared candidates that have measurements and
says which it left out. With ``frames`` (:class:`FrameTimes`: full-quality frames measured on
this machine, as the app records them) the costs, and the time :func:`duration_words` quotes,
are this machine's; the shipped figures then only scale the settings not measured here.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Shading constants of the proxy rendering (the benchmark scenes' vtkVolumeProperty).
AMBIENT = 0.3
DIFFUSE = 0.7
#: Directions towards the viewer of the six proxy views, in :func:`proxy_images`' order.
PROXY_VIEWS: tuple[tuple[float, float, float], ...] = (
    (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 1.0, 0.0),
    (0.0, 0.0, -1.0), (0.0, 0.0, 1.0))
#: Reach of the reference ambient occlusion: absorbers within this many voxels (of the
#: smallest edge) occlude, as in the benchmark's scenes (``DEFAULT_AO_DISTANCE_VOXELS``).
AO_DISTANCE_VOXELS = 24.0
#: Monte-Carlo directions per voxel of the reference AO (standard error ≤ 0.5/√32 ≈ 0.09 per
#: voxel; the SSIM of whole images averages far below that).
AO_RAYS = 32


@dataclass(frozen=True)
class Candidate:
    """A setting ``choose`` may pick: technique ``method`` with parameter overrides."""

    method: str
    parameters: Mapping[str, Any] = field(default_factory=dict, hash=False)

    @property
    def label(self) -> str:
        if not self.parameters:
            return self.method
        inner = ", ".join(f"{k}={v}" for k, v in self.parameters.items())
        return f"{self.method} ({inner})"


def spec_candidates() -> list[Candidate]:
    """The default candidates, from the declarations of the installed ``surface`` techniques:
    each one's ``bench`` settings marked ``quick`` (its representative subset), or its
    defaults when it declares none. Medium techniques are left out: the proxy rendering
    below is the surface model's shading."""
    from vtkvol.engine.technique import installed_techniques

    out: list[Candidate] = []
    for name, cls in sorted(installed_techniques().items()):
        # The benchmark's own reference renderers are no setting a user would pick.
        if cls.SPEC.engine.startswith("vtkvol.bench.") or cls.SPEC.lighting != "surface":
            continue
        chosen = [b for b in cls.SPEC.bench if b.quick]
        out += [Candidate(name, dict(b.values)) for b in chosen] or [Candidate(name)]
    return out


@dataclass(frozen=True)
class Choice:
    """What :func:`choose` picked.

    Attributes
    ----------
    method, parameters
        Technique name and full parameter values (declared defaults + the candidate's).
    predicted_ssim
        Predicted SSIM of the chosen setting against the reference (proxy rendering, 0…1).
    cost_ms
        Measured cost (ms: frame + scaled recompute on the benchmark machine), NaN if unknown.
    reason
        One or two sentences saying what was picked and why.
    considered
        Every evaluated candidate: ``label``, ``predicted_ssim``, ``cost_ms``.
    """

    method: str
    parameters: dict[str, Any]
    predicted_ssim: float
    cost_ms: float
    reason: str
    considered: tuple[dict[str, Any], ...] = ()
    #: Where the costs came from (:attr:`Timings.source`); "" when the caller passed them.
    cost_source: str = ""
    #: Labels of declared candidates left out for want of a measured cost.
    unmeasured: tuple[str, ...] = ()
    #: The picked candidate's label: the method and the settings it sets itself.
    label: str = ""
    #: Whether ``cost_ms`` is this machine's (:class:`FrameTimes`), not the shipped figures'.
    cost_here: bool = False
    #: Labels of the candidates whose cost was measured here (the others are scaled).
    measured_here: tuple[str, ...] = ()


class _CpuHost:
    """The few host attributes the techniques' CPU light paths read, without any GL."""

    def __init__(self, opacity: np.ndarray, spacing: Sequence[float], unit_distance: float):
        from vtkvol.engine.offscreen import image_from_array

        self.image = image_from_array(opacity, tuple(spacing))  # type: ignore[arg-type]
        self.spacing = tuple(float(s) for s in spacing)
        nz, ny, nx = opacity.shape
        self.dims = (nx, ny, nz)
        self.unit_distance = float(unit_distance)
        self.render_window = None
        self._opacity = opacity

    def opacity_volume(self) -> np.ndarray:
        return self._opacity


def _light_size(light: Any) -> float:
    """Angular radius (°) of a directional light: ``Light.angular_radius_deg()`` of the model,
    a ``size`` attribute, or 0 (ideal) for a bare direction."""
    if hasattr(light, "angular_radius_deg"):
        return float(light.angular_radius_deg())
    return float(getattr(light, "size", 0.0) or 0.0)


def _light_direction(light: Any) -> tuple[float, float, float]:
    """World direction towards a directional light from a ``Light`` model, a ``LightSpec`` or
    an (x, y, z) tuple."""
    if hasattr(light, "kind") and getattr(light, "kind", "directional") == "point":
        raise ValueError("auto quality supports directional lights only")
    vec = getattr(light, "direction", None) or getattr(light, "vector", None) or light
    d = np.asarray(vec, dtype=np.float64)
    if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) == 0:
        raise ValueError(f"light direction {vec!r} must be three finite numbers, not all 0")
    d = d / np.linalg.norm(d)
    return (float(d[0]), float(d[1]), float(d[2]))


def proxy_images(opacity: np.ndarray, visibility: Sequence[np.ndarray],
                 lights: Sequence[Sequence[float]], spacing: Sequence[float],
                 unit_distance: float,
                 ambient: Sequence[np.ndarray] | None = None) -> list[np.ndarray]:
    """Six orthographic CPU renderings (views towards :data:`PROXY_VIEWS`) of the host's
    shading with the given per-light visibility volumes and, optionally, one ambient
    visibility volume per view (1 − AO; None: unoccluded); float images in [0, 1].

    Per voxel: colour ``AMBIENT · A + DIFFUSE · Σ_i V_i · |n·l_i|`` (white albedo, two-sided,
    n·l := 1 where the opacity gradient vanishes), opacity corrected for the voxel's length
    along the view axis (α' = 1 − (1 − α)^(s/u)), composited front to back.
    """
    alpha = np.clip(np.asarray(opacity, dtype=np.float64), 0.0, 1.0 - 1e-6)
    gz, gy, gx = np.gradient(alpha)
    g = np.stack([gx / spacing[0], gy / spacing[1], gz / spacing[2]], axis=-1)
    glen = np.linalg.norm(g, axis=-1)
    colour = np.full(alpha.shape, AMBIENT)
    for vis, light in zip(visibility, lights, strict=True):
        ndl = np.abs(g @ np.asarray(light, dtype=np.float64)) / np.where(glen > 1e-12, glen, 1)
        ndl = np.where(glen > 1e-12, ndl, 1.0)
        colour += DIFFUSE * np.asarray(vis, dtype=np.float64) * ndl
    direct = colour - AMBIENT
    images = []
    views = iter(range(len(PROXY_VIEWS)))
    for axis, step in ((2, spacing[0]), (1, spacing[1]), (0, spacing[2])):
        a = 1.0 - np.power(1.0 - alpha, step / unit_distance)
        for flip in (False, True):
            view = next(views)
            shade = colour if ambient is None else direct + AMBIENT * np.asarray(
                ambient[view], dtype=np.float64)
            shade = np.clip(shade, 0.0, 1.0)
            aa = np.flip(a, axis) if flip else a
            cc = np.flip(shade, axis) if flip else shade
            trans = np.cumprod(1.0 - aa, axis=axis)
            before = np.concatenate([np.ones_like(np.take(trans, [0], axis)),
                                     np.take(trans, range(trans.shape[axis] - 1), axis)],
                                    axis=axis)
            images.append(np.sum(cc * aa * before, axis=axis))
    return images


def _ssim(a: np.ndarray, b: np.ndarray) -> float:
    from vtkvol.reference import image_metrics

    if min(a.shape) < 3:
        return 1.0 if np.allclose(a, b, atol=1e-3) else 0.0
    return image_metrics(np.clip(a, 0, 1).astype(np.float64),
                         np.clip(b, 0, 1).astype(np.float64))["ssim"]


def measured_costs(candidates: Sequence[Candidate], timings: Any, voxels: int,
                   renderer: str | None = None,
                   defaults: Mapping[str, Mapping[str, Any]] | None = None,
                   ) -> dict[Candidate, float]:
    """Cost (ms) per candidate from benchmark records: the median over matching records of
    ``frame_ms + recompute_ms · voxels / record voxels``. A record matches when its method is
    the candidate's and its parameters equal the candidate's, taking the technique's
    ``defaults`` (per method) for the parameters the candidate leaves out. ``timings`` is a
    path, a results document (``{"records": [...]}``) or a list of records; ``renderer``
    prefers records of that renderer (else the most common one)."""
    if timings is None:
        return {}
    if isinstance(timings, str | Path):
        try:
            timings = json.loads(Path(timings).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}
    records = timings.get("records", []) if isinstance(timings, Mapping) else list(timings)
    records = [r for r in records if r.get("ok") and r.get("frame_ms") is not None]
    if not records:
        return {}
    renderers = [r.get("renderer") for r in records]
    chosen = renderer if renderer in renderers else max(set(renderers), key=renderers.count)
    records = [r for r in records if r.get("renderer") == chosen]
    out: dict[Candidate, float] = {}
    for cand in candidates:
        wanted = {**(defaults or {}).get(cand.method, {}), **cand.parameters}
        costs = []
        for r in records:
            params = r.get("parameters") or {}
            if r["method"] != cand.method or any(params.get(k) != v for k, v in wanted.items()):
                continue
            nx, ny, nz = (int(v) for v in str(r.get("size", "1x1x1")).split("x"))
            recompute = float(r.get("recompute_ms") or 0.0) * voxels / max(1, nx * ny * nz)
            costs.append(float(r["frame_ms"]) + recompute)
        if costs:
            out[cand] = statistics.median(costs)
    return out


def choose(
    scene_opacity: np.ndarray,
    spacing: Sequence[float],
    lights: Sequence[Any],
    *,
    budget_ssim: float = 0.98,
    candidates: Sequence[Candidate] | None = None,
    timings: Any = None,
    unit_distance: float | None = None,
    renderer: str | None = None,
    voxels: int | None = None,
    costs: Mapping[Candidate, float] | None = None,
) -> Choice:
    """The cheapest candidate whose predicted SSIM against the reference is ≥ ``budget_ssim``.

    Parameters
    ----------
    scene_opacity
        Transfer-function opacity α ∈ [0, 1] per voxel, ``[z, y, x]`` (e.g.
        ``Illuminator.opacity_volume()``).
    spacing
        Voxel edge (x, y, z) in µm.
    lights
        Directional lights: ``vtkvol.Light`` objects, ``LightSpec`` or (x, y, z) directions
        towards the light (dataset space).
    budget_ssim
        Required predicted SSIM (0…1) of the image against the reference.
    candidates
        Settings to consider, cheapest first when no timings are available; default
        :func:`spec_candidates` (which then needs ``timings``). Those whose technique is not
        installed are skipped.
    timings
        Benchmark results for the cost ranking: a path (the ``benchmarks.json`` that
        ``vtkvol bench -o DIR`` wrote, ideally on this machine), a document or a list of
        records; None keeps the candidates' order.

    Raises
    ------
    ValueError
        Bad inputs, no installed candidate, or the declared candidates without measured costs
        for all of them (the message says which results file to make).
    unit_distance
        Opacity unit distance (µm); default the smallest voxel edge.
    renderer
        Prefer timings measured on this renderer string.
    voxels
        Voxel count the recompute costs are scaled to; default ``scene_opacity``'s (give the
        full data's when ``scene_opacity`` was binned, see :func:`binned_for_prediction`).
    costs
        Cost (ms) per candidate, replacing ``timings`` (e.g. :meth:`FrameTimes.costs`).
    """
    from scipy.ndimage import binary_dilation

    from vtkvol.engine.illuminator import LightSpec
    from vtkvol.engine.technique import installed_techniques
    from vtkvol.reference import (
        DirectionalLight,
        ambient_occlusion_mc,
        extended_transmittance,
        transmittance,
    )

    opacity = np.ascontiguousarray(np.clip(scene_opacity, 0.0, 1.0), dtype=np.float32)
    if opacity.ndim != 3:
        raise ValueError(f"scene_opacity must be a [z, y, x] volume, got shape {opacity.shape}")
    if not 0.0 < budget_ssim <= 1.0:
        raise ValueError(f"budget_ssim {budget_ssim} must be in (0, 1]")
    spacing = tuple(float(s) for s in spacing)
    u = float(min(spacing) if unit_distance is None else unit_distance)
    directions = [_light_direction(light) for light in lights]
    sizes = [_light_size(light) for light in lights]
    if not directions:
        raise ValueError("choose needs at least one light")
    installed = installed_techniques()
    cands = [c for c in (candidates or spec_candidates()) if c.method in installed]
    if not cands:
        raise ValueError("none of the candidate techniques is installed")
    if costs is None:
        costs = measured_costs(cands, timings, int(voxels or opacity.size), renderer,
                               {c.method: installed[c.method].defaults() for c in cands})
    if all(c in costs for c in cands):
        # Costs within ~15 % of each other count as equal (frame times on a shared machine are
        # that noisy): a stable sort on 15 %-wide log buckets keeps the listed order there.
        cands.sort(key=lambda c: round(math.log(max(costs[c], 1e-3)) / math.log(1.15)))
    elif candidates is None:
        missing = ", ".join(c.label for c in cands if c not in costs)
        raise ValueError(
            "auto quality ranks the declared settings by measured cost: pass timings= a "
            "benchmarks.json written by `vtkvol bench -o DIR` on this machine (no "
            f"measurement for {missing}), or an ordered candidates= list")
    host = _CpuHost(opacity, spacing, u)

    # The scene's one reference: transmittance averaged over each light's extent, evaluated
    # where a visible sample can read it (hard transmittance elsewhere).
    # Voxels a trilinear fetch at a visible sample can touch (the benchmark's relevant_mask).
    mask = binary_dilation(opacity > 1e-3, structure=np.ones((3, 3, 3), bool))
    pts = np.argwhere(mask)[:, ::-1] * np.asarray(spacing)
    ref_vis = []
    for d, size in zip(directions, sizes, strict=True):
        vis = transmittance(opacity, spacing, DirectionalLight(d), unit_distance=u, step=0.5)
        if size > 0 and len(pts):
            vis[mask] = extended_transmittance(opacity, spacing, DirectionalLight(d), size=size,
                                               n_rays=16, unit_distance=u, step=0.5,
                                               points=pts)
        ref_vis.append(vis)
    ref_images = proxy_images(opacity, ref_vis, directions, spacing, u)
    ref_ao_images: list[np.ndarray] | None = None  # with the reference AO, made when needed

    def reference_with_ao() -> list[np.ndarray]:
        """The reference images with the ambient light occluded by Monte-Carlo AO."""
        nonlocal ref_ao_images
        if ref_ao_images is None:
            gz, gy, gx = np.gradient(opacity.astype(np.float64))
            g = np.stack([gx / spacing[0], gy / spacing[1], gz / spacing[2]], axis=-1)[mask]
            glen = np.linalg.norm(g, axis=-1, keepdims=True)
            normals = np.where(glen > 1e-12, -g / np.where(glen > 1e-12, glen, 1.0), 0.0)
            ambient = np.ones(opacity.shape, np.float32)
            if len(pts):
                ambient[mask] = 1.0 - ambient_occlusion_mc(
                    opacity, spacing, max_distance=AO_DISTANCE_VOXELS * min(spacing),
                    n_rays=AO_RAYS, unit_distance=u, step=1.0, points=pts, normals=normals)
            ref_ao_images = proxy_images(opacity, ref_vis, directions, spacing, u,
                                         [ambient] * len(PROXY_VIEWS))
        return ref_ao_images

    considered: list[dict[str, Any]] = []
    best: tuple[float, Candidate, dict[str, Any]] | None = None
    for cand in cands:
        cls = installed[cand.method]
        values = {**cls.defaults(), **cand.parameters}
        tech = cls(host)  # type: ignore[arg-type]
        vis = []
        for d in directions:
            v = tech.light_visibility_cpu(opacity, spacing, LightSpec("directional", d,
                                                                      (1.0, 1.0, 1.0)), values)
            vis.append(np.ones_like(opacity) if v is None else np.clip(v, 0.0, 1.0))
        # A technique that occludes the ambient light is compared with the reference AO.
        ambient = tech.ambient_visibility_cpu(opacity, spacing, values, PROXY_VIEWS)
        images = proxy_images(opacity, vis, directions, spacing, u, ambient)
        reference = ref_images if ambient is None else reference_with_ao()
        ssim = min(_ssim(a, b) for a, b in zip(images, reference, strict=True))
        cost = costs.get(cand, math.nan)
        considered.append({"label": cand.label, "predicted_ssim": ssim, "cost_ms": cost,
                           "method": cand.method, "parameters": values})
        if best is None or ssim > best[0]:
            best = (ssim, cand, values)
        if ssim >= budget_ssim:
            cheaper = ", ".join(f"{c['label']} {c['predicted_ssim']:.3f}"
                                for c in considered[:-1])
            why = f"; cheaper candidates predicted {cheaper}" if cheaper else ""
            cost_text = f", cost {cost:.0f} ms" if math.isfinite(cost) else ""
            return Choice(cand.method, values, ssim, cost,
                          f"picked {cand.label}: predicted SSIM {ssim:.3f} ≥ {budget_ssim:g}"
                          f"{cost_text}{why}.", tuple(considered), label=cand.label)
    assert best is not None
    ssim, cand, values = best
    cost = costs.get(cand, math.nan)
    return Choice(cand.method, values, ssim, cost,
                  f"no candidate meets SSIM ≥ {budget_ssim:g}; picked the most accurate, "
                  f"{cand.label} (predicted SSIM {ssim:.3f}).", tuple(considered),
                  label=cand.label)


#: Environment variable naming a ``benchmarks.json`` (written by ``vtkvol bench -o DIR``) whose
#: costs :func:`default_timings` prefers to the shipped ones.
TIMINGS_ENV = "VTKVOL_BENCHMARKS"


@dataclass(frozen=True)
class Timings:
    """Benchmark records to rank candidates by, and where they came from.

    ``records``: dicts with at least ``method``, ``parameters``, ``size`` ("XxYxZ" voxels),
    ``frame_ms``, ``recompute_ms``, ``renderer`` and ``ok``. ``source``: one line for people,
    e.g. "shipped measurements (llvmpipe …, 2026-11-24)". ``note``: why a named file was not
    used ("" when nothing went wrong).
    """

    records: tuple[dict[str, Any], ...]
    source: str
    note: str = ""


def _read_records(path: Path) -> list[dict[str, Any]]:
    """The usable records of a results file; ValueError with a one-line reason otherwise."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"cannot read {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise ValueError(f"{path} is not valid JSON ({exc})") from None
    records = doc.get("records") if isinstance(doc, Mapping) else None
    if not isinstance(records, list):
        raise ValueError(f"{path} has no \"records\" list (not a benchmarks.json)")
    usable = [r for r in records if isinstance(r, Mapping) and r.get("ok")
              and isinstance(r.get("method"), str)
              and isinstance(r.get("frame_ms"), int | float) and math.isfinite(r["frame_ms"])
              and (r.get("recompute_ms") is None
                   or (isinstance(r["recompute_ms"], int | float)
                       and math.isfinite(r["recompute_ms"])))
              and isinstance(r.get("size", "1x1x1"), str)
              and _valid_size(r.get("size", "1x1x1"))]
    if not usable:
        raise ValueError(f"{path} has no successful timing records")
    return usable


def _valid_size(size: str) -> bool:
    parts = size.split("x")
    return len(parts) == 3 and all(p.isdigit() and int(p) > 0 for p in parts)


def shipped_timings() -> Timings:
    """The timings shipped with vtkvol (``resources/auto_quality/timings.json``)."""
    from importlib import resources

    text = resources.files("vtkvol.resources").joinpath("auto_quality", "timings.json")
    doc = json.loads(text.read_text(encoding="utf-8"))
    date = str(doc.get("date") or "")[:10]
    return Timings(tuple(doc["records"]),
                   f"shipped measurements ({doc.get('renderer')}, {date})")


def default_timings(environ: Mapping[str, str] | None = None) -> Timings:
    """The costs to rank by when the caller has no results file: the ``benchmarks.json`` that
    ``$VTKVOL_BENCHMARKS`` names (this machine's, ideally), else :func:`shipped_timings`. A
    named file that cannot be used falls back to the shipped timings with a ``note`` saying
    why."""
    env = os.environ if environ is None else environ
    named = env.get(TIMINGS_ENV, "").strip()
    if not named:
        return shipped_timings()
    path = Path(named).expanduser()
    try:
        records = _read_records(path)
    except ValueError as exc:
        shipped = shipped_timings()
        return dataclasses.replace(shipped, note=f"{TIMINGS_ENV}: {exc}; using the "
                                                 f"{shipped.source}")
    return Timings(tuple(records), f"measurements in {path}")


def choose_measured(
    scene_opacity: np.ndarray,
    spacing: Sequence[float],
    lights: Sequence[Any],
    *,
    budget_ssim: float = 0.98,
    timings: Timings | None = None,
    unit_distance: float | None = None,
    renderer: str | None = None,
    voxels: int | None = None,
    frames: FrameTimes | None = None,
) -> Choice:
    """:func:`choose` over the declared candidates (:func:`spec_candidates`) that ``timings``
    (default :func:`default_timings`) has costs for, cheapest first. Candidates without a
    measurement are left out (a technique newer than the measurements): the choice lists them
    in ``unmeasured`` and its ``reason`` says so, with the cost source. With ``frames``
    (this machine's measured frames) the costs are this machine's (:meth:`FrameTimes.costs`):
    measured settings at their measured time, the others scaled from ``timings``.

    Raises
    ------
    ValueError
        Bad inputs (see :func:`choose`), or no declared candidate has a measurement.
    """
    from vtkvol.engine.technique import installed_techniques

    timings = default_timings() if timings is None else timings
    installed = installed_techniques()
    declared = spec_candidates()
    opacity_size = int(voxels or np.asarray(scene_opacity).size)
    costs = measured_costs(declared, list(timings.records), opacity_size, renderer,
                           {c.method: installed[c.method].defaults() for c in declared})
    measured = [c for c in declared if c in costs]
    unmeasured = tuple(c.label for c in declared if c not in costs)
    if not measured:
        raise ValueError(f"none of the installed methods has a measured cost in the "
                         f"{timings.source}: run `vtkvol bench -o DIR` and set {TIMINGS_ENV} "
                         "to DIR/benchmarks.json")
    defaults = {c.method: installed[c.method].defaults() for c in declared}
    here, measured_here = (frames.costs(measured, costs, defaults, timings, opacity_size)
                           if frames is not None else ({}, set()))
    choice = choose(scene_opacity, spacing, lights, budget_ssim=budget_ssim,
                    candidates=measured, timings=list(timings.records),
                    unit_distance=unit_distance, renderer=renderer, voxels=opacity_size,
                    costs=here or None)
    if here:
        names = ", ".join(c.label for c in measured if c in measured_here)
        source = (f"frames measured on this machine ({names}; the others scaled by the "
                  f"{timings.source})")
    else:
        source = timings.source
    reason = f"{choice.reason} Costs: {source}."
    if unmeasured:
        reason += f" Not measured there, so not considered: {', '.join(unmeasured)}."
    if timings.note:
        reason += f" ({timings.note})"
    return dataclasses.replace(
        choice, reason=reason, cost_source=source, unmeasured=unmeasured, cost_here=bool(here),
        measured_here=tuple(c.label for c in measured if c in measured_here))


def binned_for_prediction(opacity: np.ndarray, spacing: Sequence[float],
                          max_voxels: int = 96**3) -> tuple[np.ndarray, tuple[float, ...]]:
    """``opacity`` ``[z, y, x]`` averaged over blocks of k×k×k voxels (k the smallest whole
    factor that leaves at most ``max_voxels``), and the blocks' edge (x, y, z) in µm; the
    input itself when it is small enough. The prediction's cost grows with the voxel count
    (several seconds and ~1 GB of temporaries at 96³); on binned data a coarse light volume
    is judged on the coarser grid, so the prediction errs towards finer (dearer) settings."""
    opacity = np.asarray(opacity, dtype=np.float32)
    if max_voxels < 1:
        raise ValueError(f"max_voxels {max_voxels} must be at least 1")
    k = 1
    while math.prod(-(-n // k) for n in opacity.shape) > max_voxels:
        k += 1
    if k == 1:
        return opacity, tuple(float(s) for s in spacing)
    nz, ny, nx = (-(-n // k) * k for n in opacity.shape)
    padded = np.pad(opacity, [(0, t - n) for t, n in zip((nz, ny, nx), opacity.shape,
                                                          strict=True)], mode="edge")
    blocks = padded.reshape(nz // k, k, ny // k, k, nx // k, k).mean(axis=(1, 3, 5))
    return np.ascontiguousarray(blocks, dtype=np.float32), tuple(float(s) * k for s in spacing)


# -- this machine's frames and the words for a choice ---------------------------------------------
#: Frames kept per setting (the median of the most recent ones is its cost).
KEPT_FRAMES = 9


def _setting_key(method: str, parameters: Mapping[str, Any]) -> tuple[str, tuple]:
    return method, tuple(sorted((k, repr(v)) for k, v in parameters.items()))


class FrameTimes:
    """Frame times measured on this machine, per setting (thread-safe enough for one writer).

    The app records every full-quality frame it shows (:meth:`record`: the whole view's
    render time, as the progressive refiner predicts it from its strips, plus the method's
    last precomputation), so Auto quality quotes what a frame costs *here*, not on the
    machine that made the shipped measurements. :meth:`costs` turns them into a cost per
    candidate: a measured setting costs the median of its recent frames; any other costs its
    shipped figure times the median ratio here/shipped of the measured settings (the shipped
    figures' cost *order* holds across machines, only the scale differs).
    """

    def __init__(self) -> None:
        self._frames: dict[tuple[str, tuple], tuple[str, dict[str, Any], list[float]]] = {}

    def record(self, method: str, parameters: Mapping[str, Any], frame_ms: float,
               prepare_ms: float = 0.0) -> None:
        """One full-quality frame of ``method`` with full ``parameters``: ``frame_ms`` to
        render the whole view, ``prepare_ms`` the precomputation before it (ms; 0 when none
        ran). Non-finite or non-positive times are ignored."""
        total = float(frame_ms) + max(0.0, float(prepare_ms))
        if not (math.isfinite(total) and float(frame_ms) > 0):
            return
        key = _setting_key(method, parameters)
        _, _, times = self._frames.setdefault(key, (method, dict(parameters), []))
        times.append(total)
        del times[:-KEPT_FRAMES]

    def __len__(self) -> int:
        return len(self._frames)

    def measured(self) -> list[tuple[str, dict[str, Any], float]]:
        """(method, parameters, median ms) of every setting measured here."""
        return [(m, dict(p), statistics.median(t)) for m, p, t in self._frames.values()]

    def costs(self, candidates: Sequence[Candidate], shipped: Mapping[Candidate, float],
              defaults: Mapping[str, Mapping[str, Any]], timings: Timings,
              voxels: int) -> tuple[dict[Candidate, float], set[Candidate]]:
        """(cost in ms per candidate on this machine, the candidates measured here).

        ``shipped``: the candidates' costs in ``timings`` (:func:`measured_costs`);
        ``defaults``: each method's declared defaults; ``voxels``: the scene's voxel count
        (scales the shipped recompute times). Empty when nothing was measured here, or no
        measured setting has a shipped figure to scale the others by."""
        measured = self.measured()
        here: dict[Candidate, float] = {}
        for cand in candidates:
            wanted = {**defaults.get(cand.method, {}), **cand.parameters}
            times = [ms for method, params, ms in measured if method == cand.method
                     and all(params.get(k) == v for k, v in wanted.items())]
            if times:
                here[cand] = statistics.median(times)
        ratios = [here[c] / shipped[c] for c in here if shipped.get(c, 0) > 0]
        if not ratios:  # a measured setting outside the candidates: its own shipped figure
            settings = [Candidate(m, p) for m, p, _ in measured]
            theirs = measured_costs(settings, list(timings.records), voxels)
            ratios = [ms / theirs[c] for c, (_, _, ms) in zip(settings, measured, strict=True)
                      if theirs.get(c, 0) > 0]
        if not ratios:
            return {}, set()
        scale = statistics.median(ratios)
        costs = {c: here.get(c, shipped[c] * scale) for c in candidates
                 if c in here or c in shipped}
        return costs, set(here)


def duration_words(ms: float) -> str:
    """``"about 450 ms"``, ``"about 4 s"``, ``"about 1.5 s"``, ``"about 2 min"``."""
    if not math.isfinite(ms):
        return "an unknown time"
    if ms < 950:
        return f"about {max(10, int(ms / 10 + 0.5) * 10)} ms"  # half up: 445 → 450
    seconds = ms / 1000.0
    if seconds < 9.5:
        text = f"{seconds:.1f}".rstrip("0").rstrip(".")
        return f"about {text} s"
    if seconds < 90:
        return f"about {seconds:.0f} s"
    return f"about {seconds / 60:.0f} min"


def setting_words(method: str, parameters: Mapping[str, Any]) -> str:
    """A setting as the app names it: the method's title and the labels of the parameters
    that differ from its defaults, e.g. ``"Cone-traced AO and soft shadows (ambient
    occlusion: Hemisphere (per sample), AO cones: 12)"``. Unknown methods keep their name."""
    from vtkvol.model.techniques import get_spec

    try:
        spec = get_spec(method)
    except (ValueError, KeyError):
        return method
    defaults = spec.defaults()
    parts = []
    for param in spec.parameters:
        if param.name not in parameters or parameters[param.name] == defaults.get(param.name):
            continue
        value = parameters[param.name]
        if param.choices and param.choice_labels and value in param.choices:
            value = param.choice_labels[param.choices.index(value)]
        elif isinstance(value, bool):
            value = "on" if value else "off"
        elif isinstance(value, float):
            value = f"{value:g}{(' ' + param.unit) if param.unit else ''}"
        label = param.label if param.label[:2].isupper() else param.label.lower()
        parts.append(f"{label}: {value}")
    return f"{spec.label} ({', '.join(parts)})" if parts else spec.label
