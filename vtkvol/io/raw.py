"""Raw voxel files described by their name, an NRRD header, or a ``.dat`` descriptor.

- ``name_XxYxZ_dtype.raw`` (the naming of the open SciVis data sets, e.g.
  ``bonsai_256x256x256_uint8.raw``): little-endian, one channel, optional voxel-size suffix
  ``_0.2x0.2x0.5um``. A ``.raw`` without such a name is read through a descriptor next to it
  with the same stem (``name.dat``, ``name.nhdr``).
- NRRD (``.nhdr`` detached header or ``.nrrd`` with attached data): a practical subset,
  see docs/file-formats.md.
- ``.dat``: vtkvol's ``key = value`` descriptor, the classic ``ObjectFileName: …`` text
  descriptor of the bonsai/CT-head test sets, or the binary ``.dat`` (three uint16 sizes,
  then uint16 voxels) of the Vienna data sets.

Uncompressed data are memory-mapped (``np.memmap``, read-only); sizes are checked against the
descriptor first, so a wrong descriptor gives a clear error instead of garbage.
"""

from __future__ import annotations

import bz2
import gzip
import math
import os
import re
import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_data_file, check_declared_bytes
from vtkvol.io.progress import Progress, slabs
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.units import unit_scale_um
from vtkvol.io.volume_data import Spacing, VolumeData, default_channel_names, resolve_channels

__all__ = [
    "DAT_READER",
    "NRRD_READER",
    "RAW_READER",
    "RawLayout",
    "load_raw",
    "parse_dat",
    "parse_nrrd_header",
    "parse_raw_name",
    "read_dat",
    "read_nrrd",
    "read_raw",
]

_DTYPE_NAMES: dict[str, str] = {
    # vtkvol / numpy spellings
    "uint8": "u1", "int8": "i1", "uint16": "u2", "int16": "i2", "uint32": "u4",
    "int32": "i4", "uint64": "u8", "int64": "i8", "float32": "f4", "float64": "f8",
    "float": "f4", "double": "f8", "bool": "b1",
    # classic .dat "Format:" values
    "uchar": "u1", "char": "i1", "ushort": "u2", "short": "i2", "uint": "u4", "int": "i4",
    "ubyte": "u1", "byte": "u1",
    # NRRD type names (after lower-casing and removing "_t")
    "signed char": "i1", "unsigned char": "u1", "short int": "i2", "signed short": "i2",
    "signed short int": "i2", "unsigned short": "u2", "unsigned short int": "u2",
    "signed int": "i4", "unsigned int": "u4", "longlong": "i8", "long long": "i8",
    "long long int": "i8", "signed long long": "i8", "signed long long int": "i8",
    "ulonglong": "u8", "unsigned long long": "u8", "unsigned long long int": "u8",
}  # fmt: skip


def _parse_dtype(name: str, source: Path, what: str = "type") -> np.dtype:
    key = name.strip().lower()
    key = re.sub(r"_t$", "", key)
    if key in _DTYPE_NAMES:
        return np.dtype(_DTYPE_NAMES[key])
    raise VolumeReadError(
        source,
        f"unsupported {what} {name!r}; use one of uint8, int8, uint16, int16, uint32, int32, "
        "float32, float64",
    )


@dataclass
class RawLayout:
    """Where and how the voxels of a raw volume are stored.

    Attributes
    ----------
    file
        The data file.
    size_xyz
        Voxels along x, y, z.
    dtype
        Voxel type including byte order.
    channels
        Number of channels.
    channel_axis
        Position of the channel axis in numpy order (``[…, z, y, x]`` with the channel axis
        inserted): 0 for planar (channel-major) storage, 3 for interleaved (x, y, z, c with c
        fastest, VTK's multi-component layout).
    header_bytes
        Bytes to skip before the voxels (after decompression for ``encoding="raw"``; before
        it for compressed encodings); -1 means "the voxels end at the end of the file".
    encoding
        ``raw``, ``gzip``, ``bzip2``, ``ascii`` or ``hex``.
    voxel_size_um
        (x, y, z) in µm, or None when the descriptor has none.
    channel_names
        Names, or None for ``ch0``, ``ch1``…
    """

    file: Path
    size_xyz: tuple[int, int, int]
    dtype: np.dtype
    channels: int = 1
    channel_axis: int = 0
    header_bytes: int = 0
    encoding: str = "raw"
    voxel_size_um: tuple[float, float, float] | None = None
    channel_names: list[str] | None = None
    notes: list[str] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def count(self) -> int:
        return self.channels * math.prod(self.size_xyz)

    @property
    def storage_shape(self) -> tuple[int, ...]:
        x, y, z = self.size_xyz
        shape = [z, y, x]
        if self.channels > 1 or self.channel_axis == 0:
            shape.insert(self.channel_axis, self.channels)
        return tuple(shape)


def _check_sizes(layout: RawLayout, source: Path) -> None:
    if any(n <= 0 for n in layout.size_xyz) or layout.channels <= 0:
        raise VolumeReadError(
            source,
            f"zero-size axis in the descriptor: size {layout.size_xyz} (x, y, z), "
            f"{layout.channels} channel(s)",
        )
    check_declared_bytes(source, layout.count * layout.dtype.itemsize,
                         _describe_expected(layout))


def _describe_expected(layout: RawLayout) -> str:
    x, y, z = layout.size_xyz
    text = f"{x}×{y}×{z}"
    if layout.channels > 1:
        text += f"×{layout.channels} channels"
    return f"{text} {layout.dtype.name}"


def load_raw(
    layout: RawLayout, source: Path, progress: Progress, channels: Sequence[int] | None = None
) -> np.ndarray:
    """The voxels of ``layout`` as ``[c, z, y, x]`` (memory-mapped where possible).

    Raises
    ------
    VolumeReadError
        When the data file is missing or its size does not match the descriptor (the
        message gives the expected and actual byte counts).
    """
    _check_sizes(layout, source)
    path = layout.file
    if not path.is_file():
        raise VolumeReadError(source, f"the data file {path.name!r} it names does not exist")
    expected = layout.count * layout.dtype.itemsize
    if layout.encoding == "raw":
        actual = path.stat().st_size
        if layout.header_bytes < 0:  # NRRD "byte skip: -1": the voxels are the file's last bytes
            offset, wanted = actual - expected, expected
            size_ok = offset >= 0
        else:
            offset = layout.header_bytes
            wanted = offset + expected
            size_ok = actual == wanted
        if not size_ok:
            header = f" + {layout.header_bytes} header bytes" if layout.header_bytes > 0 else ""
            raise VolumeReadError(
                source,
                f"wrong data size for the descriptor: expected {wanted} bytes "
                f"({_describe_expected(layout)}{header}), but {path.name} has {actual} bytes",
            )
        progress(1.0, f"memory-mapped {path.name}")
        array = np.memmap(
            path, dtype=layout.dtype, mode="r", offset=offset, shape=layout.storage_shape
        )
    else:
        array = _read_encoded(layout, source, expected, progress.sub(0.0, 0.8))
        array = array.reshape(layout.storage_shape)
    return _to_czyx(array, layout, channels, progress)


def _to_czyx(
    array: np.ndarray, layout: RawLayout, channels: Sequence[int] | None, progress: Progress
) -> np.ndarray:
    if array.ndim == 3:
        array = array[np.newaxis]
    elif layout.channel_axis != 0:
        array = np.moveaxis(array, layout.channel_axis, 0)
    chosen = list(range(array.shape[0])) if channels is None else list(channels)
    if chosen == list(range(array.shape[0])) and array.flags.c_contiguous:
        return array
    out = np.empty((len(chosen), *array.shape[1:]), dtype=array.dtype)
    n_z = array.shape[1]
    for sl in slabs(n_z, array[0, 0].nbytes * array.shape[0]):
        for j, c in enumerate(chosen):
            out[j, sl] = array[c, sl]
        progress(sl.stop / n_z, f"reading slice {sl.stop} of {n_z}")
    return out


def _check_gzip_size(path: Path, layout: RawLayout, source: Path, expected: int) -> None:
    """A single-member gzip stream ends with its uncompressed size modulo 2³² (ISIZE): a header
    that lies about the size is caught before the buffer is allocated."""
    size = path.stat().st_size - max(layout.header_bytes, 0)
    if size < 18:  # gzip header (10) + trailer (8)
        raise VolumeReadError(source, f"the gzip data in {path.name} are truncated ({size} bytes)")
    with path.open("rb") as fh:
        fh.seek(max(layout.header_bytes, 0))
        if fh.read(2) != b"\x1f\x8b":
            raise VolumeReadError(source, f"{path.name}: the data are not gzip-compressed")
        fh.seek(-4, os.SEEK_END)
        isize = int.from_bytes(fh.read(4), "little")
    if isize != expected % (1 << 32):
        raise VolumeReadError(
            source,
            f"wrong data size for the descriptor: expected {expected} bytes "
            f"({_describe_expected(layout)}), but the gzip stream in {path.name} holds "
            f"{isize} bytes (modulo 4 GiB)",
        )


def _read_encoded(layout: RawLayout, source: Path, expected: int, progress: Progress) -> np.ndarray:
    path = layout.file
    if layout.encoding == "gzip":
        _check_gzip_size(path, layout, source, expected)
    with path.open("rb") as fh:
        if layout.header_bytes > 0:
            fh.seek(layout.header_bytes)
        if layout.encoding in ("gzip", "bzip2"):
            stream: IO[bytes] = (
                gzip.GzipFile(fileobj=fh) if layout.encoding == "gzip" else bz2.BZ2File(fh)
            )
            buffer = bytearray(expected)
            view = memoryview(buffer)
            got = 0
            try:
                while got < expected:
                    n = stream.readinto(view[got : got + (8 << 20)])
                    if not n:
                        break
                    got += n
                    progress(got / expected, f"decompressing {path.name}")
                trailing = stream.read(1)
            except (OSError, EOFError, ValueError) as exc:
                raise VolumeReadError(
                    source, f"corrupt {layout.encoding} data in {path.name} ({exc})"
                ) from exc
            if got != expected or trailing:
                actual = f"{got}" if not trailing else f"more than {expected}"
                raise VolumeReadError(
                    source,
                    f"wrong data size for the descriptor: expected {expected} bytes "
                    f"({_describe_expected(layout)}) after {layout.encoding} decompression, "
                    f"got {actual}",
                )
            return np.frombuffer(buffer, dtype=layout.dtype)
        text = fh.read().decode("ascii", errors="replace")
    if layout.encoding == "hex":
        try:
            data = bytes.fromhex("".join(text.split()))
        except ValueError as exc:
            raise VolumeReadError(source, f"invalid hex data ({exc})") from exc
        if len(data) != expected:
            raise VolumeReadError(
                source,
                f"wrong data size for the descriptor: expected {expected} bytes "
                f"({_describe_expected(layout)}), the hex data hold {len(data)}",
            )
        return np.frombuffer(data, dtype=layout.dtype)
    try:
        values = np.array(text.replace(",", " ").split(), dtype=np.float64)
    except ValueError as exc:
        raise VolumeReadError(source, f"the text data hold a non-number ({exc})") from exc
    if values.size != layout.count:
        raise VolumeReadError(
            source,
            f"wrong data size for the descriptor: expected {layout.count} values "
            f"({_describe_expected(layout)}), the text holds {values.size}",
        )
    dtype = layout.dtype.newbyteorder("=")
    if dtype.kind in "iu" and values.size:
        # numpy would wrap 300 into an 8-bit 44 without a word
        info = np.iinfo(dtype)
        bad = (values < info.min) | (values > info.max) | (values != np.round(values))
        if bad.any():
            first = float(values[np.flatnonzero(bad)[0]])
            raise VolumeReadError(
                source, f"the text data hold {first:g}, which is not a {dtype.name} value "
                f"(whole numbers {info.min}…{info.max}); fix the header's type")
    progress(1.0, f"parsed {path.name}")
    return values.astype(dtype)


def _finish(
    layout: RawLayout,
    source: Path,
    fmt: str,
    channels: Sequence[int | str] | None,
    time_index: int,
    progress: Progress,
) -> VolumeData:
    if time_index != 0:
        raise VolumeReadError(
            source,
            f"time_index {time_index} is out of range: the file has 1 time point (index 0)",
        )
    _check_sizes(layout, source)
    names = layout.channel_names or default_channel_names(layout.channels)
    if len(names) != layout.channels:
        raise VolumeReadError(
            source, f"{len(names)} channel names for {layout.channels} channels: {names}"
        )
    chosen = resolve_channels(channels, names, str(source))
    array = load_raw(layout, source, progress, chosen)
    notes = list(layout.notes)
    if layout.voxel_size_um is None:
        spacing, from_md, voxel_source = Spacing(1.0, 1.0, 1.0), False, "not in file; default 1 µm"
        notes.append("voxel size not given: using 1 × 1 × 1 µm (pass voxel_size_um to set it)")
    else:
        spacing, from_md = Spacing(*layout.voxel_size_um), True
        voxel_source = layout.metadata.pop("voxel_size_source", f"{fmt} descriptor")
    metadata = {
        "format": fmt,
        "data_file": str(layout.file),
        "encoding": layout.encoding,
        "byte_order": "big" if layout.dtype.byteorder == ">" else "little",
        "voxel_size_source": voxel_source,
        "memory_mapped": isinstance(array, np.memmap),
        **layout.metadata,
    }
    return VolumeData(
        array,
        spacing,
        [names[c] for c in chosen],
        source=str(source),
        voxel_size_from_metadata=from_md,
        metadata=metadata,
        notes=notes,
    )


# -- name_XxYxZ_dtype.raw -----------------------------------------------------------------------
_RAW_NAME = re.compile(
    r"^(?P<name>.*?)_(?P<x>\d+)x(?P<y>\d+)x(?P<z>\d+)_(?P<dtype>u?int(?:8|16|32)|float(?:32|64))"
    r"(?:_(?P<sx>\d+(?:\.\d*)?)x(?P<sy>\d+(?:\.\d*)?)x(?P<sz>\d+(?:\.\d*)?)(?:um|µm)?)?"
    r"\.raw$",
    re.IGNORECASE,
)


def parse_raw_name(path: Path) -> RawLayout | None:
    """Layout from a ``name_XxYxZ_dtype[_sxXsyXsz[um]].raw`` file name, or None."""
    match = _RAW_NAME.match(path.name)
    if match is None:
        return None
    size = (int(match["x"]), int(match["y"]), int(match["z"]))
    dtype = np.dtype(_DTYPE_NAMES[match["dtype"].lower()]).newbyteorder("<")
    spacing = None
    metadata: dict[str, Any] = {"name": match["name"]}
    if match["sx"]:
        spacing = (float(match["sx"]), float(match["sy"]), float(match["sz"]))
        metadata["voxel_size_source"] = "file name"
    return RawLayout(path, size, dtype, voxel_size_um=spacing, metadata=metadata)


def read_raw(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read a ``.raw`` volume described by its name or by a descriptor beside it.

    Looks for, in order: the ``name_XxYxZ_dtype.raw`` pattern; ``<stem>.dat``,
    ``<stem>.nhdr`` or ``<stem>.mhd`` (MetaImage) in the same folder.
    """
    progress = progress or Progress()
    path = Path(path)
    layout = parse_raw_name(path)
    if layout is not None:
        return _finish(layout, path, "raw", channels, time_index, progress)
    from vtkvol.io.vti import read_vtk_image_file  # MetaImage .mhd headers name a .raw too

    for suffix, reader in ((".dat", read_dat), (".nhdr", read_nrrd), (".mhd", read_vtk_image_file)):
        sidecar = path.with_suffix(suffix)
        if sidecar.is_file():
            return reader(sidecar, time_index=time_index, channels=channels, progress=progress)
    raise VolumeReadError(
        path,
        "cannot tell the dimensions of this raw file: name it like "
        "'name_256x256x128_uint16.raw' or put a descriptor "
        f"'{path.with_suffix('.dat').name}' (or .nhdr, .mhd) beside it (see docs/file-formats.md)",
    )


# -- NRRD ------------------------------------------------------------------------------------
_NON_SPATIAL_KINDS = {
    "list", "point", "vector", "covariant-vector", "normal", "stub", "scalar", "complex",
    "2-vector", "3-color", "rgb-color", "hsv-color", "xyz-color", "4-color", "rgba-color",
    "3-vector", "3-gradient", "3-normal", "4-vector", "quaternion", "2d-symmetric-matrix",
    "2d-masked-symmetric-matrix", "2d-matrix", "2d-masked-matrix", "3d-symmetric-matrix",
    "3d-masked-symmetric-matrix", "3d-matrix", "3d-masked-matrix", "time",
}  # fmt: skip
_NRRD_ENCODINGS = {
    "raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2",
    "ascii": "ascii", "text": "ascii", "txt": "ascii", "hex": "hex",
}  # fmt: skip


#: Longest NRRD header line and header accepted (headers are a few hundred bytes).
_NRRD_MAX_LINE = 64 * 1024
_NRRD_MAX_HEADER = 1024 * 1024


def _header_text(raw: bytes) -> str:
    """A header line as text: UTF-8 (``µm`` written by most tools), else Latin-1."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def parse_nrrd_header(path: Path) -> tuple[dict[str, str], dict[str, str], int]:
    """Fields, key/value pairs and the byte offset just after the header of an NRRD file."""
    fields: dict[str, str] = {}
    pairs: dict[str, str] = {}
    with path.open("rb") as fh:
        magic = fh.readline()
        if not magic.startswith(b"NRRD"):
            raise VolumeReadError(path, "not an NRRD header (the first line must be NRRD000x)")
        while True:
            raw_line = fh.readline(_NRRD_MAX_LINE + 1)
            if not raw_line:
                break
            if len(raw_line) > _NRRD_MAX_LINE or fh.tell() > _NRRD_MAX_HEADER:
                # Binary data without the blank line would otherwise be read as one "line".
                raise VolumeReadError(
                    path, f"no end of the NRRD header within {_NRRD_MAX_HEADER // 1024} KiB (a "
                          "header ends at an empty line); the file is corrupt",
                )
            line = _header_text(raw_line).rstrip("\r\n")
            if not line.strip():
                break  # blank line: end of header, attached data follow
            if line.startswith("#"):
                continue
            if ":=" in line:
                key, _, value = line.partition(":=")
                pairs[key.strip()] = value.strip()
            elif ": " in line:
                key, _, value = line.partition(": ")
                fields[key.strip().lower()] = value.strip()
            else:
                raise VolumeReadError(path, f"cannot parse NRRD header line {line!r}")
        offset = fh.tell()
    return fields, pairs, offset


def _nrrd_vectors(text: str) -> list[tuple[float, ...] | None]:
    vectors: list[tuple[float, ...] | None] = []
    for token in re.findall(r"\([^)]*\)|none", text):
        if token == "none":
            vectors.append(None)
        else:
            vectors.append(tuple(float(v) for v in token.strip("()").split(",")))
    return vectors


def _nrrd_strings(text: str) -> list[str]:
    try:
        return shlex.split(text)
    except ValueError:
        return text.split()


def _nrrd_layout(
    path: Path, fields: dict[str, str], pairs: dict[str, str], offset: int
) -> RawLayout:
    def need(name: str) -> str:
        if name not in fields:
            raise VolumeReadError(path, f"the NRRD header has no {name!r} field")
        return fields[name]

    dtype = _parse_dtype(need("type"), path, "NRRD type")
    dimension = int(need("dimension"))
    sizes = [int(v) for v in need("sizes").split()]
    if len(sizes) != dimension:
        raise VolumeReadError(path, f"'sizes' has {len(sizes)} values for dimension {dimension}")
    if dimension not in (3, 4):
        raise VolumeReadError(
            path, f"dimension {dimension} is not supported; vtkvol reads 3-D and 4-D NRRD data"
        )
    if dtype.itemsize > 1:
        endian = fields.get("endian", "little").lower()
        if endian not in ("little", "big"):
            raise VolumeReadError(path, f"unknown endian {endian!r} (little or big)")
        dtype = dtype.newbyteorder("<" if endian == "little" else ">")
    encoding_name = fields.get("encoding", "raw").lower()
    if encoding_name not in _NRRD_ENCODINGS:
        raise VolumeReadError(
            path, f"encoding {encoding_name!r} is not supported (raw, gzip, bzip2, ascii, hex)"
        )
    encoding = _NRRD_ENCODINGS[encoding_name]

    # Which axis holds channels: a non-spatial kind, a "none" space direction, or NaN spacing.
    kinds = [k.lower() for k in _nrrd_strings(fields.get("kinds", ""))]
    directions = _nrrd_vectors(fields.get("space directions", ""))
    spacings_text = fields.get("spacings", "").split()
    non_spatial = set()
    if len(kinds) == dimension:
        non_spatial |= {i for i, k in enumerate(kinds) if k in _NON_SPATIAL_KINDS}
    if len(directions) == dimension:
        non_spatial |= {i for i, d in enumerate(directions) if d is None}
    if len(spacings_text) == dimension:
        non_spatial |= {i for i, s in enumerate(spacings_text) if s.lower() == "nan"}
    channel_axis_nrrd: int | None = None
    if dimension == 4:
        if len(non_spatial) != 1:
            raise VolumeReadError(
                path,
                f"cannot tell which of the 4 axes (sizes {sizes}) holds the channels: mark it "
                "with 'kinds' (e.g. 'list domain domain domain') or a 'none' space direction",
            )
        channel_axis_nrrd = next(iter(non_spatial))
    elif non_spatial:
        raise VolumeReadError(path, f"a 3-D NRRD needs 3 spatial axes; kinds {kinds}")
    spatial = [i for i in range(dimension) if i != channel_axis_nrrd]
    channels = sizes[channel_axis_nrrd] if channel_axis_nrrd is not None else 1
    size_xyz = (sizes[spatial[0]], sizes[spatial[1]], sizes[spatial[2]])
    # NRRD lists the fastest axis first; numpy order is the reverse.
    channel_axis = 0 if channel_axis_nrrd is None else dimension - 1 - channel_axis_nrrd

    notes: list[str] = []
    spacing: list[float] | None = None
    voxel_source = ""
    if len(directions) == dimension:
        vecs = [directions[i] for i in spatial]
        if all(v is not None for v in vecs):
            # math.hypot: neither overflows for huge components nor warns (numpy's norm printed
            # "RuntimeWarning: invalid value encountered in divide" for a zero vector).
            spacing = [math.hypot(*v) for v in vecs if v is not None]
            for axis, (vec, length) in enumerate(zip(vecs, spacing, strict=True)):
                if not (math.isfinite(length) and length > 0.0):
                    raise VolumeReadError(
                        path,
                        f"space direction {axis} of the NRRD header, {vec}, has length "
                        f"{length:g}: a voxel's edge must be a finite length > 0",
                    )
            matrix = np.array([np.asarray(v) / n for v, n in zip(vecs, spacing, strict=True)
                               if v is not None])
            if matrix.shape == (3, 3) and not np.allclose(np.abs(matrix), np.eye(3), atol=1e-6):
                notes.append("the NRRD space directions are rotated; only their lengths are used")
            voxel_source = "NRRD space directions"
    if spacing is None and len(spacings_text) == dimension:
        spacing = [float(spacings_text[i]) for i in spatial]
        voxel_source = "NRRD spacings"
    if spacing is not None:
        units = _nrrd_strings(fields.get("space units", "")) or _nrrd_strings(
            fields.get("units", "")
        )
        if len(units) == dimension and len(units) != 3:
            units = [units[i] for i in spatial]
        if len(units) == 3:
            scales = [unit_scale_um(u) for u in units]
            if any(s is None for s in scales):
                raise VolumeReadError(path, f"unknown space units {units}")
            spacing = [v * s for v, s in zip(spacing, scales, strict=True) if s is not None]
            voxel_source += f" in {units[0]}"
        else:
            notes.append("the NRRD header gives no space units: spacings taken as µm")
        if not all(math.isfinite(v) and v > 0 for v in spacing):
            raise VolumeReadError(path, f"invalid voxel spacing {spacing}")

    data_file = fields.get("data file") or fields.get("datafile")
    if data_file:
        if data_file.startswith("LIST") or len(data_file.split()) > 1:
            raise VolumeReadError(
                path,
                "multi-file NRRD data ('data file: LIST' or a format "
                "string) is not supported; concatenate into one file",
            )
        file = (path.parent / data_file).resolve()
        check_data_file(path, file)
        header_bytes = int(fields.get("byte skip", "0"))
        line_skip = int(fields.get("line skip", "0"))
    else:
        if path.suffix.lower() == ".nhdr":
            raise VolumeReadError(path, "the detached NRRD header has no 'data file' field")
        file = path
        header_bytes = offset + int(fields.get("byte skip", "0"))
        line_skip = int(fields.get("line skip", "0"))
    if line_skip:
        with file.open("rb") as fh:
            fh.seek(max(header_bytes, 0))
            for skipped in range(line_skip):
                if not fh.readline():
                    raise VolumeReadError(
                        path, f"'line skip: {line_skip}' runs past the end of the data file "
                              f"after {skipped} lines",
                    )
            header_bytes = fh.tell()
    axes = "".join(
        "C" if i == channel_axis_nrrd else "XYZ"[spatial.index(i)] for i in range(dimension)
    )
    # NRRD's own axis order (fastest first), e.g. "CXYZ" for interleaved channels.
    metadata: dict[str, Any] = {"nrrd_sizes": sizes, "axes": axes}
    if kinds:
        metadata["nrrd_kinds"] = kinds
    if pairs:
        metadata["nrrd_key_values"] = pairs
    if "space origin" in fields:
        metadata["nrrd_space_origin"] = fields["space origin"]
    if voxel_source:
        metadata["voxel_size_source"] = voxel_source
    return RawLayout(
        file=file,
        size_xyz=size_xyz,
        dtype=dtype,
        channels=channels,
        channel_axis=channel_axis,
        header_bytes=header_bytes,
        encoding=encoding,
        voxel_size_um=tuple(spacing) if spacing is not None else None,  # type: ignore[arg-type]
        notes=notes,
        metadata=metadata,
    )


def read_nrrd(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read an NRRD volume (``.nhdr`` + data file, or ``.nrrd`` with attached data)."""
    progress = progress or Progress()
    path = Path(path)
    fields, pairs, offset = parse_nrrd_header(path)
    try:
        layout = _nrrd_layout(path, fields, pairs, offset)
    except ValueError as exc:
        if isinstance(exc, VolumeReadError):
            raise
        raise VolumeReadError(path, f"invalid NRRD header ({exc})") from exc
    return _finish(layout, path, "nrrd", channels, time_index, progress)


# -- .dat descriptors ----------------------------------------------------------------------------
_DAT_KEYS: dict[str, str] = {
    "file": "file", "datafile": "file", "rawfile": "file", "objectfilename": "file",
    "size": "size", "resolution": "size", "dimensions": "size",
    "channels": "channels", "components": "channels",
    "dtype": "dtype", "format": "dtype", "type": "dtype",
    "endian": "endian", "byteorder": "endian",
    "voxelsizeum": "voxel_size_um", "voxelsize": "voxel_size_um", "spacing": "voxel_size_um",
    "slicethickness": "voxel_size_um",
    "headerbytes": "header_bytes", "byteskip": "header_bytes",
    "channellayout": "channel_layout",
    "channelnames": "channel_names",
    "encoding": "encoding",
    "objectmodel": "object_model",
    # classic descriptor fields that carry nothing vtkvol needs
    "taggedfilename": "", "objecttype": "", "gridtype": "", "nbrtags": "",
}  # fmt: skip
_KNOWN_DAT_KEYS = (
    "file, size, channels, dtype, endian, voxel_size_um, header_bytes, "
    "channel_layout, channel_names, encoding"
)


def parse_dat(path: Path) -> RawLayout:
    """Parse a ``.dat`` descriptor (text ``key = value`` / ``Key: value``, or binary).

    See docs/file-formats.md for the syntax.
    """
    head = path.read_bytes()[:4096]
    if b"\x00" in head:
        return _parse_binary_dat(path)
    text = path.read_text(encoding="utf-8", errors="replace")
    values: dict[str, str] = {}
    classic = False
    for number, raw_line in enumerate(text.splitlines(), start=1):
        line = raw_line.split("#", 1)[0].strip()
        if not line:
            continue
        eq, colon = line.find("="), line.find(":")
        if eq > 0 and (colon < 0 or eq < colon):
            key, value = line[:eq], line[eq + 1 :]
        elif colon > 0:
            key, value = line[:colon], line[colon + 1 :]
            classic = True
        else:
            raise VolumeReadError(path, f"line {number}: expected 'key = value', got {raw_line!r}")
        normal = re.sub(r"[\s_\-]", "", key.lower())
        if normal not in _DAT_KEYS:
            raise VolumeReadError(
                path, f"line {number}: unknown key {key.strip()!r} (known: {_KNOWN_DAT_KEYS})"
            )
        if _DAT_KEYS[normal]:
            values[_DAT_KEYS[normal]] = value.strip()
    for required in ("file", "size", "dtype"):
        if required not in values:
            raise VolumeReadError(path, f"the descriptor has no {required!r} entry")
    file_name = values["file"].strip().strip("'\"")
    file = (path.parent / file_name).resolve()
    check_data_file(path, file)
    try:
        size = tuple(int(v) for v in values["size"].replace(",", " ").split())
    except ValueError as exc:
        raise VolumeReadError(
            path, f"size must be three integers X Y Z, got {values['size']!r}"
        ) from exc
    if len(size) != 3:
        raise VolumeReadError(path, f"size must be three integers X Y Z, got {values['size']!r}")
    dtype = _parse_dtype(values["dtype"], path, "dtype")
    endian = values.get("endian", "little").lower()
    if endian not in ("little", "big"):
        raise VolumeReadError(path, f"endian must be 'little' or 'big', got {endian!r}")
    if dtype.itemsize > 1:
        dtype = dtype.newbyteorder("<" if endian == "little" else ">")
    channels = 1
    layout_name = values.get("channel_layout", "planar").lower()
    model = values.get("object_model", "").upper()
    if model in ("RGB", "RGBA"):
        channels, layout_name = len(model), "interleaved"
    if "channels" in values:
        channels = int(values["channels"])
    if layout_name not in ("planar", "interleaved"):
        raise VolumeReadError(
            path, f"channel_layout must be planar or interleaved, got {layout_name!r}"
        )
    notes: list[str] = []
    spacing = None
    metadata: dict[str, Any] = {}
    if "voxel_size_um" in values:
        numbers = [float(v) for v in values["voxel_size_um"].replace(",", " ").split()]
        if len(numbers) == 1:
            numbers *= 3
        if len(numbers) != 3 or not all(math.isfinite(v) and v > 0 for v in numbers):
            raise VolumeReadError(
                path,
                f"voxel_size_um must be 1 or 3 positive numbers, got {values['voxel_size_um']!r}",
            )
        spacing = (numbers[0], numbers[1], numbers[2])
        if classic:
            notes.append("the descriptor gives unit-less slice thickness; taken as µm")
    names = None
    if "channel_names" in values:
        names = [n.strip() for n in re.split(r"[,;]", values["channel_names"]) if n.strip()]
    encoding = values.get("encoding", "raw").lower()
    if encoding not in ("raw", "gzip", "bzip2"):
        raise VolumeReadError(path, f"encoding must be raw, gzip or bzip2, got {encoding!r}")
    metadata["descriptor_syntax"] = "classic" if classic else "key = value"
    return RawLayout(
        file=file,
        size_xyz=(size[0], size[1], size[2]),
        dtype=dtype,
        channels=channels,
        channel_axis=3 if layout_name == "interleaved" else 0,
        header_bytes=_header_bytes(values.get("header_bytes", "0"), path),
        encoding=encoding,
        voxel_size_um=spacing,
        channel_names=names,
        notes=notes,
        metadata=metadata,
    )


def _header_bytes(text: str, path: Path) -> int:
    try:
        value = int(text)
    except ValueError:
        raise VolumeReadError(path, f"header_bytes = {text!r} is not a whole number") from None
    if value < 0:
        raise VolumeReadError(path, f"header_bytes = {value} must not be negative")
    return value


def _parse_binary_dat(path: Path) -> RawLayout:
    """Binary ``.dat``: three little-endian uint16 sizes (x, y, z), then uint16 voxels."""
    actual = path.stat().st_size
    with path.open("rb") as fh:
        header = fh.read(6)
    if len(header) == 6:
        x, y, z = (int(v) for v in np.frombuffer(header, dtype="<u2"))
        if 6 + 2 * x * y * z == actual:
            return RawLayout(
                path,
                (x, y, z),
                np.dtype("<u2"),
                header_bytes=6,
                metadata={"descriptor_syntax": "binary (uint16 sizes + uint16 voxels)"},
            )
        expected = 6 + 2 * x * y * z
        raise VolumeReadError(
            path,
            f"binary .dat header says {x}×{y}×{z} uint16 voxels, so {expected} bytes are "
            f"expected, but the file has {actual} bytes",
        )
    raise VolumeReadError(path, "neither a text descriptor nor a binary .dat volume")


def read_dat(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read a volume through a ``.dat`` descriptor (or a binary ``.dat`` volume)."""
    progress = progress or Progress()
    path = Path(path)
    try:
        layout = parse_dat(path)
    except ValueError as exc:
        if isinstance(exc, VolumeReadError):
            raise
        raise VolumeReadError(path, f"invalid descriptor ({exc})") from exc
    return _finish(layout, path, "dat", channels, time_index, progress)


RAW_READER = ReaderSpec(
    name="raw",
    label="Raw volume (name_XxYxZ_dtype.raw, or with a .dat/.nhdr beside it)",
    filename_patterns=("*.raw",),
    accepts_directories=False,
    read=read_raw,
)
NRRD_READER = ReaderSpec(
    name="nrrd",
    label="NRRD (.nhdr + data, .nrrd)",
    filename_patterns=("*.nhdr", "*.nrrd"),
    accepts_directories=False,
    read=read_nrrd,
)
DAT_READER = ReaderSpec(
    name="dat",
    label="Raw volume with a .dat descriptor",
    filename_patterns=("*.dat",),
    accepts_directories=False,
    read=read_dat,
)
