"""Label images (segmentations): recognising them and showing each label in its own colour.

No VTK, no Qt. A label image stores an integer id per voxel (0 = background); the ids are
categories, not intensities, so a grey ramp shows most labels as nearly the same grey and
ramps the small ids into transparency. Here:

* :func:`detect_labels` says whether an array looks like labels: integer values, several
  distinct ids, each id covering a region (neighbouring voxels mostly equal, unlike the noise of
  an intensity image). Users can declare labels themselves; detection is a default, not a rule.
* :func:`label_colors` gives a categorical colour per id from the glasbey palette (Glasbey et
  al. 2007: colours chosen to be as distinct as possible), taken from the ``cmap`` package
  (optional extra ``labels``; BSD, the palette CC0).
* :func:`label_transfer_function` builds a :class:`TransferFunction` whose colour is constant
  over each id (steps at the half-integers between ids) and whose opacity is 0 on the
  background and on hidden labels, ``opacity`` elsewhere. Because every illumination technique
  reads opacity through the transfer function, shadows, occlusion and scattering then work on
  the labels' opacity like on any other volume.
* :func:`apply_labels` puts that transfer function on a channel of a :class:`SceneModel`,
  records the display (``Channel.labels``: opacity, hidden ids) and switches the model to
  nearest-voxel interpolation (``render.interpolation = "nearest"``): a trilinear sample
  between ids 3 and 40 is some id in between, which would paint boundaries in the colours of
  labels that are not there. :func:`show_intensities` undoes it for one channel.
* :func:`label_ids` is the one check that a channel can be shown as labels (integer values,
  a non-zero id, a span of ids the colour table resolves), used by ``vtkvol render --labels``
  and by the app alike; its refusal is one sentence naming the data.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from vtkvol.model.transfer_function import TransferFunction

if TYPE_CHECKING:
    from vtkvol.io import VolumeData
    from vtkvol.model.scene import SceneModel

__all__ = [
    "LabelDetection",
    "LabelImageError",
    "apply_labels",
    "detect_labels",
    "label_colors",
    "label_ids",
    "label_transfer_function",
    "labelled_channels",
    "show_detected_labels",
    "show_intensities",
]

#: At least this many distinct non-zero ids make a label image (a 0/1 mask or a three-class
#: image is better shown with an ordinary transfer function).
MIN_LABELS = 4
#: Of neighbouring voxel pairs along x that are not both background, at least this fraction
#: must be equal: labels are regions. Measured: segmented blobs of radius >= 3 voxels give
#: >= 0.8; the noisy 12-bit sample and dim 8-bit noise give < 0.3.
MIN_EQUAL_NEIGHBOURS = 0.7
#: Of the same pairs (and of the pairs between a few adjacent z slices), at most this
#: fraction may be small steps (both non-zero, differing by 1 or 2): intensities change
#: gradually, neighbouring ids only where objects touch. Measured along x: 28 % and 39 % on
#: the 8-bit bead and deconvolution crops of ../shared/data (whose neighbours
#: are also equal in 71 % and 61 % of pairs, like labels), 0 % on the platynereis nuclei labels
#: and on random balls; a dense segmentation numbered in raster order has small steps only at
#: its boundaries (about one pair in the objects' diameter).
MAX_SMALL_STEPS = 0.15
#: Each id must cover this many voxels on average (noise takes each value a few times).
MIN_VOXELS_PER_LABEL = 8
#: Detection looks at most at this many voxels (whole x rows of evenly spaced z slices).
MAX_SAMPLED_VOXELS = 8_000_000
#: The quick look of :func:`detect_labels` takes at most this many voxels (whole z slices)
#: and rejects the array as intensities when fewer than QUICK_REJECT of its neighbour pairs
#: are equal: half the full test's threshold, so only data far from labels is rejected on
#: the small sample. Measured: 0.5 s → 0.06 s for a 512 × 512 × 200 uint16 noise stack.
QUICK_SAMPLED_VOXELS = 1_000_000
QUICK_REJECT = MIN_EQUAL_NEIGHBOURS / 2
#: A colour is constant over [id - STEP, id + STEP] (data units), changing linearly to the
#: next id's in the 0.25 between. VTK sizes its lookup texture by the closest two points
#: (0.25 apart: 4 texels per id), so the texels either side of an id both lie on its plateau
#: and the filtered lookup returns exactly its colour (measured: with plateaus of ±0.25 and
#: 2 texels per id, 1 % of the pixels of a 30-label scene showed a blend of two ids).
STEP = 0.375
#: Largest span of ids (highest - lowest) whose colours VTK's lookup table resolves exactly:
#: its texture holds at most 16384 entries on common GL drivers (llvmpipe too), 4 per id.
MAX_ID_SPAN = 4000


@dataclass(frozen=True)
class LabelDetection:
    """Whether an array looks like a label image, and why (``reason``: one sentence)."""

    is_labels: bool
    reason: str
    #: The non-zero ids seen (in the sampled part); empty when the values are intensities.
    labels: tuple[int, ...] = ()


def detect_labels(array: np.ndarray) -> LabelDetection:
    """Decide whether ``array`` (``[z, y, x]`` or ``[c, z, y, x]``, one channel) is a label
    image: integer dtype, at least :data:`MIN_LABELS` distinct non-zero ids, neighbours
    mostly equal (:data:`MIN_EQUAL_NEIGHBOURS`) and ids covering :data:`MIN_VOXELS_PER_LABEL`
    voxels on average. Large arrays are judged on evenly spaced z slices (at most
    :data:`MAX_SAMPLED_VOXELS` voxels)."""
    a = np.asarray(array)
    if a.ndim == 4:
        if a.shape[0] != 1:
            return LabelDetection(False, f"{a.shape[0]} channels: label images have one")
        a = a[0]
    if a.ndim != 3:
        raise ValueError(f"expected a [z, y, x] array, got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.integer):
        return LabelDetection(False, f"{a.dtype} values: label ids are integers")
    # A quick look first (the app runs this on every file it opens): intensities are
    # rejected on a few slices when their neighbours are equal far less often than labels'.
    quick = _neighbours(_slices(a, QUICK_SAMPLED_VOXELS))
    if quick is not None and quick[0] < QUICK_REJECT:
        return _varies(quick[0])
    sample = _slices(a, MAX_SAMPLED_VOXELS)
    # The neighbour tests first: they are cheap, and they are what rejects intensity images.
    found = _neighbours(sample)
    equal, small = found if found is not None else (0.0, 0.0)
    if found is not None and equal < MIN_EQUAL_NEIGHBOURS:
        return _varies(equal)
    if a.shape[0] > 1:
        # Along z as well (on a few pairs of adjacent slices): a stack of flat planes changes
        # only from slice to slice.
        starts = np.unique(np.linspace(0, a.shape[0] - 2, 4).round().astype(int))
        along_z = _neighbours(np.stack([a[starts], a[starts + 1]], axis=-1))
        if along_z is not None:
            small = max(small, along_z[1])
    if small > MAX_SMALL_STEPS:
        return LabelDetection(
            False, f"neighbouring voxels differ by 1 or 2 in {small:.0%} of pairs: intensities "
                   "change in small steps, ids do not")
    ids, counts = np.unique(sample, return_counts=True)
    nonzero = ids != 0
    labels = tuple(int(v) for v in ids[nonzero])
    if len(labels) < MIN_LABELS:
        return LabelDetection(False, f"only {len(labels)} distinct non-zero value(s)", labels)
    per_label = counts[nonzero].sum() / len(labels)
    if per_label < MIN_VOXELS_PER_LABEL:
        return LabelDetection(
            False, f"{len(labels)} values covering {per_label:.1f} voxels each on average: "
                   "intensities, not regions")
    return LabelDetection(
        True, f"{len(labels)} integer ids over regions (neighbours equal in {equal:.0%} of "
              "pairs)", labels)


class LabelImageError(ValueError):
    """The values cannot be shown as labels; the message is one sentence for the user that
    names the data."""


def label_ids(values: np.ndarray, name: str) -> list[int]:
    """The non-zero ids of the label image ``values`` (any shape, one channel), ascending.

    ``name`` (a file name, or a channel's) starts the refusal. This is the one check behind
    ``vtkvol render --labels`` and the app's labels mode.

    Raises
    ------
    LabelImageError
        Float values (label ids are integers; an int32 image whose ids did not fit 16 bits
        was read as float32), no id but the background, or ids spanning more than
        :data:`MAX_ID_SPAN` values (e.g. a million distinct ids), with the hint to renumber.
    """
    a = np.asarray(values)
    if not np.issubdtype(a.dtype, np.integer):
        raise LabelImageError(f"{name} holds {a.dtype} values; label ids are integers")
    # The span first (min and max need no sort): a million ids are refused before np.unique.
    nonzero = a[a != 0]
    if nonzero.size:
        lo, hi = int(nonzero.min()), int(nonzero.max())
        hint = "renumber them first (e.g. skimage.segmentation.relabel_sequential)"
        if hi - lo > MAX_ID_SPAN:
            raise LabelImageError(
                f"{name}: ids span {lo}…{hi}, more than {MAX_ID_SPAN}: {hint}")
        if max(hi, 0) - min(lo, 0) > MAX_ID_SPAN:  # the background's 0 is a colour step too
            raise LabelImageError(
                f"{name}: ids run from {lo} to {hi}; with the background 0 they span more "
                f"than {MAX_ID_SPAN} values: {hint}")
    ids = [int(v) for v in np.unique(nonzero)]
    if not ids:
        raise LabelImageError(f"{name} has no label other than 0 (background)")
    return ids


def labelled_channels(model: SceneModel) -> list[int]:
    """Indices of the channels of ``model`` shown as labels."""
    return [c for c, channel in enumerate(model.channels) if channel.labels is not None]


def _slices(a: np.ndarray, voxels: int) -> np.ndarray:
    """Evenly spaced whole z slices of ``a`` (``[z, y, x]``), at most ``voxels`` voxels (at
    least one slice)."""
    plane = max(1, a.shape[1] * a.shape[2])
    n_slices = max(1, min(a.shape[0], voxels // plane))
    return a[np.unique(np.linspace(0, a.shape[0] - 1, n_slices).round().astype(int))]


def _neighbours(sample: np.ndarray) -> tuple[float, float] | None:
    """Of the neighbouring voxel pairs along x not both 0: the fraction that are equal, and
    the fraction of small steps (both non-zero, differing by 1 or 2); None when every pair is
    background."""
    left, right = sample[..., :-1], sample[..., 1:]
    pairs = (left != 0) | (right != 0)
    n_pairs = int(pairs.sum())
    if not n_pairs:
        return None
    same = left == right
    equal = float(same[pairs].sum()) / n_pairs
    # Only the changes between two non-zero values (few in labels); int64, so that the
    # difference of unsigned values does not wrap.
    change = ~same & (left != 0) & (right != 0)
    step = np.abs(left[change].astype(np.int64) - right[change].astype(np.int64))
    return equal, float((step <= 2).sum()) / n_pairs


def _varies(equal: float) -> LabelDetection:
    return LabelDetection(
        False, f"neighbouring voxels equal in {equal:.0%} of pairs: intensities vary voxel to "
               "voxel")


def label_colors(labels: Iterable[int]) -> np.ndarray:
    """Glasbey colours for ``labels``: an ``(n, 3)`` float array in 0…1; id ``k`` gets palette
    entry ``(k - 1) mod 256``, so an id keeps its colour whatever other ids are present (as
    Fiji's glasbey LUT does).

    Raises
    ------
    ImportError
        The ``cmap`` package is missing, with the extra to install.
    """
    try:
        from cmap import Colormap
    except ImportError:
        raise ImportError("label colours need the optional package 'cmap': "
                          "pip install 'vtkvol[labels]'") from None
    palette = np.asarray(Colormap("glasbey").color_stops.color_array, dtype=np.float64)[:, :3]
    ids = np.asarray(list(labels), dtype=np.int64)
    return palette[(ids - 1) % len(palette)]


def label_transfer_function(
    labels: Iterable[int],
    *,
    opacity: float = 1.0,
    hidden: Iterable[int] = (),
    colors: np.ndarray | None = None,
) -> TransferFunction:
    """A step transfer function for the ids ``labels`` (data units): colour constant per id,
    opacity ``opacity`` (per opacity unit distance) on every id except those in ``hidden``, 0
    on the background (0) and on hidden ids. ``colors`` (``(n, 3)``, 0…1) overrides the
    glasbey colours."""
    if not 0.0 <= opacity <= 1.0:
        raise ValueError(f"label opacity must lie in 0…1, not {opacity}")
    ids = sorted({int(v) for v in labels} - {0})
    if not ids:
        raise ValueError("no label ids (0 is the background)")
    span = max(ids[-1], 0) - min(ids[0], 0)
    if span > MAX_ID_SPAN:
        raise ValueError(
            f"label ids span {span} values (from {min(ids[0], 0)} to {max(ids[-1], 0)}); "
            f"colours stay exact up to {MAX_ID_SPAN}: renumber the labels first, e.g. "
            "skimage.segmentation.relabel_sequential")
    rgb = label_colors(ids) if colors is None else np.asarray(colors, dtype=np.float64)
    if rgb.shape != (len(ids), 3):
        raise ValueError(f"need one RGB colour per label ({len(ids)}), got shape {rgb.shape}")
    off = {int(v) for v in hidden}
    color_points: list[tuple[float, float, float, float]] = []
    opacity_points: list[tuple[float, float]] = []
    for k, (r, g, b) in zip(ids, rgb, strict=True):
        alpha = 0.0 if k in off else opacity
        for v in (k - STEP, k + STEP):
            color_points.append((v, float(r), float(g), float(b)))
            opacity_points.append((v, alpha))
    lo, hi = min(0, ids[0]) - 1.0, ids[-1] + 1.0
    # The background's own step (ids may be negative: 0 is background wherever it sits).
    for v in (-STEP, STEP):
        color_points.append((v, 0.0, 0.0, 0.0))
        opacity_points.append((v, 0.0))
    return TransferFunction(colors=color_points, opacity=opacity_points,
                            window=(lo, hi), window_range=(lo, hi))


def apply_labels(
    model: SceneModel,
    labels: Iterable[int],
    *,
    channel: int = 0,
    opacity: float = 1.0,
    hidden: Iterable[int] = (),
) -> None:
    """Show ``model.channels[channel]`` as labels: the glasbey step transfer function of
    :func:`label_transfer_function`, ``Channel.labels`` (``opacity``, ``hidden``) and
    nearest-voxel interpolation, in one model event. ``hidden`` ids get opacity 0 (per-label
    visibility). A channel following another's transfer function stops following it."""
    from vtkvol.model.scene import LabelDisplay

    tf = label_transfer_function(labels, opacity=opacity, hidden=hidden)
    target = model.channels[channel]
    with model.batch():
        target.tf = tf
        target.tf_linked_to = None
        target.tf_mode = "1d"  # the steps are a 1-D function of the id
        target.labels = LabelDisplay(opacity=opacity, hidden=list(hidden))
        model.render.interpolation = "nearest"


def show_intensities(model: SceneModel, channel: int, tf: TransferFunction) -> None:
    """Show ``model.channels[channel]`` as intensities again, through ``tf`` (data units;
    e.g. :func:`vtkvol.model.defaults.default_transfer_function`), in one model event. When
    no other channel is a label image, the interpolation returns from nearest to trilinear."""
    with model.batch():
        model.channels[channel].labels = None
        model.channels[channel].tf = tf
        if not labelled_channels(model) and model.render.interpolation == "nearest":
            model.render.interpolation = "trilinear"


def show_detected_labels(
    model: SceneModel,
    data: VolumeData,
    refused: list[tuple[int, str]] | None = None,
) -> list[tuple[int, str]]:
    """Show as labels every channel of ``data`` that :func:`detect_labels` finds to be a
    label image and :func:`label_ids` accepts (:func:`apply_labels`, on ``model``, whose
    channels are ``data``'s); the others stay as they are. Returns ``(channel, reason)`` per
    channel so shown (``reason``: detection's sentence), for the notice the app shows.
    Channels that look like labels but cannot be coloured (e.g. ids spanning more than
    :data:`MAX_ID_SPAN`) are appended to ``refused`` as ``(channel, why)``."""
    shown: list[tuple[int, str]] = []
    for c in range(min(data.n_channels, len(model.channels))):
        found = detect_labels(data.array[c])
        if not found.is_labels:
            continue
        try:
            ids = label_ids(data.array[c], f"channel {data.channel_names[c]!r}")
        except LabelImageError as exc:
            if refused is not None:  # looks like labels, but cannot be coloured: a grey ramp
                refused.append((c, str(exc)))
            continue
        apply_labels(model, ids, channel=c)
        shown.append((c, found.reason))
    return shown
