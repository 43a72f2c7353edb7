"""``vtkvol convert``: write an OME-Zarr pyramid from a large TIFF (or any readable volume)
without holding the volume in memory.

The source is wrapped as a lazy dask array: a TIFF through tifffile's Zarr view of its pages
(compressed or not, only the pages a chunk needs are decoded), a pyramid (OME-Zarr, Imaris)
through its finest level's lazy slicing, any other format through its reader (memory-mapped
where the reader maps: raw, NRRD, ``.npy``; otherwise read into memory). The pyramid is written
by ome-zarr-py's writer (``ome_zarr.writer.write_image``: NGFF v0.5 on Zarr v3, or v0.4), which
downsamples each level from the one before chunk by chunk (dask), so memory stays a few chunks
per worker thread. Voxel size (µm) and channel names go into the metadata; the output is
written to a hidden temporary folder beside the target and renamed into place when complete.
"""

from __future__ import annotations

import errno
import math
import os
import shutil
import time
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_path
from vtkvol.io.optional import require

__all__ = ["ConvertError", "ConvertResult", "convert_to_ome_zarr", "lazy_source", "plan_levels"]

#: Chunk edge in x and y of the written arrays (voxels); z chunks hold about as many bytes.
CHUNK_XY = 256
#: The coarsest level written has its largest axis at most this many voxels.
COARSEST_SIDE = 256


class ConvertError(ValueError):
    """The conversion could not be done; the message names the file and the problem."""


@dataclass
class LazySource:
    """A volume as a lazy ``[c, z, y, x]`` dask array, with its voxel size and names."""

    array: Any  # dask.array.Array
    voxel_size_um: tuple[float, float, float]
    channel_names: list[str]
    notes: list[str]


@dataclass
class ConvertResult:
    """What :func:`convert_to_ome_zarr` wrote: ``levels`` as (c, z, y, x) shapes, finest
    first; ``seconds`` of wall time."""

    path: Path
    levels: list[tuple[int, int, int, int]]
    voxel_size_um: tuple[float, float, float]
    channel_names: list[str]
    seconds: float
    notes: list[str]


def lazy_source(path: Path | str, *, time_index: int = 0,
                channels: Sequence[int | str] | None = None) -> LazySource:
    """``path`` as a :class:`LazySource` (see the module docstring for how each format is
    wrapped). Raises VolumeReadError for a file vtkvol cannot read."""
    da = require("dask.array", "a volume as a lazy array", path)
    from vtkvol.io.registry import get_reader
    from vtkvol.io.remote import is_remote, remote_reader

    if is_remote(path):  # an OME-Zarr store on a server: its chunks are fetched as needed
        reader = remote_reader(str(path))
    else:
        path = Path(path)
        if not path.exists():
            raise VolumeReadError(path, f"no such file or folder: {path}")
        check_path(path)
        reader = get_reader(path)
    if reader is None:
        raise VolumeReadError(path, "not a volume vtkvol reads (unknown file type)")
    if reader.name == "tiff" and Path(path).is_file():
        return _lazy_tiff(path, time_index, channels, da)
    if reader.open_pyramid is not None:
        pyramid = reader.open_pyramid(path, time_index=time_index, channels=channels)
        level = pyramid.levels[0]
        stored = getattr(pyramid, "has_stored_chunks", None)
        if stored is not None and not stored(0):
            # Every voxel would be the fill value: gigabytes of it, computed and written for
            # nothing (a 6 GB declaration of an empty store).
            pyramid.close()
            raise VolumeReadError(path, f"its finest level ({level.name}) stores no chunks: "
                                        "every voxel is the fill value, there is nothing to "
                                        "convert")
        array = pyramid.to_dask(0, (1, max(1, pyramid.chunk_z(0)), CHUNK_XY, CHUNK_XY))
        return LazySource(array, tuple(level.voxel_size_um), list(pyramid.channel_names),
                          list(pyramid.notes))
    data = reader(path, time_index=time_index, channels=channels)
    array = da.from_array(data.array, chunks=(1, 16, CHUNK_XY, CHUNK_XY))
    return LazySource(array, tuple(data.voxel_size_um), list(data.channel_names),
                      list(data.notes))


def _lazy_tiff(path: Path, time_index: int, channels: Sequence[int | str] | None,
               da: Any) -> LazySource:
    import tifffile
    import zarr

    from vtkvol.io import tiff
    from vtkvol.io.volume_data import resolve_channels

    try:
        tif = tifffile.TiffFile(str(path))
    except Exception as exc:  # tifffile raises many types for a file that is not a TIFF
        raise VolumeReadError(path, f"not a readable TIFF ({type(exc).__name__}: {exc})") from exc
    try:
        series = tif.series[0] if tif.series else None
        if series is None or not tif.pages:
            raise VolumeReadError(path, "the TIFF file contains no images")
        axes = series.get_axes(False)
        shape = tuple(int(n) for n in series.get_shape(False))
        if 0 in shape:
            raise VolumeReadError(path, f"the image has a zero-size axis: axes {axes!r}, "
                                        f"shape {shape}")
        plan = tiff._plan_axes(axes, shape, path, imagej=bool(tif.is_imagej))
        tiff._check_time_index(plan, time_index, path)
        names = tiff._channel_names(tif, series, plan, 0)
        chosen = resolve_channels(channels, names, str(path))
        store = series.aszarr()
        lazy = da.from_zarr(zarr.open(store, mode="r")).reshape(shape)
        view = tiff._arrange(lazy, plan.roles, time_index)[list(chosen)]
        info = tiff._voxel_info(tif, series.keyframe, 0)
        spacing, _, _, voxel_notes = tiff._finish_voxel_size(info, int(view.shape[1]))
    except VolumeReadError:
        tif.close()
        raise
    except Exception as exc:
        tif.close()
        raise VolumeReadError(path, f"corrupt or truncated TIFF ({type(exc).__name__}: "
                                    f"{exc})") from exc
    # The TiffFile stays open while dask reads through its Zarr view; closed by the caller's
    # garbage collection after the conversion (the process ends soon after for the CLI).
    view = view.rechunk((1, _z_chunk(view.shape, view.dtype.itemsize), CHUNK_XY, CHUNK_XY))
    return LazySource(view, tuple(spacing), [names[c] for c in chosen],
                      list(plan.notes) + voxel_notes)


def _z_chunk(shape_czyx: Sequence[int], itemsize: int) -> int:
    """z chunk size: about 4 MiB per chunk of CHUNK_XY² voxels, at least 1."""
    _, z, y, x = shape_czyx
    plane = min(y, CHUNK_XY) * min(x, CHUNK_XY) * itemsize
    return max(1, min(z, (4 << 20) // max(1, plane)))


def plan_levels(shape_czyx: Sequence[int], voxel_size_um: Sequence[float],
                ) -> list[dict[str, int]]:
    """Cumulative downsampling factors per level after the first (ome-zarr's
    ``scale_factors``): x and y halve each level; z halves only while its voxel is not
    coarser than x's, so an anisotropic stack becomes isotropic before z is reduced. Levels
    are added until the largest axis is at most :data:`COARSEST_SIDE` voxels."""
    _, z, y, x = (int(n) for n in shape_czyx)
    sx, _, sz = (float(v) for v in voxel_size_um)
    factors: list[dict[str, int]] = []
    fz = fxy = 1
    while max(math.ceil(x / fxy), math.ceil(y / fxy), math.ceil(z / fz)) > COARSEST_SIDE:
        if sz * fz <= sx * fxy and math.ceil(z / fz) > 1:
            fz *= 2
        fxy *= 2
        factors.append({"z": fz, "y": fxy, "x": fxy})
        if len(factors) >= 12:
            break
    return factors


class _DaskProgress:
    """Reports finished dask tasks as a fraction through ``progress(fraction, message)``."""

    def __init__(self, progress: Callable[[float, str], None], message: str) -> None:
        from dask.callbacks import Callback

        outer = self

        class _Callback(Callback):
            def _start_state(self, dsk: Any, state: Any) -> None:
                outer.total += sum(len(state[k]) for k in ("ready", "waiting", "running"))

            def _posttask(self, key: Any, result: Any, dsk: Any, state: Any, worker_id: Any,
                          ) -> None:
                outer.done += 1
                now = time.monotonic()
                if now - outer.last >= 0.5:
                    outer.last = now
                    progress(min(1.0, outer.done / max(outer.total, 1)), message)

        self.total = self.done = 0
        self.last = 0.0
        self.callback = _Callback()


def convert_to_ome_zarr(
    source: str | os.PathLike[str],
    output: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    voxel_size_um: Sequence[float] | None = None,
    version: str = "0.5",
    progress: Callable[[float, str], None] | None = None,
) -> ConvertResult:
    """Write ``source`` as an OME-Zarr pyramid at ``output`` (a ``.zarr`` folder).

    ``voxel_size_um`` (x, y, z) replaces the file's; ``version`` is the NGFF version, "0.5"
    (Zarr v3) or "0.4" (Zarr v2). The pyramid is written into a hidden folder beside
    ``output`` and renamed into place when complete; a failure (including a full disk)
    removes it and leaves any existing ``output`` as it was. Raises ConvertError (an existing
    output without ``overwrite``, a bad option, a write failure) or VolumeReadError (an
    unreadable source).
    """
    start = time.perf_counter()
    from vtkvol.io.remote import is_remote

    out = Path(output).expanduser()
    # An address stays a string (Path() would fold its "//"); it is never a local path.
    src = source if is_remote(source) else Path(source).expanduser()
    local = isinstance(src, Path)
    report = progress or (lambda fraction, message: None)
    if version not in ("0.4", "0.5"):
        raise ConvertError(f"NGFF version {version!r} is not written; use 0.4 or 0.5")
    if out.exists() and not overwrite:
        raise ConvertError(f"{out} exists; pass --overwrite to replace it")
    if out.exists() and not out.is_dir():
        raise ConvertError(f"{out} is a file, not an OME-Zarr folder; it is not replaced")
    if local and src.exists() and out.resolve() == src.resolve():
        raise ConvertError(f"{out} is the input; choose another name for the output")
    if local and src.exists() and src.resolve() in out.resolve().parents:
        # the input would be read while the output grows inside it (and hold it afterwards)
        raise ConvertError(f"{out} is inside the input {src}; choose a place outside it")
    if local and src.exists() and out.resolve() in src.resolve().parents:
        # --overwrite would delete the folder the input is in
        raise ConvertError(f"{out} holds the input {src}; choose another name for the output")
    try:
        import dask
        import ome_zarr.format as ome_format
        import ome_zarr.writer as writer
        import zarr
    except ImportError as exc:
        raise ConvertError(f"vtkvol convert needs the optional package {exc.name!r}: pip "
                           "install 'vtkvol[convert]'") from None

    lazy = lazy_source(src, time_index=time_index, channels=channels)
    spacing = tuple(float(v) for v in (voxel_size_um or lazy.voxel_size_um))
    if len(spacing) != 3 or not all(math.isfinite(v) and v > 0 for v in spacing):
        raise ConvertError(f"voxel size {spacing} must be three positive µm values (x, y, z)")
    array = lazy.array
    shape = tuple(int(n) for n in array.shape)
    factors = plan_levels(shape, spacing)
    fmt = ome_format.FormatV05() if version == "0.5" else ome_format.FormatV04()
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(f".{out.name}.partial-{uuid.uuid4().hex[:8]}")
    chunks = (1, _z_chunk(shape, array.dtype.itemsize), CHUNK_XY, CHUNK_XY)
    report(0.0, f"writing {len(factors) + 1} levels of {shape[3]}×{shape[2]}×{shape[1]} "
                f"(x×y×z, {shape[0]} channel{'s' if shape[0] != 1 else ''})")
    # Two threads: each task holds a few chunks; more threads only add memory on a 2-core
    # machine, and dask's default uses every core. Our own pool, so that an interrupted write
    # (Ctrl-C, SIGTERM through the CLI) can wait for the chunks being written before the
    # folder is removed: dask's shared pool would go on writing into a removed folder.
    pool = ThreadPoolExecutor(2, thread_name_prefix="vtkvol-convert")
    try:
        group = zarr.open_group(str(partial), mode="w-", zarr_format=fmt.zarr_format)
        watcher = _DaskProgress(report, "writing the pyramid")
        with watcher.callback, dask.config.set(scheduler="threads", pool=pool):
            writer.write_image(
                array, group, axes="czyx", fmt=fmt, scale_factors=factors,
                scale={"c": 1.0, "z": spacing[2], "y": spacing[1], "x": spacing[0]},
                axes_units={"z": "micrometer", "y": "micrometer", "x": "micrometer"},
                storage_options={"chunks": chunks},
                name=Path(str(src).rstrip("/")).name,
                omero={"channels": _omero_channels(lazy.channel_names, array.dtype)},
            )
        pool.shutdown(wait=True)
        _replace_folder(partial, out)
    except BaseException as exc:
        pool.shutdown(wait=True, cancel_futures=True)
        _remove_unfinished(partial)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise ConvertError(f"{out}: the disk is full ({exc.strerror}); nothing was written "
                               "and an existing output is unchanged") from exc
        if isinstance(exc, OSError):
            raise ConvertError(f"{out}: could not write the pyramid ({exc.strerror or exc}); "
                               "an existing output is unchanged") from exc
        raise
    report(1.0, "done")
    from vtkvol.io.ome_zarr import open_ome_zarr

    # The shapes as written (the writer rounds odd sizes down).
    levels = [lv.shape_czyx for lv in open_ome_zarr(out).levels]
    return ConvertResult(out, levels, spacing, list(lazy.channel_names),  # type: ignore[arg-type]
                         time.perf_counter() - start, lazy.notes)


#: Colours of the channels in the ``omero`` metadata (hex RRGGBB), in order.
_CHANNEL_COLORS = ("00FF00", "FF00FF", "00FFFF", "FFFF00", "FF0000", "0000FF", "FFFFFF")


def _omero_channels(names: Sequence[str], dtype: np.dtype) -> list[dict[str, Any]]:
    """``omero.channels``: label, colour and a display window over the dtype's range (the
    writer requires both; vtkvol computes its own contrast when it opens the image)."""
    if np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        lo, hi = float(info.min), float(info.max)
    else:
        lo, hi = 0.0, 1.0
    window = {"start": lo, "end": hi, "min": lo, "max": hi}
    return [{"label": name, "color": _CHANNEL_COLORS[i % len(_CHANNEL_COLORS)],
             "active": True, "window": dict(window)} for i, name in enumerate(names)]


def _remove_unfinished(partial: Path, *, settle_s: float = 0.5, limit_s: float = 10.0) -> None:
    """Remove the unfinished output folder for good.

    An interruption (SIGTERM, Ctrl-C) raised in the main thread while it waits for one of
    zarr's writes does not stop that write: zarr runs it on its own I/O thread, which may
    create files after a first removal. So remove until the folder has stayed away for
    ``settle_s`` seconds (at most ``limit_s`` in all)."""
    deadline = time.monotonic() + limit_s
    gone_since: float | None = None
    while time.monotonic() < deadline:
        if partial.exists():
            shutil.rmtree(partial, ignore_errors=True)
            gone_since = None
        elif gone_since is None:
            gone_since = time.monotonic()
        elif time.monotonic() - gone_since >= settle_s:
            return
        time.sleep(0.05)


def _replace_folder(partial: Path, out: Path) -> None:
    """Move the finished ``partial`` folder to ``out``; an existing ``out`` is moved aside
    first and deleted only once the new one is in place."""
    if not out.exists():
        os.replace(partial, out)
        return
    old = out.with_name(f".{out.name}.old-{uuid.uuid4().hex[:8]}")
    os.replace(out, old)
    try:
        os.replace(partial, out)
    except OSError:
        os.replace(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)
