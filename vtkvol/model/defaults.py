"""Sensible starting state for freshly opened data (pure: numpy + model, no VTK)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from vtkvol.model.scene import Channel, SceneModel, VolumeSource
from vtkvol.model.transfer_function import RGB, TransferFunction, above

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: Channel tints in the order fluorescence users expect (colour-blind-safe first pair).
CHANNEL_COLORS: tuple[RGB, ...] = (
    (0.1, 1.0, 0.3),  # green
    (1.0, 0.2, 1.0),  # magenta
    (0.2, 0.8, 1.0),  # cyan
    (1.0, 0.85, 0.1),  # yellow
)


def contrast_limits(data: VolumeData, c: int) -> tuple[float, float]:
    """Automatic contrast limits for fluorescence: background made transparent.

    The low limit is the background level plus three robust standard deviations
    (median + 3·1.4826·MAD, at least one quantisation step above the median for integer data),
    so camera noise does not fog the view; the high limit is the 99.9th percentile. Computed on
    the same strided subsample as :meth:`VolumeData.percentiles`.
    """
    median, p999 = data.percentiles(c, 50.0, 99.9)
    p25, p75 = data.percentiles(c, 25.0, 75.0)
    sigma = (p75 - p25) / 1.349  # IQR-based robust sigma (MAD is 0 for quantised low values)
    step = 1.0 if data.array.dtype.kind in "ui" else 0.0
    lo = median + max(3.0 * sigma, step)
    hi = p999
    rlo, rhi = data.channel_range(c)
    if not hi > lo:  # sparse data: fall back to the full range
        lo, hi = rlo, rhi
    if not hi > lo:
        hi = above(lo)
    return lo, hi


def default_transfer_function(data: VolumeData, c: int, color: RGB) -> TransferFunction:
    """A ramp over :func:`contrast_limits`: transparent at the low limit, opacity 0.6 and the
    channel colour at the high limit."""
    lo, hi = contrast_limits(data, c)
    rlo, rhi = data.channel_range(c)
    rlo, rhi = min(rlo, lo), max(rhi, hi)
    return TransferFunction(
        colors=[(lo, *(0.25 * c_ for c_ in color)), (hi, *color)],
        opacity=[(lo, 0.0), (hi, 0.6)],
        window=(rlo, rhi),
        window_range=(rlo, rhi),
    )


def default_channels(data: VolumeData) -> list[Channel]:
    """One channel per data channel; single-channel data is shown in warm white."""
    n = data.n_channels
    colors = [(1.0, 0.95, 0.85)] if n == 1 else list(CHANNEL_COLORS[:n])
    return [
        Channel(
            name=data.channel_names[c] if c < len(data.channel_names) else f"ch{c}",
            color=colors[c],
            tf=default_transfer_function(data, c, colors[c]),
        )
        for c in range(n)
    ]


def scene_for(data: VolumeData) -> SceneModel:
    """A complete :class:`SceneModel` for ``data`` (channels, source, defaults elsewhere)."""
    return SceneModel(
        volume=VolumeSource(path=data.source),
        channels=default_channels(data),
    )
