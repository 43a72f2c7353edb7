"""Turntable movies: ``vtkvol render sample --turntable``, read back; the writers' formats and
their refusals (existing outputs, odd sizes, failures leave nothing behind)."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile

from vtkvol.cli import main
from vtkvol.movie import (
    MovieCancelled,
    even_size,
    existing_outputs,
    movie_kind,
    turntable_frames,
    write_movie,
)

imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")


def _read_mp4(path):
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(meta["size"][1], meta["size"][0], 3)
              for f in reader]
    return meta, frames


@pytest.mark.gl
def test_cli_turntable_mp4_reads_back_with_its_frames_size_and_duration(tmp_path, capsys):
    out = tmp_path / "spin.mp4"
    assert main(["render", "sample", "-o", str(out), "--size", "64", "64",
                 "--turntable", "360", "--frames", "6", "--fps", "12"]) == 0
    meta, frames = _read_mp4(out)
    assert len(frames) == 6
    assert meta["size"] == (64, 64)
    assert meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
    n, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert n == 6 and seconds == pytest.approx(0.5, abs=0.05)  # 6 frames at 12 fps
    # The view turns: every later frame differs from the first, and the frames show the sample.
    assert all(np.abs(f.astype(int) - frames[0]).mean() > 2 for f in frames[1:])
    assert all(f.max() > 50 for f in frames)
    captured = capsys.readouterr()
    assert "frame 6/6" in captured.err and "wrote" in captured.out
    assert [p.name for p in tmp_path.iterdir()] == ["spin.mp4"]  # no temporary file left

    # Never overwritten without --overwrite; checked before anything is rendered.
    before = out.stat().st_mtime_ns
    assert main(["render", "sample", "-o", str(out), "--turntable", "90", "--frames", "2"]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err
    assert out.stat().st_mtime_ns == before


@pytest.mark.gl
def test_odd_size_is_rounded_up_to_even_for_h264(tmp_path, capsys):
    out = tmp_path / "odd.mp4"
    assert main(["render", "sample", "-o", str(out), "--size", "33", "21",
                 "--turntable", "30", "--frames", "2"]) == 0
    meta, frames = _read_mp4(out)
    assert meta["size"] == (34, 22) and len(frames) == 2
    assert "even sizes" in capsys.readouterr().err


@pytest.mark.gl
def test_zero_degrees_gives_identical_frames(sample_frames):
    frames = sample_frames(degrees=0.0, n=2)
    np.testing.assert_array_equal(frames[0], frames[1])


@pytest.fixture
def sample_frames():
    from vtkvol.io import confocal_phantom

    data = confocal_phantom()

    def render(degrees: float, n: int) -> list[np.ndarray]:
        return list(turntable_frames(data, frames=n, degrees=degrees, size=(32, 32)))

    return render


def _frames(n: int = 3, h: int = 10, w: int = 12) -> list[np.ndarray]:
    return [np.full((h, w, 3), 40 * i, np.uint8) for i in range(n)]


def test_png_sequences_pattern_and_folder(tmp_path):
    written = write_movie(iter(_frames()), tmp_path / "spin.png", n_frames=3)
    assert [p.name for p in written] == ["spin_0000.png", "spin_0001.png", "spin_0002.png"]
    written = write_movie(iter(_frames()), tmp_path / "custom_%02d.png", n_frames=3)
    assert [p.name for p in written] == ["custom_00.png", "custom_01.png", "custom_02.png"]
    written = write_movie(iter(_frames()), tmp_path / "frames", n_frames=3)
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [
        "frame_0000.png", "frame_0001.png", "frame_0002.png"]
    import vtk

    reader = vtk.vtkPNGReader()
    reader.SetFileName(str(written[2]))
    reader.Update()
    assert reader.GetOutput().GetDimensions() == (12, 10, 1)
    assert reader.GetOutput().GetPointData().GetScalars().GetRange(0) == (80.0, 80.0)


def test_tiff_stack_for_fiji(tmp_path):
    out = tmp_path / "spin.tif"
    write_movie(iter(_frames(4)), out, n_frames=4, fps=10)
    with tifffile.TiffFile(out) as tif:
        assert tif.is_imagej
        stack = tif.asarray()
        assert tif.imagej_metadata["finterval"] == pytest.approx(0.1)
    assert stack.shape == (4, 10, 12, 3)
    assert stack[3].max() == 120


def test_refusals_and_nothing_left_behind(tmp_path):
    existing = tmp_path / "spin_0001.png"
    existing.write_bytes(b"keep")
    assert existing_outputs(tmp_path / "spin.png", 3) == [existing]
    with pytest.raises(FileExistsError, match=r"spin_0001\.png exists"):
        write_movie(iter(_frames()), tmp_path / "spin.png", n_frames=3)
    assert existing.read_bytes() == b"keep"
    write_movie(iter(_frames()), tmp_path / "spin.png", n_frames=3, overwrite=True)
    assert existing.read_bytes() != b"keep"

    with pytest.raises(ValueError, match="even frame sizes"):
        write_movie(iter(_frames(2, 11, 12)), tmp_path / "odd.mp4", n_frames=2)
    frames = _frames(3)
    frames[2] = np.zeros((4, 4, 3), np.uint8)
    with pytest.raises(ValueError, match="frame 2 is"):
        write_movie(iter(frames), tmp_path / "mixed.mp4", n_frames=3)
    with pytest.raises(ValueError, match="3 frames announced, 2 given"):
        write_movie(iter(_frames(2)), tmp_path / "short.tif", n_frames=3)

    def failing():
        yield _frames(1)[0]
        raise RuntimeError("render failed")

    with pytest.raises(RuntimeError):
        write_movie(failing(), tmp_path / "broken.mp4", n_frames=2)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["spin_0000.png", "spin_0001.png", "spin_0002.png"]  # no partial outputs
    with pytest.raises(ValueError, match=r"unknown movie format '\.gif'"):
        movie_kind(tmp_path / "x.gif")
    assert even_size((33, 21)) == (34, 22) and even_size((64, 64)) == (64, 64)


def test_cli_checks_movie_options_before_reading(tmp_path, capsys):
    assert main(["render", "no-such-file.tif", "-o", str(tmp_path / "a.mp4"),
                 "--turntable", "360", "--frames", "0"]) == 2
    assert "--frames must be at least 1" in capsys.readouterr().err
    assert main(["render", "no-such-file.tif", "-o", str(tmp_path / "a.gif"),
                 "--turntable", "360"]) == 2
    assert "unknown movie format" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["c.mp4", "c.tif", "c.png", "folder"])
def test_cancel_leaves_nothing(tmp_path, name):
    asked = []

    def cancel() -> bool:
        asked.append(1)
        return len(asked) > 2  # after two frames

    done = []
    with pytest.raises(MovieCancelled):
        write_movie(iter(_frames(4)), tmp_path / name, n_frames=4, cancel=cancel,
                    progress=lambda i, n: done.append((i, n)))
    assert done == [(1, 4), (2, 4)]
    left = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert left == []
