"""Path-traced illumination, engine part: Monte-Carlo light on the data grid, refined over
frames within a time budget per frame, shaded through the host's medium model.

On a restart (opacity, lights, material or a restarting parameter changed; never the camera):
the direct light towards each light, exact (:func:`vtkvol.reference.transmittance`, averaged
over the light's extent where the light has one and a visible sample can read it), goes into
one texture (a channel per light, up to four); then, for ``scattering = multiple``, every frame
traces ``paths_per_iteration`` more paths from a share of the voxels a visible sample can read
(:func:`vtkvol.reference.inscattered_mc`: delta tracking, ratio-tracked next-event estimation
weighted by each light's colour, the medium's albedo and Henyey–Greenstein g), until
``frame_budget_ms`` is spent; an iteration ends when every such voxel got its paths. The running
mean is the in-scattered light (RGB) the shader adds. Coordinates: the reference functions take
positions with the first voxel centre at 0, so dataset-space light positions are shifted by the
image's origin.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtkvol.engine.gl import Texture3D
from vtkvol.engine.technique import Technique, TechniqueStats
from vtkvol.plugins.path_traced import TECHNIQUE
from vtkvol.reference import (
    DirectionalLight,
    PointLight,
    extended_transmittance,
    inscattered_mc,
    transmittance,
)

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

DIRECT_UNIFORM = "vv_path_traced_direct"
SCATTERED_UNIFORM = "vv_path_traced_scattered"
MAX_LIGHTS = 4
#: Stratified samples of a light's extent per voxel for the direct light (error ~1/rays).
EXTENT_RAYS = 16
#: Voxels traced together (one call of the path tracer); the frame budget is checked between.
CHUNK = 2048
#: Largest grid it takes (160³): the exact direct light alone takes about a minute on two
#: cores there, and the paths hours; larger data should be viewed with a faster method.
MAX_VOXELS = 160**3
#: Offset of the path seeds (batch k of seed s uses SEED_BASE + s·1000003 + k): the benchmark's
#: reference uses seeds 0 and 1, and a technique measured against it must not share its paths.
SEED_BASE = 1 << 20


class PathTraced(Technique):
    """Monte-Carlo direct and in-scattered light, progressive, CPU."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "path_traced.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._direct: Texture3D | None = None
        self._scattered: Texture3D | None = None
        self._restarts = 0
        self._last_ms = 0.0
        self._opacity: np.ndarray | None = None
        self._points: np.ndarray = np.zeros((0, 3))  # traced voxels: positions (x, y, z) µm
        self._index: tuple[np.ndarray, ...] = ()  # … and their [z, y, x] indices
        self._sum = np.zeros((0, 3))
        self._count = np.zeros(0)
        self._cursor = 0
        self._lights: list[Any] = []
        self._colors = np.zeros((0, 3))
        self._dirty = False

    # -- hooks --------------------------------------------------------------------------------
    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        if changes.reset_accumulation or self._opacity is None:
            self._restart(values)
        if values["scattering"] == "multiple" and not self.converged:
            self._trace(values)
        if self._dirty:
            self._upload_scattered()
        assert self._direct is not None and self._scattered is not None
        self.host.bind_texture(DIRECT_UNIFORM, self._direct)
        self.host.bind_texture(SCATTERED_UNIFORM, self._scattered)

    def stats(self) -> TechniqueStats:
        """Restarts as ``recomputes``, the last frame's ms, ``backend`` "cpu" (the estimator
        is numpy's); ``extra``: ``paths_per_voxel`` (the fewest paths any voxel has)."""
        textures = [t for t in (self._direct, self._scattered) if t is not None]
        return TechniqueStats(
            recomputes=self._restarts, recompute_ms=self._last_ms, backend="cpu",
            texture_bytes=sum(t.nbytes for t in textures), iterations=self.iteration,
            extra={"paths_per_voxel": float(self._count.min()) if self._count.size else 0.0})

    def release(self) -> None:
        for tex in (self._direct, self._scattered):
            if tex is not None:
                tex.release()
        self._direct = self._scattered = None
        self._opacity = None

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """The exact transmittance towards ``light`` (what this technique shades with)."""
        ref = self._reference_light(light)
        return transmittance(opacity, spacing, ref, unit_distance=self.host.unit_distance,
                             step=0.5).astype(np.float32)

    # -- internals ----------------------------------------------------------------------------
    def _reference_light(self, light: LightSpec) -> DirectionalLight | PointLight:
        if light.is_point:
            origin = np.asarray(self.host.image.GetOrigin(), dtype=np.float64)
            pos = np.asarray(light.vector, dtype=np.float64) - origin
            return PointLight(tuple(float(v) for v in pos),  # type: ignore[arg-type]
                              falloff_distance=light.falloff_distance)
        return DirectionalLight(tuple(float(v) for v in light.vector))  # type: ignore[arg-type]

    def _restart(self, values: Mapping[str, Any]) -> None:
        t0 = time.perf_counter()
        nx, ny, nz = self.host.dims
        if nx * ny * nz > MAX_VOXELS:
            raise RuntimeError(
                f"path tracing takes volumes of at most {MAX_VOXELS:,} voxels (about 160³); this "
                f"one has {nx * ny * nz:,} ({nx}×{ny}×{nz}): use multiple scattering "
                "(hybrid diffusion) or open the data downsampled")
        opacity = np.asarray(self.host.opacity_volume(), dtype=np.float32)
        spacing = self.host.spacing
        unit = self.host.unit_distance
        specs = self.host.light_specs()[:MAX_LIGHTS]
        self._lights = [self._reference_light(s) for s in specs]
        self._colors = np.array([s.color for s in specs], dtype=np.float64).reshape(-1, 3)
        from scipy.ndimage import binary_dilation

        # the voxels a trilinear fetch at a visible sample can read
        relevant = binary_dilation(opacity > 1e-3, structure=np.ones((3, 3, 3), bool))
        zyx = np.argwhere(relevant)
        self._index = tuple(zyx.T)
        self._points = zyx[:, ::-1] * np.asarray(spacing, dtype=np.float64)
        channels = 1 if len(specs) <= 1 else (2 if len(specs) == 2 else 4)
        direct = np.ones((*opacity.shape, channels), np.float32)
        for i, (spec, light) in enumerate(zip(specs, self._lights, strict=True)):
            direct[..., i] = transmittance(opacity, spacing, light, unit_distance=unit, step=0.5)
            if spec.size > 0 and self._points.size:
                size = math.degrees(spec.size) if not spec.is_point else spec.size
                direct[..., i][self._index] = extended_transmittance(
                    opacity, spacing, light, size=size, n_rays=EXTENT_RAYS, unit_distance=unit,
                    step=0.5, points=self._points)
        self._opacity = opacity
        self._sum = np.zeros((len(self._points), 3))
        self._count = np.zeros(len(self._points))
        self._cursor = 0
        self.iteration = 0
        self.converged = values["scattering"] != "multiple" or not self._lights
        self._restarts += 1
        self._upload_direct(direct[..., 0] if channels == 1 else direct, channels)
        self._dirty = True
        self._last_ms = (time.perf_counter() - t0) * 1e3

    def _trace(self, values: Mapping[str, Any]) -> None:
        """Trace paths from the next voxels until the frame's budget is spent."""
        assert self._opacity is not None
        budget = float(values["frame_budget_ms"]) / 1e3
        paths = int(values["paths_per_iteration"])
        t0 = time.perf_counter()
        n = len(self._points)
        while n and not self.converged and time.perf_counter() - t0 < budget:
            stop = min(self._cursor + CHUNK, n)
            chunk = slice(self._cursor, stop)
            light = inscattered_mc(
                self._opacity, self.host.spacing, self._lights, albedo=self.host.albedo,
                phase_g=self.host.phase_g, n_paths=paths,
                seed=SEED_BASE + int(values["seed"]) * 1_000_003 + self.iteration,
                unit_distance=self.host.unit_distance, max_bounces=int(values["max_bounces"]),
                points=self._points[chunk], light_colors=self._colors)
            self._sum[chunk] += light * paths
            self._count[chunk] += paths
            self._cursor = stop
            self._dirty = True
            if stop == n:
                self._cursor = 0
                self.iteration += 1
                self.converged = self.iteration >= int(values["max_iterations"])
        if not n:
            self.converged = True

    def _upload_direct(self, direct: np.ndarray, channels: int) -> None:
        shape = direct.shape[:3]
        if self._direct is not None:
            self._direct.release()
        self._direct = Texture3D(self.host.render_window, shape, channels=channels, data=direct)

    def _upload_scattered(self) -> None:
        assert self._opacity is not None
        shape = self._opacity.shape
        rgba = np.zeros((*shape, 4), np.float32)
        seen = self._count > 0
        if seen.any():
            where = tuple(i[seen] for i in self._index)
            rgba[(*where, slice(0, 3))] = self._sum[seen] / self._count[seen, None]
        if self._scattered is None or self._scattered.shape != shape:
            if self._scattered is not None:
                self._scattered.release()
            self._scattered = Texture3D(self.host.render_window, shape, channels=4, data=rgba)
        else:
            self._scattered.upload(rgba)
        self._dirty = False
