"""Precomputed shadow volumes: the engine hooks (docs/shadow-volume.md).

One light volume per light (visibility 0…1 at the light grid's cell centres, one light per
texture channel), recomputed only when the opacity, the light geometry or an ILLUMINATION
parameter changes, never on camera moves. The propagation runs in a compute shader
(:mod:`.gpu`) or in numpy (:mod:`.cpu`), which agree to about 1e-6.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtkvol.engine.gl import GLUnavailableError, Texture3D
from vtkvol.engine.light_grid import (
    LightGrid,
    light_softness,
    light_volume_cpu,
    prefilter_cpu,
    propagate_cpu,
)
from vtkvol.engine.light_grid_gpu import (
    GpuPropagator,
    LightTexture,
    ensure_work_textures,
)
from vtkvol.engine.light_grid_technique import LightGridTechnique
from vtkvol.engine.technique import TechniqueStats, scale_steps
from vtkvol.model.params import Invalidates
from vtkvol.plugins.shadow_volume import TECHNIQUE

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec


TEXTURE_UNIFORM = "vv_shadow_volume_tex"
#: Seconds of GPU work per chunk when the host precomputes in chunks (Illuminator.precompute):
#: the longest the application's event loop waits between two chunks.
CHUNK_S = 0.08

_ILLUM = Invalidates.ILLUMINATION


class ShadowVolume(LightGridTechnique):
    """Shadows from a precomputed light volume per light (packed one light per channel)."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "shadow_volume.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self.light_texture: LightTexture | None = None
        self._sigma_tex: Texture3D | None = None
        self._sigma_cpu: np.ndarray | None = None

    # -- hooks --------------------------------------------------------------------------------
    def prepare_steps(self, changes: Changes, values: Mapping[str, Any]) -> Iterator[float]:
        """Recompute the light volume when needed, in chunks: the opacity (numpy), the
        extinction grid, then slabs of slices per light (GPU) or one light per chunk (numpy).
        The new light is bound when every light is done; a cancelled recomputation leaves
        the light texture half-written, and the host releases the technique."""
        specs = self.host.light_specs()
        # Colour changes need no recompute; a size changes the penumbra.
        light_key = tuple((s.kind, s.vector, s.size) for s in specs)
        grid = LightGrid.for_data(self.host.dims, self.host.spacing, values["resolution"])
        if changes.first or changes.opacity or grid != self.grid:
            self._sigma_valid = {"gpu": False, "cpu": False}
        gpu = self._gpu_path(values)  # compiles its first program on first use
        needed = (
            changes.first
            or not self._sigma_valid["gpu" if gpu is not None else "cpu"]  # opacity, grid
            or light_key != self._light_key
            or changes.any_parameter(self.PARAMETERS, _ILLUM)
            or self.light_texture is None
        )
        if not needed:
            return
        # The light key is set only at the end: a cancelled recomputation must not look done.
        self._light_key = None
        with self.timed("recompute"):
            yield from self._recompute_steps(grid, specs, gpu, values)
        self._light_key = light_key
        self._recomputes += 1

    def _recompute_steps(self, grid: LightGrid, specs: Sequence[LightSpec],
                         gpu: GpuPropagator | None, values: Mapping[str, Any]) -> Iterator[float]:
        self.grid = grid
        channels = 1 if len(specs) <= 1 else (2 if len(specs) == 2 else 4)
        if self._ensure_light_texture(grid, channels):
            yield 0.0  # a new texture (large: allocated and filled with 1)
        chunk_s = CHUNK_S if self.host.precomputing else None
        if gpu is not None:
            try:
                yield from self._recompute_gpu(gpu, grid, specs, values, chunk_s)
                self._backend = "gpu"
            except GLUnavailableError as exc:
                self._compute.disable(exc)
                gpu = None
        if gpu is None:
            yield from self._recompute_cpu(grid, specs, values)
            self._backend = "cpu"
        assert self.light_texture is not None
        self.host.bind_texture(TEXTURE_UNIFORM, self.light_texture)

    def stats(self) -> TechniqueStats:
        """The light volume's recomputations (``texture_bytes``: light, extinction and work
        textures)."""
        textures = [self.light_texture, self._sigma_tex, *self._work_tex.values()]
        return TechniqueStats(
            recomputes=self._recomputes, recompute_ms=self.elapsed_ms("recompute"),
            backend=self._backend,
            texture_bytes=sum(t.nbytes for t in textures if t is not None))

    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        """``VV_SV_POINT_LIGHTS``: whether any light is a point light (their offset direction
        is taken per sample; without them the shader has no such code)."""
        points = any(spec.is_point for spec in self.host.light_specs())
        return {"VV_SV_POINT_LIGHTS": "1" if points else "0"}

    def release(self) -> None:
        super().release()
        for tex in (self.light_texture, self._sigma_tex):
            if tex is not None:
                tex.release()
        self.light_texture = self._sigma_tex = None
        self._sigma_cpu = None

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """Visibility of ``light`` at every data voxel centre, ``[z, y, x]`` float32 (the CPU
        path; a reduced-resolution grid is interpolated trilinearly back to the voxels)."""
        merged = {**self.defaults(), **values}
        grid = LightGrid.for_data(opacity.shape[::-1], spacing, merged["resolution"])
        vis = light_volume_cpu(
            opacity, spacing, light, unit_distance=self.host.unit_distance,
            model=merged["model"], resolution=merged["resolution"],
            softness=light_softness(light, grid, merged, self._origin(), self._direction()),
            origin=self._origin(),
            direction=self._direction(),
        )
        return grid.to_data(vis)

    # -- internals ----------------------------------------------------------------------------
    def _gpu_path(self, values: Mapping[str, Any]) -> GpuPropagator | None:
        """The GPU propagator (compiled on first use), or None for the numpy path."""
        return self._compute.get(self.host, values["backend"])

    def _ensure_light_texture(self, grid: LightGrid, channels: int) -> bool:
        """Whether a new light texture was made."""
        shape = grid.shape_zyx
        tex = self.light_texture
        if tex is None or tex.shape != shape or tex.channels != channels:
            if tex is not None:
                tex.release()
            self.light_texture = LightTexture(self.host.render_window, shape, channels)
            return True
        return False

    def _recompute_gpu(
        self, gpu: GpuPropagator, grid: LightGrid, specs: Sequence[LightSpec],
        values: Mapping[str, Any], chunk_s: float | None,
    ) -> Iterator[float]:
        rw = self.host.render_window
        lights = [grid.light(spec, self._origin(), self._direction()) for spec in specs]
        # Progress: the opacity and extinction grid count as much as one light's slices.
        per_light = [GpuPropagator.slice_count(grid, kind, vec) for kind, vec in lights]
        prefilter = max(per_light, default=1) if not self._sigma_valid["gpu"] else 0
        total = max(1, prefilter + sum(per_light))
        if not self._sigma_valid["gpu"]:
            if self._sigma_tex is None or self._sigma_tex.shape != grid.shape_zyx:
                if self._sigma_tex is not None:
                    self._sigma_tex.release()
                self._sigma_tex = Texture3D(rw, grid.shape_zyx)
                yield 0.0
            # The host's optical depth (classified and converted on the GPU: no numpy pass,
            # no upload, no conversion pass of ours; or numpy uploaded once).
            depth = yield from scale_steps(self.host.opacity_texture_steps("optical_depth"),
                                           0.0, 0.5 * prefilter / total)
            yield from scale_steps(
                gpu.prefilter_texture_steps(depth, self._sigma_tex, grid,
                                            chunked=chunk_s is not None),
                0.5 * prefilter / total, prefilter / total)
            self._sigma_valid["gpu"] = True
        ensure_work_textures(rw, self._work_tex, grid)
        assert self._sigma_tex is not None and self.light_texture is not None
        done = prefilter
        for channel, (spec, (kind, vec)) in enumerate(zip(specs, lights, strict=True)):
            for slices in gpu.propagate_steps(
                self._sigma_tex, self._work_tex, self.light_texture, grid, kind, vec,
                model=values["model"],
                softness=light_softness(spec, grid, values, self._origin(), self._direction()),
                unit_distance=self.host.unit_distance, channel=channel, chunk_s=chunk_s,
            ):
                yield (done + slices) / total
            done += per_light[channel]

    def _recompute_cpu(
        self, grid: LightGrid, specs: Sequence[LightSpec], values: Mapping[str, Any]
    ) -> Iterator[float]:
        total = len(specs) + 1
        if not self._sigma_valid["cpu"] or self._sigma_cpu is None:
            opacity = yield from scale_steps(self.host.opacity_volume_steps(), 0.0,
                                             0.5 / total)
            self._sigma_cpu = prefilter_cpu(opacity, grid)
            self._sigma_valid["cpu"] = True
        yield 1 / total
        assert self.light_texture is not None
        packed = np.ones((*grid.shape_zyx, self.light_texture.channels), np.float32)
        for channel, spec in enumerate(specs):
            kind, vec = grid.light(spec, self._origin(), self._direction())
            packed[..., channel] = propagate_cpu(
                self._sigma_cpu, grid, kind, vec, model=values["model"],
                softness=light_softness(spec, grid, values, self._origin(), self._direction()),
                unit_distance=self.host.unit_distance,
            )
            yield (channel + 2) / total
        self.light_texture.upload(packed[..., 0] if packed.shape[-1] == 1 else packed)
