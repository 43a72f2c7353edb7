"""Cone-traced ambient occlusion and soft shadows: the engine hooks (docs/cone-tracing.md).

The filtered-opacity pyramid (and, in ``baked_hemisphere`` mode, the baked AO) is rebuilt only
when the opacity or a parameter it reads changes, never for light or camera moves; compute
shaders (:mod:`.gpu`) or numpy (:mod:`.cpu`) build it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from vtk import vtkTextureObject

from vtkvol.engine.gl import Texture3D
from vtkvol.engine.technique import (
    ComputePath,
    Technique,
    TechniqueStats,
    finish_gl,
    scale_steps,
)
from vtkvol.plugins.cone_traced import AO_MODES, TECHNIQUE
from vtkvol.plugins.cone_traced.cpu import (
    _FAR,
    MAX_STEPS,
    TAU_EXIT,
    ambient_occlusion_cpu,
    ao_grid_dims,
    baked_ao_cpu,
    cone_trace_cpu,
    filtered_pyramid_cpu,
    gaussian_weights,
    hemisphere_pattern,
    level_shapes,
    mip_level_count,
    sample_grid,
    source_pyramid,
    voxel_normals,
    voxel_points,
)
from vtkvol.plugins.cone_traced.gpu import GpuAoBaker, GpuFilter

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

#: Parameters that change the baked AO (besides the filter's σ and span): re-bake, but only in
#: baked_hemisphere mode; for the per-sample modes they are per-frame uniforms.
BAKE_PARAMETERS = frozenset(
    {"ao_mode", "ao_cones", "ao_resolution", "max_distance", "lod_width", "h", "h0"}
)
#: Parameters of the filtered pyramid itself (``backend``: the pyramid is built anew on the
#: chosen path, and the baked AO with it).
FILTER_PARAMETERS = frozenset({"sigma", "span", "backend"})
#: Seconds of GPU work per bake slab when the host precomputes in chunks
#: (Illuminator.precompute): the longest the application's event loop waits between two.
CHUNK_S = 0.08
#: Voxels per part of a chunked upload of the opacity.
UPLOAD_SLAB_VOXELS = 1 << 22

class ConeTraced(Technique):
    """Cone-traced soft shadows and ambient occlusion through a filtered-opacity mip chain."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "cone_traced.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._recomputes = 0
        self._backend = ""  # "gpu" or "cpu": the path of the last pyramid rebuild
        self.source: Texture3D | None = None  #: opacity pyramid S_L (level 0 = α)
        self.filtered: Texture3D | None = None  #: D_L = −ln(1 − G_σ * S_L)
        self._scratch: Texture3D | None = None
        #: The GPU-or-numpy choice of the pyramid filter and of the AO bake (the ``backend``
        #: parameter; numpy for good after a failure of either).
        self._compute = ComputePath("cone_traced", GpuFilter)
        self._bake_compute = ComputePath("cone_traced AO bake", GpuAoBaker)
        #: Baked AO (ao_mode = baked_hemisphere): occlusion on the AO grid, and its bookkeeping.
        self.ao: Texture3D | None = None
        self._bakes = 0
        self._bake_backend = ""
        self._cpu_pyramids: tuple[list[np.ndarray], list[np.ndarray]] | None = None
        #: Textures made by a chunked rebuild that has not finished (released on cancel).
        self._pending_textures: list[Texture3D] = []

    # -- shader ---------------------------------------------------------------------------------
    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        mode = AO_MODES.index(values["ao_mode"])
        cones = int(values["ao_cones"])
        pattern, half_angle = hemisphere_pattern(cones)
        dirs = ", ".join(f"vec3({x:.8f}, {y:.8f}, {z:.8f})" for x, y, z in pattern)
        return {
            "VV_CT_SHADOWS": "1" if values["shadows"] else "0",
            "VV_CT_CONE_FROM_LIGHT": "1" if values["shadow_cone"] == "light size" else "0",
            "VV_CT_AO": str(mode),
            "VV_CT_AO_CONES": str(cones),
            "VV_CT_AO_DIRS": f"vec3[{cones}]({dirs})",
            "VV_CT_AO_SIN": f"{math.sin(math.radians(half_angle)):.8f}",
            "VV_CONE_MAX_STEPS": str(MAX_STEPS),
            "VV_CONE_TAU_EXIT": f"{TAU_EXIT:.8f}",
        }

    def stats(self) -> TechniqueStats:
        """The pyramid's rebuilds as ``recomputes``/``recompute_ms``/``backend``; ``extra``:
        the AO bake's ``bakes`` (count), ``bake_ms`` (as ``recompute_ms``) and ``bake_backend``
        ("gpu" or "cpu")."""
        textures = (self.source, self.filtered, self._scratch, self.ao)
        return TechniqueStats(
            recomputes=self._recomputes, recompute_ms=self.elapsed_ms("recompute"),
            backend=self._backend,
            texture_bytes=sum(t.nbytes for t in textures if t is not None),
            extra={"bakes": self._bakes, "bake_ms": self.elapsed_ms("bake"),
                   "bake_backend": self._bake_backend})

    def uniforms(self, values: Mapping[str, Any]) -> dict[str, Any]:
        nz, ny, nx = self.source.shape if self.source is not None else (1, 1, 1)
        levels = self.filtered.mip_levels if self.filtered is not None else 1
        spacing = self.host.spacing
        az, ay, ax = self.ao.shape if self.ao is not None else (1, 1, 1)
        return {
            "vv_cone_traced_aoDims": (float(ax), float(ay), float(az)),
            "vv_cone_traced_dims": (float(nx), float(ny), float(nz)),
            "vv_cone_traced_maxLod": float(levels - 1),
            "vv_cone_traced_unit": float(self.host.unit_distance),
            "vv_cone_traced_shadowSin": math.sin(math.radians(values["shadow_angle"])),
            "vv_cone_traced_aoSin": math.sin(math.radians(values["ao_angle"])),
            "vv_cone_traced_maxDistanceUm": float(values["max_distance"]) * min(spacing),
        }

    # -- precomputation -------------------------------------------------------------------------
    def prepare_steps(self, changes: Changes, values: Mapping[str, Any]) -> Iterator[float]:
        """Rebuild the pyramid (opacity, reduction, one chunk per blur pass of the larger
        levels) and bake the AO (slabs of grid slices) when needed, yielding the fraction
        done. Chunks wait for the GPU only when the host runs them one by one
        (``host.precomputing``); a frame's ``prepare`` issues them in a row."""
        baked = values["ao_mode"] == "baked_hemisphere"
        rebuild = (changes.first or changes.opacity or self.filtered is None
                   or bool(changes.parameters & FILTER_PARAMETERS))
        bake = baked and (rebuild or self.ao is None
                          or bool(changes.parameters & BAKE_PARAMETERS))
        # Share of the progress bar: the bake costs most (cones × steps per grid point).
        share = 0.3 if bake else 1.0
        if rebuild:
            with self.timed("recompute"):
                for fraction in self._recompute_steps(values):
                    yield share * fraction
            self._recomputes += 1
        if bake:
            with self.timed("bake"):
                for fraction in self._bake_steps(values):
                    yield share + (1.0 - share) * fraction
            self._bakes += 1
        elif not baked and self.ao is not None:
            self._release_ao()

    def recompute(self, values: Mapping[str, Any]) -> None:
        """Rebuild the filtered pyramid from ``host.opacity_volume()`` (context current)."""
        with self.timed("recompute"):
            for _ in self._recompute_steps(values):
                pass
        self._recomputes += 1

    def _recompute_steps(self, values: Mapping[str, Any]) -> Iterator[float]:
        chunked = self.host.precomputing
        gpu = self._gpu_filter(values)
        self._cpu_pyramids = None
        if gpu is not None:
            # The host's opacity texture (classified on the GPU: no numpy pass, no upload)
            # copied into the source's level 0.
            opacity_tex = yield from scale_steps(self.host.opacity_texture_steps(), 0.0, 0.1)
            yield from scale_steps(self._ensure_textures_steps(opacity_tex.shape), 0.1, 0.1)
            assert self.source is not None and self.filtered is not None
            opacity_tex.copy_to(self.source, 0)
        else:
            opacity = yield from scale_steps(self.host.opacity_volume_steps(), 0.0, 0.1)
            yield from scale_steps(self._ensure_textures_steps(opacity.shape), 0.1, 0.1)
            assert self.source is not None and self.filtered is not None
            if chunked:  # the upload in parts, each waited for
                slab = max(1, UPLOAD_SLAB_VOXELS // max(1, opacity.shape[1] * opacity.shape[2]))
                for z0 in range(0, opacity.shape[0], slab):
                    self.source.upload_slab(opacity[z0:z0 + slab], z0)
                    finish_gl(self.host.render_window)
                    yield 0.1
            else:
                self.source.upload(opacity, 0)
        weights = gaussian_weights(values["sigma"], values["span"])
        if gpu is not None:
            assert self._scratch is not None
            for fraction in gpu.run_steps(self.source, self.filtered, self._scratch, weights,
                                          chunked=chunked):
                yield 0.1 + 0.9 * fraction
            self._backend = "gpu"
        else:
            levels = self.filtered.mip_levels
            src = source_pyramid(opacity, levels)
            for lev in range(1, levels):  # keep the source chain complete for the gate fetch
                self.source.upload(src[lev].astype(np.float32), lev)
            yield 0.3
            filtered = filtered_pyramid_cpu(opacity, levels=levels, sigma=values["sigma"],
                                            span=values["span"], alpha_levels=src)
            for lev, d in enumerate(filtered):
                self.filtered.upload(d, lev)
            self._cpu_pyramids = (src, filtered)  # reused by a CPU bake
            self._backend = "cpu"
            yield 1.0

    def bake(self, values: Mapping[str, Any]) -> None:
        """Bake the hemisphere AO on the AO grid from the current pyramids (context current)."""
        with self.timed("bake"):
            for _ in self._bake_steps(values):
                pass
        self._bakes += 1

    def _bake_steps(self, values: Mapping[str, Any]) -> Iterator[float]:
        assert self.filtered is not None and self.source is not None
        data_dims = self.host.dims
        grid = ao_grid_dims(data_dims, values["ao_resolution"])
        if self.ao is None or self.ao.shape != tuple(int(n) for n in grid[::-1]):
            self._ensure_ao(grid)
            yield 0.0  # a new (large) texture
        assert self.ao is not None
        baker = self._gpu_baker(values)
        if baker is not None:
            chunk_s = CHUNK_S if self.host.precomputing else None
            self._source_mips(True)
            try:
                yield from baker.run_steps(
                    self.filtered, self.source, self.ao, data_dims=data_dims,
                    spacing=self.host.spacing, unit_distance=self.host.unit_distance,
                    values=values, chunk_s=chunk_s)
            finally:
                self._source_mips(False)
            self._bake_backend = "gpu"
        else:
            opacity = self.host.opacity_volume()
            src, filtered = self._cpu_pyramids or (None, None)
            self.ao.upload(baked_ao_cpu(
                opacity, self.host.spacing, resolution=values["ao_resolution"],
                cones=int(values["ao_cones"]),
                max_distance_um=float(values["max_distance"]) * min(self.host.spacing),
                sigma=values["sigma"], span=values["span"], lod_width=values["lod_width"],
                h=values["h"], h0=values["h0"], unit_distance=self.host.unit_distance,
                pyramid=filtered, source=src,
            ))
            self._bake_backend = "cpu"
            yield 1.0

    def _gpu_baker(self, values: Mapping[str, Any]) -> GpuAoBaker | None:
        """The GPU AO baker, or None for the numpy bake (also whenever the filter is on numpy)."""
        if self._gpu_filter(values) is None:
            return None
        baker = self._bake_compute.get(self.host, values["backend"])
        if baker is None:
            self._compute.failed = True  # CPU for good (the filter follows at the next rebuild)
        return baker

    def _ensure_ao(self, grid_xyz: Sequence[int]) -> None:
        shape = (int(grid_xyz[2]), int(grid_xyz[1]), int(grid_xyz[0]))
        if self.ao is not None and self.ao.shape == shape:
            return
        self._release_ao()
        self.ao = Texture3D(self.host.render_window, shape)  # linear, clamp to edge
        self.host.bind_texture("vv_cone_traced_ao", self.ao)

    def _release_ao(self, unbind: bool = True) -> None:
        # Unbind only when the AO goes away while we stay active (ao_mode changed); on
        # release() the host removes every binding it made for us.
        if unbind:
            self.host.unbind_texture("vv_cone_traced_ao")
        if self.ao is not None:
            self.ao.release()
            self.ao = None

    def _gpu_filter(self, values: Mapping[str, Any]) -> GpuFilter | None:
        """The GPU pyramid filter (compiled on first use), or None for the numpy path."""
        return self._compute.get(self.host, values["backend"])

    def _source_mips(self, on: bool) -> None:
        """Sample the source pyramid with (bake) or without (rendering) its mip levels."""
        if self.source is None:  # released while a chunked bake was suspended (cancel)
            return
        self.source.tex.SetMinificationFilter(
            vtkTextureObject.LinearMipmapNearest if on else vtkTextureObject.Linear
        )
        self.source.activate()  # sends the filter

    def _ensure_textures_steps(self, shape_zyx: tuple[int, ...]) -> Iterator[float]:
        """Make the pyramids' textures for ``shape_zyx`` (one chunk per texture: on a
        software GL allocating a large one takes about a second)."""
        shape = tuple(int(s) for s in shape_zyx)
        if self.source is not None and self.source.shape == shape:
            return
        self._release_textures()
        rw = self.host.render_window
        levels = mip_level_count(shape)
        textures = []
        for k in range(3):
            # Border 0: cones leaving the volume see empty space, also at coarse levels.
            tex = Texture3D(rw, shape, mip_levels=levels, border=0.0)
            for lev, lshape in enumerate(level_shapes(shape, levels)[1:], start=1):
                tex.upload(np.zeros(lshape, np.float32), lev)  # allocate: complete mip chain
            textures.append(tex)
            if k < 2:
                self._pending_textures = textures  # released with us if cancelled here
                yield (k + 1) / 3
        self._pending_textures = []
        self.source, self.filtered, self._scratch = textures
        # Levels are chosen by an integer LOD: one level per fetch is enough (half the texels
        # of LinearMipmapLinear on llvmpipe); the filter is sent at the next Activate().
        # The fragment shader reads only level 0 of the source (the opacity gate): without a
        # mip filter llvmpipe samples it on its faster non-mip path (measured: frame time
        # −3.5 % median, docs/cone-tracing.md §6). The bake's emptiness gate reads coarser
        # source levels, so the bake switches the mip filter on for its dispatch (_source_mips).
        self.filtered.tex.SetMinificationFilter(vtkTextureObject.LinearMipmapNearest)
        self.source.tex.SetMinificationFilter(vtkTextureObject.Linear)
        self.host.bind_texture("vv_cone_traced_filtered", self.filtered)
        self.host.bind_texture("vv_cone_traced_opacity", self.source)
        yield 1.0

    def _release_textures(self) -> None:
        # Rebinding a new texture to the same uniform replaces the old binding, and release()
        # leaves the bindings to the host: nothing to unbind here.
        pending, self._pending_textures = self._pending_textures, []
        for tex in (self.source, self.filtered, self._scratch, *pending):
            if tex is not None:
                tex.release()
        self.source = self.filtered = self._scratch = None

    def release(self) -> None:
        self._release_textures()
        self._release_ao(unbind=False)
        self._compute.release()
        self._bake_compute.release()
        self._release_timers()

    # -- verification ---------------------------------------------------------------------------
    def ambient_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float],
        values: Mapping[str, Any], view_directions: Sequence[Sequence[float]],
    ) -> list[np.ndarray] | None:
        """1 − ao_strength·AO per voxel (numpy, the shader's algorithm for each
        ``ao_mode``): the baked grid sampled trilinearly, the per-sample hemisphere at every
        voxel with material, or the view cone towards each of ``view_directions``; None when
        AO is off."""
        mode = values["ao_mode"]
        if mode == "off":
            return None
        strength = float(values["ao_strength"])
        max_um = float(values["max_distance"]) * min(spacing)
        common = dict(sigma=values["sigma"], lod_width=values["lod_width"], h=values["h"],
                      h0=values["h0"], unit_distance=self.host.unit_distance)
        if mode == "baked_hemisphere":
            grid = baked_ao_cpu(opacity, spacing, resolution=values["ao_resolution"],
                                cones=int(values["ao_cones"]), max_distance_um=max_um,
                                span=values["span"], **common)
            ao = sample_grid(grid, opacity.shape[::-1], voxel_points(opacity.shape))
            visible = (1.0 - strength * ao).reshape(opacity.shape).astype(np.float32)
            return [visible] * len(view_directions)
        # Per-sample modes: traced only where there is material (elsewhere nothing is shaded).
        pyramid = filtered_pyramid_cpu(opacity, values["sigma"], values["span"])
        where = np.flatnonzero(opacity.ravel() > 1e-3)
        pts = voxel_points(opacity.shape)[where]
        normals = voxel_normals(opacity, spacing).reshape(-1, 3)[where]

        def visibility(view: Sequence[float]) -> np.ndarray:
            out = np.ones(opacity.size, np.float32)
            ao = ambient_occlusion_cpu(
                pyramid, spacing, pts, normals, view, mode=mode, cones=int(values["ao_cones"]),
                ao_angle=values["ao_angle"], max_distance_um=max_um, **common)
            out[where] = 1.0 - strength * ao
            return out.reshape(opacity.shape)

        if mode == "hemisphere":  # about the normal: the same for every view
            return [visibility(view_directions[0])] * len(view_directions)
        return [visibility(view) for view in view_directions]

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """Cone transmittance towards ``light`` at every voxel centre (numpy, the shader's
        algorithm), without the shadow strength: 1 = unshadowed, ``[z, y, x]``."""
        pyramid = filtered_pyramid_cpu(opacity, values["sigma"], values["span"])
        pts = voxel_points(opacity.shape)
        # Dataset space (where LightSpec lives) includes the image origin.
        world = np.asarray(self.host.image.GetOrigin()) + pts * np.asarray(spacing)
        if light.is_point:
            to_light = np.asarray(light.vector) - world
            dist = np.linalg.norm(to_light, axis=1)
            dirs = to_light / np.where(dist > 0, dist, 1.0)[:, None]
            far: float | np.ndarray = dist
        else:
            dirs = np.broadcast_to(np.asarray(light.vector, dtype=np.float64), pts.shape)
            far = _FAR
        if values["shadow_cone"] == "custom":
            sines = np.full(len(pts), math.sin(math.radians(values["shadow_angle"])))
        elif light.is_point:  # radius / distance, as the shader computes it per sample
            sines = np.minimum(light.size / np.maximum(np.asarray(far), 1e-6), 1.0)
        else:
            sines = np.full(len(pts), math.sin(light.size))
        # The CPU tracer marches all points in lock step with one cone angle: group the points
        # by angle (to 1e-3 in sin) and trace each group.
        t = np.empty(len(pts))
        keys = np.round(sines, 3)
        for key in np.unique(keys):
            group = keys == key
            t[group] = cone_trace_cpu(
                pyramid, spacing, pts[group], np.asarray(dirs)[group],
                sin_angle=float(key),
                sigma=values["sigma"], lod_width=values["lod_width"], h=values["h"],
                h0=values["h0"],
                max_distance_um=far if np.ndim(far) == 0 else np.asarray(far)[group],
                unit_distance=self.host.unit_distance,
            )
        return t.reshape(opacity.shape).astype(np.float32)
