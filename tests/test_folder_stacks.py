"""Folders that hold several stacks (issue 25 §3): listed, refused with the list, one of them or
all of them as channels; bad input (empty folder, mismatched or unreadable stacks, 10⁵ files)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest
import tifffile

from vtkvol.cli import main
from vtkvol.io import VolumeReadError, read_volume
from vtkvol.io.folder import SeveralStacksError, folder_stacks
from vtkvol.io.folder_channels import read_folder_as_channels, read_stacks_as_channels

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def _stack(path: Path, shape=(6, 10, 12), value: int = 1, spacing: float = 0.5) -> np.ndarray:
    """A small uint8 ImageJ stack with a gradient, voxel size spacing × spacing × 2 µm."""
    z, y, x = np.indices(shape)
    array = ((x + y + z) * value % 200 + 10).astype(np.uint8)
    tifffile.imwrite(path, array, imagej=True, resolution=(1 / spacing, 1 / spacing),
                     metadata={"spacing": 2.0, "unit": "um", "axes": "ZYX"})
    return array


def test_a_folder_of_stacks_is_refused_with_their_names(tmp_path):
    for name in ("nucleus.tif", "membrane.tif", "actin.tif"):
        _stack(tmp_path / name)
    with pytest.raises(SeveralStacksError) as info:
        read_volume(tmp_path)
    assert [p.name for p in info.value.stacks] == ["actin.tif", "membrane.tif", "nucleus.tif"]
    assert str(info.value) == (
        f"{tmp_path.name}: holds 3 stacks rather than the slices of one (actin.tif, "
        "membrane.tif, nucleus.tif); open one of them, or all of them as channels "
        "(--as-channels)")


def test_a_folder_of_slices_still_reads_as_one_stack(tmp_path):
    for z in range(4):
        tifffile.imwrite(tmp_path / f"slice_{z:02d}.tif", np.full((8, 9), z * 10, np.uint8))
    assert folder_stacks(tmp_path) == []
    data = read_volume(tmp_path)
    assert data.array.shape == (1, 4, 8, 9)
    assert data.array[0, :, 0, 0].tolist() == [0, 10, 20, 30]


def test_a_folder_of_one_stack_reads_that_stack(tmp_path):
    expected = _stack(tmp_path / "only.tif")
    (tmp_path / "notes.txt").write_text("not a volume")
    data = read_volume(tmp_path)
    assert data.array.shape == (1, 6, 10, 12)
    np.testing.assert_array_equal(data.array[0], expected)


def test_matching_stacks_become_the_channels_of_one_volume(tmp_path):
    a = _stack(tmp_path / "nucleus.tif", value=1)
    b = _stack(tmp_path / "membrane.tif", value=3)
    data = read_folder_as_channels(tmp_path)
    assert data.channel_names == ["membrane", "nucleus"]
    np.testing.assert_array_equal(data.array[0], b)
    np.testing.assert_array_equal(data.array[1], a)
    assert data.voxel_size_um == pytest.approx((0.5, 0.5, 2.0))
    assert data.metadata["files"] == ["membrane.tif", "nucleus.tif"]


def test_stacks_of_different_shapes_are_refused_naming_both(tmp_path):
    _stack(tmp_path / "a.tif", shape=(6, 10, 12))
    _stack(tmp_path / "b.tif", shape=(5, 10, 12))
    with pytest.raises(VolumeReadError) as info:
        read_folder_as_channels(tmp_path)
    assert str(info.value) == ("b.tif: its shape (z, y, x) (5, 10, 12) differs from a.tif's "
                               "(6, 10, 12); only stacks of one shape can be channels of one "
                               "volume")


def test_stacks_of_different_voxel_sizes_need_one_given(tmp_path):
    _stack(tmp_path / "a.tif", spacing=0.5)
    _stack(tmp_path / "b.tif", spacing=0.25)
    with pytest.raises(VolumeReadError, match=r"^b\.tif: its voxel size 0\.25 × 0\.25 × 2 µm "
                                              r"differs from a\.tif's 0\.5 × 0\.5 × 2 µm"):
        read_folder_as_channels(tmp_path)
    data = read_folder_as_channels(tmp_path, voxel_size_um=(1.0, 1.0, 2.0))
    assert data.array.shape == (2, 6, 10, 12)
    assert data.voxel_size_um == pytest.approx((1.0, 1.0, 2.0))


def test_an_unreadable_stack_is_listed_and_named_when_read(tmp_path):
    (tmp_path / "a_broken.tif").write_bytes(b"II*\x00 not a TIFF at all")
    _stack(tmp_path / "b.tif")
    _stack(tmp_path / "c.tif")
    assert [p.name for p in folder_stacks(tmp_path)] == ["a_broken.tif", "b.tif", "c.tif"]
    with pytest.raises(VolumeReadError, match=r"^a_broken\.tif: "):
        read_folder_as_channels(tmp_path)


def test_an_empty_folder_says_so(tmp_path):
    assert folder_stacks(tmp_path) == []
    with pytest.raises(VolumeReadError, match="the folder holds no file that a reader accepts"):
        read_volume(tmp_path)
    with pytest.raises(VolumeReadError) as info:
        read_folder_as_channels(tmp_path)
    assert str(info.value) == (f"{tmp_path.name}: holds the slices of one stack; reading "
                               "stacks as channels needs a folder of two or more stacks")


def test_more_stacks_than_channels_are_refused_before_reading(tmp_path):
    for i in range(5):
        _stack(tmp_path / f"s{i}.tif")
    with pytest.raises(VolumeReadError) as info:
        read_folder_as_channels(tmp_path)
    assert str(info.value) == (f"{tmp_path.name}: 5 stacks (s0.tif, s1.tif, s2.tif, s3.tif, "
                               "s4.tif) are more channels than the 4 vtkvol shows at once; "
                               "open them one at a time")


def test_a_hundred_thousand_stacks_are_listed_in_one_line_quickly(tmp_path):
    sources = [tmp_path / "stack_000000.tif", tmp_path / "stack_050000.tif"]
    for source in sources:
        _stack(source, shape=(2, 4, 4))
    for i in range(100_000):  # hard links (≤ 65000 per file): 10⁵ names, two files' bytes
        if i % 50_000:
            os.link(sources[i // 50_000], tmp_path / f"stack_{i:06d}.tif")
    start = time.perf_counter()
    with pytest.raises(SeveralStacksError) as info:
        read_volume(tmp_path)
    seconds = time.perf_counter() - start
    assert len(info.value.stacks) == 100_000
    assert str(info.value).startswith(
        f"{tmp_path.name}: holds 100000 stacks rather than the slices of one (stack_000000.tif, "
        "stack_000001.tif, stack_000002.tif, stack_000003.tif, stack_000004.tif, "
        "stack_000005.tif and 99994 more); ")
    # One listing and one TIFF header: 4–10 s on two cores at load 12; reading every
    # header (as the slice reader would) took over 10 min there.
    assert seconds < 60.0


def test_cli_open_lists_the_stacks_in_one_line(tmp_path, capsys):
    _stack(tmp_path / "a.tif")
    _stack(tmp_path / "b.tif")
    assert main(["open", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == (f"vtkvol: {tmp_path.name}: holds 2 stacks rather than the slices of one "
                   "(a.tif, b.tif); open one of them, or all of them as channels "
                   "(--as-channels)\n")


def test_cli_as_channels_reads_the_folder_and_refuses_a_file(tmp_path, capsys):
    _stack(tmp_path / "a.tif")
    _stack(tmp_path / "b.tif")
    assert main(["info", str(tmp_path), "--as-channels"]) == 0
    out = capsys.readouterr().out
    assert "format: stacks-as-channels" in out
    assert "shape: 12 × 10 × 6 voxels (x × y × z), 2 channels;" in out
    assert "  [0] a: range" in out and "  [1] b: range" in out
    assert main(["open", str(tmp_path / "a.tif"), "--as-channels"]) == 2
    err = capsys.readouterr().err
    assert err == (f"vtkvol: --as-channels needs a folder of stacks; {tmp_path / 'a.tif'} is "
                   "not a folder\n")


@pytest.mark.skipif(not SHARED.is_dir(), reason="needs ../shared/data")
def test_the_shared_data_folder_is_a_folder_of_stacks():
    with pytest.raises(SeveralStacksError) as info:
        read_volume(SHARED)
    names = [p.name for p in info.value.stacks]
    assert names == ["Bead_Image1_crop.tif", "DeconvolutionSampleVerticalGrid1AU-crop.tif",
                     "platynereis_nuclei_labels_256x256x103.tif", "psf_all_nan.tif"]
    with pytest.raises(VolumeReadError, match=r"^DeconvolutionSampleVerticalGrid1AU-crop\.tif: "
                                              r"its shape \(z, y, x\) \(21, 150, 150\) differs "
                                              r"from Bead_Image1_crop\.tif's \(41, 150, 150\)"):
        read_stacks_as_channels(info.value.stacks[:2])
