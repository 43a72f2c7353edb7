"""Counter-based random numbers and direction sampling for the Monte-Carlo references.

Random numbers are a pure function of (seed, the evaluation point's world coordinates, the
ray/path index, a purpose tag, a draw counter), hashed with the SplitMix64 finaliser; there is no
generator state. Hence

* results are deterministic for a given seed and independent of chunk sizes;
* a voxel gets exactly the same estimate whether the whole volume is evaluated or only a
  ``points=`` subset that contains its centre (same float64 coordinates);
* lock-step loops can draw "the i-th number of every path" with one vectorised call.

``u = mix(key + (counter + 1)·γ)`` is exactly the SplitMix64 sequence seeded with ``key``
(γ = 0x9E3779B97F4A7C15), a generator that passes BigCrush; keys are themselves hashed, so
different points and paths get unrelated sequences.

Directions are world-space unit vectors (x, y, z), returned as (M, 3) float64.
"""

from __future__ import annotations

import numpy as np

_MASK = (1 << 64) - 1
_GAMMA = 0x9E3779B97F4A7C15
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = (np.uint64(s) for s in (30, 27, 31, 11))


def _mix_int(x: int) -> int:
    """SplitMix64 finaliser on a Python int (no numpy scalar overflow warnings)."""
    z = x & _MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser on a uint64 array (array arithmetic wraps modulo 2**64 silently)."""
    z = x ^ (x >> _S30)
    z *= _M1
    z ^= z >> _S27
    z *= _M2
    z ^= z >> _S31
    return z


def point_keys(points: np.ndarray, seed: int) -> np.ndarray:
    """One uint64 key per world point (M, 3) µm, from the seed and the coordinates' float64 bits."""
    p = np.ascontiguousarray(points, dtype=np.float64) + 0.0  # + 0.0 turns −0.0 into 0.0
    bits = p.view(np.uint64).reshape(-1, 3)
    h = np.full(bits.shape[0], _mix_int(int(seed) + _GAMMA), dtype=np.uint64)
    for a in range(3):
        h = _mix((h ^ bits[:, a]) + np.uint64(_GAMMA))
    return h


def stream_keys(keys: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Key of stream ``index`` (e.g. ray or path number, int array) of each point key."""
    idx = np.asarray(index).astype(np.uint64)
    return _mix(keys ^ _mix(idx * np.uint64(_GAMMA) + np.uint64(_GAMMA)))


def tagged(keys: np.ndarray, tag: int) -> np.ndarray:
    """Derived keys for one purpose (e.g. "direction at bounce 3"), so streams never overlap."""
    return _mix(keys ^ np.uint64(_mix_int(tag * _GAMMA + 0x5DEECE66D)))


def uniform(keys: np.ndarray, counter: int) -> np.ndarray:
    """The ``counter``-th uniform number in (0, 1] of each key's sequence (float64, 53 bits)."""
    offset = np.uint64(((int(counter) + 1) * _GAMMA) & _MASK)
    x = _mix(keys + offset)
    return ((x >> _S11).astype(np.float64) + 1.0) * (1.0 / 9007199254740992.0)


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (M, 3) completing unit vectors ``n`` (M, 3) to a right-handed frame.

    Branchless construction of Duff et al. 2017 ("Building an orthonormal basis, revisited").
    """
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    sign = np.where(nz >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx], axis=1)
    s = np.stack([b, sign + ny * ny * a, -ny], axis=1)
    return t, s


def around(axis: np.ndarray, cos_theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit directions at polar angle θ (given as cos θ) and azimuth φ (radians) about ``axis``.

    With cos θ = 1 the result is ``axis`` bit for bit (1·axis + 0·…), which makes a zero-width
    cone reproduce the single-ray transmittance exactly.
    """
    t, s = orthonormal_basis(axis)
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
    return (
        cos_theta[:, None] * axis
        + (sin_theta * np.cos(phi))[:, None] * t
        + (sin_theta * np.sin(phi))[:, None] * s
    )


def uniform_sphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions uniform over the sphere (pdf 1/4π) from two uniform numbers each."""
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def cosine_hemisphere(normal: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions about unit ``normal`` with pdf cos θ / π (Malley: disc sampling lifted up)."""
    return around(normal, np.sqrt(np.maximum(0.0, 1.0 - u1)), 2.0 * np.pi * u2)


def uniform_cone(axis: np.ndarray, cos_max: float, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions uniform in solid angle within the cone {θ ≤ θ_max} about unit ``axis``.

    cos θ is uniform on [cos θ_max, 1] (uniform solid angle); u1 = 1 maps to cos θ = cos θ_max.
    """
    return around(axis, 1.0 - u1 * (1.0 - cos_max), 2.0 * np.pi * u2)
