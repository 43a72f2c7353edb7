"""Cone tracing on the GPU: drivers of the compute shaders that build the filtered-opacity
pyramid (shaders/filter.comp.glsl) and bake the hemisphere AO (shaders/bake_ao.comp.glsl);
docs/cone-tracing.md. Expects VTK's context to be current.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np

from vtkvol.engine.gl import ComputeProgram, Texture3D, gl, unbind_images
from vtkvol.engine.shaders import compute_source
from vtkvol.plugins.cone_traced.cpu import (
    _FRAME_A,
    _FRAME_B,
    MAX_OPACITY,
    MAX_STEPS,
    NORMAL_EPS,
    TAU_EXIT,
    ao_gate,
    ao_grid_step,
    hemisphere_pattern,
    level_shapes,
)


class GpuFilter:
    """The compute-shader pipeline: source pyramid, then three blur passes per level.

    The blur program is compiled per kernel radius (a compile-time constant lets the sliding
    window live in registers); programs are kept, so changing σ back and forth is cheap.
    """

    def __init__(self, render_window: Any) -> None:
        self.render_window = render_window
        self._gl = gl(render_window)
        self.down = self._build(0, 0)
        self._blur: dict[int, ComputeProgram] = {}

    def _build(self, pass_id: int, radius: int) -> ComputeProgram:
        defines = {"VV_PASS": str(pass_id), "VV_RADIUS": str(radius),
                   "VV_MAX_OPACITY": repr(MAX_OPACITY)}
        name = "cone_traced.down" if pass_id == 0 else f"cone_traced.blur{radius}"
        return ComputeProgram(self.render_window,
                              compute_source("filter.comp.glsl", defines, __package__), name)

    def blur(self, radius: int) -> ComputeProgram:
        if radius not in self._blur:
            self._blur[radius] = self._build(1, radius)
        return self._blur[radius]

    def run(
        self, source: Texture3D, filtered: Texture3D, scratch: Texture3D, weights: np.ndarray
    ) -> None:
        """Fill ``source`` levels 1… from level 0, then ``filtered`` with D_L of every level."""
        for _ in self.run_steps(source, filtered, scratch, weights, chunked=False):
            pass

    def run_steps(
        self, source: Texture3D, filtered: Texture3D, scratch: Texture3D, weights: np.ndarray,
        *, chunked: bool,
    ) -> Iterator[float]:
        """:meth:`run` as a generator yielding the fraction done; ``chunked``: wait for the
        GPU (``glFinish``) and yield after the reduction and after every blur pass, binding
        everything again after each yield (the caller may run other GL work in between)."""
        shapes = level_shapes(source.shape, source.mip_levels)
        if all(n & (n - 1) == 0 for n in source.shape):
            # Power-of-two sizes: every reduction is an exact 2×2×2 (or 2×2×1, …) box, which
            # the driver's own mipmap generation computes faster than our shader on llvmpipe.
            source.generate_mipmaps()
            self._gl.glMemoryBarrier(self._gl.GL_ALL_BARRIER_BITS)
        else:
            down = self.down
            down.use()
            for lev in range(1, len(shapes)):
                nz, ny, nx = shapes[lev]
                down.set_uniform_array("vv_srcSize", list(shapes[lev - 1][::-1]), kind="i")
                down.set_uniform_array("vv_dstSize", [nx, ny, nz], kind="i")
                source.bind_image(0, "read", lev - 1)
                source.bind_image(1, "write", lev)
                down.dispatch(((nx + 15) // 16, ny, 1))
            unbind_images(self.render_window, 2)
            down.done()
        # Work of each blur pass ∝ its level's voxels (level 0 is ~7/8 of the whole).
        sizes = [float(np.prod(shape)) for shape in shapes]
        total = 3.0 * sum(sizes) * (1.0 + 1.0 / 6.0)  # the reduction: about a sixth more
        done = 3.0 * sum(sizes) / 6.0
        if chunked:
            self._gl.glFinish()
            yield done / total
        radius = (len(weights) - 1) // 2
        blur = self.blur(radius)
        # x: source → filtered, y: filtered → scratch, z: scratch → filtered (+ −ln(1 − F)).
        passes = ((source, filtered, 0), (filtered, scratch, 1), (scratch, filtered, 2))
        for lev, shape in enumerate(shapes):
            nz, ny, nx = shape
            for src, dst, axis in passes:
                blur.use()
                blur.set_uniform_array("vv_weights", [float(w) for w in weights])
                blur.set_uniform_array("vv_size", [nx, ny, nz], kind="i")
                blur.set_uniform("vv_axis", axis)
                blur.set_uniform("vv_convert", 1 if axis == 2 else 0)
                src.bind_image(0, "read", lev)
                dst.bind_image(1, "write", lev)
                lanes, rows = {0: (ny, nz), 1: (nx, nz), 2: (nx, ny)}[axis]
                blur.dispatch(((lanes + 15) // 16, rows, 1))
                done += sizes[lev]
                if chunked and sizes[lev] * 64 >= sizes[0]:  # coarse levels: no own chunk
                    unbind_images(self.render_window, 2)
                    blur.done()
                    self._gl.glFinish()
                    yield done / total
        unbind_images(self.render_window, 2)
        blur.done()
        if chunked:
            self._gl.glFinish()
        yield 1.0

    def release(self) -> None:
        self.down.release()
        for prog in self._blur.values():
            prog.release()
        self._blur.clear()


def _glsl_unit(v: Sequence[float]) -> str:
    u = np.asarray(v, dtype=np.float64) / np.linalg.norm(v)
    return "vec3({:.8f}, {:.8f}, {:.8f})".format(*u)


class GpuAoBaker:
    """The compute shader that bakes the hemisphere AO (``bake_ao.comp.glsl``),
    one program per cone count (the pattern is compiled in)."""

    def __init__(self, render_window: Any) -> None:
        self.render_window = render_window
        self._programs: dict[tuple[int, int], ComputeProgram] = {}
        self.program(6, 1)  # compile now: a context without compute shaders fails here

    def program(self, cones: int, gate_taps: int) -> ComputeProgram:
        key = (cones, gate_taps)
        if key not in self._programs:
            pattern, half_angle = hemisphere_pattern(cones)
            dirs = ", ".join(f"vec3({x:.8f}, {y:.8f}, {z:.8f})" for x, y, z in pattern)
            defines = {
                "VV_CONES": str(cones), "VV_DIRS": f"vec3[{cones}]({dirs})",
                "VV_SIN": f"{math.sin(math.radians(half_angle)):.8f}",
                "VV_CONE_MAX_STEPS": str(MAX_STEPS), "VV_CONE_TAU_EXIT": f"{TAU_EXIT:.8f}",
                "VV_NORMAL_EPS": repr(NORMAL_EPS),
                "VV_FRAME_A": _glsl_unit(_FRAME_A), "VV_FRAME_B": _glsl_unit(_FRAME_B),
                "VV_GATE_TAPS": str(gate_taps),
            }
            self._programs[key] = ComputeProgram(
                self.render_window, compute_source("bake_ao.comp.glsl", defines, __package__),
                f"cone_traced.bake_ao{cones}_{gate_taps}",
            )
        return self._programs[key]

    def run(
        self, filtered: Texture3D, source: Texture3D, ao: Texture3D, *,
        data_dims: Sequence[int], spacing: Sequence[float], unit_distance: float,
        values: Mapping[str, Any],
    ) -> None:
        """Fill ``ao`` (grid ``ao.shape``) from the filtered and source pyramids."""
        for _ in self.run_steps(filtered, source, ao, data_dims=data_dims, spacing=spacing,
                                unit_distance=unit_distance, values=values, chunk_s=None):
            pass

    def run_steps(
        self, filtered: Texture3D, source: Texture3D, ao: Texture3D, *,
        data_dims: Sequence[int], spacing: Sequence[float], unit_distance: float,
        values: Mapping[str, Any], chunk_s: float | None,
    ) -> Iterator[float]:
        """:meth:`run` in slabs of AO grid slices, yielding the fraction done. With
        ``chunk_s`` (seconds) each slab is waited for (``glFinish``) and sized to take about
        that long; everything is bound again for every slab. ``None``: one dispatch."""
        grid = ao.shape[::-1]
        gate_level, gate_offset = ao_gate(values["ao_resolution"])
        program = self.program(int(values["ao_cones"]), 1 if gate_offset == 0 else 8)
        depth = int(grid[2])
        first, slab = 0, depth if chunk_s is None else 1
        while first < depth:
            count = min(slab, depth - first)
            t0 = time.perf_counter()
            self._bind(program, filtered, source, ao, grid, data_dims, spacing, unit_distance,
                       values, gate_level, gate_offset, first)
            program.dispatch(((grid[0] + 15) // 16, grid[1], count))
            unbind_images(self.render_window, 1)
            program.done()
            first += count
            if chunk_s is not None:
                gl(self.render_window).glFinish()
                per_slice = max(time.perf_counter() - t0, 1e-4) / count
                slab = max(1, min(4 * slab, int(chunk_s / per_slice)))
            yield first / depth

    @staticmethod
    def _bind(program: ComputeProgram, filtered: Texture3D, source: Texture3D, ao: Texture3D,
              grid: Sequence[int], data_dims: Sequence[int], spacing: Sequence[float],
              unit_distance: float, values: Mapping[str, Any], gate_level: int,
              gate_offset: float, z_offset: int) -> None:
        program.use()
        program.set_uniform("vv_filtered", filtered.activate())
        program.set_uniform("vv_opacity", source.activate())
        program.set_uniform_array("vv_gridDims", [int(m) for m in grid], kind="i")
        program.set_uniform("vv_gridStep", *(float(v) for v in ao_grid_step(data_dims, grid)),
                            kind="f")
        program.set_uniform("vv_dims", *(float(n) for n in data_dims), kind="f")
        program.set_uniform("vv_spacing", *(float(v) for v in spacing), kind="f")
        for name, value in (
                ("vv_unit", unit_distance), ("vv_maxLod", filtered.mip_levels - 1),
                ("vv_gateLod", min(gate_level, filtered.mip_levels - 1)),
                ("vv_gateOffset", gate_offset),
                ("vv_lodWidth", values["lod_width"] * values["sigma"]),
                ("vv_h", values["h"]), ("vv_h0", values["h0"]),
                ("vv_maxDistUm", float(values["max_distance"]) * min(spacing))):
            # vv_gateOffset is read only by the 8-tap gate variant (VV_GATE_TAPS 8).
            program.set_uniform(name, float(value), kind="f", optional=name == "vv_gateOffset")
        program.set_uniform("vv_zOffset", int(z_offset))
        ao.bind_image(0, "write", 0)

    def release(self) -> None:
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
