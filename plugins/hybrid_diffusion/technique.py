"""Hybrid diffusion (seed 003 HD), engine part: the direct light's running mean ρ_d and the
diffused light ρ_s, on the GPU (``direct.comp.glsl`` + convection–diffusion's diffusion step)
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
from collections.abc import Mapping
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
    dispatch_groups,
    relative_residual,
)
from vtkvol.engine.gl import ComputeProgram, Texture3D, unbind_images
from vtkvol.engine.shaders import compute_source
from vtkvol.engine.technique import finish_gl
from vtkvol.plugins.hybrid_diffusion import TECHNIQUE, cpu

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Illuminator, LightSpec

#: The diffusion step reads the direct light as three "lights" with these colours: ρ_d's r, g, b.
RGB_AS_LIGHTS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
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
                 scatter_coefficients: np.ndarray | None = None) -> None:
        self.grid, self.sigma_t, self.lights, self.colors, self.lam = (
            grid, sigma_t, lights, colors, lam)
        self.model, self.coefficients = model, coefficients
        #: The per-brick majorant grid (``majorant = "bricks"``), None for the global one.
        self.bricks = bricks
        self.scatter = scatter if scatter is not None else ScatterGrid(grid, 1)
        self.scatter_coefficients = scatter_coefficients

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
              majorant: str = "global", scatter_grid: str = "full") -> Setup:
        specs = specs[:4]
        lights = [
            kd.LightSource(s.kind, tuple(float(v) for v in (
                s.vector if s.kind == "point" else cpu.unit(s.vector))),
                float(getattr(s, "falloff_distance", 0.0)), float(getattr(s, "size", 0.0)))
            for s in specs
        ]
        colors = [tuple(float(c) for c in getattr(s, "color", (1.0, 1.0, 1.0))) for s in specs]
        coefficients = (kd.source_coefficients(sigma_t, grid, albedo, phase_g)
                        if model == "source" else None)
        bricks = cpu.brick_majorants(sigma_t) if majorant == "bricks" else None
        # The published model's scattered volume stays on the data grid.
        scatter = ScatterGrid.named(grid, scatter_grid if model == "source" else "full")
        scatter_coefficients = (scatter.coefficients(sigma_t, albedo, phase_g)
                                if scatter.coarse else None)
        return cls(grid, sigma_t, lights, colors, kd.diffusion_rate(sigma_t, grid, albedo),
                   model, coefficients, bricks, scatter, scatter_coefficients)


class HybridDiffusion(GridScattering):
    """Tracked direct light plus diffused multiple scattering, refined over frames."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "hybrid_diffusion.glsl"

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._rho_d: np.ndarray | None = None  # numpy path state
        self._rho_s: np.ndarray | None = None
        #: Source model, numpy path: q (restricted to the scatter grid) of the current ρ_d.
        self._q: np.ndarray | None = None
        #: The current sample's next region's first (z layer, y row): not (0, 0) while a
        #: sample is drawn in parts.
        self._next_region = (0, 0)
        #: Measured cost (ms) of one finishing iteration (its sweeps and the residual check).
        self._finish_ms: float | None = None
        #: Measured cost (ms) of one row (a y line of one z layer) of one sample: sizes the
        #: next region.
        self._row_ms: float | None = None

    def make_driver(self, window: vtk.vtkRenderWindow) -> GpuHybrid:
        return GpuHybrid(window)

    def build_setup(self, grid: kd.Grid, sigma_t: np.ndarray,
                    values: Mapping[str, Any]) -> Setup:
        return Setup.build(grid, sigma_t, self.host.light_specs(), self.host.albedo,
                           str(values["diffusion_model"]), self.host.phase_g,
                           str(values["majorant"]), str(values["scatter_grid"]))

    def start_gpu(self, gpu: GpuHybrid, values: Mapping[str, Any]) -> None:
        assert self.setup is not None
        gpu.reset(self.setup, values)

    def start_cpu(self, values: Mapping[str, Any]) -> None:
        assert self.setup is not None
        shape = self.setup.grid.shape_zyx
        self._rho_d = np.zeros((*shape, 3), np.float32)
        self._rho_s = np.zeros((*self.setup.scatter.grid.shape_zyx, 3), np.float32)
        self._q = None
        self._upload_cpu_state()

    def advance(self, values: Mapping[str, Any]) -> None:
        """Up to ``iterations_per_frame`` samples before this frame. With the host's
        :attr:`~vtkvol.engine.technique.TechniqueHost.work_budget_ms` (the app sets one), the
        work stops once the budget is spent: a sample is drawn in z slabs or y bands sized
        from the measured cost per row, and the finishing sweeps in batches that fit, each
        resumed next frame — one frame never holds the event loop for a whole sample."""
        assert self.setup is not None
        samples = int(values["max_iterations"])
        count = min(int(values["iterations_per_frame"]), samples - self.iteration)
        budget = self.host.work_budget_ms
        t0 = time.perf_counter()
        worked = False
        done = 0
        while done < count:
            spent = (time.perf_counter() - t0) * 1e3
            if budget is not None and worked and spent >= budget:
                break
            worked = True
            left = None if budget is None else max(budget - spent, 0.0)
            if self._sample_region(values, left):
                done += 1
        if self._finishing(values):
            spent = (time.perf_counter() - t0) * 1e3
            if budget is None or not worked or spent < budget:
                worked = True
                self._finish_source(values, None if budget is None else budget - spent)
        if worked:
            if self._gpu is None:
                self._upload_cpu_state()
            self._last_ms = (time.perf_counter() - t0) * 1e3
        self.converged = self.iteration >= samples and not self._finishing(values)

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
        group (4 layers × 8 rows). True when the sample is complete (its diffusion steps then
        ran and the iteration advanced)."""
        setup = self.setup
        assert setup is not None
        nz, ny, _nx = setup.grid.shape_zyx
        z0, y0 = self._next_region
        if budget_ms is None:
            region = (0, nz, 0, ny)
        else:
            fit = (GROUP[1] * GROUP[2] if self._row_ms is None
                   else int(budget_ms / max(self._row_ms, 1e-6)))
            if y0 == 0 and fit >= ny * GROUP[2]:  # whole slabs
                layers = (fit // ny) // GROUP[2] * GROUP[2]
                region = (z0, min(nz, z0 + layers), 0, ny)
            else:  # a band of rows of one slab
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
        if y1 < ny:
            self._next_region = (z0, y1)
            return False
        self._next_region = (z1, 0) if z1 < nz else (0, 0)
        if z1 < nz:
            return False
        self._iterate(values, sample=False)  # the diffusion steps of the complete sample
        self.iteration += 1
        if self._gpu is not None and setup.model == "source" and int(values["diffusion_steps"]):
            self.residual = self._gpu.residual()
        return True

    def _finish_source(self, values: Mapping[str, Any], budget_ms: float | None = None) -> None:
        """After the last sample, the source model's sweeps until the residual tolerance (the
        last iteration ends the solve: the result is final when the samples are), in batches
        of up to ``FINISH_BATCH`` iterations between residual checks; with ``budget_ms`` each
        batch is as many as fit at the measured cost of one (at least one), and it stops
        once the budget is spent."""
        tolerance = float(values["tolerance"])
        t0 = time.perf_counter()
        for _ in range(MAX_FINISHING_SWEEPS):
            if self.residual < tolerance:
                return
            batch = FINISH_BATCH
            if budget_ms is not None and self._finish_ms is not None:
                left = budget_ms - (time.perf_counter() - t0) * 1e3
                batch = max(1, min(FINISH_BATCH, int(left / max(self._finish_ms, 1e-6))))
            t1 = time.perf_counter()
            for _ in range(batch):
                self._iterate(values, sample=False)
            if self._gpu is not None:
                self.residual = self._gpu.residual()  # reads back: the batch has run
            self._finish_ms = (time.perf_counter() - t1) * 1e3 / batch
            if budget_ms is not None and (time.perf_counter() - t0) * 1e3 >= budget_ms:
                return

    def release(self) -> None:
        super().release()
        self._rho_d = self._rho_s = self._q = None

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
                            majorant=str(merged["majorant"]))
        mean = np.zeros((*grid.shape_zyx, 3), np.float32)
        for k in range(int(merged["max_iterations"])):
            sample = cpu.direct_sample(sigma_t, grid, setup.lights, [(1.0, 1.0, 1.0)],
                                       bricks=setup.bricks,
                                       iteration=k, seed=int(merged["seed"]),
                                       estimator=merged["estimator"], light_sampling="all")
            mean += (sample - mean) / np.float32(k + 1)
        return mean[..., 0]

    # -- internals ----------------------------------------------------------------------------
    def _restart(self, values: Mapping[str, Any]) -> None:
        self._next_region = (0, 0)  # a new accumulation draws its first sample from (0, 0)
        super()._restart(values)

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
        )
        mean = self._rho_d[z0:z1, y0:y1]
        self._rho_d[z0:z1, y0:y1] = mean + (draw[z0:z1, y0:y1] - mean) / np.float32(
            self.iteration + 1)
        self._q = None  # ρ_d changed: the source model's q is stale

    def _iterate(self, values: Mapping[str, Any], sample: bool = True) -> None:
        """One iteration: a whole sample of the direct light (while ``sample``), then
        ``diffusion_steps`` steps of the model."""
        setup = self.setup
        assert setup is not None
        if self._gpu is not None:
            self._gpu.step(self.iteration, values, sample)
            return
        assert self._rho_d is not None and self._rho_s is not None
        if sample:
            nz, ny, _nx = setup.grid.shape_zyx
            self._sample_cpu(values, (0, nz, 0, ny))
        steps = int(values["diffusion_steps"])
        if setup.model == "source":
            assert setup.coefficients is not None
            if steps:
                if self._q is None:  # after a sample; the finishing sweeps reuse it
                    self._q = setup.scatter.restrict(kd.source_term(
                        setup.coefficients, np.moveaxis(self._rho_d, -1, 0), RGB_AS_LIGHTS,
                        [1.0] * 3))
                q = self._q
                grid, coefficients = setup.solve
                for _ in range(steps):
                    new, r2, q2 = kd.jacobi_sweep(self._rho_s, q, coefficients, grid)
                    self.residual = relative_residual(r2, q2)
                    self._rho_s = new
            return
        for _ in range(steps):
            self._rho_s = kd.diffusion_step(self._rho_d + self._rho_s, self._rho_s, setup.lam,
                                            setup.grid)

    def _upload_cpu_state(self) -> None:
        assert self._rho_d is not None and self._rho_s is not None
        self._direct = self._show(self._direct, _rgba(self._rho_d), 4)
        self._scattered = self._show(self._scattered, _rgba(self._rho_s), 4)


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
        self._programs: dict[tuple[str, str], ComputeProgram] = {}
        self.rho_d: Texture3D | None = None  # type: ignore[assignment]
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
        own = [t for t in (self.rho_d, self._sigma, self._bricks) if t is not None]
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

    def residual(self) -> float:
        """The source model's relative residual after the last sweep's start."""
        return relative_residual(*self.source.residual())

    def program(self, estimator: str, light_sampling: str, bricks: bool) -> ComputeProgram:
        key = (estimator, light_sampling, bricks)
        prog = self._programs.get(key)
        if prog is None:
            defines = {
                "VV_RATIO": "1" if estimator == "ratio" else "0",
                "VV_ALL_LIGHTS": "1" if light_sampling == "all" else "0",
                "VV_MAX_STEPS": str(cpu.MAX_STEPS),
                "VV_MIN_THROUGHPUT": repr(cpu.MIN_THROUGHPUT),
                "VV_BRICKS": "1" if bricks else "0",
                "VV_BRICK": str(cpu.BRICK),
            }
            source = compute_source("direct.comp.glsl", defines, __package__)
            prog = ComputeProgram(self.render_window, source, f"hybrid direct {key}")
            self._programs[key] = prog
        return prog

    def reset(self, setup: Setup, values: Mapping[str, Any]) -> None:
        self._release_textures()
        rw = self.render_window
        shape = setup.grid.shape_zyx
        self.rho_d = Texture3D(rw, shape, channels=4, data=np.zeros((*shape, 4), np.float32))
        self._sigma = Texture3D(rw, shape, data=setup.sigma_t)
        if setup.bricks is not None:
            self._bricks = Texture3D(rw, setup.bricks.shape, data=setup.bricks)
            self._bricks.tex.Deactivate()
        for tex in (self.rho_d, self._sigma):
            tex.tex.Deactivate()  # created bound to units; image units are separate
        self.diffusion.reset(setup.grid, setup.lam, channels=4)
        if setup.model == "source":
            assert setup.coefficients is not None
            # ρ_d's r, g, b as three "lights"; their fall-off is in the tracked samples already.
            self.source.reset(setup.grid, setup.solve[1], 4,
                              [kd.LightSource("directional", (0.0, 0.0, 1.0))] * 3,
                              setup.scatter, fine_sigma_s=setup.coefficients[..., 2])
        self._setup = setup

    def step(self, iteration: int, values: Mapping[str, Any], sample: bool = True) -> None:
        """Sample ``iteration`` of the direct light (while ``sample``), then the diffusion."""
        setup = self._setup
        assert setup is not None and self.rho_d is not None and self._sigma is not None
        steps = int(values["diffusion_steps"])
        if sample:
            self.sample(iteration, values, (0, setup.grid.shape_zyx[0], 0, setup.grid.shape_zyx[1]))
        if not steps:
            return
        if setup.model == "source":
            self.source.run(self.rho_d, RGB_AS_LIGHTS, steps, source_changed=self._sampled)
            self._sampled = False
        else:
            self.diffusion.run(self.rho_d, RGB_AS_LIGHTS, steps)

    def sample(self, iteration: int, values: Mapping[str, Any],
               region: tuple[int, int, int, int]) -> None:
        """Sample ``iteration`` of the direct light in ``region`` (z0, z1, y0, y1) into ρ_d."""
        setup = self._setup
        assert setup is not None and self.rho_d is not None and self._sigma is not None
        grid = setup.grid
        nz, ny, nx = grid.shape_zyx
        bricks = self._bricks if setup.bricks is not None else None
        prog = self.program(values["estimator"], values["light_sampling"], bricks is not None)
        prog.use()
        vecs: list[float] = []
        for light in setup.lights:
            vecs += [*light.vector, 1.0 if light.kind == "point" else 0.0]
        vecs += [0.0] * (16 - len(vecs))
        colors = [c for color in setup.colors for c in color]
        colors += [0.0] * (12 - len(colors))
        falloffs: list[float] = []
        for light in setup.lights:
            d0 = light.falloff_distance if light.kind == "point" else 0.0
            falloffs += [*light.vector, d0]
        falloffs += [0.0] * (16 - len(falloffs))
        for name, unit in (("vv_sigma", 0), ("vv_direct", 1)):
            prog.set_uniform(name, unit)
        prog.set_uniform("vv_dims", nx, ny, nz)
        prog.set_uniform("vv_first", region[0], region[2])
        prog.set_uniform("vv_end", region[1], region[3])
        prog.set_uniform("vv_origin", *grid.origin, kind="f")
        prog.set_uniform("vv_spacing", *grid.spacing, kind="f")
        prog.set_uniform("vv_majorant", float(setup.sigma_t.max()), kind="f")
        prog.set_uniform("vv_iteration", iteration, kind="ui")
        prog.set_uniform("vv_seed", int(values["seed"]), kind="ui")
        prog.set_uniform("vv_numLights", len(setup.lights))
        prog.set_uniform_array("vv_lightVec", vecs, size=4)
        prog.set_uniform_array("vv_color", colors, size=3)
        prog.set_uniform_array("vv_falloff", falloffs, size=4)
        sizes = [float(light.size) for light in setup.lights]
        prog.set_uniform_array("vv_lightSize", sizes + [0.0] * (4 - len(sizes)), size=1)
        self._sigma.bind_image(0, "read")
        self.rho_d.bind_image(1, "readwrite")
        if bricks is not None:
            prog.set_uniform("vv_bricks", 2)
            nbz, nby, nbx = setup.bricks.shape
            prog.set_uniform("vv_brickDims", nbx, nby, nbz)
            bricks.bind_image(2, "read")
        groups = dispatch_groups(grid)
        prog.dispatch((groups[0], -(-(region[3] - region[2]) // GROUP[1]),
                       -(-(region[1] - region[0]) // GROUP[2])))
        unbind_images(self.render_window, 3)
        prog.done()
        self._sampled = True

    def download(self) -> tuple[np.ndarray, np.ndarray]:
        """(ρ_d, ρ_s), each ``[z, y, x, 3]`` (tests and verification)."""
        assert self.rho_d is not None
        return self.rho_d.download()[..., :3], self.rho_s.download()[..., :3]

    def _release_textures(self) -> None:
        for tex in (self.rho_d, self._sigma, self._bricks):
            if tex is not None:
                tex.release()
        self.rho_d = self._sigma = self._bricks = None

    def release(self) -> None:
        self._release_textures()
        self.diffusion.release()
        self.source.release()
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
