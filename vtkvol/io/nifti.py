"""NIfTI-1/-2 volumes (``.nii``, ``.nii.gz``): MRI templates, light-sheet exports, atlases.

Read with nibabel (optional extra ``formats``). NIfTI stores voxels x fastest, indexed
``[x, y, z, t, c]``; they are returned as ``[c, z, y, x]`` for the chosen time point. The voxel
size comes from the header's ``pixdim`` in its declared unit (metre, mm or µm); NIfTI's
"unknown" unit is read as mm, the format's customary unit, with a note. The orientation matrix
(``qform``/``sform``) is not applied: voxels are shown in file order, with a note when the
matrix is not diagonal.
"""

from __future__ import annotations

import contextlib
import gzip
import logging
import math
import os
import struct
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.optional import require
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = ["NIFTI_READER", "read_nifti"]

#: nibabel's names for NIfTI's spatial units → µm.
_UNITS = {"meter": 1e6, "mm": 1e3, "micron": 1.0}
#: Bytes a gzip stream may hold beyond the header and voxels (padding some writers add).
_GZIP_SLACK = 1 << 20


@dataclass(frozen=True)
class _RawHeader:
    """The fields of a NIfTI-1 or -2 header as stored, before nibabel "fixes" them (it makes a
    negative pixdim positive and guesses the byte order from dim[0], with log lines)."""

    version: int
    dim0: int
    pixdim: tuple[float, float, float]
    scl_slope: float
    scl_inter: float


def _raw_header(path: Path) -> _RawHeader | None:
    """The stored header of ``path`` (gzip-decompressed for ``.gz``), or None when it is not
    one vtkvol can parse itself (nibabel then reports the problem)."""
    try:
        with (gzip.open(path, "rb") if _is_gzip(path) else path.open("rb")) as fh:
            head = fh.read(540)
    except (OSError, EOFError, zlib.error):
        return None
    for order in "<>":
        if len(head) >= 348 and struct.unpack_from(order + "i", head)[0] == 348:
            dim0 = struct.unpack_from(order + "h", head, 40)[0]
            pixdim = struct.unpack_from(order + "3f", head, 80)
            slope, inter = struct.unpack_from(order + "2f", head, 112)
            return _RawHeader(1, dim0, pixdim, slope, inter)
        if len(head) >= 540 and struct.unpack_from(order + "i", head)[0] == 540:
            dim0 = struct.unpack_from(order + "q", head, 16)[0]
            pixdim = struct.unpack_from(order + "3d", head, 112)
            slope, inter = struct.unpack_from(order + "2d", head, 176)
            return _RawHeader(2, dim0, pixdim, slope, inter)
    return None


def _is_gzip(path: Path) -> bool:
    with path.open("rb") as fh:
        return fh.read(2) == b"\x1f\x8b"


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


@contextlib.contextmanager
def _nibabel_log(notes: list[str]) -> Iterator[None]:
    """nibabel reports the header fields it "fixes" by logging to stderr through its own
    handler; while reading, its records become notes instead (nothing reaches stderr)."""
    logger = logging.getLogger("nibabel")
    loggers = [logger, logging.getLogger("nibabel.global")]
    saved = [(lg, list(lg.handlers), lg.propagate) for lg in loggers]

    class _Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            text = " ".join(record.getMessage().split())
            if text and f"NIfTI header: {text}" not in notes:
                notes.append(f"NIfTI header: {text}")

    collector = _Collect(level=logging.WARNING)
    for lg in loggers:
        for handler in list(lg.handlers):
            lg.removeHandler(handler)
        lg.propagate = lg is not logger  # nibabel.global → nibabel → collector, no further
    logger.addHandler(collector)
    try:
        yield
    finally:
        logger.removeHandler(collector)
        for lg, handlers, propagate in saved:
            for handler in handlers:
                lg.addHandler(handler)
            lg.propagate = propagate


def _check_stored_bytes(path: Path, offset: int, nbytes: int) -> None:
    """The file holds the ``offset + nbytes`` bytes its header declares, checked before
    nibabel allocates the volume (a 71-byte gzip declaring 3 GB took 3 GB of memory for 30 s
    before failing). A gzip stream's last 4 bytes give its size modulo 4 GiB; when they do not
    fit (or the stream has several members), the stream is decompressed and counted, in
    pieces, without keeping it."""
    expected = offset + nbytes
    if not _is_gzip(path):
        actual = path.stat().st_size
        if actual < expected:
            raise VolumeReadError(path, f"the header declares {expected} bytes ({offset} header "
                                        f"+ {nbytes} voxel data), but the file has {actual}")
        return
    with path.open("rb") as fh:
        fh.seek(-4, os.SEEK_END)
        isize = int.from_bytes(fh.read(4), "little")
    if (isize - expected) % (1 << 32) <= _GZIP_SLACK:
        return
    got = 0
    try:
        with gzip.open(path, "rb") as stream:
            while got < expected:
                piece = stream.read(min(8 << 20, expected - got))
                if not piece:
                    break
                got += len(piece)
    except (OSError, EOFError, zlib.error) as exc:
        raise VolumeReadError(path, f"corrupt gzip data ({_one_line(exc)})") from exc
    if got < expected:
        raise VolumeReadError(path, f"the header declares {expected} bytes ({offset} header + "
                                    f"{nbytes} voxel data), but the gzip data hold only {got}")


def read_nifti(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of a NIfTI file as ``[c, z, y, x]`` (see the module docstring)."""
    progress = progress or Progress()
    path = Path(path)
    nib = require("nibabel", "NIfTI files", path)
    notes: list[str] = []
    raw = _raw_header(path)
    if raw is not None and not 1 <= raw.dim0 <= 7:
        # nibabel takes such a header for the other byte order and reports nonsense fields
        raise VolumeReadError(path, f"dim[0] = {raw.dim0} is not a number of dimensions (1 to "
                                    "7): the header is damaged")
    if raw is not None and math.isinf(raw.scl_slope):
        raise VolumeReadError(path, f"scl_slope = {raw.scl_slope} is not a finite scale factor")
    if raw is not None and raw.scl_slope != 0 and math.isfinite(raw.scl_slope) and \
            math.isinf(raw.scl_inter):
        raise VolumeReadError(path, f"scl_inter = {raw.scl_inter} is not a finite offset")
    with _nibabel_log(notes):
        try:
            image = nib.load(str(path))
        except Exception as exc:  # nibabel raises many types for bad headers
            raise VolumeReadError(path, f"not a readable NIfTI file ({_one_line(exc)})") from exc
    if not isinstance(image, nib.Nifti1Image | nib.Nifti2Image):
        raise VolumeReadError(path, f"not a NIfTI image (nibabel read a {type(image).__name__})")
    try:
        shape = tuple(int(n) for n in image.shape)
        dtype = np.dtype(image.get_data_dtype())
        # the proxy's offset is the file's vox_offset (the image's header copy says 0)
        offset = int(getattr(image.dataobj, "offset", 0))
    except Exception as exc:  # a header nibabel loaded lazily but cannot describe
        raise VolumeReadError(path, f"not a readable NIfTI file ({_one_line(exc)})") from exc
    if dtype.kind == "c":
        raise VolumeReadError(path, "complex-valued voxels cannot be displayed")
    if dtype.kind not in "biuf":
        raise VolumeReadError(path, f"{dtype} voxels (NIfTI datatype "
                                    f"{int(image.header['datatype'])}) cannot be displayed")
    if len(shape) < 3 or min(shape[:3]) < 1:
        raise VolumeReadError(path, f"expected at least 3 dimensions (x, y, z), got {shape}")
    if len(shape) > 5:
        raise VolumeReadError(path, f"{len(shape)}-D data {shape}: at most x, y, z, t, channel")
    n_time = shape[3] if len(shape) > 3 else 1
    n_channels = shape[4] if len(shape) > 4 else 1
    if not 0 <= time_index < n_time:
        raise VolumeReadError(
            path, f"time_index {time_index} is out of range: the file has {n_time} time point(s)"
        )
    names = default_channel_names(n_channels)
    chosen = resolve_channels(channels, names, str(path))
    # what is read (one time point, the chosen channels) must fit in memory; what the file
    # declares in all must be in it
    check_declared_bytes(path, math.prod(shape[:3]) * len(chosen) * dtype.itemsize,
                         f"{' × '.join(map(str, shape[:3]))} × {len(chosen)} channel(s) "
                         f"{dtype.name}")
    _check_stored_bytes(path, offset, math.prod(shape) * dtype.itemsize)
    progress(0.0, "reading NIfTI")
    with _nibabel_log(notes):
        array = _read_voxels(image, path, shape, time_index, chosen, progress)
    zooms = [float(z) for z in image.header.get_zooms()[:3]]
    if raw is not None and any(v < 0 for v in raw.pixdim):
        shown = ", ".join(f"{v:g}" for v in raw.pixdim)
        notes[:] = [n for n in notes if "pixdim[1,2,3]" not in n]  # nibabel's less clear line
        notes.append(f"NIfTI pixdim ({shown}) has negative sizes: their magnitudes are used "
                     "(the orientation matrix, not pixdim, flips axes)")
    unit = image.header.get_xyzt_units()[0]
    scale = _UNITS.get(unit)
    if scale is None:
        scale = unit_scale_um("mm")
        notes.append("NIfTI header gives no length unit: voxel size read as mm")
    spacing, from_metadata = spacing_or_default(
        [z * scale for z in zooms],  # type: ignore[operator]
        f"NIfTI voxel size {tuple(zooms)} is not positive: using 1 × 1 × 1 µm", notes,
    )
    affine = image.affine
    if affine is not None and np.count_nonzero(affine[:3, :3] - np.diag(np.diag(affine[:3, :3]))):
        notes.append("the file's orientation matrix is rotated or sheared: shown in voxel order")
    return VolumeData(
        array,
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": "nifti",
            "time_points": n_time,
            "time_index": time_index,
            "voxel_size_source": "NIfTI pixdim" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


def _read_voxels(image, path: Path, shape: tuple[int, ...], time_index: int,
                 chosen: Sequence[int], progress: Progress) -> np.ndarray:
    """The chosen channels of one time point as ``[c, z, y, x]`` (NIfTI stores x fastest)."""
    try:
        proxy = image.dataobj
        index = (slice(None),) * 3 + ((time_index,) if len(shape) > 3 else ())
        volumes = []
        for c in chosen:
            block = np.asanyarray(proxy[(*index, c) if len(shape) > 4 else index])
            volumes.append(np.ascontiguousarray(block.transpose(2, 1, 0)))  # → [z, y, x]
            progress(len(volumes) / len(chosen), "reading NIfTI")
    except (OSError, ValueError, EOFError, zlib.error) as exc:
        raise VolumeReadError(path, f"the voxel data are truncated or unreadable "
                                    f"({_one_line(exc)})") from exc
    return np.stack(volumes)


NIFTI_READER = ReaderSpec(
    name="nifti",
    label="NIfTI (.nii, .nii.gz)",
    filename_patterns=("*.nii", "*.nii.gz"),
    accepts_directories=False,
    read=read_nifti,
)
