"""Hostile inputs that used to kill or hang the process (``std::bad_alloc`` aborts, SIGBUS,
reads that never return). Each is read in a child process with a time limit, so a regression
fails its test instead of taking pytest down; each must end in one clear refusal."""

from __future__ import annotations

import json
import math
import os
import struct
import zlib

import numpy as np
import pytest
import tifffile
from tests_support_hostile import lying_tiff, read_in_child, run_child, snapshot

from vtkvol.io import VolumeReadError, read_volume
from vtkvol.io.limits import physical_memory_bytes

REFUSED = 3  # READ_CHILD's exit status for a VolumeReadError


def assert_refused(result, message: str) -> None:
    assert result.died_of is None, f"killed by {result.died_of}: {result.stderr[-2000:]}"
    assert "timed out" not in result.stderr, result.stderr[-2000:]
    assert result.returncode == REFUSED, (result.stdout, result.stderr[-2000:])
    assert message in result.stdout, result.stdout


def side_beyond_memory(bytes_per_voxel: int) -> int:
    """A cube side whose voxels take twice this machine's memory."""
    return math.ceil((2 * physical_memory_bytes() / bytes_per_voxel) ** (1 / 3))


# -- std::bad_alloc inside VTK's readers -------------------------------------------------------
def vtk_file(folder, kind: str, n: int):
    header = (f"ObjectType = Image\nNDims = 3\nDimSize = {n} {n} {n}\nElementType = MET_DOUBLE\n"
              "ElementNumberOfChannels = 4\n")
    if kind == "vti":
        extent = f"0 {n - 1} 0 {n - 1} 0 {n - 1}"
        path = folder / "wide.vti"
        path.write_text(
            '<?xml version="1.0"?>\n<VTKFile type="ImageData" version="0.1" '
            'byte_order="LittleEndian">\n'
            f'<ImageData WholeExtent="{extent}" Origin="0 0 0" Spacing="1 1 1">\n'
            f'<Piece Extent="{extent}"><PointData Scalars="s">'
            '<DataArray type="Float64" Name="s" NumberOfComponents="4" format="ascii">0 1'
            "</DataArray></PointData></Piece>\n</ImageData>\n</VTKFile>\n"
        )
    elif kind == "mha":
        path = folder / "wide.mha"
        path.write_bytes((header + "ElementDataFile = LOCAL\n").encode() + bytes(64))
    elif kind == "mhd":
        (folder / "wide.raw").write_bytes(bytes(64))
        path = folder / "wide.mhd"
        path.write_text(header + "ElementDataFile = wide.raw\n")
    else:
        path = folder / "wide.vtk"
        path.write_text(
            f"# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\n"
            f"DIMENSIONS {n} {n} {n}\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA {n**3}\n"
            "SCALARS s double 4\nLOOKUP_TABLE default\n0 1 2\n"
        )
    return path


@pytest.mark.parametrize("kind", ["vti", "mha", "mhd", "vtk"])
def test_vtk_headers_declaring_wide_voxels_beyond_memory_are_refused_not_aborted(tmp_path, kind):
    """The grid alone fits in memory at one byte per voxel; its float64 × 4 voxels do not
    (VTK aborted the process with std::bad_alloc for .vti, .mha and .mhd)."""
    n = side_beyond_memory(32)
    path = vtk_file(tmp_path, kind, n)
    assert n**3 < physical_memory_bytes()
    result = read_in_child(path)
    assert_refused(result, f"declares a {n}×{n}×{n} grid of float64 × 4")


def appended_vti(path, header: bytes, blob: bytes, compressor: str = "vtkZLibDataCompressor"):
    extent = "0 3 0 3 0 3"
    text = (
        '<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
        f'byte_order="LittleEndian" header_type="UInt64" compressor="{compressor}">\n'
        f'<ImageData WholeExtent="{extent}" Origin="0 0 0" Spacing="1 1 1">\n'
        f'<Piece Extent="{extent}"><PointData Scalars="s">'
        '<DataArray type="UInt8" Name="s" format="appended" offset="0"/>'
        '</PointData></Piece>\n</ImageData>\n<AppendedData encoding="raw">\n_'
    )
    path.write_bytes(text.encode() + header + blob + b"\n</AppendedData>\n</VTKFile>\n")
    return path


@pytest.mark.parametrize(
    ("header", "blob", "compressor", "message"),
    [
        (struct.pack("<QQQ", 2**40, 64, 64), bytes(32), "vtkZLibDataCompressor",
         "its compression header declares 1099511627776 blocks of 64 bytes"),
        (struct.pack("<QQQQ", 1, 2**40, 2**40, 16), zlib.compress(bytes(64))[:16],
         "vtkZLibDataCompressor", "its compression header declares 1 blocks of 1099511627776"),
        (struct.pack("<QQQQ", 1, 64, 64, 2**40), bytes(16), "vtkLZMADataCompressor",
         "the file ends before its compressed blocks do"),
    ],
    ids=["block_count", "block_size", "compressed_size"],
)
def test_vti_compression_headers_that_lie_are_refused_not_aborted(tmp_path, header, blob,
                                                                   compressor, message):
    path = appended_vti(tmp_path / "lying.vti", header, blob, compressor)
    result = read_in_child(path)
    assert_refused(result, f"lying.vti: array 's' (UInt8 × 1 on a 4×4×4 grid, 64 bytes): {message}")


def test_tiff_pages_declaring_more_than_memory_are_refused_before_allocating(tmp_path):
    """Compressed pages (not memory-mappable) that together declare twice the machine's memory:
    numpy's MemoryError escaped read_volume before; now the header is refused unread."""
    side = 65535
    pages = math.ceil(2 * physical_memory_bytes() / side**2)
    # 64 KiB of stored data per page: a ratio zlib could reach, so only memory speaks.
    path = lying_tiff(tmp_path / "lying.tif", width=side, height=side, pages=pages,
                      compression=8, data=bytes(64 * 1024))
    result = read_in_child(path)
    assert_refused(result, f"lying.tif: declares {pages}×{side}×{side} uint8")


def test_a_compressed_page_claiming_more_than_any_codec_packs_is_refused_before_decoding(
        tmp_path):
    """Found by the fuzz test: a 63754² two-sample uint16 page (15 GiB, under this machine's
    memory) from 100 stored bytes; decoding allocated it twice (output and codec buffer) and
    the kernel killed the test run."""
    path = lying_tiff(tmp_path / "bomb.tif", width=63754, height=63754, samples=2, bits=16,
                      compression=50000, data=bytes(100))
    result = read_in_child(path, memory_bytes=4 * 2**30)
    assert_refused(result, "bomb.tif: corrupt TIFF: page 0 claims 16258290064 bytes of image "
                           "data stored in 100 bytes, more than any TIFF compression achieves")


def test_running_out_of_memory_in_any_reader_is_a_volume_read_error(tmp_path, monkeypatch):
    def exhausted(*_args, **_kwargs):
        raise MemoryError

    np.save(tmp_path / "v.npy", np.zeros((2, 2, 2), np.uint8))
    monkeypatch.setattr("vtkvol.io.read.get_reader", lambda _path: exhausted)
    with pytest.raises(VolumeReadError, match=r"^v.npy: there is not enough free memory to read "
                                              r"it; close other programs"):
        read_volume(tmp_path / "v.npy")


# -- SIGBUS: a memory-mapped file truncated while in use ------------------------------------
def mapped_files(folder):
    volume = (np.arange(32 * 32 * 32) % 251).astype(np.uint8).reshape(32, 32, 32)
    raw = folder / "stack_32x32x32_uint8.raw"
    volume.tofile(raw)
    npy = folder / "stack.npy"
    np.save(npy, volume)
    tif = folder / "stack.tif"
    tifffile.imwrite(tif, volume, imagej=True, metadata={"axes": "ZYX"})
    return {"raw": raw, "npy": npy, "tif": tif}, int(volume.sum(dtype=np.int64))


@pytest.mark.parametrize("kind", ["raw", "npy", "tif"])
def test_a_file_truncated_after_reading_does_not_kill_the_process(tmp_path, kind):
    """Re-saving a stack in place (Fiji truncates, then writes) while vtkvol shows it: a
    memory map of the old file raised SIGBUS at the next access (a histogram, the GPU upload,
    a shadow recompute). Data that fits easily in memory is now read into memory."""
    files, total = mapped_files(tmp_path)
    path = files[kind]
    result = read_in_child(path, extra=f"""
        import os
        os.truncate({json.dumps(str(path))}, 100)
        print("SUM", int(data.array.sum(dtype="int64")), data.metadata["memory_mapped"])
    """)
    assert result.died_of is None, f"killed by {result.died_of}"
    assert result.returncode == 0, result.stderr[-2000:]
    assert f"SUM {total} False" in result.stdout


def test_only_data_too_large_to_copy_stays_memory_mapped(tmp_path, monkeypatch):
    files, total = mapped_files(tmp_path)
    monkeypatch.setattr("vtkvol.io.limits.COPY_MAPPED_UP_TO", 32**3 - 1)
    data = read_volume(files["raw"])
    assert isinstance(data.array, np.memmap) and data.metadata["memory_mapped"] is True
    assert "memory-mapped from disk" in data.describe()
    monkeypatch.setattr("vtkvol.io.limits.COPY_MAPPED_UP_TO", 32**3)
    data = read_volume(files["raw"])
    assert not isinstance(data.array, np.memmap) and data.metadata["memory_mapped"] is False
    assert int(data.array.sum(dtype=np.int64)) == total


# -- reads that never returned --------------------------------------------------------------
DETACHED = {
    "v.nhdr": ("v.raw", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                        "line skip: 1\ndata file: v.raw\n"),
    "v.mhd": ("v.raw", "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\n"
                       "ElementType = MET_UCHAR\nElementDataFile = v.raw\n"),
    "v.dat": ("v.raw", "file = v.raw\nsize = 2 2 2\ndtype = uint8\n"),
    "gz.nhdr": ("v.raw.gz", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                            "encoding: gzip\ndata file: v.raw.gz\n"),
}


@pytest.mark.parametrize("descriptor", sorted(DETACHED))
def test_a_header_naming_a_pipe_as_its_data_is_refused_without_blocking(tmp_path, descriptor):
    """MetaImage (inside VTK) and NRRD's 'line skip' opened the named pipe and waited for a
    writer forever; the others said the pipe "does not exist"."""
    data_name, text = DETACHED[descriptor]
    os.mkfifo(tmp_path / data_name)
    (tmp_path / descriptor).write_text(text)
    result = read_in_child(tmp_path / descriptor, timeout=30)
    assert_refused(result, f"{descriptor}: the data file {data_name!r} it names is not a regular "
                           "file (a pipe, socket or device)")


def test_a_header_naming_a_device_through_a_link_is_refused(tmp_path, monkeypatch):
    os.symlink("/dev/zero", tmp_path / "zero.raw")
    (tmp_path / "v.nhdr").write_text("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                                     "encoding: raw\ndata file: zero.raw\n")
    monkeypatch.setenv("VTKVOL_ALLOW_EXTERNAL_DATA", "1")  # even where outside data is allowed
    with pytest.raises(VolumeReadError, match="is not a regular file"):
        read_volume(tmp_path / "v.nhdr")


def test_a_session_that_is_a_pipe_or_names_one_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "view.vtkvol.json")
    result = run_child(f"""
        import sys
        from vtkvol.model.session import SessionError, read_session
        try:
            read_session({json.dumps(str(tmp_path / "view.vtkvol.json"))})
        except SessionError as exc:
            print("REFUSED", exc)
            sys.exit(3)
    """, timeout=30)
    assert_refused(result, "view.vtkvol.json: is not a regular file (a pipe, socket or device)")

    from vtkvol.model.scene import SceneModel
    from vtkvol.model.session import save_session

    np.save(tmp_path / "v.npy", np.arange(8, dtype=np.uint8).reshape(2, 2, 2))
    data = read_volume(tmp_path / "v.npy")
    session = save_session(tmp_path / "other", SceneModel(), data=data)
    os.unlink(tmp_path / "v.npy")
    os.mkfifo(tmp_path / "v.npy")  # the data file became a pipe
    before = snapshot(tmp_path)
    result = run_child(f"""
        import sys
        from vtkvol.io import VolumeReadError
        from vtkvol.model.session import load_session_with_data
        try:
            load_session_with_data({json.dumps(str(session))})
        except VolumeReadError as exc:
            print("REFUSED", exc)
            sys.exit(3)
    """, timeout=30)
    assert_refused(result, "v.npy: is not a regular file or folder")
    assert snapshot(tmp_path) == before


def test_an_nrrd_header_that_never_ends_is_refused_without_reading_the_file(tmp_path):
    """No blank line after the header and 256 MiB of data without a newline: the header
    reader took the whole file as one line (all of it in memory)."""
    path = tmp_path / "endless.nrrd"
    with path.open("wb") as fh:
        fh.write(b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n")
        fh.truncate(256 * 2**20)  # sparse: zeros, and no newline
    result = read_in_child(path, timeout=30, memory_bytes=2 * 2**30)
    assert_refused(result, "endless.nrrd: no end of the NRRD header within 1024 KiB")


def test_a_tiff_whose_pages_link_in_a_circle_is_refused_without_looping(tmp_path):
    """tifffile stops at the loop and returns the pages before it (1 of 3 here), which was
    shown as the image with a note; a damaged chain is now refused (issue 28), in one pass."""
    path = lying_tiff(tmp_path / "circle.tif", pages=3, circular=True, data=bytes(16))
    result = read_in_child(path, timeout=30)
    assert_refused(result, "circle.tif: corrupt or truncated TIFF (its chain of pages loops "
                           "back on itself: invalid circular reference to IFD 0")


LEGACY = ("# vtk DataFile Version 3.0\nlying\nBINARY\nDATASET STRUCTURED_POINTS\n"
          "DIMENSIONS 2 2 2\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 8\n")
META = "ObjectType = Image\nNDims = 3\nElementType = MET_UCHAR\n"


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("sizes.mha", META + "DimSize = -2 2 2\nElementDataFile = LOCAL\n",
         "DimSize = -2 2 2 must be 3 integers of at least 1"),
        ("channels.mha", META + "DimSize = 2 2 2\nElementNumberOfChannels = -4\n"
                                "ElementDataFile = LOCAL\n",
         "ElementNumberOfChannels = -4 must be 1 integer from 1 to 64"),
        ("packed.mha", META + "DimSize = 2 2 2\nCompressedData = True\n"
                              "CompressedDataSize = 99999999999\nElementDataFile = LOCAL\n",
         "CompressedDataSize = 99999999999 is larger than the data"),
        ("colours.vtk", LEGACY + "COLOR_SCALARS s 2000000000\n",
         "'COLOR_SCALARS s 2000000000': components must be 1 to 64"),
        ("field.vtk", LEGACY + "FIELD f 1\narr 2000000000 8 unsigned_char\n",
         "field array 'arr 2000000000 8 unsigned_char' declares 2000000000 components"),
        ("arrays.vtk", LEGACY + "FIELD f 99999999\narr 1 8 unsigned_char\n",
         "'FIELD f 99999999': at most 1024 arrays"),
    ],
    ids=["negative_size", "negative_channels", "compressed_size", "colour_components",
         "field_array", "field_count"],
)
def test_metaimage_and_legacy_vtk_numbers_vtk_trusts_are_checked_first(tmp_path, name, text,
                                                                       message):
    """VTK aborted the process on the MetaImage ones (std::bad_alloc, vector length error) and
    spent minutes (past this test's 30 s) on the legacy ones."""
    path = tmp_path / name
    path.write_bytes(text.encode() + bytes(16))
    result = read_in_child(path, timeout=30)
    assert_refused(result, f"{name}: {message}")
