"""Raw volumes: name_XxYxZ_dtype.raw, NRRD (.nhdr/.nrrd) and .dat descriptors."""

from __future__ import annotations

import bz2
import gzip

import numpy as np
import pytest

from vtkvol.io import VolumeReadError, get_reader, read_volume


def _vol(shape=(6, 5, 4), dtype=np.uint16):
    return (np.arange(int(np.prod(shape))) % 250).astype(dtype).reshape(shape)


# -- name pattern ----------------------------------------------------------------------------
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.int16])
def test_named_raw_round_trip_is_memory_mapped(tmp_path, monkeypatch, dtype):
    monkeypatch.setattr("vtkvol.io.limits.COPY_MAPPED_UP_TO", 0)  # keep even small files mapped
    a = _vol((6, 5, 4), dtype)  # z, y, x
    name = f"bonsai_4x5x6_{np.dtype(dtype).name}.raw"
    path = tmp_path / name
    a.astype(np.dtype(dtype).newbyteorder("<")).tofile(path)
    data = read_volume(path)
    assert data.array.shape == (1, 6, 5, 4)
    assert isinstance(data.array, np.memmap)
    np.testing.assert_array_equal(data.array[0], a)
    assert data.voxel_size_um == (1.0, 1.0, 1.0)
    assert not data.voxel_size_from_metadata
    assert data.metadata["format"] == "raw"


def test_named_raw_with_spacing_suffix(tmp_path):
    path = tmp_path / "head_4x5x6_uint8_0.5x0.5x1.25um.raw"
    _vol(dtype=np.uint8).tofile(path)
    data = read_volume(path)
    assert data.voxel_size_um == pytest.approx((0.5, 0.5, 1.25))
    assert data.voxel_size_from_metadata


def test_named_raw_wrong_size_says_expected_and_actual(tmp_path):
    path = tmp_path / "bonsai_256x256x256_uint8.raw"
    path.write_bytes(b"\0" * 1000)
    with pytest.raises(VolumeReadError) as info:
        read_volume(path)
    message = str(info.value)
    assert message.startswith("bonsai_256x256x256_uint8.raw: wrong data size")
    assert "expected 16777216 bytes (256×256×256 uint8)" in message
    assert "has 1000 bytes" in message


def test_raw_without_descriptor(tmp_path):
    path = tmp_path / "mystery.raw"
    path.write_bytes(b"\0" * 64)
    with pytest.raises(
        VolumeReadError, match=r"mystery\.raw: cannot tell the dimensions .*mystery\.dat"
    ):
        read_volume(path)


def test_raw_with_sidecar_dat(tmp_path):
    a = _vol()
    a.astype("<u2").tofile(tmp_path / "scan.raw")
    (tmp_path / "scan.dat").write_text("file = scan.raw\nsize = 4 5 6\ndtype = uint16\n")
    data = read_volume(tmp_path / "scan.raw")
    np.testing.assert_array_equal(data.array[0], a)


# -- .dat ------------------------------------------------------------------------------------
def test_dat_key_value_with_channels_endian_header_and_names(tmp_path):
    a = _vol((2, 6, 5, 4))
    with (tmp_path / "cells.bin").open("wb") as fh:
        fh.write(b"H" * 16)
        fh.write(a.astype(">u2").tobytes())
    (tmp_path / "cells.dat").write_text(
        "# vtkvol raw descriptor\n"
        "file = cells.bin\n"
        "size = 4 5 6          # x y z\n"
        "channels = 2\n"
        "dtype = uint16\n"
        "endian = big\n"
        "voxel_size_um = 0.2 0.2 0.5\n"
        "header_bytes = 16\n"
        "channel_names = DAPI, membrane\n"
    )
    data = read_volume(tmp_path / "cells.dat")
    assert data.array.dtype == np.dtype("=u2")
    np.testing.assert_array_equal(data.array, a)
    assert data.voxel_size_um == pytest.approx((0.2, 0.2, 0.5))
    assert data.voxel_size_from_metadata
    assert data.channel_names == ["DAPI", "membrane"]
    assert data.metadata["byte_order"] == "big"
    one = read_volume(tmp_path / "cells.dat", channels=["membrane"])
    np.testing.assert_array_equal(one.array[0], a[1])


def test_dat_interleaved_channels(tmp_path):
    a = _vol((6, 5, 4, 3), np.uint8)  # z y x c: VTK's multi-component layout
    a.tofile(tmp_path / "rgb.raw")
    (tmp_path / "rgb.dat").write_text(
        "file = rgb.raw\nsize = 4 5 6\nchannels = 3\ndtype = uint8\nchannel_layout = interleaved\n"
    )
    data = read_volume(tmp_path / "rgb.dat")
    np.testing.assert_array_equal(data.array, np.moveaxis(a, -1, 0))
    assert data.array.flags.c_contiguous


def test_dat_classic_syntax(tmp_path):
    a = _vol(dtype=np.uint8)
    a.tofile(tmp_path / "bonsai.raw")
    (tmp_path / "bonsai.dat").write_text(
        "ObjectFileName: bonsai.raw\nTaggedFileName: ---\nResolution: 4 5 6\n"
        "SliceThickness: 1 1 1.4\nFormat: UCHAR\nNbrTags: 0\nObjectType: TEXTURE_VOLUME_OBJECT\n"
        "ObjectModel: I\nGridType: EQUIDISTANT\n"
    )
    data = read_volume(tmp_path / "bonsai.dat")
    np.testing.assert_array_equal(data.array[0], a)
    assert data.voxel_size_um == pytest.approx((1, 1, 1.4))
    assert any("unit-less slice thickness" in n for n in data.notes)


def test_dat_gzip_encoding(tmp_path):
    a = _vol()
    (tmp_path / "v.raw.gz").write_bytes(gzip.compress(a.astype("<u2").tobytes()))
    (tmp_path / "v.dat").write_text(
        "file = v.raw.gz\nsize = 4 5 6\ndtype = uint16\nencoding = gzip\n"
    )
    np.testing.assert_array_equal(read_volume(tmp_path / "v.dat").array[0], a)


def test_binary_dat(tmp_path):
    a = _vol((6, 5, 4), np.uint16)
    path = tmp_path / "stagbeetle.dat"
    path.write_bytes(np.array([4, 5, 6], "<u2").tobytes() + a.astype("<u2").tobytes())
    data = read_volume(path)
    np.testing.assert_array_equal(data.array[0], a)
    path.write_bytes(np.array([4, 5, 6], "<u2").tobytes() + b"\0" * 10)
    with pytest.raises(
        VolumeReadError,
        match=r"4×5×6 uint16 voxels, so 246 bytes are expected, but the file has 16",
    ):
        read_volume(path)


def test_dat_wrong_size_names_expected_and_actual(tmp_path):
    (tmp_path / "v.raw").write_bytes(b"\0" * 100)
    (tmp_path / "v.dat").write_text(
        "file = v.raw\nsize = 4 5 6\nchannels = 2\ndtype = uint16\nheader_bytes = 8\n"
    )
    with pytest.raises(VolumeReadError) as info:
        read_volume(tmp_path / "v.dat")
    assert str(info.value) == (
        "v.dat: wrong data size for the descriptor: expected 488 bytes "
        "(4×5×6×2 channels uint16 + 8 header bytes), but v.raw has 100 bytes"
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("file = v.raw\nsize = 4 5\ndtype = uint8\n", "size must be three integers X Y Z"),
        ("file = v.raw\nsize = 4 5 6\ndtype = complex64\n", "unsupported dtype 'complex64'"),
        ("file = v.raw\nsize = 4 5 6\n", "the descriptor has no 'dtype' entry"),
        ("file = v.raw\nsize = 4 5 6\ndtype = uint8\nvoxelsize_nm = 3\n", "line 4: unknown key"),
        ("file = v.raw\nsize = 4 0 6\ndtype = uint8\n", "zero-size axis in the descriptor"),
        (
            "file = missing.raw\nsize = 4 5 6\ndtype = uint8\n",
            "'missing.raw' it names does not exist",
        ),
        ("file = v.raw\nsize = 4 5 6\ndtype = uint8\nendian = middle\n", "endian must be"),
        ("just some words\n", "line 1: expected 'key = value'"),
    ],
)
def test_dat_errors(tmp_path, text, message):
    (tmp_path / "v.raw").write_bytes(b"\0" * 120)
    (tmp_path / "v.dat").write_text(text)
    with pytest.raises(VolumeReadError, match="^v\\.dat: .*" + message.replace("(", r"\(")):
        read_volume(tmp_path / "v.dat")


# -- NRRD ------------------------------------------------------------------------------------
def test_nhdr_3d_with_spacings_and_units(tmp_path, monkeypatch):
    monkeypatch.setattr("vtkvol.io.limits.COPY_MAPPED_UP_TO", 0)  # keep even small files mapped
    a = _vol()
    a.astype("<u2").tofile(tmp_path / "vol.raw")
    (tmp_path / "vol.nhdr").write_text(
        "NRRD0004\n# Complete NRRD file format specification at: http://teem.sf.net\n"
        "type: unsigned short\ndimension: 3\nsizes: 4 5 6\nendian: little\nencoding: raw\n"
        'spacings: 200 200 500\nspace units: "nm" "nm" "nm"\ndata file: vol.raw\n'
    )
    data = read_volume(tmp_path / "vol.nhdr")
    assert isinstance(data.array, np.memmap)
    np.testing.assert_array_equal(data.array[0], a)
    assert data.voxel_size_um == pytest.approx((0.2, 0.2, 0.5))
    assert data.metadata["format"] == "nrrd"


def test_nhdr_4d_interleaved_channels_space_directions_gzip(tmp_path):
    a = _vol((6, 5, 4, 2), np.float32)  # z y x c
    (tmp_path / "v.raw.gz").write_bytes(gzip.compress(a.astype(">f4").tobytes()))
    (tmp_path / "v.nhdr").write_text(
        "NRRD0005\ntype: float\ndimension: 4\nsizes: 2 4 5 6\nendian: big\nencoding: gzip\n"
        "kinds: vector domain domain domain\nspace dimension: 3\n"
        'space directions: none (0.3,0,0) (0,0.3,0) (0,0,1.2)\nspace units: "mm" "mm" "mm"\n'
        "data file: v.raw.gz\n"
    )
    data = read_volume(tmp_path / "v.nhdr")
    np.testing.assert_array_equal(data.array, np.moveaxis(a, -1, 0))
    assert data.voxel_size_um == pytest.approx((300.0, 300.0, 1200.0))


def test_nhdr_4d_planar_channels_by_kinds_bzip2(tmp_path):
    a = _vol((3, 6, 5, 4), np.uint8)  # c z y x
    (tmp_path / "v.bz2").write_bytes(bz2.compress(a.tobytes()))
    (tmp_path / "v.nhdr").write_text(
        "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 4 5 6 3\nencoding: bzip2\n"
        "kinds: domain domain domain list\nspacings: 0.5 0.5 2 nan\ndata file: v.bz2\n"
    )
    data = read_volume(tmp_path / "v.nhdr")
    np.testing.assert_array_equal(data.array, a)
    assert data.voxel_size_um == pytest.approx((0.5, 0.5, 2.0))
    assert any("no space units" in n for n in data.notes)


def test_nrrd_attached_data(tmp_path):
    a = _vol()
    path = tmp_path / "att.nrrd"
    header = "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 5 6\nendian: little\nencoding: raw\n\n"
    path.write_bytes(header.encode() + a.astype("<u2").tobytes())
    data = read_volume(path)
    np.testing.assert_array_equal(data.array[0], a)


def test_nrrd_ascii_encoding(tmp_path):
    a = _vol((2, 2, 3), np.int16) - 100
    path = tmp_path / "txt.nrrd"
    body = " ".join(str(v) for v in a.ravel())
    path.write_text(
        "NRRD0004\ntype: short\ndimension: 3\nsizes: 3 2 2\nencoding: ascii\n\n" + body + "\n"
    )
    np.testing.assert_array_equal(read_volume(path).array[0], a)


@pytest.mark.parametrize(
    ("header", "message"),
    [
        ("type: uchar\ndimension: 3\nsizes: 4 5 6\nencoding: raw\ndata file: v.raw\n",
         r"wrong data size for the descriptor: expected 120 bytes \(4×5×6 uint8\), "
         r"but v\.raw has 119 bytes"),
        ("type: uchar\ndimension: 4\nsizes: 2 4 5 6\nencoding: raw\ndata file: v.raw\n",
         "cannot tell which of the 4 axes"),
        ("type: uchar\ndimension: 2\nsizes: 4 5\nencoding: raw\ndata file: v.raw\n",
         "dimension 2 is not supported"),
        ("type: block\ndimension: 3\nsizes: 4 5 6\nencoding: raw\ndata file: v.raw\n",
         "unsupported NRRD type 'block'"),
        ("type: uchar\ndimension: 3\nsizes: 4 5 6\nencoding: jpeg\ndata file: v.raw\n",
         "encoding 'jpeg' is not supported"),
        ("type: uchar\ndimension: 3\nsizes: 4 5 6\nencoding: raw\n",
         "the detached NRRD header has no 'data file' field"),
        ("dimension: 3\nsizes: 4 5 6\nencoding: raw\ndata file: v.raw\n",
         "the NRRD header has no 'type' field"),
    ],
)  # fmt: skip
def test_nhdr_errors(tmp_path, header, message):
    (tmp_path / "v.raw").write_bytes(b"\0" * 119)
    (tmp_path / "v.nhdr").write_text("NRRD0004\n" + header)
    with pytest.raises(VolumeReadError, match=r"^v\.nhdr: " + message):
        read_volume(tmp_path / "v.nhdr")


def test_nhdr_bad_magic(tmp_path):
    (tmp_path / "v.nhdr").write_text("hello\n")
    with pytest.raises(VolumeReadError, match=r"v\.nhdr: not an NRRD header"):
        read_volume(tmp_path / "v.nhdr")


def test_truncated_gzip(tmp_path):
    a = _vol()
    (tmp_path / "v.gz").write_bytes(gzip.compress(a.astype("<u2").tobytes())[:-30])
    (tmp_path / "v.nhdr").write_text(
        "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 5 6\nencoding: gzip\ndata file: v.gz\n"
    )
    with pytest.raises(VolumeReadError, match=r"v\.nhdr: (corrupt gzip data|wrong data size)"):
        read_volume(tmp_path / "v.nhdr")


def test_readers_are_found_for_raw_formats(tmp_path):
    assert get_reader(tmp_path / "a_1x2x3_uint8.raw").name == "raw"
    assert get_reader(tmp_path / "a.NHDR").name == "nrrd"
    assert get_reader(tmp_path / "a.nrrd").name == "nrrd"
    assert get_reader(tmp_path / "a.dat").name == "dat"
