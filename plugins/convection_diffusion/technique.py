"""Convection–diffusion (seed 003 KD), engine part: progressive transport on the GPU (compute
shaders, ping-pong textures) or in numpy (:mod:`.cpu`), shaded through the host's medium model.
The diffusion machinery it shares with hybrid diffusion is the engine's
(:mod:`vtkvol.engine.diffusion`).

State lives on the data grid: ρ_l for up to four lights (one per channel of one texture) and
the scattered RGB light ρ_s. ``diffusion_model = "source"`` computes ρ_l at the restart by
ray-marching every voxel's transmittance to the light (the first frame shows the final direct
light) and then refines ρ_s by Jacobi
sweeps until the residual tolerance; with ``traced_orders`` k > 0 each iteration first draws one
path per voxel of the first k scattering orders (the engine's tracker,
:mod:`vtkvol.engine.traced_orders`) into the running means E_1 + … + E_k (shown: the shader's
third texture ``vv_convection_diffusion_traced``) and E_k (the sweeps' source, σ_s·E_k instead
of σ_s·E_0), until ``traced_paths`` are drawn. ``"published"`` convects and diffuses ρ_l
together.
It restarts when the opacity, the lights, the material or a parameter marked ACCUMULATION
changes (``Changes.reset_accumulation``), never for the camera.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk

from vtkvol.engine.coarse_diffusion import ScatterGrid
from vtkvol.engine.diffusion import (
    GROUP,
    MARCH_STEP_EDGES,
    MAX_OPACITY,
    GpuFieldDiffusion,
    GpuSourceDiffusion,
    GridScattering,
    dispatch_groups,
    light_channels,
    light_quadrature,
    relative_residual,
    source_coefficients,
)
from vtkvol.engine.gl import ComputeProgram, Texture3D, unbind_images
from vtkvol.engine.shaders import compute_source
from vtkvol.engine.technique import finish_gl
from vtkvol.engine.traced_orders import (
    RGB_AS_LIGHTS,
    RGB_LIGHTS,
    GpuTracker,
    brick_majorants,
)
from vtkvol.plugins.convection_diffusion import TECHNIQUE, cpu

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Illuminator, LightSpec



class ConvectionDiffusion(GridScattering):
    """Multiple scattering by convection–diffusion, refined over frames."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "convection_diffusion.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._transport: cpu.Transport | None = None  # numpy path state
        #: Numpy path: the traced orders' light the shader samples (None without them).
        self._traced_texture: Texture3D | None = None
        self._placeholder: Texture3D | None = None  # a 1³ zero texel: no traced orders
        #: GPU traced orders under a work budget: where the current path's next region
        #: starts (z layer, y row), and the measured cost (ms) of one row of one layer.
        self._orders_next = (0, 0)
        self._row_ms: float | None = None

    def make_driver(self, window: vtk.vtkRenderWindow) -> GpuTransport:
        return GpuTransport(window)

    # -- hooks --------------------------------------------------------------------------------
    def build_setup(self, grid: cpu.Grid, sigma_t: np.ndarray,
                    values: Mapping[str, Any]) -> Setup:
        return Setup.build(grid, sigma_t, self.host.light_specs(), values, self.host.albedo,
                           self.host.unit_distance, self.host.phase_g)

    def start_gpu(self, gpu: GpuTransport, values: Mapping[str, Any]) -> None:
        assert self.setup is not None
        gpu.reset(self.setup)
        self._orders_next = (0, 0)  # a new accumulation draws its first path from (0, 0)

    def start_cpu(self, values: Mapping[str, Any]) -> None:
        assert self.setup is not None
        self._transport = self.setup.transport(values["diffusion_steps"])
        self._upload_cpu_state()

    def advance(self, values: Mapping[str, Any]) -> None:
        """Up to ``iterations_per_frame`` iterations: the source model stops on the residual
        tolerance, with traced orders once ``traced_paths`` paths are drawn too (a non-zero
        ``max_iterations`` still caps it), the published one after ``max_iterations`` (0:
        :meth:`automatic_iterations`). With traced orders each iteration draws a path per
        voxel; with the host's :attr:`~vtkvol.engine.technique.TechniqueHost.work_budget_ms`
        (the app sets one) the frame's iterations stop once it is spent (at least one runs)."""
        setup = self.setup
        assert setup is not None
        source = setup.model == "source"
        steps = int(values["diffusion_steps"])
        paths = setup.traced_paths if setup.orders else 0
        if source:
            # Stopped by the residual (and the traced paths), not a count; a non-zero
            # max_iterations still caps it.
            limit = int(values["max_iterations"]) or None
            done = steps == 0 or (self.residual < float(values["tolerance"])
                                  and self.iteration >= paths)
        else:
            limit = int(values["max_iterations"]) or self.automatic_iterations()
            done = False
        count = int(values["iterations_per_frame"])
        if limit is not None:
            count = min(count, limit - self.iteration)
        if (count > 0 and not done and setup.orders and self._gpu is not None
                and self.host.work_budget_ms is not None):
            self._advance_in_parts(count, steps, self.host.work_budget_ms)
        elif count > 0 and not done:
            t0 = time.perf_counter()
            budget = self.host.work_budget_ms if setup.orders else None
            # Without traced orders an iteration is a few sweeps: the frame's run at once.
            # With them each draws paths through the volume: one at a time within a budget.
            batches = [count] if budget is None else [1] * count
            for batch in batches:
                if self._gpu is not None:
                    self._gpu.step(batch, steps)
                    if budget is not None:
                        finish_gl(self.host.render_window)  # the cost, not the queue
                else:
                    assert self._transport is not None
                    self._transport.step(batch)
                self.iteration += batch
                if budget is not None and (time.perf_counter() - t0) * 1e3 >= budget:
                    break
            if self._gpu is not None:
                if source:
                    self.residual = self._gpu.residual()
            else:
                assert self._transport is not None
                self.residual = self._transport.residual
                self._upload_cpu_state()
            self._last_ms = (time.perf_counter() - t0) * 1e3
        if source:
            self.converged = (steps == 0
                              or (self.residual < float(values["tolerance"])
                                  and self.iteration >= paths)
                              or (limit is not None and self.iteration >= limit))
        else:
            assert limit is not None
            self.converged = self.iteration >= limit

    def _advance_in_parts(self, count: int, steps: int, budget_ms: float) -> None:
        """GPU, traced orders, under the host's work budget: up to ``count`` iterations, each
        path drawn in parts sized from the measured cost per row (one y line of one z layer):
        whole slabs of 4 z layers while they fit, else a band of y rows of one slab (at least
        one work group); an iteration ends (its sweeps run, ``iteration`` advances) when its
        path is drawn everywhere. The next frame resumes where this one stopped, so one frame
        never holds the event loop for a whole path of every voxel (seconds on llvmpipe at
        10⁶ voxels)."""
        gpu = self._gpu
        setup = self.setup
        assert gpu is not None and setup is not None
        nz, ny, _nx = setup.grid.shape_zyx
        t0 = time.perf_counter()
        worked = False
        done = 0
        while done < count:
            spent = (time.perf_counter() - t0) * 1e3
            if worked and spent >= budget_ms:
                break
            worked = True
            sampled = gpu.sampling
            if sampled:
                z0, y0 = self._orders_next
                rows_fit = (GROUP[1] * GROUP[2] if self._row_ms is None
                            else int(max(budget_ms - spent, 0.0) / max(self._row_ms, 1e-6)))
                if y0 == 0 and rows_fit >= ny * GROUP[2]:  # whole slabs of 4 layers
                    z1 = min(nz, z0 + max(1, rows_fit // (ny * GROUP[2])) * GROUP[2])
                    region = (z0, z1, 0, ny)
                else:  # a band of rows of one slab
                    z1 = min(nz, z0 + GROUP[2])
                    rows = max(GROUP[1], rows_fit // (z1 - z0) // GROUP[1] * GROUP[1])
                    region = (z0, z1, y0, min(ny, y0 + rows))
                t_part = time.perf_counter()
                gpu.sample_region(region)
                finish_gl(self.host.render_window)  # the cost must be measured, not queued
                rows_drawn = (region[1] - region[0]) * (region[3] - region[2])
                self._row_ms = (time.perf_counter() - t_part) * 1e3 / rows_drawn
                if region[3] < ny:
                    self._orders_next = (region[0], region[3])
                    continue
                self._orders_next = (region[1], 0) if region[1] < nz else (0, 0)
                if region[1] < nz:
                    continue
                gpu.end_sample()
            gpu.sweeps(steps, sampled)
            self.iteration += 1
            done += 1
        if setup.model == "source":
            self.residual = gpu.residual()
        self._last_ms = (time.perf_counter() - t0) * 1e3

    def _bind(self, gpu_textures: tuple[Texture3D, Texture3D] | None) -> None:
        """The direct and scattered light (the base class's), and the traced orders' light
        ``vv_convection_diffusion_traced`` (a zero texel without traced orders)."""
        super()._bind(gpu_textures)
        gpu = self._gpu
        traced = gpu.traced if gpu is not None else self._traced_texture
        if traced is None:
            if self._placeholder is None:
                self._placeholder = Texture3D(self.host.render_window, (1, 1, 1), channels=4,
                                              data=np.zeros((1, 1, 1, 4), np.float32))
            traced = self._placeholder
        self.host.bind_texture(f"vv_{self.NAME}_traced", traced)

    def release(self) -> None:
        super().release()
        self._transport = None
        for tex in (self._traced_texture, self._placeholder):
            if tex is not None:
                tex.release()
        self._traced_texture = self._placeholder = None

    def automatic_iterations(self) -> int:
        """Iterations of ``max_iterations = 0`` in the published model: four times what the
        light front needs to cross the grid's diagonal (it moves half a voxel per iteration)."""
        if self.setup is None:
            raise RuntimeError("the technique has not been prepared yet")
        return 4 * cpu.iterations_to_cross(self.setup.grid)

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """The final direct light ρ of ``light`` alone at every voxel, ``[z, y, x]`` (0…1):
        what this technique uses as the direct light's visibility (source model: the
        ray-marched transmittance; published: the one convected field, diffusion included)."""
        merged = {**self.defaults(), **values}
        grid = cpu.Grid(opacity.shape, spacing, self._origin())
        sigma_t = cpu.extinction(opacity, self.host.unit_distance)
        setup = Setup.build(grid, sigma_t, [light], merged, self.host.albedo,
                            self.host.unit_distance, self.host.phase_g)
        if setup.model == "source":
            return setup.transport(diffusion_steps=0).rho[0]
        transport = setup.transport(diffusion_steps=int(merged["diffusion_steps"]))
        transport.step(merged["max_iterations"] or 4 * cpu.iterations_to_cross(grid))
        return transport.rho[0]

    # -- internals ----------------------------------------------------------------------------
    def _upload_cpu_state(self) -> None:
        transport = self._transport
        assert transport is not None
        shape = transport.grid.shape_zyx
        channels = light_channels(len(transport.lights))
        direct = np.zeros((*shape, channels), np.float32)
        direct[..., : len(transport.lights)] = np.moveaxis(transport.rho[: len(transport.lights)],
                                                           0, -1)
        # The scattered light on its own grid (the data's, or the reduced one, which tiles the
        # same extent: the shader samples either at texPos).
        scattered = np.zeros((*transport.rho_s.shape[:3], 4), np.float32)
        scattered[..., :3] = transport.rho_s
        self._direct = self._show(self._direct, _squeeze(direct), channels)
        self._scattered = self._show(self._scattered, scattered, 4)
        if transport.traced is not None:
            traced = np.zeros((*shape, 4), np.float32)
            traced[..., :3] = transport.traced
            self._traced_texture = self._show(self._traced_texture, traced, 4)
        elif self._traced_texture is not None:
            self._traced_texture.release()
            self._traced_texture = None


def _squeeze(a: np.ndarray) -> np.ndarray:
    return a[..., 0] if a.shape[-1] == 1 else a


class Setup:
    """What one accumulation runs on: grid, lights, the model, per-voxel absorption per
    iteration, diffusion rate (published) and source-model coefficients (source) on the data
    grid, and the grid the scattered light is solved on (``scatter``: the data grid, or the
    source model's reduced ``scatter_grid`` with its own ``scatter_coefficients``). The source
    model's traced orders: ``orders`` (0: none), ``traced_paths``, the medium's ``albedo`` and
    ``phase_g`` and the per-brick majorants ``bricks`` (``[bz, by, bx]`` per µm,
    :func:`~vtkvol.engine.traced_orders.brick_majorants`: paths cross empty bricks in one
    step, so sparse stacks do not crawl; None without traced orders)."""

    def __init__(self, grid: cpu.Grid, lights: list[cpu.LightSource],
                 colors: list[tuple[float, float, float]], sigma_a: np.ndarray,
                 lam: np.ndarray, model: str, coefficients: np.ndarray | None,
                 scatter: ScatterGrid | None = None,
                 scatter_coefficients: np.ndarray | None = None,
                 sigma_t: np.ndarray | None = None, unit_distance: float = 1.0,
                 orders: int = 0, traced_paths: int = 256, albedo: float = 1.0,
                 phase_g: float = 0.0, bricks: np.ndarray | None = None) -> None:
        self.grid, self.lights, self.colors = grid, lights, colors
        self.orders, self.traced_paths = orders, traced_paths
        self.albedo, self.phase_g, self.bricks = albedo, phase_g, bricks
        #: Extinction (per µm) and unit distance (µm) the source model's direct light is
        #: ray-marched through.
        self.sigma_t, self.unit_distance = sigma_t, unit_distance
        self.sigma_a, self.lam = sigma_a, lam
        self.model, self.coefficients = model, coefficients
        self.scatter = scatter if scatter is not None else ScatterGrid(grid, 1)
        self.scatter_coefficients = scatter_coefficients

    @classmethod
    def build(cls, grid: cpu.Grid, sigma_t: np.ndarray, specs: Sequence[Any],
              values: Mapping[str, Any], albedo: float, unit_distance: float,
              phase_g: float = 0.0) -> Setup:
        specs = list(specs)[:4]
        lights = [cpu.LightSource(s.kind, tuple(float(v) for v in s.vector),
                                  float(getattr(s, "falloff_distance", 0.0)),
                                  float(getattr(s, "size", 0.0))) for s in specs]
        colors = [tuple(float(c) for c in getattr(s, "color", (1.0, 1.0, 1.0))) for s in specs]
        model = str(values["diffusion_model"])
        # Published (eq. 8): the convected field loses its absorbed part only; source: the
        # direct light is the uncollided beam, attenuated by the whole extinction.
        sigma_a = cpu.absorption_per_iteration(
            sigma_t, grid, albedo=albedo, mapping=values["absorption_mapping"],
            convection_extinction="paper" if model == "published" else "total",
            unit_distance=unit_distance,
        )
        lam = cpu.diffusion_rate(sigma_t, grid, albedo)
        coefficients = (source_coefficients(sigma_t, grid, albedo, phase_g)
                        if model == "source" else None)
        # The published model has no separate scattered field: always the data grid.
        scatter = ScatterGrid.named(grid, str(values["scatter_grid"]) if model == "source"
                                    else "full")
        scatter_coefficients = (scatter.coefficients(sigma_t, albedo, phase_g)
                                if scatter.coarse else None)
        # Traced orders: the source model's, and only with its diffusion (diffusion_steps 0
        # is the direct light alone).
        orders = (int(values.get("traced_orders", 0))
                  if model == "source" and int(values.get("diffusion_steps", 1)) > 0 else 0)
        return cls(grid, lights, colors, sigma_a, lam, model,  # type: ignore[arg-type]
                   coefficients, scatter, scatter_coefficients,
                   sigma_t if model == "source" else None, unit_distance, orders=orders,
                   traced_paths=int(values.get("traced_paths", 256)), albedo=albedo,
                   phase_g=phase_g, bricks=brick_majorants(sigma_t) if orders else None)

    def transport(self, diffusion_steps: int) -> cpu.Transport:
        return cpu.Transport(self.grid, self.lights, self.colors, self.sigma_a, self.lam,
                             diffusion_steps=diffusion_steps, model=self.model,  # type: ignore[arg-type]
                             coefficients=self.coefficients, scatter=self.scatter,
                             scatter_coefficients=self.scatter_coefficients,
                             sigma_t=self.sigma_t, unit_distance=self.unit_distance,
                             orders=self.orders if diffusion_steps else 0, albedo=self.albedo,
                             phase_g=self.phase_g, traced_paths=self.traced_paths)


class GpuTransport:
    """The compute-shader path: ρ ping-pongs between two textures (a GPU updating in place
    would depend on invocation order; ping-pong matches numpy to float rounding); the scattered
    light is the engine's source-model driver (source) or a zero texture (published). With
    traced orders (source model) the engine's tracker (:class:`~vtkvol.engine.traced_orders.
    GpuTracker`, ``VV_DIRECT 0``) draws one path per voxel and iteration into the running means
    :attr:`traced` (E_1 + … + E_k, shown) and E_k, the sweeps' source (read as three "lights"
    r, g, b without fall-off: it is in the traced light already); σ_t (r32f) and the per-brick
    majorants are images for it."""

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[tuple[str, int, bool], ComputeProgram] = {}
        self._rho: list[Texture3D] = []
        self._sigma_a: Texture3D | None = None
        self._lam: Texture3D | None = None
        self._zero: Texture3D | None = None  # the published model's (empty) scattered volume
        self.source = GpuSourceDiffusion(render_window)
        self.field = GpuFieldDiffusion(render_window)
        self.tracker = GpuTracker(render_window, "convection_diffusion")
        #: Traced orders: running means of E_1 + … + E_k (shown) and of E_k (the sweeps'
        #: source), RGBA on the data grid; None without traced orders.
        self.traced: Texture3D | None = None
        self._last: Texture3D | None = None
        self._sigma: Texture3D | None = None  # σ_t per µm (r32f), the tracker's medium
        self._bricks: Texture3D | None = None  # per-brick majorants per µm (r32f)
        self._setup: Setup | None = None
        self._samples = 0  # traced paths drawn per voxel
        self._model = "published"
        self._grid = cpu.Grid((1, 1, 1), (1.0, 1.0, 1.0))
        self._channels = 1
        self._lights: list[cpu.LightSource] = []
        self._colors: list[tuple[float, float, float]] = []
        self.program("convection", 1)  # fail now, not mid-frame, when compute cannot work

    @property
    def rho(self) -> Texture3D:
        return self._rho[0]

    @property
    def shown(self) -> tuple[Texture3D, Texture3D]:
        """(ρ, ρ_s): what the shader samples as the direct and the scattered light."""
        return self.rho, self.rho_s

    @property
    def rho_s(self) -> Texture3D:
        if self._model == "source":
            return self.source.phi
        assert self._zero is not None
        return self._zero

    @property
    def textures(self) -> list[Texture3D]:
        own = [*self._rho, *(t for t in (self._sigma_a, self._lam, self._zero, *self._traced_set)
                             if t)]
        return own + self.source.textures

    @property
    def _traced_set(self) -> tuple[Texture3D | None, ...]:
        return (self.traced, self._last, self._sigma, self._bricks)

    def program(self, kind: str, channels: int, steady: bool = False) -> ComputeProgram:
        key = (kind, channels, steady)
        prog = self._programs.get(key)
        if prog is None:
            defines = {"VV_CHANNELS": str(channels), "VV_STEADY": "1" if steady else "0"}
            source = compute_source(f"{kind}.comp.glsl", defines, __package__)
            prog = ComputeProgram(self.render_window, source, f"convection_diffusion {kind}")
            self._programs[key] = prog
        return prog

    def reset(self, setup: Setup) -> None:
        """New textures for ``setup``; the source model's direct light is final here (one ray
        march per voxel and light: the first frame already shows it)."""
        self._release_textures()
        rw = self.render_window
        shape = setup.grid.shape_zyx
        channels = light_channels(len(setup.lights))
        zeros = np.zeros(shape if channels == 1 else (*shape, channels), np.float32)
        self._rho = [Texture3D(rw, shape, channels=channels, data=zeros) for _ in range(2)]
        self._sigma_a = Texture3D(rw, shape, data=setup.sigma_a)
        self._lam = Texture3D(rw, shape, data=setup.lam)
        self._zero = Texture3D(rw, shape, channels=4, data=np.zeros((*shape, 4), np.float32))
        for tex in (*self._rho, self._sigma_a, self._lam, self._zero):
            tex.tex.Deactivate()  # created bound to units; image units are separate
        self._grid, self._lights, self._colors = setup.grid, setup.lights, setup.colors
        self._channels, self._model = channels, setup.model
        self._setup, self._samples = setup, 0
        if setup.model == "source":
            assert setup.coefficients is not None
            # With traced orders the sweeps' source is E_k (rgb): three "lights" r, g, b.
            source_channels, source_lights = ((4, list(RGB_LIGHTS)) if setup.orders
                                              else (channels, setup.lights))
            if setup.scatter.coarse:
                assert setup.scatter_coefficients is not None
                self.source.reset(setup.grid, setup.scatter_coefficients, source_channels,
                                  source_lights, setup.scatter,
                                  fine_sigma_s=setup.coefficients[..., 2])
            else:
                self.source.reset(setup.grid, setup.coefficients, source_channels,
                                  source_lights)
            self._warm_start(setup)
            if setup.orders:
                assert setup.sigma_t is not None and setup.bricks is not None
                self.tracker.program(direct=False, orders=setup.orders, bricks=True)  # fail now
                self._sigma = Texture3D(rw, shape, data=setup.sigma_t.astype(np.float32))
                self._bricks = Texture3D(rw, setup.bricks.shape, data=setup.bricks)
                zeros4 = np.zeros((*shape, 4), np.float32)
                self.traced = Texture3D(rw, shape, channels=4, data=zeros4)
                self._last = Texture3D(rw, shape, channels=4, data=zeros4)
                for tex in self._traced_set:
                    assert tex is not None
                    tex.tex.Deactivate()

    def _warm_start(self, setup: Setup) -> None:
        """The source model's final direct light: every voxel's transmittance ray-marched to
        each light (``march.comp.glsl``), or for sized lights the weighted marches of their
        :func:`~vtkvol.engine.diffusion.light_quadrature`, summed in numpy."""
        assert setup.sigma_t is not None
        rw = self.render_window
        alpha = (-np.expm1(-setup.sigma_t.astype(np.float64) * setup.unit_distance)).astype(
            np.float32)
        alpha_tex = Texture3D(rw, setup.grid.shape_zyx, data=alpha)
        alpha_tex.tex.Deactivate()
        try:
            quadratures = [light_quadrature(light) for light in setup.lights]
            if all(len(q) == 1 for q in quadratures):
                self._march(alpha_tex, setup)
                return
            count = max(len(q) for q in quadratures)
            total: np.ndarray | None = None
            for k in range(count):
                # An ideal light takes part in every pass with weight 1/count (the same
                # light); a shorter quadrature (a point light's six points beside a cone's
                # seven) sits out.
                parts = [(q[0][0], 1.0 / count) if len(q) == 1
                         else (q[k] if k < len(q) else (q[0][0], 0.0)) for q in quadratures]
                self._lights = [ideal for ideal, _ in parts]
                self._march(alpha_tex, setup)
                weights = np.asarray([w for _, w in parts], np.float32)
                rho = self._rho[0].download()
                weighted = rho * (weights[0] if rho.ndim == 3 else np.pad(
                    weights, (0, rho.shape[-1] - len(weights))))
                total = weighted if total is None else total + weighted
            self._lights = setup.lights
            assert total is not None
            self._rho[0].upload(total.astype(np.float32))
        finally:
            alpha_tex.release()

    def _march(self, alpha: Texture3D, setup: Setup) -> None:
        """One dispatch of ``march.comp.glsl`` for the current ideal lights into ρ."""
        grid = self._grid
        nz, ny, nx = grid.shape_zyx
        prog = self.program("march", self._channels)
        light_vecs: list[float] = []
        for light in self._lights:
            if light.kind == "point":
                light_vecs += [*light.vector, 1.0]
            else:
                w = np.asarray(light.vector, np.float64)
                w /= max(float(np.linalg.norm(w)), 1e-30)
                light_vecs += [*(float(c) for c in w), 0.0]
        light_vecs += [0.0] * (16 - len(light_vecs))
        prog.use()
        prog.set_uniform("vv_rhoOut", 0)
        prog.set_uniform("vv_alpha", 1)
        prog.set_uniform("vv_dims", nx, ny, nz)
        prog.set_uniform("vv_origin", *grid.origin, kind="f")
        prog.set_uniform("vv_spacing", *grid.spacing, kind="f")
        prog.set_uniform("vv_unitDistance", float(setup.unit_distance), kind="f")
        prog.set_uniform("vv_step", MARCH_STEP_EDGES * min(grid.spacing), kind="f")
        prog.set_uniform("vv_maxOpacity", float(MAX_OPACITY), kind="f")
        prog.set_uniform("vv_numLights", len(self._lights))
        prog.set_uniform_array("vv_lightVec", light_vecs, size=4)
        self._rho[0].bind_image(0, "write")
        alpha.bind_image(1, "read")
        prog.dispatch(dispatch_groups(grid))
        unbind_images(self.render_window, 2)
        prog.done()

    def _convect(self, iterations: int, steady: bool, diffusion_steps: int = 0) -> None:
        """``iterations`` convection dispatches (time steps, or steady sweeps), each followed by
        ``diffusion_steps`` explicit diffusion steps of the same field."""
        grid = self._grid
        nz, ny, nx = grid.shape_zyx
        groups = dispatch_groups(grid)
        conv = self.program("convection", self._channels, steady)
        light_vecs = []
        for light in self._lights:
            if light.kind == "point":
                light_vecs += [*light.vector, 1.0]
            else:
                u = cpu.propagation(grid, light).reshape(3)
                light_vecs += [*(float(c) for c in u), 0.0]
        light_vecs += [0.0] * (16 - len(light_vecs))
        assert self._sigma_a is not None and self._lam is not None
        for _ in range(iterations):
            conv.use()
            conv.set_uniform("vv_rhoIn", 0)
            conv.set_uniform("vv_rhoOut", 1)
            conv.set_uniform("vv_sigmaA", 2)
            conv.set_uniform("vv_dims", nx, ny, nz)
            conv.set_uniform("vv_ratio", *grid.axis_ratios.tolist(), kind="f")
            conv.set_uniform("vv_origin", *grid.origin, kind="f")
            conv.set_uniform("vv_spacing", *grid.spacing, kind="f")
            conv.set_uniform("vv_sourceRadius2", max(grid.spacing) ** 2, kind="f")
            conv.set_uniform("vv_numLights", len(self._lights))
            conv.set_uniform_array("vv_lightVec", light_vecs, size=4)
            self._rho[0].bind_image(0, "read")
            self._rho[1].bind_image(1, "write")
            self._sigma_a.bind_image(2, "read")
            conv.dispatch(groups)
            unbind_images(self.render_window, 3)
            conv.done()
            self._rho.reverse()
            for _ in range(diffusion_steps):
                self.field.run(self._rho[0], self._rho[1], self._lam, grid, self._channels)
                self._rho.reverse()

    @property
    def sampling(self) -> bool:
        """Traced orders whose paths are not all drawn yet (an iteration draws one)."""
        setup = self._setup
        return (self._model == "source" and setup is not None and bool(setup.orders)
                and self._samples < setup.traced_paths)

    def sample_region(self, region: tuple[int, int, int, int]) -> None:
        """The current path of every voxel in ``region`` (z0, z1, y0, y1; all x) into the
        traced orders' running means; :meth:`end_sample` once the regions cover the grid.
        Each voxel's stream depends on its index and the path number only, so a path drawn
        in regions equals one drawn whole, bit for bit."""
        setup = self._setup
        assert setup is not None and self._sigma is not None and self._last is not None
        self.tracker.sample(setup, self._samples, 0, region, self._sigma, bricks=self._bricks,
                            traced=self.traced, last=self._last)

    def end_sample(self) -> None:
        """The current path is drawn everywhere: the next iteration draws the next one."""
        self._samples += 1

    def sweeps(self, diffusion_steps: int, source_changed: bool) -> None:
        """One iteration's ``diffusion_steps`` sweeps from the traced orders' E_k (restricted
        again on a reduced grid when ``source_changed``)."""
        assert self._last is not None
        if diffusion_steps:
            self.source.run(self._last, RGB_AS_LIGHTS, diffusion_steps,
                            source_changed=source_changed)

    def step(self, iterations: int, diffusion_steps: int) -> None:
        """``iterations`` iterations of the accumulation's model (see :mod:`.cpu`); with traced
        orders each first draws one path per voxel (while fewer than ``traced_paths`` are
        drawn), then its sweeps start from the new E_k."""
        setup = self._setup
        if self._model == "source" and setup is not None and setup.orders:
            nz, ny, _nx = setup.grid.shape_zyx
            for _ in range(iterations):
                sampled = self.sampling
                if sampled:
                    self.sample_region((0, nz, 0, ny))
                    self.end_sample()
                self.sweeps(diffusion_steps, sampled)
            return
        if self._model == "source":
            if diffusion_steps:
                # The direct light is final after the warm start: q is restricted once.
                self.source.run(self._rho[0], self._colors, iterations * diffusion_steps,
                                source_changed=False)
            return
        self._convect(iterations, steady=False, diffusion_steps=diffusion_steps)

    def residual(self) -> float:
        """The source model's relative residual after the last sweep's start."""
        return relative_residual(*self.source.residual())

    def download(self) -> tuple[np.ndarray, np.ndarray]:
        """(ρ ``[z, y, x(, channels)]``, ρ_s ``[z, y, x, 4]``) for tests and verification."""
        return self._rho[0].download(), self.rho_s.download()

    def _release_textures(self) -> None:
        for tex in [*self._rho, *(t for t in (self._sigma_a, self._lam, self._zero,
                                              *self._traced_set) if t)]:
            tex.release()
        self._rho = []
        self._sigma_a = self._lam = self._zero = None
        self.traced = self._last = self._sigma = self._bricks = None

    def release(self) -> None:
        self._release_textures()
        self.source.release()
        self.field.release()
        self.tracker.release()
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
