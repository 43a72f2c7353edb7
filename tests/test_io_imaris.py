"""Imaris .ims reader (h5py, extra ``formats``): files written with Imaris' layout by h5py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtkvol.io import VolumeReadError, read_volume

h5py = pytest.importorskip("h5py")


def chars(text: str) -> np.ndarray:
    """Imaris stores attribute strings as arrays of single bytes."""
    return np.array([c.encode() for c in text], dtype="S1")


def write_ims(path: Path, channels: list[np.ndarray], *, extent_max=(4.0, 2.5, 12.0),
              unit: str | None = "um", names=("DAPI", "GFP"), pad: int = 2,
              times: int = 1) -> Path:
    nz, ny, nx = channels[0].shape
    with h5py.File(path, "w") as f:
        image = f.create_group("DataSetInfo/Image")
        for key, value in (("X", nx), ("Y", ny), ("Z", nz)):
            image.attrs[key] = chars(str(value))
        for axis, hi in enumerate(extent_max):
            image.attrs[f"ExtMin{axis}"] = chars("0")
            image.attrs[f"ExtMax{axis}"] = chars(repr(hi))
        if unit is not None:
            image.attrs["Unit"] = chars(unit)
        for c, name in enumerate(names[: len(channels)]):
            f.create_group(f"DataSetInfo/Channel {c}").attrs["Name"] = chars(name)
        for t in range(times):
            for c, data in enumerate(channels):
                padded = np.zeros((nz + pad, ny + pad, nx + pad), data.dtype)
                padded[:nz, :ny, :nx] = data + t
                f.create_dataset(f"DataSet/ResolutionLevel 0/TimePoint {t}/Channel {c}/Data",
                                 data=padded)
    return path


def volumes(shape=(6, 5, 8)) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 4000, shape).astype(np.uint16) for _ in range(2)]


def test_channels_names_voxel_size_and_padding(tmp_path):
    chans = volumes()
    data = read_volume(write_ims(tmp_path / "cells.ims", chans, times=3), time_index=2)
    assert data.array.shape == (2, 6, 5, 8)
    np.testing.assert_array_equal(data.array[1], chans[1] + 2)
    assert data.channel_names == ["DAPI", "GFP"]
    assert tuple(data.voxel_size_um) == pytest.approx((4.0 / 8, 2.5 / 5, 12.0 / 6))
    assert data.metadata["reader"] == "imaris" and data.metadata["time_points"] == 3
    only = read_volume(tmp_path / "cells.ims", channels=["GFP"])
    assert only.channel_names == ["GFP"] and only.array.shape[0] == 1


def test_units_and_missing_extent(tmp_path):
    nm = read_volume(write_ims(tmp_path / "nm.ims", volumes(), extent_max=(800, 500, 1200),
                               unit="nm"))
    assert tuple(nm.voxel_size_um) == pytest.approx((0.1, 0.1, 0.2))
    flat = read_volume(write_ims(tmp_path / "flat.ims", volumes(), extent_max=(0, 0, 0)))
    assert tuple(flat.voxel_size_um) == (1.0, 1.0, 1.0)
    assert any("no positive voxel size" in n for n in flat.notes)


def test_bad_imaris_files_name_the_problem(tmp_path):
    garbage = tmp_path / "garbage.ims"
    garbage.write_bytes(b"not hdf5" * 100)
    with pytest.raises(VolumeReadError, match=r"^garbage.ims: not a readable Imaris"):
        read_volume(garbage)
    other = tmp_path / "other.ims"
    with h5py.File(other, "w") as f:
        f.create_dataset("x", data=np.zeros(3))
    with pytest.raises(VolumeReadError, match="without Imaris' DataSet"):
        read_volume(other)
    path = write_ims(tmp_path / "lying.ims", volumes(), pad=0)
    with h5py.File(path, "a") as f:
        f["DataSetInfo/Image"].attrs["X"] = chars("80")  # larger than the data
    with pytest.raises(VolumeReadError, match=r"smaller than the image's \(z, y, x\)"):
        read_volume(path)
    with h5py.File(path, "a") as f:
        f["DataSetInfo/Image"].attrs["X"] = chars("eight")
    with pytest.raises(VolumeReadError, match="X = 'eight' is not a number"):
        read_volume(path)
    with pytest.raises(VolumeReadError, match="time_index 1 is out of range"):
        read_volume(write_ims(tmp_path / "one.ims", volumes()), time_index=1)
