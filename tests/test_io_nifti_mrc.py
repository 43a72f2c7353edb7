"""NIfTI and MRC readers (optional extra ``formats``), with files written by the formats' own
libraries, and their bad inputs."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from vtkvol.io import VolumeReadError, read_volume
from vtkvol.io.registry import get_reader

nib = pytest.importorskip("nibabel")
mrcfile = pytest.importorskip("mrcfile")


def write_nifti(path: Path, xyz: np.ndarray, zooms=(0.5, 0.5, 2.0), unit="micron") -> Path:
    affine = np.diag([*zooms[:3], 1.0])
    image = nib.Nifti1Image(xyz, affine)
    image.header.set_zooms(zooms)
    image.header.set_xyzt_units(unit, "sec")
    nib.save(image, str(path))
    return path


def test_nifti_is_read_in_zyx_order_with_its_voxel_size_and_time_points(tmp_path):
    xyzt = np.arange(4 * 5 * 6 * 3, dtype=np.int16).reshape(4, 5, 6, 3)
    path = write_nifti(tmp_path / "brain.nii.gz", xyzt, zooms=(0.5, 0.25, 2.0, 1.0))
    assert get_reader(path).name == "nifti"
    data = read_volume(path, time_index=2)
    assert data.array.shape == (1, 6, 5, 4)
    np.testing.assert_array_equal(data.array[0], xyzt[..., 2].transpose(2, 1, 0))
    assert tuple(data.voxel_size_um) == pytest.approx((0.5, 0.25, 2.0))
    assert data.voxel_size_from_metadata and data.metadata["time_points"] == 3
    with pytest.raises(VolumeReadError, match=r"brain.nii.gz: time_index 3 is out of range"):
        read_volume(path, time_index=3)


def test_nifti_in_mm_and_without_unit(tmp_path):
    xyz = np.ones((3, 3, 3), np.float32)
    mm = read_volume(write_nifti(tmp_path / "mm.nii", xyz, zooms=(1.0, 1.0, 1.0), unit="mm"))
    assert tuple(mm.voxel_size_um) == pytest.approx((1000.0, 1000.0, 1000.0))
    unknown = read_volume(write_nifti(tmp_path / "u.nii", xyz, zooms=(2.0, 2.0, 2.0),
                                      unit="unknown"))
    assert tuple(unknown.voxel_size_um) == pytest.approx((2000.0, 2000.0, 2000.0))
    assert any("no length unit" in n for n in unknown.notes)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "not a readable NIfTI file"),
        (b"this is not a brain" * 40, "not a readable NIfTI file"),
    ],
)
def test_bad_nifti_files_name_the_problem(tmp_path, content, message):
    path = tmp_path / "bad.nii"
    path.write_bytes(content)
    with pytest.raises(VolumeReadError, match=rf"^bad.nii: {message}"):
        read_volume(path)


def test_truncated_nifti_is_refused(tmp_path):
    path = write_nifti(tmp_path / "cut.nii", np.ones((16, 16, 16), np.float32))
    path.write_bytes(path.read_bytes()[:2000])
    with pytest.raises(VolumeReadError, match=r"^cut.nii: "):
        read_volume(path)


def test_two_dimensional_nifti_is_refused(tmp_path):
    path = tmp_path / "flat.nii"
    nib.save(nib.Nifti1Image(np.ones((4, 4), np.float32), np.eye(4)), str(path))
    with pytest.raises(VolumeReadError, match=r"expected at least 3 dimensions"):
        read_volume(path)


def write_mrc(path: Path, zyx: np.ndarray, angstrom: float | None = 10.0) -> Path:
    with mrcfile.new(str(path), overwrite=True) as mrc:
        mrc.set_data(zyx)
        if angstrom is not None:
            mrc.voxel_size = angstrom
    return path


def test_mrc_is_read_with_its_voxel_size_in_micrometres(tmp_path):
    zyx = np.random.default_rng(0).normal(size=(5, 6, 7)).astype(np.float32)
    path = write_mrc(tmp_path / "tomo.mrc", zyx, angstrom=25.0)
    data = read_volume(path)
    assert data.array.shape == (1, 5, 6, 7)
    assert data.metadata["reader"] == "mrc"
    assert tuple(data.voxel_size_um) == pytest.approx((0.0025,) * 3)
    np.testing.assert_allclose(data.array[0], zyx, rtol=1e-6)


def test_mrc_without_voxel_size_uses_1_um_and_says_so(tmp_path):
    data = read_volume(write_mrc(tmp_path / "plain.map", np.ones((3, 4, 5), np.int16),
                                 angstrom=None))
    assert tuple(data.voxel_size_um) == (1.0, 1.0, 1.0) and not data.voxel_size_from_metadata
    assert any("is not set" in n for n in data.notes)


@pytest.mark.parametrize(
    ("mangle", "message"),
    [
        (lambda b: b[:500], "not a valid MRC file"),
        (lambda b: b"MRC?" * 300, "not a valid MRC file"),
    ],
    ids=["truncated", "garbage"],
)
def test_bad_mrc_files_name_the_problem(tmp_path, mangle, message):
    path = write_mrc(tmp_path / "bad.mrc", np.ones((8, 8, 8), np.float32))
    path.write_bytes(mangle(path.read_bytes()))
    with pytest.raises(VolumeReadError, match=rf"^bad.mrc: {message}"):
        read_volume(path)


def test_complex_mrc_is_refused(tmp_path):
    path = write_mrc(tmp_path / "fft.mrc", np.ones((2, 3, 4), np.complex64))
    with pytest.raises(VolumeReadError, match="complex-valued voxels"):
        read_volume(path)


def test_a_missing_format_library_names_the_extra(tmp_path, monkeypatch):
    path = write_mrc(tmp_path / "v.mrc", np.ones((2, 2, 2), np.float32))
    monkeypatch.setitem(sys.modules, "mrcfile", None)  # what "not installed" looks like
    expected = r"^v.mrc: reading MRC files needs the optional package 'mrcfile': pip install "
    with pytest.raises(VolumeReadError, match=expected + r"'vtkvol\[formats\]'"):
        read_volume(path)
