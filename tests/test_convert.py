"""``vtkvol convert``: an OME-Zarr pyramid from a TIFF (or any readable volume) through
ome-zarr-py's writer, written lazily and atomically; bad input and full disks."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import numpy as np
import pytest
import tifffile

pytest.importorskip("zarr")
pytest.importorskip("ome_zarr.writer")
pytest.importorskip("dask")

from vtkvol.cli import main
from vtkvol.io import VolumeReadError, read_volume
from vtkvol.io.convert import ConvertError, convert_to_ome_zarr, plan_levels
from vtkvol.io.ome_zarr import open_ome_zarr


def write_stack(path: Path, *, z: int = 24, y: int = 40, x: int = 64,
                compression: str | None = None) -> np.ndarray:
    """A 2-channel ImageJ hyperstack, ZCYX on disk, 0.25 × 0.25 × 1.5 µm, named channels."""
    rng = np.random.default_rng(7)
    data = rng.integers(0, 4000, size=(z, 2, y, x), dtype=np.uint16)
    tifffile.imwrite(path, data, imagej=True, resolution=(4.0, 4.0), compression=compression,
                     metadata={"axes": "ZCYX", "spacing": 1.5, "unit": "um",
                               "Labels": ["DAPI", "GFP"] * z})
    return data.transpose(1, 0, 2, 3)


@pytest.mark.parametrize("compression", [None, "zlib"])
def test_round_trip_shape_voxel_size_names_levels(tmp_path, compression, monkeypatch):
    import vtkvol.io.convert as convert

    monkeypatch.setattr(convert, "COARSEST_SIDE", 16)  # small data, several levels
    czyx = write_stack(tmp_path / "cells.tif", compression=compression)
    names = read_volume(tmp_path / "cells.tif").channel_names
    seen: list[float] = []
    result = convert_to_ome_zarr(tmp_path / "cells.tif", tmp_path / "cells.ome.zarr",
                                 progress=lambda f, m: seen.append(f))
    assert result.levels[0] == (2, 24, 40, 64)
    # x and y halve each level; z (1.5 µm) only once x's voxel is as coarse (2 µm, level 4).
    assert result.levels[1:] == [(2, 24, 20, 32), (2, 24, 10, 16), (2, 24, 5, 8), (2, 12, 2, 4)]
    assert seen[-1] == 1.0
    pyramid = open_ome_zarr(tmp_path / "cells.ome.zarr")
    assert [lv.shape_czyx for lv in pyramid.levels] == result.levels
    assert pyramid.channel_names == names
    assert tuple(pyramid.levels[0].voxel_size_um) == pytest.approx((0.25, 0.25, 1.5))
    assert tuple(pyramid.levels[2].voxel_size_um) == pytest.approx((1.0, 1.0, 1.5))
    # The writer states each level's scale from its real shape: 40 → 2 voxels is 20× in y.
    assert tuple(pyramid.levels[4].voxel_size_um) == pytest.approx((4.0, 5.0, 3.0))
    vol = read_volume(tmp_path / "cells.ome.zarr", level=0)
    np.testing.assert_array_equal(vol.array, czyx)
    meta = json.loads((tmp_path / "cells.ome.zarr" / "zarr.json").read_text())
    assert meta["attributes"]["ome"]["version"] == "0.5"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial left


def test_ngff_04_and_other_formats(tmp_path):
    data = np.arange(6 * 20 * 30, dtype=np.uint16).reshape(6, 20, 30)
    np.save(tmp_path / "v.npy", data)
    convert_to_ome_zarr(tmp_path / "v.npy", tmp_path / "v.zarr", version="0.4",
                        voxel_size_um=(0.5, 0.5, 2.0))
    assert (tmp_path / "v.zarr" / ".zattrs").exists()
    vol = read_volume(tmp_path / "v.zarr", level=0)
    np.testing.assert_array_equal(vol.array[0], data)
    assert tuple(vol.voxel_size_um) == pytest.approx((0.5, 0.5, 2.0))
    # A pyramid converts from its finest level, lazily (here: back to 0.5).
    again = convert_to_ome_zarr(tmp_path / "v.zarr", tmp_path / "w.zarr")
    np.testing.assert_array_equal(read_volume(tmp_path / "w.zarr", level=0).array[0], data)
    assert again.voxel_size_um == pytest.approx((0.5, 0.5, 2.0))


def test_plan_levels_stops_at_the_coarsest_side():
    assert plan_levels((1, 512, 2048, 2048), (0.2, 0.2, 0.2)) == [
        {"z": 2, "y": 2, "x": 2}, {"z": 4, "y": 4, "x": 4}, {"z": 8, "y": 8, "x": 8}]
    assert plan_levels((1, 10, 200, 200), (1.0, 1.0, 1.0)) == []


def test_existing_output_is_refused_and_overwrite_replaces_it(tmp_path):
    write_stack(tmp_path / "a.tif", z=4, y=8, x=8)
    out = tmp_path / "a.zarr"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(ConvertError, match=r"a\.zarr exists; pass --overwrite"):
        convert_to_ome_zarr(tmp_path / "a.tif", out)
    assert (out / "keep.txt").read_text() == "mine"
    assert main(["convert", str(tmp_path / "a.tif"), str(out)]) == 2
    convert_to_ome_zarr(tmp_path / "a.tif", out, overwrite=True)
    assert not (out / "keep.txt").exists() and (out / "zarr.json").exists()
    plain = tmp_path / "file.zarr"
    plain.write_text("not a folder")
    with pytest.raises(ConvertError, match="is a file, not an OME-Zarr folder"):
        convert_to_ome_zarr(tmp_path / "a.tif", plain, overwrite=True)


def test_unreadable_input(tmp_path, capsys):
    bad = tmp_path / "broken.tif"
    bad.write_bytes(b"II*\x00 this is not a TIFF at all")
    with pytest.raises(VolumeReadError, match=r"^broken\.tif: "):
        convert_to_ome_zarr(bad, tmp_path / "o.zarr")
    assert main(["convert", str(tmp_path / "nothing.tif"), str(tmp_path / "o.zarr")]) == 1
    assert "no such file" in capsys.readouterr().err
    assert not (tmp_path / "o.zarr").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_full_disk_leaves_nothing_and_keeps_the_old_output(tmp_path, monkeypatch):
    import ome_zarr.writer

    write_stack(tmp_path / "a.tif", z=4, y=8, x=8)
    out = tmp_path / "a.zarr"
    convert_to_ome_zarr(tmp_path / "a.tif", out)
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    real = ome_zarr.writer.write_image

    def write_until_full(image, group, **kwargs):
        real(image, group, **kwargs)  # files written into the temporary folder, then:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(ome_zarr.writer, "write_image", write_until_full)
    with pytest.raises(ConvertError, match=r"the disk is full \(No space left on device\); "
                                           "nothing was written"):
        convert_to_ome_zarr(tmp_path / "a.tif", out, overwrite=True)
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert main(["convert", str(tmp_path / "a.tif"), str(tmp_path / "b.zarr")]) == 1
    assert not (tmp_path / "b.zarr").exists()


def test_cli_convert_reports_and_the_output_opens(tmp_path, capsys):
    write_stack(tmp_path / "c.tif", z=4, y=8, x=8)
    assert main(["convert", str(tmp_path / "c.tif"), str(tmp_path / "c.zarr")]) == 0
    captured = capsys.readouterr()
    assert "wrote" in captured.out and "1 levels from 8×8×4 (x×y×z, 2 channels" in captured.out
    assert "writing" in captured.err  # progress on stderr
    assert main(["info", str(tmp_path / "c.zarr"), "--gpu-budget", "100"]) == 1
    assert "no pyramid level fits" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["info", str(tmp_path / "c.zarr"), "--gpu-budget", "plenty"])
    assert "is not a size" in capsys.readouterr().err


def test_gpu_budget_option_of_open_and_render():
    from vtkvol.cli import _parser

    args = _parser().parse_args(["open", "brain.ome.zarr", "--gpu-budget", "2GiB"])
    assert args.gpu_budget == 2 << 30
    args = _parser().parse_args(["render", "b.zarr", "-o", "b.png", "--gpu-budget", "512MB"])
    assert args.gpu_budget == 512 * 10 ** 6
    assert _parser().parse_args(["render", "b.zarr", "-o", "b.png"]).gpu_budget is None


def test_an_imaris_file_converts_lazily(tmp_path):
    h5py = pytest.importorskip("h5py")

    def chars(text: str) -> np.ndarray:
        return np.array([c.encode() for c in text], dtype="S1")

    rng = np.random.default_rng(2)
    vols = [rng.integers(0, 4000, (6, 20, 24)).astype(np.uint16) for _ in range(2)]
    path = tmp_path / "cells.ims"
    with h5py.File(path, "w") as f:
        image = f.create_group("DataSetInfo/Image")
        for key, value in (("X", 24), ("Y", 20), ("Z", 6)):
            image.attrs[key] = chars(str(value))
        for axis, hi in enumerate((12.0, 10.0, 6.0)):
            image.attrs[f"ExtMin{axis}"] = chars("0")
            image.attrs[f"ExtMax{axis}"] = chars(repr(hi))
        image.attrs["Unit"] = chars("um")
        for c, name in enumerate(("DAPI", "GFP")):
            f.create_group(f"DataSetInfo/Channel {c}").attrs["Name"] = chars(name)
            f.create_dataset(f"DataSet/ResolutionLevel 0/TimePoint 0/Channel {c}/Data",
                             data=np.pad(vols[c], ((0, 2), (0, 2), (0, 2))),  # padded at the end
                             chunks=(2, 8, 8))
    result = convert_to_ome_zarr(path, tmp_path / "cells.zarr")
    assert result.channel_names == ["DAPI", "GFP"]
    assert result.voxel_size_um == pytest.approx((0.5, 0.5, 1.0))
    vol = read_volume(tmp_path / "cells.zarr", level=0)
    np.testing.assert_array_equal(vol.array, np.stack(vols))
