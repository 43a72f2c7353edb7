"""The (value, gradient magnitude) space of a volume: its 2-D histogram, and spatialized
transfer functions (Roettger, Bauer & Stamminger 2005; seed 001 §2.5) that propose classes
from it. Pure numpy; gradients are VTK's (:mod:`vtkvol.model.gradient`), so a class drawn
here lands where the renderer classifies (docs/transfer-functions-2d.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vtkvol.model.gradient import vtk_gradient
from vtkvol.model.transfer_function import MAX_PRIMITIVES, TFPrimitive, TransferFunction2D

#: Voxels the histogram and the classification read at most (a strided lattice).
MAX_SAMPLES = 1_000_000
#: STF parameter ranges (the seed gives no values; ours, see the docs).
RADIUS_RANGE = (0.01, 1.0)
OPACITY_SCALE_RANGE = (0.0, 10.0)
DEFAULT_RADIUS = 0.2
DEFAULT_OPACITY_SCALE = 1.0
#: Bins of the STF's 2-D histogram (values × gradients): coarse enough that each bin holds
#: voxels from several places, fine enough to separate arcs.
STF_BINS = (24, 48)
#: Bins with fewer voxels than this are noise: not classified.
MIN_BIN_COUNT = 4


@dataclass(frozen=True)
class FeatureSample:
    """Voxels on a strided lattice with VTK's gradient at each (full-resolution neighbours).

    ``values`` (data units), ``gradients`` (|∇I|, data units per µm) and ``positions``
    (normalised 0…1 per axis, x, y, z) are flat arrays over the same voxels."""

    values: np.ndarray
    gradients: np.ndarray
    positions: np.ndarray
    stride: int


def feature_sample(volume: np.ndarray, spacing: tuple[float, float, float],
                   max_samples: int = MAX_SAMPLES) -> FeatureSample:
    """Sample ``volume`` ``[z, y, x]`` on a lattice of at most ``max_samples`` voxels; each
    gradient is VTK's central difference over the voxel's real neighbours (not the lattice's),
    so a 2 GB memory-mapped stack costs a few strided reads."""
    if volume.ndim != 3 or min(volume.shape) < 1:
        raise ValueError(f"need a 3-D volume, not shape {volume.shape}")
    nz, ny, nx = volume.shape
    stride = max(1, math.ceil((volume.size / max(1, max_samples)) ** (1.0 / 3.0)))
    axes = [np.arange(0, n, stride) for n in (nz, ny, nx)]
    if stride == 1:
        centre = np.asarray(volume, dtype=np.float32)
        grad = vtk_gradient(centre, spacing)
    else:
        centre = np.asarray(volume[np.ix_(*axes)], dtype=np.float32)
        grad = np.empty((*centre.shape, 3), np.float32)
        mean = sum(spacing) / 3.0
        for k, axis in enumerate((2, 1, 0)):  # gradient x, y, z = array axes 2, 1, 0
            n = volume.shape[axis]
            plus = list(axes)
            minus = list(axes)
            plus[axis] = np.minimum(axes[axis] + 1, n - 1)
            minus[axis] = np.maximum(axes[axis] - 1, 0)
            diff = (np.asarray(volume[np.ix_(*plus)], np.float32)
                    - np.asarray(volume[np.ix_(*minus)], np.float32))
            grad[..., k] = diff / np.float32(2.0 * spacing[k] / mean)
    mean = sum(spacing) / 3.0
    magnitude = np.sqrt(np.einsum("...k,...k->...", grad, grad)) / np.float32(mean)
    finite = np.isfinite(centre) & np.isfinite(magnitude)
    z, y, x = np.meshgrid(*[a / max(1, n - 1) for a, n in zip(axes, (nz, ny, nx),
                                                               strict=True)], indexing="ij")
    positions = np.stack([x[finite], y[finite], z[finite]], axis=1).astype(np.float32)
    return FeatureSample(centre[finite], magnitude[finite], positions, stride)


def histogram2d(sample: FeatureSample, value_range: tuple[float, float],
                gradient_range: tuple[float, float], bins: tuple[int, int]) -> np.ndarray:
    """Counts ``(gradient bins, value bins)`` (row = gradient, as the TF's table); voxels
    outside the ranges are left out, gradients above the top fall in the top row (the
    renderer clamps them there too)."""
    g = np.minimum(sample.gradients, np.nextafter(np.float32(gradient_range[1]), 0))
    counts, _, _ = np.histogram2d(g, sample.values, bins=bins,
                                  range=(gradient_range, value_range))
    return counts


@dataclass(frozen=True)
class SpatializedClasses:
    """The outcome of :func:`spatialized_classes`.

    ``labels``: class per histogram bin ``(gradient bins, value bins)``, −1 = none, after
    smoothing; ``raw_labels`` before it; ``counts`` the histogram; ``barycentres``
    ``(h, w, 3)`` and ``variances`` ``(h, w)`` per bin; the bin edges of both axes."""

    labels: np.ndarray
    raw_labels: np.ndarray
    counts: np.ndarray
    barycentres: np.ndarray
    variances: np.ndarray
    value_edges: np.ndarray
    gradient_edges: np.ndarray

    @property
    def n_classes(self) -> int:
        return int(self.labels.max()) + 1 if self.labels.size else 0


def spatialized_classes(sample: FeatureSample, value_range: tuple[float, float],
                        gradient_range: tuple[float, float], *, radius: float = DEFAULT_RADIUS,
                        bins: tuple[int, int] = STF_BINS) -> SpatializedClasses:
    """Roettger et al.'s classification of the (value, |∇I|) histogram by where the voxels
    of each bin lie.

    Per bin T: barycentre b(T) = mean of its voxels' normalised positions, spatial variance
    v(T) = mean ‖p − b(T)‖. Repeatedly take the unclassified bin T₀ with the most voxels and
    put every unclassified bin T with ‖b(T) − b(T₀)‖ + |v(T₀) − v(T)| < ``radius`` in its
    class. Then denoise the label image (:func:`_smooth_labels`: a Gaussian majority vote
    and a closing of one-bin gaps)."""
    lo, hi = RADIUS_RANGE
    if not (math.isfinite(radius) and lo <= radius <= hi):
        raise ValueError(f"radius {radius} must lie in {lo}…{hi}")
    h, w = bins
    value_edges = np.linspace(*value_range, w + 1)
    gradient_edges = np.linspace(*gradient_range, h + 1)
    inside = ((sample.values >= value_range[0]) & (sample.values <= value_range[1]))
    vi = np.clip(np.searchsorted(value_edges, sample.values[inside], side="right") - 1, 0, w - 1)
    gi = np.clip(np.searchsorted(gradient_edges, sample.gradients[inside], side="right") - 1,
                 0, h - 1)
    flat = gi * w + vi
    pos = sample.positions[inside].astype(np.float64)
    counts = np.bincount(flat, minlength=h * w).astype(np.float64)
    sums = np.stack([np.bincount(flat, pos[:, k], minlength=h * w) for k in range(3)], 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        bary = sums / counts[:, None]
        dist = np.linalg.norm(pos - bary[flat], axis=1)
        var = np.bincount(flat, dist, minlength=h * w) / counts
    usable = counts >= MIN_BIN_COUNT
    labels = np.full(h * w, -1, np.int64)
    order = np.argsort(-counts, kind="stable")
    n_classes = 0
    for t0 in order:
        if not usable[t0]:
            break
        if labels[t0] != -1:
            continue
        free = usable & (labels == -1)
        norm = np.linalg.norm(bary - bary[t0], axis=1) + np.abs(var - var[t0])
        labels[free & (norm < radius)] = n_classes
        labels[t0] = n_classes
        n_classes += 1
    raw = labels.reshape(h, w)
    smooth = _smooth_labels(raw, n_classes)
    return SpatializedClasses(smooth, raw, counts.reshape(h, w), bary.reshape(h, w, 3),
                              var.reshape(h, w), value_edges, gradient_edges)


def _smooth_labels(labels: np.ndarray, n_classes: int) -> np.ndarray:
    """Denoise the label image with a Gaussian vote (σ = 1 bin) per class: a labelled bin
    takes another class where that class's vote is over twice its own (a majority filter),
    and an empty bin takes the strongest class whose vote reaches 0.3 (a closing: one-bin
    gaps inside a class are filled). Isolated bins keep their class (rare values still get
    a colour)."""
    if n_classes == 0:
        return labels.copy()
    kernel = np.exp(-0.5 * np.arange(-2, 3) ** 2)
    kernel /= kernel.sum()
    votes = np.empty((n_classes, *labels.shape))
    for k in range(n_classes):
        mask = (labels == k).astype(np.float64)
        for axis in (0, 1):
            mask = np.apply_along_axis(lambda r: np.convolve(r, kernel, mode="same"), axis,
                                       mask)
        votes[k] = mask
    best = votes.argmax(axis=0)
    strongest = votes.max(axis=0)
    own = np.take_along_axis(votes, np.clip(labels, 0, None)[None], axis=0)[0]
    relabel = (labels >= 0) & (best != labels) & (strongest > 2.0 * own)
    fill = (labels < 0) & (strongest >= 0.3)
    return np.where(relabel | fill, best, labels)


def class_colors(n: int, seed: int = 0) -> list[tuple[float, float, float]]:
    """``n`` distinct saturated colours (random hues, golden-ratio spaced, as the seed's
    "random colour per class" but never two alike)."""
    rng = np.random.default_rng(seed)
    start = float(rng.uniform())
    out = []
    for i in range(n):
        hue = (start + i * 0.618033988749895) % 1.0
        out.append(_hsv_to_rgb(hue, 0.75, 1.0))
    return out


def _hsv_to_rgb(h: float, s: float, v: float) -> tuple[float, float, float]:
    i = int(h * 6.0) % 6
    f = h * 6.0 - int(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    r, g, b = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i]
    return (float(r), float(g), float(b))


def classes_to_tf(classes: SpatializedClasses, *, opacity_scale: float = DEFAULT_OPACITY_SCALE,
                  colors: list[tuple[float, float, float]] | None = None,
                  soft_edge: float = 0.0, one_per_class: bool = False,
                  background: bool = True) -> TransferFunction2D:
    """The classes as an editable 2-D TF: per class and gradient row, one rectangle per run
    of bins, in the class's colour, with opacity = min(1, c_α · g/g_max) at the row's centre
    gradient (seed 001 eq. 2.46, read as a scale; the row's rectangle carries it). Rows of a
    class with the same run merge (their opacity averaged) when the primitive count would
    pass :data:`MAX_PRIMITIVES`.

    ``one_per_class``: one rectangle per class instead, the box of its bins, its opacity at
    the box's centre gradient: a few regions a user can edit (the runs made ~60 small ones,
    issue 25). ``background=False`` leaves out the class of the histogram's fullest bin, in
    microscopy the background and its noise (which showed as a fog over the volume)."""
    lo, hi = OPACITY_SCALE_RANGE
    if not (math.isfinite(opacity_scale) and lo <= opacity_scale <= hi):
        raise ValueError(f"opacity scale c_α {opacity_scale} must lie in {lo}…{hi}")
    n = classes.n_classes
    colors = colors if colors is not None else class_colors(n)
    ve, ge = classes.value_edges, classes.gradient_edges
    gmax = float(ge[-1]) or 1.0
    skip = -1
    if not background and n > 0 and classes.counts.size:
        skip = int(classes.labels.flat[int(np.argmax(classes.counts))])
    if one_per_class:
        boxes = []
        for k in range(n):
            rows, cols = np.nonzero(classes.labels == k)
            if k == skip or rows.size == 0:
                continue
            r0, r1 = int(rows.min()), int(rows.max()) + 1
            a, b = int(cols.min()), int(cols.max()) + 1
            g_mid = 0.5 * (ge[r0] + ge[r1])
            boxes.append(TFPrimitive(
                value_range=(float(ve[a]), float(ve[b])),
                gradient_range=(float(ge[r0]), float(ge[r1])),
                color=colors[k], opacity=float(min(1.0, opacity_scale * g_mid / gmax)),
                soft_edge=soft_edge))
        return TransferFunction2D(primitives=boxes)
    runs: list[tuple[int, int, int, int]] = []  # (class, row, first bin, last bin + 1)
    for row in range(classes.labels.shape[0]):
        line = classes.labels[row]
        start = 0
        for i in range(1, len(line) + 1):
            if i == len(line) or line[i] != line[start]:
                if line[start] >= 0 and line[start] != skip:
                    runs.append((int(line[start]), row, start, i))
                start = i
    # Merge vertically while over the limit: identical runs of one class in adjacent rows.
    blocks = [(k, row, row + 1, a, b) for k, row, a, b in runs]
    if len(blocks) > MAX_PRIMITIVES:
        merged: list[tuple[int, int, int, int, int]] = []
        for block in sorted(blocks, key=lambda q: (q[0], q[3], q[4], q[1])):
            last = merged[-1] if merged else None
            if last and last[0] == block[0] and last[3:] == block[3:] and last[2] == block[1]:
                merged[-1] = (last[0], last[1], block[2], last[3], last[4])
            else:
                merged.append(block)
        blocks = merged[:MAX_PRIMITIVES]
    primitives = []
    for k, r0, r1, a, b in blocks:
        g_mid = 0.5 * (ge[r0] + ge[r1])
        primitives.append(TFPrimitive(
            value_range=(float(ve[a]), float(ve[b])),
            gradient_range=(float(ge[r0]), float(ge[r1])),
            color=colors[k], opacity=float(min(1.0, opacity_scale * g_mid / gmax)),
            soft_edge=soft_edge if b - a > 1 else 0.0))
    return TransferFunction2D(primitives=primitives)
