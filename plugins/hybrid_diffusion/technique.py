"""Hybrid diffusion (seed 003 HD), engine part: the direct light's running mean ρ_d and the
diffused light ρ_s, on the GPU (the engine's ``tracker.comp.glsl`` and diffusion)
or in numpy (:mod:`.cpu`). Restarts like every progressive technique: on opacity, light,
material and ACCUMULATION-parameter changes, never on camera moves.

HD is seed 003's KD with the convection replaced by tracking; the grid, extinction and both
diffusion models are the engine's (:mod:`vtkvol.engine.diffusion`), shared with KD. ``source``:
each iteration adds one sample to ρ_d and runs ``diffusion_steps`` Jacobi sweeps of the source
model with E_0 = ρ_d; the last iteration (sample ``max_iterations``) sweeps on until the residual
tolerance, so the result is final exactly when the samples are.
``published``: the explicit step ρ_s ← ρ_s + λ∇²(ρ_d + ρ_s) in a separate volume (§3.3).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk

from vtkvol.engine import diffusion as kd
from vtkvol.engine.coarse_diffusion import ScatterGrid
from vtkvol.engine.diffusion import (
    GROUP,
    GpuDiffusion,
    GpuSourceDiffusion,
    GridScattering,
    relative_residual,
)
from vtkvol.engine.gl import ComputeProgram, GLUnavailableError, Texture3D
from vtkvol.engine.technique import finish_gl
from vtkvol.engine.traced_orders import RGB_AS_LIGHTS, RGB_LIGHTS, GpuTracker
from vtkvol.plugins.hybrid_diffusion import TECHNIQUE, cpu

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

#: Source model: sweeps between residual checks after the last sample, and their cap (a
#: safety bound only: Jacobi on this M-matrix converges; 64³ thin media need ~10³ sweeps).
FINISH_BATCH = 16
MAX_FINISHING_SWEEPS = 100000


class Setup:
    """What one accumulation runs on (dataset space, µm). ``scatter``: the grid the scattered
    light is solved on (the data grid, or the source model's reduced ``scatter_grid`` with its
    own ``scatter_coefficients``)."""

    def __init__(self, grid: kd.Grid, sigma_t: np.ndarray, lights: list[kd.LightSource],
                 colors: list[tuple[float, float, float]], lam: np.ndarray, model: str = "source",
                 coefficients: np.ndarray | None = None,
                 bricks: np.ndarray | None = None, scatter: ScatterGrid | None = None,
                 scatter_coefficients: np.ndarray | None = None,
                 unit_distance: float | None = None, orders: int = 0,
                 albedo: float = 1.0, phase_g: float = 0.0) -> None:
        self.grid, self.sigma_t, self.lights, self.colors, self.lam = (
            grid, sigma_t, lights, colors, lam)
        #: The opacity's unit distance (µm): the tracker samples the extinction of the
        #: interpolated opacity (:func:`.cpu.extinction_at`); None: σ_t interpolated linearly.
        self.unit_distance = unit_distance
        self.model, self.coefficients = model, coefficients
        #: The per-brick majorant grid (``majorant = "bricks"``), None for the global one.
        self.bricks = bricks
        self.scatter = scatter if scatter is not None else ScatterGrid(grid, 1)
        self.scatter_coefficients = scatter_coefficients
        #: Scattering orders traced per voxel before the diffusion (source model only; 0:
        #: the diffusion's source is the direct light), and the material they scatter in.
        self.orders = orders if model == "source" else 0
        self.albedo, self.phase_g = albedo, phase_g

    @property
    def solve(self) -> tuple[kd.Grid, np.ndarray]:
        """(grid, coefficients) the source model's sweeps run on."""
        if self.scatter.coarse:
            assert self.scatter_coefficients is not None
            return self.scatter.grid, self.scatter_coefficients
        assert self.coefficients is not None
        return self.grid, self.coefficients

    @classmethod
    def build(cls, grid: kd.Grid, sigma_t: np.ndarray, specs: list[Any],
              albedo: float, model: str = "source", phase_g: float = 0.0,
              majorant: str = "global", scatter_grid: str = "full",
              coefficients: np.ndarray | None = None, lam: np.ndarray | None = None,
              unit_distance: float | None = None, orders: int = 0) -> Setup:
        """``coefficients`` and ``lam``: the per-voxel arrays when already computed (a restart
        builds them in z slabs, :meth:`HybridDiffusion._stages`), else computed here."""
        specs = specs[:4]
        lights = [
            kd.LightSource(s.kind, tuple(float(v) for v in (
                s.vector if s.kind == "point" else cpu.unit(s.vector))),
                float(getattr(s, "falloff_distance", 0.0)), float(getattr(s, "size", 0.0)))
            for s in specs
        ]
        colors = [tuple(float(c) for c in getattr(s, "color", (1.0, 1.0, 1.0))) for s in specs]
        if model == "source" and coefficients is None:
            coefficients = kd.source_coefficients(sigma_t, grid, albedo, phase_g)
        bricks = cpu.brick_majorants(sigma_t) if majorant == "bricks" else None
        if lam is None:
            lam = kd.diffusion_rate(sigma_t, grid, albedo)
        # The published model's scattered volume stays on the data grid.
        scatter = ScatterGrid.named(grid, scatter_grid if model == "source" else "full")
        scatter_coefficients = (scatter.coefficients(sigma_t, albedo, phase_g)
                                if scatter.coarse else None)
        return cls(grid, sigma_t, lights, colors, lam, model,
                   coefficients if model == "source" else None, bricks, scatter,
                   scatter_coefficients, unit_distance, orders, albedo, phase_g)


class HybridDiffusion(GridScattering):
    """Tracked direct light plus diffused multiple scattering, refined over frames. Its own
    :meth:`prepare` and :meth:`_restart` (the restart in parts, :meth:`_stages`) replace the
    base class's one-step restart (``build_setup``/``start_gpu`` are not used)."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "hybrid_diffusion.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._rho_d: np.ndarray | None = None  # numpy path state
        self._rho_s: np.ndarray | None = None
        #: Numpy path, traced orders: running means of E_1 + … + E_k and of E_k (rgb).
        self._traced: np.ndarray | None = None
        self._last: np.ndarray | None = None
        #: Numpy path: the traced orders' texture the shader samples.
        self._traced_texture: Texture3D | None = None
        #: Source model, numpy path: q (restricted to the scatter grid) of the current ρ_d.
        self._q: np.ndarray | None = None
        #: The current sample's next region's first (z layer, y row): not (0, 0) while a
        #: sample is drawn in parts.
        self._next_region = (0, 0)
        #: Measured cost (ms) of one row (a y line of one z layer) of one sample: sizes the
        #: next region.
        self._row_ms: float | None = None
        #: The same per slab of 4 z layers (its index z // 4), as last measured there.
        self._row_ms_at: dict[int, float] = {}
        #: The restart under way in parts (z slabs of the per-voxel arrays, then the state):
        #: None when none is; meanwhile the previous accumulation's light stays shown.
        self._staging: Iterator[None] | None = None
        #: Measured cost (ms) of one z layer of the restart's per-voxel arrays and uploads.
        self._stage_layer_ms: float | None = None
        #: Diffusion sweeps left in the current unit (a complete sample's ``diffusion_steps``,
        #: or a finishing batch of ``FINISH_BATCH``); ``_sweep_z``: the current sweep's next
        #: z layer; ``_sweep_of_sample``: the unit ends a sample (the iteration advances).
        self._sweeps_left = 0
        self._sweep_z = 0
        self._sweep_of_sample = False
        #: Measured cost (ms) of one z layer of one diffusion sweep (GPU source model).
        self._sweep_layer_ms: float | None = None
        #: The GPU source model's (Σ residual², Σ source²) per z layer of the current unit's
        #: last sweep, read back slab by slab.
        self._residual_layers = np.zeros((2, 0))
        #: Finishing batches run in this accumulation (bounded by ``MAX_FINISHING_SWEEPS``).
        self._finish_batches = 0
        #: Zero light shown while the first restart is under way (nothing computed yet).
        self._placeholder: Texture3D | None = None
        self._frame_t0 = 0.0
        #: Voxel updates of the last frame: per-voxel arrays of a restart, sampled voxels,
        #: swept voxels (work counted in units, not time: tests bound it under a budget).
        self.last_work_voxels = 0

    def make_driver(self, window: vtk.vtkRenderWindow) -> GpuHybrid:
        return GpuHybrid(window)

    def start_cpu(self, values: Mapping[str, Any]) -> None:
        assert self.setup is not None
        shape = self.setup.grid.shape_zyx
        self._rho_d = np.zeros((*shape, 3), np.float32)
        self._rho_s = np.zeros((*self.setup.scatter.grid.shape_zyx, 3), np.float32)
        self._traced = np.zeros((*shape, 3), np.float32) if self.setup.orders else None
        self._last = np.zeros((*shape, 3), np.float32) if self.setup.orders else None
        self._q = None
        self._upload_cpu_state()

    # -- the frame: a restart in parts, then the samples ----------------------------------------
    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        """A restart (on ``reset_accumulation``) is built in parts under the host's work
        budget — z slabs of the per-voxel arrays and their uploads, then the zeroed state —
        while the previous accumulation's light stays shown; then this frame's samples."""
        self._frame_t0 = time.perf_counter()
        self.last_work_voxels = 0
        if changes.reset_accumulation or (self.setup is None and self._staging is None):
            self._restart(values)
        staged = self._staging is not None
        if staged:
            self._stage()
        budget = self.host.work_budget_ms
        if self._staging is None and not (staged and budget is not None
                                          and self._spent_ms() >= budget):
            self.advance(values)
        self._bind_shown()

    def _restart(self, values: Mapping[str, Any]) -> None:
        """Begin a new accumulation: its setup is built by :meth:`_stages` (all of it now
        without a work budget)."""
        self._next_region = (0, 0)  # a new accumulation draws its first sample from (0, 0)
        self._sweeps_left = self._sweep_z = self._finish_batches = 0
        self.iteration = 0
        self.residual = float("inf")
        self.converged = False
        self._restarts += 1
        self._staging = self._stages(dict(values))

    @property
    def restarting(self) -> bool:
        """A restart is being built in parts (the previous light is shown meanwhile)."""
        return self._staging is not None

    def _spent_ms(self) -> float:
        return (time.perf_counter() - self._frame_t0) * 1e3

    def _stage(self) -> None:
        """Run the restart's parts while the budget lasts (at least one part a frame)."""
        budget = self.host.work_budget_ms
        worked = False
        while self._staging is not None:
            if budget is not None and worked and self._spent_ms() >= budget:
                return
            worked = True
            try:
                next(self._staging)
            except StopIteration:
                self._staging = None

    def _stages(self, values: Mapping[str, Any]) -> Iterator[None]:
        """The restart, one part per step: extinction, diffusion rate and (source model)
        coefficients of z slabs — each voxel's values depend on that voxel only, so slabs add
        up to the whole-grid arrays bit for bit — uploaded slab by slab on the GPU path (into
        the previous storage when the grid is unchanged); then the brick majorants and the
        zeroed state. A slab is as many layers (a multiple of 4) as the budget left allows at
        the measured cost per layer, at least 4."""
        host = self.host
        nx, ny, nz = host.dims
        grid = kd.Grid((nz, ny, nx), host.spacing, self._origin())
        model = str(values["diffusion_model"])
        # A reduced scatter grid's coefficients are built whole at the end (a restriction of
        # every slab's σ_t); the data grid's coefficients go up slab by slab.
        coarse = model == "source" and str(values["scatter_grid"]) != "full"
        opacity = host.opacity_volume()
        sigma_t = np.empty((nz, ny, nx), np.float32)
        lam = np.empty_like(sigma_t)
        coefficients = np.empty((nz, ny, nx, 4), np.float32) if model == "source" else None
        had_driver = self._gpu is not None
        gpu: GpuHybrid | None = self._compute.get(host, values["backend"])
        if gpu is not None and not had_driver:
            yield  # the driver was made now: compute checked, a program compiled
        if gpu is not None:
            yield from self._gl_steps(gpu.input_steps(grid.shape_zyx, model, coarse))
            gpu = self._gpu
        budget = host.work_budget_ms
        z0 = 0
        while z0 < nz:
            layers = nz
            if budget is not None:
                left = max(budget - self._spent_ms(), 0.0)
                fit = (GROUP[2] if self._stage_layer_ms is None
                       else int(left / max(self._stage_layer_ms, 1e-6)))
                layers = max(GROUP[2], fit // GROUP[2] * GROUP[2])
            z1 = min(nz, z0 + layers)
            t0 = time.perf_counter()
            sigma_t[z0:z1] = kd.extinction(opacity[z0:z1], host.unit_distance)
            lam[z0:z1] = kd.diffusion_rate(sigma_t[z0:z1], grid, host.albedo)
            if coefficients is not None:
                coefficients[z0:z1] = kd.source_coefficients(sigma_t[z0:z1], grid, host.albedo,
                                                             host.phase_g)
            if gpu is not None:
                slab = (sigma_t[z0:z1],
                        None if coefficients is None or coarse else coefficients[z0:z1])
                gpu = self._gl(gpu.upload_slab, *slab, z0)
                if gpu is not None and budget is not None:
                    finish_gl(host.render_window)  # the cost must be measured, not queued
            self._stage_layer_ms = (time.perf_counter() - t0) * 1e3 / (z1 - z0)
            self.last_work_voxels += (z1 - z0) * ny * nx
            z0 = z1
            yield
        self.setup = Setup.build(grid, sigma_t, host.light_specs(), host.albedo, model,
                                 host.phase_g, str(values["majorant"]),
                                 str(values["scatter_grid"]), coefficients=coefficients,
                                 lam=lam, unit_distance=host.unit_distance,
                                 # diffusion_steps 0 is the direct light alone: no orders
                                 orders=(int(values["traced_orders"])
                                         if int(values["diffusion_steps"]) > 0 else 0))
        if gpu is not None:
            yield from self._gl_steps(gpu.state_steps(self.setup))
            gpu = self._gpu
        if gpu is not None:
            gpu = self._gl(gpu.finish, self.setup)
        if gpu is not None:
            self._backend = "gpu"
        else:
            self.start_cpu(values)
            self._backend = "cpu"

    def _gl_steps(self, steps: Iterator[None]) -> Iterator[None]:
        """The GPU driver's ``steps``, ended by a GL failure (numpy from then on)."""
        try:
            yield from steps
        except GLUnavailableError as exc:
            self._compute.disable(exc)

    def _gl(self, call: Callable[..., None], *args: Any) -> GpuHybrid | None:
        """``call(*args)`` of the GPU driver: the driver, or None after a GL failure (numpy
        from then on, as a failed restart on the GPU does)."""
        try:
            call(*args)
        except GLUnavailableError as exc:
            self._compute.disable(exc)
            return None
        return self._gpu

    def _bind_shown(self) -> None:
        """What the shader samples: the accumulation's light; during a restart in parts the
        previous accumulation's (a zero light before the first is ready)."""
        gpu = self._gpu
        if self._staging is None:
            self._bind(gpu.shown if gpu is not None else None)
        elif gpu is not None and gpu.ready:
            self._bind(gpu.shown)
        elif gpu is None and self._direct is not None and self._scattered is not None:
            self._bind(None)
        else:
            zero = self._zero_texel()
            self._bind((zero, zero))

    def _bind(self, gpu_textures: tuple[Texture3D, Texture3D] | None) -> None:
        """The direct and scattered light (the base class's), and the traced orders' light
        ``vv_hybrid_diffusion_traced`` (a zero texel when none is traced)."""
        super()._bind(gpu_textures)
        gpu = self._gpu
        traced = gpu.traced if gpu is not None else self._traced_texture
        if traced is None or (gpu_textures is not None
                              and gpu_textures[0] is self._placeholder):
            traced = self._zero_texel()
        self.host.bind_texture(f"vv_{self.NAME}_traced", traced)

    def _zero_texel(self) -> Texture3D:
        """A 1³ zero RGBA texture: what is shown before anything is computed."""
        if self._placeholder is None:
            self._placeholder = Texture3D(self.host.render_window, (1, 1, 1), channels=4,
                                          data=np.zeros((1, 1, 1, 4), np.float32))
        return self._placeholder

    def advance(self, values: Mapping[str, Any]) -> None:
        """Up to ``iterations_per_frame`` samples before this frame. With the host's
        :attr:`~vtkvol.engine.technique.TechniqueHost.work_budget_ms` (the app sets one), the
        work stops once the budget is spent: a sample is drawn in z slabs or y bands sized
        from the measured cost per row, each diffusion sweep (GPU source model) in z slabs
        sized from the measured cost per layer, the finishing sweeps in the same batches as
        without a budget, each resumed next frame — one frame never holds the event loop for
        a whole sample or a whole sweep."""
        assert self.setup is not None
        samples = int(values["max_iterations"])
        count = min(int(values["iterations_per_frame"]), samples - self.iteration)
        budget = self.host.work_budget_ms
        t0 = time.perf_counter()
        worked = False
        done = 0
        while True:
            spent = (time.perf_counter() - t0) * 1e3
            if budget is not None and worked and spent >= budget:
                break
            left = None if budget is None else max(budget - spent, 0.0)
            if self._sweeps_left:
                if self._sweep_part(values, left) and self._sweep_of_sample:
                    done += 1
            elif done < count and self.iteration < samples:
                if self._sample_region(values, left):
                    done += 1
            elif self._finishing(values) and self._finish_batches < MAX_FINISHING_SWEEPS:
                self._finish_batches += 1
                self._sweeps_left, self._sweep_of_sample = FINISH_BATCH, False
                continue
            else:
                break
            worked = True
        if worked:
            if self._gpu is None:
                self._upload_cpu_state()
            self._last_ms = (time.perf_counter() - t0) * 1e3
        self.converged = (self.iteration >= samples and not self._sweeps_left
                          and not (self._finishing(values)
                                   and self._finish_batches < MAX_FINISHING_SWEEPS))

    def _finishing(self, values: Mapping[str, Any]) -> bool:
        """All samples are drawn and the source model's sweeps have not reached the tolerance."""
        setup = self.setup
        assert setup is not None
        return (self.iteration >= int(values["max_iterations"]) and setup.model == "source"
                and int(values["diffusion_steps"]) > 0
                and self.residual >= float(values["tolerance"]))

    def _sample_region(self, values: Mapping[str, Any], budget_ms: float | None) -> bool:
        """Draw the current sample's next region (all of it without a budget, else what
        ``budget_ms`` allows at the measured cost per row — one y line of one z layer): whole
        slabs of z layers while they fit, else bands of y rows of one slab, at least one work
        group (4 layers × 8 rows). When the sample is complete its ``diffusion_steps`` sweeps
        follow (:meth:`_sweep_part`); True when the iteration advanced (no sweeps)."""
        setup = self.setup
        assert setup is not None
        nz, ny, nx = setup.grid.shape_zyx
        z0, y0 = self._next_region
        if budget_ms is None:
            region = (0, nz, 0, ny)
        else:
            # The cost per row differs along z (paths towards the light differ in length):
            # each slab of 4 layers is sized at its own cost in the last sample.
            def row_ms(z: int) -> float | None:
                return self._row_ms_at.get(z // GROUP[2], self._row_ms)

            layers, spent = 0, 0.0
            while y0 == 0 and z0 + layers < nz:
                cost = row_ms(z0 + layers)
                slab_ms = None if cost is None else cost * ny * GROUP[2]
                if slab_ms is None or spent + slab_ms > budget_ms:
                    break
                spent += slab_ms
                layers += GROUP[2]
            if layers:  # whole slabs
                region = (z0, min(nz, z0 + layers), 0, ny)
            else:  # a band of rows of one slab
                cost = row_ms(z0)
                fit = (GROUP[1] * GROUP[2] if cost is None
                       else int(budget_ms / max(cost, 1e-6)))
                z1 = min(nz, z0 + GROUP[2])
                rows = max(GROUP[1], fit // (z1 - z0) // GROUP[1] * GROUP[1])
                region = (z0, z1, y0, min(ny, y0 + rows))
        t0 = time.perf_counter()
        if self._gpu is not None:
            self._gpu.sample(self.iteration, values, region)
            if budget_ms is not None:
                finish_gl(self.host.render_window)  # the cost must be measured, not queued
        else:
            self._sample_cpu(values, region)
        z0, z1, y0, y1 = region
        self._row_ms = (time.perf_counter() - t0) * 1e3 / ((z1 - z0) * (y1 - y0))
        for group in range(z0 // GROUP[2], -(-z1 // GROUP[2])):
            self._row_ms_at[group] = self._row_ms
        self.last_work_voxels += (z1 - z0) * (y1 - y0) * nx
        if y1 < ny:
            self._next_region = (z0, y1)
            return False
        self._next_region = (z1, 0) if z1 < nz else (0, 0)
        if z1 < nz:
            return False
        self._sweeps_left, self._sweep_z = int(values["diffusion_steps"]), 0
        self._sweep_of_sample = True
        if not self._sweeps_left:
            self.iteration += 1
            return True
        return False

    def _sweep_part(self, values: Mapping[str, Any], budget_ms: float | None) -> bool:
        """The next part of the current unit of diffusion sweeps: on the GPU with the source
        model a z slab of one sweep (as many layers as ``budget_ms`` allows at the measured
        cost per layer, a multiple of 4, at least 4; the whole grid without a budget), else
        one whole sweep. True when the unit is complete: the residual is then read (GPU)
        and, after a sample's sweeps, the iteration advances."""
        setup = self.setup
        assert setup is not None
        nz, ny, nx = setup.scatter.grid.shape_zyx  # the grid the scattered light is solved on
        gpu = self._gpu
        if gpu is not None and setup.model == "source":
            z0, z1 = self._sweep_z, nz
            if z0 == 0:
                gpu.restrict_source()
            if self._residual_layers.shape != (2, nz):
                self._residual_layers = np.zeros((2, nz))
            if budget_ms is not None:
                fit = (GROUP[2] if self._sweep_layer_ms is None
                       else int(budget_ms / max(self._sweep_layer_ms, 1e-6)))
                z1 = min(nz, z0 + max(GROUP[2], fit // GROUP[2] * GROUP[2]))
            t0 = time.perf_counter()
            gpu.source.sweep_slab(gpu.source_light, RGB_AS_LIGHTS, z0, z1)
            if budget_ms is not None:
                finish_gl(self.host.render_window)
            if self._sweeps_left == 1:  # the unit's last sweep: its residual, slab by slab
                r2, q2 = gpu.source.residual_layers(z0, z1)
                self._residual_layers[:, z0:z1] = r2, q2
            self._sweep_layer_ms = (time.perf_counter() - t0) * 1e3 / (z1 - z0)
            self.last_work_voxels += (z1 - z0) * ny * nx
            if z1 < nz:
                self._sweep_z = z1
                return False
            gpu.source.swap()
            self._sweep_z = 0
        else:
            self._whole_sweep(values)
            self.last_work_voxels += nz * ny * nx
        self._sweeps_left -= 1
        if self._sweeps_left:
            return False
        if gpu is not None and setup.model == "source":
            # layer sums added in z order: the same total however the sweep was cut
            r2, q2 = self._residual_layers.sum(axis=1)
            self.residual = relative_residual(float(r2), float(q2))
        if self._sweep_of_sample:
            self.iteration += 1
        return True

    def release(self) -> None:
        super().release()
        self._rho_d = self._rho_s = self._q = self._traced = self._last = None
        if self._traced_texture is not None:
            self._traced_texture.release()
            self._traced_texture = None
        self._staging = None
        if self._placeholder is not None:
            self._placeholder.release()
            self._placeholder = None

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """The tracked transmittance towards ``light`` alone, averaged over ``max_iterations``
        samples per voxel (default parameters: 256), ``[z, y, x]`` in 0…1."""
        merged = {**self.defaults(), **values}
        grid = kd.Grid(opacity.shape, spacing, self._origin())
        sigma_t = kd.extinction(opacity, self.host.unit_distance)
        setup = Setup.build(grid, sigma_t, [light], self.host.albedo,
                            majorant=str(merged["majorant"]),
                            unit_distance=self.host.unit_distance)
        mean = np.zeros((*grid.shape_zyx, 3), np.float32)
        for k in range(int(merged["max_iterations"])):
            sample = cpu.direct_sample(sigma_t, grid, setup.lights, [(1.0, 1.0, 1.0)],
                                       bricks=setup.bricks,
                                       iteration=k, seed=int(merged["seed"]),
                                       estimator=merged["estimator"], light_sampling="all",
                                       unit_distance=setup.unit_distance)
            mean += (sample - mean) / np.float32(k + 1)
        return mean[..., 0]

    # -- internals ----------------------------------------------------------------------------
    def _sample_cpu(self, values: Mapping[str, Any],
                    region: tuple[int, int, int, int]) -> None:
        """The numpy path's sample ``iteration`` of the direct light in ``region`` (z0, z1,
        y0, y1), into the running mean ρ_d."""
        setup = self.setup
        assert setup is not None and self._rho_d is not None
        z0, z1, y0, y1 = region
        draw = cpu.direct_sample(
            setup.sigma_t, setup.grid, setup.lights, setup.colors, iteration=self.iteration,
            seed=int(values["seed"]), estimator=values["estimator"],
            light_sampling=values["light_sampling"], region=region, bricks=setup.bricks,
            unit_distance=setup.unit_distance,
        )
        weight = np.float32(1.0 / (self.iteration + 1))
        mean = self._rho_d[z0:z1, y0:y1]
        self._rho_d[z0:z1, y0:y1] = mean + (draw[z0:z1, y0:y1] - mean) * weight
        if setup.orders:
            assert self._traced is not None and self._last is not None
            traced, last = cpu.traced_orders_sample(setup, region, self.iteration,
                                                    int(values["seed"]))
            for field, draw_orders in ((self._traced, traced), (self._last, last)):
                mean = field[z0:z1, y0:y1]
                field[z0:z1, y0:y1] = mean + (draw_orders - mean) * weight
        self._q = None  # ρ_d changed: the source model's q is stale

    def _whole_sweep(self, values: Mapping[str, Any]) -> None:
        """One whole-grid diffusion step of the model: the numpy path's (source or published)
        or the GPU's published explicit step (the GPU source model sweeps in slabs)."""
        setup = self.setup
        assert setup is not None
        gpu = self._gpu
        if gpu is not None:
            gpu.diffusion.run(gpu.rho_d, RGB_AS_LIGHTS, 1)
            return
        assert self._rho_d is not None and self._rho_s is not None
        if setup.model == "source":
            assert setup.coefficients is not None
            if self._q is None:  # after a sample; the finishing sweeps reuse it
                # the diffusion carries on from the last traced order (or the direct light)
                light = self._last if setup.orders else self._rho_d
                assert light is not None
                self._q = setup.scatter.restrict(kd.source_term(
                    setup.coefficients, np.moveaxis(light, -1, 0), RGB_AS_LIGHTS, [1.0] * 3))
            grid, coefficients = setup.solve
            new, r2, q2 = kd.jacobi_sweep(self._rho_s, self._q, coefficients, grid)
            self.residual = relative_residual(r2, q2)
            self._rho_s = new
            return
        self._rho_s = kd.diffusion_step(self._rho_d + self._rho_s, self._rho_s, setup.lam,
                                        setup.grid)

    def _upload_cpu_state(self) -> None:
        assert self._rho_d is not None and self._rho_s is not None
        self._direct = self._show(self._direct, _rgba(self._rho_d), 4)
        self._scattered = self._show(self._scattered, _rgba(self._rho_s), 4)
        if self._traced is not None:
            self._traced_texture = self._show(self._traced_texture, _rgba(self._traced), 4)
        elif self._traced_texture is not None:
            self._traced_texture.release()
            self._traced_texture = None


def _rgba(rgb: np.ndarray) -> np.ndarray:
    """``[z, y, x, 3]`` → ``[z, y, x, 4]`` float32 with alpha 0 (the textures are RGBA)."""
    rgba = np.zeros((*rgb.shape[:3], 4), np.float32)
    rgba[..., :3] = rgb
    return rgba


class GpuHybrid:
    """The compute path: ρ_d updated in place (each invocation owns its voxel), σ_t as an image,
    and the engine's diffusion: the source model from ρ_d, or the published explicit step on
    ρ_d + ρ_s."""

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        #: The engine's tracker (direct light and traced orders, ``tracker.comp.glsl``).
        self.tracker = GpuTracker(render_window, "hybrid")
        self.rho_d: Texture3D | None = None  # type: ignore[assignment]
        #: Traced orders (source model): running means of E_1 + … + E_k (shown) and of E_k
        #: (the diffusion's source), RGBA on the data grid; None without traced orders.
        self.traced: Texture3D | None = None
        self._last: Texture3D | None = None
        self._sigma: Texture3D | None = None
        self._bricks: Texture3D | None = None
        self.diffusion = GpuDiffusion(render_window)
        self.source = GpuSourceDiffusion(render_window)
        self._setup: Setup | None = None
        #: A sample changed ρ_d since the source model last read it (its q is stale).
        self._sampled = True
        self.program("ratio", "one", False)  # fail now, not mid-frame, when compute cannot work

    @property
    def textures(self) -> list[Texture3D]:
        own = [t for t in (self.rho_d, self.traced, self._last, self._sigma, self._bricks)
               if t is not None]
        return own + self.diffusion.textures + self.source.textures

    @property
    def shown(self) -> tuple[Texture3D, Texture3D]:
        """(ρ_d, ρ_s): what the shader samples as the direct and the scattered light."""
        assert self.rho_d is not None
        return self.rho_d, self.rho_s

    @property
    def rho_s(self) -> Texture3D:
        """The scattered light of the accumulation's model."""
        assert self._setup is not None
        return self.source.phi if self._setup.model == "source" else self.diffusion.rho_s

    @property
    def source_light(self) -> Texture3D:
        """What the source model's diffusion starts from: E_k of the last traced order, or
        the direct light ρ_d without traced orders."""
        light = self._last if self._last is not None else self.rho_d
        assert light is not None
        return light

    def program(self, estimator: str, light_sampling: str, bricks: bool,
                orders: int = 0) -> ComputeProgram:
        """The engine's tracker with the direct light (``tracker.comp.glsl``) in this variant."""
        return self.tracker.program(direct=True, orders=orders, estimator=estimator,
                                    light_sampling=light_sampling, bricks=bricks)

    @property
    def ready(self) -> bool:
        """An accumulation's light is there to show (a restart has finished once)."""
        return self._setup is not None and self.rho_d is not None

    def input_steps(self, shape: tuple[int, int, int], model: str,
                    coarse: bool = False) -> Iterator[None]:
        """Storage for a restart's per-voxel inputs (σ_t, the source model's coefficients on
        the data grid unless they are a ``coarse`` scatter grid's, which :meth:`finish` uploads
        whole) on a ``shape`` grid, one new texture a step (none when the grid is unchanged:
        kept); the light shown is not touched. :meth:`upload_slab` fills them, :meth:`finish`
        ends."""
        if not kd.fits(self._sigma, shape, 1):
            self._sigma = kd.storage(self._sigma, self.render_window, shape, 1)
            yield
        if model == "source" and not coarse and not kd.fits(self.source.coefficients, shape, 4):
            self.source.allocate_coefficients(shape)
            yield

    def state_steps(self, setup: Setup) -> Iterator[None]:
        """New storage for ρ_d and the source model's φ where the grid's shape differs, one
        texture a step; :attr:`ready` is False from the first (nothing consistent to show)
        until :meth:`finish`."""
        shape = setup.grid.shape_zyx
        if not kd.fits(self.rho_d, shape, 4):
            self._setup = None
            self.rho_d = kd.storage(self.rho_d, self.render_window, shape, 4)
            yield
        if setup.orders:
            for name in ("traced", "_last"):
                if not kd.fits(getattr(self, name), shape, 4):
                    self._setup = None
                    setattr(self, name, kd.storage(getattr(self, name), self.render_window,
                                                   shape, 4))
                    yield
        if setup.model == "source":
            for _ in self.source.allocation_steps(setup.scatter.grid.shape_zyx):
                self._setup = None
                yield

    def upload_slab(self, sigma_t: np.ndarray, coefficients: np.ndarray | None,
                    z0: int) -> None:
        """σ_t (and the source model's coefficients) of layers z0… ."""
        assert self._sigma is not None
        self._sigma.upload_slab(sigma_t, z0)
        self._sigma.tex.Deactivate()  # image units, not texture units
        if coefficients is not None:
            self.source.upload_coefficients(coefficients, z0)

    def finish(self, setup: Setup) -> None:
        """The restart's end: brick majorants, ρ_d and the model's scattered light zeroed."""
        rw = self.render_window
        shape = setup.grid.shape_zyx
        if self._bricks is not None:
            self._bricks.release()
            self._bricks = None
        if setup.bricks is not None:
            self._bricks = Texture3D(rw, setup.bricks.shape, data=setup.bricks)
            self._bricks.tex.Deactivate()
        self.rho_d = kd.storage(self.rho_d, rw, shape, 4, zero=True)
        if setup.orders:
            self.traced = kd.storage(self.traced, rw, shape, 4, zero=True)
            self._last = kd.storage(self._last, rw, shape, 4, zero=True)
        else:
            for tex in (self.traced, self._last):
                if tex is not None:
                    tex.release()
            self.traced = self._last = None
        # The other model's storage goes (a switch of diffusion_model).
        if setup.model == "source":
            if self.diffusion.textures:
                self.diffusion.release()
            # ρ_d's r, g, b as three "lights"; their fall-off is in the tracked samples already.
            lights = list(RGB_LIGHTS)
            if setup.scatter.coarse:  # the sweeps' coefficients are the coarse cells'
                _grid, coarse = setup.solve
                self.source.allocate_coefficients(coarse.shape[:3])
                self.source.upload_coefficients(coarse, 0)
                assert setup.coefficients is not None
                self.source.zero(setup.grid, 4, lights, setup.scatter,
                                 fine_sigma_s=setup.coefficients[..., 2])
            else:
                self.source.zero(setup.grid, 4, lights)
            self._sampled = True
        else:
            if self.source.textures:
                self.source.release()
            self.diffusion.reset(setup.grid, setup.lam, channels=4)
        self._setup = setup

    def restrict_source(self) -> None:
        """Before a unit of source-model sweeps on a reduced grid: q of the current ρ_d into
        the coarse source texture, when a sample changed ρ_d since the last restriction (one
        dispatch over the data grid, not split)."""
        self.source.restrict(self.source_light, RGB_AS_LIGHTS, self._sampled)
        self._sampled = False

    def sample(self, iteration: int, values: Mapping[str, Any],
               region: tuple[int, int, int, int]) -> None:
        """Sample ``iteration`` of the direct light (and the traced orders) in ``region``
        (z0, z1, y0, y1) into ρ_d (and the orders' running means): the engine's tracker."""
        setup = self._setup
        assert setup is not None and self.rho_d is not None and self._sigma is not None
        bricks = self._bricks if setup.bricks is not None else None
        self.tracker.sample(setup, iteration, int(values["seed"]), region, self._sigma,
                            bricks=bricks, direct=self.rho_d, traced=self.traced,
                            last=self._last, estimator=values["estimator"],
                            light_sampling=values["light_sampling"])
        self._sampled = True

    def download(self) -> tuple[np.ndarray, np.ndarray]:
        """(ρ_d, ρ_s), each ``[z, y, x, 3]`` (tests and verification)."""
        assert self.rho_d is not None
        return self.rho_d.download()[..., :3], self.rho_s.download()[..., :3]

    def _release_textures(self) -> None:
        for tex in (self.rho_d, self.traced, self._last, self._sigma, self._bricks):
            if tex is not None:
                tex.release()
        self.rho_d = self.traced = self._last = self._sigma = self._bricks = None

    def release(self) -> None:
        self._release_textures()
        self.diffusion.release()
        self.source.release()
        self.tracker.release()
