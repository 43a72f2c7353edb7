"""Transfer functions: colour and opacity control points over data values.

Values are in **data units** (the raw intensities of the channel, e.g. 0…4095 for 12-bit).
Opacity is the opacity of a slab one *opacity unit distance* thick (see
:class:`vtkvol.model.scene.RenderSettings`), so images do not depend on the sampling step.
Interpolation between points is linear; outside the first/last point the end value holds.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, field_validator, model_validator

from vtkvol.model.evented import EventedModel

RGB = tuple[float, float, float]


class TransferFunction(EventedModel):
    """Per-channel colour and opacity mapping.

    ``colors`` are ``(value, r, g, b)`` with r, g, b in 0…1; ``opacity`` are ``(value, alpha)``
    with alpha in 0…1. ``window`` is the value range shown by the editor (a zoom into a 16-bit
    range); ``window_range`` is how far the window may move (the data's value range). Growing
    the window grows the range; shrinking the range clips the window.
    """

    colors: list[tuple[float, float, float, float]] = Field(
        default_factory=lambda: [(0.0, 0.0, 0.0, 0.0), (255.0, 1.0, 1.0, 1.0)]
    )
    opacity: list[tuple[float, float]] = Field(
        default_factory=lambda: [(0.0, 0.0), (255.0, 1.0)]
    )
    window: tuple[float, float] = (0.0, 255.0)
    window_range: tuple[float, float] = (0.0, 255.0)

    @field_validator("colors")
    @classmethod
    def _check_colors(cls, v: list[tuple[float, float, float, float]]):
        if not v:
            raise ValueError("a transfer function needs at least one colour point")
        for point in v:
            if not all(np.isfinite(point)):
                raise ValueError(f"colour point {point} is not finite")
            if not all(0.0 <= c <= 1.0 for c in point[1:]):
                raise ValueError(f"colour point {point}: r, g, b must lie in 0…1")
        return sorted(v, key=lambda p: p[0])

    @field_validator("opacity")
    @classmethod
    def _check_opacity(cls, v: list[tuple[float, float]]):
        if not v:
            raise ValueError("a transfer function needs at least one opacity point")
        for value, alpha in v:
            if not (np.isfinite(value) and np.isfinite(alpha)):
                raise ValueError(f"opacity point {(value, alpha)} is not finite")
            if not 0.0 <= alpha <= 1.0:
                raise ValueError(f"opacity point {(value, alpha)}: alpha must lie in 0…1")
        return sorted(v, key=lambda p: p[0])

    @model_validator(mode="after")
    def _check_window(self):
        lo, hi = self.window
        rlo, rhi = self.window_range
        if not (np.isfinite([lo, hi, rlo, rhi]).all() and lo < hi and rlo < rhi):
            raise ValueError(f"window {self.window} / range {self.window_range} must be increasing")
        return self

    # -- evaluation (numpy; the engine and the CPU references share it) -------------------------
    def opacity_at(self, values: np.ndarray) -> np.ndarray:
        """Opacity (per opacity unit distance) at data ``values``; float32, same shape."""
        xs, ys = zip(*self.opacity, strict=True)
        return np.interp(np.asarray(values, dtype=np.float64), xs, ys).astype(np.float32)

    def color_at(self, values: np.ndarray) -> np.ndarray:
        """RGB at data ``values``; float32 array of shape ``values.shape + (3,)``."""
        pts = np.asarray(self.colors, dtype=np.float64)
        v = np.asarray(values, dtype=np.float64)
        return np.stack([np.interp(v, pts[:, 0], pts[:, k]) for k in (1, 2, 3)], -1).astype(
            np.float32
        )

    def set_window(self, lo: float, hi: float) -> None:
        """Set the editor window, growing ``window_range`` if needed (one event)."""
        with self.batch():
            rlo, rhi = self.window_range
            self.window_range = (min(rlo, lo), max(rhi, hi))
            self.window = (lo, hi)

    @property
    def value_span(self) -> tuple[float, float]:
        """Lowest and highest control-point value (the contrast limits the TF spans)."""
        values = [p[0] for p in self.colors] + [p[0] for p in self.opacity]
        return min(values), max(values)

    def rescale(self, lo: float, hi: float) -> None:
        """Stretch all control points linearly so they span ``lo``…``hi`` (contrast limits)."""
        if not hi > lo:
            raise ValueError(f"contrast limits ({lo}, {hi}) must be increasing")
        old_lo, old_hi = self.value_span
        scale = (hi - lo) / (old_hi - old_lo) if old_hi > old_lo else 0.0

        def f(v: float) -> float:
            return lo + (v - old_lo) * scale if scale else (lo if v <= old_lo else hi)

        with self.batch():
            self.set_window(min(lo, self.window[0]), max(hi, self.window[1]))
            self.colors = [(f(v), r, g, b) for v, r, g, b in self.colors]
            self.opacity = [(f(v), a) for v, a in self.opacity]

    @classmethod
    def ramp(
        cls,
        lo: float,
        hi: float,
        color: RGB = (1.0, 1.0, 1.0),
        *,
        max_opacity: float = 0.8,
        value_range: tuple[float, float] | None = None,
    ) -> TransferFunction:
        """A linear ramp from transparent black at ``lo`` to ``color`` at ``hi``."""
        rlo, rhi = value_range if value_range is not None else (min(lo, 0.0), hi)
        if rhi <= rlo:
            rhi = rlo + 1.0
        hi = hi if hi > lo else lo + 1.0
        return cls(
            colors=[(lo, 0.0, 0.0, 0.0), (hi, *color)],
            opacity=[(lo, 0.0), (hi, max_opacity)],
            window=(rlo, rhi),
            window_range=(rlo, rhi),
        )
