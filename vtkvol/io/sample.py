"""The app's built-in sample: a synthetic two-channel confocal stack of a cell cluster.

It looks like what vtkvol is for, so that every feature can be tried without a file:
packed cells (a jittered-grid Voronoi tessellation) with textured ellipsoidal nuclei in
channel 0 and thin membranes along the cell boundaries in channel 1, on anisotropic voxels
(z coarser than x, y), blurred along z like a confocal PSF, with a camera-like noise model
(background offset + Poisson shot noise + Gaussian read noise), stored as 12-bit values in
uint16. Deterministic for a given seed and built with numpy only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from vtkvol.io.volume_data import Spacing, VolumeData, as_spacing

__all__ = ["confocal_phantom"]

_CELL_SPACING_UM = 7.0  # typical distance between neighbouring cell centres
_MEMBRANE_HALF_WIDTH_UM = 0.25
_Z_PSF_SIGMA_UM = 0.6  # axial blur (the lateral PSF is below the sampling)
_OFFSET_ADU = 100.0  # camera/detector background offset
_GAIN_ADU_PER_PHOTON = 2.0
_READ_NOISE_ADU = 4.0
_NUCLEUS_PEAK_ADU = 2600.0
_MEMBRANE_PEAK_ADU = 1500.0
_CYTOPLASM_ADU = 60.0  # weak autofluorescence in the nuclear channel


def _upsample_linear(coarse: np.ndarray, shape: Sequence[int]) -> np.ndarray:
    """Separable linear interpolation of ``coarse`` to ``shape`` (a smooth random field)."""
    out = coarse
    for axis, n in enumerate(shape):
        m = out.shape[axis]
        t = np.linspace(0.0, m - 1.0, n, dtype=np.float32)
        i0 = np.minimum(t.astype(np.int64), max(m - 2, 0))
        w = t - i0
        i1 = np.minimum(i0 + 1, m - 1)
        shape_w = [1] * out.ndim
        shape_w[axis] = n
        w = w.reshape(shape_w)
        out = np.take(out, i0, axis=axis) * (1 - w) + np.take(out, i1, axis=axis) * w
    return out.astype(np.float32, copy=False)


def _blur_z(volume: np.ndarray, sigma_voxels: float) -> np.ndarray:
    """Gaussian blur along z only (axis 0), edges clamped."""
    if sigma_voxels < 0.3 or volume.shape[0] < 2:
        return volume
    radius = max(1, math.ceil(3 * sigma_voxels))
    taps = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 * (taps / sigma_voxels) ** 2)
    kernel /= kernel.sum()
    n = volume.shape[0]
    out = np.zeros_like(volume)
    for tap, weight in zip(taps, kernel, strict=True):
        index = np.clip(np.arange(n) + tap, 0, n - 1)
        out += np.float32(weight) * volume[index]
    return out


def _shot_noise(rng: np.random.Generator, mean_photons: np.ndarray) -> np.ndarray:
    """Poisson photon counts; λ ≥ 25 uses the normal approximation N(λ, λ).

    numpy's Poisson sampler is slow for large λ (0.25 s per million voxels), and at λ ≥ 25
    the normal approximation is indistinguishable in an image.
    """
    out = np.empty(mean_photons.shape, dtype=np.float32)
    low = mean_photons < 25.0
    out[low] = rng.poisson(mean_photons[low])
    high = ~low
    lam = mean_photons[high]
    out[high] = np.maximum(
        0.0, np.rint(lam + np.sqrt(lam) * rng.standard_normal(lam.shape, dtype=np.float32))
    )
    return out


def confocal_phantom(
    shape_zyx: Sequence[int] = (64, 128, 128),
    *,
    voxel_size_um: Sequence[float] = (0.2, 0.2, 0.6),
    seed: int = 0,
) -> VolumeData:
    """A synthetic confocal stack: channel 0 ``"nuclei"``, channel 1 ``"membranes"``.

    Parameters
    ----------
    shape_zyx
        Voxels along (z, y, x) (array order).
    voxel_size_um
        Voxel size (x, y, z) in µm; the default has z three times coarser than x and y, as
        in a typical confocal stack.
    seed
        Random seed; the same seed gives the same volume.

    Returns
    -------
    VolumeData
        uint16 ``[2, z, y, x]`` with values in 0…4095 (``metadata["bit_depth"] == 12``).
        About 0.2 s for the default 64 × 128 × 128.
    """
    nz, ny, nx = (int(v) for v in shape_zyx)
    if min(nz, ny, nx) < 1:
        raise ValueError(f"shape_zyx must be positive, got {tuple(shape_zyx)}")
    spacing = as_spacing(voxel_size_um)
    sx, sy, sz = spacing
    rng = np.random.default_rng(seed)
    zc = (np.arange(nz, dtype=np.float32) * sz)[:, None, None]
    yc = (np.arange(ny, dtype=np.float32) * sy)[None, :, None]
    xc = (np.arange(nx, dtype=np.float32) * sx)[None, None, :]
    extent = (nx * sx, ny * sy, nz * sz)

    # Cell centres on a jittered grid: packed like tissue, never two nuclei on top of each other.
    counts = [max(1, round(e / _CELL_SPACING_UM)) for e in extent]
    step = [e / n for e, n in zip(extent, counts, strict=True)]
    centres = np.array(
        [
            [(i + 0.5 + rng.uniform(-0.25, 0.25)) * step[0],
             (j + 0.5 + rng.uniform(-0.25, 0.25)) * step[1],
             (k + 0.5 + rng.uniform(-0.25, 0.25)) * step[2]]
            for k in range(counts[2])
            for j in range(counts[1])
            for i in range(counts[0])
        ],
        dtype=np.float32,
    )  # fmt: skip

    # Nearest and second-nearest centre distances (µm², per voxel) give the cell boundaries.
    # Each centre only touches a box of 1.3 cell spacings around it, so cost grows with
    # the volume, not with volume × cells.
    d1 = np.full((nz, ny, nx), np.inf, dtype=np.float32)
    d2 = np.full((nz, ny, nx), np.inf, dtype=np.float32)
    nuclei = np.zeros((nz, ny, nx), dtype=np.float32)
    reach = 1.3 * max(step)

    def box(cx: float, cy: float, cz: float, r: float) -> tuple[slice, slice, slice]:
        return (
            slice(max(0, int((cz - r) / sz)), min(nz, int((cz + r) / sz) + 2)),
            slice(max(0, int((cy - r) / sy)), min(ny, int((cy + r) / sy) + 2)),
            slice(max(0, int((cx - r) / sx)), min(nx, int((cx + r) / sx) + 2)),
        )

    for cx, cy, cz in centres:
        zs, ys, xs = box(cx, cy, cz, reach)
        d = (zc[zs] - cz) ** 2 + (yc[:, ys] - cy) ** 2 + (xc[:, :, xs] - cx) ** 2
        b1, b2 = d1[zs, ys, xs], d2[zs, ys, xs]
        np.minimum(b2, np.maximum(b1, d), out=b2)
        np.minimum(b1, d, out=b1)

        # Ellipsoidal nucleus, randomly sized and turned in the xy plane, soft-edged.
        ax, ay, az = rng.uniform(2.0, 3.0), rng.uniform(1.6, 2.6), rng.uniform(1.8, 2.8)
        angle = rng.uniform(0.0, math.pi)
        brightness = np.float32(rng.uniform(0.55, 1.0))
        zs, ys, xs = box(cx, cy, cz, max(ax, ay, az) + 0.5)
        dz, dy, dx = zc[zs] - cz, yc[:, ys] - cy, xc[:, :, xs] - cx
        c, s = math.cos(angle), math.sin(angle)
        u = (dx * c + dy * s) / ax
        v = (-dx * s + dy * c) / ay
        e = u * u + v * v + (dz / az) ** 2
        blob = np.clip((1.0 - e) * 3.0, 0.0, 1.0) * brightness
        np.maximum(nuclei[zs, ys, xs], blob, out=nuclei[zs, ys, xs])

    # Membrane: a thin shell where the two nearest centres are almost equally far.
    with np.errstate(invalid="ignore"):
        gap = (np.sqrt(d2) - np.sqrt(d1)) * 0.5  # ≈ distance to the boundary, µm
    membranes = np.exp(-((np.nan_to_num(gap, nan=1e3, posinf=1e3) / _MEMBRANE_HALF_WIDTH_UM) ** 2))
    membranes *= 0.75 + 0.25 * _upsample_linear(
        rng.random((max(2, nz // 6), max(2, ny // 10), max(2, nx // 10)), dtype=np.float32),
        (nz, ny, nx),
    )

    # Chromatin texture: a fine random field plus a coarser one, multiplied into the nuclei.
    fine = _upsample_linear(
        rng.random((max(2, nz // 2), max(2, ny // 4), max(2, nx // 4)), dtype=np.float32),
        (nz, ny, nx),
    )
    coarse = _upsample_linear(
        rng.random((max(2, nz // 8), max(2, ny // 16), max(2, nx // 16)), dtype=np.float32),
        (nz, ny, nx),
    )
    nuclei *= 0.45 + 0.35 * fine + 0.2 * coarse

    signal = np.empty((2, nz, ny, nx), dtype=np.float32)
    signal[0] = nuclei * _NUCLEUS_PEAK_ADU + _CYTOPLASM_ADU
    signal[1] = membranes * _MEMBRANE_PEAK_ADU
    sigma_z = _Z_PSF_SIGMA_UM / sz
    for ch in range(2):
        signal[ch] = _blur_z(signal[ch], sigma_z)

    photons = _shot_noise(rng, signal / _GAIN_ADU_PER_PHOTON)
    adu = photons * _GAIN_ADU_PER_PHOTON + _OFFSET_ADU
    adu += rng.normal(0.0, _READ_NOISE_ADU, size=adu.shape).astype(np.float32)
    array = np.clip(np.rint(adu), 0, 4095).astype(np.uint16)

    return VolumeData.from_array(
        array,
        Spacing(sx, sy, sz),
        ["nuclei", "membranes"],
        voxel_size_from_metadata=True,
        metadata={
            "format": "sample",
            "axes": "CZYX",
            "generator": "confocal_phantom",
            "seed": int(seed),
            "cells": len(centres),
            "bit_depth": 12,
            "voxel_size_source": "sample definition",
        },
    )
