"""The ``vtkvol`` command: render, info and their error handling (GL, real data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

from vtkvol.cli import main

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BEAD = DATA / "Bead_Image1_crop.tif"
needs_data = pytest.mark.skipif(not BEAD.exists(), reason="../shared/data not present")
BACKGROUND = np.array([0.08, 0.08, 0.1]) * 255


def foreground(path: Path) -> np.ndarray:
    img = np.asarray(Image.open(path).convert("RGB"), dtype=float)
    return np.clip(img - BACKGROUND, 0, None).sum(axis=2)


@pytest.mark.gl
def test_render_sample_writes_a_png_with_content(tmp_path):
    out = tmp_path / "sample.png"
    assert main(["render", "sample", "-o", str(out), "--size", "160", "120"]) == 0
    fg = foreground(out)
    assert fg.shape == (120, 160)
    assert (fg > 30).mean() > 0.05  # the phantom fills a good part of the view


@pytest.mark.gl
def test_render_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "keep.png"
    out.write_bytes(b"user data")
    assert main(["render", "sample", "-o", str(out), "--size", "64", "64"]) == 2
    assert out.read_bytes() == b"user data"
    assert "exists" in capsys.readouterr().err


def largest_blob_aspect(fg: np.ndarray) -> float:
    labels, n = ndimage.label(fg > 0.3 * fg.max())
    sizes = ndimage.sum(np.ones_like(fg), labels, range(1, n + 1))
    rows, cols = ndimage.find_objects(labels)[int(np.argmax(sizes))]
    return (rows.stop - rows.start) / (cols.stop - cols.start)


@needs_data
@pytest.mark.gl
def test_bead_render_has_the_right_anisotropy(tmp_path):
    """Beads are point sources: their image (the PSF) is elongated along z by the optics, and
    z voxels are 5.6× the xy voxels. With the true voxel size the brightest bead is tall; with
    isotropic voxels forced it is squashed by the same factor."""
    true = tmp_path / "bead.png"
    flat = tmp_path / "bead_iso.png"
    common = ["--size", "240", "240", "--blend", "mip", "--azimuth", "0", "--elevation", "0"]
    assert main(["render", str(BEAD), "-o", str(true), *common]) == 0
    assert main(["render", str(BEAD), "-o", str(flat), *common,
                 "--voxel-size", "0.0225", "0.0225", "0.0225"]) == 0
    tall, squashed = largest_blob_aspect(foreground(true)), largest_blob_aspect(foreground(flat))
    assert tall > 1.8
    assert tall / squashed == pytest.approx(5.56, rel=0.35)


@needs_data
def test_info_reports_voxel_size_and_anisotropy(capsys):
    assert main(["info", str(BEAD)]) == 0
    out = capsys.readouterr().out
    assert "0.125 µm" in out and "anisotropy 5.56" in out and "uint8" in out


@needs_data
def test_all_nan_file_is_a_clear_error_not_a_traceback(capsys, tmp_path):
    assert main(["info", str(DATA / "psf_all_nan.tif")]) == 1
    err = capsys.readouterr().err
    assert "psf_all_nan.tif" in err and "NaN" in err and "Traceback" not in err
    out = tmp_path / "nan.png"
    assert main(["render", str(DATA / "psf_all_nan.tif"), "-o", str(out)]) == 1
    assert not out.exists()


def test_missing_file_and_bad_param(capsys, tmp_path):
    assert main(["info", str(tmp_path / "nope.tif")]) == 1
    assert "nope.tif" in capsys.readouterr().err
    assert main(["render", "sample", "-o", str(tmp_path / "x.png"), "--param", "novalue"]) == 2
    assert "NAME=VALUE" in capsys.readouterr().err


def test_render_with_a_failing_method_says_so_in_one_line_and_writes_local_shading(
        tmp_path, capsys):
    from tests_support_techniques import BROKEN_SPEC

    from vtkvol.model.techniques import register

    out = tmp_path / "broken.png"
    with register(BROKEN_SPEC):
        assert main(["render", "sample", "-o", str(out), "--size", "64", "64",
                     "--method", BROKEN_SPEC.name]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["vtkvol: The 'Broken' illumination could not be compiled by this OpenGL "
                   "driver (the driver's message is in the log); showing local shading instead."]
    assert out.is_file() and out.stat().st_size > 100


def test_bench_needs_an_output_folder_and_readable_data(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "--quick"])
    assert exit_info.value.code == 2 and "--output" in capsys.readouterr().err
    a_file = tmp_path / "results.txt"
    a_file.write_text("keep me")
    assert main(["bench", "-o", str(a_file)]) == 1
    assert "is a file, not a folder" in capsys.readouterr().err
    assert a_file.read_text() == "keep me"
    assert main(["bench", "-o", str(tmp_path / "out"), "--data", str(tmp_path / "nope.tif")]) == 1
    err = capsys.readouterr().err
    assert "--data" in err and "nope.tif: no such file" in err
    bad = tmp_path / "bad.tif"
    bad.write_bytes(b"not a tiff at all")
    assert main(["bench", "-o", str(tmp_path / "out"), "--data", str(bad)]) == 1
    assert capsys.readouterr().err.startswith("vtkvol: bad.tif: ")
    assert not (tmp_path / "out" / "benchmarks.json").exists()


@pytest.mark.gl
def test_render_of_a_session_shows_its_time_point_unless_time_is_given(tmp_path):
    """A session saved at time point 3 renders time point 3; ``--time 0`` renders point 0.
    The ball of the time-lapse moves one voxel along x per point, so the images differ."""
    from tests_support_time import write_time_lapse

    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.session import save_session

    lapse = tmp_path / "lapse.tif"
    write_time_lapse(lapse, 4)
    data3 = read_volume(lapse, time_index=3)
    model = scene_for(data3)
    model.volume.time_index = 3
    session = save_session(tmp_path / "view", model, data=data3)

    def render(name: str, *extra: str) -> np.ndarray:
        out = tmp_path / name
        assert main(["render", str(session), "-o", str(out), "--size", "96", "64", *extra]) == 0
        return foreground(out)

    saved, at3, at0 = render("saved.png"), render("t3.png", "--time", "3"), render(
        "t0.png", "--time", "0")
    assert np.array_equal(saved, at3)
    assert np.abs(saved - at0).max() > 30
