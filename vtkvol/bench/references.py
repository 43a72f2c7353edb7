"""What each scene is measured against, per lighting model, and computing it (numpy).

One physical truth per scene and lighting model. Every ``surface`` technique approximates the
same light, so all of them (and VTK's built-in scattering) are measured against one
reference, :class:`SurfaceReference`:

* light visibility: the exact transmittance towards each light **averaged over the light's
  extent** (:func:`~vtkvol.reference.extended_transmittance`: directions uniform in solid
  angle within the light's angular radius; hard for an ideal light). Every method is charged
  for what it leaves out: local shading for all shadows, a hard-shadow method for the
  penumbrae, a near-field offset for the absorbers it skips;
* ambient visibility: 1 − AO, cosine-weighted about the outward normal, within the scene's
  fixed AO distance (:func:`~vtkvol.reference.ambient_occlusion_mc`).

The ``medium`` model (multiple scattering) has :class:`MediumReference`: the same light
visibility, plus the light scattered inside the volume, all orders, by Monte-Carlo path tracing
(:func:`~vtkvol.reference.scattering.inscattered_mc`, with the scene's albedo and phase
function), shaded isotropically as the medium model shades every technique's volume. Its
``orders="single"`` variant leaves the in-scattered light out (direct light only): the
convergence study (:mod:`vtkvol.bench.convergence`) measures against both.

A lighting model's reference is an object with a ``lighting`` name, ``spec(scene)`` (what it
computes, as a label for the tables) and ``volumes(cache, scene)`` (what the reference
technique renders); :func:`reference_for` looks it up in :data:`LIGHTING_REFERENCES`;
techniques of a model without a reference are not measured (the runner says so).

Monte-Carlo and light-extent references are evaluated only where they can matter: at voxels
within one voxel (26-neighbourhood) of any non-zero opacity, which are all the corners a
trilinear fetch at a visible sample can touch. Elsewhere the hard transmittance (light) or 0
occlusion is stored.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from vtkvol.bench.reference_technique import ReferenceVolumes
from vtkvol.bench.scenes import Scene
from vtkvol.reference import (
    DirectionalLight,
    ambient_occlusion_mc,
    extended_transmittance,
    inscattered_mc,
    transmittance,
)


@dataclass(frozen=True)
class ReferenceSpec:
    """The surface illumination a scene is measured against.

    Attributes
    ----------
    light_size_deg
        Angular radius (°) of the scene's directional lights: visibility is the transmittance
        averaged over that cone of directions; 0 is an ideal light (hard shadows).
    ao_distance_um
        None: no ambient occlusion (ambient visibility 1); otherwise AO counts absorbers within
        this many µm, cosine-weighted about the outward normal.
    """

    light_size_deg: float = 0.0
    ao_distance_um: float | None = None

    @property
    def label(self) -> str:
        """Short text for tables: ``T``, ``T(2°) + AO(24 µm)``."""
        light = f"T({self.light_size_deg:g}°)" if self.light_size_deg > 0 else "T"
        if self.ao_distance_um is None:
            return light
        return f"{light} + AO({self.ao_distance_um:g} µm)"


@dataclass(frozen=True)
class ReferenceBudget:
    """Accuracy of the references: march step (voxels) and ray counts.

    ``light_rays``: stratified samples of each light's extent per voxel (error ~1/rays for a
    penumbra); ``ao_rays``: Monte-Carlo AO rays (standard error ≤ 0.5/√rays);
    ``scatter_paths``: Monte-Carlo paths per voxel of the in-scattered light, followed for at
    most ``scatter_bounces`` scattering events. Hard transmittance is deterministic (midpoint
    rule, error O(step²)).
    """

    step: float = 0.5
    light_rays: int = 32
    ao_rays: int = 128
    ao_step: float = 1.0
    scatter_paths: int = 32
    scatter_bounces: int = 48


QUICK_BUDGET = ReferenceBudget(step=0.5, light_rays=16, ao_rays=64, ao_step=1.0,
                               scatter_paths=8)
FULL_BUDGET = ReferenceBudget(step=0.5, light_rays=32, ao_rays=128, ao_step=1.0,
                              scatter_paths=32)


class LightingReference(Protocol):
    """The one reference of a lighting model (see the module docstring)."""

    lighting: str

    def spec(self, scene: Scene, budget: ReferenceBudget | None = None) -> Any:
        """What the reference computes for ``scene`` with ``budget`` (default the quick one);
        hashable, its ``label`` goes into the records."""
        ...

    def volumes(self, cache: ReferenceCache, scene: Scene) -> ReferenceVolumes:
        """The volumes the ``bench_reference`` technique renders for ``scene``."""
        ...

    def light_visibility(self, cache: ReferenceCache, scene: Scene,
                         opacity: np.ndarray) -> np.ndarray:
        """Per-voxel truth of light 0 for the per-voxel metrics, float32 ``[z, y, x]``."""
        ...


@dataclass(frozen=True)
class SurfaceReference:
    """The surface model's truth: transmittance averaged over each light's extent plus AO
    within the scene's AO distance."""

    lighting: str = "surface"

    def spec(self, scene: Scene, budget: ReferenceBudget | None = None) -> ReferenceSpec:
        return ReferenceSpec(
            light_size_deg=float(scene.light_size_deg),
            ao_distance_um=float(scene.ao_distance_voxels) * min(scene.spacing),
        )

    def volumes(self, cache: ReferenceCache, scene: Scene) -> ReferenceVolumes:
        return cache.volumes(scene, self.spec(scene))

    def light_visibility(self, cache: ReferenceCache, scene: Scene,
                         opacity: np.ndarray) -> np.ndarray:
        return cache.light_visibility(scene, scene.lights[0], scene.light_size_deg, opacity)


@dataclass(frozen=True)
class MediumSpec:
    """The medium illumination a scene is measured against.

    ``light_size_deg``: as :class:`ReferenceSpec`; ``albedo``/``phase_g``: the scene's material;
    ``orders``: ``"multiple"`` (direct light plus the in-scattered light, all orders) or
    ``"single"`` (direct light only); ``seeds``: independent Monte-Carlo estimates averaged
    (two give the reference's own noise, see :mod:`vtkvol.bench.convergence`); ``paths``: paths
    per voxel and seed.
    """

    light_size_deg: float
    albedo: float
    phase_g: float
    orders: str = "multiple"
    seeds: tuple[int, ...] = (0,)
    paths: int = 0

    @property
    def label(self) -> str:
        """Short text for tables: ``T(2°) + MS(a 0.9, g 0, 8 paths)``, ``T(2°)``."""
        light = f"T({self.light_size_deg:g}°)" if self.light_size_deg > 0 else "T"
        if self.orders == "single":
            return light
        return (f"{light} + MS(a {self.albedo:g}, g {self.phase_g:g}, "
                f"{self.paths * len(self.seeds)} paths)")


@dataclass(frozen=True)
class MediumReference:
    """The medium model's truth: the surface reference's light visibility plus Monte-Carlo
    in-scattered light (``orders="multiple"``), or the direct light alone (``"single"``)."""

    lighting: str = "medium"
    orders: str = "multiple"
    seeds: tuple[int, ...] = (0,)

    def spec(self, scene: Scene, budget: ReferenceBudget | None = None) -> MediumSpec:
        paths = (budget or QUICK_BUDGET).scatter_paths if self.orders == "multiple" else 0
        return MediumSpec(float(scene.light_size_deg), float(scene.albedo),
                          float(scene.phase_g), self.orders, self.seeds, paths)

    def volumes(self, cache: ReferenceCache, scene: Scene) -> ReferenceVolumes:
        return cache.medium_volumes(scene, self.spec(scene, cache.budget))

    def light_visibility(self, cache: ReferenceCache, scene: Scene,
                         opacity: np.ndarray) -> np.ndarray:
        return cache.light_visibility(scene, scene.lights[0], scene.light_size_deg, opacity)


#: The reference of each lighting model (``TechniqueSpec.lighting``).
LIGHTING_REFERENCES: dict[str, LightingReference] = {
    "surface": SurfaceReference(), "medium": MediumReference()}


def reference_for(lighting: str) -> LightingReference:
    """The reference of lighting model ``lighting``; KeyError naming the known models."""
    try:
        return LIGHTING_REFERENCES[lighting]
    except KeyError:
        known = ", ".join(sorted(LIGHTING_REFERENCES))
        raise KeyError(f"the bench has no reference for the {lighting!r} lighting model "
                       f"(it has: {known})") from None


def outward_normals(opacity: np.ndarray, spacing: Sequence[float]) -> np.ndarray:
    """Outward unit normals (x, y, z) per voxel, ``[z, y, x, 3]``: −∇α by central differences in
    µm; zero where the gradient vanishes (the AO reference then samples the full sphere)."""
    gz, gy, gx = np.gradient(np.asarray(opacity, dtype=np.float64))
    g = np.stack([gx / spacing[0], gy / spacing[1], gz / spacing[2]], axis=-1)
    length = np.linalg.norm(g, axis=-1, keepdims=True)
    safe = np.where(length > 1e-12, length, 1.0)
    return np.where(length > 1e-12, -g / safe, 0.0)


def relevant_mask(opacity: np.ndarray, threshold: float = 1e-3) -> np.ndarray:
    """Voxels whose value a trilinear fetch at a visible sample can touch: the 26-neighbourhood
    dilation of ``opacity > threshold``."""
    from scipy.ndimage import binary_dilation

    return binary_dilation(opacity > threshold, structure=np.ones((3, 3, 3), bool))


class ReferenceCache:
    """Reference volumes per (scene data, lights, spec), computed once per benchmark run.

    ``seconds`` accumulates the CPU time spent (reported in the run's metadata).
    """

    def __init__(self, budget: ReferenceBudget = QUICK_BUDGET) -> None:
        self.budget = budget
        self.seconds = 0.0
        self._light: dict[tuple, np.ndarray] = {}
        self._ambient: dict[tuple, np.ndarray] = {}
        self._volumes: dict[tuple, ReferenceVolumes] = {}
        self._scattered: dict[tuple, np.ndarray] = {}

    @staticmethod
    def _scene_key(scene: Scene) -> tuple:
        return (scene.name, id(scene.data), scene.spacing, tuple(scene.opacity_points))

    def light_visibility(self, scene: Scene, light: Sequence[float], size_deg: float,
                         opacity: np.ndarray | None = None) -> np.ndarray:
        """Transmittance towards the directional light ``light`` (world direction towards it)
        averaged over a cone of angular radius ``size_deg`` (hard for 0); float32
        ``[z, y, x]``."""
        key = (self._scene_key(scene), tuple(light), float(size_deg))
        if key in self._light:
            return self._light[key]
        alpha = scene.opacity() if opacity is None else opacity
        t0 = time.perf_counter()
        dl = DirectionalLight(tuple(float(c) for c in light))  # type: ignore[arg-type]
        if size_deg <= 0:
            out = transmittance(alpha, scene.spacing, dl, unit_distance=scene.unit_distance,
                                step=self.budget.step)
        else:
            # Hard transmittance away from material (where nothing samples it), the light's
            # extent only where a visible sample's trilinear fetch can read it.
            out = self.light_visibility(scene, light, 0.0, alpha).copy()
            mask = relevant_mask(alpha)
            pts = np.argwhere(mask)[:, ::-1] * np.asarray(scene.spacing)
            out[mask] = extended_transmittance(
                alpha, scene.spacing, dl, size=size_deg, n_rays=self.budget.light_rays,
                unit_distance=scene.unit_distance, step=self.budget.step, points=pts)
        self.seconds += time.perf_counter() - t0
        self._light[key] = out
        return out

    def ambient_visibility(self, scene: Scene, distance_um: float,
                           opacity: np.ndarray | None = None) -> np.ndarray:
        """1 − AO from absorbers within ``distance_um`` µm (cosine-weighted about the outward
        normal), float32 ``[z, y, x]``; 1 away from any material."""
        key = (self._scene_key(scene), float(distance_um))
        if key in self._ambient:
            return self._ambient[key]
        alpha = scene.opacity() if opacity is None else opacity
        t0 = time.perf_counter()
        mask = relevant_mask(alpha)
        out = np.ones(alpha.shape, np.float32)
        if mask.any():
            pts = np.argwhere(mask)[:, ::-1] * np.asarray(scene.spacing)
            normals = outward_normals(alpha, scene.spacing)[mask]
            ao = ambient_occlusion_mc(
                alpha, scene.spacing, max_distance=distance_um, n_rays=self.budget.ao_rays,
                unit_distance=scene.unit_distance, step=self.budget.ao_step, points=pts,
                normals=normals)
            out[mask] = 1.0 - ao
        self.seconds += time.perf_counter() - t0
        self._ambient[key] = out
        return out

    def volumes(self, scene: Scene, spec: ReferenceSpec) -> ReferenceVolumes:
        """The :class:`ReferenceVolumes` of ``scene`` (all its lights) for ``spec``."""
        key = (self._scene_key(scene), tuple(tuple(v) for v in scene.lights), spec)
        if key not in self._volumes:
            alpha = scene.opacity()
            vis = self._visibilities(scene, spec.light_size_deg, alpha)
            amb = None
            if spec.ao_distance_um is not None:
                amb = np.clip(self.ambient_visibility(scene, spec.ao_distance_um, alpha), 0, 1)
            self._volumes[key] = ReferenceVolumes(vis, amb)
        return self._volumes[key]

    def _visibilities(self, scene: Scene, size_deg: float,
                      alpha: np.ndarray) -> tuple[np.ndarray, ...]:
        """Every light's visibility over ``size_deg``, clipped to [0, 1] for the textures."""
        return tuple(np.clip(self.light_visibility(scene, light, size_deg, alpha), 0, 1)
                     for light in scene.lights)

    def scattered(self, scene: Scene, albedo: float, phase_g: float, seed: int) -> np.ndarray:
        """Monte-Carlo in-scattered light from all the scene's lights (every order ≥ 1), float32
        ``[z, y, x]`` ≥ 0; evaluated where a visible sample can read it, 0 elsewhere."""
        key = (self._scene_key(scene), tuple(tuple(v) for v in scene.lights), float(albedo),
               float(phase_g), int(seed), self.budget.scatter_paths)
        if key in self._scattered:
            return self._scattered[key]
        alpha = scene.opacity()
        t0 = time.perf_counter()
        out = np.zeros(alpha.shape, np.float32)
        mask = relevant_mask(alpha)
        if mask.any():
            pts = np.argwhere(mask)[:, ::-1] * np.asarray(scene.spacing)
            lights = [DirectionalLight(tuple(float(c) for c in d))  # type: ignore[arg-type]
                      for d in scene.lights]
            out[mask] = inscattered_mc(
                alpha, scene.spacing, lights, albedo=albedo, phase_g=phase_g,
                n_paths=self.budget.scatter_paths, seed=seed,
                unit_distance=scene.unit_distance, max_bounces=self.budget.scatter_bounces,
                points=pts)
        self.seconds += time.perf_counter() - t0
        self._scattered[key] = out
        return out

    def medium_volumes(self, scene: Scene, spec: MediumSpec) -> ReferenceVolumes:
        """The :class:`ReferenceVolumes` of ``scene`` for the medium ``spec``: visibility per
        light, and the mean in-scattered light over ``spec.seeds`` (multiple orders only)."""
        key = (self._scene_key(scene), tuple(tuple(v) for v in scene.lights), spec,
               scene.light_intensity)
        if key not in self._volumes:
            alpha = scene.opacity()
            vis = self._visibilities(scene, spec.light_size_deg, alpha)
            irradiance = None
            if spec.orders == "multiple":
                # unit-irradiance lights in the reference; the host scales the direct light by
                # each light's intensity, the in-scattered light is scaled here
                irradiance = (scene.light_intensity * np.mean(
                    [self.scattered(scene, spec.albedo, spec.phase_g, seed)
                     for seed in spec.seeds], axis=0)).astype(np.float32)
            self._volumes[key] = ReferenceVolumes(vis, None, irradiance)
        return self._volumes[key]

    def clear_scene(self, scene: Scene) -> None:
        """Forget everything computed for ``scene`` (keeps memory bounded across scenes)."""
        sk = self._scene_key(scene)
        for table in (self._light, self._ambient, self._volumes, self._scattered):
            for key in [k for k in table if k[0] == sk]:
                del table[key]
