"""Translucency on the CPU (numpy): the indirect extinction, the cone blur and the RGBA light
volume of one light. No VTK, no GL.

The propagation itself is the shadow volume's (:func:`vtkvol.engine.light_grid.
propagate_cpu`, mirrored by its compute shader): the direct term is that model unchanged, the
indirect term runs the same propagation once per RGB channel through its own extinction, with the
per-slice Gaussian widened by the cone (docs/translucency.md). Spaces as in the shadow volume:
``[z, y, x]`` arrays at data voxels, the light grid in cells, lights in dataset space (µm).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from vtkvol.engine.light_grid import (
    MAX_OPACITY,
    LightGrid,
    light_softness,
    prefilter_cpu,
    propagate_cpu,
    softness_for_std,
    tap_std,
)

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import LightSpec

#: The direct term's blur: the shadow volume's transmittance model with the light's own size.
DIRECT_VALUES: Mapping[str, Any] = {
    "model": "transmittance", "softness_from": "light size", "softness": 0.0,
}
#: Largest per-slice softness (cells): the shadow volume's declared range.
MAX_SOFTNESS = 4.0


def direct_softness(
    spec: LightSpec, grid: LightGrid, origin: Sequence[float] = (0.0, 0.0, 0.0),
    direction: np.ndarray | None = None,
) -> float:
    """Per-slice softness (light-grid cells) of the direct term: the shadow volume's penumbra
    of the light's physical size (0 for an ideal light)."""
    return light_softness(spec, grid, DIRECT_VALUES, origin, direction)


def _propagation_axis(
    spec: LightSpec, grid: LightGrid, origin: Sequence[float], direction: np.ndarray | None
) -> int:
    """The dominant grid axis of the light's path through the grid's centre (as the shadow
    volume picks it for the penumbra)."""
    kind, vec = grid.light(spec, origin, direction)
    if kind == "point":
        centre = (np.asarray(grid.dims, float) - 1.0) / 2.0
        vec = centre - vec
    return int(np.argmax(np.abs(vec)))


def cone_std(angle_deg: float, grid: LightGrid, axis: int) -> float:
    """Standard deviation (in-plane cells) of the per-slice cone blur of half-angle
    ``angle_deg``: the cone's radius over one slice is d·tan θ (d = the cell edge along
    ``axis``, µm), taken as the Gaussian's 2σ reach, converted to cells of the slice plane."""
    if angle_deg <= 0.0:
        return 0.0
    cell = np.asarray(grid.cell_um, float)
    plane = float(np.mean([cell[a] for a in range(3) if a != axis]))
    return 0.5 * math.tan(math.radians(angle_deg)) * float(cell[axis]) / plane


def indirect_softness(
    spec: LightSpec, grid: LightGrid, angle_deg: float, origin: Sequence[float] = (0.0, 0.0, 0.0),
    direction: np.ndarray | None = None,
) -> float:
    """Per-slice softness of the indirect term: the light's own penumbra blur and the cone
    blur, added as independent spreads (variances add), at most the shadow volume's 4 cells."""
    std_direct = tap_std(direct_softness(spec, grid, origin, direction))
    std_cone = cone_std(angle_deg, grid, _propagation_axis(spec, grid, origin, direction))
    return softness_for_std(math.hypot(std_direct, std_cone), MAX_SOFTNESS)


def indirect_opacity(
    opacity: np.ndarray, colour: np.ndarray, extinction: float, tint: float
) -> np.ndarray:
    """The indirect term's opacity per unit distance, ``[z, y, x, 3]`` float32: extinction
    τ_i,c = k·τ·(1 − tint·colour_c) (τ = −ln(1 − α) per unit distance; ``colour`` ``[z, y, x,
    3]`` in 0…1) expressed as an opacity α_i,c = 1 − exp(−τ_i,c), the quantity both propagation
    paths take (so the GPU and numpy paths start from the same float32 numbers)."""
    a = np.clip(np.asarray(opacity, np.float64), 0.0, MAX_OPACITY)
    tau = -np.log1p(-a)
    factor = extinction * (1.0 - tint * np.clip(np.asarray(colour, np.float64), 0.0, 1.0))
    return (-np.expm1(-tau[..., None] * factor)).astype(np.float32)


def sigma_grids_cpu(
    opacity: np.ndarray, colour: np.ndarray, grid: LightGrid, extinction: float, tint: float
) -> list[np.ndarray]:
    """The four optical-depth grids the propagation reads (the shadow volume's
    :func:`prefilter_cpu` of the direct opacity, then of the indirect R, G and B opacity)."""
    alpha_i = indirect_opacity(opacity, colour, extinction, tint)
    return [prefilter_cpu(opacity, grid)] + [
        prefilter_cpu(np.ascontiguousarray(alpha_i[..., c]), grid) for c in range(3)
    ]


def light_rgba_cpu(
    sigmas: Sequence[np.ndarray], grid: LightGrid, kind: str, vec: np.ndarray, *,
    direct_soft: float, indirect_soft: float, unit_distance: float,
) -> np.ndarray:
    """One light's volume ``[z, y, x, 4]`` float32 from :func:`sigma_grids_cpu`'s grids
    (``kind``/``vec`` in grid space, :meth:`LightGrid.light`): RGB indirect, A direct."""
    out = np.empty((*grid.shape_zyx, 4), np.float32)
    for channel, sigma, soft in ((3, sigmas[0], direct_soft), (0, sigmas[1], indirect_soft),
                                 (1, sigmas[2], indirect_soft), (2, sigmas[3], indirect_soft)):
        out[..., channel] = propagate_cpu(sigma, grid, kind, vec, model="transmittance",
                                          softness=soft, unit_distance=unit_distance)
    return out


def translucency_volume_cpu(
    opacity: np.ndarray,
    colour: np.ndarray,
    spacing: Sequence[float],
    light: LightSpec,
    *,
    unit_distance: float | None = None,
    resolution: str = "full",
    angle: float = 15.0,
    extinction: float = 0.5,
    tint: float = 0.75,
    origin: Sequence[float] = (0.0, 0.0, 0.0),
    direction: np.ndarray | None = None,
) -> np.ndarray:
    """The light volume of one light on the light grid, ``[z, y, x, 4]`` float32 in 0…1:
    RGB = indirect transmittance, A = direct transmittance (the shadow volume's).

    ``opacity`` is the TF opacity per data voxel (``[z, y, x]``, per ``unit_distance`` µm,
    default the smallest voxel edge), ``colour`` the TF colour ``[z, y, x, 3]``; ``spacing``
    (x, y, z) µm; ``light`` in dataset space; the rest as the declared parameters.
    """
    grid = LightGrid.for_data(np.shape(opacity)[::-1], spacing, resolution)
    u = float(min(spacing)) if unit_distance is None else float(unit_distance)
    kind, vec = grid.light(light, origin, direction)
    return light_rgba_cpu(
        sigma_grids_cpu(opacity, colour, grid, extinction, tint), grid, kind, vec,
        direct_soft=direct_softness(light, grid, origin, direction),
        indirect_soft=indirect_softness(light, grid, angle, origin, direction),
        unit_distance=u,
    )
