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


def add_level(path: Path, level: int, channels: list[np.ndarray], *, sizes: bool = True,
              pad: int = 3) -> None:
    """Add ``ResolutionLevel level`` (the given (z, y, x) volumes, padded as Imaris pads to
    whole chunks) with ``ImageSizeX/Y/Z`` on each channel group, as Imaris writes them."""
    with h5py.File(path, "a") as f:
        for c, data in enumerate(channels):
            nz, ny, nx = data.shape
            padded = np.zeros((nz + pad, ny + pad, nx + pad), data.dtype)
            padded[:nz, :ny, :nx] = data
            group = f.create_group(f"DataSet/ResolutionLevel {level}/TimePoint 0/Channel {c}")
            group.create_dataset("Data", data=padded, chunks=(2, ny + pad, nx + pad))
            if sizes:
                for key, value in (("ImageSizeX", nx), ("ImageSizeY", ny), ("ImageSizeZ", nz)):
                    group.attrs[key] = chars(str(value))


def test_a_coarser_level_is_read_when_the_finest_does_not_fit(tmp_path):
    from vtkvol.io.imaris import read_imaris

    fine = volumes((8, 12, 16))
    coarse = [v[::2, ::2, ::2] for v in fine]
    path = write_ims(tmp_path / "pyr.ims", fine, extent_max=(8.0, 6.0, 16.0))
    add_level(path, 1, coarse)
    whole = read_imaris(path)  # the default budget holds level 0
    assert whole.metadata["level"] == 0 and whole.array.shape == (2, 8, 12, 16)
    small = read_volume(path, memory_budget_bytes=fine[0].nbytes)  # two channels do not fit
    assert small.metadata["level"] == 1 and small.array.shape == (2, 4, 6, 8)
    np.testing.assert_array_equal(small.array[1], coarse[1])
    # Extent / the level's size: 8 µm / 8 voxels in x, 6 / 6 in y, 16 / 4 in z.
    assert tuple(small.voxel_size_um) == pytest.approx((1.0, 1.0, 4.0))
    # Voxel centres at ExtMin + (i + ½)·size: level 1's first sits ½ a level-0 voxel further.
    assert small.metadata["origin_um"] == pytest.approx([0.25, 0.25, 1.0])
    assert "pyramid level 1 of 2 ('ResolutionLevel 1'" in small.notes[0]


def test_an_imaris_region_equals_direct_slicing(tmp_path):
    fine = volumes((8, 12, 16))
    path = write_ims(tmp_path / "reg.ims", fine, extent_max=(8.0, 6.0, 16.0))
    add_level(path, 1, [v[::2, ::2, ::2] for v in fine])
    # Level 0 voxel centres at 0.5·i µm (x, y) and 2·i µm (z) in pyramid space.
    vol = read_volume(path, channels=["GFP"], region_um=((1.0, 3.0), (0.5, 2.0), (2.0, 6.0)))
    assert vol.metadata["level"] == 0
    np.testing.assert_array_equal(vol.array[0], fine[1][1:4, 1:5, 2:7])
    assert vol.metadata["origin_um"] == pytest.approx([1.0, 0.5, 2.0])


def test_imaris_levels_that_lie_or_are_missing(tmp_path):
    fine = volumes((8, 12, 16))
    path = write_ims(tmp_path / "nosize.ims", fine)
    add_level(path, 1, [v[::2, ::2, ::2] for v in fine], sizes=False)
    vol = read_volume(path, memory_budget_bytes=1 << 20)
    assert vol.metadata["levels"] == [[2, 8, 12, 16]]  # the level without sizes is left out
    assert any("ResolutionLevel 1 has no ImageSizeX/Y/Z attributes" in n for n in vol.notes)

    lying = write_ims(tmp_path / "lying_level.ims", fine)
    add_level(lying, 1, [v[::4, ::4, ::4] for v in fine], pad=0)
    with h5py.File(lying, "a") as f:  # declares more voxels than the level holds
        f["DataSet/ResolutionLevel 1/TimePoint 0/Channel 0"].attrs["ImageSizeX"] = chars("9")
    with pytest.raises(VolumeReadError, match=r"ResolutionLevel 1 Channel 0 Data has shape "
                                              r"\(2, 3, 4\), smaller than"):
        read_volume(lying)

    missing = write_ims(tmp_path / "missing_level.ims", fine)
    add_level(missing, 1, [fine[0][::2, ::2, ::2]])  # channel 1 of level 1 is missing
    with pytest.raises(VolumeReadError, match=r"ResolutionLevel 1 Channel 1 has no Data"):
        read_volume(missing)
