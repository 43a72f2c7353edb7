"""Sensible starting state for freshly opened data (pure: numpy + model, no VTK)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from vtkvol.model.scene import Channel, SceneModel, VolumeSource
from vtkvol.model.transfer_function import RGB, TransferFunction

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: Channel tints in the order fluorescence users expect (colour-blind-safe first pair).
CHANNEL_COLORS: tuple[RGB, ...] = (
    (0.1, 1.0, 0.3),  # green
    (1.0, 0.2, 1.0),  # magenta
    (0.2, 0.8, 1.0),  # cyan
    (1.0, 0.85, 0.1),  # yellow
)


def default_transfer_function(data: VolumeData, c: int, color: RGB) -> TransferFunction:
    """A ramp from the 0.5th to the 99.8th percentile, opacity rising to 0.6."""
    lo, hi = data.percentiles(c)
    rlo, rhi = data.channel_range(c)
    if not hi > lo:
        lo, hi = rlo, rhi if rhi > rlo else rlo + 1.0
    rlo, rhi = min(rlo, lo), max(rhi, hi)
    if not rhi > rlo:
        rhi = rlo + 1.0
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
