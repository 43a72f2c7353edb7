"""The painted layer of a 2-D transfer function: a small RGBA raster over (value, |∇I|).

Seed 001 §2.5 paints 2-D transfer functions with a brush. vtkvol keeps the paint as one
raster per channel (:class:`TFPaintLayer`, default :data:`PAINT_SHAPE` = 128 × 128) over a
box in (value, gradient magnitude) space, next to the primitives; the two combine as
independent absorbers (docs/transfer-functions-2d.md). Pure numpy; nothing imports VTK or Qt.

Coordinates: ``value_range`` in **data units** along the columns, ``gradient_range`` in **data
units per µm** along the rows, row 0 at the lowest gradient. Pixel (j, i) holds the layer at
its centre, value ``v0 + (i + ½)(v1 − v0)/width``, gradient ``g0 + (j + ½)(g1 − g0)/height``
(the lookup-table convention of :meth:`TransferFunction2D.table`). Pixels are straight
(not premultiplied) RGBA bytes; alpha/255 is the opacity per opacity unit distance.

Storage (sessions, undo): ``rgba`` is the base64 text of the zlib-compressed ``uint8`` array
of shape ``(height, width, 4)`` in C order; ``shape`` states ``(height, width)``. A mostly
empty layer is a few hundred characters.
"""

from __future__ import annotations

import base64
import binascii
import functools
import itertools
import math
import zlib
from collections.abc import Iterable

import numpy as np
from pydantic import BaseModel, ConfigDict, field_validator, model_validator

#: (rows = gradient, columns = value) of a new layer: VTK's 1024² table reads it bilinearly.
PAINT_SHAPE = (128, 128)
#: Largest layer per axis (a painted layer is a sketch, not a table).
MAX_PAINT_SIZE = 512
#: Largest brush radius in layer pixels.
MAX_BRUSH_RADIUS = 64.0

Range = tuple[float, float]


def check_range(v: tuple[float, float], what: str) -> tuple[float, float]:
    """``(low, high)`` finite, increasing and within ±1e30, else one-line ValueError."""
    lo, hi = v
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{what} {v} must be finite")
    if not lo < hi:
        raise ValueError(f"{what} {v} must be increasing (low < high)")
    if abs(lo) > 1e30 or abs(hi) > 1e30:
        raise ValueError(f"{what} {v} is out of range (|x| ≤ 1e30)")
    return (float(lo), float(hi))


def encode_pixels(pixels: np.ndarray) -> str:
    """``(h, w, 4)`` uint8 → the ``rgba`` text of a layer."""
    data = np.ascontiguousarray(pixels, dtype=np.uint8).tobytes()
    return base64.b64encode(zlib.compress(data, 6)).decode("ascii")


@functools.lru_cache(maxsize=16)
def _decode(rgba: str, height: int, width: int) -> np.ndarray:
    """The pixels of ``rgba`` (read-only, cached: a layer is decoded once, not per lookup).
    Raises one-line ValueErrors for every way the text can be wrong."""
    expected = height * width * 4
    # base64 of zlib of n bytes is never longer than ~(n + n/1000 + 64)·4/3: refuse huge text
    # before decoding it.
    if len(rgba) > (expected + expected // 500 + 128) * 4 // 3 + 4:
        raise ValueError(f"paint layer rgba is {len(rgba)} characters, too long for "
                         f"{height} × {width} pixels")
    try:
        packed = base64.b64decode(rgba.encode("ascii"), validate=True)
    except (binascii.Error, UnicodeEncodeError, ValueError):
        raise ValueError("paint layer rgba is not valid base64") from None
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(packed, expected + 1)  # never inflate past the stated size
    except zlib.error:
        raise ValueError("paint layer rgba is not zlib-compressed pixel data") from None
    if len(raw) != expected or not inflater.eof:
        size = f"more than {expected}" if len(raw) > expected else f"{len(raw)}"
        if len(raw) == expected and not inflater.eof:
            size = "a truncated stream of"
        raise ValueError(f"paint layer rgba holds {size} bytes, expected height × width × 4 "
                         f"= {height} × {width} × 4 = {expected}")
    pixels = np.frombuffer(raw, np.uint8).reshape(height, width, 4)
    pixels.flags.writeable = False
    return pixels


class TFPaintLayer(BaseModel):
    """A painted RGBA raster over the box ``value_range × gradient_range`` (module docstring).

    Outside the box the layer is transparent; inside it is read bilinearly between pixel
    centres (clamped to the edge pixels within half a pixel of the border), with colour
    interpolated premultiplied by alpha so that a painted edge does not fade to black.

    An immutable value (frozen, like a tuple): an edit replaces the whole layer
    (:meth:`with_pixels`), so its fields, which must agree with each other (``shape`` and
    ``rgba``), are never assigned one by one — restoring a state (undo, opening a session)
    assigns the layer whole and validates it whole."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    value_range: Range = (0.0, 255.0)
    gradient_range: Range = (0.0, 1.0)
    shape: tuple[int, int] = PAINT_SHAPE
    rgba: str = ""

    @field_validator("value_range", "gradient_range")
    @classmethod
    def _increasing(cls, v: Range, info) -> Range:
        return check_range(v, f"paint layer {info.field_name.replace('_', ' ')}")

    @field_validator("shape")
    @classmethod
    def _shape(cls, v: tuple[int, int]) -> tuple[int, int]:
        if not all(2 <= s <= MAX_PAINT_SIZE for s in v):
            raise ValueError(f"paint layer shape {tuple(v)} must lie within 2…{MAX_PAINT_SIZE} "
                             "pixels per axis")
        return v

    @model_validator(mode="after")
    def _pixels_match(self):
        if self.rgba == "":  # the blank layer of this shape
            object.__setattr__(self, "rgba", encode_pixels(np.zeros((*self.shape, 4), np.uint8)))
        _decode(self.rgba, *self.shape)
        return self

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def blank(cls, value_range: Range, gradient_range: Range,
              shape: tuple[int, int] = PAINT_SHAPE) -> TFPaintLayer:
        return cls(value_range=value_range, gradient_range=gradient_range, shape=shape)

    def with_pixels(self, pixels: np.ndarray) -> TFPaintLayer:
        """A new layer over the same box holding ``pixels`` ``(h, w, 4)`` uint8."""
        arr = np.asarray(pixels)
        if arr.shape != (*self.shape, 4) or arr.dtype != np.uint8:
            raise ValueError(f"paint pixels must be uint8 {(*self.shape, 4)}, not "
                             f"{arr.dtype} {arr.shape}")
        return TFPaintLayer(value_range=self.value_range, gradient_range=self.gradient_range,
                            shape=self.shape, rgba=encode_pixels(arr))

    # -- reading --------------------------------------------------------------------------------
    def pixels(self) -> np.ndarray:
        """The raster, ``(height, width, 4)`` uint8, read-only; row 0 = lowest gradient."""
        return _decode(self.rgba, *self.shape)

    @property
    def empty(self) -> bool:
        return not self.pixels()[..., 3].any()

    def pixel_coords(self, values: np.ndarray, gradients: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Continuous pixel coordinates (x = column, y = row; pixel centres at integers) of
        data ``values`` and ``gradients``."""
        (v0, v1), (g0, g1) = self.value_range, self.gradient_range
        h, w = self.shape
        x = (np.asarray(values, np.float64) - v0) * (w / (v1 - v0)) - 0.5
        y = (np.asarray(gradients, np.float64) - g0) * (h / (g1 - g0)) - 0.5
        return x, y

    def sample_grid(self, values: np.ndarray, gradients: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`sample` on the grid ``gradients[:, None] × values[None, :]`` (1-D inputs),
        separably (two small matrix products per channel instead of a gather per texel):
        shapes ``(len(gradients), len(values))`` and ``… + (3,)``."""
        x, y = self.pixel_coords(np.ravel(values), np.ravel(gradients))
        h, w = self.shape
        wx = _interpolation_matrix(x, w)
        wy = _interpolation_matrix(y, h)
        px = self.pixels().astype(np.float64) / 255.0
        premult = np.concatenate([px[..., 3:] * px[..., :3], px[..., 3:]], axis=-1)
        out = np.einsum("aj,jik,bi->abk", wy, premult, wx, optimize=True)
        return out[..., 3], out[..., :3]

    def sample(self, values: np.ndarray, gradients: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """(alpha, alpha·rgb) at broadcastable ``values`` / ``gradients``: float64 of shapes
        ``S`` and ``S + (3,)``; zero outside the box, NaN reads as outside."""
        x, y = self.pixel_coords(values, gradients)
        x, y = np.broadcast_arrays(x, y)
        h, w = self.shape
        inside = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
        xc = np.clip(np.nan_to_num(x), 0.0, w - 1.0)
        yc = np.clip(np.nan_to_num(y), 0.0, h - 1.0)
        x0 = np.minimum(xc.astype(np.int64), w - 2)
        y0 = np.minimum(yc.astype(np.int64), h - 2)
        fx, fy = xc - x0, yc - y0
        px = self.pixels().astype(np.float64) / 255.0
        premult = np.concatenate([px[..., 3:] * px[..., :3], px[..., 3:]], axis=-1)

        def at(j: np.ndarray, i: np.ndarray) -> np.ndarray:
            return premult[j, i]

        out = ((at(y0, x0) * (1 - fx)[..., None] + at(y0, x0 + 1) * fx[..., None])
               * (1 - fy)[..., None]
               + (at(y0 + 1, x0) * (1 - fx)[..., None] + at(y0 + 1, x0 + 1) * fx[..., None])
               * fy[..., None])
        out[~inside] = 0.0
        return out[..., 3], out[..., :3]


def _interpolation_matrix(coords: np.ndarray, n: int) -> np.ndarray:
    """``(len(coords), n)`` linear-interpolation weights of pixel coordinates ``coords``
    (centres at integers, clamped to the edge within half a pixel, zero rows beyond)."""
    c = np.asarray(coords, np.float64)
    inside = (c >= -0.5) & (c <= n - 0.5)
    cc = np.clip(np.nan_to_num(c), 0.0, n - 1.0)
    c0 = np.minimum(cc.astype(np.int64), n - 2)
    f = cc - c0
    rows = np.arange(len(c))
    out = np.zeros((len(c), n))
    out[rows, c0] = 1.0 - f
    out[rows, c0 + 1] += f
    out[~inside] = 0.0
    return out


# -- the brush (pure functions: the editor reports a stroke, the dock writes the result) ------
def stroke_mask(shape: tuple[int, int], points: Iterable[tuple[float, float]],
                radius: float) -> np.ndarray:
    """Coverage 0…1 of a stroke through ``points`` (pixel coordinates x, y; pixel centres at
    integers) with a round brush of ``radius`` pixels: 1 up to radius − ½ from the path, 0
    beyond radius + ½, linear between (antialiasing); the segments between points filled.
    ``(h, w)`` float64; a pixel covered twice is covered once (a stroke paints its colour, it
    does not pile up)."""
    h, w = shape
    if not (math.isfinite(radius) and 0.0 < radius <= MAX_BRUSH_RADIUS):
        raise ValueError(f"brush radius {radius} must lie within 0…{MAX_BRUSH_RADIUS:g} pixels")
    pts = np.array([p for p in points if all(math.isfinite(c) for c in p)], np.float64)
    mask = np.zeros((h, w))
    if len(pts) == 0:
        return mask
    if len(pts) == 1:
        pts = np.vstack([pts, pts])
    jj, ii = np.mgrid[0:h, 0:w].astype(np.float64)
    for (ax, ay), (bx, by) in itertools.pairwise(pts.tolist()):
        # Only the pixels within reach of this segment.
        x_lo = max(math.floor(min(ax, bx) - radius - 1), 0)
        x_hi = min(math.ceil(max(ax, bx) + radius + 1) + 1, w)
        y_lo = max(math.floor(min(ay, by) - radius - 1), 0)
        y_hi = min(math.ceil(max(ay, by) + radius + 1) + 1, h)
        if x_lo >= x_hi or y_lo >= y_hi:
            continue
        px, py = ii[y_lo:y_hi, x_lo:x_hi], jj[y_lo:y_hi, x_lo:x_hi]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = np.clip(((px - ax) * dx + (py - ay) * dy) / length2, 0.0, 1.0) if length2 else 0.0
        dist = np.hypot(px - (ax + t * dx), py - (ay + t * dy))
        cover = np.clip(radius + 0.5 - dist, 0.0, 1.0)
        np.maximum(mask[y_lo:y_hi, x_lo:x_hi], cover, out=mask[y_lo:y_hi, x_lo:x_hi])
    return mask


def apply_stroke(base: np.ndarray, mask: np.ndarray, color: tuple[float, float, float],
                 opacity: float, *, erase: bool = False) -> np.ndarray:
    """``base`` (uint8 ``(h, w, 4)``) with a stroke of coverage ``mask`` applied: each pixel
    moves towards the brush (``color``, ``opacity``) by its coverage, premultiplied (so a
    half-covered empty pixel gets the brush colour at half alpha, not a darker colour).
    ``erase``: towards transparent; where the eraser covers fully the pixel is exactly 0."""
    if not (math.isfinite(opacity) and 0.0 <= opacity <= 1.0):
        raise ValueError(f"brush opacity {opacity} must lie within 0…1")
    if not all(math.isfinite(c) and 0.0 <= c <= 1.0 for c in color):
        raise ValueError(f"brush colour {tuple(color)}: r, g, b must lie in 0…1")
    px = base.astype(np.float64) / 255.0
    alpha = px[..., 3]
    premult = px[..., :3] * alpha[..., None]
    m = np.asarray(mask, np.float64)
    if erase:
        target_alpha, target_premult = 0.0, np.zeros(3)
    else:
        target_alpha = float(opacity)
        target_premult = float(opacity) * np.asarray(color, np.float64)
    new_alpha = alpha + m * (target_alpha - alpha)
    new_premult = premult + m[..., None] * (target_premult - premult)
    out = np.zeros_like(px)
    with np.errstate(divide="ignore", invalid="ignore"):
        out[..., :3] = np.where(new_alpha[..., None] > 0,
                                new_premult / new_alpha[..., None], 0.0)
    out[..., 3] = new_alpha
    result = np.round(np.clip(out, 0.0, 1.0) * 255.0).astype(np.uint8)
    result[result[..., 3] == 0] = 0  # a transparent pixel has no colour
    result[m <= 0] = base[m <= 0]  # untouched pixels keep their exact bytes
    return result
