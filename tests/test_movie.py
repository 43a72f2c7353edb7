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
    fit_turn,
    movie_kind,
    turned_camera,
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


# -- keyframe movies --------------------------------------------------------------------------
def _keyframe_doc(cameras, times, time_indices=None, **settings) -> dict:
    keys = []
    for i, (cam, t) in enumerate(zip(cameras, times, strict=True)):
        key = {"time": t, "camera": cam}
        if time_indices is not None:
            key["time_index"] = time_indices[i]
        keys.append(key)
    return {"format": "vtkvol-keyframes", "version": 1, **settings, "keyframes": keys}


def _orbit_camera(data, azimuth_deg: float, distance: float = 60.0) -> dict:
    """A camera ``azimuth_deg`` round the data's centre (z up), as keyframe JSON."""
    import math

    nz, ny, nx = data.shape_zyx
    sx, sy, sz = data.voxel_size_um
    centre = [(nx - 1) * sx / 2, (ny - 1) * sy / 2, (nz - 1) * sz / 2]
    a = math.radians(azimuth_deg)
    position = [centre[0] + distance * math.sin(a), centre[1] - distance * math.cos(a),
                centre[2] + 0.3 * distance]
    return {"position": position, "focal_point": centre, "view_up": [0, 0, 1]}


@pytest.fixture(scope="module")
def small_stack(tmp_path_factory):
    """A 16 × 32 × 32 single-time-point TIFF and its data."""
    from vtkvol.io import confocal_phantom, read_volume

    path = tmp_path_factory.mktemp("stack") / "cells.tif"
    sample = confocal_phantom((16, 32, 32), voxel_size_um=(0.5, 0.5, 1.0)).array[0]
    tifffile.imwrite(path, sample, imagej=True, resolution=(2.0, 2.0),
                     metadata={"axes": "ZYX", "spacing": 1.0, "unit": "micron"})
    return path, read_volume(path)


@pytest.fixture(scope="module")
def time_series(tmp_path_factory):
    """A 4-time-point 16 × 32 × 32 ImageJ TIFF whose content moves along x."""
    from vtkvol.io import confocal_phantom

    base = confocal_phantom((16, 32, 32), voxel_size_um=(0.5, 0.5, 1.0)).array[0]
    stack = np.stack([np.roll(base, 4 * t, axis=2) for t in range(4)])
    path = tmp_path_factory.mktemp("series") / "series.tif"
    tifffile.imwrite(path, stack, imagej=True, resolution=(2.0, 2.0),
                     metadata={"axes": "TZYX", "spacing": 1.0, "unit": "micron"})
    return path


def _reference(data, camera: dict, size=(32, 32), time_index=None, model_data=None):
    """render_image with the keyframe's camera on the scene the CLI makes for a file."""
    from vtkvol.engine.api import render_image
    from vtkvol.model.defaults import scene_for

    model = scene_for(model_data if model_data is not None else data)
    model.camera.update({k: tuple(v) for k, v in camera.items()})
    return render_image(data, model=model, size=size)


@pytest.mark.gl
def test_cli_keyframe_mp4_reads_back_with_frames_duration_and_the_orbit(tmp_path, capsys,
                                                                         small_stack):
    import json

    path, data = small_stack
    cams = [_orbit_camera(data, 0.0), _orbit_camera(data, 90.0)]
    keys = tmp_path / "orbit.keyframes.json"
    keys.write_text(json.dumps(_keyframe_doc(cams, [0.0, 1.0], easing="linear")))
    out = tmp_path / "orbit.mp4"
    assert main(["render", str(path), "--keyframes", str(keys), "--fps", "6",
                 "--size", "63", "48", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "even sizes: rendering 64×48" in captured.err and "frame 7/7" in captured.err
    meta, frames = _read_mp4(out)
    assert len(frames) == 7 and meta["size"] == (64, 48)  # 1 s at 6 fps, both ends
    n, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert n == 7 and seconds == pytest.approx(7 / 6, abs=0.05)
    # The ends are the keyframes' views (H.264 at crf 18: within a few grey levels) ...
    for frame, cam in ((frames[0], cams[0]), (frames[-1], cams[1])):
        expected = _reference(data, cam, size=(64, 48)).astype(float)
        assert np.abs(frame - expected).mean() < 3.0
    # ... and every frame moves on from the one before: the view turns throughout.
    steps = [np.abs(frames[i + 1].astype(float) - frames[i]).mean() for i in range(6)]
    assert min(steps) > 1.0
    assert np.abs(frames[-1].astype(float) - frames[0]).mean() > max(steps)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["orbit.keyframes.json", "orbit.mp4"]


@pytest.mark.gl
def test_cli_keyframes_play_time_points_into_a_png_sequence(tmp_path, capsys, time_series):
    import json

    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    from vtkvol.io import read_volume

    first = read_volume(time_series, time_index=0)
    cam = _orbit_camera(first, 20.0)
    keys = tmp_path / "t.keyframes.json"
    keys.write_text(json.dumps(_keyframe_doc([cam, cam], [0.0, 3.0], time_indices=[0, 3])))
    out = tmp_path / "frames" / "t.png"
    assert main(["render", str(time_series), "--keyframes", str(keys), "--fps", "1",
                 "--size", "32", "32", "-o", str(out)]) == 0
    files = sorted((tmp_path / "frames").iterdir())
    assert [p.name for p in files] == [f"t_000{i}.png" for i in range(4)]
    for t, file in enumerate(files):
        reader = vtk.vtkPNGReader()
        reader.SetFileName(str(file))
        reader.Update()
        png = vtk_to_numpy(reader.GetOutput().GetPointData().GetScalars()).reshape(32, 32, 3)
        # frame t shows time point t, with the scene (contrast) of the first time point
        expected = _reference(read_volume(time_series, time_index=t), cam, model_data=first)
        np.testing.assert_array_equal(png[::-1], expected)
    assert "wrote" in capsys.readouterr().out

    # asking for a time point the file lacks is refused before rendering
    keys.write_text(json.dumps(_keyframe_doc([cam, cam], [0.0, 1.0], time_indices=[0, 9])))
    assert main(["render", str(time_series), "--keyframes", str(keys),
                 "-o", str(tmp_path / "x.mp4")]) == 2
    assert "time point 9, but series.tif has 4 (0–3)" in capsys.readouterr().err
    assert main(["render", "sample", "--keyframes", str(keys), "-o", str(tmp_path / "x.mp4")]) == 2
    assert "has only one time point" in capsys.readouterr().err


@pytest.mark.gl
def test_time_points_are_read_once_each_through_the_cache(time_series):
    from vtkvol.io import read_volume
    from vtkvol.model.keyframes import Animation, CameraState, Keyframe
    from vtkvol.movie import TimePointCache, keyframe_frames

    first = read_volume(time_series, time_index=0)
    cam = CameraState(**_orbit_camera(first, 0.0))
    anim = Animation((Keyframe(0, cam, 0), Keyframe(3, cam, 3), Keyframe(6, cam, 0)),
                     easing="linear")
    cache = TimePointCache.for_file(time_series, size=4)
    cache.put(0, first)
    frames = list(keyframe_frames(first, anim, fps=1, size=(16, 16), time_points=cache))
    assert len(frames) == 7 and cache.reads == 3  # 1, 2, 3 read once; back down from the cache
    for a, b in ((0, 6), (1, 5), (2, 4)):  # there and back: the same time points, same images
        np.testing.assert_array_equal(frames[a], frames[b])
    assert np.abs(frames[3].astype(float) - frames[0]).mean() > 1.0
    with pytest.raises(ValueError, match="not a file they can be read from"):
        next(keyframe_frames(first, anim, fps=1, size=(16, 16)))


def test_cli_keyframe_option_conflicts_and_bad_files_before_reading(tmp_path, capsys):
    import json

    keys = tmp_path / "k.keyframes.json"
    cam = {"position": [0, -10, 0], "focal_point": [0, 0, 0], "view_up": [0, 0, 1]}
    keys.write_text(json.dumps(_keyframe_doc([cam, cam], [0.0, 1.0], time_indices=[0, 1])))
    base = ["render", "no-such-file.tif", "--keyframes", str(keys), "-o", str(tmp_path / "m.mp4")]
    for extra, message in (
        (["--turntable", "360"], "--turntable and --keyframes are two kinds of movie"),
        (["--frames", "10"], "--frames does not apply to --keyframes"),
        (["--azimuth", "10"], "--azimuth does not apply to --keyframes: the keyframes place"),
        (["--time", "2"], "--time does not apply: the keyframes choose the time points"),
        (["--fps", "0"], "fps must be > 0"),
        (["--fps", "2000"], "--fps must be between 0 and 1000"),
    ):
        assert main(base + extra) == 2, extra
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, (extra, err)
    assert main(["render", "no-such-file.tif", "--frames", "3", "-o", str(tmp_path / "a.png")]) == 2
    assert "--frames applies to --turntable movies only" in capsys.readouterr().err
    keys.write_text('{"format": "vtkvol-keyframes", "version": 1, "keyframes": [{"time": NaN}]}')
    assert main(base) == 2
    assert capsys.readouterr().err == ("vtkvol: k.keyframes.json: is not valid JSON: NaN is not "
                                       "a number JSON allows\n")
    assert main(["render", "no-such-file.tif", "--keyframes", str(tmp_path / "none.json"),
                 "-o", str(tmp_path / "m.mp4")]) == 2
    assert "none.json: no such file" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [keys]


def test_cli_names_the_movie_extra_when_the_encoder_is_missing(tmp_path, capsys, monkeypatch):
    import vtkvol.movie

    monkeypatch.setattr(vtkvol.movie, "has_video_encoder", lambda: False)
    assert main(["render", "no-such-file.tif", "--turntable", "90", "-o",
                 str(tmp_path / "a.mp4")]) == 2
    err = capsys.readouterr().err
    assert "pip install 'vtkvol[movie]'" in err and err.count("\n") == 1
    with pytest.raises(ValueError, match=r"vtkvol\[movie\]"):
        write_movie(iter(_frames(2, 4, 4)), tmp_path / "b.mp4", n_frames=2)
    assert list(tmp_path.iterdir()) == []


def test_the_turn_about_the_sample_axis_keeps_a_tilted_view_upright():
    """Issue 25: the app turned about the tilted view-up, so the box tumbled. About the
    sample's z axis the camera keeps its height (elevation) at every angle; about the
    tilted view-up it does not."""
    position, focal = np.array([0.0, -10.0, 5.0]), np.zeros(3)
    up = np.array([0.0, 5.0, 10.0]) / np.linalg.norm([0.0, 5.0, 10.0])  # tilted towards +y
    heights, tumbling = [], []
    for degrees in (0.0, 45.0, 90.0, 180.0, 270.0):
        p, u = turned_camera(position, focal, up, (0.0, 0.0, 1.0), degrees)
        heights.append(p[2])
        assert np.linalg.norm(p - focal) == pytest.approx(np.linalg.norm(position))
        assert np.dot(u, p - focal) == pytest.approx(0.0, abs=1e-9)  # still a view-up
        tumbling.append(turned_camera(position, focal, up, up, degrees)[0][2])
    np.testing.assert_allclose(heights, 5.0, atol=1e-9)
    assert np.ptp(tumbling) > 5.0


@pytest.mark.parametrize("aspect", [0.5, 1.0, 2.0])
def test_fit_turn_keeps_every_corner_in_frame_at_every_angle(aspect):
    """A camera 3 µm from the centre of a 4 µm cube (parts of it outside the frame) is moved
    back until each corner lies inside both fields of view at every angle of the turn."""
    import math

    import vtk

    cam = vtk.vtkCamera()
    cam.SetFocalPoint(0.0, 0.0, 0.0)
    cam.SetPosition(0.0, -3.0, 1.0)
    cam.SetViewUp(0.0, 0.0, 1.0)
    cam.OrthogonalizeViewUp()  # as a renderer's camera is
    cam.SetViewAngle(30.0)
    bounds = (-2.0, 2.0, -2.0, 2.0, -2.0, 2.0)
    fit_turn(cam, bounds, aspect)
    half_v = math.radians(15.0)
    half_h = math.atan(math.tan(half_v) * aspect)
    corners = np.array([[x, y, z] for x in (-2, 2) for y in (-2, 2) for z in (-2, 2)], float)
    assert np.linalg.norm(cam.GetPosition()) > 3.1
    for degrees in range(0, 360, 15):
        p, u = turned_camera(cam.GetPosition(), (0, 0, 0), cam.GetViewUp(), (0, 0, 1), degrees)
        forward = -p / np.linalg.norm(p)
        right = np.cross(forward, u)
        for c in corners:
            v = c - p
            depth = float(np.dot(v, forward))
            assert abs(np.dot(v, u)) / depth <= math.tan(half_v) + 1e-9
            assert abs(np.dot(v, right)) / depth <= math.tan(half_h) + 1e-9
    far = cam.GetPosition()
    fit_turn(cam, bounds, aspect)  # far enough already: it stays
    assert cam.GetPosition() == pytest.approx(far)


def test_turntable_axis_is_checked():
    with pytest.raises(ValueError, match="axis must be 'sample' or 'view'"):
        next(turntable_frames(None, frames=2, axis="diagonal"))  # type: ignore[arg-type]


def test_overlays_scale_with_the_frame():
    """Issue 25: the colour legend took a fifth of small movie frames (fixed 12 px text,
    90 px wide). Its pixel sizes now follow the frame's shorter side, so it takes about the
    same share of a small frame as of a large one."""
    import vtk

    from vtkvol.engine.offscreen import make_render_window
    from vtkvol.engine.overlays import SceneOverlays, overlay_scale
    from vtkvol.model.scene import Overlays

    assert overlay_scale(1200, 600) == 1.0 and overlay_scale(320, 240) == pytest.approx(0.45)
    assert overlay_scale(4000, 3000) == 3.0
    shares = []
    for width, height in ((320, 240), (960, 720)):
        window = make_render_window((width, height))
        renderer = vtk.vtkRenderer()
        window.AddRenderer(renderer)
        overlays = SceneOverlays(renderer)
        lut = vtk.vtkColorTransferFunction()
        lut.AddRGBPoint(0.0, 0, 0, 0)
        lut.AddRGBPoint(100.0, 1, 1, 1)
        overlays.set_legend_channels([("ch0", lut)])
        overlays.apply(Overlays(color_legend=True, scale_bar=True))
        window.Render()
        [legend] = overlays.legends
        shares.append(legend.GetMaximumWidthInPixels() / width)
        font = legend.GetLabelTextProperty().GetFontSize()
        assert font == max(6, round(12 * overlay_scale(width, height)))
        overlays.close()
    assert shares[0] == pytest.approx(shares[1], rel=0.15)
