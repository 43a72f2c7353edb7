"""Cone tracing on the GPU: drivers of the compute shaders that build the filtered-opacity
pyramid (shaders/filter.comp.glsl) and bake the hemisphere AO (shaders/bake_ao.comp.glsl);
docs/cone-tracing.md. Expects VTK's context to be current.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from vtkvol.engine.gl import ComputeProgram, Texture3D, gl
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
        shapes = level_shapes(source.shape, source.mip_levels)
        if all(n & (n - 1) == 0 for n in source.shape):
            # Power-of-two sizes: every reduction is an exact 2×2×2 (or 2×2×1, …) box, which
            # the driver's own mipmap generation computes faster than our shader on llvmpipe.
            source.generate_mipmaps()
            self._gl.glMemoryBarrier(self._gl.GL_ALL_BARRIER_BITS)
        else:
            prog = self.down.use()
            for lev in range(1, len(shapes)):
                nz, ny, nx = shapes[lev]
                prog.SetUniform1iv("vv_srcSize", 3, list(shapes[lev - 1][::-1]))
                prog.SetUniform1iv("vv_dstSize", 3, [nx, ny, nz])
                source.bind_image(0, "read", lev - 1)
                source.bind_image(1, "write", lev)
                self.down.dispatch(((nx + 15) // 16, ny, 1))
            self.down.done()
        radius = (len(weights) - 1) // 2
        blur = self.blur(radius)
        prog = blur.use()
        prog.SetUniform1fv("vv_weights", len(weights), [float(w) for w in weights])
        # x: source → filtered, y: filtered → scratch, z: scratch → filtered (+ −ln(1 − F)).
        passes = ((source, filtered, 0), (filtered, scratch, 1), (scratch, filtered, 2))
        for lev, shape in enumerate(shapes):
            nz, ny, nx = shape
            prog.SetUniform1iv("vv_size", 3, [nx, ny, nz])
            for src, dst, axis in passes:
                prog.SetUniformi("vv_axis", axis)
                prog.SetUniformi("vv_convert", 1 if axis == 2 else 0)
                src.bind_image(0, "read", lev)
                dst.bind_image(1, "write", lev)
                lanes, rows = {0: (ny, nz), 1: (nx, nz), 2: (nx, ny)}[axis]
                blur.dispatch(((lanes + 15) // 16, rows, 1))
        blur.done()

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
        grid = ao.shape[::-1]
        gate_level, gate_offset = ao_gate(values["ao_resolution"])
        program = self.program(int(values["ao_cones"]), 1 if gate_offset == 0 else 8)
        prog = program.use()
        prog.SetUniformi("vv_filtered", filtered.activate())
        prog.SetUniformi("vv_opacity", source.activate())
        prog.SetUniform1iv("vv_gridDims", 3, [int(m) for m in grid])
        prog.SetUniform3f("vv_gridStep", [float(v) for v in ao_grid_step(data_dims, grid)])
        prog.SetUniform3f("vv_dims", [float(n) for n in data_dims])
        prog.SetUniform3f("vv_spacing", [float(v) for v in spacing])
        prog.SetUniformf("vv_unit", float(unit_distance))
        prog.SetUniformf("vv_maxLod", float(filtered.mip_levels - 1))
        prog.SetUniformf("vv_gateLod", float(min(gate_level, filtered.mip_levels - 1)))
        prog.SetUniformf("vv_gateOffset", float(gate_offset))
        prog.SetUniformf("vv_lodWidth", float(values["lod_width"] * values["sigma"]))
        prog.SetUniformf("vv_h", float(values["h"]))
        prog.SetUniformf("vv_h0", float(values["h0"]))
        prog.SetUniformf("vv_maxDistUm", float(values["max_distance"]) * min(spacing))
        ao.bind_image(0, "write", 0)
        program.dispatch(((grid[0] + 15) // 16, grid[1], grid[2]))
        program.done()

    def release(self) -> None:
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
