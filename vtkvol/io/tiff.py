"""TIFF reader: ImageJ hyperstacks, OME-TIFF, plain multi-page TIFF, folders of slices.

Axes come from tifffile's series axes (``TZCYXS`` for ImageJ, the OME ``DimensionOrder``,
tifffile's own ``shaped`` metadata, ``I``/``Q`` for unlabelled stacks) and are rearranged to
``[c, z, y, x]``; ``C`` and ``S`` (RGB samples) become channels, ``T`` is indexed by
``time_index``. Uncompressed contiguous files (what ImageJ and tifffile write by default)
are memory-mapped; other files are decoded page by page, several pages at a time on a
thread pool, with a progress/cancel check per chunk.

Voxel size (µm), in order of precedence: OME ``PhysicalSize{X,Y,Z}`` with their units;
ImageJ (``XResolution``/``YResolution`` in the ``unit`` of the description, ``spacing`` for z);
Zeiss LSM voxel sizes; plain ``XResolution``/``YResolution`` with ``ResolutionUnit``.
"""

from __future__ import annotations

import logging
import math
import os
import re
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tifffile

from vtkvol.io.errors import ReadCancelled, VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.progress import Progress, slabs
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.tiff_metadata import (
    _bit_depth,
    _channel_names,
    _finish_voxel_size,
    _format_name,
    _tag_value,
    _voxel_info,
)
from vtkvol.io.time_series import time_unit_seconds
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
)

__all__ = ["TIFF_READER", "natural_sort_key", "read_tiff", "read_tiff_folder"]

TIFF_SUFFIXES = (".tif", ".tiff", ".btf", ".tf8", ".tf2")
_MAXWORKERS = max(1, min(8, os.cpu_count() or 1))
_CHUNK_BYTES = 32 << 20
_MAX_IMAGEJ_CHANNELS = 7
_CORRUPTION_HINTS = (
    "invalid page offset",
    "invalid offset to first page",
    "corrupt",
    "truncated",
    "failed to reshape",
    "failed to read",
    "invalid tag",
)


# -- tifffile log capture --------------------------------------------------------------------
class _LogCapture(logging.Handler):
    """Collects tifffile's log records of the current thread.

    tifffile reports truncated and corrupted files by *logging* and carrying on with fewer
    pages; we turn those records into errors. While this handler is attached, Python's
    last-resort stderr handler stays quiet, so the user sees our message instead.
    """

    def __init__(self) -> None:
        super().__init__(level=logging.WARNING)
        self.thread = threading.get_ident()
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.thread == self.thread:
            self.records.append(record)

    def corruption(self) -> str | None:
        for record in self.records:
            message = record.getMessage()
            if "circular reference" in message.lower():
                # tifffile stops at the loop and returns the pages before it: a damaged file
                # whose other pages are lost, not a shorter image.
                return ("its chain of pages loops back on itself: "
                        + _strip_logger_prefix(message))
            if any(hint in message.lower() for hint in _CORRUPTION_HINTS):
                return _strip_logger_prefix(message)
        return None

    def other_errors(self) -> list[str]:
        return [
            _strip_logger_prefix(r.getMessage()) for r in self.records if r.levelno >= logging.ERROR
        ]


def _strip_logger_prefix(message: str) -> str:
    # "<tifffile.TiffPages @8> invalid page offset 65888" -> "invalid page offset 65888"
    return re.sub(r"^<[^>]*>\s*", "", message).strip()


@contextmanager
def _capture_tifffile_log() -> Iterator[_LogCapture]:
    logger = logging.getLogger("tifffile")
    handler = _LogCapture()
    logger.addHandler(handler)
    try:
        yield handler
    finally:
        logger.removeHandler(handler)


# -- axes ------------------------------------------------------------------------------------
@dataclass
class _AxisPlan:
    """What each axis of the unsqueezed series is used for.

    ``roles[i]`` is one of ``"t"`` (indexed by time_index), ``"z"``, ``"c"`` (all ``C``/``S``
    axes merge into one channel axis, in file order), ``"y"``, ``"x"`` or ``"drop"`` (a
    size-1 axis, indexed at 0).
    """

    axes: str
    shape: tuple[int, ...]
    roles: list[str]
    n_time: int
    notes: list[str] = field(default_factory=list)

    @property
    def n_channels(self) -> int:
        return math.prod(n for n, r in zip(self.shape, self.roles, strict=True) if r == "c")


def _plan_axes(axes: str, shape: Sequence[int], source: Path, *, imagej: bool = False) -> _AxisPlan:
    """Decide the role of every axis; raise if the axes are ambiguous.

    ``imagej``: tifffile writes a 3-D array saved with ``imagej=True`` and no axes as
    *channels* (CYX); more than 7 channels (ImageJ's composite limit) and no z or time axis
    is read as a z-stack, with a note.
    """
    shape = tuple(int(n) for n in shape)
    sizes = dict(zip(axes, shape, strict=True))
    if (
        imagej
        and sizes.get("C", 1) > _MAX_IMAGEJ_CHANNELS
        and sizes.get("Z", 1) == 1
        and sizes.get("T", 1) == 1
        and sizes.get("S", 1) == 1
    ):
        plan = _plan_axes(axes.replace("C", "Z"), shape, source)
        plan.axes = axes
        plan.notes.append(
            f"the ImageJ metadata declare {sizes['C']} channels and no z axis; read as "
            f"{sizes['C']} z slices (more than {_MAX_IMAGEJ_CHANNELS} channels is a z-stack "
            "saved without axes)"
        )
        return plan
    if "Y" not in axes or "X" not in axes:
        raise VolumeReadError(source, f"no image plane (Y, X axes) in axes {axes!r}, shape {shape}")
    roles: list[str] = []
    for axis, n in zip(axes, shape, strict=True):
        if axis in "YX":
            roles.append(axis.lower())
        elif axis in "CS":
            roles.append("c")
        elif n == 1:
            roles.append("drop")
        elif axis == "Z":
            roles.append("z")
        elif axis == "T":
            roles.append("t")
        else:
            roles.append("?")
    plan = _AxisPlan(axes, shape, roles, n_time=1)
    unknown = [i for i, r in enumerate(roles) if r == "?"]
    has_z = "z" in roles
    described = f"axes {axes!r}, shape {shape}"
    if unknown and has_z:
        extra = ", ".join(f"{axes[i]!r} (size {shape[i]})" for i in unknown)
        raise VolumeReadError(
            source,
            f"ambiguous axes: besides Z there is {extra}, which vtkvol cannot interpret "
            f"({described}); save one z-stack per file or use .npy [c, z, y, x]",
        )
    if len(unknown) > 1:
        raise VolumeReadError(
            source,
            f"ambiguous axes: {len(shape)}-D data ({described}) has {len(unknown)} unlabelled "
            "axes, so it is unclear which is z, channel or time; save it as an ImageJ "
            "hyperstack or OME-TIFF (with axes metadata), or as .npy [c, z, y, x]",
        )
    if unknown:
        i = unknown[0]
        roles[i] = "z"
        if axes[i] not in "QI":
            plan.notes.append(f"axis {axes[i]!r} (size {shape[i]}) is used as z")
    elif not has_z and "t" in roles:
        i = roles.index("t")
        roles[i] = "z"
        plan.notes.append(
            f"the file has no z axis: its {shape[i]} time points are used as z slices"
        )
    if "t" in roles:
        plan.n_time = shape[roles.index("t")]
    return plan


def _check_time_index(plan: _AxisPlan, time_index: int, source: Path) -> None:
    n = plan.n_time
    if not 0 <= time_index < n:
        if n == 1:
            problem = (
                f"time_index {time_index} is out of range: the file has 1 time point (index 0)"
            )
        else:
            problem = (
                f"time_index {time_index} is out of range: the file has {n} time points (0–{n - 1})"
            )
        raise VolumeReadError(source, problem)


def _arrange(array: np.ndarray, roles: Sequence[str], time_index: int) -> np.ndarray:
    """View of ``array`` (axes per ``roles``) as ``[c, z, y, x]``; copies only when 2+ C axes."""
    index: list[Any] = []
    kept: list[str] = []
    for role in roles:
        if role == "t":
            index.append(time_index)
        elif role == "drop":
            index.append(0)
        else:
            index.append(slice(None))
            kept.append(role)
    view = array[tuple(index)]
    c_axes = [i for i, r in enumerate(kept) if r == "c"]
    others = [kept.index(r) for r in ("z", "y", "x") if r in kept]
    view = view.transpose(c_axes + others)
    n_c = math.prod(view.shape[: len(c_axes)])
    if "z" not in kept:
        view = view.reshape(*view.shape[: len(c_axes)], 1, *view.shape[len(c_axes) :])
    if len(c_axes) != 1:
        # No channel axis: add one (a view). Several (C and RGB S): merge them (may copy).
        view = view.reshape(n_c, *view.shape[len(c_axes) :])
    return view


def _materialize(
    view: np.ndarray, channels: Sequence[int], progress: Progress, message: str
) -> np.ndarray:
    """C-contiguous ``[c, z, y, x]`` of the selected channels, copied slab by slab.

    A view that already is contiguous with all channels is returned as is (so a
    memory-mapped single-channel stack stays memory-mapped and costs nothing to "read").
    """
    if list(channels) == list(range(view.shape[0])) and view.flags.c_contiguous:
        progress(1.0, message)
        return view
    out = np.empty((len(channels), *view.shape[1:]), dtype=view.dtype)
    n_z = view.shape[1]
    per_z = view[0, 0].nbytes * len(channels)
    # z outer, channels inner: follows the file order of ImageJ's ZCYX layout.
    for sl in slabs(n_z, per_z):
        for j, c in enumerate(channels):
            out[j, sl] = view[c, sl]
        progress(sl.stop / n_z, f"{message}: slice {sl.stop} of {n_z}")
    return out


# -- reading ---------------------------------------------------------------------------------
def _open(path: Path, **flags: bool) -> tifffile.TiffFile:
    try:
        return tifffile.TiffFile(path, **flags)
    except MemoryError:
        raise
    except Exception as exc:  # tifffile's parser fails in many ways on corrupt tags (TypeError…)
        raise VolumeReadError(path, f"not a readable TIFF file ({exc})") from exc


def _imagej_page_mismatch(tif: tifffile.TiffFile) -> str | None:
    """When an ImageJ description promises a different number of images than the file has
    pages (slices=5 on 10 pages), what it says; tifffile would follow the description and
    drop pages without a word."""
    try:
        if not tif.is_imagej or not tif.series:
            return None
        series = tif.series[0]
        planes = math.prod(int(n) for n, a in zip(series.get_shape(False),
                                                  series.get_axes(False), strict=True)
                           if a not in "YXS")
        pages = len(tif.pages)
    except Exception:  # a corrupt file: the reader proper names what is wrong with it
        return None
    # Fewer pages than images is how ImageJ stores files over 4 GiB (one IFD, contiguous
    # planes), which tifffile reads, or a truncated file, which it reports: only more pages
    # than the description accounts for would be dropped.
    if pages <= planes:
        return None
    ij = tif.imagej_metadata or {}
    said = ", ".join(f"{k}={ij[k]}" for k in ("images", "channels", "slices", "frames") if k in ij)
    return (f"the ImageJ description ({said}) describes {planes} images but the file has "
            f"{pages} pages: the description was ignored and every page read as a z slice")


def _memmap(tif: tifffile.TiffFile, series: Any, path: Path) -> np.memmap | None:
    """The series as a read-only memory map in its unsqueezed shape, if stored contiguously."""
    offset = series.dataoffset
    page = series.keyframe
    if offset is None or not page.is_memmappable:
        return None
    shape = tuple(series.get_shape(False))
    dtype = np.dtype(series.dtype).newbyteorder(tif.byteorder)
    counts = page.databytecounts
    if counts is not None and 0 < sum(int(c) for c in counts) < page.nbytes:
        # The strips hold less than the page: mapping it would show the bytes that follow
        # (other tags, the next page) as voxels.
        raise VolumeReadError(
            path,
            f"corrupt TIFF: page 0 declares {sum(int(c) for c in counts)} bytes of image data, "
            f"but a {'×'.join(str(n) for n in page.shape)} {np.dtype(page.dtype).name} page "
            f"needs {page.nbytes}",
        )
    expected = offset + math.prod(shape) * dtype.itemsize
    actual = path.stat().st_size
    if actual < expected:
        raise VolumeReadError(
            path,
            f"truncated TIFF: the image data should end at byte {expected}, but the file has "
            f"{actual} bytes",
        )
    return np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape)


def _page_split(series: Any, shape: tuple[int, ...], axes: str) -> int | None:
    """Number k of trailing axes that one page holds, or None if pages don't tile the series."""
    pages = series.pages
    n_pages = len(pages)
    page_size = math.prod(series.keyframe.shaped)
    for k in range(2, len(shape) + 1):
        if (
            math.prod(shape[-k:]) == page_size
            and math.prod(shape[:-k]) == n_pages
            and "Y" in axes[-k:]
            and "X" in axes[-k:]
        ):
            return k
    return None


#: No TIFF codec packs more than this (zlib ≈ 1000:1, zstd's RLE blocks ≈ 33000:1).
MAX_COMPRESSION_RATIO = 100_000


def _check_page_bounds(series: Any, path: Path) -> None:
    size = path.stat().st_size
    for i, page in enumerate(series.pages):
        if page is None:
            raise VolumeReadError(path, f"corrupt TIFF: page {i} of the image series is missing")
        offsets = page.dataoffsets
        counts = page.databytecounts
        if offsets is None or counts is None or len(offsets) == 0:
            continue
        end = max(int(o) + int(c) for o, c in zip(offsets, counts, strict=False))
        if end > size:
            raise VolumeReadError(
                path,
                f"truncated TIFF: page {i} needs data up to byte {end}, the file has {size} bytes",
            )
        if page.dtype is None:
            raise VolumeReadError(
                path, f"page {i} stores {_tag_value(page, 'BitsPerSample')}-bit samples of "
                      "a kind tifffile cannot decode",
            )
        stored = sum(int(c) for c in counts)
        if page.nbytes > MAX_COMPRESSION_RATIO * stored + (1 << 20):
            # Decoding would allocate what the tags claim (once per codec buffer too).
            raise VolumeReadError(
                path,
                f"corrupt TIFF: page {i} claims {page.nbytes} bytes of image data stored in "
                f"{stored} bytes, more than any TIFF compression achieves",
            )


def _read_pages(
    tif: tifffile.TiffFile,
    series: Any,
    plan: _AxisPlan,
    k: int,
    time_index: int,
    channel_index: list[int],
    progress: Progress,
) -> tuple[np.ndarray, list[int]]:
    """Decode only the pages needed; returns ([c, z, y, x] view, channels still to select)."""
    rest_shape = plan.shape[:-k]
    rest_roles = plan.roles[:-k]
    page_roles = plan.roles[-k:]
    page_shape = plan.shape[-k:]
    grid = np.arange(len(series.pages)).reshape(rest_shape)
    index: list[Any] = []
    kept_roles: list[str] = []
    remaining = channel_index
    c_rest = [i for i, r in enumerate(rest_roles) if r == "c" and rest_shape[i] > 1]
    c_page = [i for i, r in enumerate(page_roles) if r == "c" and page_shape[i] > 1]
    channel_axis: int | None = None
    for i, role in enumerate(rest_roles):
        if role == "t":
            index.append(time_index)
        elif role == "drop":
            index.append(0)
        else:
            if role == "c" and c_rest == [i] and not c_page:
                channel_axis = len(kept_roles)
            index.append(slice(None))
            kept_roles.append(role)
    selected = grid[tuple(index)]
    if channel_axis is not None:
        # Select channels here, so that unselected channels' pages are never decoded.
        selected = np.take(selected, channel_index, axis=channel_axis)
        remaining = list(range(len(channel_index)))
    keys = [int(v) for v in selected.ravel()]
    buffer = np.empty((len(keys), *page_shape), dtype=series.dtype)
    page_bytes = max(1, buffer[0].nbytes) if keys else 1
    chunk = max(_MAXWORKERS, _CHUNK_BYTES // page_bytes)
    for start in range(0, len(keys), chunk):
        stop = min(len(keys), start + chunk)
        block = tif.asarray(key=keys[start:stop], series=series, maxworkers=_MAXWORKERS)
        buffer[start:stop] = np.asarray(block).reshape(stop - start, *page_shape)
        progress(stop / len(keys), f"decoding page {stop} of {len(keys)}")
    buffer = buffer.reshape(*selected.shape, *page_shape)
    view = _arrange(buffer, kept_roles + list(page_roles), time_index)
    return view, remaining


def read_tiff(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read a TIFF file (or a folder of single-slice TIFFs) into ``[c, z, y, x]``.

    Parameters
    ----------
    path
        A ``.tif``/``.tiff`` file, or a folder (see :func:`read_tiff_folder`).
    time_index
        Which time point to read when the file has a T axis.
    channels
        Indices or names of the channels to keep (default all).
    progress
        Called per chunk of pages; raises ReadCancelled on cancel.

    Returns
    -------
    VolumeData
        Voxels in the file's dtype (normalised later by the caller), voxel size in µm.
    """
    progress = progress or Progress()
    path = Path(path)
    if path.is_dir():
        return read_tiff_folder(path, time_index=time_index, channels=channels, progress=progress)
    with _capture_tifffile_log() as log:
        tif = _open(path)
        mismatch = _imagej_page_mismatch(tif)
        if mismatch:
            tif.close()
            tif = _open(path, is_imagej=False)  # the pages as they are
        try:
            data = _read_tiff_file(tif, path, time_index, channels, progress, log)
            if mismatch:
                data.notes.insert(0, mismatch)
            return data
        except (VolumeReadError, ReadCancelled, MemoryError):
            raise
        except Exception as exc:
            problem = log.corruption()
            detail = problem or str(exc) or type(exc).__name__
            raise VolumeReadError(path, f"corrupt or truncated TIFF ({detail})") from exc
        finally:
            tif.close()


def _read_tiff_file(
    tif: tifffile.TiffFile,
    path: Path,
    time_index: int,
    channels: Sequence[int | str] | None,
    progress: Progress,
    log: _LogCapture,
) -> VolumeData:
    series_list = tif.series
    if not series_list or not tif.pages:
        problem = log.corruption()
        if problem:
            raise VolumeReadError(path, f"corrupt or truncated TIFF ({problem})")
        raise VolumeReadError(path, "the TIFF file contains no images")
    problem = log.corruption()
    if problem:
        raise VolumeReadError(path, f"corrupt or truncated TIFF ({problem})")
    series = series_list[0]
    axes = series.get_axes(False)
    shape = tuple(int(n) for n in series.get_shape(False))
    # tifffile describes a file of one 1×1 page with the axes "XYX": it is one voxel.
    single_voxel = len(tif.pages) == 1 and math.prod(shape) == 1
    if single_voxel:
        axes, shape = "YX", (1, 1)
    if 0 in shape:
        raise VolumeReadError(path, f"the image has a zero-size axis: axes {axes!r}, shape {shape}")
    plan = _plan_axes(axes, shape, path, imagej=bool(tif.is_imagej))
    _check_time_index(plan, time_index, path)
    page = series.keyframe
    names = _channel_names(tif, series, plan, 0)
    channel_index = resolve_channels(channels, names, str(path))

    memmapped = None if single_voxel else _memmap(tif, series, path)
    if memmapped is not None:
        view = _arrange(memmapped, plan.roles, time_index)
        array = _materialize(view, channel_index, progress, "reading")
    else:
        _check_page_bounds(series, path)
        # Decoding allocates what the header declares (for one time point); refuse a lie
        # before numpy fails with a MemoryError.
        check_declared_bytes(
            path, math.prod(shape) // max(plan.n_time, 1) * np.dtype(series.dtype).itemsize,
            f"{'×'.join(str(n) for n in shape)} {np.dtype(series.dtype).name} (axes {axes})",
        )
        k = _page_split(series, shape, axes)
        if k is None:
            progress(0.0, "reading image data")
            whole = np.asarray(series.asarray(maxworkers=_MAXWORKERS)).reshape(shape)
            view = _arrange(whole, plan.roles, time_index)
            remaining = channel_index
        else:
            view, remaining = _read_pages(
                tif, series, plan, k, time_index, channel_index, progress.sub(0.0, 0.9)
            )
        array = _materialize(view, remaining, progress.sub(0.9, 1.0), "arranging")
    problem = log.corruption()
    if problem:
        raise VolumeReadError(path, f"corrupt or truncated TIFF ({problem})")

    info = _voxel_info(tif, page, 0)
    spacing, from_md, voxel_source, voxel_notes = _finish_voxel_size(info, array.shape[1])
    notes = list(plan.notes) + voxel_notes
    notes.extend(f"tifffile: {message}" for message in log.other_errors())
    if len(series_list) > 1:
        notes.append(f"the file holds {len(series_list)} image series; the first one was read")
    metadata: dict[str, Any] = {
        "format": _format_name(tif),
        "axes": series.axes,
        "shape_in_file": tuple(int(n) for n in series.shape),
        "time_points": plan.n_time,
        "time_index": time_index,
        "compression": _compression_name(page),
        "memory_mapped": isinstance(array, np.memmap),
        "voxel_size_source": voxel_source,
    }
    bits = _bit_depth(tif, page, 0)
    if bits:
        metadata["bit_depth"] = bits
        notes.append(f"the file declares {bits}-bit data")
    if tif.is_imagej and tif.imagej_metadata:
        ij = tif.imagej_metadata
        for key in ("min", "max", "finterval", "unit"):
            if key in ij:
                metadata[f"imagej_{key}"] = ij[key]
        interval = _frame_interval_s(ij, plan.n_time, notes)
        if interval is not None:
            metadata["time_interval_s"] = interval
    return VolumeData(
        array,
        spacing,
        [names[i] for i in channel_index],
        source=str(path),
        voxel_size_from_metadata=from_md,
        metadata=metadata,
        notes=notes,
    )


def _frame_interval_s(ij: dict[str, Any], n_time: int, notes: list[str]) -> float | None:
    """Seconds between time points from ImageJ's ``finterval`` (in ``tunit``, seconds when
    absent); None for single time points or a value that is not a positive number."""
    if n_time < 2 or "finterval" not in ij:
        return None
    try:
        value = float(ij["finterval"])
    except (TypeError, ValueError):
        value = math.nan
    scale = time_unit_seconds(ij.get("tunit"))
    if scale is None:
        notes.append(f"unknown time unit {ij.get('tunit')!r}: the frame interval is ignored")
        return None
    if not (math.isfinite(value) and value > 0):
        return None
    return value * scale


def _compression_name(page: Any) -> str:
    compression = getattr(page, "compression", 1)
    name = getattr(compression, "name", None)
    return str(name).lower() if name else str(compression)


# -- folders of slices -----------------------------------------------------------------------
_NATURAL = re.compile(r"(\d+)")
_CHANNEL_TOKEN = re.compile(r"(?:^|[^a-z0-9])(?:ch|channel|c)[_-]?(\d+)(?=$|[^0-9])", re.IGNORECASE)


def natural_sort_key(name: str) -> list[Any]:
    """Sort key that orders embedded numbers numerically: ``z2`` before ``z10``."""
    parts = _NATURAL.split(name.lower())
    return [int(p) if i % 2 else p for i, p in enumerate(parts)]


def _group_by_channel(files: list[Path], folder: Path) -> tuple[list[str], list[list[Path]]]:
    """Split files into channels when every name carries a channel token (``_c0_``, ``ch1``).

    Only when there are at least two channels; otherwise everything is one channel (a token
    like ``c0`` in all names is then just a name part). Channels with different numbers of
    files are refused (VolumeReadError naming each channel's count): which slice a channel
    lacks is unknown, and stacking all files as one channel would mix channels into z.
    """
    tokens = [_CHANNEL_TOKEN.findall(f.stem) for f in files]
    if not all(tokens):
        return ["ch0"], [files]
    labels = [int(t[-1]) for t in tokens]
    distinct = sorted(set(labels))
    if len(distinct) < 2:
        return ["ch0"], [files]
    groups = [[f for f, lab in zip(files, labels, strict=True) if lab == d] for d in distinct]
    if len({len(g) for g in groups}) != 1:
        counts = ", ".join(f"c{d}: {len(g)}" for d, g in zip(distinct, groups, strict=True))
        raise VolumeReadError(
            folder,
            f"the file names give {len(groups)} channels with different numbers of slices "
            f"({counts}); nothing was read, since which slices are missing is unknown and one "
            "stack of every file would mix channels into z. Give each channel the same slices "
            "(or move each channel to a folder of its own)",
        )

    def z_key(f: Path) -> list[Any]:
        # Sort each channel's slices without the channel number getting in the way.
        return natural_sort_key(_CHANNEL_TOKEN.sub("_", f.name))

    return [f"c{d}" for d in distinct], [sorted(g, key=z_key) for g in groups]


def _read_slice(path: Path) -> np.ndarray:
    """One file of a folder as ``(c, y, x)``."""
    with _capture_tifffile_log() as log:
        tif = _open(path)
        try:
            series = tif.series[0] if tif.series else None
            if series is None:
                raise VolumeReadError(path, "the TIFF file contains no images")
            axes = series.get_axes(False)
            shape = tuple(int(n) for n in series.get_shape(False))
            extra = [(a, n) for a, n in zip(axes, shape, strict=True) if a not in "YXCS" and n > 1]
            if extra:
                raise VolumeReadError(
                    path,
                    f"every file in a folder must hold one 2-D slice, but this one has axes "
                    f"{axes!r}, shape {shape}",
                )
            data = np.asarray(series.asarray()).reshape(shape)
            problem = log.corruption()
            if problem:
                raise VolumeReadError(path, f"corrupt or truncated TIFF ({problem})")
            roles = ["c" if a in "CS" else (a.lower() if a in "YX" else "drop") for a in axes]
            return _arrange(data, roles, 0)[:, 0]
        except VolumeReadError:
            raise
        except Exception as exc:
            detail = log.corruption() or str(exc) or type(exc).__name__
            raise VolumeReadError(path, f"corrupt or truncated TIFF ({detail})") from exc
        finally:
            tif.close()


def read_tiff_folder(
    folder: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read a folder of single-slice TIFFs as a z-stack.

    Files (``.tif``/``.tiff``, hidden files ignored) are sorted naturally, so ``z2`` comes
    before ``z10``. When every file name carries a channel token (``img_c0_z001.tif``,
    ``ch1``, ``channel2``), the channels are read separately (channels with different numbers
    of files are refused); RGB slices give three channels. Voxel size (x, y) comes from the first
    file's metadata; z from its ImageJ ``spacing`` if any, else it is assumed equal to x.
    """
    progress = progress or Progress()
    folder = Path(folder)
    files = sorted(
        (
            f
            for f in folder.iterdir()
            if f.is_file() and f.suffix.lower() in TIFF_SUFFIXES and not f.name.startswith(".")
        ),
        key=lambda f: natural_sort_key(f.name),
    )
    if not files:
        raise VolumeReadError(folder, "the folder holds no .tif/.tiff files")
    if time_index != 0:
        raise VolumeReadError(
            folder,
            f"time_index {time_index} is out of range: a folder of slices has 1 time point "
            "(index 0)",
        )
    group_names, groups = _group_by_channel(files, folder)
    first = _read_slice(groups[0][0])
    per_file = first.shape[0]
    if per_file > 1:
        names = [
            f"{g}-{s}" if len(groups) > 1 else s
            for g in group_names
            for s in (
                ["red", "green", "blue", "alpha"][:per_file]
                if per_file in (3, 4)
                else default_channel_names(per_file)
            )
        ]
    else:
        names = group_names if len(groups) > 1 else ["ch0"]
    chosen = resolve_channels(channels, names, str(folder))
    n_z = len(groups[0])
    out = np.empty((len(chosen), n_z, *first.shape[1:]), dtype=first.dtype)
    needed_groups = sorted({c // per_file for c in chosen})
    total = len(needed_groups) * n_z
    done = 0
    for g in needed_groups:
        for z, file in enumerate(groups[g]):
            plane = first if (g == 0 and z == 0) else _read_slice(file)
            if plane.shape != first.shape or plane.dtype != first.dtype:
                raise VolumeReadError(
                    folder,
                    f"slice {file.name} has shape {plane.shape[1:]} and dtype {plane.dtype}, "
                    f"but {groups[0][0].name} has {first.shape[1:]} and {first.dtype}; all "
                    "slices must match",
                )
            for j, c in enumerate(chosen):
                if c // per_file == g:
                    out[j, z] = plane[c % per_file]
            done += 1
            progress(done / total, f"reading {file.name} ({done} of {total})")

    with _capture_tifffile_log():
        tif = _open(groups[0][0])
        try:
            info = _voxel_info(tif, tif.pages[0], 0)
        finally:
            tif.close()
    spacing, from_md, voxel_source, notes = _finish_voxel_size(info, n_z)
    metadata = {
        "format": "tiff-folder",
        "axes": "ZYX" if per_file == 1 else "ZCYX",
        "files": len(files),
        "first_file": groups[0][0].name,
        "last_file": groups[0][-1].name,
        "time_points": 1,
        "time_index": 0,
        "voxel_size_source": voxel_source,
    }
    return VolumeData(
        out,
        spacing,
        [names[c] for c in chosen],
        source=str(folder),
        voxel_size_from_metadata=from_md,
        metadata=metadata,
        notes=notes,
    )


TIFF_READER = ReaderSpec(
    name="tiff",
    label="TIFF (ImageJ, OME-TIFF, multi-page, folder of slices)",
    filename_patterns=("*.tif", "*.tiff", "*.btf", "*.tf8", "*.tf2"),
    accepts_directories=True,
    read=read_tiff,
)
