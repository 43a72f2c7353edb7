"""OME-Zarr reader: pyramids written by the reference writer (ome-zarr) in NGFF v0.4 and v0.5."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

zarr = pytest.importorskip("zarr")
writer = pytest.importorskip("ome_zarr.writer")
ome_format = pytest.importorskip("ome_zarr.format")

from vtkvol.io import ReadCancelled, VolumeReadError, read_volume  # noqa: E402
from vtkvol.io.ome_zarr import OME_ZARR_READER, choose_level, read_ome_zarr  # noqa: E402
from vtkvol.io.registry import get_reader  # noqa: E402

WINDOW = {"start": 0, "end": 1000, "min": 0, "max": 65535}


def _write(path: Path, data: np.ndarray, axes: str, *, version: str = "0.5",
           scale: dict[str, float] | None = None, unit: str = "micrometer",
           labels: list[str] | None = None, levels: int = 3) -> Path:
    fmt = ome_format.FormatV05() if version == "0.5" else ome_format.FormatV04()
    group = zarr.open_group(str(path), mode="w", zarr_format=fmt.zarr_format)
    extra = {}
    if labels is not None:
        colors = ["0000FF", "00FF00", "FF0000"]
        extra["omero"] = {"channels": [{"label": label, "color": colors[i], "window": WINDOW}
                                       for i, label in enumerate(labels)]}
    writer.write_image(
        data, group, axes=axes, fmt=fmt, scale_factors=tuple(2 ** i for i in range(1, levels)),
        scale=scale, axes_units={a: unit for a in axes if a in "zyx"}, **extra,
    )
    return path


def _cells(c: int = 2, z: int = 16, y: int = 32, x: int = 40) -> np.ndarray:
    rng = np.random.default_rng(1)
    return rng.integers(0, 4000, size=(c, z, y, x), dtype=np.uint16)


@pytest.mark.parametrize("version", ["0.4", "0.5"])
def test_reads_shape_voxel_size_channels_from_either_version(tmp_path, version):
    data = _cells()
    path = _write(tmp_path / "cells.zarr", data, "czyx", version=version,
                  scale={"c": 1.0, "z": 0.5, "y": 0.2, "x": 0.2}, labels=["DAPI", "GFP"])
    assert get_reader(path) is OME_ZARR_READER  # the folder is recognised by its zarr metadata
    vol = read_volume(path)
    assert vol.array.shape == (2, 16, 32, 40)
    np.testing.assert_array_equal(vol.array, data)
    assert vol.voxel_size_um == pytest.approx((0.2, 0.2, 0.5))
    assert vol.voxel_size_from_metadata
    assert vol.channel_names == ["DAPI", "GFP"]
    assert vol.metadata["channel_colors"] == [(0.0, 0.0, 1.0), (0.0, 1.0, 0.0)]
    assert vol.metadata["format"] == f"ome-zarr {version}"
    assert vol.metadata["level"] == 0
    assert any("pyramid level 0 of 3" in note for note in vol.notes)


def test_metadata_file_itself_opens_the_image(tmp_path):
    path = _write(tmp_path / "a.zarr", _cells(1), "czyx", labels=["only"])
    vol = read_volume(path / "zarr.json")
    assert vol.channel_names == ["only"]


def test_units_are_converted_to_micrometres(tmp_path):
    path = _write(tmp_path / "em.zarr", _cells(1, 8, 16, 16)[0], "zyx", version="0.4",
                  scale={"z": 40.0, "y": 8.0, "x": 8.0}, unit="nanometer")
    vol = read_volume(path)
    assert vol.voxel_size_um == pytest.approx((0.008, 0.008, 0.04))


def test_budget_picks_a_coarser_level_and_never_reads_the_finer_one(tmp_path):
    data = _cells()
    path = _write(tmp_path / "big.zarr", data, "czyx",
                  scale={"c": 1.0, "z": 0.5, "y": 0.2, "x": 0.2}, labels=["DAPI", "GFP"])
    # Corrupt every chunk of level 0: a read of it would fail, so success proves it was skipped.
    for chunk in (path / "s0").rglob("*"):
        if chunk.is_file() and chunk.name != "zarr.json":
            chunk.write_bytes(b"\x00garbage")
    level0_bytes = data.nbytes
    vol = read_ome_zarr(path, memory_budget_bytes=level0_bytes // 2)
    assert vol.metadata["level"] == 1
    assert vol.array.shape == (2, 16, 16, 20)
    assert vol.voxel_size_um == pytest.approx((0.4, 0.4, 0.5))
    assert vol.array.nbytes <= level0_bytes // 2
    assert "pyramid level 1 of 3" in vol.notes[0] and "budget" in vol.notes[0]
    # Choosing one channel halves the bytes: level 0 would now fit, and its damage shows.
    with pytest.raises(VolumeReadError, match=r"^big\.zarr: level 's0' cannot be read"):
        read_ome_zarr(path, memory_budget_bytes=level0_bytes // 2, channels=["GFP"])


def test_texture_limit_also_picks_a_coarser_level(tmp_path):
    path = _write(tmp_path / "wide.zarr", _cells(1, 4, 32, 64)[0], "zyx")
    vol = read_ome_zarr(path, max_texture_size=32)
    assert vol.array.shape == (1, 4, 16, 32)
    assert "texture size 32" in vol.notes[0]


def test_choose_level_order_and_failure():
    shapes = [(1, 64, 64, 64), (1, 64, 32, 32), (1, 64, 16, 16)]
    assert choose_level(shapes, 2, 64 ** 3 * 2, None)[0] == 0
    assert choose_level(shapes, 2, 64 * 32 * 32 * 2, None)[0] == 1
    index, reason = choose_level(shapes, 2, 100, None)
    assert index == -1 and "coarsest" in reason


def test_time_axis(tmp_path):
    data = np.stack([np.full((2, 4, 8, 8), t * 10 + 1, np.uint16) for t in range(3)])
    data[:, 1] += 5  # channel 1 differs from channel 0
    path = _write(tmp_path / "t.zarr", data, "tczyx", levels=1)
    vol = read_volume(path, time_index=2, channels=[1])
    assert vol.metadata["time_points"] == 3
    assert np.all(vol.array == 26)
    with pytest.raises(VolumeReadError, match=r"^t\.zarr: time_index 3 is out of range: the image "
                                              r"has 3 time point"):
        read_volume(path, time_index=3)


def _one_line(exc: pytest.ExceptionInfo, name: str) -> str:
    text = str(exc.value)
    assert "\n" not in text and text.startswith(f"{name}: ")
    return text


def test_missing_level_is_named(tmp_path):
    path = _write(tmp_path / "cut.zarr", _cells(1), "czyx")
    shutil.rmtree(path / "s1")
    with pytest.raises(VolumeReadError) as exc:
        read_volume(path)
    assert "pyramid level 's1' named in the metadata is missing" in _one_line(exc, "cut.zarr")


def test_truncated_chunk_is_an_error_not_zeros(tmp_path):
    path = _write(tmp_path / "trunc.zarr", _cells(1), "czyx", levels=1)
    chunks = [p for p in (path / "s0").rglob("*") if p.is_file() and p.name != "zarr.json"]
    assert chunks
    for chunk in chunks:
        chunk.write_bytes(chunk.read_bytes()[:10])
    with pytest.raises(VolumeReadError) as exc:
        read_volume(path)
    assert "truncated or corrupt" in _one_line(exc, "trunc.zarr")


def test_wrong_metadata(tmp_path):
    plain = tmp_path / "plain.zarr"
    zarr.open_group(str(plain), mode="w").create_array("0", shape=(4, 4), dtype="uint8")
    with pytest.raises(VolumeReadError) as exc:
        read_volume(plain)
    assert "without OME-Zarr 'multiscales' metadata" in _one_line(exc, "plain.zarr")

    plate = tmp_path / "plate.zarr"
    zarr.open_group(str(plate), mode="w").attrs["ome"] = {"version": "0.5", "plate": {}}
    with pytest.raises(VolumeReadError) as exc:
        read_volume(plate)
    assert "high-content-screening plate" in _one_line(exc, "plate.zarr")

    path = _write(tmp_path / "axes.zarr", _cells(1), "czyx", version="0.5", levels=1)
    meta = json.loads((path / "zarr.json").read_text())
    meta["attributes"]["ome"]["multiscales"][0]["axes"].pop(0)  # 3 axes for 4-D arrays
    (path / "zarr.json").write_text(json.dumps(meta))
    with pytest.raises(VolumeReadError) as exc:
        read_volume(path)
    assert "do not match the 4-D arrays" in _one_line(exc, "axes.zarr")

    meta["attributes"]["ome"]["multiscales"][0]["datasets"] = []
    (path / "zarr.json").write_text(json.dumps(meta))
    with pytest.raises(VolumeReadError, match="'datasets' list is missing, empty"):
        read_volume(path)

    not_zarr = tmp_path / "empty.zarr"
    not_zarr.mkdir()
    (not_zarr / ".zattrs").write_text("{not json")
    with pytest.raises(VolumeReadError) as exc:
        read_volume(not_zarr)
    _one_line(exc, "empty.zarr")


def test_no_level_fits_the_budget(tmp_path):
    path = _write(tmp_path / "huge.zarr", _cells(1), "czyx")
    with pytest.raises(VolumeReadError, match=r"no pyramid level fits: even the coarsest"):
        read_ome_zarr(path, memory_budget_bytes=16)


def test_cancel_stops_the_read(tmp_path):
    path = _write(tmp_path / "c.zarr", _cells(), "czyx", levels=1)
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 3  # after the header, during the chunk reads

    with pytest.raises(ReadCancelled):
        read_volume(path, cancel=cancel)


def test_bioformats2raw_layout_reads_image_0(tmp_path):
    root = tmp_path / "converted.zarr"
    group = zarr.open_group(str(root), mode="w", zarr_format=3)
    group.attrs["ome"] = {"version": "0.5", "bioformats2raw.layout": 3}
    _write(root / "0", _cells(1, 4, 8, 8), "czyx", labels=["nuclei"], levels=1)
    vol = read_volume(root)
    assert vol.channel_names == ["nuclei"] and vol.array.shape == (1, 4, 8, 8)
    assert "bioformats2raw layout: image 0 read" in vol.notes


# -- regions and levels (vtkvol.io.pyramid) --------------------------------------------------
def _ball(z: int = 16, y: int = 48, x: int = 64) -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.integers(0, 60000, size=(z, y, x), dtype=np.uint16)


def test_region_at_the_finest_level_equals_direct_slicing(tmp_path):
    data = _ball()
    path = _write(tmp_path / "r.zarr", data[None], "czyx", scale={"c": 1.0, "z": 2.0, "y": 0.5,
                                                                   "x": 0.25})
    # x 3.1…9.0 µm at 0.25 µm: voxel centres 13…36; y 1.0…4.2 at 0.5: 2…8; z 4…20 at 2: 2…10.
    region = ((3.1, 9.0), (1.0, 4.2), (4.0, 20.0))
    vol = read_volume(path, level=0, region_um=region)
    np.testing.assert_array_equal(vol.array[0], data[2:11, 2:9, 13:37])
    assert vol.voxel_size_um == pytest.approx((0.25, 0.5, 2.0))
    assert vol.metadata["origin_um"] == pytest.approx([13 * 0.25, 2 * 0.5, 2 * 2.0])
    assert vol.metadata["region_voxels"] == [[13, 37], [2, 9], [2, 11]]
    assert vol.metadata["region_um"] == [pytest.approx([3.25, 9.0]), pytest.approx([1.0, 4.0]),
                                         pytest.approx([4.0, 20.0])]
    assert "region x 3.25…9 × y 1…4 × z 4…20 µm" in vol.notes[0]


def test_region_chooses_the_finest_level_where_it_fits(tmp_path):
    data = _ball()
    path = _write(tmp_path / "fit.zarr", data[None], "czyx", scale={"c": 1.0, "z": 1.0, "y": 1.0,
                                                                     "x": 1.0})
    whole = read_ome_zarr(path, memory_budget_bytes=data.nbytes // 4)
    assert whole.metadata["level"] == 1  # the whole image fits only from level 1
    # A quarter of the image fits at level 0 within the same budget, and equals level 0's voxels.
    region = ((0.0, 31.0), (0.0, 23.0), (0.0, 15.0))
    part = read_ome_zarr(path, memory_budget_bytes=data.nbytes // 4, region_um=region)
    assert part.metadata["level"] == 0
    np.testing.assert_array_equal(part.array[0], data[:, :24, :32])
    assert part.array.nbytes <= data.nbytes // 4
    # Refining a region read from level 1 in its own µm (voxel centres of level 1 at
    # 0.5 + 2·i µm: ome-zarr's writer shifts coarser levels by half a voxel) gives level 0.
    assert whole.metadata["origin_um"] == pytest.approx([0.5, 0.5, 0.0])


def test_region_thinner_than_a_voxel_keeps_the_nearest(tmp_path):
    data = _ball(4, 8, 8)
    path = _write(tmp_path / "thin.zarr", data[None], "czyx", levels=1)
    vol = read_ome_zarr(path, region_um=((2.4, 2.45), (0.0, 7.0), (0.0, 3.0)))
    np.testing.assert_array_equal(vol.array[0], data[:, :, 2:3])


def test_bad_regions_and_levels(tmp_path):
    path = _write(tmp_path / "bad.zarr", _cells(1), "czyx")
    with pytest.raises(VolumeReadError) as exc:
        read_volume(path, region_um=((100.0, 200.0), (0.0, 5.0), (0.0, 5.0)))
    assert "the region x = 100…200 µm lies outside the data (0…39 µm)" in _one_line(
        exc, "bad.zarr")
    with pytest.raises(ValueError, match="finite"):
        read_volume(path, region_um=((float("nan"), 2.0), (0.0, 5.0), (0.0, 5.0)))
    with pytest.raises(ValueError, match="low end above its high end"):
        read_volume(path, region_um=((5.0, 2.0), (0.0, 5.0), (0.0, 5.0)))
    with pytest.raises(ValueError, match=r"needs three finite \(low, high\) pairs"):
        read_volume(path, region_um=((0.0, 2.0),))
    with pytest.raises(ValueError, match=r"is not \(\(x0, x1\)"):
        read_volume(path, region_um="everything")
    with pytest.raises(VolumeReadError, match=r"level 7 is out of range: the pyramid has 3"):
        read_volume(path, level=7)
    with pytest.raises(VolumeReadError, match=r"no level fits the region: even the coarsest"):
        read_ome_zarr(path, memory_budget_bytes=4, region_um=((0.0, 39.0), (0.0, 31.0),
                                                              (0.0, 15.0)))
    npy = tmp_path / "plain.npy"
    np.save(npy, np.zeros((4, 4, 4), np.uint8))
    with pytest.raises(VolumeReadError, match=r"^plain\.npy: is not a multiscale image"):
        read_volume(npy, level=0)


def test_truncated_chunk_inside_a_region_is_an_error(tmp_path):
    path = _write(tmp_path / "cut.zarr", _cells(1), "czyx", levels=2)
    chunks = [p for p in (path / "s0").rglob("*") if p.is_file() and p.name != "zarr.json"]
    for chunk in chunks:
        chunk.write_bytes(chunk.read_bytes()[:7])
    with pytest.raises(VolumeReadError) as exc:
        read_volume(path, level=0, region_um=((0.0, 5.0), (0.0, 5.0), (0.0, 3.0)))
    assert "level 's0' cannot be read: the chunks are truncated or corrupt" in _one_line(
        exc, "cut.zarr")
    # The coarser level is intact and still reads.
    assert read_volume(path, level=1).array.shape == (1, 16, 16, 20)


def test_parse_bytes():
    from vtkvol.io.pyramid import parse_bytes

    assert parse_bytes("1GiB") == 1 << 30
    assert parse_bytes("512 MiB") == 512 << 20
    assert parse_bytes("1.5G") == 3 << 29
    assert parse_bytes("800MB") == 800 * 10 ** 6
    assert parse_bytes(4096) == 4096
    for bad in ("lots", "-1GiB", "0", "1 parsec", "nanGiB", "infGiB"):
        with pytest.raises(ValueError):
            parse_bytes(bad)


def test_small_blocks_on_chunk_boundaries_give_the_same_voxels(tmp_path, monkeypatch):
    """With a tiny block size every read is split into z-slabs and y-strips; the voxels are
    the same, and no chunk is read twice (the slices start on chunk boundaries)."""
    import vtkvol.io.pyramid as pyramid_module

    data = _ball(20, 48, 40)
    group = zarr.open_group(str(tmp_path / "blocks.zarr"), mode="w", zarr_format=3)
    writer.write_image(data[None], group, axes="czyx", fmt=ome_format.FormatV05(),
                       scale_factors=(2,), storage_options={"chunks": (1, 4, 8, 16)})
    monkeypatch.setattr(pyramid_module, "SLAB_BYTES", 1000)
    reads: list[tuple[int, int, int, int]] = []
    from vtkvol.io.ome_zarr import ZarrPyramid

    original = ZarrPyramid.read_block

    def counting(self, level, channel, z, y, x):
        reads.append((z.start, z.stop, y.start, y.stop))
        return original(self, level, channel, z, y, x)

    monkeypatch.setattr(ZarrPyramid, "read_block", counting)
    vol = read_ome_zarr(tmp_path / "blocks.zarr", level=0,
                        region_um=((3.0, 30.0), (5.0, 41.0), (2.0, 17.0)))
    np.testing.assert_array_equal(vol.array[0], data[2:18, 5:42, 3:31])
    assert len(reads) > 10
    inner_z = {e for z0, z1, _, _ in reads for e in (z0, z1)} - {2, 18}
    inner_y = {e for _, _, y0, y1 in reads for e in (y0, y1)} - {5, 42}
    assert inner_z and all(e % 4 == 0 for e in inner_z)
    assert inner_y and all(e % 8 == 0 for e in inner_y)


def test_a_level_as_a_lazy_dask_array(tmp_path):
    pytest.importorskip("dask")
    from vtkvol.io.ome_zarr import open_ome_zarr

    data = _cells()
    path = _write(tmp_path / "lazy.zarr", data, "czyx", labels=["DAPI", "GFP"])
    pyramid = open_ome_zarr(path, channels=["GFP"])
    lazy = pyramid.to_dask(1, (1, 4, 8, 8))
    assert lazy.shape == (1, 16, 16, 20) and lazy.chunks[1] == (4, 4, 4, 4)
    np.testing.assert_array_equal(lazy.compute(), read_ome_zarr(path, level=1,
                                                                channels=["GFP"]).array)
    np.testing.assert_array_equal(pyramid.to_dask(0)[0, 3:9, 5:20, 7].compute(),
                                  data[1, 3:9, 5:20, 7])
