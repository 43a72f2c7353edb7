"""Error metrics between a method's output and a reference: images and per-voxel volumes."""

from __future__ import annotations

import math

import numpy as np


def _as_pair(image: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Both arrays as float64 in a common range, and that range (255 for two uint8 images)."""
    a = np.asarray(image)
    b = np.asarray(reference)
    if a.shape != b.shape:
        raise ValueError(f"image shape {a.shape} differs from reference shape {b.shape}")
    if a.ndim not in (2, 3):
        raise ValueError(f"expected a (H, W) or (H, W, C) image, got shape {a.shape}")
    if a.dtype == np.uint8 and b.dtype == np.uint8:
        return a.astype(np.float64), b.astype(np.float64), 255.0
    # Mixed or float inputs: uint8 is rescaled to [0, 1] so both share data range 1.
    a = a / 255.0 if a.dtype == np.uint8 else a.astype(np.float64)
    b = b / 255.0 if b.dtype == np.uint8 else b.astype(np.float64)
    return a, b, 1.0


def image_metrics(image: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Compare a rendered image with a reference image of the same shape.

    Images are (H, W) or (H, W, C) (C = channels, e.g. RGB or RGBA; every channel given is
    compared, pass ``image[..., :3]`` to ignore alpha). Two uint8 images are compared in 0…255
    (data range 255); otherwise values are taken as floats in [0, 1] (data range 1), a uint8
    operand being divided by 255 first.

    Returns ``{"rmse", "psnr", "ssim", "max_abs"}``: rmse and max_abs in the image's own units,
    psnr = 20·log10(data_range / rmse) in dB (``inf`` for identical images), ssim from
    :func:`skimage.metrics.structural_similarity` with its default 7×7 uniform window (shrunk
    to the largest odd size that fits a small image), averaged over channels.
    """
    from skimage.metrics import structural_similarity

    a, b, data_range = _as_pair(image, reference)
    diff = a - b
    rmse = float(np.sqrt(np.mean(diff * diff)))
    psnr = math.inf if rmse == 0.0 else 20.0 * math.log10(data_range / rmse)
    win = min(7, a.shape[0], a.shape[1])
    win -= 1 - win % 2  # structural_similarity needs an odd window
    if win < 3:
        raise ValueError(f"image {a.shape} too small for SSIM (needs at least 3×3 pixels)")
    ssim = structural_similarity(
        a, b, data_range=data_range, channel_axis=-1 if a.ndim == 3 else None, win_size=win
    )
    return {"rmse": rmse, "psnr": psnr, "ssim": float(ssim), "max_abs": float(np.abs(diff).max())}


def volume_metrics(
    values: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None
) -> dict[str, float]:
    """Per-voxel error of ``values`` against ``reference`` (same shape, e.g. ``[z, y, x]``).

    ``mask`` (boolean, same shape) restricts the statistics to where shading is applied, e.g.
    ``opacity > 0.05``. Returns ``{"rmse", "max_abs", "mean_abs", "bias"}`` with
    bias = mean(values − reference) (positive: the method is too bright / transmits too much).
    """
    v = np.asarray(values, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if v.shape != r.shape:
        raise ValueError(f"values shape {v.shape} differs from reference shape {r.shape}")
    diff = v - r
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != v.shape or m.dtype != bool:
            raise ValueError(f"mask must be a boolean array of shape {v.shape}")
        diff = diff[m]
    if diff.size == 0:
        raise ValueError("no voxels to compare (empty volume or empty mask)")
    ad = np.abs(diff)
    return {
        "rmse": float(np.sqrt(np.mean(diff * diff))),
        "max_abs": float(ad.max()),
        "mean_abs": float(ad.mean()),
        "bias": float(diff.mean()),
    }
