"""Convection–diffusion (seed 003 KD), engine part: progressive transport on the GPU (compute
shaders, ping-pong textures) or in numpy (:mod:`.cpu`), shaded through the host's medium model.

State lives on the data grid: ρ_l for up to four lights (one per channel of one texture) and
the scattered RGB light ρ_s. It restarts when the opacity, the lights, the material or a
parameter marked ACCUMULATION changes (``Changes.reset_accumulation``), never for the camera.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk

from vtkvol.engine.gl import ComputeProgram, GLUnavailableError, Texture3D, gl
from vtkvol.engine.shaders import compute_source
from vtkvol.engine.technique import ComputePath, Technique
from vtkvol.plugins.convection_diffusion import TECHNIQUE, cpu

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

DIRECT_UNIFORM = "vv_convection_diffusion_direct"
SCATTERED_UNIFORM = "vv_convection_diffusion_scattered"
GROUP = (8, 8, 4)  #: work-group size of both compute shaders


def light_channels(count: int) -> int:
    """Texture channels that hold ``count`` lights (1, 2 or 4)."""
    return 1 if count <= 1 else (2 if count == 2 else 4)


class GridScattering(Technique):
    """What seed 003's two methods share: progressive light on the data grid with a GPU
    (``ComputePath``) and a numpy path, shown through two textures — the direct light and the
    scattered light — bound under ``DIRECT``/``SCATTERED``; their counters in ``stats()``."""

    DIRECT: ClassVar[str]
    SCATTERED: ClassVar[str]

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._compute = ComputePath(self.NAME, self.make_driver)
        self._direct: Texture3D | None = None  # numpy path: what the shader samples
        self._scattered: Texture3D | None = None
        self._restarts = 0
        self._backend = ""
        self._last_ms = 0.0

    def make_driver(self, window: vtk.vtkRenderWindow) -> Any:
        """The GPU driver (compute programs and textures) of this technique."""
        raise NotImplementedError

    @property
    def _gpu(self) -> Any:
        return self._compute.driver

    def _bind(self, gpu_textures: tuple[Texture3D, Texture3D] | None) -> None:
        """Bind the GPU path's (direct, scattered) textures, or the numpy path's."""
        direct, scattered = gpu_textures or (self._direct, self._scattered)
        assert direct is not None and scattered is not None
        self.host.bind_texture(self.DIRECT, direct)
        self.host.bind_texture(self.SCATTERED, scattered)

    def stats(self) -> dict[str, Any]:
        textures = [self._direct, self._scattered]
        if self._gpu is not None:
            textures += self._gpu.textures
        return {
            "recomputes": self._restarts,
            "iterations": self.iteration,
            "recompute_ms": self._last_ms,
            "backend": self._backend,
            "texture_bytes": sum(t.nbytes for t in textures if t is not None),
        }

    def release(self) -> None:
        for tex in (self._direct, self._scattered):
            if tex is not None:
                tex.release()
        self._direct = self._scattered = None
        self._compute.release()

    def _origin(self) -> tuple[float, float, float]:
        return tuple(float(o) for o in self.host.image.GetOrigin())  # type: ignore[return-value]


class ConvectionDiffusion(GridScattering):
    """Multiple scattering by convection–diffusion, refined over frames."""

    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "convection_diffusion.glsl"
    DIRECT = DIRECT_UNIFORM
    SCATTERED = SCATTERED_UNIFORM

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self.setup: Setup | None = None
        self._transport: cpu.Transport | None = None  # numpy path state

    def make_driver(self, window: vtk.vtkRenderWindow) -> GpuTransport:
        return GpuTransport(window)

    # -- hooks --------------------------------------------------------------------------------
    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        if changes.reset_accumulation or self.setup is None:
            self._restart(values)
        setup = self.setup
        assert setup is not None
        limit = values["max_iterations"] or self.automatic_iterations()
        count = min(int(values["iterations_per_frame"]), limit - self.iteration)
        if count > 0:
            t0 = time.perf_counter()
            if self._gpu is not None:
                self._gpu.step(count, values["diffusion_steps"])
            else:
                assert self._transport is not None
                self._transport.step(count)
                self._upload_cpu_state()
            self.iteration += count
            self._last_ms = (time.perf_counter() - t0) * 1e3
        self.converged = self.iteration >= limit
        gpu = self._gpu
        self._bind((gpu.rho, gpu.rho_s) if gpu is not None else None)

    def release(self) -> None:
        super().release()
        self._transport = None
        self.setup = None

    def automatic_iterations(self) -> int:
        """Iterations of ``max_iterations = 0``: four times what the light front needs to
        cross the grid's diagonal (it moves half a voxel per iteration)."""
        if self.setup is None:
            raise RuntimeError("the technique has not been prepared yet")
        return 4 * cpu.iterations_to_cross(self.setup.grid)

    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray:
        """The converged convected light ρ of ``light`` alone at every voxel, ``[z, y, x]``
        (0…1): what this technique uses as the direct light's visibility."""
        merged = {**self.defaults(), **values}
        grid = cpu.Grid(opacity.shape, spacing, self._origin())
        sigma_t = cpu.extinction(opacity, self.host.unit_distance)
        setup = Setup.build(grid, sigma_t, [light], merged, self.host.albedo,
                            self.host.unit_distance)
        transport = setup.transport(diffusion_steps=0)
        transport.step(merged["max_iterations"] or 4 * cpu.iterations_to_cross(grid))
        return transport.rho[0]

    # -- internals ----------------------------------------------------------------------------
    def _restart(self, values: Mapping[str, Any]) -> None:
        nx, ny, nz = self.host.dims
        grid = cpu.Grid((nz, ny, nx), self.host.spacing, self._origin())
        sigma_t = cpu.extinction(self.host.opacity_volume(), self.host.unit_distance)
        self.setup = Setup.build(grid, sigma_t, self.host.light_specs(), values, self.host.albedo,
                                 self.host.unit_distance)
        self.iteration = 0
        self.converged = False
        self._restarts += 1
        gpu = self._compute.get(self.host, values["backend"])
        if gpu is not None:
            try:
                gpu.reset(self.setup)
                self._backend = "gpu"
                return
            except GLUnavailableError as exc:
                self._compute.disable(exc)
        self._transport = self.setup.transport(values["diffusion_steps"])
        self._backend = "cpu"
        self._upload_cpu_state()

    def _upload_cpu_state(self) -> None:
        transport = self._transport
        assert transport is not None
        rw = self.host.render_window
        shape = transport.grid.shape_zyx
        channels = light_channels(len(transport.lights))
        direct = np.zeros((*shape, channels), np.float32)
        direct[..., : len(transport.lights)] = np.moveaxis(transport.rho[: len(transport.lights)],
                                                           0, -1)
        scattered = np.zeros((*shape, 4), np.float32)
        scattered[..., :3] = transport.rho_s
        if self._direct is None or self._direct.shape != shape or self._direct.channels != channels:
            if self._direct is not None:
                self._direct.release()
            self._direct = Texture3D(rw, shape, channels=channels, data=_squeeze(direct))
        else:
            self._direct.upload(_squeeze(direct))
        if self._scattered is None or self._scattered.shape != shape:
            if self._scattered is not None:
                self._scattered.release()
            self._scattered = Texture3D(rw, shape, channels=4, data=scattered)
        else:
            self._scattered.upload(scattered)


def _squeeze(a: np.ndarray) -> np.ndarray:
    return a[..., 0] if a.shape[-1] == 1 else a


class Setup:
    """What one accumulation runs on: grid, lights, per-voxel absorption and diffusion rate."""

    def __init__(self, grid: cpu.Grid, lights: list[cpu.LightSource],
                 colors: list[tuple[float, float, float]], sigma_a: np.ndarray,
                 lam: np.ndarray) -> None:
        self.grid, self.lights, self.colors = grid, lights, colors
        self.sigma_a, self.lam = sigma_a, lam

    @classmethod
    def build(cls, grid: cpu.Grid, sigma_t: np.ndarray, specs: Sequence[Any],
              values: Mapping[str, Any], albedo: float, unit_distance: float) -> Setup:
        specs = list(specs)[:4]
        lights = [cpu.LightSource(s.kind, tuple(float(v) for v in s.vector)) for s in specs]
        colors = [tuple(float(c) for c in getattr(s, "color", (1.0, 1.0, 1.0))) for s in specs]
        sigma_a = cpu.absorption_per_iteration(
            sigma_t, grid, albedo=albedo, mapping=values["absorption_mapping"],
            convection_extinction=values["convection_extinction"], unit_distance=unit_distance,
        )
        lam = cpu.diffusion_rate(sigma_t, grid, albedo)
        return cls(grid, lights, colors, sigma_a, lam)  # type: ignore[arg-type]

    def transport(self, diffusion_steps: int) -> cpu.Transport:
        return cpu.Transport(self.grid, self.lights, self.colors, self.sigma_a, self.lam,
                             diffusion_steps=diffusion_steps)


class GpuTransport:
    """The compute-shader path: ρ and ρ_s ping-pong between two textures each (a GPU updating
    in place would depend on invocation order; ping-pong matches numpy to float rounding)."""

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[tuple[str, int], ComputeProgram] = {}
        self._locations: dict[tuple[int, str], int] = {}
        self._rho: list[Texture3D] = []
        self._sigma_a: Texture3D | None = None
        self.diffusion: GpuDiffusion | None = None
        self._grid = cpu.Grid((1, 1, 1), (1.0, 1.0, 1.0))
        self._channels = 1
        self._lights: list[cpu.LightSource] = []
        self._colors: list[tuple[float, float, float]] = []
        self.program("convection", 1)  # fail now, not mid-frame, when compute cannot work

    @property
    def rho(self) -> Texture3D:
        return self._rho[0]

    @property
    def rho_s(self) -> Texture3D:
        assert self.diffusion is not None
        return self.diffusion.rho_s

    @property
    def textures(self) -> list[Texture3D]:
        own = [*self._rho, *(t for t in (self._sigma_a,) if t)]
        return own + (self.diffusion.textures if self.diffusion is not None else [])

    def program(self, kind: str, channels: int) -> ComputeProgram:
        key = (kind, channels)
        prog = self._programs.get(key)
        if prog is None:
            source = compute_source(f"{kind}.comp.glsl", {"VV_CHANNELS": str(channels)},
                                    __package__)
            prog = ComputeProgram(self.render_window, source, f"convection_diffusion {kind}")
            self._programs[key] = prog
        return prog

    def reset(self, setup: Setup) -> None:
        self._release_textures()
        rw = self.render_window
        shape = setup.grid.shape_zyx
        channels = light_channels(len(setup.lights))
        zeros = np.zeros(shape if channels == 1 else (*shape, channels), np.float32)
        self._rho = [Texture3D(rw, shape, channels=channels, data=zeros) for _ in range(2)]
        self._sigma_a = Texture3D(rw, shape, data=setup.sigma_a)
        self._sigma_a.tex.Deactivate()
        for tex in self._rho:
            tex.tex.Deactivate()  # created bound to units; image units are separate
        if self.diffusion is None:
            self.diffusion = GpuDiffusion(rw)
        self.diffusion.reset(setup.grid, setup.lam, channels)
        self._grid, self._lights, self._colors = setup.grid, setup.lights, setup.colors
        self._channels = channels

    def step(self, iterations: int, diffusion_steps: int) -> None:
        GL = gl(self.render_window)
        grid = self._grid
        nz, ny, nx = grid.shape_zyx
        groups = (-(-nx // GROUP[0]), -(-ny // GROUP[1]), -(-nz // GROUP[2]))
        conv = self.program("convection", self._channels)
        light_vecs = []
        for light in self._lights:
            if light.kind == "point":
                light_vecs += [*light.vector, 1.0]
            else:
                u = cpu.propagation(grid, light).reshape(3)
                light_vecs += [*(float(c) for c in u), 0.0]
        light_vecs += [0.0] * (16 - len(light_vecs))
        for _ in range(iterations):
            program = conv.use()
            self._set(conv, "vv_rhoIn", 0)
            self._set(conv, "vv_rhoOut", 1)
            self._set(conv, "vv_sigmaA", 2)
            self._set(conv, "vv_dims", nx, ny, nz)
            self._set(conv, "vv_ratio", *grid.axis_ratios.tolist(), integer=False)
            self._set(conv, "vv_origin", *grid.origin, integer=False)
            self._set(conv, "vv_spacing", *grid.spacing, integer=False)
            self._set(conv, "vv_sourceRadius2", max(grid.spacing) ** 2, integer=False)
            self._set(conv, "vv_numLights", len(self._lights))
            program.SetUniform4fv("vv_lightVec", 4, light_vecs)
            self._rho[0].bind_image(0, "read")
            self._rho[1].bind_image(1, "write")
            assert self._sigma_a is not None
            self._sigma_a.bind_image(2, "read")
            conv.dispatch(groups)
            self._rho.reverse()
            if diffusion_steps:
                assert self.diffusion is not None
                self.diffusion.run(self._rho[0], self._colors, diffusion_steps)
        unbind_images(GL, 4)
        conv.done()

    def _set(self, prog: ComputeProgram, name: str, *values: float, integer: bool = True) -> None:
        set_uniform(self._locations, prog, name, *values, integer=integer)

    def download(self) -> tuple[np.ndarray, np.ndarray]:
        """(ρ ``[z, y, x(, channels)]``, ρ_s ``[z, y, x, 4]``) for tests and verification."""
        return self._rho[0].download(), self.rho_s.download()

    def _release_textures(self) -> None:
        for tex in [*self._rho, *(t for t in (self._sigma_a,) if t)]:
            tex.release()
        self._rho = []
        self._sigma_a = None

    def release(self) -> None:
        self._release_textures()
        if self.diffusion is not None:
            self.diffusion.release()
            self.diffusion = None
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
        self._locations.clear()


class GpuDiffusion:
    """The diffusion step on the GPU (``diffusion.comp.glsl``): ρ_s ping-pongs between two RGBA
    textures; the direct light comes from a texture of up to four channels weighted by RGB
    colours. Also used by the hybrid method (seed 003 HD), which shares KD's diffusion."""

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[int, ComputeProgram] = {}
        self._locations: dict[tuple[int, str], int] = {}
        self._rho_s: list[Texture3D] = []
        self._lam: Texture3D | None = None
        self._grid = cpu.Grid((1, 1, 1), (1.0, 1.0, 1.0))
        self._channels = 1

    @property
    def rho_s(self) -> Texture3D:
        return self._rho_s[0]

    @property
    def textures(self) -> list[Texture3D]:
        return [*self._rho_s, *(t for t in (self._lam,) if t)]

    def program(self, channels: int) -> ComputeProgram:
        prog = self._programs.get(channels)
        if prog is None:
            source = compute_source("diffusion.comp.glsl", {"VV_CHANNELS": str(channels)},
                                    __package__)
            prog = ComputeProgram(self.render_window, source, "diffusion")
            self._programs[channels] = prog
        return prog

    def reset(self, grid: cpu.Grid, lam: np.ndarray, channels: int) -> None:
        """Zero ρ_s on ``grid`` with diffusion rate ``lam``; the direct light will have
        ``channels`` channels."""
        self._release_textures()
        rw = self.render_window
        empty = np.zeros((*grid.shape_zyx, 4), np.float32)
        self._rho_s = [Texture3D(rw, grid.shape_zyx, channels=4, data=empty) for _ in range(2)]
        self._lam = Texture3D(rw, grid.shape_zyx, data=lam)
        for tex in self.textures:
            tex.tex.Deactivate()  # created bound to units; image units are separate
        self._grid, self._channels = grid, channels

    def run(self, direct: Texture3D, colors: Sequence[tuple[float, float, float]],
            steps: int) -> None:
        """``steps`` diffusion steps of Σ_l colors[l]·direct[l] + ρ_s into ρ_s."""
        GL = gl(self.render_window)
        nz, ny, nx = self._grid.shape_zyx
        groups = (-(-nx // GROUP[0]), -(-ny // GROUP[1]), -(-nz // GROUP[2]))
        flat = [c for color in colors for c in color]
        flat += [0.0] * (12 - len(flat))
        prog = self.program(self._channels)
        program = prog.use()
        for name, unit in (("vv_direct", 0), ("vv_scatteredIn", 1), ("vv_scatteredOut", 2),
                           ("vv_lambda", 3)):
            set_uniform(self._locations, prog, name, unit)
        set_uniform(self._locations, prog, "vv_dims", nx, ny, nz)
        set_uniform(self._locations, prog, "vv_weights", *self._grid.axis_weights.tolist(),
                    integer=False)
        set_uniform(self._locations, prog, "vv_numLights", len(colors))
        program.SetUniform3fv("vv_color", 4, flat)
        assert self._lam is not None
        direct.bind_image(0, "read")
        self._lam.bind_image(3, "read")
        for _ in range(steps):
            self._rho_s[0].bind_image(1, "read")
            self._rho_s[1].bind_image(2, "write")
            prog.dispatch(groups)
            self._rho_s.reverse()
        unbind_images(GL, 4)
        prog.done()

    def _release_textures(self) -> None:
        for tex in self.textures:
            tex.release()
        self._rho_s = []
        self._lam = None

    def release(self) -> None:
        self._release_textures()
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
        self._locations.clear()


def set_uniform(cache: dict[tuple[int, str], int], prog: ComputeProgram, name: str,
                *values: float, integer: bool = True) -> None:
    """Set a uniform of the bound compute program; a missing one is an error (a renamed or
    optimised-away uniform must not be silently ignored)."""
    GL = gl(prog.render_window)
    handle = int(prog.prog.GetHandle())
    loc = cache.get((handle, name))
    if loc is None:
        loc = int(GL.glGetUniformLocation(handle, name))
        if loc < 0:
            raise GLUnavailableError(f"compute shader {prog.name!r} has no uniform {name!r}")
        cache[(handle, name)] = loc
    getattr(GL, f"glUniform{len(values)}{'i' if integer else 'f'}")(loc, *values)


def unbind_images(GL: Any, units: int) -> None:
    """Detach image units 0…units−1 (a texture left bound there stays referenced)."""
    for unit in range(units):
        GL.glBindImageTexture(unit, 0, 0, GL.GL_FALSE, 0, GL.GL_READ_ONLY, GL.GL_R32F)
