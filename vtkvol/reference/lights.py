"""Light descriptions shared by every reference.

Both lights live in **world space** (µm, axes x, y, z, first voxel centre at the origin; see
``docs/architecture.md``). Lights have no colour or power: every reference reports visibility
(transmittance) or light normalised to a unit-irradiance light, so the values compare directly
with the illumination volumes of the GPU techniques.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]


def _finite3(v: Sequence[float], what: str) -> Vec3:
    if len(v) != 3 or not all(math.isfinite(float(c)) for c in v):
        raise ValueError(f"{what} {tuple(v)} must be three finite numbers (x, y, z)")
    return (float(v[0]), float(v[1]), float(v[2]))


@dataclass(frozen=True)
class DirectionalLight:
    """A light at infinity.

    ``direction`` is a world-space vector (x, y, z) pointing from the scene **towards** the light.
    It need not be unit length; the references normalise it (a zero vector is rejected).
    """

    direction: Vec3

    def __post_init__(self) -> None:
        d = _finite3(self.direction, "light direction")
        if math.hypot(*d) == 0.0:
            raise ValueError("light direction must not be the zero vector")
        object.__setattr__(self, "direction", d)

    def unit(self) -> np.ndarray:
        """The normalised direction towards the light, shape (3,), order (x, y, z)."""
        d = np.asarray(self.direction, dtype=np.float64)
        return d / np.linalg.norm(d)


@dataclass(frozen=True)
class PointLight:
    """A point light at world ``position`` (x, y, z) in µm; it may lie inside the volume's box.

    ``falloff_distance`` d₀ (µm): 0 gives unit irradiance everywhere (what the visibility
    references assume); d₀ > 0 gives the irradiance (d₀/r)² at distance r, the host's
    inverse-square fall-off (used by :func:`~vtkvol.reference.scattering.inscattered_mc`).
    """

    position: Vec3
    falloff_distance: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _finite3(self.position, "light position"))
        d0 = float(self.falloff_distance)
        if not (math.isfinite(d0) and d0 >= 0.0):
            raise ValueError(f"falloff distance {self.falloff_distance} must be finite and >= 0")
        object.__setattr__(self, "falloff_distance", d0)


Light = DirectionalLight | PointLight


def light_rays(points: np.ndarray, light: Light) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions from ``points`` (M, 3) world µm towards ``light`` and the ray lengths in µm.

    A directional light is reached at infinity (length ``inf``; the march stops where the ray
    leaves the box). A point light is reached after ``|position − point|``; a point at the light's
    position gets length 0 (nothing in between, transmittance 1) and an arbitrary direction.
    """
    m = points.shape[0]
    if isinstance(light, DirectionalLight):
        return np.broadcast_to(light.unit(), (m, 3)).copy(), np.full(m, np.inf)
    if isinstance(light, PointLight):
        v = np.asarray(light.position, dtype=np.float64) - points
        dist = np.linalg.norm(v, axis=1)
        safe = dist > 0.0
        dirs = np.zeros_like(v)
        dirs[:, 2] = 1.0
        dirs[safe] = v[safe] / dist[safe, None]
        return dirs, dist
    raise TypeError(f"expected DirectionalLight or PointLight, got {type(light).__name__}")


def as_light_list(lights: Light | Sequence[Light]) -> list[Light]:
    """Accept one light or a sequence of lights; reject anything else."""
    items = [lights] if isinstance(lights, DirectionalLight | PointLight) else list(lights)
    if not items:
        raise ValueError("at least one light is needed")
    for light in items:
        if not isinstance(light, DirectionalLight | PointLight):
            raise TypeError(f"expected DirectionalLight or PointLight, got {type(light).__name__}")
    return items
