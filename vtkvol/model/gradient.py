"""The gradient VTK's GPU ray caster classifies 2-D transfer functions with (pure numpy).

``vtkOpenGLGPUVolumeRayCastMapper``'s ``computeGradient`` (VTK 9.7) fetches the volume one
voxel away along each axis (beyond the border the clamped texture repeats the edge voxel),
in data units, divides each difference by ``2·sᵢ / mean(s)`` and normalises the length by a
quarter of the value range. The 2-D histogram, the spatialized classes and the illumination's
opacity volume all use these functions, so they see the gradient the renderer sees
(docs/transfer-functions-2d.md).
"""

from __future__ import annotations

import numpy as np

#: VTK normalises |∇I| by this fraction of the value range (``computeGradient``).
GRADIENT_RANGE_FRACTION = 0.25


def gradient_axis_max(value_range: tuple[float, float],
                      spacing: tuple[float, float, float]) -> float:
    """|∇I| (data units per µm) at the top of VTK's gradient axis (t = 1).

    ``spacing`` is (x, y, z) in µm."""
    span = float(value_range[1] - value_range[0]) or 1.0
    return GRADIENT_RANGE_FRACTION * span / (sum(spacing) / 3.0)


def vtk_gradient(values: np.ndarray, spacing: tuple[float, float, float]) -> np.ndarray:
    """VTK's shading gradient at every voxel centre of ``values`` ``[z, y, x]``, as
    ``[z, y, x, 3]`` (x, y, z components): ``(I[i+1] − I[i−1]) / (2·sᵢ / mean(s))`` with the
    edge voxel repeated outside, in data units scaled by the mean spacing (so its length is
    mean(s)·|∇I|). float32."""
    v = np.asarray(values, dtype=np.float32)
    mean = sum(spacing) / 3.0
    out = np.empty((*v.shape, 3), np.float32)
    padded = np.pad(v, 1, mode="edge")
    core = (slice(1, -1),) * 3
    for k, axis in enumerate((2, 1, 0)):  # x, y, z are array axes 2, 1, 0
        hi = list(core)
        lo = list(core)
        hi[axis] = slice(2, None)
        lo[axis] = slice(None, -2)
        out[..., k] = (padded[tuple(hi)] - padded[tuple(lo)]) / np.float32(
            2.0 * spacing[k] / mean)
    return out


def normalised_gradient(values: np.ndarray, spacing: tuple[float, float, float],
                        value_range: tuple[float, float]) -> np.ndarray:
    """The gradient-axis coordinate ``t`` in 0…1 that VTK's shader computes per voxel
    (a NaN neighbour gives 0: the bottom row)."""
    g = vtk_gradient(values, spacing)
    magnitude = np.sqrt(np.einsum("...k,...k->...", g, g, dtype=np.float32))
    span = float(value_range[1] - value_range[0])
    if not (np.isfinite(span) and span > 0.0):
        span = 1.0
    t = np.clip(magnitude / np.float32(GRADIENT_RANGE_FRACTION * span), 0.0, 1.0)
    return np.nan_to_num(t, nan=0.0)


def gradient_magnitude(values: np.ndarray, spacing: tuple[float, float, float]) -> np.ndarray:
    """|∇I| in data units per µm at every voxel, VTK's differences (not clamped)."""
    g = vtk_gradient(values, spacing)
    mean = sum(spacing) / 3.0
    return np.sqrt(np.einsum("...k,...k->...", g, g, dtype=np.float32)) / np.float32(mean)
