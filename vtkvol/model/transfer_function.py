"""Transfer functions: colour and opacity control points over data values.

Values are in **data units** (the raw intensities of the channel, e.g. 0…4095 for 12-bit).
Opacity is the opacity of a slab one *opacity unit distance* thick (see
:class:`vtkvol.model.scene.RenderSettings`), so images do not depend on the sampling step.
Interpolation between points is linear; outside the first/last point the end value holds.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from vtkvol.model.evented import EventedModel
from vtkvol.model.tf_paint import TFPaintLayer, check_range

RGB = tuple[float, float, float]


#: Most colour (and most opacity) points a transfer function is rendered with: the width of
#: the renderer's classification tables (vtkvol.engine.tf2d.TABLE_SHAPE, the empty-space
#: skipping table). A longer function (a session with 100 000 points took minutes to hand to
#: VTK, which re-sorts its function on every point added) is sampled down to this many
#: points: :meth:`TransferFunction.reduced`.
MAX_POINTS = 1024


def above(lo: float) -> float:
    """A value just above ``lo`` (data units) to end a range that would otherwise be empty.

    ``lo + 1`` for ordinary data; where 1 is below the float spacing (a uint64 volume near
    2⁶⁴, whose values all round to one float) a step of one millionth of ``lo``, so the range
    stays increasing in float32 too.
    """
    return lo + max(1.0, abs(lo) * 1e-6)


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

    def reduced(self, max_points: int = MAX_POINTS) -> TransferFunction | None:
        """A copy with at most ``max_points`` colour and at most ``max_points`` opacity points,
        or None when this function has no more than that.

        A list that is too long is replaced by the function sampled at ``max_points`` evenly
        spaced values from its first to its last point (data units); the ends are kept
        exactly, and a feature narrower than one sample spacing is smoothed over it, as the
        renderer's table of :data:`MAX_POINTS` entries would smooth it anyway.
        """
        changes: dict[str, list[tuple[float, ...]]] = {}
        if len(self.colors) > max_points:
            xs = np.linspace(self.colors[0][0], self.colors[-1][0], max_points)
            rgb = np.clip(self.color_at(xs).astype(np.float64), 0.0, 1.0)
            changes["colors"] = [(float(x), *map(float, c)) for x, c in zip(xs, rgb, strict=True)]
        if len(self.opacity) > max_points:
            xs = np.linspace(self.opacity[0][0], self.opacity[-1][0], max_points)
            alpha = np.clip(self.opacity_at(xs).astype(np.float64), 0.0, 1.0)
            changes["opacity"] = [(float(x), float(a)) for x, a in zip(xs, alpha, strict=True)]
        return type(self).model_validate({**self.model_dump(), **changes}) if changes else None

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
            rhi = above(rlo)
        hi = hi if hi > lo else above(lo)
        return cls(
            colors=[(lo, 0.0, 0.0, 0.0), (hi, *color)],
            opacity=[(lo, 0.0), (hi, max_opacity)],
            window=(rlo, rhi),
            window_range=(rlo, rhi),
        )


# -- 2-D transfer functions (seed 001 eq. 2.45) ------------------------------------------------
#: Largest lookup table a 2-D TF rasterises to, per axis (VTK uploads at least 1024 × 1024).
MAX_TABLE_SIZE = 4096
#: Most primitives one 2-D TF may hold (an editor's widget list, not a paint buffer).
MAX_PRIMITIVES = 256


class TFPrimitive(EventedModel):
    """One region of a 2-D transfer function in (value, gradient magnitude) space.

    Coordinates: ``value_range`` in **data units**, ``gradient_range`` in **data units per
    µm** (|∇I| with the voxel size applied), both ``(low, high)`` with low < high.

    * ``kind="rectangle"``: the box ``value_range × gradient_range``.
    * ``kind="triangle"``: Kniss's boundary widget inscribed in that box: apex at
      (centre value, gradient low), base along gradient high from value low to value high.
      Boundaries between two materials form arcs that rise from the axis, which it covers.

    ``opacity`` (0…1, per opacity unit distance like the 1-D TF) and ``color`` (r, g, b in 0…1)
    hold inside. ``soft_edge`` (0…1) is the fraction of the half-width (and half-height) over
    which opacity ramps linearly from 0 at the border to full inside; 0 is a hard edge. A
    border lying on the gradient axis' origin (gradient low ≤ 0) does not fade: nothing lies
    below it.
    """

    kind: Literal["rectangle", "triangle"] = "rectangle"
    value_range: tuple[float, float] = (0.0, 255.0)
    gradient_range: tuple[float, float] = (0.0, 1.0)
    color: RGB = (1.0, 1.0, 1.0)
    opacity: float = Field(0.5, ge=0.0, le=1.0)
    soft_edge: float = Field(0.0, ge=0.0, le=1.0)

    @field_validator("value_range", "gradient_range")
    @classmethod
    def _increasing(cls, v: tuple[float, float], info):
        return check_range(v, info.field_name.replace("_", " "))

    @field_validator("color")
    @classmethod
    def _rgb(cls, v: RGB):
        if not all(math.isfinite(c) and 0.0 <= c <= 1.0 for c in v):
            raise ValueError(f"primitive colour {v}: r, g, b must lie in 0…1")
        return v

    def coverage(self, values: np.ndarray, gradients: np.ndarray) -> np.ndarray:
        """Weight 0…1 of this primitive (before ``opacity``) at broadcastable ``values`` (data
        units) and ``gradients`` (data units per µm); float64."""
        v = np.asarray(values, dtype=np.float64)
        g = np.asarray(gradients, dtype=np.float64)
        v0, v1 = self.value_range
        g0, g1 = self.gradient_range
        half_g = 0.5 * (g1 - g0)
        if self.kind == "rectangle":
            half_v = 0.5 * (v1 - v0)
            inside_v = np.minimum(v - v0, v1 - v) / half_v
        else:
            # Half-width grows linearly from 0 at the apex (g0) to (v1 - v0)/2 at the base (g1).
            half_v = 0.5 * (v1 - v0) * np.clip((g - g0) / (g1 - g0), 0.0, None)
            centre = 0.5 * (v0 + v1)
            with np.errstate(divide="ignore", invalid="ignore"):
                inside_v = np.where(half_v > 0, 1.0 - np.abs(v - centre) / half_v, -1.0)
        top = (g1 - g) / half_g
        if self.kind == "triangle":
            inside = np.minimum(inside_v, top)  # inside_v < 0 below the apex
        elif g0 > 0:
            inside = np.minimum(np.minimum(inside_v, top), (g - g0) / half_g)
        else:  # the bottom border lies on the axis' origin: it does not fade
            inside = np.where(g >= g0, np.minimum(inside_v, top), -1.0)
        if self.soft_edge > 0:
            return np.clip(inside / self.soft_edge, 0.0, 1.0)
        return (inside >= 0).astype(np.float64)


class TransferFunction2D(EventedModel):
    """A 2-D transfer function over (value, gradient magnitude): RGBA from a list of
    :class:`TFPrimitive` regions (seed 001 eq. 2.45) and an optional painted raster ``paint``
    (:class:`~vtkvol.model.tf_paint.TFPaintLayer`, ``None`` until the user paints).

    Overlapping primitives, and the paint, combine as independent absorbers,
    α = 1 − Π(1 − αᵢ), with the opacity-weighted mean colour; outside every primitive and the
    paint α = 0. ``gradient_max`` is the top of
    the editor's gradient axis in data units per µm (``None``: the renderer's own axis, which
    VTK fixes at a quarter of the channel's value range per mean voxel edge, see
    docs/transfer-functions-2d.md).
    """

    primitives: list[TFPrimitive] = Field(default_factory=list)
    gradient_max: float | None = Field(None, gt=0.0)
    paint: TFPaintLayer | None = None

    @field_validator("primitives")
    @classmethod
    def _count(cls, v: list[TFPrimitive]):
        if len(v) > MAX_PRIMITIVES:
            raise ValueError(f"a 2-D transfer function holds at most {MAX_PRIMITIVES} "
                             f"primitives, not {len(v)}")
        return v

    @field_validator("gradient_max")
    @classmethod
    def _finite_max(cls, v: float | None):
        if v is not None and not (math.isfinite(v) and v < 1e30):
            raise ValueError(f"gradient axis maximum {v} must be finite")
        return v

    def evaluate(self, values: np.ndarray, gradients: np.ndarray) -> np.ndarray:
        """RGBA (float32, shape ``broadcast(values, gradients).shape + (4,)``) at data
        ``values`` and gradient magnitudes (data units per µm). Alpha is per opacity unit
        distance."""
        v = np.asarray(values, dtype=np.float64)
        g = np.asarray(gradients, dtype=np.float64)
        shape = np.broadcast_shapes(v.shape, g.shape)
        transparency = np.ones(shape)
        weighted = np.zeros((*shape, 3))
        total = np.zeros(shape)
        for prim in self.primitives:
            alpha = prim.opacity * prim.coverage(v, g)
            transparency *= 1.0 - alpha
            weighted += alpha[..., None] * np.asarray(prim.color, dtype=np.float64)
            total += alpha
        if self.paint is not None:
            alpha, premult = self.paint.sample(v, g)
            transparency *= 1.0 - alpha
            weighted += premult
            total += alpha
        out = np.zeros((*shape, 4), np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[..., :3] = np.where(total[..., None] > 0, weighted / total[..., None], 0.0)
        out[..., 3] = 1.0 - transparency
        return out

    def table(self, value_range: tuple[float, float], gradient_range: tuple[float, float],
              shape: tuple[int, int]) -> np.ndarray:
        """Rasterise to a lookup table, float32 ``(height, width, 4)`` RGBA, row = gradient.

        Texel (j, i) holds the TF at the texel's centre: value ``v0 + (i + ½)·(v1 − v0)/width``
        and gradient ``g0 + (j + ½)·(g1 − g0)/height`` (the convention of an OpenGL texture
        sampled with linear filtering, so a lookup interpolates between these samples)."""
        values, gradients = table_axes(value_range, gradient_range, shape)
        h, w = len(gradients), len(values)
        transparency = np.ones((h, w))
        weighted = np.zeros((h, w, 3))
        total = np.zeros((h, w))
        for prim in self.primitives:
            # A primitive covers nothing outside its box: evaluate only the texels inside.
            i0 = np.searchsorted(values, prim.value_range[0], side="left")
            i1 = np.searchsorted(values, prim.value_range[1], side="right")
            j0 = np.searchsorted(gradients, prim.gradient_range[0], side="left")
            j1 = np.searchsorted(gradients, prim.gradient_range[1], side="right")
            if i0 >= i1 or j0 >= j1:
                continue
            box = (slice(j0, j1), slice(i0, i1))
            alpha = prim.opacity * prim.coverage(values[None, i0:i1], gradients[j0:j1, None])
            transparency[box] *= 1.0 - alpha
            weighted[box] += alpha[..., None] * np.asarray(prim.color, dtype=np.float64)
            total[box] += alpha
        if self.paint is not None:
            # The paint's box only (outside it the layer is transparent).
            (pv0, pv1), (pg0, pg1) = self.paint.value_range, self.paint.gradient_range
            i0, i1 = np.searchsorted(values, pv0, "left"), np.searchsorted(values, pv1, "right")
            j0 = np.searchsorted(gradients, pg0, "left")
            j1 = np.searchsorted(gradients, pg1, "right")
            if i0 < i1 and j0 < j1:
                box = (slice(j0, j1), slice(i0, i1))
                alpha, premult = self.paint.sample_grid(values[i0:i1], gradients[j0:j1])
                transparency[box] *= 1.0 - alpha
                weighted[box] += premult
                total[box] += alpha
        out = np.zeros((h, w, 4), np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[..., :3] = np.where(total[..., None] > 0, weighted / total[..., None], 0.0)
        out[..., 3] = 1.0 - transparency
        return out


def table_axes(value_range: tuple[float, float], gradient_range: tuple[float, float],
               shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Texel-centre coordinates ``(values[width], gradients[height])`` of a lookup table."""
    height, width = _check_table_shape(shape)
    v0, v1 = _check_axis(value_range, "value range")
    g0, g1 = _check_axis(gradient_range, "gradient range")
    values = v0 + (np.arange(width) + 0.5) * ((v1 - v0) / width)
    gradients = g0 + (np.arange(height) + 0.5) * ((g1 - g0) / height)
    return values, gradients


def rasterise(evaluate, value_range: tuple[float, float], gradient_range: tuple[float, float],
              shape: tuple[int, int]) -> np.ndarray:
    """``evaluate(values, gradients)`` (RGBA) sampled at texel centres, ``(h, w, 4)`` float32."""
    values, gradients = table_axes(value_range, gradient_range, shape)
    return np.ascontiguousarray(evaluate(values[None, :], gradients[:, None]), np.float32)


def table_from_1d(tf: TransferFunction, value_range: tuple[float, float],
                  shape: tuple[int, int]) -> np.ndarray:
    """The 1-D TF ``tf`` as a 2-D table constant along the gradient axis, ``(h, w, 4)``."""
    height, width = _check_table_shape(shape)
    values, _ = table_axes(value_range, (0.0, 1.0), shape)
    row = np.concatenate([tf.color_at(values), tf.opacity_at(values)[:, None]], axis=1)
    return np.ascontiguousarray(np.broadcast_to(row, (height, width, 4)), np.float32)


#: Layer shape (gradient rows, value columns) of :func:`paint_from_1d`: the 1-D TF sampled at
#: 256 values, constant over the rows (a brush still has rows to paint in).
PAINT_FROM_1D_SHAPE = (64, 256)


def paint_from_1d(tf: TransferFunction, value_range: tuple[float, float],
                  gradient_range: tuple[float, float],
                  shape: tuple[int, int] = PAINT_FROM_1D_SHAPE) -> TFPaintLayer:
    """A painted layer over ``value_range`` (data units) × ``gradient_range`` (data units per
    µm) that classifies as the 1-D TF ``tf`` does, whatever the gradient: the 2-D TF a
    channel starts from when it switches to 2-D (it showed nothing until a region was added,
    issue 25). Exact at the layer's pixel centres up to 8-bit rounding (colour and opacity
    within 1/510), linear between them."""
    values, _ = table_axes(value_range, gradient_range, shape)
    row = np.concatenate([tf.color_at(values), tf.opacity_at(values)[:, None]], axis=1)
    pixels = np.broadcast_to(np.clip(np.rint(row * 255.0), 0, 255).astype(np.uint8),
                             (shape[0], shape[1], 4))
    return TFPaintLayer.blank(value_range, gradient_range, shape).with_pixels(
        np.ascontiguousarray(pixels))


def _check_table_shape(shape: tuple[int, int]) -> tuple[int, int]:
    try:
        height, width = (int(s) for s in shape)
    except (TypeError, ValueError):
        raise ValueError(f"table shape {shape!r} must be (height, width)") from None
    if not (1 <= height <= MAX_TABLE_SIZE and 2 <= width <= MAX_TABLE_SIZE):
        raise ValueError(f"table shape {shape} must lie within 1…{MAX_TABLE_SIZE} rows and "
                         f"2…{MAX_TABLE_SIZE} columns")
    return height, width


def _check_axis(axis: tuple[float, float], what: str) -> tuple[float, float]:
    lo, hi = (float(a) for a in axis)
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"{what} {axis} must be finite and increasing")
    return lo, hi
