"""Orthogonal slices through the cursor: the 2-D views beside the 3-D view (numpy, no VTK).

A slice is one plane of voxels through the cursor, normal to x, y or z. Each visible
channel's value is coloured by the channel's effective transfer function (a linked channel
follows its source), so the contrast limits and the colour ramp are the 3-D view's; the
channels then mix as ``RenderSettings.channel_mixing`` says:

* ``additive`` (the default): the colours add, clipped to 1 (napari's additive blending);
* ``composite``: the opacity-weighted mean of the colours, Σ αᵢ·Cᵢ / Σ αᵢ (VTK's mix of
  independent components at one sample), black where no channel is opaque.

The alpha channel of the result is the channels' combined TF opacity 1 − Π(1 − αᵢ): how
opaque the 3-D view makes that voxel (one opacity unit distance of it).

A slice shows the 3-D view's classification, so it hides what the 3-D view hides (before
issue 25 it showed every voxel through the 1-D TF):

* a channel in 2-D mode (``Channel.tf_mode == "2d"``) is coloured by its 2-D TF at the voxel's
  value and VTK's gradient magnitude there (:mod:`vtkvol.engine.tf2d`: central differences
  over the neighbouring slices, the edge voxel repeated), over the axes the renderer uses;
* the slice-contribution weights multiply each channel's colour and opacity by
  wX(x)·wY(y)·wZ(z) (voxels below the renderer's 1e-10 are dropped);
* the enabled clipping plane removes the voxels on its cut side (VTK keeps the side its normal
  points to).

Coordinate spaces (docs/architecture.md):

* **voxel index** (i, j, k) along (x, y, z); arrays are ``[c, z, y, x]``;
* **world µm**: voxel (i, j, k) has its centre at (i·sx, j·sy, k·sz); the data's box spans
  voxel centres, 0…(n − 1)·s per axis;
* **slice pixels**: row ``r``, column ``q`` of a slice image is the voxel whose index along
  the plane's row axis is ``r`` and along its column axis ``q`` (see :data:`PLANES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from vtkvol.model.gamma import with_gamma
from vtkvol.model.gradient import gradient_axis_max, normalised_gradient

if TYPE_CHECKING:
    from vtkvol.io import VolumeData
    from vtkvol.model.scene import Channel, SceneModel
    from vtkvol.model.transfer_function import TransferFunction

Vec3 = tuple[float, float, float]
Index3 = tuple[int, int, int]
AXES = "xyz"
#: Colour of each plane by its normal axis (x, y, z), as the orientation axes colour the axes:
#: the slice views' frames and crosshairs and the 3-D view's plane outlines.
PLANE_COLORS: tuple[Vec3, Vec3, Vec3] = ((1.0, 0.25, 0.25), (0.3, 1.0, 0.3), (0.35, 0.55, 1.0))


@dataclass(frozen=True)
class Plane:
    """One orthogonal slice orientation.

    ``normal``, ``column`` and ``row`` are axis numbers (0 = x, 1 = y, 2 = z): the plane holds
    the voxels with one index along ``normal``; image columns run along ``column`` and image
    rows (top to bottom) along ``row``.
    """

    name: str
    normal: int
    column: int
    row: int


#: The three planes, laid out as Fiji's orthogonal views: xy with y downwards; yz to its
#: right with z across (its rows are the xy view's rows); xz below it with z downwards (its
#: columns are the xy view's columns).
PLANES: dict[str, Plane] = {
    "xy": Plane("xy", normal=2, column=0, row=1),
    "yz": Plane("yz", normal=0, column=2, row=1),
    "xz": Plane("xz", normal=1, column=0, row=2),
}


def _shape_xyz(shape_zyx: tuple[int, ...]) -> Index3:
    nz, ny, nx = (int(n) for n in shape_zyx[-3:])
    return nx, ny, nz


def box_um(shape_zyx: tuple[int, ...], spacing: Vec3) -> tuple[Vec3, Vec3]:
    """The data's box in world µm as (low, high) corners: voxel centres, (0, 0, 0) to
    ((nx − 1)·sx, (ny − 1)·sy, (nz − 1)·sz)."""
    n = _shape_xyz(shape_zyx)
    high = tuple(float((n[a] - 1) * spacing[a]) for a in range(3))
    return (0.0, 0.0, 0.0), high  # type: ignore[return-value]


def default_cursor(shape_zyx: tuple[int, ...], spacing: Vec3) -> Vec3:
    """The cursor when the model has none: the centre voxel, in world µm."""
    n = _shape_xyz(shape_zyx)
    return tuple(float(((n[a] - 1) // 2) * spacing[a]) for a in range(3))  # type: ignore


def cursor_index(cursor_um: Vec3 | None, shape_zyx: tuple[int, ...], spacing: Vec3) -> Index3:
    """The voxel (i, j, k) nearest to ``cursor_um`` (world µm), clamped into the data.

    ``None`` is the centre voxel. Raises ``ValueError`` for a cursor that is not finite.
    """
    n = _shape_xyz(shape_zyx)
    if cursor_um is None:
        cursor_um = default_cursor(shape_zyx, spacing)
    if not all(math.isfinite(float(c)) for c in cursor_um):
        raise ValueError(f"cursor {tuple(cursor_um)} µm must be finite")
    return tuple(int(min(max(round(float(cursor_um[a]) / float(spacing[a])), 0), n[a] - 1))
                 for a in range(3))  # type: ignore[return-value]


def index_to_um(index: Index3, spacing: Vec3) -> Vec3:
    """World µm of voxel centre ``index`` (i, j, k)."""
    return tuple(float(index[a] * spacing[a]) for a in range(3))  # type: ignore[return-value]


def snap_cursor(cursor_um: Vec3 | None, shape_zyx: tuple[int, ...], spacing: Vec3) -> Vec3:
    """``cursor_um`` moved to the nearest voxel centre inside the data (world µm)."""
    return index_to_um(cursor_index(cursor_um, shape_zyx, spacing), spacing)


def effective_tf(model: SceneModel, channel: int) -> TransferFunction:
    """The transfer function channel ``channel`` is drawn with: its own, or the one of the
    channel it is linked to (``Channel.tf_linked_to``), as the 3-D view does."""
    channels = model.channels
    link = channels[channel].tf_linked_to
    if link is not None and 0 <= link < len(channels) and link != channel:
        return channels[link].tf
    return channels[channel].tf


def effective_channel(model: SceneModel, channel: int) -> Channel:
    """The channel whose transfer functions (1-D or 2-D, and the mode between them) channel
    ``channel`` is drawn with: itself, or the channel it is linked to."""
    channels = model.channels
    link = channels[channel].tf_linked_to
    if link is not None and 0 <= link < len(channels) and link != channel:
        return channels[link]
    return channels[channel]


def shown_tf(model: SceneModel, channel: int) -> TransferFunction:
    """:func:`effective_tf` with the channel's own gamma baked in (vtkvol.model.gamma): what
    the 3-D view and the slice views classify channel ``channel``'s values (data units) with.
    A label channel's colours are categories: gamma does not apply to them."""
    tf = effective_tf(model, channel)
    own = model.channels[channel]
    return tf if own.labels is not None else with_gamma(tf, own.gamma)


def slice_values(array: np.ndarray, plane: Plane | str, index: int) -> np.ndarray:
    """The raw values of slice ``index`` (voxels along the plane's normal) of ``array``
    (``[c, z, y, x]``) as ``[c, rows, columns]`` (a view where numpy can make one)."""
    plane = PLANES[plane] if isinstance(plane, str) else plane
    _, nz, ny, nx = array.shape
    limit = (nx, ny, nz)[plane.normal]
    if not 0 <= index < limit:
        raise ValueError(f"slice {index} along {AXES[plane.normal]} is outside 0…{limit - 1}")
    # The array's axes 1, 2, 3 are z, y, x: axis a of the world is array axis 3 − a.
    taken = np.take(array, index, axis=3 - plane.normal)  # [c, remaining two, in zyx order]
    remaining = [a for a in (2, 1, 0) if a != plane.normal]  # world axes of taken's axes 1, 2
    order = [0, 1 + remaining.index(plane.row), 1 + remaining.index(plane.column)]
    return taken.transpose(order)


#: Integer slices look their values up in a table of the TF over the slice's value span when
#: that span is at most this many values and smaller than the slice (the same numbers as
#: evaluating the TF per voxel, several times faster for 16-bit data).
MAX_TABLE = 1 << 16


def _tf_lookup(tf: TransferFunction, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(RGB ``[..., 3]``, opacity ``[...]``), float32, of ``tf`` at data ``values``."""
    if np.issubdtype(values.dtype, np.integer) and values.size:
        lo, hi = int(values.min()), int(values.max())
        if hi - lo < min(MAX_TABLE, values.size):
            table = np.arange(lo, hi + 1, dtype=np.float64)
            offsets = np.asarray(values, dtype=np.int64) - lo
            return tf.color_at(table)[offsets], tf.opacity_at(table)[offsets]
    return tf.color_at(values), tf.opacity_at(values)


def slice_rgba(data: VolumeData, model: SceneModel, plane: Plane | str,
               index: int) -> np.ndarray:
    """Slice ``index`` of ``plane`` coloured as the 3-D view colours its voxels.

    Returns ``float32 [rows, columns, 4]``: RGB in 0…1 (the visible channels' TF colours,
    mixed by ``model.render.channel_mixing``; see the module docstring) and A, the combined
    TF opacity 1 − Π(1 − αᵢ). A pixel with no visible channel is black with A = 0.
    """
    plane = PLANES[plane] if isinstance(plane, str) else plane
    values = slice_values(data.array, plane, index)
    rows, columns = values.shape[1:]
    rgb = np.zeros((rows, columns, 3), dtype=np.float32)
    transparency = np.ones((rows, columns), dtype=np.float32)
    composite = model.render.channel_mixing == "composite"
    weight = np.zeros((rows, columns), dtype=np.float32)
    kept = slice_weight(data, model, plane, index)
    for c, channel in enumerate(model.channels[: values.shape[0]]):
        if not channel.visible:
            continue
        source = effective_channel(model, c)
        if source.tf_mode == "2d":
            color, alpha = _tf2d_lookup(data, source, c, plane, index, values[c])
        else:
            color, alpha = _tf_lookup(shown_tf(model, c), values[c])
        if kept is not None:  # the renderer multiplies the sample's RGBA by the weight
            color = color * kept[..., None]
            alpha = alpha * kept
        if composite:
            rgb += alpha[..., None] * color
            weight += alpha
        else:
            rgb += color
        transparency *= 1.0 - alpha
    if composite:
        np.divide(rgb, weight[..., None], out=rgb, where=weight[..., None] > 0.0)
    out = np.empty((rows, columns, 4), dtype=np.float32)
    np.clip(rgb, 0.0, 1.0, out=out[..., :3])
    out[..., 3] = 1.0 - transparency
    return out


#: (gradient rows, value columns) of the 2-D TF table a slice is coloured with: finer than the
#: 2-D editor's preview, far cheaper to rasterise than the renderer's 1024² table, and the
#: same function (both sample the primitives at texel centres and interpolate linearly).
SLICE_TABLE_SHAPE = (256, 256)
#: The renderer drops samples whose slice weight is below this (host_slice_weights.glsl).
MIN_WEIGHT = 1e-10


def _tf2d_lookup(data: VolumeData, channel: Channel, c: int, plane: Plane, index: int,
                 values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(RGB, opacity per unit distance) of component ``c``'s slice ``values`` by
    ``channel.tf2d``, at VTK's gradient of the voxels (axes as the renderer's table:
    the component's value range, 0 … :func:`gradient_axis_max` per µm)."""
    lo, hi = data.channel_range(c)
    value_range = (float(lo), float(hi) if hi > lo else float(lo) + 1.0)
    spacing = tuple(float(v) for v in data.voxel_size_um)
    gradient_range = (0.0, gradient_axis_max(value_range, spacing))  # type: ignore[arg-type]
    table = channel.tf2d.table(value_range, gradient_range, SLICE_TABLE_SHAPE)
    # The slab of the slice and its two neighbours (fewer at the border, where VTK's clamped
    # texture repeats the edge voxel, as vtk_gradient's padding does).
    axis = 3 - plane.normal  # of the [c, z, y, x] array
    n = data.array.shape[axis]
    first, last = max(index - 1, 0), min(index + 1, n - 1)
    slab = np.take(data.array[c], np.arange(first, last + 1), axis=axis - 1)
    t = normalised_gradient(slab, spacing, value_range)  # type: ignore[arg-type]
    t_slice = np.take(t, index - first, axis=axis - 1)  # [remaining two, zyx order]
    remaining = [a for a in (2, 1, 0) if a != plane.normal]
    if remaining.index(plane.row) != 0:
        t_slice = t_slice.T
    span = value_range[1] - value_range[0]
    s = ((np.asarray(values, dtype=np.float64) - value_range[0]) / span).astype(np.float32)
    from vtkvol.engine.tf2d import lookup  # imports VTK: only where a 2-D TF is shown

    rgba = lookup(table, s, t_slice)
    return rgba[..., :3], rgba[..., 3]


def slice_weight(data: VolumeData, model: SceneModel, plane: Plane | str,
                 index: int) -> np.ndarray | None:
    """The factor ``[rows, columns]`` (0…1) the renderer multiplies each voxel of the slice
    by: the slice-contribution weights wX·wY·wZ (positions normalised over the data's extent)
    and 0 on the cut side of the enabled clipping plane (world µm); None when both are off."""
    plane = PLANES[plane] if isinstance(plane, str) else plane
    weights = model.slice_weights
    clip = model.clip_plane
    if weights.is_identity and not clip.enabled:
        return None
    n = _shape_xyz(data.array.shape)
    spacing = tuple(float(v) for v in data.voxel_size_um)
    # Per world axis: the voxel indices the slice's rows, columns or single plane cover.
    ranges = [np.arange(n[a]) if a != plane.normal else np.array([index]) for a in range(3)]
    row = ranges[plane.row][:, None]
    column = ranges[plane.column][None, :]
    factor = np.ones((len(ranges[plane.row]), len(ranges[plane.column])), dtype=np.float64)
    if not weights.is_identity:
        for a, points in enumerate((weights.x, weights.y, weights.z)):
            xs, ws = np.asarray(points, dtype=np.float64).T
            w = np.interp(ranges[a] / max(n[a] - 1, 1), xs, ws)
            factor = factor * (w[:, None] if a == plane.row else
                               w[None, :] if a == plane.column else w[0])
        factor[factor < MIN_WEIGHT] = 0.0
    if clip.enabled:
        low, high = box_um(data.array.shape, spacing)  # type: ignore[arg-type]
        origin = clip.origin if clip.origin is not None else tuple(
            (low[a] + high[a]) / 2 for a in range(3))
        side = np.zeros_like(factor)
        for a in range(3):
            offset = ((row if a == plane.row else column if a == plane.column
                       else ranges[a][0]) * spacing[a] - origin[a]) * clip.normal[a]
            side = side + offset
        factor = np.where(side >= 0.0, factor, 0.0)
    return factor.astype(np.float32)


def to_rgba8(rgba: np.ndarray) -> np.ndarray:
    """A float RGBA slice (0…1) as a C-contiguous ``uint8 [rows, columns, 4]`` image."""
    return np.ascontiguousarray(np.rint(np.clip(rgba, 0.0, 1.0) * 255.0).astype(np.uint8))
