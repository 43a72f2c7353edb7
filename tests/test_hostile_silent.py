"""Hostile inputs that used to be read without a word, giving wrong voxels or a wrong
geometry: each is now refused in one line or read with a note saying what was assumed. Files
are generated (lying headers, not real data); reading never changes any file."""

from __future__ import annotations

import base64
import struct

import numpy as np
import pytest
from tests_support_hostile import lying_tiff, snapshot

from vtkvol.io import VolumeReadError, read_volume


def test_tiff_strips_shorter_than_their_page_are_refused_not_read_past(tmp_path):
    """A 4×4 uint64 page whose one strip holds 64 of its 128 bytes: the memory map read the
    next 64 bytes of the file (the page's own tags) as voxels."""
    path = lying_tiff(tmp_path / "short.tif", bits=64, data=bytes(64))
    before = snapshot(tmp_path)
    with pytest.raises(VolumeReadError, match=r"^short.tif: corrupt TIFF: page 0 declares 64 "
                                              r"bytes of image data, but a 4×4 uint64 page "
                                              r"needs 128"):
        read_volume(path)
    assert snapshot(tmp_path) == before


def vti_text(array_xml: str, appended: bytes | None = None, encoding: str = "raw") -> bytes:
    extent = "0 3 0 3 0 3"
    head = (
        '<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64">\n'
        f'<ImageData WholeExtent="{extent}" Origin="0 0 0" Spacing="1 1 1">\n'
        f'<Piece Extent="{extent}"><PointData Scalars="s">{array_xml}</PointData></Piece>\n'
        "</ImageData>\n"
    ).encode()
    if appended is None:
        return head + b"</VTKFile>\n"
    return (head + f'<AppendedData encoding="{encoding}">\n_'.encode() + appended
            + b"\n</AppendedData>\n</VTKFile>\n")


APPENDED = '<DataArray type="UInt8" Name="s" format="appended" offset="0"/>'


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # The byte count claims 2⁶² bytes; 8 follow, then the closing tags.
        (vti_text(APPENDED, struct.pack("<Q", 2**62) + bytes(8)),
         "the file ends before its data does"),
        (vti_text(APPENDED, struct.pack("<Q", 8) + bytes(64)),
         "its header says it holds only 8 bytes"),
        (vti_text(APPENDED, base64.b64encode(struct.pack("<Q", 64) + bytes(8)), "base64"),
         "the file ends before its data does"),
        (vti_text('<DataArray type="UInt8" Name="s" format="binary">'
                  + base64.b64encode(struct.pack("<Q", 2**50) + bytes(8)).decode()
                  + "</DataArray>"),
         "the file ends before its data does"),
    ],
    ids=["appended_raw_truncated", "appended_raw_count_short", "appended_base64", "inline"],
)
def test_vti_arrays_shorter_than_their_grid_are_refused(tmp_path, text, message):
    """VTK filled the rest of a short array with the bytes after it: the closing XML tags and
    then uninitialised heap memory, shown as voxels."""
    path = tmp_path / "short.vti"
    path.write_bytes(text)
    before = snapshot(tmp_path)
    with pytest.raises(VolumeReadError, match=rf"^short.vti: array 's' \(UInt8 × 1 on a 4×4×4 "
                                              rf"grid, 64 bytes\): {message}"):
        read_volume(path)
    assert snapshot(tmp_path) == before


def test_well_formed_vti_arrays_of_every_encoding_still_read(tmp_path):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    values = np.arange(5 * 4 * 3 * 2, dtype=np.uint16)
    image = vtk.vtkImageData()
    image.SetDimensions(5, 4, 3)
    array = numpy_to_vtk(values.reshape(-1, 2), deep=True)
    array.SetName("s")
    image.GetPointData().SetScalars(array)
    for mode in ("binary", "appended_raw", "appended_base64"):
        for compressed in (False, True):
            for header in ("UInt32", "UInt64"):
                writer = vtk.vtkXMLImageDataWriter()
                writer.SetInputData(image)
                writer.SetFileName(str(tmp_path / "ok.vti"))
                writer.SetDataModeToBinary() if mode == "binary" else (
                    writer.SetDataModeToAppended())
                writer.SetEncodeAppendedData(mode == "appended_base64")
                getattr(writer, f"SetHeaderTypeTo{header}")()
                if not compressed:
                    writer.SetCompressorTypeToNone()
                writer.SetBlockSize(16)  # several compressed blocks
                assert writer.Write() == 1
                data = read_volume(tmp_path / "ok.vti")
                assert data.array.shape == (2, 3, 4, 5), (mode, compressed, header)
                assert data.array[1].ravel().tolist() == values[1::2].tolist()


@pytest.mark.parametrize(
    ("descriptor", "text", "declared"),
    [
        ("huge.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 2 3 4\nElementSpacing = 1e30 1 1\n"
                     "ElementType = MET_UCHAR\nElementDataFile = v.raw\n", "(1e+30, 1, 1)"),
        ("flat.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nencoding: raw\n"
                      'spacings: 0.0001 0.0001 100\nspace units: "µm" "µm" "µm"\n'
                      "data file: v.raw\n", "(0.0001, 0.0001, 100)"),
    ],
    ids=["absurd_size", "absurd_anisotropy"],
)
def test_implausible_voxel_sizes_are_replaced_with_a_note(tmp_path, descriptor, text, declared):
    """Before: read as declared; a 1e30 µm voxel (or a million-fold anisotropy) made the view
    and the step sizes meaningless without a word."""
    (tmp_path / "v.raw").write_bytes(bytes(24))
    (tmp_path / descriptor).write_text(text)
    data = read_volume(tmp_path / descriptor)
    assert tuple(data.voxel_size_um) == (1.0, 1.0, 1.0) and not data.voxel_size_from_metadata
    assert any(f"voxel size {declared} µm is not plausible" in n for n in data.notes), data.notes
    chosen = read_volume(tmp_path / descriptor, voxel_size_um=(0.5, 0.5, 2.0))
    assert tuple(chosen.voxel_size_um) == (0.5, 0.5, 2.0)
    assert not any("not plausible" in n for n in chosen.notes)


def test_byte_order_and_fortran_order_are_honoured(tmp_path):
    """Already fine: big-endian and Fortran-ordered data keep their values (no silent
    byte-swapped or transposed volume)."""
    volume = np.arange(24, dtype=np.uint16).reshape(2, 3, 4) * 1000
    np.save(tmp_path / "big.npy", volume.astype(">u2"))
    np.save(tmp_path / "fortran.npy", np.asfortranarray(volume))
    volume.astype(">u2").tofile(tmp_path / "big.raw")
    (tmp_path / "big.nhdr").write_text("NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 3 2\n"
                                       "endian: big\nencoding: raw\ndata file: big.raw\n")
    for name in ("big.npy", "fortran.npy", "big.nhdr"):
        data = read_volume(tmp_path / name)
        assert np.array_equal(data.array[0], volume), name
    assert any("Fortran-ordered" in n for n in read_volume(tmp_path / "fortran.npy").notes)


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("zero.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 2 3 4\nElementSpacing = 0 -1 nan\n"
                     "ElementType = MET_UCHAR\nElementDataFile = v.raw\n",
         r"invalid spacing \(0.0, 1.0, 0.0\)"),
        ("short.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 2 3 8\n"
                      "ElementType = MET_UCHAR\nElementDataFile = v.raw\n",
         "VTK could not read an image from this file"),
    ],
    ids=["bad_spacing", "short_data"],
)
def test_metaimage_lies_about_spacing_and_size_are_refused(tmp_path, name, text, message):
    """Already fine: refused in one line."""
    (tmp_path / "v.raw").write_bytes(bytes(24))
    (tmp_path / name).write_text(text)
    with pytest.raises(VolumeReadError, match=rf"^{name}: {message}"):
        read_volume(tmp_path / name)


def test_nrrd_headers_in_utf8_name_their_units(tmp_path):
    """'µm' written in UTF-8 (as most tools do) was decoded as Latin-1 and refused as the
    unknown unit 'Âµm'."""
    (tmp_path / "v.raw").write_bytes(bytes(24))
    (tmp_path / "v.nhdr").write_bytes(
        'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nencoding: raw\n'
        'spacings: 0.5 0.5 2\nspace units: "µm" "µm" "µm"\ndata file: v.raw\n'.encode()
    )
    data = read_volume(tmp_path / "v.nhdr")
    assert tuple(data.voxel_size_um) == (0.5, 0.5, 2.0) and data.voxel_size_from_metadata


@pytest.mark.parametrize(
    ("files", "message"),
    [(["a.raw"], "ElementDataFile = LIST 2D lists 1 files; DimSize 2 2 2 needs 2"),
     (["a.raw", "short.raw"], "data file 'short.raw' holds 2 bytes; each file of the list "
                              "needs 4")],
    ids=["too_few_files", "short_file"],
)
def test_metaimage_lists_that_do_not_cover_the_grid_are_refused(tmp_path, files, message):
    """VTK read the slices the list does not provide from uninitialised memory."""
    (tmp_path / "a.raw").write_bytes(bytes(range(4)))
    (tmp_path / "short.raw").write_bytes(bytes(2))
    (tmp_path / "list.mhd").write_text(
        "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
        "ElementDataFile = LIST 2D\n" + "\n".join(files) + "\n"
    )
    before = snapshot(tmp_path)
    with pytest.raises(VolumeReadError, match=rf"^list.mhd: {message}"):
        read_volume(tmp_path / "list.mhd")
    assert snapshot(tmp_path) == before
    (tmp_path / "list.mhd").write_text(
        "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
        "ElementDataFile = LIST 2D\na.raw\na.raw\n"
    )
    assert read_volume(tmp_path / "list.mhd").array.ravel().tolist() == [0, 1, 2, 3] * 2
