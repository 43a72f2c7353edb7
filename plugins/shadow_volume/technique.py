"""Precomputed shadow volumes inside VTK's ray caster (seed 000 §2.7, made fast and physical).

For every light, a *light volume* holds the visibility V ∈ [0, 1] of the light at the cell
centres of a grid covering the data's point bounds (full, ½ or ¼ resolution per axis). The ray
caster reads it with one texture fetch per shaded sample, offset ``offset`` cells towards the
light so a surface does not shadow itself (resources/shaders/shadow_volume.glsl). The volume is
recomputed only when the opacity (data, transfer function, crop, slice weights, placement), the
light geometry or an ILLUMINATION parameter changes: never on camera moves.

Propagation (docs/shadow-volume.md has the derivation and the measurements): slices of the grid
are processed one after the other along the axis most aligned with the light, starting at the
light. A cell A of slice k takes the value of the previous slice where the ray from A towards the
light crosses it (point P), filtered by a small kernel around P:

* ``transmittance`` (default): multiplicative transmittance, T = Π (1 − α_corrected) with the
  opacity corrected for the oblique path, α_corrected = 1 − (1 − α)^(Δs/u), Δs (µm) the length
  of the segment A→P and u the opacity unit distance. Integrated with Simpson's rule on each
  segment, s = −ln(1 − α) trilinear at its midpoint M:
  T(A) = W̃(P) · exp(−(4 s(M) + s(A))/6 · Δs/u), where W = T · exp(−s Δs/6u) is what a slice
  hands on and W̃ is W interpolated bilinearly at P, then blurred by a discrete Gaussian of
  ``softness`` cells (0 = hard shadows). A ray that leaves through a side face before the
  previous slice integrates only its part inside the volume.
* ``seed000``: the thesis's S(A) = min(1, α(A) + Σ G₁(B − P) S(B)) over the 8×8 neighbours B
  of P with a unit Gaussian; stored as V = 1 − S.

Directional lights use one pass along their dominant axis. Point lights use up to six passes,
one per pyramid around the light (each cell is stored by the pass along the largest component of
its offset from the light), so a light inside the box is handled too.

Two paths compute the same thing: a compute shader (one dispatch per slice, one invocation per
cell, or per 4 cells along a row for directional lights, which share their filter taps) and
vectorised numpy (per slice), used when compute shaders are missing and for verification. The
GPU kernel is resources/shaders/shadow_volume_propagate.comp; every formula there is mirrored
here, and the two agree to about 1e-6.

Spaces: "data index" = voxel indices of the image; "grid" = indices of the light grid, cell g at
data index g · step (step = (n − 1)/(m − 1) per axis); light vectors arrive in dataset space
(µm, the image's own coordinates) from :meth:`Illuminator.light_specs`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk

from vtkvol.engine.gl import (
    ComputeProgram,
    GLUnavailableError,
    Texture3D,
    compute_supported,
    gl,
)
from vtkvol.engine.shaders import compute_source
from vtkvol.engine.technique import Technique
from vtkvol.model.params import Invalidates
from vtkvol.plugins.shadow_volume import RESOLUTIONS, TECHNIQUE

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

log = logging.getLogger(__name__)

#: Largest filter radius R in cells (the filter has (2R + 2)² taps per cell).
RMAX = 8
#: Work-group size (u, v) of the propagation kernel.
GROUP = (8, 8)
#: Cells along u per invocation for directional lights (they share taps; see the kernel).
BLOCK = 4
#: α is clamped here before s = −ln(1 − α), as in the compute shader (float32 of 0.999999).
MAX_OPACITY = float(np.float32(0.999999))
#: Tap radius and weights of the thesis model (8×8 neighbourhood, σ = 1).
SEED000_RADIUS = 3
COMPUTE_SOURCE = "propagate.comp.glsl"
TEXTURE_UNIFORM = "vv_shadow_volume_tex"

_ILLUM = Invalidates.ILLUMINATION


class ShadowVolume(Technique):
    """Shadows from a precomputed light volume per light (packed one light per channel)."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "shadow_volume.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self.recompute_count = 0  #: light-volume recomputations so far (stats())
        self.last_backend = ""  #: "gpu" or "cpu": the path of the last recomputation
        self.grid: LightGrid | None = None
        self.light_texture: LightTexture | None = None
        self._gpu: GpuPropagator | None = None
        self._gpu_failed = False
        self._sigma_tex: Texture3D | None = None
        self._work_tex: dict[int, Texture3D] = {}
        self._sigma_cpu: np.ndarray | None = None
        self._sigma_valid: dict[str, bool] = {"gpu": False, "cpu": False}
        self._light_key: tuple | None = None

    # -- hooks --------------------------------------------------------------------------------
    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        specs = self.host.light_specs()
        # Colour changes need no recompute; a size changes the penumbra.
        light_key = tuple((s.kind, s.vector, s.size) for s in specs)
        grid = LightGrid.for_data(self.host.dims, self.host.spacing, values["resolution"])
        if changes.first or changes.opacity or grid != self.grid:
            self._sigma_valid = {"gpu": False, "cpu": False}
        gpu = self._gpu_path(values)
        needed = (
            changes.first
            or not self._sigma_valid["gpu" if gpu is not None else "cpu"]  # opacity, grid
            or light_key != self._light_key
            or changes.any_parameter(self.PARAMETERS, _ILLUM)
            or self.light_texture is None
        )
        if not needed:
            return
        with self.timed("recompute"):
            self._recompute(grid, light_key, specs, gpu, values)
        self.recompute_count += 1

    def _recompute(self, grid: LightGrid, light_key: tuple, specs: Sequence[LightSpec],
                   gpu: GpuPropagator | None, values: Mapping[str, Any]) -> None:
        self.grid = grid
        self._light_key = light_key
        channels = 1 if len(specs) <= 1 else (2 if len(specs) == 2 else 4)
        self._ensure_light_texture(grid, channels)
        if gpu is not None:
            try:
                self._recompute_gpu(gpu, grid, specs, values)
                self.last_backend = "gpu"
            except GLUnavailableError as exc:
                self._disable_gpu(exc)
                gpu = None
        if gpu is None:
            self._recompute_cpu(grid, specs, values)
            self.last_backend = "cpu"
        assert self.light_texture is not None
        self.host.bind_texture(TEXTURE_UNIFORM, self.light_texture)

    def stats(self) -> dict[str, Any]:
        textures = [self.light_texture, self._sigma_tex, *self._work_tex.values()]
        return {
            "recomputes": self.recompute_count,
            "recompute_ms": self.elapsed_ms("recompute"),
            "backend": self.last_backend,
            "texture_bytes": sum(t.nbytes for t in textures if t is not None),
        }

    def uniforms(self, values: Mapping[str, Any]) -> dict[str, Any]:
        grid = self.grid
        if grid is None:
            return {}
        return {
            "vv_shadow_volume_dims": tuple(float(m) for m in grid.dims),
            "vv_shadow_volume_cellTex": tuple(
                float(st / n) for st, n in zip(grid.step, grid.data_dims, strict=True)
            ),
        }

    def release(self) -> None:
        # The host removes our uniforms and texture bindings; we release what we created.
        self._release_timers()
        for tex in (self.light_texture, self._sigma_tex, *self._work_tex.values()):
            if tex is not None:
                tex.release()
        self.light_texture = self._sigma_tex = None
        self._work_tex = {}
        if self._gpu is not None:
            self._gpu.release()
            self._gpu = None
        self._sigma_cpu = None
        self._sigma_valid = {"gpu": False, "cpu": False}
        self.grid = None
        self._light_key = None

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
            softness=light_softness(light, grid, merged), origin=self._origin(),
            direction=self._direction(),
        )
        return grid.to_data(vis)

    # -- internals ----------------------------------------------------------------------------
    def _origin(self) -> tuple[float, float, float]:
        return tuple(float(o) for o in self.host.image.GetOrigin())  # type: ignore[return-value]

    def _direction(self) -> np.ndarray:
        m = self.host.image.GetDirectionMatrix()
        return np.array([[m.GetElement(i, j) for j in range(3)] for i in range(3)])

    def _gpu_path(self, values: Mapping[str, Any]) -> GpuPropagator | None:
        if values["backend"] == "cpu" or self._gpu_failed:
            return None
        if self._gpu is None:
            rw = self.host.render_window
            try:
                if rw is None or not compute_supported(rw):
                    raise GLUnavailableError("this OpenGL context has no compute shaders")
                self._gpu = GpuPropagator(rw)
            except GLUnavailableError as exc:
                self._disable_gpu(exc)
                return None
        return self._gpu

    def _disable_gpu(self, exc: Exception) -> None:
        if not self._gpu_failed:
            log.warning("shadow_volume: compute path unavailable, using numpy (%s)", exc)
        self._gpu_failed = True
        if self._gpu is not None:
            self._gpu.release()
            self._gpu = None

    def _ensure_light_texture(self, grid: LightGrid, channels: int) -> None:
        shape = grid.shape_zyx
        tex = self.light_texture
        if tex is None or tex.shape != shape or tex.channels != channels:
            if tex is not None:
                tex.release()
            self.light_texture = LightTexture(self.host.render_window, shape, channels)

    def _recompute_gpu(
        self, gpu: GpuPropagator, grid: LightGrid, specs: Sequence[LightSpec],
        values: Mapping[str, Any],
    ) -> None:
        rw = self.host.render_window
        if not self._sigma_valid["gpu"]:
            if self._sigma_tex is None or self._sigma_tex.shape != grid.shape_zyx:
                if self._sigma_tex is not None:
                    self._sigma_tex.release()
                self._sigma_tex = Texture3D(rw, grid.shape_zyx)
            gpu.prefilter(self.host.opacity_volume(), self._sigma_tex, grid)
            self._sigma_valid["gpu"] = True
        for axis in range(3):
            ua, va = in_plane_axes(axis)
            shape = (2, grid.dims[va], grid.dims[ua])  # exactly one slice: loads outside are 0
            old = self._work_tex.get(axis)
            if old is None or old.shape != shape:
                if old is not None:
                    old.release()
                self._work_tex[axis] = Texture3D(rw, shape)
        assert self._sigma_tex is not None and self.light_texture is not None
        for channel, spec in enumerate(specs):
            kind, vec = grid.light(spec, self._origin(), self._direction())
            gpu.propagate(
                self._sigma_tex, self._work_tex, self.light_texture, grid, kind, vec,
                model=values["model"], softness=light_softness(spec, grid, values),
                unit_distance=self.host.unit_distance, channel=channel,
            )

    def _recompute_cpu(
        self, grid: LightGrid, specs: Sequence[LightSpec], values: Mapping[str, Any]
    ) -> None:
        if not self._sigma_valid["cpu"] or self._sigma_cpu is None:
            self._sigma_cpu = prefilter_cpu(self.host.opacity_volume(), grid)
            self._sigma_valid["cpu"] = True
        assert self.light_texture is not None
        packed = np.ones((*grid.shape_zyx, self.light_texture.channels), np.float32)
        for channel, spec in enumerate(specs):
            kind, vec = grid.light(spec, self._origin(), self._direction())
            packed[..., channel] = propagate_cpu(
                self._sigma_cpu, grid, kind, vec, model=values["model"],
                softness=light_softness(spec, grid, values),
                unit_distance=self.host.unit_distance,
            )
        self.light_texture.upload(packed)


# ---------------------------------------------------------------------------------------------
# Geometry shared by both paths
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LightGrid:
    """The light grid: ``dims`` cells (x, y, z) spanning the data's point bounds.

    ``step`` is the distance between cell centres in data voxels per axis, ``cell_um`` in µm.
    """

    data_dims: tuple[int, int, int]
    dims: tuple[int, int, int]
    spacing: tuple[float, float, float]

    @classmethod
    def for_data(
        cls, data_dims: Sequence[int], spacing: Sequence[float], resolution: str
    ) -> LightGrid:
        factor = RESOLUTIONS[resolution]
        dims = []
        for n in data_dims:
            n = int(n)
            m = n if factor == 1 or n <= 2 else max(2, math.ceil(n / factor))
            dims.append(m)
        return cls(
            tuple(int(n) for n in data_dims),  # type: ignore[arg-type]
            tuple(dims),  # type: ignore[arg-type]
            tuple(float(s) for s in spacing),  # type: ignore[arg-type]
        )

    @property
    def shape_zyx(self) -> tuple[int, int, int]:
        return self.dims[2], self.dims[1], self.dims[0]

    @property
    def step(self) -> tuple[float, float, float]:
        return tuple(  # type: ignore[return-value]
            (n - 1) / (m - 1) if m > 1 else 1.0
            for n, m in zip(self.data_dims, self.dims, strict=True)
        )

    @property
    def cell_um(self) -> tuple[float, float, float]:
        return tuple(st * s for st, s in zip(self.step, self.spacing, strict=True))  # type: ignore

    def light(
        self, spec: LightSpec, origin: Sequence[float] = (0.0, 0.0, 0.0),
        direction: np.ndarray | None = None,
    ) -> tuple[str, np.ndarray]:
        """``(kind, vector)`` of a dataset-space light in grid index space: a direction in grid
        cells (not normalised) or a position in grid coordinates. float32-rounded, as the GPU
        sees it, so both paths make the same tie decisions."""
        rot = np.eye(3) if direction is None else np.asarray(direction, float)
        vec = np.asarray(spec.vector, float)
        cell = np.asarray(self.cell_um)
        if spec.kind == "point":
            index = rot.T @ (vec - np.asarray(origin, float))  # µm along the image axes
            out = index / cell
        else:
            out = (rot.T @ vec) / cell
        return spec.kind, out.astype(np.float32).astype(np.float64)

    def to_data(self, grid_values: np.ndarray) -> np.ndarray:
        """Trilinear resampling of a grid volume ``[z, y, x]`` at the data voxel centres."""
        if self.dims == self.data_dims:
            return np.asarray(grid_values, np.float32)
        from scipy.ndimage import map_coordinates

        axes = [np.arange(n) / st for n, st in zip(self.data_dims, self.step, strict=True)]
        zz, yy, xx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
        out = map_coordinates(grid_values, [zz, yy, xx], order=1, mode="nearest")
        return out.astype(np.float32)

    def nbytes_per_light(self) -> int:
        return 4 * self.dims[0] * self.dims[1] * self.dims[2]


@dataclass(frozen=True)
class Pass:
    """Slices processed along ``axis`` (0 = x) in the order given, away from the light.

    ``restrict``: store only the cells of this pass's pyramid (point lights).
    """

    axis: int
    sweep: int
    slices: tuple[int, ...]
    restrict: bool


def plan_passes(dims: Sequence[int], kind: str, vec: np.ndarray) -> list[Pass]:
    """The passes that cover the grid for one light (grid-space ``kind``/``vec``)."""
    dims = [int(d) for d in dims]
    if kind != "point":
        mag = np.abs(vec) if np.any(vec) else np.array([0.0, 0.0, 1.0])
        axis = int(np.argmax(mag))  # ties -> lowest axis, as np.argmax
        sweep = -1 if vec[axis] > 0 else 1  # start at the face nearest the light
        n = dims[axis]
        slices = tuple(range(n)) if sweep > 0 else tuple(range(n - 1, -1, -1))
        return [Pass(axis, sweep, slices, restrict=False)]
    passes = []
    for axis in range(3):
        la = float(vec[axis])
        n = dims[axis]
        start = math.ceil(la)
        for sweep in (1, -1):
            if sweep > 0:
                slices = list(range(max(0, start), n))
            else:
                slices = list(range(min(n - 1, start - 1), -1, -1))
            # Skip slices whose pyramid cross-section misses the box (it only grows).
            while slices and not _pyramid_meets_slice(dims, axis, vec, slices[0]):
                slices.pop(0)
            if slices:
                passes.append(Pass(axis, sweep, tuple(slices), restrict=True))
    return passes


def _pyramid_meets_slice(dims: Sequence[int], axis: int, pos: np.ndarray, k: int) -> bool:
    reach = abs(k - float(pos[axis]))
    for b in range(3):
        if b == axis:
            continue
        lo = max(0.0, float(pos[b]) - reach)
        hi = min(dims[b] - 1.0, float(pos[b]) + reach)
        if math.ceil(lo) > math.floor(hi):
            return False
    return True


def in_plane_axes(axis: int) -> tuple[int, int]:
    """The (u, v) axes of a slice across ``axis`` (0 = x): the other two, in increasing order."""
    return (1, 2) if axis == 0 else ((0, 2) if axis == 1 else (0, 1))


def light_softness(spec: LightSpec, grid: LightGrid, values: Mapping[str, Any]) -> float:
    """The per-slice blur σ (light-grid cells) for ``spec``: the declared ``softness``, or, with
    ``softness_from = "light size"``, the σ whose penumbra equals the light's geometric one
    half-way through the grid along the light.

    A light of angular radius r casts a penumbra of half-width d·tan r at distance d; the
    per-slice Gaussian blur widens it as √k·σ after k slices. Matching both at k = n/2 slices
    (n along the dominant axis) gives σ = √k·(Δ_axis/Δ_plane)·tan r, clamped to the declared
    range (4 cells). Nearer occluders get a slightly too wide penumbra, farther ones a too
    narrow one (√k against k): the limit of a slice-by-slice blur (docs/shadow-volume.md).
    """
    if values.get("softness_from", "custom") == "custom" or values.get("model") == "seed000":
        return float(values["softness"])
    cell = np.asarray(grid.cell_um, float)
    if spec.is_point:
        centre = np.array([(n - 1) * c / 2.0 for n, c in zip(grid.dims, cell, strict=True)])
        to_centre = centre - np.asarray(spec.vector, float)
        distance = float(np.linalg.norm(to_centre))
        tan_r = spec.size / max(distance, 1e-9)
        direction = to_centre
    else:
        tan_r = math.tan(spec.size)
        direction = np.asarray(spec.vector, float)
    if tan_r <= 0:
        return 0.0
    axis = int(np.argmax(np.abs(direction / cell)))
    k = max(grid.dims[axis] / 2.0, 1.0)
    plane = float(np.mean([cell[a] for a in range(3) if a != axis]))
    return float(min(math.sqrt(k) * cell[axis] / plane * tan_r, 4.0))


def gauss_taps(softness: float) -> tuple[int, np.ndarray]:
    """Radius R and one-sided normalised discrete Gaussian g(0..R) for ``softness`` cells.

    The Gaussian is cut at 2σ (R = ⌈2σ⌉, at most RMAX) and renormalised: the taps cost
    (2R + 2)² per cell, and the 2σ tail (4.6 %) only shortens the penumbra slightly.
    """
    if softness <= 0:
        return 0, np.ones(1)
    radius = min(RMAX, math.ceil(2.0 * softness - 1e-9))
    k = np.arange(radius + 1)
    g = np.exp(-0.5 * (k / softness) ** 2)
    return radius, g / (g[0] + 2.0 * g[1:].sum())


# ---------------------------------------------------------------------------------------------
# CPU path (numpy): the same algorithm, vectorised over a slice
# ---------------------------------------------------------------------------------------------
def prefilter_cpu(alpha: np.ndarray, grid: LightGrid) -> np.ndarray:
    """s = −ln(1 − α) averaged over each grid cell's box (see the compute shader's pass 0).

    ``alpha`` is ``[z, y, x]`` at data resolution; returns float64 ``grid.shape_zyx``.
    """
    a = np.clip(np.asarray(alpha, np.float64), 0.0, MAX_OPACITY)
    s = -np.log1p(-a)
    if grid.dims == grid.data_dims:
        return s
    for axis_xyz in range(3):
        w = _box_weights(grid.data_dims[axis_xyz], grid.dims[axis_xyz], grid.step[axis_xyz])
        s = np.moveaxis(np.tensordot(w, s, axes=([1], [2 - axis_xyz])), 0, 2 - axis_xyz)
    return s


def _box_weights(n: int, m: int, step: float) -> np.ndarray:
    """(m, n) row-normalised overlap of voxel cells with each grid cell's box."""
    half = 0.5 * max(step, 1.0)
    centres = np.arange(m) * step
    i = np.arange(n)
    lo = np.maximum(i[None, :] - 0.5, centres[:, None] - half)
    hi = np.minimum(i[None, :] + 0.5, centres[:, None] + half)
    w = np.maximum(hi - lo, 0.0)
    return w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)


def light_volume_cpu(
    opacity: np.ndarray,
    spacing: Sequence[float],
    light: LightSpec,
    *,
    unit_distance: float | None = None,
    model: str = "transmittance",
    resolution: str = "full",
    softness: float = 0.5,
    origin: Sequence[float] = (0.0, 0.0, 0.0),
    direction: np.ndarray | None = None,
) -> np.ndarray:
    """Light volume of one light on the light grid, ``[z, y, x]`` float32 visibility in 0…1.

    ``opacity`` is the TF opacity per data voxel (``[z, y, x]``, per ``unit_distance`` µm,
    default the smallest voxel edge); ``spacing`` (x, y, z) µm; ``light`` in dataset space.
    """
    grid = LightGrid.for_data(np.shape(opacity)[::-1], spacing, resolution)
    u = float(min(spacing)) if unit_distance is None else float(unit_distance)
    kind, vec = grid.light(light, origin, direction)
    return propagate_cpu(
        prefilter_cpu(opacity, grid), grid, kind, vec, model=model, softness=softness,
        unit_distance=u,
    )


def propagate_cpu(
    sigma: np.ndarray,
    grid: LightGrid,
    kind: str,
    vec: np.ndarray,
    *,
    model: str,
    softness: float,
    unit_distance: float,
) -> np.ndarray:
    """Propagate one light through the extinction grid ``sigma`` (s per cell, ``[z, y, x]``);
    ``kind``/``vec`` in grid space (:meth:`LightGrid.light`). Returns visibility, float32."""
    seed = model == "seed000"
    radius, g = (SEED000_RADIUS, np.ones(1)) if seed else gauss_taps(softness)
    inv_unit = 1.0 / unit_distance
    cell = np.asarray(grid.cell_um)
    dims = grid.dims
    out = np.ones(grid.shape_zyx, np.float64)
    point = kind == "point"
    for p in plan_passes(dims, kind, vec):
        a = p.axis
        ua, va = in_plane_axes(a)
        nu, nv, na = dims[ua], dims[va], dims[a]
        cu = np.arange(nu, dtype=np.float64)
        cv = np.arange(nv, dtype=np.float64)
        work = np.zeros((nv, nu))  # S, or 1 − W (see the compute shader): 0 outside
        for index, k in enumerate(p.slices):
            kp = k - p.sweep
            prev_inside = 0 <= kp < na
            direct = point and abs(vec[a] - k) < 1.0
            # This cell's step to the previous slice (grid cells), separable in u and v.
            if point:
                reach = max(abs(vec[a] - k), 1.0)
                step_u, step_v = (vec[ua] - cu) / reach, (vec[va] - cv) / reach
            else:
                step_u = np.full(nu, vec[ua] / abs(vec[a]))
                step_v = np.full(nv, vec[va] / abs(vec[a]))
            acc = np.zeros((nv, nu))
            pu, pv = cu + step_u, cv + step_v
            # A crossing outside the outermost cell centres has left the volume.
            p_inside = _inside(pv, nv)[:, None] & _inside(pu, nu)[None, :]
            if prev_inside and not direct and index > 0:
                acc = _filter_slice(work, pu, pv, radius, g, seed)
                if not seed:  # (the thesis model keeps what the taps inside give)
                    acc *= p_inside
            s_a = _slice(sigma, a, k)
            if seed:
                stored = np.minimum(1.0, -np.expm1(-s_a) + acc)
                vis = 1.0 - stored
            else:
                ds = np.sqrt(
                    ((step_u * cell[ua]) ** 2)[None, :]
                    + ((step_v * cell[va]) ** 2)[:, None]
                    + cell[a] ** 2
                )
                depth_per_s = ds * inv_unit
                if not prev_inside:
                    vis = np.ones((nv, nu))
                elif direct:
                    du = (cu - vec[ua]) * cell[ua]
                    dv = (cv - vec[va]) * cell[va]
                    dist = np.sqrt(
                        du[None, :] ** 2 + dv[:, None] ** 2 + ((k - vec[a]) * cell[a]) ** 2
                    )
                    vis = np.exp(-s_a * dist * inv_unit)
                else:
                    plane_k, plane_p = s_a, _slice(sigma, a, kp)
                    vv_, uu_ = np.meshgrid(cv, cu, indexing="ij")
                    su = np.broadcast_to(step_u[None, :], (nv, nu))
                    svv = np.broadcast_to(step_v[:, None], (nv, nu))
                    s_m = _between(plane_k, plane_p, uu_ + 0.5 * su, vv_ + 0.5 * svv, 0.5)
                    vis = np.clip(
                        (1.0 - acc) * np.exp(-(4.0 * s_m + s_a) / 6.0 * depth_per_s), 0.0, 1.0
                    )
                    # Rays leaving through a side face before the previous slice: Simpson's
                    # rule on the fraction f of the segment inside the volume.
                    out_mask = ~p_inside
                    if out_mask.any():
                        f = np.ones((nv, nu))
                        for c, st, n_b in ((uu_, su, nu), (vv_, svv, nv)):
                            with np.errstate(divide="ignore", invalid="ignore"):
                                f = np.where(c + st > n_b - 1, np.minimum(f, (n_b - 1 - c) / st), f)
                                f = np.where(c + st < 0, np.minimum(f, -c / st), f)
                        f = np.maximum(f, 0.0)[out_mask]
                        cu_o, cv_o = uu_[out_mask], vv_[out_mask]
                        su_o, sv_o = su[out_mask], svv[out_mask]
                        s_mf = _between(plane_k, plane_p, cu_o + 0.5 * f * su_o,
                                        cv_o + 0.5 * f * sv_o, 0.5 * f)
                        s_e = _between(plane_k, plane_p, cu_o + f * su_o, cv_o + f * sv_o, f)
                        vis[out_mask] = np.exp(
                            -(s_a[out_mask] + 4.0 * s_mf + s_e) / 6.0 * f * depth_per_s[out_mask]
                        )
                stored = 1.0 - vis * np.exp(-s_a / 6.0 * depth_per_s)
            work = stored
            target = _slice(out, a, k)
            if p.restrict:
                mask = _pyramid_mask(cu, cv, k, a, ua, va, vec)
                target[mask] = vis[mask]
            else:
                target[...] = vis
    return out.astype(np.float32)


def _slice(arr: np.ndarray, axis_xyz: int, k: int) -> np.ndarray:
    """View of slice k along x/y/z of a ``[z, y, x]`` array, indexed ``[v, u]``."""
    index: list[Any] = [slice(None)] * 3
    index[2 - axis_xyz] = k
    return arr[tuple(index)]


def _tap_weights(
    p: np.ndarray, radius: int, g: np.ndarray, seed: bool
) -> tuple[np.ndarray, np.ndarray]:
    f = np.floor(p)
    m = np.arange(2 * radius + 2)
    idx = (f[:, None] - radius + m[None, :]).astype(np.int64)
    if seed:
        x = idx - p[:, None]
        return idx, 0.3989422804014327 * np.exp(-0.5 * x * x)
    t = (p - f)[:, None]
    k = m - radius

    def gk(kk: np.ndarray) -> np.ndarray:
        ak = np.abs(kk)
        return np.where(ak <= radius, g[np.minimum(ak, radius)], 0.0)

    return idx, (1.0 - t) * gk(k)[None, :] + t * gk(k - 1)[None, :]


def _filter_slice(
    prev: np.ndarray, pu: np.ndarray, pv: np.ndarray, radius: int, g: np.ndarray, seed: bool
) -> np.ndarray:
    """Σ w_u w_v · prev over the (2R + 2)² taps around the crossings (pu × pv); 0 outside the
    slice. Separable: a u pass over all rows, then a v pass."""
    nv, nu = prev.shape
    iu, wu = _tap_weights(pu, radius, g, seed)
    iv, wv = _tap_weights(pv, radius, g, seed)
    rows = np.zeros((nv, pu.size))
    for m in range(iu.shape[1]):
        col = iu[:, m]
        ok = (col >= 0) & (col < nu)
        rows += prev[:, np.clip(col, 0, nu - 1)] * np.where(ok, wu[:, m], 0.0)[None, :]
    res = np.zeros((pv.size, pu.size))
    for m in range(iv.shape[1]):
        row = iv[:, m]
        ok = (row >= 0) & (row < nv)
        res += rows[np.clip(row, 0, nv - 1), :] * np.where(ok, wv[:, m], 0.0)[:, None]
    return res


def _inside(p: np.ndarray, n: int) -> np.ndarray:
    return (p >= 0.0) & (p <= n - 1)


def _between(
    plane_k: np.ndarray, plane_p: np.ndarray, pu: np.ndarray, pv: np.ndarray,
    lam: np.ndarray | float,
) -> np.ndarray:
    """s at in-plane points (pu, pv) a fraction ``lam`` of the way from slice k (``plane_k``,
    ``[v, u]``) to slice kp (``plane_p``): trilinear, 0 outside the grid (``sigmaBetween``)."""
    nv, nu = plane_k.shape
    iu = np.floor(pu).astype(np.int64)
    iv = np.floor(pv).astype(np.int64)
    tu = pu - iu
    tv = pv - iv
    res = np.zeros(np.shape(pu))
    for dv, wv in ((0, 1.0 - tv), (1, tv)):
        rv = iv + dv
        for du, wu in ((0, 1.0 - tu), (1, tu)):
            ru = iu + du
            ok = (rv >= 0) & (rv < nv) & (ru >= 0) & (ru < nu)
            r, c = np.clip(rv, 0, nv - 1), np.clip(ru, 0, nu - 1)
            vals = (1.0 - lam) * plane_k[r, c] + lam * plane_p[r, c]
            res += np.where(ok, vals, 0.0) * wv * wu
    return res


def _pyramid_mask(
    cu: np.ndarray, cv: np.ndarray, k: int, a: int, ua: int, va: int, vec: np.ndarray
) -> np.ndarray:
    """Cells of slice k whose largest |cell − light| component is along ``a`` (ties: lower
    axis wins), as in the compute shader."""
    da = abs(k - vec[a])
    du = np.abs(cu - vec[ua])[None, :]
    dv = np.abs(cv - vec[va])[:, None]

    def beats(d: np.ndarray, b: int) -> np.ndarray:
        return d < da if b < a else d <= da

    return beats(du, ua) & beats(dv, va)


# ---------------------------------------------------------------------------------------------
# GPU path
# ---------------------------------------------------------------------------------------------
class LightTexture(Texture3D):
    """Float 3D texture with one light per channel (1, 2 or 4 channels: R32F, RG32F, RGBA32F).

    Linear filtering; clamp to a border of 1 (unshadowed) so lookups that the offset pushes out
    of the volume see no shadow. ``shape`` is (nz, ny, nx); created filled with 1. A
    :class:`Texture3D` with more channels (so tools that scan a technique's textures see it).
    """

    _FORMATS: ClassVar[dict[int, str]] = {1: "GL_R32F", 2: "GL_RG32F", 4: "GL_RGBA32F"}
    _PIXEL: ClassVar[dict[int, str]] = {1: "GL_RED", 2: "GL_RG", 4: "GL_RGBA"}

    def __init__(
        self, render_window: vtk.vtkRenderWindow, shape_zyx: tuple[int, int, int], channels: int
    ) -> None:
        if channels not in self._FORMATS:
            raise ValueError(f"channels must be 1, 2 or 4, not {channels}")
        self.render_window = render_window
        self.shape = tuple(int(s) for s in shape_zyx)
        self.channels = channels
        self.mip_levels = 1
        tex = vtk.vtkTextureObject()
        tex.SetContext(render_window)
        tex.SetMinificationFilter(vtk.vtkTextureObject.Linear)
        tex.SetMagnificationFilter(vtk.vtkTextureObject.Linear)
        for set_wrap in (tex.SetWrapS, tex.SetWrapT, tex.SetWrapR):
            set_wrap(vtk.vtkTextureObject.ClampToBorder)
        tex.SetBorderColor(1.0, 1.0, 1.0, 1.0)
        nz, ny, nx = self.shape
        ones = np.ones((nz, ny, nx, channels), np.float32)
        if not tex.Create3DFromRaw(nx, ny, nz, channels, vtk.VTK_FLOAT, ones):
            raise GLUnavailableError(f"could not allocate a {nx}×{ny}×{nz}×{channels} texture")
        self.tex: vtk.vtkTextureObject | None = tex

    @property
    def gl_format(self) -> int:
        return getattr(gl(self.render_window), self._FORMATS[self.channels])

    def upload(self, data: np.ndarray, level: int = 0) -> None:
        """Replace the contents with ``data`` of shape (nz, ny, nx, channels)."""
        if level != 0:
            raise ValueError("the light volume has no mip levels")
        GL = gl(self.render_window)
        arr = np.ascontiguousarray(data, dtype=np.float32)
        if arr.shape != (*self.shape, self.channels):
            want = (*self.shape, self.channels)
            raise ValueError(f"light volume data shape {arr.shape} != {want}")
        self.activate()
        self.render_window.GetState().vtkglPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        nz, ny, nx = self.shape
        fmt = getattr(GL, self._PIXEL[self.channels])
        GL.glTexSubImage3D(GL.GL_TEXTURE_3D, 0, 0, 0, 0, nx, ny, nz, fmt, GL.GL_FLOAT, arr)

    def download(self, level: int = 0) -> np.ndarray:
        """Contents as (nz, ny, nx, channels) float32 (tests and verification)."""
        if level != 0:
            raise ValueError("the light volume has no mip levels")
        GL = gl(self.render_window)
        self.activate()
        GL.glFinish()
        out = np.empty((*self.shape, self.channels), np.float32)
        self.render_window.GetState().vtkglPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        fmt = getattr(GL, self._PIXEL[self.channels])
        GL.glGetTexImage(GL.GL_TEXTURE_3D, 0, fmt, GL.GL_FLOAT, out)
        return out

    def bind_image(self, unit: int, access: str = "write", level: int = 0) -> None:
        GL = gl(self.render_window)
        mode = {"read": GL.GL_READ_ONLY, "write": GL.GL_WRITE_ONLY, "readwrite": GL.GL_READ_WRITE}
        GL.glBindImageTexture(unit, self.handle, level, GL.GL_TRUE, 0, mode[access], self.gl_format)

    def generate_mipmaps(self) -> None:
        raise ValueError("the light volume has no mip levels")

    @property
    def nbytes(self) -> int:
        nz, ny, nx = self.shape
        return nz * ny * nx * self.channels * 4


class GpuPropagator:
    """Compute programs of shadow_volume_propagate.comp and their dispatch (GL context current).

    Programs are compiled on first use per variant (prefilter; propagate × model × channels ×
    filter radius × cells per invocation) and kept until :meth:`release`.
    """

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[tuple, ComputeProgram] = {}
        self._locations: dict[tuple[int, str], int] = {}
        self.program(("convert",))  # fail now, not mid-frame, when compute cannot work

    def program(self, key: tuple) -> ComputeProgram:
        prog = self._programs.get(key)
        if prog is None:
            if key[0] == "convert":
                defines = {"VV_PASS": 0}
            elif key[0] == "reduce":
                defines = {"VV_PASS": 2}
            else:
                defines = {
                    "VV_PASS": 1, "VV_SEED000": int(key[1]), "VV_CHANNELS": key[2],
                    "VV_RADIUS": key[3], "VV_BLOCK": key[4], "VV_GROUP_X": GROUP[0],
                    "VV_GROUP_Y": GROUP[1],
                }
            source = compute_source(COMPUTE_SOURCE, {k: str(v) for k, v in defines.items()},
                                    __package__)
            prog = ComputeProgram(self.render_window, source, f"shadow {key}")
            self._programs[key] = prog
        return prog

    def _set(self, prog: ComputeProgram, name: str, *values: float, integer: bool = True) -> None:
        GL = gl(self.render_window)
        handle = int(prog.prog.GetHandle())
        loc = self._locations.get((handle, name))
        if loc is None:
            loc = int(GL.glGetUniformLocation(handle, name))
            self._locations[(handle, name)] = loc
        if loc < 0:
            return  # optimised away
        fn = {1: "glUniform1", 2: "glUniform2", 3: "glUniform3"}[len(values)]
        getattr(GL, fn + ("i" if integer else "f"))(loc, *values)

    def prefilter(self, alpha: np.ndarray, sigma: Texture3D, grid: LightGrid) -> None:
        """TF opacity ``alpha`` (data resolution, ``[z, y, x]``) -> s on the light grid.

        Full resolution: uploaded into ``sigma`` itself and converted in place (no extra
        memory). Coarser grids: a temporary data-resolution texture, converted in place, then
        reduced by box averaging into ``sigma``.
        """
        GL = gl(self.render_window)
        full = grid.dims == grid.data_dims
        data = sigma if full else Texture3D(self.render_window, alpha.shape)
        try:
            data.upload(alpha)
            data.tex.Deactivate()  # upload() bound it to a unit; image units are separate
            prog = self.program(("convert",))
            prog.use()
            self._set(prog, "vv_volume", 0)
            self._set(prog, "vv_dataDims", *grid.data_dims)
            data.bind_image(0, "readwrite")
            nx, ny, nz = grid.data_dims
            prog.dispatch((-(-nx // 8), -(-ny // 8), -(-nz // 4)))
            if not full:
                prog = self.program(("reduce",))
                prog.use()
                self._set(prog, "vv_sigmaData", 0)
                self._set(prog, "vv_sigmaOut", 1)
                self._set(prog, "vv_dataDims", *grid.data_dims)
                self._set(prog, "vv_gridDims", *grid.dims)
                self._set(prog, "vv_gridStep", *grid.step, integer=False)
                data.bind_image(0, "read")
                sigma.bind_image(1, "write")
                mx, my, mz = grid.dims
                prog.dispatch((-(-mx // 8), -(-my // 8), -(-mz // 4)))
            self._unbind_images(GL, 2)
            prog.done()
        finally:
            if not full:
                data.release()

    def propagate(
        self, sigma: Texture3D, work: Mapping[int, Texture3D], out: LightTexture,
        grid: LightGrid, kind: str, vec: np.ndarray, *, model: str, softness: float,
        unit_distance: float, channel: int,
    ) -> None:
        """All passes of one light into channel ``channel`` of ``out``; ``work`` holds one
        2-layer slice texture per propagation axis."""
        GL = gl(self.render_window)
        seed = model == "seed000"
        radius, g = (SEED000_RADIUS, np.ones(1)) if seed else gauss_taps(softness)
        block = 1 if kind == "point" else BLOCK
        prog = self.program(("propagate", seed, out.channels, radius, block))
        program = prog.use()
        self._set(prog, "vv_sigma", 0)
        self._set(prog, "vv_work", 1)
        self._set(prog, "vv_out", 2)
        self._set(prog, "vv_dims", *grid.dims)
        self._set(prog, "vv_point", int(kind == "point"))
        self._set(prog, "vv_light", *(float(c) for c in vec), integer=False)
        self._set(prog, "vv_cellUm", *grid.cell_um, integer=False)
        self._set(prog, "vv_invUnit", 1.0 / unit_distance, integer=False)
        self._set(prog, "vv_radius", radius)
        self._set(prog, "vv_channel", channel)
        program.SetUniform1fv("vv_gauss", radius + 1, [float(x) for x in g])
        sigma.bind_image(0, "read")
        out.bind_image(2, "write" if out.channels == 1 else "readwrite")
        barrier = GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT
        slice_loc = self._location(prog, "vv_slice")
        first_loc = self._location(prog, "vv_first")
        for p in plan_passes(grid.dims, kind, vec):
            a = p.axis
            ua, va = in_plane_axes(a)
            columns = -(-grid.dims[ua] // block)
            groups = (-(-columns // GROUP[0]), -(-grid.dims[va] // GROUP[1]), 1)
            work[a].bind_image(1, "readwrite")
            self._set(prog, "vv_axis", a)
            self._set(prog, "vv_sweep", p.sweep)
            self._set(prog, "vv_restrict", int(p.restrict))
            for index, k in enumerate(p.slices):
                GL.glUniform1i(slice_loc, k)
                GL.glUniform1i(first_loc, int(index == 0))
                GL.glDispatchCompute(*groups)
                GL.glMemoryBarrier(barrier)
        GL.glMemoryBarrier(GL.GL_TEXTURE_FETCH_BARRIER_BIT | GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT)
        self._unbind_images(GL, 3)
        prog.done()

    def _location(self, prog: ComputeProgram, name: str) -> int:
        self._set(prog, name, 0)  # caches the location
        return self._locations[(int(prog.prog.GetHandle()), name)]

    @staticmethod
    def _unbind_images(GL: Any, count: int) -> None:
        for unit in range(count):
            GL.glBindImageTexture(unit, 0, 0, GL.GL_FALSE, 0, GL.GL_READ_ONLY, GL.GL_R32F)

    def release(self) -> None:
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
        self._locations.clear()
