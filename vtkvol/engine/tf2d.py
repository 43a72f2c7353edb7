"""VTK's 2-D transfer functions and the gradient its ray caster classifies with.

Everything here mirrors what ``vtkOpenGLGPUVolumeRayCastMapper`` (VTK 9.7) does, so that the
CPU side (:meth:`vtkvol.engine.illuminator.Illuminator.opacity_volume`, read by every
illumination technique) classifies each voxel exactly as the GPU does
(docs/transfer-functions-2d.md):

* **Value axis** (table x, texture s): the sample's value normalised over the component's
  scalar range ``[lo, hi]`` (``in_scalarsRange``, the data array's range per component).
* **Gradient axis** (table y, texture t): ``computeGradient`` takes central differences one
  voxel apart (``in_cellStep``; at the border the clamped texture repeats the edge voxel), in
  data units, divides each by ``2·spacingᵢ / mean(spacing)`` and normalises the length by a
  quarter of the value range: ``t = clamp(mean(spacing)·|∇I| / (0.25·(hi − lo)), 0, 1)``
  with |∇I| in data units per µm. So ``t = 1`` is |∇I| = 0.25·(hi − lo)/mean(spacing).
* **Lookup**: an RGBA float texture, linear filtering, clamp to edge; VTK resamples any table
  to at least 1024 texels per axis (a power of two), so tables are made at
  :data:`TABLE_SHAPE` and uploaded unchanged.
* **Opacity**: the table's alpha is used per *sample* (VTK applies no opacity-unit-distance
  correction to 2-D tables, unlike 1-D ones), and the gradient-opacity function is ignored
  in 2-D mode. The engine therefore writes ``1 − (1 − α)^(step/unit)`` into the table and
  keeps α per unit distance in a second array, :data:`UNIT_ALPHA_ARRAY`, for the CPU side.
* **Several components**: VTK 9.7 generates two compile errors for 2-D tables with more than
  one independent component (a gradient cache of one entry and a ``computeRGBAWithGrad``
  without ``;``); :func:`multi_component_fixes` are the replacements that make it compile.
  Dependent components (RGBA data) have no 2-D mode in VTK; vtkvol always renders
  independent components.
"""

from __future__ import annotations

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

from vtkvol.model.gradient import (  # re-exported: the engine's view of VTK's gradient
    GRADIENT_RANGE_FRACTION,
    gradient_axis_max,
    normalised_gradient,
    vtk_gradient,
)

__all__ = ["GRADIENT_RANGE_FRACTION", "TABLE_SHAPE", "UNIT_ALPHA_ARRAY", "TableImage",
           "gradient_axis_max", "lookup", "multi_component_fixes", "normalised_gradient",
           "normalised_values", "per_sample_alpha", "per_unit_alpha", "rgb_table",
           "unit_alpha_mtime",
           "unit_alpha_table", "vtk_gradient"]

#: (height = gradient rows, width = value columns) of the tables the engine uploads: VTK's
#: smallest size (``vtkOpenGLVolumeLookupTable::GetMaximumSupportedTextureWidth``), so VTK
#: never resamples them.
TABLE_SHAPE = (1024, 1024)
#: Name of the table image's second point array: alpha per opacity unit distance (h·w).
UNIT_ALPHA_ARRAY = "vtkvol_alpha_per_unit_distance"
def normalised_values(values: np.ndarray, value_range: tuple[float, float]) -> np.ndarray:
    """The value-axis coordinate ``s`` (0…1 inside the range) of every voxel; NaN reads the
    first column (the 1-D path maps NaN to the first node likewise)."""
    lo, hi = (float(r) for r in value_range)
    span = hi - lo
    if not (np.isfinite(span) and span > 0.0):
        return np.zeros(np.shape(values), np.float32)
    s = ((np.asarray(values, dtype=np.float64) - lo) / span).astype(np.float32)
    return np.nan_to_num(s, nan=0.0, posinf=1.0, neginf=0.0)


def lookup(table: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Bilinear lookup in ``table`` ``(h, w)`` or ``(h, w, k)`` at texture coordinates
    ``s`` (columns) and ``t`` (rows) in 0…1, as an OpenGL linear filter with clamp to edge
    reads it (texel centres at (i + ½)/w)."""
    h, w = table.shape[:2]
    x = np.clip(np.asarray(s, dtype=np.float32) * np.float32(w) - np.float32(0.5), 0, w - 1)
    y = np.clip(np.asarray(t, dtype=np.float32) * np.float32(h) - np.float32(0.5), 0, h - 1)
    x0 = np.minimum(x.astype(np.int32), max(w - 2, 0))
    y0 = np.minimum(y.astype(np.int32), max(h - 2, 0))
    fx = x - x0
    fy = y - y0
    dx = 1 if w > 1 else 0
    dy = w if h > 1 else 0
    flat = table.reshape(h * w, *table.shape[2:])
    i00 = y0 * np.int32(w) + x0
    if table.ndim == 3:
        fx = fx[..., None]
        fy = fy[..., None]
    top = flat[i00] * (1 - fx) + flat[i00 + dx] * fx
    bottom = flat[i00 + dy] * (1 - fx) + flat[i00 + dy + dx] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32, copy=False)


def per_sample_alpha(alpha_per_unit: np.ndarray, step: float, unit: float) -> np.ndarray:
    """Opacity of one ray step ``step`` from opacity per unit distance (both µm)."""
    a = np.clip(np.asarray(alpha_per_unit, dtype=np.float64), 0.0, 1.0)
    return (1.0 - np.power(1.0 - a, step / unit)).astype(np.float32)


def per_unit_alpha(alpha_per_sample: np.ndarray, step: float, unit: float) -> np.ndarray:
    """Inverse of :func:`per_sample_alpha` (a foreign table without :data:`UNIT_ALPHA_ARRAY`)."""
    a = np.clip(np.asarray(alpha_per_sample, dtype=np.float64), 0.0, 1.0)
    return (1.0 - np.power(1.0 - a, unit / step)).astype(np.float32)


class TableImage:
    """One component's 2-D TF as VTK reads it: a float RGBA ``vtkImageData`` of
    :data:`TABLE_SHAPE` (alpha per ray step) with alpha per unit distance beside it.

    :meth:`set_table` stores a new TF (per unit distance); :meth:`set_step` re-derives the
    per-step alpha only (interaction changes the step). The per-unit array keeps its MTime
    across step changes, so the illumination does not recompute for a camera drag."""

    def __init__(self) -> None:
        h, w = TABLE_SHAPE
        self.image = vtk.vtkImageData()
        self.image.SetDimensions(w, h, 1)
        self._rgba = np.zeros((h * w, 4), np.float32)
        self._unit = np.zeros(h * w, np.float32)
        scalars = numpy_to_vtk(self._rgba, deep=False)
        scalars.SetName("rgba")
        self.image.GetPointData().SetScalars(scalars)
        unit = numpy_to_vtk(self._unit, deep=False)
        unit.SetName(UNIT_ALPHA_ARRAY)
        self.image.GetPointData().AddArray(unit)
        self._step = 1.0
        self._unit_distance = 1.0

    def set_table(self, rgba_per_unit: np.ndarray, step: float, unit: float) -> None:
        """A new TF: ``(h, w, 4)`` RGBA with alpha per ``unit`` µm, drawn at ``step`` µm."""
        table = np.asarray(rgba_per_unit, dtype=np.float32).reshape(-1, 4)
        self._rgba[:, :3] = table[:, :3]
        self._unit[:] = table[:, 3]
        self.image.GetPointData().GetArray(UNIT_ALPHA_ARRAY).Modified()
        self._step, self._unit_distance = step, unit
        self._update_alpha()

    def set_step(self, step: float, unit: float) -> None:
        if (step, unit) != (self._step, self._unit_distance):
            self._step, self._unit_distance = step, unit
            self._update_alpha()

    def _update_alpha(self) -> None:
        self._rgba[:, 3] = per_sample_alpha(self._unit, self._step, self._unit_distance)
        self.image.GetPointData().GetScalars().Modified()
        self.image.Modified()


def unit_alpha_table(image: vtk.vtkImageData, step: float, unit: float) -> np.ndarray:
    """Alpha per ``unit`` µm of a component's 2-D table, ``(h, w)`` float32: vtkvol's own
    per-unit array, or else (a table someone else set) the per-step alpha converted back."""
    w, h, _ = image.GetDimensions()
    stored = image.GetPointData().GetArray(UNIT_ALPHA_ARRAY)
    if stored is not None:
        return vtk_to_numpy(stored).reshape(h, w).astype(np.float32, copy=False)
    scalars = image.GetPointData().GetScalars()
    if scalars is None or scalars.GetNumberOfComponents() < 4:
        raise RuntimeError("a 2-D transfer function must be an RGBA image")
    alpha = vtk_to_numpy(scalars).reshape(h, w, -1)[..., 3]
    return per_unit_alpha(alpha, step, unit)


def rgb_table(image: vtk.vtkImageData) -> np.ndarray:
    """Colour (r, g, b in 0…1) of a component's 2-D table, ``(h, w, 3)`` float32: what VTK's
    shader reads for a sample's colour (the step conversion touches alpha only)."""
    w, h, _ = image.GetDimensions()
    scalars = image.GetPointData().GetScalars()
    if scalars is None or scalars.GetNumberOfComponents() < 3:
        raise RuntimeError("a 2-D transfer function must be an RGBA image")
    return vtk_to_numpy(scalars).reshape(h, w, -1)[..., :3].astype(np.float32)


def unit_alpha_mtime(image: vtk.vtkImageData) -> int:
    """What changes when the classification (not only the step) of a table changes."""
    stored = image.GetPointData().GetArray(UNIT_ALPHA_ARRAY)
    return int(stored.GetMTime()) if stored is not None else int(image.GetMTime())


def multi_component_fixes(n_components: int) -> dict[str, str]:
    """Fragment-shader replacements (tag → code) that make VTK 9.7's 2-D TF shader compile
    for ``n_components`` > 1 independent components: a gradient cache with one entry per
    component, and ``computeRGBAWithGrad`` with its missing semicolons."""
    lookups = "".join(
        f"  if (component == {c}) return texture2D(in_transfer2D_0[{c}], "
        f"vec2(scalar[{c}], grad.w));\n" for c in range(n_components))
    return {
        "//VTK::GradientCache::Dec": f"vec4 g_gradients_0[{n_components}];",
        "//VTK::ComputeRGBA2DWithGradient::Dec": (
            "vec4 computeRGBAWithGrad(vec4 scalar, vec4 grad, int component)\n{\n"
            f"{lookups}  return vec4(0.0);\n}}\n"),
    }
