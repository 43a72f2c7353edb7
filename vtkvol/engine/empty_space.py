"""Empty-space skipping: the occupancy grid rays jump over (``engine/occupancy.py`` decides).

One service of the technique host: per brick of voxels, whether anything there can be visible
under the current transfer functions, crop and slice weights; uploaded as a small 3-D texture
(``vv_essOccupancy``) that ``host_empty_space.glsl`` reads. Recomputed only when what decides
it changes (camera moves cost nothing); any failure leaves the full march and says why in
:attr:`EmptySpaceSkipper.stats`.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from vtkvol.engine import occupancy
from vtkvol.engine.gl import Texture3D
from vtkvol.engine.opacity_source import _node

# The failure is logged under the host's name: applications and tests filter on it.
logger = logging.getLogger("vtkvol.engine.illuminator")

_ESS_UNIFORMS = ("vv_essTexDims", "vv_essBricks")


class EmptySpaceSkipper:
    """Occupancy grid, texture and statistics of one illuminated volume."""

    def __init__(self, host: Any) -> None:
        # The host (engine/illuminator.py), typed loosely: importing it here would close an
        # import circle (scripts/import_graph.py).
        self._host = host
        #: (key, per-brick ranges, ms the pass took): computed once per data set.
        self._ranges: tuple[tuple, occupancy.BrickRanges, float] | None = None
        self._key: tuple | None = None
        self._texture: Texture3D | None = None
        #: What the last update found: ``active``, ``reason`` and, when computed, the grid's
        #: ``bricks`` (x, y, z), ``brick_voxels`` (x, y, z), ``empty_fraction`` and timings.
        self.stats: dict[str, Any] = {"active": False, "reason": "not rendered yet"}

    def update(self) -> None:
        """Recompute the occupancy grid when what decides it changed (data, TFs, crop, slice
        weights, blend mode, filter, the switch) and bind it; camera moves cost nothing."""
        mapper = self._host.volume.GetMapper()
        prop = self._host.volume.GetProperty()
        key = (self._host.changes.opacity_signature, self._host._skip_empty,
               int(mapper.GetBlendMode()),
               self._host._interpolation, int(prop.GetTransferFunctionMode()),
               mapper.GetMaskInput() is not None)
        if key == self._key:
            return
        self._key = key
        try:
            stats, grid = self._occupancy_grid()
            if grid is not None:
                self._upload_occupancy(grid)
        except Exception as exc:  # never lose the view to an optimisation
            logger.exception("empty-space skipping failed; rays march the whole volume")
            stats, grid = {"active": False, "reason": f"failed ({type(exc).__name__}: {exc})"}, None
        self.stats = stats
        if grid is None:
            self.drop()

    def _upload_occupancy(self, grid: np.ndarray) -> None:
        data = grid.astype(np.float32)
        if self._texture is None or self._texture.shape != data.shape:
            if self._texture is not None:
                self._texture.release()
                self._texture = None
            self._texture = Texture3D(self._host.render_window, data.shape, data=data)
        else:
            self._texture.upload(data)
        self._host.bind_texture("vv_essOccupancy", self._texture)
        nz, ny, nx = (int(n) for n in self._host.image.GetDimensions()[::-1])
        bz, by, bx = data.shape
        fu = self._host.shader_property.GetFragmentCustomUniforms()
        fu.SetUniform3f("vv_essTexDims", [float(nx), float(ny), float(nz)])
        fu.SetUniform3f("vv_essBricks", [float(bx), float(by), float(bz)])

    def drop(self) -> None:
        self._host.unbind_texture("vv_essOccupancy")
        fu = self._host.shader_property.GetFragmentCustomUniforms()
        for name in _ESS_UNIFORMS:
            fu.RemoveUniform(name)
        if self._texture is not None:
            self._texture.release()
            self._texture = None

    def _occupancy_grid(self) -> tuple[dict[str, Any], np.ndarray | None]:
        """``(stats, grid)``: the occupancy (bool ``[bz, by, bx]``) the shader reads, or None
        with the reason skipping does not apply to this volume's settings."""
        def off(reason: str) -> tuple[dict[str, Any], None]:
            return {"active": False, "reason": reason}, None

        if not self._host._skip_empty:
            return off("switched off")
        mapper = self._host.volume.GetMapper()
        prop = self._host.volume.GetProperty()
        if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_1D:
            return off("2-D transfer functions are not supported")
        if mapper.GetMaskInput() is not None:
            return off("masked volumes are not supported")
        blend = mapper.GetBlendMode()
        img = self._host.image
        nx, ny, nz = img.GetDimensions()
        scalars = img.GetPointData().GetScalars()
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1)
        ncomp = values.shape[-1]
        independent = ncomp == 1 or bool(prop.GetIndependentComponents())
        functions: list[tuple[np.ndarray, np.ndarray] | None] = [None] * ncomp
        for c in range(ncomp) if independent else [ncomp - 1]:
            fc = c if independent else 0
            if independent and ncomp > 1 and prop.GetComponentWeight(fc) <= 0:
                continue  # VTK multiplies this component's contribution by 0
            function = prop.GetScalarOpacity(fc)
            nodes = np.array([_node(function, i)[:2] for i in range(function.GetSize())])
            functions[c] = (nodes[:, 0], nodes[:, 1]) if len(nodes) else (
                np.zeros(1), np.zeros(1))
        composite = (vtk.vtkVolumeMapper.COMPOSITE_BLEND, vtk.vtkVolumeMapper.ADDITIVE_BLEND)
        if blend == vtk.vtkVolumeMapper.MAXIMUM_INTENSITY_BLEND:
            # The maximum of the samples left equals the full maximum, or both map to
            # opacity 0, only if zero opacity is a prefix of the value axis; the final
            # classification reads the slice weight at the ray's last position, which a jump
            # moves.
            if not all(f is None or occupancy.non_decreasing(f) for f in functions):
                return off("maximum-intensity projection needs non-decreasing opacity")
            if self._host._weights is not None:
                return off("maximum-intensity projection with slice weights")
        elif blend not in composite:
            return off("average, minimum-intensity and isosurface blending count or compare "
                       "every sample")
        apron = 2 if self._host.shader_builder.interpolation_sections() else 1
        brick = occupancy.brick_for_spacing(img.GetSpacing())
        range_key = (img.GetMTime(), scalars.GetMTime(), apron, brick)
        if self._ranges is None or self._ranges[0] != range_key:
            t0 = time.perf_counter()
            computed = occupancy.brick_ranges(values, apron=apron, brick=brick)
            self._ranges = (range_key, computed, (time.perf_counter() - t0) * 1e3)
        _key, ranges, ranges_ms = self._ranges
        t1 = time.perf_counter()
        # VTK samples each opacity table over the component's scalar range (the data's).
        table_range = []
        for c in range(ncomp):
            finite_lo = ranges.lo[c][np.isfinite(ranges.lo[c])]
            finite_hi = ranges.hi[c][np.isfinite(ranges.hi[c])]
            table_range.append((float(finite_lo.min()), float(finite_hi.max()))
                               if finite_lo.size and finite_hi.size else (np.nan, np.nan))
        if apron == 2:
            ranges = occupancy.widen_for_corrected(ranges)
        grid = occupancy.transfer_occupancy(ranges, functions, table_range)
        if mapper.GetCropping():
            grid &= occupancy.crop_occupancy(
                (nz, ny, nx), img.GetOrigin(), img.GetSpacing(),
                mapper.GetCroppingRegionPlanes(), int(mapper.GetCroppingRegionFlags()),
                brick=brick)
        if self._host._weights is not None and blend != vtk.vtkVolumeMapper.MAXIMUM_INTENSITY_BLEND:
            grid &= occupancy.weight_occupancy((nz, ny, nx), self._host._weights, brick=brick)
        empty = float(1.0 - grid.mean())
        stats = {
            "active": empty >= occupancy.MIN_EMPTY_FRACTION,
            "reason": "" if empty >= occupancy.MIN_EMPTY_FRACTION else (
                f"only {100 * empty:.0f} % of the bricks are empty (below "
                f"{100 * occupancy.MIN_EMPTY_FRACTION:.0f} %: the check per sample would cost "
                "more than the jumps save)"),
            "bricks": tuple(int(n) for n in grid.shape[::-1]),
            "brick_voxels": tuple(brick[::-1]),
            "brick_voxels_zyx": brick,
            "empty_fraction": empty,
            "ranges_ms": ranges_ms,
            "occupancy_ms": (time.perf_counter() - t1) * 1e3,
        }
        return stats, grid if stats["active"] else None
