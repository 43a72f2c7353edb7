"""Checks of a ``.vti`` file's binary arrays against its own header, before VTK reads them.

VTK trusts the byte counts in front of each binary array: a compressed array whose block
header claims 2⁴⁰ blocks makes it allocate that much (``std::bad_alloc`` aborts the process),
and an uncompressed one shorter than its grid is filled with whatever follows in the file and
in the heap (silently wrong voxels). The layout is VTK's (https://docs.vtk.org/en/latest/
design_documents/VTKFileFormats.html): per array a header of ``header_type`` words, either
``[nbytes]`` before the raw bytes, or ``[nblocks, blocksize, lastblocksize, csize_1…]`` before
compressed blocks; ``binary`` arrays and ``encoding="base64"`` appended data hold the same bytes
in base64 (a compressed header encoded on its own).
"""

from __future__ import annotations

import base64
import binascii
import math
import re
import struct
from dataclasses import dataclass
from pathlib import Path

from vtkvol.io.errors import VolumeReadError

__all__ = ["check_xml_arrays"]

#: The XML part is read whole up to this size when it holds inline (``binary``) arrays.
MAX_INLINE_BYTES = 64 * 2**20
#: A compressed block may be larger than its array (VTK's writer uses 32 KiB blocks), not
#: larger than this.
MAX_BLOCK_BYTES = 64 * 2**20
#: Compressed-block headers larger than this are not checked block by block.
MAX_HEADER_BYTES = 64 * 2**20
_HEAD_BYTES = 2**20
_TYPE_BYTES = {"Int8": 1, "UInt8": 1, "Int16": 2, "UInt16": 2, "Int32": 4, "UInt32": 4,
               "Int64": 8, "UInt64": 8, "Float32": 4, "Float64": 8}
_TAG = re.compile(rb"<(/?)(VTKFile|Piece|PointData|CellData|DataArray|AppendedData)\b([^>]*)>")
_ATTR = re.compile(rb"([A-Za-z_]+)\s*=\s*\"([^\"]*)\"")


@dataclass
class _Layout:
    path: Path
    size: int  # of the file
    word: str  # struct format of one header word, with byte order
    compressed: bool
    appended_at: int | None  # file offset of the first appended byte (after "_")
    appended_base64: bool


def check_xml_arrays(path: Path) -> None:
    """Refuse a ``.vti`` whose binary arrays' headers disagree with its grid or its size.

    Raises
    ------
    VolumeReadError
        Naming the array and what its header claims against what the grid needs or the file
        holds.
    """
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(_HEAD_BYTES)
        marker = head.find(b"<AppendedData")
        if marker < 0 and size > len(head):
            if size > MAX_INLINE_BYTES:
                return  # inline arrays this large: left to VTK
            head += fh.read()
            marker = head.find(b"<AppendedData")
    xml = head if marker < 0 else head[: head.find(b">", marker) + 1 or len(head)]
    layout: _Layout | None = None
    extent: list[int] | None = None
    section = ""
    for match in _TAG.finditer(xml):
        closing, name, attrs = match.group(1), match.group(2).decode(), dict(
            (k.decode(), v.decode("latin-1")) for k, v in _ATTR.findall(match.group(3))
        )
        if closing:
            section = "" if name in ("PointData", "CellData") else section
            continue
        if name == "VTKFile":
            layout = _file_layout(path, size, attrs, head, marker)
        elif name == "Piece":
            extent = _ints(attrs.get("Extent", ""))
        elif name in ("PointData", "CellData"):
            section = name
        elif name == "DataArray" and layout is not None and extent and len(extent) == 6 and section:
            _check_array(layout, attrs, extent, section == "CellData", xml, match.end())


def _file_layout(path: Path, size: int, attrs: dict[str, str], head: bytes, marker: int
                 ) -> _Layout:
    order = ">" if attrs.get("byte_order") == "BigEndian" else "<"
    word = "Q" if attrs.get("header_type") == "UInt64" else "I"
    appended_at = None
    appended_base64 = False
    if marker >= 0:
        tag_end = head.find(b">", marker)
        underscore = head.find(b"_", tag_end)
        appended_base64 = b'encoding="base64"' in head[marker:tag_end]
        appended_at = underscore + 1 if underscore >= 0 else None
    return _Layout(path, size, order + word, bool(attrs.get("compressor")), appended_at,
                   appended_base64)


def _ints(text: str) -> list[int] | None:
    try:
        return [int(v) for v in text.split()]
    except ValueError:
        return None


def _check_array(layout: _Layout, attrs: dict[str, str], extent: list[int], cells: bool,
                 xml: bytes, content_at: int) -> None:
    kind, form = attrs.get("type", ""), attrs.get("format", "ascii")
    if kind not in _TYPE_BYTES or form == "ascii":
        return
    comps = _ints(attrs.get("NumberOfComponents", "1")) or [1]
    dims = [max(extent[2 * a + 1] - extent[2 * a] + (0 if cells else 1), 0) for a in range(3)]
    needed = math.prod(dims) * max(comps[0], 1) * _TYPE_BYTES[kind]
    name = attrs.get("Name", "?")
    if form == "appended":
        offset = (_ints(attrs.get("offset", "0")) or [0])[0]
        if layout.appended_at is None:
            raise VolumeReadError(layout.path, f"array {name!r} is appended, but the file has "
                                               "no appended data")
        source = _Source.in_file(layout, layout.appended_at + offset, layout.appended_base64)
    else:  # binary: base64 text inside the element
        end = xml.find(b"<", content_at)
        text = b"".join(xml[content_at: end if end >= 0 else None].split())
        source = _Source(layout.path, 0, len(text), True, text)
    what = (f"array {name!r} ({kind} × {comps[0]} on a {dims[0]}×{dims[1]}×{dims[2]} grid, "
            f"{needed} bytes)")
    word = struct.calcsize(layout.word)
    if not layout.compressed:
        (declared,) = struct.unpack(layout.word, source.header(word, alone=False))
        if declared < needed:
            raise VolumeReadError(layout.path, f"{what}: its header says it holds only "
                                               f"{declared} bytes; the file is corrupt")
        if source.after(word, alone=False) < needed:
            raise VolumeReadError(layout.path, f"{what}: the file ends before its data does "
                                               "(truncated)")
        return
    blocks, block, last = struct.unpack(f"{layout.word[0]}3{layout.word[1]}",
                                        source.header(3 * word, alone=True))
    total = (blocks - 1) * block + (last or block) if blocks else 0
    header = (3 + blocks) * word
    if total != needed or block > max(needed, MAX_BLOCK_BYTES) or header > source.length:
        raise VolumeReadError(
            layout.path,
            f"{what}: its compression header declares {blocks} blocks of {block} bytes "
            f"({total} bytes uncompressed); the file is corrupt",
        )
    if header > MAX_HEADER_BYTES:
        return  # block sizes beyond 64 MiB are not read here; VTK bounds them by the file
    sizes = struct.unpack(f"{layout.word[0]}{blocks}{layout.word[1]}",
                          source.header(header, alone=True)[3 * word:])
    if source.after(header, alone=True) < sum(sizes):
        raise VolumeReadError(layout.path, f"{what}: the file ends before its compressed "
                                           "blocks do (truncated)")


@dataclass
class _Source:
    """Where one array's stored bytes are: raw bytes in the file, or base64 text (inline, or
    appended with ``encoding="base64"``), read on demand. ``length`` counts what is stored
    from the array's start to the end of the file or element (an upper bound of its size)."""

    path: Path
    start: int
    length: int
    base64_text: bool
    text: bytes | None = None

    @classmethod
    def in_file(cls, layout: _Layout, at: int, base64_text: bool) -> _Source:
        if at > layout.size:
            raise VolumeReadError(layout.path, f"an appended array starts at byte {at}, past "
                                               f"the end of the file ({layout.size} bytes)")
        return cls(layout.path, at, layout.size - at, base64_text)

    def _stored(self, count: int) -> bytes:
        if self.text is not None:
            return self.text[:count]
        with self.path.open("rb") as fh:
            fh.seek(self.start)
            return fh.read(count)

    def header(self, nbytes: int, *, alone: bool) -> bytes:
        """The first ``nbytes`` of the array's header (decoded). ``alone``: a compressed
        array's header, base64-encoded on its own."""
        stored = self._stored(4 * math.ceil(nbytes / 3) if self.base64_text else nbytes)
        if self.base64_text:
            try:
                stored = base64.b64decode(stored)[:nbytes]
            except (binascii.Error, ValueError) as exc:
                raise VolumeReadError(self.path, f"an array is not valid base64 ({exc})") from exc
        if len(stored) < nbytes:
            raise VolumeReadError(self.path, "the file ends inside an array's header (truncated)")
        return stored

    def after(self, header: int, *, alone: bool) -> int:
        """At most how many bytes follow a header of ``header`` bytes."""
        if not self.base64_text:
            return self.length - header
        if alone:
            return (self.length - 4 * math.ceil(header / 3)) * 3 // 4
        return self.length * 3 // 4 - header
