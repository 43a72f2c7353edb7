"""TIFF reading: ImageJ, OME, plain, compressed, folders, metadata, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tifffile

from vtkvol.io import ReadCancelled, VolumeReadError, read_volume
from vtkvol.io.tiff import natural_sort_key

DATA = Path(__file__).parents[1].parent / "shared" / "data"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data not available")


def _ramp(shape, dtype=np.uint16):
    return (np.arange(int(np.prod(shape))) % 4000).astype(dtype).reshape(shape)


# -- ImageJ ----------------------------------------------------------------------------------
def test_imagej_hyperstack_time_channels_and_voxel_size(tmp_path):
    a = _ramp((3, 4, 2, 16, 20))  # T Z C Y X
    path = tmp_path / "hyper.tif"
    tifffile.imwrite(
        path,
        a,
        imagej=True,
        resolution=(1 / 0.25, 1 / 0.25),
        metadata={"axes": "TZCYX", "spacing": 0.75, "unit": "micron"},
    )
    data = read_volume(path, time_index=1)
    assert data.array.shape == (2, 4, 16, 20)
    np.testing.assert_array_equal(data.array, a[1].transpose(1, 0, 2, 3))
    assert data.array.flags.c_contiguous
    assert data.voxel_size_um == pytest.approx((0.25, 0.25, 0.75))
    assert data.voxel_size_from_metadata
    md = data.metadata
    assert md["format"] == "imagej-tiff"
    assert md["axes"] == "TZCYX"
    assert md["time_points"] == 3 and md["time_index"] == 1
    assert md["bit_depth"] == 12


def test_imagej_time_index_out_of_range_names_the_count(tmp_path):
    path = tmp_path / "t.tif"
    tifffile.imwrite(path, _ramp((3, 2, 8, 8)), imagej=True, metadata={"axes": "TZYX"})
    with pytest.raises(
        VolumeReadError,
        match=r"^t\.tif: time_index 3 is out of range: the file has 3 time points \(0–2\)",
    ):
        read_volume(path, time_index=3)
    single = tmp_path / "z.tif"
    tifffile.imwrite(single, _ramp((2, 8, 8)), imagej=True)
    with pytest.raises(
        VolumeReadError,
        match=r"z\.tif: time_index 1 is out of range: the file has 1 time point \(index 0\)",
    ):
        read_volume(single, time_index=1)


def test_channel_selection_by_index_and_name(tmp_path):
    a = _ramp((3, 3, 8, 8))  # Z C Y X
    path = tmp_path / "c.tif"
    tifffile.imwrite(path, a, imagej=True, metadata={"axes": "ZCYX"})
    data = read_volume(path, channels=[2, 0])
    np.testing.assert_array_equal(data.array[0], a[:, 2])
    np.testing.assert_array_equal(data.array[1], a[:, 0])
    assert data.channel_names == ["ch2", "ch0"]
    assert read_volume(path, channels="ch1").array.shape == (1, 3, 8, 8)
    with pytest.raises(
        VolumeReadError, match=r"c\.tif: channel 5 is out of range: the file has 3 channels"
    ):
        read_volume(path, channels=[5])


def test_uncompressed_single_channel_imagej_is_memory_mapped(tmp_path, monkeypatch):
    monkeypatch.setattr("vtkvol.io.limits.COPY_MAPPED_UP_TO", 0)  # keep even small files mapped
    a = _ramp((5, 16, 16), np.uint8)
    path = tmp_path / "mm.tif"
    tifffile.imwrite(path, a, imagej=True, metadata={"axes": "ZYX"})
    data = read_volume(path)
    assert isinstance(data.array, np.memmap)
    assert data.metadata["memory_mapped"] is True
    np.testing.assert_array_equal(data.array[0], a)


def test_imagej_stack_saved_as_many_channels_is_read_as_z(tmp_path):
    path = tmp_path / "noaxes.tif"
    a = _ramp((12, 8, 8), np.uint8)
    tifffile.imwrite(path, a, imagej=True)  # tifffile declares this as 12 channels
    data = read_volume(path)
    assert data.array.shape == (1, 12, 8, 8)
    np.testing.assert_array_equal(data.array[0], a)
    assert any("declare 12 channels and no z axis" in n for n in data.notes)
    few = tmp_path / "three.tif"
    tifffile.imwrite(few, a[:3], imagej=True)
    assert read_volume(few).array.shape == (3, 1, 8, 8)


def test_time_axis_without_z_is_used_as_z(tmp_path):
    path = tmp_path / "frames.tif"
    tifffile.imwrite(path, _ramp((6, 8, 8)), imagej=True, metadata={"axes": "TYX"})
    data = read_volume(path)
    assert data.array.shape == (1, 6, 8, 8)
    assert any("no z axis: its 6 time points are used as z slices" in n for n in data.notes)


@pytest.mark.parametrize(
    ("unit", "resolution", "spacing", "expected"),
    [
        ("micron", 5.0, 0.5, (0.2, 0.2, 0.5)),
        ("\\u00B5m", 5.0, 0.5, (0.2, 0.2, 0.5)),  # what ImageJ writes for µm
        ("nm", 1 / 200, 500, (0.2, 0.2, 0.5)),
        ("mm", 5000.0, 0.0005, (0.2, 0.2, 0.5)),
    ],
)
def test_imagej_units(tmp_path, unit, resolution, spacing, expected):
    path = tmp_path / "u.tif"
    tifffile.imwrite(
        path,
        _ramp((3, 8, 8), np.uint8),
        imagej=True,
        resolution=(resolution, resolution),
        metadata={"unit": unit, "spacing": spacing},
    )
    data = read_volume(path)
    assert data.voxel_size_um == pytest.approx(expected)
    assert data.voxel_size_from_metadata


def test_voxel_size_argument_overrides_metadata(tmp_path):
    path = tmp_path / "o.tif"
    tifffile.imwrite(
        path,
        _ramp((3, 8, 8)),
        imagej=True,
        resolution=(5, 5),
        metadata={"unit": "um", "spacing": 1},
    )
    data = read_volume(path, voxel_size_um=(0.1, 0.1, 0.3))
    assert data.voxel_size_um == pytest.approx((0.1, 0.1, 0.3))
    assert not data.voxel_size_from_metadata
    assert data.metadata["voxel_size_source"] == "given by the caller"
    assert any("replaces (0.2, 0.2, 1) µm from the file" in n for n in data.notes)
    partial = read_volume(path, voxel_size_um=(None, None, 2.0))
    assert partial.voxel_size_um == pytest.approx((0.2, 0.2, 2.0))
    with pytest.raises(ValueError, match="finite and > 0"):
        read_volume(path, voxel_size_um=(0.1, -1, 0.3))


# -- OME -------------------------------------------------------------------------------------
@pytest.mark.parametrize("axes", ["TCZYX", "TZCYX", "ZTCYX", "CTZYX"])
def test_ome_any_axis_order(tmp_path, axes):
    sizes = {"T": 2, "C": 3, "Z": 4, "Y": 8, "X": 6}
    a = _ramp(tuple(sizes[ax] for ax in axes))
    path = tmp_path / "o.ome.tif"
    tifffile.imwrite(path, a, ome=True, metadata={"axes": axes})
    data = read_volume(path, time_index=1)
    expected = np.moveaxis(a, [axes.index(ax) for ax in "TCZYX"], range(5))[1]
    assert data.array.shape == (3, 4, 8, 6)
    np.testing.assert_array_equal(data.array, expected)
    assert data.metadata["format"] == "ome-tiff"


@pytest.mark.parametrize(
    ("value", "unit", "expected_um"),
    [(200, "nm", 0.2), (0.2, "µm", 0.2), (0.0002, "mm", 0.2), (2e-7, "m", 0.2), (2000, "Å", 0.2)],
)
def test_ome_physical_size_units(tmp_path, value, unit, expected_um):
    path = tmp_path / "u.ome.tif"
    tifffile.imwrite(
        path,
        _ramp((3, 2, 8, 8)),
        ome=True,
        metadata={
            "axes": "ZCYX",
            "PhysicalSizeX": value,
            "PhysicalSizeXUnit": unit,
            "PhysicalSizeY": value,
            "PhysicalSizeYUnit": unit,
            "PhysicalSizeZ": 1500,
            "PhysicalSizeZUnit": "nm",
            "Channel": {"Name": ["DAPI", "GFP"]},
        },
    )
    data = read_volume(path)
    assert data.voxel_size_um == pytest.approx((expected_um, expected_um, 1.5))
    assert data.voxel_size_from_metadata
    assert data.channel_names == ["DAPI", "GFP"]
    assert "OME PhysicalSize" in data.metadata["voxel_size_source"]


def test_ome_default_unit_is_micrometre(tmp_path):
    path = tmp_path / "d.ome.tif"
    tifffile.imwrite(
        path,
        _ramp((2, 8, 8)),
        ome=True,
        metadata={"axes": "ZYX", "PhysicalSizeX": 0.3, "PhysicalSizeY": 0.3, "PhysicalSizeZ": 2},
    )
    assert read_volume(path).voxel_size_um == pytest.approx((0.3, 0.3, 2.0))


# -- plain TIFF ------------------------------------------------------------------------------
def test_plain_multipage_tiff_and_missing_voxel_size(tmp_path):
    a = _ramp((7, 10, 12))
    path = tmp_path / "plain.tif"
    tifffile.imwrite(path, a)  # tifffile's own "shaped" metadata: axes QYX
    data = read_volume(path)
    np.testing.assert_array_equal(data.array[0], a)
    assert data.voxel_size_um == (1.0, 1.0, 1.0)
    assert not data.voxel_size_from_metadata
    assert any("voxel size not stored in the file" in n for n in data.notes)


def test_pages_without_any_metadata(tmp_path):
    path = tmp_path / "pages.tif"
    a = _ramp((4, 8, 8), np.uint8)
    with tifffile.TiffWriter(path) as tw:
        for plane in a:
            tw.write(plane, metadata=None, contiguous=False)
    data = read_volume(path)
    np.testing.assert_array_equal(data.array[0], a)


@pytest.mark.parametrize(
    ("resolution", "unit", "expected"),
    [((20000, 20000), "CENTIMETER", 0.5), ((254000, 254000), "INCH", 0.1)],
)
def test_plain_resolution_units(tmp_path, resolution, unit, expected):
    path = tmp_path / "r.tif"
    tifffile.imwrite(path, _ramp((1, 8, 8)), resolution=resolution, resolutionunit=unit)
    data = read_volume(path)
    assert data.voxel_size_um.x == pytest.approx(expected)
    assert data.voxel_size_um.y == pytest.approx(expected)
    assert data.voxel_size_from_metadata  # a single slice needs no z spacing


def test_default_dpi_is_not_a_pixel_size(tmp_path):
    path = tmp_path / "dpi.tif"
    tifffile.imwrite(path, _ramp((5, 8, 8)), resolution=(72, 72), resolutionunit="INCH")
    data = read_volume(path)
    assert data.voxel_size_um == (1.0, 1.0, 1.0)
    assert any("72 dpi ignored" in n for n in data.notes)


def test_xy_known_z_assumed_with_note(tmp_path):
    path = tmp_path / "xy.tif"
    tifffile.imwrite(path, _ramp((5, 8, 8)), resolution=(20000, 20000), resolutionunit="CENTIMETER")
    data = read_volume(path)
    assert data.voxel_size_um == pytest.approx((0.5, 0.5, 0.5))
    assert not data.voxel_size_from_metadata
    assert any("z spacing not stored in the file: assumed equal to x" in n for n in data.notes)


def test_shaped_tiff_with_axes_metadata(tmp_path):
    a = _ramp((2, 3, 8, 8))
    path = tmp_path / "czyx.tif"
    tifffile.imwrite(path, a, photometric="minisblack", metadata={"axes": "CZYX"})
    data = read_volume(path)
    np.testing.assert_array_equal(data.array, a)


def test_rgb_tiff_gives_three_named_channels(tmp_path):
    a = _ramp((4, 8, 8, 3), np.uint8)
    path = tmp_path / "rgb.tif"
    tifffile.imwrite(path, a, photometric="rgb")
    data = read_volume(path)
    assert data.channel_names == ["red", "green", "blue"]
    np.testing.assert_array_equal(data.array, np.moveaxis(a, -1, 0))


@pytest.mark.parametrize("compression", ["zlib", "lzw", "zstd", "packbits"])
def test_compressed_pages(tmp_path, compression):
    a = _ramp((2, 5, 2, 16, 16))  # T Z C Y X
    path = tmp_path / f"{compression}.tif"
    tifffile.imwrite(path, a, compression=compression, metadata={"axes": "TZCYX"})
    calls: list[float] = []
    data = read_volume(path, time_index=1, channels=[1], progress=lambda f, m: calls.append(f))
    np.testing.assert_array_equal(data.array[0], a[1, :, 1])
    assert data.metadata["compression"] != "none"
    assert data.metadata["memory_mapped"] is False
    assert calls and calls[-1] == 1.0


def test_big_endian_tiff(tmp_path):
    a = _ramp((3, 8, 8))
    path = tmp_path / "be.tif"
    tifffile.imwrite(path, a, byteorder=">", imagej=True, metadata={"axes": "ZYX"})
    data = read_volume(path)
    assert data.array.dtype == np.dtype("=u2")
    np.testing.assert_array_equal(data.array[0], a)


def test_tiff_declared_bit_depth_and_12_bit_detection(tmp_path):
    path = tmp_path / "twelve.tif"
    a = _ramp((5, 8, 8))
    a[0, 0, 0] = 4095
    tifffile.imwrite(path, a)
    data = read_volume(path)
    assert data.metadata["bit_depth"] == 12
    assert any("treated as 12-bit" in n for n in data.notes)


def test_float64_tiff_becomes_float32(tmp_path):
    path = tmp_path / "f64.tif"
    tifffile.imwrite(path, np.linspace(0, 1, 5 * 8 * 8).reshape(5, 8, 8))
    data = read_volume(path)
    assert data.array.dtype == np.float32
    assert any("float64 data converted to float32" in n for n in data.notes)


# -- bad TIFFs -------------------------------------------------------------------------------
def test_five_d_without_axes_is_ambiguous(tmp_path):
    path = tmp_path / "five.tif"
    tifffile.imwrite(path, np.zeros((2, 3, 4, 8, 8), np.uint8), photometric="minisblack")
    with pytest.raises(
        VolumeReadError, match=r"^five\.tif: ambiguous axes: 5-D data .* 3 unlabelled axes"
    ):
        read_volume(path)


def test_four_d_without_axes_is_ambiguous(tmp_path):
    path = tmp_path / "four.tif"
    tifffile.imwrite(path, np.zeros((2, 3, 8, 8), np.uint8), photometric="minisblack")
    with pytest.raises(VolumeReadError, match=r"four\.tif: ambiguous axes: 4-D data \(axes 'QQYX'"):
        read_volume(path)


@pytest.mark.parametrize(
    "kwargs",
    [{"imagej": True}, {}, {"compression": "zlib"}],
    ids=["imagej", "plain", "zlib"],
)
def test_truncated_tiff(tmp_path, kwargs):
    rng = np.random.default_rng(0)
    path = tmp_path / "cut.tif"
    tifffile.imwrite(path, rng.integers(0, 60000, (8, 64, 64), dtype=np.uint16), **kwargs)
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(VolumeReadError, match=r"^cut\.tif: (corrupt or )?truncated TIFF"):
        read_volume(path)


@pytest.mark.parametrize("content", [b"", b"II*\x00garbage", b"not a tiff at all"])
def test_corrupt_tiff(tmp_path, content):
    path = tmp_path / "bad.tif"
    path.write_bytes(content)
    with pytest.raises(
        VolumeReadError,
        match=r"^bad\.tif: (not a readable TIFF file|corrupt|the TIFF file contains no images)",
    ):
        read_volume(path)


def test_corrupt_compressed_strip(tmp_path):
    path = tmp_path / "strip.tif"
    a = _ramp((5, 32, 32))
    tifffile.imwrite(path, a, compression="zlib")
    with tifffile.TiffFile(path) as tif:
        offset = int(tif.pages[2].dataoffsets[0])
    raw = bytearray(path.read_bytes())
    raw[offset : offset + 16] = b"\xff" * 16
    path.write_bytes(bytes(raw))
    with pytest.raises(VolumeReadError, match=r"^strip\.tif: corrupt or truncated TIFF"):
        read_volume(path)


# -- progress and cancel ---------------------------------------------------------------------
def test_progress_and_cancel_for_a_multichannel_imagej_file(tmp_path):
    a = _ramp((40, 2, 64, 64))
    path = tmp_path / "p.tif"
    tifffile.imwrite(path, a, imagej=True, metadata={"axes": "ZCYX"})
    seen: list[tuple[float, str]] = []
    read_volume(path, progress=lambda f, m: seen.append((f, m)))
    fractions = [f for f, _ in seen]
    assert len(seen) >= 3 and fractions == sorted(fractions) and fractions[-1] == 1.0
    assert all(isinstance(m, str) and m for _, m in seen)

    calls = {"n": 0}

    def cancel() -> bool:
        calls["n"] += 1
        return calls["n"] > 2

    with pytest.raises(ReadCancelled):
        read_volume(path, cancel=cancel)
    with pytest.raises(ReadCancelled):
        read_volume(path, cancel=lambda: True)


def test_cancel_while_decoding_compressed_pages(tmp_path):
    path = tmp_path / "z.tif"
    tifffile.imwrite(path, _ramp((64, 32, 32)), compression="zlib", rowsperstrip=8)
    state = {"n": 0}

    def cancel() -> bool:
        state["n"] += 1
        return state["n"] > 1

    with pytest.raises(ReadCancelled):
        read_volume(path, cancel=cancel)


# -- folders ---------------------------------------------------------------------------------
def test_natural_sort_key():
    names = ["z10.tif", "z2.tif", "z1.tif", "Z3.tif"]
    assert sorted(names, key=natural_sort_key) == ["z1.tif", "z2.tif", "Z3.tif", "z10.tif"]


def test_folder_of_slices_in_natural_order(tmp_path):
    folder = tmp_path / "stack"
    folder.mkdir()
    for z in range(12):
        plane = np.full((6, 5), z * 10, np.uint16)
        tifffile.imwrite(
            folder / f"slice_z{z}.tif",
            plane,
            imagej=True,
            resolution=(4, 4),
            metadata={"unit": "um", "spacing": 0.5},
        )
    (folder / "notes.txt").write_text("not an image")
    (folder / ".hidden.tif").write_bytes(b"junk")
    data = read_volume(folder)
    assert data.array.shape == (1, 12, 6, 5)
    np.testing.assert_array_equal(data.array[0, :, 0, 0], np.arange(12) * 10)  # z2 before z10
    assert data.voxel_size_um == pytest.approx((0.25, 0.25, 0.5))
    assert data.metadata["format"] == "tiff-folder"
    assert data.metadata["files"] == 12


def test_folder_with_channel_tokens(tmp_path):
    for c in range(2):
        for z in range(3):
            tifffile.imwrite(
                tmp_path / f"img_c{c}_z{z}.tif", np.full((4, 4), 100 * c + z, np.uint8)
            )
    data = read_volume(tmp_path)
    assert data.array.shape == (2, 3, 4, 4)
    assert data.channel_names == ["c0", "c1"]
    np.testing.assert_array_equal(data.array[:, :, 0, 0], [[0, 1, 2], [100, 101, 102]])
    only = read_volume(tmp_path, channels=["c1"])
    np.testing.assert_array_equal(only.array[0, :, 0, 0], [100, 101, 102])
    assert any("z spacing not stored" in n or "voxel size not stored" in n for n in data.notes)


def test_folder_with_mismatched_slice(tmp_path):
    tifffile.imwrite(tmp_path / "a1.tif", np.zeros((4, 4), np.uint8))
    tifffile.imwrite(tmp_path / "a2.tif", np.zeros((4, 5), np.uint8))
    with pytest.raises(
        VolumeReadError, match=r"slice a2\.tif has shape \(4, 5\) .* all slices must match"
    ):
        read_volume(tmp_path)


def test_a_stack_among_a_folders_slices_is_rejected(tmp_path):
    """A folder of 2-D slices with one multi-page file among them is refused, naming it (a
    folder of stacks only is a different case: tests/test_folder_stacks.py)."""
    tifffile.imwrite(tmp_path / "a1.tif", np.zeros((6, 6), np.uint8), photometric="minisblack")
    tifffile.imwrite(tmp_path / "a2.tif", np.zeros((5, 6, 6), np.uint8), photometric="minisblack")
    with pytest.raises(
        VolumeReadError, match=r"a2\.tif: every file in a folder must hold one 2-D slice"
    ):
        read_volume(tmp_path)


# -- real data -------------------------------------------------------------------------------
@needs_data
def test_real_bead_image_voxel_size():
    data = read_volume(DATA / "Bead_Image1_crop.tif")
    assert data.array.shape == (1, 41, 150, 150)
    assert data.array.dtype == np.uint8
    assert data.voxel_size_um.x == pytest.approx(0.0225, abs=1e-4)
    assert data.voxel_size_um.y == pytest.approx(0.0225, abs=1e-4)
    assert data.voxel_size_um.z == pytest.approx(0.125)
    assert data.voxel_size_from_metadata
    assert data.voxel_size_um.z / data.voxel_size_um.x == pytest.approx(5.56, abs=0.01)


@needs_data
def test_real_low_dynamic_range_grid():
    data = read_volume(DATA / "DeconvolutionSampleVerticalGrid1AU-crop.tif")
    assert data.array.shape == (1, 21, 150, 150)
    lo, hi = data.channel_range(0)
    assert lo >= 1 and hi <= 8
    assert data.voxel_size_um.z == pytest.approx(0.125)


@needs_data
def test_real_int32_labels_become_uint16():
    data = read_volume(DATA / "platynereis_nuclei_labels_256x256x103.tif")
    assert data.array.shape == (1, 103, 256, 256)
    assert data.array.dtype == np.uint16
    assert data.channel_range(0) == (0.0, 37.0)
    assert any("int32 data converted to uint16" in n for n in data.notes)
    assert not any("12-bit" in n for n in data.notes)


@needs_data
def test_real_all_nan_file():
    with pytest.raises(VolumeReadError) as info:
        read_volume(DATA / "psf_all_nan.tif")
    assert str(info.value) == "psf_all_nan.tif: every voxel is NaN or infinite; nothing to display"
