"""VolumeData, dtype normalisation and value checks (vtkvol.io.volume_data)."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.io import Spacing, VolumeData, VolumeReadError
from vtkvol.io.volume_data import as_spacing, normalize_volume, resolve_channels


def test_from_array_3d_becomes_one_channel_czyx():
    arr = np.arange(4 * 5 * 6, dtype=np.uint8).reshape(4, 5, 6)
    data = VolumeData.from_array(arr, (0.5, 0.25, 2.0))
    assert data.array.shape == (1, 4, 5, 6)
    assert data.shape_zyx == (4, 5, 6)
    assert data.n_channels == 1
    assert data.nbytes == arr.nbytes
    assert data.voxel_size_um == Spacing(0.5, 0.25, 2.0)
    assert data.voxel_size_um.z == 2.0
    assert data.channel_names == ["ch0"]
    assert data.extent_um == Spacing(3.0, 1.25, 8.0)
    assert np.shares_memory(data.array, arr)  # no copy for a supported contiguous array


def test_from_array_4d_keeps_names_and_scalar_voxel_size():
    arr = np.zeros((2, 3, 4, 5), dtype=np.float32)
    arr[1, 0, 0, 0] = 7.0
    data = VolumeData.from_array(arr, 0.3, ["a", "b"])
    assert data.voxel_size_um == Spacing(0.3, 0.3, 0.3)
    assert data.channel_names == ["a", "b"]
    assert data.channel_range(1) == (0.0, 7.0)


@pytest.mark.parametrize("shape", [(5,), (4, 5), (1, 2, 3, 4, 5)])
def test_from_array_rejects_wrong_ndim(shape):
    with pytest.raises(VolumeReadError, match=r"expected a 3-D \(z, y, x\) or 4-D"):
        VolumeData.from_array(np.zeros(shape, np.uint8))


def test_constructor_validates():
    with pytest.raises(ValueError, match="must be 4-D"):
        VolumeData(np.zeros((2, 3, 4), np.uint8), Spacing(1, 1, 1), [])
    with pytest.raises(ValueError, match="2 channel names for 1 channels"):
        VolumeData(np.zeros((1, 2, 3, 4), np.uint8), Spacing(1, 1, 1), ["a", "b"])
    with pytest.raises(ValueError, match="finite and > 0"):
        as_spacing((1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="3 values"):
        as_spacing((1.0, 2.0))


@pytest.mark.parametrize(
    ("dtype", "values", "expected", "note"),
    [
        (np.int32, [0, 5, 37], np.uint16, "int32 data converted to uint16"),
        (np.int32, [-5, 0, 300], np.int16, "int32 data converted to int16"),
        (np.int64, [-1, 0, 100_000], np.float32, "int64 data converted to float32"),
        (np.uint32, [0, 70_000, 3], np.float32, "uint32 data converted to float32"),
        (np.int8, [-3, 0, 3], np.int16, "int8 data converted to int16"),
        (np.float64, [0.5, 1.5, 2.5], np.float32, "float64 data converted to float32"),
        (np.float16, [0.5, 1.5, 2.5], np.float32, "float16 data converted to float32"),
        (np.bool_, [True, False, True], np.uint8, "boolean data stored as uint8"),
    ],
)
def test_dtype_conversion_with_note(dtype, values, expected, note):
    arr = np.resize(np.array(values, dtype=dtype), (2, 3, 4))
    data = VolumeData.from_array(arr)
    assert data.array.dtype == expected
    assert any(note in n for n in data.notes), data.notes
    np.testing.assert_array_equal(data.array[0].astype(np.float64), arr.astype(np.float64))
    assert data.metadata["original_dtype"] == np.dtype(dtype).name


def test_supported_dtypes_are_kept_without_notes():
    for dtype in (np.uint8, np.int16, np.float32):
        data = VolumeData.from_array(np.ones((2, 2, 2), dtype=dtype) * 3)
        assert data.array.dtype == dtype
        assert not any("converted" in n for n in data.notes)


def test_big_endian_and_fortran_order_become_native_c_order():
    arr = np.arange(24, dtype=">u2").reshape(2, 3, 4)
    data = VolumeData.from_array(np.asfortranarray(arr))
    assert data.array.dtype == np.dtype("=u2")
    assert data.array.flags.c_contiguous
    np.testing.assert_array_equal(data.array[0], arr)


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_complex_is_rejected(dtype):
    with pytest.raises(
        VolumeReadError, match=r"array: complex data \(complex\d+\) is not supported"
    ):
        VolumeData.from_array(np.zeros((2, 2, 2), dtype=dtype))


def test_strings_are_rejected():
    with pytest.raises(VolumeReadError, match="unsupported data type <U1"):
        VolumeData.from_array(np.full((2, 2, 2), "a"))


def test_zero_size_axis_is_rejected():
    with pytest.raises(
        VolumeReadError, match=r"zero-size axis: shape \(c, z, y, x\) = \(1, 0, 4, 4\)"
    ):
        VolumeData.from_array(np.zeros((0, 4, 4), np.uint8))


def test_all_nan_is_rejected_and_names_the_source():
    arr = np.full((1, 2, 3, 3), np.nan, dtype=np.float32)
    arr[0, 1, 1, 1] = np.inf
    data = VolumeData(arr, Spacing(1, 1, 1), [], source="/x/psf.tif")
    with pytest.raises(
        VolumeReadError, match=r"^psf\.tif: every voxel is NaN or infinite; nothing"
    ):
        normalize_volume(data)


def test_partial_nan_is_kept_with_a_note_and_ranges_ignore_it():
    arr = np.arange(27, dtype=np.float32).reshape(3, 3, 3)
    arr[0, 0, 0] = np.nan
    arr[2, 2, 2] = -np.inf
    data = VolumeData.from_array(arr)
    assert np.isnan(data.array[0, 0, 0, 0])
    assert data.metadata["nonfinite_voxels"] == 2
    assert any("2 of 27 voxels" in n and "NaN or infinite" in n for n in data.notes)
    assert data.channel_range(0) == (1.0, 25.0)
    lo, hi = data.percentiles(0, 0, 100)
    assert (lo, hi) == (1.0, 25.0)


def test_twelve_bit_detection():
    arr = np.zeros((4, 4, 4), np.uint16)
    arr[0, 0, 0] = 4095
    data = VolumeData.from_array(arr)
    assert data.metadata["bit_depth"] == 12
    assert any("12-bit" in n for n in data.notes)
    arr[0, 0, 1] = 4096
    data = VolumeData.from_array(arr)
    assert data.metadata["bit_depth"] == 16
    assert not any("12-bit" in n for n in data.notes)


def test_uniform_volume_gets_a_note():
    data = VolumeData.from_array(np.full((2, 2, 2), 5, np.uint8))
    assert any("same value" in n for n in data.notes)


def test_channel_range_is_cached_and_follows_array_replacement():
    data = VolumeData.from_array(np.arange(8, dtype=np.uint8).reshape(2, 2, 2))
    assert data.channel_range(0) == (0.0, 7.0)
    data.array = np.full((1, 2, 2, 2), 3, np.uint8)
    assert data.channel_range(0) == (3.0, 3.0)


def test_percentiles_on_large_data_use_a_subsample():
    rng = np.random.default_rng(1)
    arr = rng.integers(0, 1000, size=(160, 160, 160), dtype=np.uint16)
    data = VolumeData(arr[np.newaxis], Spacing(1, 1, 1), [])
    lo, hi = data.percentiles(0, 1, 99)
    assert 0 <= lo < 30 and 970 < hi <= 999


def test_describe_mentions_everything():
    arr = np.zeros((2, 3, 4, 5), np.uint16)
    arr[0] = 100
    arr[1, 0, 0, 0] = 4000
    data = VolumeData.from_array(
        arr,
        (0.1, 0.1, 0.5),
        ["dapi", "gfp"],
        source="/data/stack.tif",
        voxel_size_from_metadata=True,
        metadata={"axes": "TZCYX", "time_points": 4, "time_index": 2, "format": "imagej-tiff"},
    )
    text = data.describe()
    for expected in (
        "/data/stack.tif",
        "5 × 4 × 3 voxels",
        "2 channels",
        "axes in file: TZCYX",
        "index 2 of 4",
        "uint16 (12-bit content)",
        "x 0.1 µm, y 0.1 µm, z 0.5 µm (from file metadata)",
        "[0] dapi: range 100 … 100",
        "[1] gfp: range 0 … 4000",
        "memory: 240 B",
        "12-bit",
    ):
        assert expected in text, (expected, text)
    assert "VolumeData(shape_czyx=(2, 3, 4, 5)" in repr(data)


def test_resolve_channels():
    names = ["a", "b", "c"]
    assert resolve_channels(None, names, "f.tif") == [0, 1, 2]
    assert resolve_channels([2, "a", -1], names, "f.tif") == [2, 0, 2]
    with pytest.raises(
        VolumeReadError, match=r"f\.tif: channel 3 is out of range: the file has 3 channels \(0–2\)"
    ):
        resolve_channels([3], names, "f.tif")
    with pytest.raises(VolumeReadError, match="no channel named 'x'"):
        resolve_channels(["x"], names, "f.tif")
