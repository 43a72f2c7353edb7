"""Hostile and lying inputs (generated files: lying headers, not real bytes): each gets one
clear message naming the file and the problem, quickly, without allocating what it claims and
without touching any other file."""

from __future__ import annotations

import gzip
import os
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from vtkvol.io import VolumeReadError, read_volume
from vtkvol.io.limits import ALLOW_EXTERNAL_DATA, physical_memory_bytes


def test_a_fifo_named_like_a_tiff_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "stack.tif"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with pytest.raises(VolumeReadError, match=r"^stack.tif: is not a regular file or folder"):
        read_volume(fifo)
    assert time.perf_counter() - t0 < 5


@pytest.mark.parametrize(
    ("path", "message"),
    [("cells\x00.tif", "contains a NUL byte"), ("x" * 5000 + ".tif", "cannot use this path")],
    ids=["nul", "too_long"],
)
def test_impossible_paths_are_volume_read_errors(tmp_path, path, message):
    with pytest.raises(VolumeReadError, match=message):
        read_volume(tmp_path / path)


def test_more_channels_than_can_be_shown_asks_for_a_choice(tmp_path):
    path = tmp_path / "six.npy"
    np.save(path, np.zeros((6, 2, 3, 4), np.uint8))
    with pytest.raises(VolumeReadError, match=r"^six.npy: has 6 channels \(ch0, .*ch5\); vtkvol "
                                              r"shows up to 4 at once: choose them"):
        read_volume(path)
    assert read_volume(path, channels=[0, 5]).channel_names == ["ch0", "ch5"]


def test_headers_declaring_more_than_the_machine_holds_are_refused_before_allocating(tmp_path):
    huge = 100_000
    assert huge**3 > physical_memory_bytes()
    raw = tmp_path / f"big_{huge}x{huge}x{huge}_uint8.raw"
    raw.write_bytes(b"\0" * 64)
    with pytest.raises(VolumeReadError, match=r"declares 100000×100000×100000 uint8 .* more than "
                                              r"this machine's memory"):
        read_volume(raw)
    vti = tmp_path / "big.vti"
    extent = f"0 {huge - 1} 0 {huge - 1} 0 {huge - 1}"
    vti.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="ImageData" version="0.1" '
        'byte_order="LittleEndian">\n'
        f'<ImageData WholeExtent="{extent}" Origin="0 0 0" Spacing="1 1 1">\n'
        f'<Piece Extent="{extent}"><PointData Scalars="s">'
        '<DataArray type="UInt8" Name="s" format="ascii">0 1</DataArray>'
        "</PointData></Piece>\n</ImageData>\n</VTKFile>\n"
    )
    with pytest.raises(VolumeReadError, match=r"^big.vti: declares a 100000×100000×100000 grid"):
        read_volume(vti)


def test_numpy_headers_with_absurd_shapes(tmp_path):
    npy = tmp_path / "absurd.npy"
    header = "{'descr': '<u1', 'fortran_order': False, 'shape': (1180591620717411303424, 1, 1), }"
    header = header.ljust(118) + "\n"
    npy.write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode())
    with pytest.raises(VolumeReadError, match=r"^absurd.npy: not a readable .npy file"):
        read_volume(npy)
    npz = tmp_path / "absurd.npz"
    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 1000000, 120), }"
    header = header.ljust(118) + "\n"
    with zipfile.ZipFile(npz, "w") as zf:
        zf.writestr("volume.npy", b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little")
                    + header.encode())
    with pytest.raises(VolumeReadError, match=r"^absurd.npz: declares an array of shape "
                                              r"\(1000000, 1000000, 120\) float64"):
        read_volume(npz)


def test_gzip_nrrd_that_lies_about_its_size_is_refused_before_decompressing(tmp_path):
    (tmp_path / "v.raw.gz").write_bytes(gzip.compress(b"\0" * 4096))
    (tmp_path / "v.nhdr").write_text(
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 6000 1000 1000\nencoding: gzip\n"
        "data file: v.raw.gz\n"
    )
    t0 = time.perf_counter()
    with pytest.raises(VolumeReadError, match=r"expected 6000000000 bytes .* holds 4096 bytes"):
        read_volume(tmp_path / "v.nhdr")
    assert time.perf_counter() - t0 < 2


def test_nrrd_line_skip_past_the_end_is_refused_quickly(tmp_path):
    (tmp_path / "v.raw").write_bytes(b"header\n" + b"\0" * 8)
    (tmp_path / "v.nhdr").write_text(
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
        "line skip: 1000000000\ndata file: v.raw\n"
    )
    with pytest.raises(VolumeReadError, match=r"'line skip: 1000000000' runs past the end of the "
                                              r"data file after 2 lines"):
        read_volume(tmp_path / "v.nhdr")


@pytest.mark.parametrize(
    ("descriptor", "text"),
    [
        ("v.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                   "data file: ../outside/secret.raw\n"),
        ("v.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                  "ElementDataFile = ../outside/secret.raw\n"),
        ("v.dat", "file = ../outside/secret.raw\nsize = 2 2 2\ndtype = uint8\n"),
    ],
    ids=["nrrd", "metaimage", "dat"],
)
def test_detached_headers_may_not_reach_outside_their_folder(tmp_path, monkeypatch, descriptor,
                                                             text):
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "secret.raw").write_bytes(bytes(range(8)))
    folder = tmp_path / "download"
    folder.mkdir()
    (folder / descriptor).write_text(text)
    with pytest.raises(VolumeReadError, match=rf"^{descriptor}: names a data file outside its "
                                              rf"folder .*{ALLOW_EXTERNAL_DATA}=1"):
        read_volume(folder / descriptor)
    monkeypatch.setenv(ALLOW_EXTERNAL_DATA, "1")
    data = read_volume(folder / descriptor)
    assert data.array.ravel().tolist() == list(range(8))


def test_negative_dat_header_bytes_are_refused(tmp_path):
    (tmp_path / "v.raw").write_bytes(bytes(8))
    (tmp_path / "v.dat").write_text("file = v.raw\nsize = 2 2 2\ndtype = uint8\n"
                                    "header_bytes = -7\n")
    with pytest.raises(VolumeReadError, match="header_bytes = -7 must not be negative"):
        read_volume(tmp_path / "v.dat")


def vti(path: Path, spacing: str, extent: str = "0 1 0 1 0 1") -> Path:
    path.write_text(
        '<?xml version="1.0"?>\n<VTKFile type="ImageData" version="0.1" '
        'byte_order="LittleEndian">\n'
        f'<ImageData WholeExtent="{extent}" Origin="0 0 0" Spacing="{spacing}">\n'
        f'<Piece Extent="{extent}"><PointData Scalars="s">'
        '<DataArray type="UInt8" Name="s" format="ascii">0 1 2 3 4 5 6 7</DataArray>'
        "</PointData></Piece>\n</ImageData>\n</VTKFile>\n"
    )
    return path


def test_vti_spacing_that_is_negative_is_noted_and_nan_is_refused(tmp_path):
    data = read_volume(vti(tmp_path / "neg.vti", "-0.5 1 2"))
    assert tuple(data.voxel_size_um) == (0.5, 1.0, 2.0)
    assert any("negative spacing" in n for n in data.notes)
    with pytest.raises(VolumeReadError, match=r'^nan.vti: invalid Spacing="nan 1 1"'):
        read_volume(vti(tmp_path / "nan.vti", "nan 1 1"))
    with pytest.raises(VolumeReadError, match=r"invalid spacing \(0.0, 1.0, 1.0\): every axis"):
        read_volume(vti(tmp_path / "zero.vti", "0 1 1"))


def test_metaimage_file_lists_may_not_reach_outside_their_folder(tmp_path):
    """The check above skipped ``ElementDataFile = LIST``: every listed file is checked now."""
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "secret.raw").write_bytes(bytes(range(4)))
    folder = tmp_path / "download"
    folder.mkdir()
    (folder / "own.raw").write_bytes(bytes(4))
    (folder / "list.mhd").write_text(
        "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
        "ElementDataFile = LIST 2D\nown.raw\n../outside/secret.raw\n"
    )
    with pytest.raises(VolumeReadError, match=r"^list.mhd: names a data file outside its folder"):
        read_volume(folder / "list.mhd")
