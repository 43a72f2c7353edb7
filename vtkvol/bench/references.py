"""What each scene is measured against, and computing it (numpy).

Every surface technique of a scene is measured against one physical truth,
:func:`scene_reference`: the light the scene has (its size) and ambient occlusion within a
fixed distance. :class:`ReferenceSpec` names an illumination in physical terms and
:class:`ReferenceCache` computes it with the independent CPU references of
:mod:`vtkvol.reference`. (:func:`reference_spec` still maps a setting to the illumination it
*means* to compute, which :func:`~vtkvol.bench.auto_quality.choose` uses to predict errors.)

* light visibility: the transmittance towards each light (``transmittance``), or, when the
  setting models an area light seen under a cone half-angle, the mean transmittance over that
  cone (``cone_transmittance_mc``). Every reference casts shadows, so methods that do not
  (local shading) are charged for the missing shadows;
* ambient visibility: 1 − AO, cosine-weighted about the outward normal within the setting's
  AO distance (``ambient_occlusion_mc``), only for settings that compute ambient occlusion;
  otherwise 1 (unoccluded), as in the host's shading formula;
* near-field offset: techniques skip absorbers within a small distance of the sample, so a
  surface does not shadow itself (the shadow volume reads its volume ``offset`` cells towards
  the light, the cone tracer starts its cones at ``h0``). Their reference skips the same
  distance (``min_distance`` of the references): the image comparison then measures how well
  the technique computes the light it means to compute. Settings with offset 0 are compared
  with the full physical transmittance, which is what shows the offset's own cost.

How a technique's parameters map to a spec: a bench helper module
``vtkvol.bench.<technique>_timing`` may define ``reference_spec(values) -> ReferenceSpec | dict``;
otherwise the built-in rules of :func:`reference_spec` apply.

Monte-Carlo references are evaluated only where they can matter: at voxels within one voxel
(26-neighbourhood) of any non-zero opacity, which are all the corners a trilinear fetch at a
visible sample can touch. Elsewhere the hard transmittance (light) or 0 occlusion is stored.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from vtkvol.bench.reference_technique import ReferenceVolumes
from vtkvol.bench.scenes import Scene
from vtkvol.reference import (
    DirectionalLight,
    ambient_occlusion_mc,
    cone_transmittance_mc,
    transmittance,
)


@dataclass(frozen=True)
class ReferenceSpec:
    """The illumination a setting is compared against.

    Attributes
    ----------
    cone_angle_deg
        0: hard shadows (point/directional light); > 0: the light is a disc seen under this
        half-angle (degrees) and visibility is the cone-averaged transmittance.
    ao_distance_um
        None: no ambient occlusion (ambient visibility 1); otherwise AO counts absorbers within
        this many µm, cosine-weighted about the outward normal.
    light_offset
        The technique's self-shadowing offset towards the light, in cells of
        ``offset_cell_um`` (µm per cell, (x, y, z)): absorbers closer than that along the light
        ray are skipped by the technique, and so by its reference (``min_distance``).
        0 compares with the full physical transmittance.
    ao_offset_um
        The same for the AO rays (µm).
    volume_has_offset
        True when the technique's CPU light volume (``light_visibility_cpu``) already skips
        the offset (it marches from there); False when the offset is a shift of the texture
        lookup in the shader and the stored volume is the transmittance at the voxel itself.
    """

    cone_angle_deg: float = 0.0
    ao_distance_um: float | None = None
    light_offset: float = 0.0
    offset_cell_um: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ao_offset_um: float = 0.0
    volume_has_offset: bool = False

    def light_min_distance(self, direction: Sequence[float]) -> float:
        """µm skipped along the unit ``direction`` towards the light: ``light_offset`` cells,
        measured in the cell grid's own (possibly anisotropic) units, as the shaders do."""
        if self.light_offset <= 0:
            return 0.0
        u = np.asarray(direction, dtype=np.float64)
        u = u / np.linalg.norm(u)
        cells_per_um = float(np.linalg.norm(u / np.asarray(self.offset_cell_um)))
        return self.light_offset / max(cells_per_um, 1e-30)

    @property
    def label(self) -> str:
        """Short text for tables: ``T``, ``T(cone 5°, offset 3 µm) + AO(24 µm, offset 3 µm)``."""
        parts = []
        if self.cone_angle_deg > 0:
            parts.append(f"cone {self.cone_angle_deg:g}°")
        if self.light_offset > 0:
            cells = set(self.offset_cell_um)
            if len(cells) == 1:
                parts.append(f"offset {self.light_offset * cells.pop():.3g} µm")
            else:
                parts.append(f"offset {self.light_offset:g} cells")
        light = f"T({', '.join(parts)})" if parts else "T"
        if self.ao_distance_um is None:
            return light
        ao = f"{self.ao_distance_um:g} µm"
        if self.ao_offset_um > 0:
            ao += f", offset {self.ao_offset_um:.3g} µm"
        return f"{light} + AO({ao})"


@dataclass(frozen=True)
class ReferenceBudget:
    """Accuracy of the references: march step (voxels) and Monte-Carlo ray counts.

    The per-voxel standard error of an MC estimate is at most 0.5/√rays; hard transmittance is
    deterministic (midpoint rule, error O(step²)).
    """

    step: float = 0.5
    cone_rays: int = 32
    ao_rays: int = 128
    ao_step: float = 1.0


QUICK_BUDGET = ReferenceBudget(step=0.5, cone_rays=16, ao_rays=64, ao_step=1.0)
FULL_BUDGET = ReferenceBudget(step=0.5, cone_rays=32, ao_rays=128, ao_step=1.0)


def bench_helper(method: str) -> Any | None:
    """The technique's bench helper module ``vtkvol.bench.<method>_timing``, if it exists."""
    try:
        return importlib.import_module(f"vtkvol.bench.{method}_timing")
    except ModuleNotFoundError as exc:
        if exc.name != f"vtkvol.bench.{method}_timing":
            raise  # the helper exists but is broken: say so instead of hiding it
        return None


def reference_spec(
    method: str, values: Mapping[str, Any], spacing: Sequence[float],
    shape_zyx: Sequence[int] | None = None,
) -> ReferenceSpec:
    """The :class:`ReferenceSpec` a setting (technique ``method`` with parameter ``values``) is
    measured against, for data of ``shape_zyx`` voxels of ``spacing`` (x, y, z) µm.

    A bench helper's ``reference_spec(values)`` wins. Built-in rules: the shadow volume's
    ``offset`` (light-grid cells, a lookup shift); the cone tracer's ``shadow_angle`` (when
    ``shadows``), ``h0`` (voxels, where its cones start), and AO within ``max_distance``
    voxels of the smallest edge when ``ao_mode`` is not off. Anything else: hard shadows
    (``T``), no AO, no offset.
    """
    helper = bench_helper(method)
    if helper is not None and hasattr(helper, "reference_spec"):
        spec = helper.reference_spec(dict(values))
        return spec if isinstance(spec, ReferenceSpec) else ReferenceSpec(**dict(spec))
    sp = (float(spacing[0]), float(spacing[1]), float(spacing[2]))
    if method == "shadow_volume" and "offset" in values:
        cell = sp
        if shape_zyx is not None and "resolution" in values:
            try:  # the light grid's cell size, from the technique itself
                from vtkvol.plugins.shadow_volume.technique import LightGrid

                grid = LightGrid.for_data(tuple(shape_zyx)[::-1], sp, values["resolution"])
                cx, cy, cz = (float(c) for c in grid.cell_um)
                cell = (cx, cy, cz)
            except (ImportError, AttributeError, KeyError, ValueError):
                cell = sp
        return ReferenceSpec(light_offset=float(values["offset"]), offset_cell_um=cell)
    cone = 0.0
    if values.get("shadows", True) and "shadow_angle" in values:
        cone = float(values["shadow_angle"])
    h0 = float(values.get("h0", 0.0)) if "shadow_angle" in values else 0.0
    ao = None
    if values.get("ao_mode", "off") != "off" and "max_distance" in values:
        ao = float(values["max_distance"]) * min(sp)
    return ReferenceSpec(cone_angle_deg=cone, ao_distance_um=ao, light_offset=h0,
                         offset_cell_um=sp, ao_offset_um=h0 * min(sp) if ao else 0.0,
                         volume_has_offset=h0 > 0)


def scene_reference(scene: Scene) -> ReferenceSpec:
    """The one physical truth of ``scene`` that every surface technique is measured against:
    the exact transmittance averaged over the light's extent (a cone of the lights' angular
    radius; hard for an ideal light) plus Monte-Carlo ambient occlusion within the scene's AO
    distance, with no self-shadowing offset."""
    return ReferenceSpec(
        cone_angle_deg=float(scene.light_size_deg),
        ao_distance_um=float(scene.ao_distance_voxels) * min(scene.spacing),
    )


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

    @staticmethod
    def _scene_key(scene: Scene) -> tuple:
        return (scene.name, id(scene.data), scene.spacing, tuple(scene.opacity_points))

    def light_visibility(self, scene: Scene, light: Sequence[float], cone_deg: float,
                         min_distance_um: float = 0.0,
                         opacity: np.ndarray | None = None) -> np.ndarray:
        """Transmittance towards the directional light ``light`` (world direction towards it),
        hard (``cone_deg`` 0) or cone-averaged, skipping the first ``min_distance_um`` µm;
        float32 ``[z, y, x]``."""
        import time

        key = (self._scene_key(scene), tuple(light), float(cone_deg), float(min_distance_um))
        if key in self._light:
            return self._light[key]
        alpha = scene.opacity() if opacity is None else opacity
        t0 = time.perf_counter()
        dl = DirectionalLight(tuple(float(c) for c in light))  # type: ignore[arg-type]
        if cone_deg <= 0:
            out = transmittance(alpha, scene.spacing, dl, unit_distance=scene.unit_distance,
                                step=self.budget.step, min_distance=min_distance_um)
        else:
            out = self.light_visibility(scene, light, 0.0, min_distance_um, alpha).copy()
            mask = relevant_mask(alpha)
            pts = np.argwhere(mask)[:, ::-1] * np.asarray(scene.spacing)
            out[mask] = cone_transmittance_mc(
                alpha, scene.spacing, dl, half_angle_deg=cone_deg, n_rays=self.budget.cone_rays,
                unit_distance=scene.unit_distance, step=self.budget.step, points=pts,
                min_distance=min_distance_um)
        self.seconds += time.perf_counter() - t0
        self._light[key] = out
        return out

    def ambient_visibility(self, scene: Scene, distance_um: float, min_distance_um: float = 0.0,
                           opacity: np.ndarray | None = None) -> np.ndarray:
        """1 − AO from absorbers between ``min_distance_um`` and ``distance_um`` µm
        (cosine-weighted about the outward normal), float32 ``[z, y, x]``; 1 away from any
        material."""
        import time

        key = (self._scene_key(scene), float(distance_um), float(min_distance_um))
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
                normals=normals, min_distance=min(min_distance_um, distance_um))
            out[mask] = 1.0 - ao
        self.seconds += time.perf_counter() - t0
        self._ambient[key] = out
        return out

    def volumes(self, scene: Scene, spec: ReferenceSpec) -> ReferenceVolumes:
        """The :class:`ReferenceVolumes` of ``scene`` (all its lights) for ``spec``."""
        key = (self._scene_key(scene), tuple(tuple(v) for v in scene.lights), spec)
        if key not in self._volumes:
            alpha = scene.opacity()
            vis = tuple(
                np.clip(self.light_visibility(scene, light, spec.cone_angle_deg,
                                              spec.light_min_distance(light), alpha), 0, 1)
                for light in scene.lights
            )
            amb = None
            if spec.ao_distance_um is not None:
                amb = np.clip(self.ambient_visibility(scene, spec.ao_distance_um,
                                                      spec.ao_offset_um, alpha), 0, 1)
            self._volumes[key] = ReferenceVolumes(vis, amb)
        return self._volumes[key]

    def clear_scene(self, scene: Scene) -> None:
        """Forget everything computed for ``scene`` (keeps memory bounded across scenes)."""
        sk = self._scene_key(scene)
        for table in (self._light, self._ambient, self._volumes):
            for key in [k for k in table if k[0] == sk]:
                del table[key]
