"""fit_volume: average / subsample / crop / none, shapes, voxel sizes, notes."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.io import ReadCancelled, VolumeData, VolumeReadError, fit_volume, read_volume
from vtkvol.io.fit import plan_factors


def _data(shape_czyx=(2, 10, 12, 16), dtype=np.uint16, voxel=(0.2, 0.2, 0.5)):
    rng = np.random.default_rng(3)
    arr = rng.integers(0, 4000, size=shape_czyx).astype(dtype)
    return VolumeData.from_array(arr, voxel, source="/data/big.tif")


def test_fitting_volume_is_returned_unchanged():
    data = _data()
    assert fit_volume(data, max_texture_size=16, memory_budget_bytes=None) is data


def test_average_texture_limit_shape_voxel_size_and_block_mean():
    data = _data((1, 10, 12, 16))
    out = fit_volume(data, max_texture_size=8, memory_budget_bytes=None, strategy="average")
    # factors x 2 (16→8), y 2 (12→6), z 2 (10→5)
    assert out.array.shape == (1, 5, 6, 8)
    assert out.voxel_size_um == pytest.approx((0.4, 0.4, 1.0))
    assert out.array.dtype == np.uint16
    src = data.array[0].astype(np.float64)
    expected = src.reshape(5, 2, 6, 2, 8, 2).mean(axis=(1, 3, 5))
    np.testing.assert_array_equal(out.array[0], np.rint(expected))
    assert out.metadata["fit"]["factors_xyz"] == (2, 2, 2)
    assert out.metadata["fit"]["from_shape_czyx"] == (1, 10, 12, 16)
    note = out.notes[-1]
    assert "downsampled by area averaging" in note
    assert "from 16×12×10 (x×y×z, 1 channel) to 8×6×5" in note
    assert "x has 16 voxels > max texture size 8" in note
    assert "voxel size now 0.4 × 0.4 × 1 µm" in note
    assert data.array.shape == (1, 10, 12, 16)  # input untouched


def test_average_handles_partial_edge_blocks():
    arr = np.arange(7, dtype=np.float32).reshape(1, 1, 7)  # z=1, y=1, x=7
    data = VolumeData.from_array(arr)
    out = fit_volume(data, max_texture_size=3, strategy="average")
    assert out.array.shape == (1, 1, 1, 3)
    np.testing.assert_allclose(out.array[0, 0, 0], [1.0, 4.0, 6.0])  # last block has 1 voxel


def test_average_ignores_nan_in_blocks():
    arr = np.array([[[1.0, np.nan, 3.0, 5.0]]], dtype=np.float32)
    out = fit_volume(VolumeData.from_array(arr), max_texture_size=2)
    np.testing.assert_allclose(out.array[0, 0, 0], [1.0, 4.0])


def test_memory_budget_reduces_finest_axis_first():
    # x, y at 0.2 µm, z at 1.0 µm: halving x and y keeps the volume more isotropic.
    data = _data((1, 8, 16, 16), voxel=(0.2, 0.2, 1.0))
    budget = data.nbytes // 4
    out = fit_volume(data, max_texture_size=None, memory_budget_bytes=budget)
    assert out.nbytes <= budget
    assert out.array.shape == (1, 8, 8, 8)
    assert out.voxel_size_um == pytest.approx((0.4, 0.4, 1.0))
    assert "memory budget" in out.notes[-1]


def test_plan_factors():
    assert plan_factors((1, 100, 5000, 5000), 2, (1, 1, 1), 2048, None) == (3, 3, 1)
    f = plan_factors((2, 64, 64, 64), 2, (1, 1, 1), None, 2 * 2 * 32**3)
    assert np.prod([int(np.ceil(64 / v)) for v in f]) * 4 <= 2 * 2 * 32**3


def test_subsample():
    data = _data((1, 10, 12, 16))
    out = fit_volume(data, max_texture_size=8, strategy="subsample")
    np.testing.assert_array_equal(out.array, data.array[:, ::2, ::2, ::2])
    assert out.voxel_size_um == pytest.approx((0.4, 0.4, 1.0))
    assert "subsampled" in out.notes[-1] and "from 16×12×10" in out.notes[-1]


def test_crop_centred_and_with_offset():
    data = _data((2, 10, 12, 16))
    out = fit_volume(data, max_texture_size=8, strategy="crop")
    assert out.array.shape == (2, 8, 8, 8)
    # centred: offsets x (16-8)//2 = 4, y 2, z 1
    np.testing.assert_array_equal(out.array, data.array[:, 1:9, 2:10, 4:12])
    assert out.voxel_size_um == data.voxel_size_um
    assert out.metadata["fit"]["offset_xyz"] == (4, 2, 1)
    assert out.metadata["fit"]["origin_um"] == pytest.approx((0.8, 0.4, 0.5))
    assert "cropped from 16×12×10 (x×y×z, 2 channels) to 8×8×8" in out.notes[-1]
    assert "offset x=4, y=2, z=1" in out.notes[-1]
    corner = fit_volume(data, max_texture_size=8, strategy="crop", crop_offset=(0, None, 2))
    np.testing.assert_array_equal(corner.array, data.array[:, 2:10, 2:10, 0:8])
    with pytest.raises(ValueError, match="crop_offset x=9 is out of range 0–8"):
        fit_volume(data, max_texture_size=8, strategy="crop", crop_offset=(9, 0, 0))


def test_crop_to_memory_budget():
    data = _data((1, 16, 16, 16))
    out = fit_volume(
        data, max_texture_size=None, memory_budget_bytes=data.nbytes // 8, strategy="crop"
    )
    assert out.nbytes <= data.nbytes // 8
    assert out.array.shape == (1, 8, 8, 8)


def test_none_raises_a_clear_error():
    data = _data((1, 10, 12, 16))
    with pytest.raises(VolumeReadError) as info:
        fit_volume(data, max_texture_size=8, strategy="none")
    message = str(info.value)
    assert message.startswith("big.tif: the volume 16×12×10 (x×y×z, 1 channel)")
    assert "x has 16 voxels > max texture size 8" in message
    assert "use fit='average', 'subsample' or 'crop'" in message


def test_budget_smaller_than_one_voxel():
    with pytest.raises(VolumeReadError, match="cannot hold even one voxel"):
        fit_volume(_data(), max_texture_size=None, memory_budget_bytes=1)


def test_unknown_strategy():
    with pytest.raises(ValueError, match="unknown fit strategy 'shrink'"):
        fit_volume(_data(), max_texture_size=4, strategy="shrink")  # type: ignore[arg-type]


def test_fit_progress_and_cancel():
    data = _data((1, 16, 16, 16))
    seen: list[float] = []
    fit_volume(data, max_texture_size=4, progress=lambda f, m: seen.append(f))
    assert seen[-1] == 1.0 and len(seen) > 2
    with pytest.raises(ReadCancelled):
        fit_volume(data, max_texture_size=4, cancel=lambda: True)


def test_read_volume_fits_and_keeps_memmap_source_untouched(tmp_path):
    arr = (np.arange(2 * 20 * 24 * 24) % 200).astype(np.uint8).reshape(2, 20, 24, 24)
    np.save(tmp_path / "v.npy", arr)
    data = read_volume(tmp_path / "v.npy", max_texture_size=12, voxel_size_um=(1, 1, 2))
    assert data.array.shape == (2, 10, 12, 12)
    assert data.voxel_size_um == pytest.approx((2, 2, 4))
    assert any("downsampled by area averaging" in n for n in data.notes)
    with pytest.raises(VolumeReadError, match=r"v\.npy: the volume 24×24×20"):
        read_volume(tmp_path / "v.npy", max_texture_size=12, fit="none")
    with pytest.raises(ValueError, match="unknown fit strategy"):
        read_volume(tmp_path / "v.npy", fit="smaller")  # type: ignore[arg-type]
