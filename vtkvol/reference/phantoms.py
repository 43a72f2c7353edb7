"""Synthetic opacity volumes for the reference tests and the benchmark.

Every phantom is a float32 opacity volume α ∈ [0, 1] of shape ``(n, n, n)``, indexed
``[z, y, x]``, meant for spacing (1, 1, 1) µm (so voxel units = µm). Except for
:func:`phantom_slab`, which is exactly voxelised, surfaces are anti-aliased over about one voxel
(α = α₀ · clip(0.5 − d, 0, 1) with d the signed distance in voxels, negative inside), so their
rendering does not depend on how the surface happens to cut the grid.
"""

from __future__ import annotations

from typing import Literal

import numpy as np


def _grid(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voxel index coordinates (z, y, x) as broadcastable float arrays."""
    if int(n) != n or n < 4:
        raise ValueError(f"phantom size n must be an integer >= 4, got {n}")
    c = np.arange(int(n), dtype=np.float64)
    return c[:, None, None], c[None, :, None], c[None, None, :]


def _solid(signed_distance: np.ndarray, opacity: float) -> np.ndarray:
    """Anti-aliased occupancy from a signed distance (voxels, negative inside) times α₀."""
    if not (0.0 <= opacity <= 1.0):
        raise ValueError(f"opacity {opacity} must be in [0, 1]")
    return opacity * np.clip(0.5 - signed_distance, 0.0, 1.0)


def phantom_sphere_over_slab(
    n: int = 64, *, sphere_opacity: float = 0.9, slab_opacity: float = 0.6
) -> np.ndarray:
    """A sphere floating above a horizontal slab: the classic hard/soft shadow scene.

    Slab: full extent in x and y, normal +z, z ∈ [0.1, 0.2]·(n−1) (thickness ≈ 0.1·n voxels).
    Sphere: radius 0.15·n voxels, centred at ((n−1)/2, (n−1)/2, 0.6·(n−1)) (x, y, z), so a light
    from +z casts its shadow on the slab's top face.
    """
    z, y, x = _grid(n)
    m = n - 1
    slab = np.abs(z - 0.15 * m) - 0.05 * m + 0.0 * (x + y)
    sphere = np.sqrt((x - m / 2) ** 2 + (y - m / 2) ** 2 + (z - 0.6 * m) ** 2) - 0.15 * n
    out = np.maximum(_solid(slab, slab_opacity), _solid(sphere, sphere_opacity))
    return out.astype(np.float32)


def phantom_hollow_sphere(
    n: int = 64, thickness: float = 3, *, opacity: float = 0.99
) -> np.ndarray:
    """A spherical shell ``thickness`` voxels thick, outer radius 0.4·(n−1), centred in the box.

    The inside is empty: with an opaque shell, a point inside is fully occluded (AO ≈ 1 once the
    AO distance exceeds the distance to the shell) and fully shadowed from outside lights.
    """
    if not (0 < thickness < 0.4 * (n - 1)):
        raise ValueError(f"thickness {thickness} voxels must be in (0, 0.4·(n−1))")
    z, y, x = _grid(n)
    m = n - 1
    r = np.sqrt((x - m / 2) ** 2 + (y - m / 2) ** 2 + (z - m / 2) ** 2)
    mid = 0.4 * m - thickness / 2
    return _solid(np.abs(r - mid) - thickness / 2, opacity).astype(np.float32)


def phantom_groove(
    n: int = 64, *, opacity: float = 0.9, profile: Literal["v", "u"] = "v"
) -> np.ndarray:
    """A block filling the lower half (top face at z = (n−1)/2, normal +z) with a groove on top.

    The groove runs along y, centred at x = (n−1)/2, 0.25·n voxels deep and 0.5·n wide at the
    top: ``"v"`` has planar 45° walls, ``"u"`` a half-cylinder of radius 0.25·n. Ambient
    occlusion darkens the groove's floor: the classic AO test shape.
    """
    z, y, x = _grid(n)
    m = n - 1
    top = m / 2
    w = 0.25 * n  # groove half-width at the top == depth
    cx = m / 2
    block = z - top + 0.0 * y
    # g: signed distance (voxels, negative inside) to the region cut away by the groove.
    if profile == "v":
        # Above the walls z = top − w + |x − cx| (slope 1): the distance is the vertical offset/√2.
        g = (top - w + np.abs(x - cx) - z) / np.sqrt(2.0)
    elif profile == "u":
        g = np.sqrt((x - cx) ** 2 + (z - top) ** 2) - w
    else:
        raise ValueError(f"profile must be 'v' or 'u', got {profile!r}")
    # Solid = block minus the groove: max of the block's distance and the negated groove's.
    return _solid(np.maximum(block, -g), opacity).astype(np.float32)


def phantom_slab(
    n: int = 64, thickness: int = 1, axis: Literal["x", "y", "z"] = "z", *, opacity: float = 0.5
) -> np.ndarray:
    """A homogeneous slab exactly ``thickness`` voxel layers thick, normal to ``axis``.

    The layers are indices (n − thickness)//2 … (n − thickness)//2 + thickness − 1 along the
    axis, the full extent along the other two; α = ``opacity`` there and 0 elsewhere (no
    anti-aliasing). With trilinear α (the references' medium) the optical depth across the slab
    along its normal is spacing · ((thickness − 1)·σ + 2·(1 + (1 − α)·ln(1 − α)/α)) per unit
    distance: σ inside, and a one-voxel ramp of α on each side.
    """
    if int(thickness) != thickness or not (1 <= thickness <= n):
        raise ValueError(f"thickness must be an integer in [1, n], got {thickness}")
    if axis not in ("x", "y", "z"):
        raise ValueError(f"axis must be 'x', 'y' or 'z', got {axis!r}")
    _grid(n)
    if not (0.0 <= opacity <= 1.0):
        raise ValueError(f"opacity {opacity} must be in [0, 1]")
    out = np.zeros((n, n, n), dtype=np.float32)
    lo = (n - int(thickness)) // 2
    sl = slice(lo, lo + int(thickness))
    index = {
        "z": (sl, slice(None), slice(None)),
        "y": (slice(None), sl, slice(None)),
        "x": (slice(None), slice(None), sl),
    }[axis]
    out[index] = opacity
    return out
