"""Checks of MetaImage (``.mha``/``.mhd``) and legacy VTK (``.vtk``) headers before VTK reads
them: VTK trusts their numbers and aborts the process (``std::bad_alloc``, a length error) on a
negative size, a negative channel count or an absurd compressed size, and spends minutes on a
declared field of 10⁸ arrays. The values are checked here against the grid and the file."""

from __future__ import annotations

import re
from pathlib import Path

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_data_file

__all__ = ["check_legacy_vtk_header", "check_metaimage_header"]

_HEADER_BYTES = 1 << 20
_MET_TYPES = {"MET_CHAR", "MET_UCHAR", "MET_SHORT", "MET_USHORT", "MET_INT", "MET_UINT",
              "MET_LONG", "MET_ULONG", "MET_LONG_LONG", "MET_ULONG_LONG", "MET_FLOAT",
              "MET_DOUBLE"}
#: Components per voxel a header may declare (VTK's readers give vtkvol channels from them).
MAX_COMPONENTS = 64


def check_metaimage_header(path: Path) -> None:
    """Refuse a MetaImage header whose sizes, channels, element type, compressed size or data
    files VTK cannot be trusted with. Data files (one, ``LOCAL`` or a ``LIST``) must be regular
    files beside the header (:func:`vtkvol.io.limits.check_data_file`)."""
    with path.open("rb") as fh:
        head = fh.read(_HEADER_BYTES)
    fields: dict[str, str] = {}
    lines = head.split(b"\n")
    data_line = None
    for number, raw in enumerate(lines):
        key, sep, value = raw.decode("latin-1").partition("=")
        if not sep:
            continue
        key = key.strip().lower()
        fields[key] = value.strip()
        if key == "elementdatafile":
            data_line = number
            break
    dims = _ints(path, fields, "ndims", 1, 1, 16)
    sizes = _ints(path, fields, "dimsize", dims[0] if dims else None, 1, None)
    _ints(path, fields, "elementnumberofchannels", 1, 1, MAX_COMPONENTS)
    kind = fields.get("elementtype", "").upper()
    if "elementtype" in fields and kind not in _MET_TYPES:
        raise VolumeReadError(path, f"ElementType = {fields['elementtype']} is not a type "
                                    "MetaImage defines (MET_UCHAR, MET_USHORT, MET_FLOAT, …)")
    header = _ints(path, fields, "headersize", 1, -1, None)
    name = fields.get("elementdatafile")
    if name is None or sizes is None:
        return  # VTK refuses these itself
    folder = path.parent
    if name.upper() == "LOCAL":
        data_size = path.stat().st_size - len(b"\n".join(lines[: (data_line or 0) + 1])) - 1
        files = []
    elif name.upper().startswith("LIST"):
        files = [line.decode("latin-1").strip() for line in lines[(data_line or 0) + 1:]]
        files = [f for f in files if f]
        if not files:
            raise VolumeReadError(path, "ElementDataFile = LIST names no files")
        data_size = None
    elif len(name.split()) > 1:
        raise VolumeReadError(path, f"ElementDataFile = {name}: numbered file-name patterns are "
                                    "not supported; use LIST or one data file")
    else:
        files = [name]
        data_size = None
    for file in files:
        check_data_file(path, folder / file)
    if name.upper().startswith("LIST"):
        _check_list(path, name, files, sizes, fields)
    if len(files) == 1:
        data_size = (folder / files[0]).stat().st_size
    if header and header[0] > 0 and data_size is not None and header[0] > data_size:
        raise VolumeReadError(path, f"HeaderSize = {header[0]} is larger than the data "
                                    f"({data_size} bytes)")
    compressed = _ints(path, fields, "compresseddatasize", 1, 0, None)
    if compressed and data_size is not None and compressed[0] > data_size:
        raise VolumeReadError(path, f"CompressedDataSize = {compressed[0]} is larger than the "
                                    f"data ({data_size} bytes); the file is truncated or corrupt")


_MET_BYTES = {"MET_CHAR": 1, "MET_UCHAR": 1, "MET_SHORT": 2, "MET_USHORT": 2, "MET_INT": 4,
              "MET_UINT": 4, "MET_LONG": 4, "MET_ULONG": 4, "MET_LONG_LONG": 8,
              "MET_ULONG_LONG": 8, "MET_FLOAT": 4, "MET_DOUBLE": 8}


def _check_list(path: Path, name: str, files: list[str], sizes: list[int],
                fields: dict[str, str]) -> None:
    """``LIST [nD]``: one file per (N−n)-D block, each holding an n-D block (default n = N−1).
    VTK filled missing blocks from uninitialised memory."""
    words = name.split()
    per_file = len(sizes) - 1
    if len(words) > 1:
        match = re.fullmatch(r"(\d+)D", words[1], re.I)
        if match is None or not 1 <= int(match.group(1)) <= len(sizes):
            raise VolumeReadError(path, f"ElementDataFile = {name}: expected LIST or LIST nD "
                                        f"with n from 1 to {len(sizes)}")
        per_file = int(match.group(1))
    wanted = 1
    for n in sizes[per_file:]:
        wanted *= n
    if len(files) != wanted:
        raise VolumeReadError(path, f"ElementDataFile = {name} lists {len(files)} files; "
                                    f"DimSize {' '.join(map(str, sizes))} needs {wanted}")
    if fields.get("compresseddata", "").lower() == "true":
        return
    block = _MET_BYTES.get(fields.get("elementtype", "").upper(), 1)
    block *= int((fields.get("elementnumberofchannels") or "1").split()[0])
    for n in sizes[:per_file]:
        block *= n
    for file in files:
        size = (path.parent / file).stat().st_size
        if size < block:
            raise VolumeReadError(path, f"data file {file!r} holds {size} bytes; each file of "
                                        f"the list needs {block}")


def _ints(path: Path, fields: dict[str, str], key: str, count: int | None, lo: int,
          hi: int | None) -> list[int] | None:
    """The integers of a MetaImage field (None when absent), each in ``lo…hi``."""
    if key not in fields:
        return None
    text = fields[key]
    try:
        values = [int(v) for v in text.split()]
    except ValueError:
        values = []
    if (count is not None and len(values) != count) or not values or any(
            v < lo or (hi is not None and v > hi) for v in values):
        what = f"{count} integer{'s' if count != 1 else ''}" if count else "integers"
        bound = f" from {lo} to {hi}" if hi is not None else f" of at least {lo}"
        raise VolumeReadError(path, f"{_KEY_NAMES[key]} = {text} must be {what}{bound}")
    return values


_KEY_NAMES = {"ndims": "NDims", "dimsize": "DimSize", "headersize": "HeaderSize",
              "elementnumberofchannels": "ElementNumberOfChannels",
              "compresseddatasize": "CompressedDataSize"}

_LEGACY_TYPES = ("bit", "unsigned_char", "char", "unsigned_short", "short", "unsigned_int",
                 "int", "unsigned_long", "long", "float", "double", "vtktypeint64",
                 "vtktypeuint64", "vtkidtype", "string")
_DIMENSIONS = re.compile(rb"^DIMENSIONS\s+(-?\d+)\s+(-?\d+)\s+(-?\d+)\s*$", re.I | re.M)
_DECLARATIONS = re.compile(
    rb"^(POINT_DATA|CELL_DATA|SCALARS|COLOR_SCALARS|FIELD|LOOKUP_TABLE)\b([^\n]*)$", re.I | re.M
)
_FIELD_ARRAY = re.compile(
    rb"^\S+[ \t]+(\d+)[ \t]+(\d+)[ \t]+(" + b"|".join(t.encode() for t in _LEGACY_TYPES)
    + rb")[ \t]*\r?$", re.I | re.M,
)
#: Legacy files are scanned this far for declarations (the header and the declarations between
#: data blocks); a hostile header is small.
MAX_LEGACY_SCAN = 64 * 2**20
MAX_FIELD_ARRAYS = 1024


def check_legacy_vtk_header(path: Path) -> None:
    """Refuse a legacy structured-points file whose declarations exceed its grid: counts of
    points or cells beyond it, 0 or more than 64 components, a FIELD of more than 1024
    arrays, or an array of more values than the grid has voxels × 64."""
    with path.open("rb") as fh:
        text = fh.read(MAX_LEGACY_SCAN)
    match = _DIMENSIONS.search(text)
    if match is None:
        return  # VTK refuses it
    dims = [int(v) for v in match.groups()]
    if min(dims) < 1:
        raise VolumeReadError(path, f"DIMENSIONS {' '.join(map(str, dims))}: every size must "
                                    "be at least 1")
    points = dims[0] * dims[1] * dims[2]
    for found in _DECLARATIONS.finditer(text):
        keyword = found.group(1).decode().upper()
        words = found.group(2).decode("latin-1").split()
        numbers = [int(w) for w in words if w.lstrip("-").isdigit()]
        line = f"{keyword} {' '.join(words)}".strip()
        if keyword in ("POINT_DATA", "CELL_DATA") and (not numbers or not 0 <= numbers[0]
                                                       <= points):
            raise VolumeReadError(path, f"'{line}' does not match the {points} points of "
                                        f"DIMENSIONS {' '.join(map(str, dims))}")
        if keyword == "SCALARS" and len(words) > 2 and not (
                words[2].isdigit() and 1 <= int(words[2]) <= MAX_COMPONENTS):
            raise VolumeReadError(path, f"'{line}': components must be 1 to {MAX_COMPONENTS}")
        if keyword == "COLOR_SCALARS" and not (len(words) > 1 and words[1].isdigit()
                                               and 1 <= int(words[1]) <= MAX_COMPONENTS):
            raise VolumeReadError(path, f"'{line}': components must be 1 to {MAX_COMPONENTS}")
        if keyword == "FIELD" and not (numbers and 0 <= numbers[-1] <= MAX_FIELD_ARRAYS):
            raise VolumeReadError(path, f"'{line}': at most {MAX_FIELD_ARRAYS} arrays")
    for found in _FIELD_ARRAY.finditer(text):
        comps, tuples = int(found.group(1)), int(found.group(2))
        if comps < 1 or comps > MAX_COMPONENTS or tuples > points:
            raise VolumeReadError(
                path, f"field array '{found.group(0).decode('latin-1').strip()}' declares "
                      f"{comps} components × {tuples} values for a grid of {points} points",
            )
