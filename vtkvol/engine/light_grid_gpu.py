"""The light grid on the GPU: the light texture and the drivers of
resources/shaders/propagate.comp.glsl (one dispatch per slice, plus one for the edge strips
of large directional slices; docs/shadow-volume.md §3). Expects VTK's context to be current.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping

import numpy as np
import vtk

from vtkvol.engine.gl import ComputeProgram, Texture3D, gl, unbind_images
from vtkvol.engine.light_grid import (
    SEED000_RADIUS,
    LightGrid,
    gauss_taps,
    in_plane_axes,
    plan_passes,
)
from vtkvol.engine.shaders import compute_source

#: Work-group size (u, v) of the propagation kernel.
GROUP = (8, 8)
#: Cells along u per invocation for directional lights (they share taps; see the kernel).
BLOCK = 4
#: The same when the edge strips are split off (EDGE_STRIPS_MIN_CELLS): fastest measured there.
SPLIT_BLOCK = 16
COMPUTE_SOURCE = "propagate.comp.glsl"
#: Directional transmittance with slices of at least this many cells: the block kernel is
#: compiled without the side-face arm and the edge strips of every slice (rays leaving through
#: a side face) are recomputed by the one-cell kernel in a second dispatch. The extra dispatch
#: and program switch (~0.05 ms a slice on llvmpipe) outweigh the saving below ~192² cells.
#: None: never (the previous design, kept for benchmarks/shadow_volume_timing.py).
EDGE_STRIPS_MIN_CELLS: int | None = 192 * 192


def ensure_work_textures(window: vtk.vtkRenderWindow, work: dict[int, Texture3D],
                         grid: LightGrid) -> None:
    """Make ``work[axis]`` the one-slice work texture of each sweep axis of ``grid``
    (re)allocated only when its shape changed; exactly one slice, so loads outside are 0."""
    for axis in range(3):
        ua, va = in_plane_axes(axis)
        shape = (2, grid.dims[va], grid.dims[ua])
        old = work.get(axis)
        if old is None or old.shape != shape:
            if old is not None:
                old.release()
            work[axis] = Texture3D(window, shape)


class LightTexture(Texture3D):
    """The light volume: one light per channel (1, 2 or 4 float channels), ``shape`` (nz, ny,
    nx) in light-grid cells, created filled with 1 (unshadowed). Linear filtering, clamped to a
    border of 1, so lookups that the offset pushes out of the volume see no shadow."""

    def __init__(
        self, render_window: vtk.vtkRenderWindow, shape_zyx: tuple[int, int, int], channels: int
    ) -> None:
        ones = np.ones((*shape_zyx, channels) if channels > 1 else shape_zyx, np.float32)
        super().__init__(render_window, shape_zyx, data=ones, border=1.0, channels=channels)


def edge_strips(dims: tuple[int, int, int], axis: int,
                vec: np.ndarray) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """The cells of a slice whose crossing with the previous slice may lie outside it, for a
    directional light (grid-space ``vec``) swept along ``axis``: up to two rectangles
    ``((u0, v0), (nu, nv))`` of the slice, one column or row wider than exact (the kernel
    decides per cell in float32; a cell computed by both kernels gets the same value)."""
    ua, va = in_plane_axes(axis)
    strips = []
    for b, other in ((ua, va), (va, ua)):
        step = float(vec[b]) / abs(float(vec[axis]))
        n = dims[b]
        if step > 0.0:
            lo = max(0, math.floor(n - 1 - step) - 1)
            span = (lo, n - lo)
        elif step < 0.0:
            span = (0, min(n, math.ceil(-step) + 1))
        else:
            continue
        if span[1] <= 0:
            continue
        full = (0, dims[other])
        if b == ua:
            strips.append(((span[0], full[0]), (span[1], full[1])))
        else:
            strips.append(((full[0], span[0]), (full[1], span[1])))
    return strips


class GpuPropagator:
    """Compute programs of shaders/propagate.comp.glsl and their dispatch (GL context current).

    Programs are compiled on first use per variant (prefilter; propagate × model × channels ×
    filter radius × cells per invocation × side-face arm) and kept until :meth:`release`.
    """

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[tuple, ComputeProgram] = {}
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
                    "VV_RADIUS": key[3], "VV_BLOCK": key[4], "VV_SIDE_FACES": int(key[5]),
                    "VV_GROUP_X": GROUP[0], "VV_GROUP_Y": GROUP[1],
                }
            source = compute_source(COMPUTE_SOURCE, {k: str(v) for k, v in defines.items()})
            prog = ComputeProgram(self.render_window, source, f"shadow {key}")
            self._programs[key] = prog
        return prog

    def prefilter(self, alpha: np.ndarray, sigma: Texture3D, grid: LightGrid) -> None:
        """TF opacity ``alpha`` (data resolution, ``[z, y, x]``, numpy) -> s on the light grid,
        for techniques that derive their own opacities (translucency's per-channel ones; the
        shadow volume reads the host's optical depth, :meth:`prefilter_texture_steps`).

        Full resolution: uploaded into ``sigma`` itself and converted in place (no extra
        memory). Coarser grids: a temporary data-resolution texture, converted in place, then
        reduced by box averaging into ``sigma``.
        """
        full = grid.dims == grid.data_dims
        data = sigma if full else Texture3D(self.render_window, alpha.shape)
        try:
            data.upload(alpha)
            data.tex.Deactivate()  # upload bound it to a unit; image units are separate
            prog = self.program(("convert",))
            prog.use()
            prog.set_uniform("vv_volume", 0)
            prog.set_uniform("vv_dataDims", *grid.data_dims)
            data.bind_image(0, "readwrite")
            nx, ny, nz = grid.data_dims
            prog.dispatch((-(-nx // 8), -(-ny // 8), -(-nz // 4)))
            if not full:
                prog = self._reduce(data, sigma, grid)
            unbind_images(self.render_window, 2)
            prog.done()
        finally:
            if not full:
                data.release()

    def prefilter_texture_steps(self, depth: Texture3D, sigma: Texture3D,
                                grid: LightGrid, *, chunked: bool) -> Iterator[float]:
        """The host's optical-depth texture (``Illuminator.opacity_texture("optical_depth")``:
        s per data voxel, classified and converted on the GPU) -> s on the light grid, with no
        upload and no conversion pass: copied into ``sigma`` at full resolution, reduced
        (pass 2) on a coarser grid. Yields 1.0 when done (``chunked``: waited for)."""
        GL = gl(self.render_window)
        if grid.dims == grid.data_dims:
            depth.copy_to(sigma)
        else:
            prog = self._reduce(depth, sigma, grid)
            unbind_images(self.render_window, 2)
            prog.done()
        if chunked:
            GL.glFinish()
        yield 1.0

    def _reduce(self, data: Texture3D, sigma: Texture3D, grid: LightGrid) -> ComputeProgram:
        """Dispatch pass 2: s per data voxel in ``data`` -> its box average per cell of the
        coarser light grid in ``sigma``. Returns the program (in use, images bound) for the
        caller to unbind and finish."""
        prog = self.program(("reduce",))
        prog.use()
        prog.set_uniform("vv_sigmaData", 0)
        prog.set_uniform("vv_sigmaOut", 1)
        prog.set_uniform("vv_dataDims", *grid.data_dims)
        prog.set_uniform("vv_gridDims", *grid.dims)
        prog.set_uniform("vv_gridStep", *grid.step, kind="f")
        data.bind_image(0, "read")
        sigma.bind_image(1, "write")
        mx, my, mz = grid.dims
        prog.dispatch((-(-mx // 8), -(-my // 8), -(-mz // 4)))
        return prog

    def propagate(
        self, sigma: Texture3D, work: Mapping[int, Texture3D], out: LightTexture,
        grid: LightGrid, kind: str, vec: np.ndarray, *, model: str, softness: float,
        unit_distance: float, channel: int,
    ) -> None:
        """All passes of one light into channel ``channel`` of ``out``; ``work`` holds one
        2-layer slice texture per propagation axis."""
        for _done in self.propagate_steps(sigma, work, out, grid, kind, vec, model=model,
                                          softness=softness, unit_distance=unit_distance,
                                          channel=channel, chunk_s=None):
            pass

    def propagate_steps(
        self, sigma: Texture3D, work: Mapping[int, Texture3D], out: LightTexture,
        grid: LightGrid, kind: str, vec: np.ndarray, *, model: str, softness: float,
        unit_distance: float, channel: int, chunk_s: float | None,
    ) -> Iterator[int]:
        """:meth:`propagate` in chunks of slices: with ``chunk_s`` (seconds), the slices
        dispatched since the last yield are waited for (``glFinish``) once they may take about
        that long, and the number of slices done so far is yielded; the chunk length adapts to
        the measured time. Everything is bound again after each yield (the caller may run
        other GL work in between). ``chunk_s=None``: one chunk, no wait (a frame's prepare)."""
        GL = gl(self.render_window)
        seed = model == "seed000"
        radius, g = (SEED000_RADIUS, np.ones(1)) if seed else gauss_taps(softness)
        passes = plan_passes(grid.dims, kind, vec)
        # Directional transmittance on large slices: the block kernel assumes every crossing
        # inside the slice and the one-cell kernel redoes the edge strips (see the kernel).
        split = False
        if kind != "point" and not seed and EDGE_STRIPS_MIN_CELLS is not None:
            ua, va = in_plane_axes(passes[0].axis)  # directional: exactly one pass
            split = grid.dims[ua] * grid.dims[va] >= EDGE_STRIPS_MIN_CELLS
        block = 1 if kind == "point" else (SPLIT_BLOCK if split else BLOCK)
        prog = self.program(("propagate", seed, out.channels, radius, block, not split))
        edge = self.program(("propagate", seed, out.channels, radius, 1, True)) if split else None
        barrier = GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT

        def bind(axis: int, p_sweep: int, restrict: bool) -> tuple[int, int]:
            if edge is not None:
                set_uniforms(edge, axis, p_sweep, restrict)
                edge_locs[:] = [edge.location(n) for n in ("vv_slice", "vv_first", "vv_cellOrigin")]
            set_uniforms(prog, axis, p_sweep, restrict)
            sigma.bind_image(0, "read")
            out.bind_image(2, "write" if out.channels == 1 else "readwrite")
            work[axis].bind_image(1, "readwrite")
            return prog.location("vv_slice"), prog.location("vv_first")

        edge_locs: list[int] = []

        def set_uniforms(target: ComputeProgram, axis: int, p_sweep: int, restrict: bool) -> None:
            # The pass is compiled in variants (model, channels, cells per invocation) and each
            # reads a subset: the variant-dependent uniforms are optional (measured per
            # variant: the seed-000 model reads no cell size, unit or Gaussian; one channel no
            # vv_channel; the block kernel no vv_point, vv_restrict, vv_cellOrigin).
            target.use()
            target.set_uniform("vv_sigma", 0)
            target.set_uniform("vv_work", 1)
            target.set_uniform("vv_out", 2)
            target.set_uniform("vv_dims", *grid.dims)
            target.set_uniform("vv_light", *(float(c) for c in vec), kind="f")
            target.set_uniform("vv_axis", axis)
            target.set_uniform("vv_sweep", p_sweep)
            target.set_uniform("vv_point", int(kind == "point"), optional=True)
            target.set_uniform("vv_cellUm", *grid.cell_um, kind="f", optional=True)
            target.set_uniform("vv_invUnit", 1.0 / unit_distance, kind="f", optional=True)
            target.set_uniform("vv_channel", channel, optional=True)
            target.set_uniform_array("vv_gauss", [float(x) for x in g], optional=True)
            target.set_uniform("vv_restrict", int(restrict), optional=True)
            target.set_uniform("vv_cellOrigin", 0, 0, optional=True)

        done = 0
        per_chunk = 4  # slices per chunk; adapted to chunk_s after each measured chunk
        for p in passes:
            a = p.axis
            ua, va = in_plane_axes(a)
            columns = -(-grid.dims[ua] // block)
            groups = (-(-columns // GROUP[0]), -(-grid.dims[va] // GROUP[1]), 1)
            strips = edge_strips(grid.dims, a, vec) if edge is not None else []
            slice_loc, first_loc = bind(a, p.sweep, p.restrict)
            issued, t0 = 0, time.perf_counter()
            for index, k in enumerate(p.slices):
                if strips:
                    prog.use()
                GL.glUniform1i(slice_loc, k)
                GL.glUniform1i(first_loc, int(index == 0))
                GL.glDispatchCompute(*groups)
                GL.glMemoryBarrier(barrier)
                if strips:
                    assert edge is not None
                    edge.use()
                    GL.glUniform1i(edge_locs[0], k)
                    GL.glUniform1i(edge_locs[1], int(index == 0))
                    for (u0, v0), (nu, nv) in strips:
                        GL.glUniform2i(edge_locs[2], u0, v0)
                        GL.glDispatchCompute(-(-nu // GROUP[0]), -(-nv // GROUP[1]), 1)
                    GL.glMemoryBarrier(barrier)
                done += 1
                issued += 1
                if chunk_s is not None and issued >= per_chunk and index + 1 < len(p.slices):
                    GL.glFinish()
                    elapsed = max(time.perf_counter() - t0, 1e-4)
                    per_chunk = max(1, min(4 * per_chunk, round(per_chunk * chunk_s / elapsed)))
                    unbind_images(self.render_window, 3)
                    prog.done()
                    yield done
                    slice_loc, first_loc = bind(a, p.sweep, p.restrict)
                    issued, t0 = 0, time.perf_counter()
        GL.glMemoryBarrier(GL.GL_TEXTURE_FETCH_BARRIER_BIT | GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT)
        unbind_images(self.render_window, 3)
        prog.done()
        if chunk_s is not None:
            GL.glFinish()
        yield done

    @staticmethod
    def slice_count(grid: LightGrid, kind: str, vec: np.ndarray) -> int:
        """Slices :meth:`propagate_steps` dispatches for one light (its progress total)."""
        return sum(len(p.slices) for p in plan_passes(grid.dims, kind, vec))

    def release(self) -> None:
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
