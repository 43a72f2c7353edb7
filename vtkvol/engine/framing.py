"""Where the visible content of a volume is: the box the first view and "reset view" frame.

A microscopy or MRI stack is mostly transparent background; framing its whole box can leave
the object a few percent of the image. :func:`visible_bounds` finds the box of what the
transfer functions make visible (non-zero opacity), inside the crop box and weighted by the
slice-contribution functions. Pure numpy (no VTK): the scene calls it, tests check it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from vtkvol.io import VolumeData
    from vtkvol.model.scene import SceneModel

Bounds = tuple[float, float, float, float, float, float]

#: Voxels evaluated at most (a strided subsample above this): about 0.1 s on one core.
MAX_SAMPLES = 4_000_000
#: Share of the visible opacity left out at each end of each axis, so that a few stray noise
#: voxels above the TF's low limit do not stretch the frame back to the whole box.
TRIM = 0.002


def visible_bounds(data: VolumeData, model: SceneModel) -> Bounds | None:
    """(xmin, xmax, ymin, ymax, zmin, zmax) in world µm of the voxels with non-zero opacity.

    Each visible channel's effective TF (a linked channel follows its source) gives every
    voxel an opacity; the crop box and the slice weights multiply it. Along each axis the
    bounds hold all but :data:`TRIM` of the summed opacity at each end. Large volumes are
    evaluated on a strided subsample, and the bounds are widened by one stride so that the
    subsample does not cut the content. ``None`` when nothing is visible.
    """
    arr = data.array
    n_c, nz, ny, nx = arr.shape
    spacing = np.asarray(data.voxel_size_um, dtype=np.float64)  # (x, y, z)
    stride = max(1, int(np.ceil((nz * ny * nx / MAX_SAMPLES) ** (1.0 / 3.0))))
    index = [np.arange(0, n, stride) for n in (nx, ny, nz)]
    alpha = np.zeros((len(index[2]), len(index[1]), len(index[0])), dtype=np.float32)
    channels = model.channels
    for c, channel in enumerate(channels[:n_c]):
        if not channel.visible:
            continue
        link = channel.tf_linked_to
        tf = channels[link].tf if link is not None and 0 <= link < len(channels) else channel.tf
        values = np.asarray(arr[c, ::stride, ::stride, ::stride], dtype=np.float32)
        xs, ys = (np.asarray(v, dtype=np.float64) for v in zip(*tf.opacity, strict=True))
        # Alpha of independent channels combines as 1 − Π(1 − α); only "> 0" matters below,
        # and summing keeps each channel's share of the mass.
        alpha += np.interp(values, xs, ys).astype(np.float32)
    full = (0.0, (nx - 1) * spacing[0], 0.0, (ny - 1) * spacing[1], 0.0, (nz - 1) * spacing[2])
    box = model.crop.as_bounds(full)
    weights = model.slice_weights
    profiles: list[tuple[np.ndarray, tuple[int, ...]]] = []
    for axis, (n, points) in enumerate(zip((nx, ny, nz), (weights.x, weights.y, weights.z),
                                           strict=True)):
        positions = index[axis] * spacing[axis]  # voxel centres, µm
        profile_axes = tuple(a for a in range(3) if a != 2 - axis)  # array is [z, y, x]
        t = index[axis] / max(n - 1, 1)
        w = np.interp(t, *np.asarray(points, dtype=np.float64).T)
        w[(positions < box[2 * axis]) | (positions > box[2 * axis + 1])] = 0.0
        shape = [1, 1, 1]
        shape[2 - axis] = -1
        alpha *= w.reshape(shape).astype(np.float32)
        profiles.append((positions, profile_axes))
    total = float(alpha.sum())
    if not total > 0.0:
        return None
    out: list[float] = []
    for axis, (positions, profile_axes) in enumerate(profiles):
        profile = alpha.sum(axis=profile_axes, dtype=np.float64)
        cumulative = np.cumsum(profile) / total
        first = int(np.searchsorted(cumulative, TRIM, side="right"))
        last = int(np.searchsorted(cumulative, 1.0 - TRIM, side="left"))
        first, last = min(first, len(positions) - 1), min(last, len(positions) - 1)
        margin = (stride - 1) * spacing[axis]
        lo = max(box[2 * axis], positions[first] - margin)
        hi = min(box[2 * axis + 1], positions[last] + margin)
        if not hi > lo:  # one slice thick: give it one voxel of depth to frame
            lo, hi = lo - 0.5 * spacing[axis], hi + 0.5 * spacing[axis]
        out += [float(lo), float(hi)]
    return tuple(out)  # type: ignore[return-value]
