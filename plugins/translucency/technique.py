"""Translucency: the engine hooks (docs/translucency.md).

One RGBA light volume per light (RGB = indirect transmittance, A = direct transmittance),
recomputed only when the opacity, the transfer function's colour (which sets the indirect
extinction), the light geometry or an ILLUMINATION parameter changes, never on camera moves.
The propagation is the engine's light-grid propagation (the shadow volume's too): its compute
shader through :class:`~vtkvol.engine.light_grid_gpu.GpuPropagator` (one dispatch sequence per
channel) or its numpy twin (:mod:`.cpu`); the two agree to about 1e-6. The grid, the GPU-or-numpy
choice and the release are :class:`~vtkvol.engine.light_grid_technique.LightGridTechnique`'s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from vtkvol.engine import shaders, tf2d
from vtkvol.engine.gl import GLUnavailableError, Texture3D
from vtkvol.engine.light_grid import LightGrid, light_volume_cpu
from vtkvol.engine.light_grid_gpu import (
    GpuPropagator,
    LightTexture,
    ensure_work_textures,
)
from vtkvol.engine.light_grid_technique import LightGridTechnique
from vtkvol.engine.technique import TechniqueStats
from vtkvol.model.params import Invalidates
from vtkvol.plugins.translucency import TECHNIQUE
from vtkvol.plugins.translucency.cpu import (
    direct_softness,
    indirect_opacity,
    indirect_softness,
    light_rgba_cpu,
    sigma_grids_cpu,
)

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

_ILLUM = Invalidates.ILLUMINATION
#: Samples of the transfer functions' lookup tables (colour volume): finer than VTK's own
#: colour texture, so the table adds no error of its own.
TABLE_SIZE = 4096


def texture_uniform(light: int) -> str:
    """GLSL name of light ``light``'s light volume."""
    return f"vv_translucency_light{light}"


def colour_volume(host: Illuminator) -> np.ndarray:
    """The transfer function's colour at every voxel, ``[z, y, x, 3]`` float32 in 0…1.

    One component: its colour function. Independent components: their colours averaged with
    the weight of each component's opacity × component weight (what each adds to the
    extinction). Dependent components: two → the colour function of the first; four → the first
    three components as RGB (8-bit data divided by 255, others by their maximum), as VTK
    shows them. In 2-D mode (docs/transfer-functions-2d.md) colour and opacity are each
    component's 2-D table read by the host at VTK's (value, gradient) coordinates
    (:meth:`~vtkvol.engine.illuminator.Illuminator.classify_2d`, the lookup its opacity volume
    makes), so the tint follows the same classification as the extinction.
    """
    img = host.image
    nx, ny, nz = img.GetDimensions()
    values = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(nz, ny, nx, -1)
    prop = host.volume.GetProperty()
    ncomp = values.shape[-1]
    if ncomp > 1 and not prop.GetIndependentComponents():
        if ncomp >= 3:
            rgb = values[..., :3].astype(np.float32)
            scale = 255.0 if values.dtype == np.uint8 else max(float(rgb.max()), 1e-30)
            return np.clip(rgb / scale, 0.0, 1.0)
        return _colour_of(prop, 0, values[..., 0])
    if ncomp == 1:
        return _component_colour(host, 0, values[..., 0])
    total = np.zeros((nz, ny, nx, 3), np.float64)
    weight_sum = np.zeros((nz, ny, nx), np.float64)
    for c in range(ncomp):
        weight = prop.GetComponentWeight(c)
        if weight <= 0:
            continue
        alpha = host.classify_2d(c, "alpha")
        if alpha is None:
            alpha = _table_lookup(prop.GetScalarOpacity(c), values[..., c], 1)[..., 0]
        w = alpha * weight
        total += w[..., None] * _component_colour(host, c, values[..., c])
        weight_sum += w
    # Where nothing is opaque the colour does not matter (it multiplies a zero extinction).
    out = np.where(weight_sum[..., None] > 0, total / np.maximum(weight_sum, 1e-30)[..., None],
                   1.0)
    return out.astype(np.float32)


def _component_colour(host: Illuminator, c: int, values: np.ndarray) -> np.ndarray:
    """Independent component ``c``'s colour at every voxel: its 2-D table in 2-D mode, else
    its colour function; ``[z, y, x, 3]`` float32."""
    rgb = host.classify_2d(c, "rgb")
    if rgb is not None:
        return rgb
    return _colour_of(host.volume.GetProperty(), c, values)


def _colour_function(prop: vtk.vtkVolumeProperty, c: int) -> Any:
    """Component ``c``'s colour function: grey (piecewise) or RGB. Only the one in use is
    asked for: VTK's getter of the other kind creates a default one and switches the
    property to it."""
    if prop.GetColorChannels(c) == 1:
        return prop.GetGrayTransferFunction(c)
    return prop.GetRGBTransferFunction(c)


def _colour_of(prop: vtk.vtkVolumeProperty, c: int, values: np.ndarray) -> np.ndarray:
    if prop.GetColorChannels(c) == 1:
        return np.repeat(_table_lookup(_colour_function(prop, c), values, 1), 3, axis=-1)
    return _table_lookup(_colour_function(prop, c), values, 3)


def _table_lookup(function: Any, values: np.ndarray, channels: int) -> np.ndarray:
    """``function`` (piecewise or colour transfer function) at ``values``: a fine lookup table
    over the function's node range, interpolated linearly, clamped outside (as VTK's TF
    textures); ``[..., channels]`` float32."""
    lo, hi = (float(r) for r in function.GetRange())
    if not hi > lo:
        hi = lo + 1.0
    table = np.zeros(TABLE_SIZE * channels)
    function.GetTable(lo, hi, TABLE_SIZE, table)
    table = table.reshape(TABLE_SIZE, channels)
    xs = np.linspace(lo, hi, TABLE_SIZE)
    flat = np.asarray(values, np.float64).ravel()
    flat = np.where(np.isfinite(flat), flat, lo)
    out = np.stack([np.interp(flat, xs, table[:, k]) for k in range(channels)], axis=-1)
    return out.reshape(*np.shape(values), channels).astype(np.float32)


class Translucency(LightGridTechnique):
    """Direct + chromatic indirect light from a precomputed RGBA light volume per light."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "translucency.glsl"
    #: Kniss's surface-shading factor: replaces the host's shading result (surface_factor.glsl).
    SURFACE_SHADER: ClassVar[str] = "surface_factor.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self.light_textures: list[LightTexture] = []
        self._sigma_tex: list[Texture3D] = []  # direct, indirect R, G, B
        self._sigma_cpu: list[np.ndarray] | None = None
        self._colour_key: tuple | None = None

    # -- hooks --------------------------------------------------------------------------------
    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        return {"VV_TL_LIGHTS": str(len(self.light_textures))}

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        """The hook file, plus the surface-shading factor where VTK builds its shaded lighting
        (the Exit tag and the gradient exist only there)."""
        out = super().sections(values)
        if values["surface_factor"] == "gradient" and self.host.shaded:
            out += shaders.load(self.SURFACE_SHADER, package=self.shader_package())
        return out

    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        specs = self.host.light_specs()
        # Colour or intensity changes need no recompute; a size changes the penumbra.
        light_key = tuple((s.kind, s.vector, s.size) for s in specs)
        grid = LightGrid.for_data(self.host.dims, self.host.spacing, values["resolution"])
        colour_key = self._colour_signature(values)
        if (changes.first or changes.opacity or grid != self.grid
                or colour_key != self._colour_key
                or changes.any_parameter(self.PARAMETERS, _ILLUM)):
            self._sigma_valid = {"gpu": False, "cpu": False}
            self._colour_key = colour_key
        gpu = self._compute.get(self.host, values["backend"])
        needed = (
            changes.first
            or not self._sigma_valid["gpu" if gpu is not None else "cpu"]
            or light_key != self._light_key
            or len(self.light_textures) != len(specs)
        )
        if not needed:
            return
        with self.timed("recompute"):
            self._recompute(grid, light_key, specs, gpu, values)
        self._recomputes += 1

    def stats(self) -> TechniqueStats:
        """The light volumes' recomputations; ``extra``: ``lights`` (light volumes held)."""
        textures = [*self.light_textures, *self._sigma_tex, *self._work_tex.values()]
        return TechniqueStats(
            recomputes=self._recomputes, recompute_ms=self.elapsed_ms("recompute"),
            backend=self._backend, texture_bytes=sum(t.nbytes for t in textures),
            extra={"lights": len(self.light_textures)})

    def release(self) -> None:
        super().release()
        for tex in (*self.light_textures, *self._sigma_tex):
            tex.release()
        self.light_textures = []
        self._sigma_tex = []
        self._sigma_cpu = None
        self._colour_key = None

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """The **direct** transmittance of ``light`` at every data voxel centre, ``[z, y, x]``
        float32 (the shadow volume's transmittance model with the light's own penumbra; the
        indirect term has no physical visibility to compare with)."""
        merged = {**self.defaults(), **values}
        grid = LightGrid.for_data(opacity.shape[::-1], spacing, merged["resolution"])
        vis = light_volume_cpu(
            opacity, spacing, light, unit_distance=self.host.unit_distance,
            model="transmittance", resolution=merged["resolution"],
            softness=direct_softness(light, grid, self._origin(), self._direction()),
            origin=self._origin(), direction=self._direction(),
        )
        return grid.to_data(vis)

    def light_volumes_cpu(self, values: Mapping[str, Any]) -> list[np.ndarray]:
        """Every light's RGBA volume computed by the numpy path from the host's current
        opacity and colour (verification of the GPU path), ``[z, y, x, 4]`` each."""
        merged = {**self.defaults(), **values}
        grid = LightGrid.for_data(self.host.dims, self.host.spacing, merged["resolution"])
        sigmas = self._cpu_sigmas(grid, merged)
        return [self._light_rgba_cpu(sigmas, grid, spec, merged)
                for spec in self.host.light_specs()]

    # -- internals ----------------------------------------------------------------------------
    def _colour_signature(self, values: Mapping[str, Any]) -> tuple:
        """What the colour volume depends on beyond the opacity signature (only while the
        colour tints the indirect extinction)."""
        if values["tint"] <= 0.0 or values["indirect_extinction"] <= 0.0:
            return ()
        prop = self.host.volume.GetProperty()
        scalars = self.host.image.GetPointData().GetScalars()
        ncomp = scalars.GetNumberOfComponents() if scalars is not None else 1
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            # The tables' colour; the per-unit alpha's MTime moves with every new table and
            # not with the ray step, so a camera drag (coarser step) recomputes nothing.
            return ("2d", *(
                tf2d.unit_alpha_mtime(prop.GetTransferFunction2D(c))
                if prop.GetTransferFunction2D(c) is not None else None
                for c in range(max(1, ncomp))))
        return tuple(_colour_function(prop, c).GetMTime() for c in range(max(1, ncomp)))

    def _colour(self, shape_zyx: tuple[int, ...], values: Mapping[str, Any]) -> np.ndarray:
        """The colour volume while it tints the indirect extinction, else zeros (unused by the
        formula, so colour edits then cost nothing)."""
        if values["tint"] > 0.0 and values["indirect_extinction"] > 0.0:
            return colour_volume(self.host)
        return np.zeros((*shape_zyx, 3), np.float32)

    def _cpu_sigmas(self, grid: LightGrid, values: Mapping[str, Any]) -> list[np.ndarray]:
        opacity = self.host.opacity_volume()
        return sigma_grids_cpu(opacity, self._colour(opacity.shape, values), grid,
                               values["indirect_extinction"], values["tint"])

    def _softness(
        self, spec: LightSpec, grid: LightGrid, values: Mapping[str, Any]
    ) -> tuple[float, float]:
        origin, direction = self._origin(), self._direction()
        return (direct_softness(spec, grid, origin, direction),
                indirect_softness(spec, grid, values["indirect_angle"], origin, direction))

    def _light_rgba_cpu(self, sigmas: Sequence[np.ndarray], grid: LightGrid, spec: LightSpec,
                        values: Mapping[str, Any]) -> np.ndarray:
        kind, vec = grid.light(spec, self._origin(), self._direction())
        direct, indirect = self._softness(spec, grid, values)
        return light_rgba_cpu(sigmas, grid, kind, vec, direct_soft=direct,
                              indirect_soft=indirect, unit_distance=self.host.unit_distance)

    def _recompute(self, grid: LightGrid, light_key: tuple, specs: Sequence[LightSpec],
                   gpu: GpuPropagator | None, values: Mapping[str, Any]) -> None:
        self.grid = grid
        self._light_key = light_key
        self._ensure_light_textures(grid, len(specs))
        if gpu is not None:
            try:
                self._recompute_gpu(gpu, grid, specs, values)
                self._backend = "gpu"
            except GLUnavailableError as exc:
                self._compute.disable(exc)
                gpu = None
        if gpu is None:
            self._recompute_cpu(grid, specs, values)
            self._backend = "cpu"
        for i, tex in enumerate(self.light_textures):
            self.host.bind_texture(texture_uniform(i), tex)

    def _ensure_light_textures(self, grid: LightGrid, count: int) -> None:
        while len(self.light_textures) > count:
            i = len(self.light_textures) - 1
            self.host.unbind_texture(texture_uniform(i))
            self.light_textures.pop().release()
        for i in range(count):
            old = self.light_textures[i] if i < len(self.light_textures) else None
            if old is not None and old.shape == grid.shape_zyx:
                continue
            if old is not None:
                old.release()
            tex = LightTexture(self.host.render_window, grid.shape_zyx, 4)
            if i < len(self.light_textures):
                self.light_textures[i] = tex
            else:
                self.light_textures.append(tex)

    def _recompute_gpu(self, gpu: GpuPropagator, grid: LightGrid, specs: Sequence[LightSpec],
                       values: Mapping[str, Any]) -> None:
        rw = self.host.render_window
        if not self._sigma_valid["gpu"]:
            if len(self._sigma_tex) != 4 or self._sigma_tex[0].shape != grid.shape_zyx:
                for tex in self._sigma_tex:
                    tex.release()
                self._sigma_tex = [Texture3D(rw, grid.shape_zyx) for _ in range(4)]
            opacity = self.host.opacity_volume()
            gpu.prefilter(opacity, self._sigma_tex[0], grid)
            alpha_i = indirect_opacity(opacity, self._colour(opacity.shape, values),
                                       values["indirect_extinction"], values["tint"])
            for c in range(3):
                gpu.prefilter(np.ascontiguousarray(alpha_i[..., c]), self._sigma_tex[1 + c], grid)
            self._sigma_valid["gpu"] = True
        ensure_work_textures(rw, self._work_tex, grid)
        for tex, spec in zip(self.light_textures, specs, strict=True):
            kind, vec = grid.light(spec, self._origin(), self._direction())
            direct, indirect = self._softness(spec, grid, values)
            for channel, sigma, soft in ((3, 0, direct), (0, 1, indirect), (1, 2, indirect),
                                         (2, 3, indirect)):
                gpu.propagate(
                    self._sigma_tex[sigma], self._work_tex, tex, grid, kind, vec,
                    model="transmittance", softness=soft,
                    unit_distance=self.host.unit_distance, channel=channel,
                )

    def _recompute_cpu(self, grid: LightGrid, specs: Sequence[LightSpec],
                       values: Mapping[str, Any]) -> None:
        if not self._sigma_valid["cpu"] or self._sigma_cpu is None:
            self._sigma_cpu = self._cpu_sigmas(grid, values)
            self._sigma_valid["cpu"] = True
        for tex, spec in zip(self.light_textures, specs, strict=True):
            tex.upload(self._light_rgba_cpu(self._sigma_cpu, grid, spec, values))
