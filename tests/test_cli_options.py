"""`vtkvol render`/`batch` options that crashed, aborted or were silently ignored are refused
in one line before anything is read or rendered; an output that appears during a render is
never overwritten without --overwrite."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol import cli
from vtkvol.cli import main


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--size", "-5", "-5"], "--size W H must be whole numbers of pixels from 1 to 8192, "
                                 "got -5 -5"),
        (["--size", "0", "0"], "got 0 0"),
        (["--size", "100000", "100000"], "got 100000 100000"),
        (["--azimuth", "nan"], "--azimuth must be a finite number of degrees, got nan"),
        (["--elevation", "inf"], "--elevation must be a finite number of degrees, got inf"),
        (["--voxel-size", "1", "1", "2"], "--voxel-size does not apply to the built-in sample"),
        (["--time", "3"], "--time does not apply to the built-in sample"),
        (["--time", "-1"], "--time must be a time point index >= 0, got -1"),
    ],
)
def test_bad_render_options_are_refused_before_reading(tmp_path, capsys, monkeypatch, args,
                                                       message):
    monkeypatch.setattr(cli, "_load", lambda *a, **k: pytest.fail("read before the check"))
    out = tmp_path / "never.png"
    assert main(["render", "sample", "-o", str(out), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vtkvol: ") and message in err and "\n" not in err
    assert not out.exists()


def test_voxel_size_values_and_sessions(tmp_path, capsys):
    volume = tmp_path / "v.npy"
    np.save(volume, np.zeros((4, 4, 4), np.uint8))
    assert main(["render", str(volume), "-o", str(tmp_path / "a.png"),
                 "--voxel-size", "1", "nan", "2"]) == 2
    assert "--voxel-size X Y Z must be three positive µm values, got 1 nan 2" in \
        capsys.readouterr().err
    session = tmp_path / "view.vtkvol.json"
    session.write_text("{}")
    assert main(["render", str(session), "-o", str(tmp_path / "b.png"),
                 "--voxel-size", "1", "1", "1"]) == 2
    assert "--voxel-size does not apply to a session" in capsys.readouterr().err


def test_batch_refuses_a_bad_size_before_starting_a_cluster(tmp_path, capsys):
    assert main(["batch", "sample", "-o", str(tmp_path / "out"), "--size", "0", "10"]) == 2
    assert "--size W H must be whole numbers of pixels from 1 to 8192" in \
        capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.gl
def test_an_output_that_appears_during_the_render_is_kept(tmp_path, capsys, monkeypatch):
    out = tmp_path / "view.png"
    real = cli.__dict__.get("render_image")
    from vtkvol.engine import api

    original = api.render_image

    def render_and_meanwhile(*args, **kwargs):
        image = original(*args, **kwargs)
        out.write_bytes(b"someone else's file")  # e.g. another run with the same name
        return image

    monkeypatch.setattr(api, "render_image", render_and_meanwhile)
    assert real is None  # cmd_render imports it at call time, so the patch applies
    assert main(["render", "sample", "-o", str(out), "--size", "32", "32"]) == 2
    assert "appeared while rendering; it is left as it is" in capsys.readouterr().err
    assert out.read_bytes() == b"someone else's file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["view.png"]  # no temporary left
    # with --overwrite it is replaced, as asked
    assert main(["render", "sample", "-o", str(out), "--size", "32", "32", "--overwrite"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.gl
def test_pyvista_blend_names_render_like_ours(tmp_path):
    """--blend takes PyVista's names (maximum, minimum) for MIP and MinIP: the same image."""
    from PIL import Image

    volume = tmp_path / "v.npy"
    rng = np.random.default_rng(0)
    np.save(volume, rng.integers(0, 255, (16, 16, 16)).astype(np.uint8))
    images = {}
    for name in ("mip", "maximum", "composite"):
        out = tmp_path / f"{name}.png"
        assert main(["render", str(volume), "-o", str(out), "--size", "64", "64",
                     "--blend", name]) == 0
        images[name] = np.asarray(Image.open(out)).astype(int)
    assert np.array_equal(images["maximum"], images["mip"])
    assert np.abs(images["mip"] - images["composite"]).max() > 20  # the option took effect
    with pytest.raises(SystemExit):
        main(["render", str(volume), "-o", str(tmp_path / "x.png"), "--blend", "brightest"])
