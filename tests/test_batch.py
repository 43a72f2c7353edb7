"""``vtkvol batch`` / ``vtkvol.batch``: many renders on a Dask cluster equal the single-process
ones; bad inputs fail early with one line; a failed job does not stop the others."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from vtkvol.batch import (
    RenderJob,
    RenderOptions,
    parse_time_range,
    plan_jobs,
    render_job,
)
from vtkvol.cli import main

SIZE = (48, 48)


def _read_png(path: Path) -> np.ndarray:
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    reader = vtk.vtkPNGReader()
    reader.SetFileName(str(path))
    reader.Update()
    image = reader.GetOutput()
    w, h, _ = image.GetDimensions()
    pixels = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(h, w, -1)
    return np.ascontiguousarray(pixels[::-1, :, :3])


@pytest.fixture(scope="module")
def time_series(tmp_path_factory) -> Path:
    """A 4-time-point, 16 × 32 × 32 uint16 ImageJ TIFF whose content moves along x."""
    import tifffile

    from vtkvol.io import confocal_phantom

    base = confocal_phantom((16, 32, 32), voxel_size_um=(0.5, 0.5, 1.0)).array[0]
    stack = np.stack([np.roll(base, 3 * t, axis=2) for t in range(4)])
    path = tmp_path_factory.mktemp("series") / "series.tif"
    tifffile.imwrite(path, stack, imagej=True,
                     metadata={"axes": "TZYX", "spacing": 1.0, "unit": "micron"},
                     resolution=(2.0, 2.0))
    return path


def test_two_worker_cluster_equals_single_process(tmp_path, time_series, capsys):
    """8 renders (a volume and a session over 4 time points) on a LocalCluster of two worker
    processes are byte-identical to render_image in this process; 4 jobs of a session whose
    data is gone fail with one line each, the others finish, and the exit code is 1."""
    import shutil

    from vtkvol.engine.api import render_image
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.presets import apply_preset
    from vtkvol.model.session import load_session_with_data, save_session

    data0 = read_volume(time_series)
    model = scene_for(data0)
    apply_preset(model.channels[0].tf, "magma")
    model.render.background = (0.2, 0.2, 0.3)
    session = save_session(tmp_path / "view", model, data=data0)
    gone = tmp_path / "gone.tif"
    shutil.copy(time_series, gone)
    broken = save_session(tmp_path / "broken", scene_for(read_volume(gone)),
                          data=read_volume(gone))
    gone.unlink()

    out = tmp_path / "out"
    t0 = time.perf_counter()
    code = main(["batch", str(time_series), str(session), str(broken), "-o", str(out),
                 "--time", "0:4", "--workers", "2", "--size", *map(str, SIZE)])
    seconds = time.perf_counter() - t0
    captured = capsys.readouterr()
    assert code == 1, captured.err
    assert "wrote 8 of 12 image(s)" in captured.out and "4 failed" in captured.out

    failed = [line for line in captured.err.splitlines() if "FAILED" in line]
    assert sorted(line.split("FAILED ")[1].split(":")[0] for line in failed) == [
        f"broken.vtkvol.json t={t}" for t in range(4)]
    assert all("gone.tif" in line for line in failed), failed
    done = [line for line in captured.err.splitlines() if " -> " in line]
    assert len(done) == 8
    # Two worker processes shared the work.
    assert len({line.rsplit(", ", 1)[1].rstrip(")") for line in done}) == 2, done

    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"series_t{t:04d}.png" for t in range(4)] + [f"view_t{t:04d}.png" for t in range(4)])
    for t in range(4):
        ref = render_image(read_volume(time_series, time_index=t), size=SIZE)
        assert np.array_equal(_read_png(out / f"series_t{t:04d}.png"), ref), t
        view_model, view_data = load_session_with_data(session, time_index=t)
        ref_view = render_image(view_data, model=view_model, size=SIZE)
        assert np.array_equal(_read_png(out / f"view_t{t:04d}.png"), ref_view), t
        assert not np.array_equal(ref, ref_view)  # the session's own look was rendered
    # The time points really differ (the content moves along x).
    assert not np.array_equal(_read_png(out / "series_t0000.png"),
                              _read_png(out / "series_t0003.png"))
    print(f"batch of 12 jobs on 2 workers: {seconds:.1f} s")


def test_missing_session_file_is_refused_before_rendering(tmp_path, capsys):
    code = main(["batch", "sample", str(tmp_path / "nothere.vtkvol.json"),
                 "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err == (f"vtkvol: {tmp_path / 'nothere.vtkvol.json'}: no such file or folder; "
                   "nothing was rendered")
    assert not (tmp_path / "out").exists()


def test_unreachable_scheduler_fails_fast_with_one_line(tmp_path, capsys):
    import socket

    with socket.socket() as sock:  # a port nobody listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    t0 = time.perf_counter()
    code = main(["batch", "sample", "-o", str(tmp_path / "out"), "--size", "48", "48",
                 "--scheduler", f"tcp://127.0.0.1:{port}", "--connect-timeout", "1"])
    seconds = time.perf_counter() - t0
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert err[-1].startswith(f"vtkvol: no dask scheduler answered at tcp://127.0.0.1:{port} "
                              "within 1 s")
    assert seconds < 15
    assert not (tmp_path / "out").exists()


def test_existing_output_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "sample.png").write_bytes(b"mine")
    code = main(["batch", "sample", "-o", str(out), "--size", "48", "48"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err == f"vtkvol: {out / 'sample.png'} exists; pass --overwrite to replace it"
    assert (out / "sample.png").read_bytes() == b"mine"
    # The worker checks again (another batch may have written it since the plan was made).
    job = RenderJob("sample", str(out / "sample.png"), None, RenderOptions(size=SIZE))
    result = render_job(job)
    assert not result.ok
    assert result.error == (f"{out / 'sample.png'}: exists; pass overwrite (--overwrite) "
                            "to replace it")
    assert (out / "sample.png").read_bytes() == b"mine"
    assert sorted(p.name for p in out.iterdir()) == ["sample.png"]  # no temporary file left


def test_render_job_in_process_writes_the_render_image_png(tmp_path):
    """The job function itself (what each worker runs), without a cluster: its PNG is
    render_image's image, and a bad time point is one line naming the limit."""
    from vtkvol.engine.api import render_image
    from vtkvol.io import confocal_phantom

    job = RenderJob("sample", str(tmp_path / "a" / "s.png"), None,
                    RenderOptions(size=SIZE, azimuth=75.0))
    result = render_job(job)
    assert result.ok and result.worker == "local", result
    ref = render_image(confocal_phantom(), size=SIZE, azimuth=75.0)
    assert np.array_equal(_read_png(tmp_path / "a" / "s.png"), ref)

    bad = render_job(RenderJob("sample", str(tmp_path / "t.png"), 2, RenderOptions(size=SIZE)))
    assert not bad.ok and bad.error == "the built-in sample has one time point (0)"
    assert not (tmp_path / "t.png").exists()


def test_time_ranges_and_job_names(tmp_path):
    assert parse_time_range("3") == range(3, 4)
    assert parse_time_range("0:20") == range(0, 20)
    assert list(parse_time_range("0:20:5")) == [0, 5, 10, 15]
    for text, message in [("5:5", "STOP is excluded"), ("a:3", "START:STOP"),
                          ("-1:3", "START:STOP"), ("0:4:0", "step must be at least 1")]:
        with pytest.raises(ValueError, match=message):
            parse_time_range(text)
    a, b = tmp_path / "a", tmp_path / "b"
    for folder in (a, b):
        folder.mkdir()
        (folder / "v.vtkvol.json").write_text("{}")
    jobs = plan_jobs([a / "v.vtkvol.json"], tmp_path / "out", times=range(2))
    assert [Path(j.output).name for j in jobs] == ["v_t0000.png", "v_t0001.png"]
    assert [j.name for j in jobs] == ["v.vtkvol.json t=0", "v.vtkvol.json t=1"]
    with pytest.raises(ValueError, match=r"would both write v\.png"):
        plan_jobs([a / "v.vtkvol.json", b / "v.vtkvol.json"], tmp_path / "out")


def test_egl_device_per_local_worker(monkeypatch):
    """``--egl-devices``: worker i of a LocalCluster (named 0, 1, …) gets devices[i % n] as
    VTK_DEFAULT_EGL_DEVICE_INDEX, which VTK reads when it constructs an EGL render window."""
    import os
    from types import SimpleNamespace

    from vtkvol.batch import _egl_device_plugin

    monkeypatch.delenv("VTK_DEFAULT_EGL_DEVICE_INDEX", raising=False)
    plugin = _egl_device_plugin([2, 3])
    seen = []
    for name in (0, 1, 2):
        plugin.setup(SimpleNamespace(name=name, address=f"tcp://127.0.0.1:{4000 + name}"))
        seen.append(os.environ["VTK_DEFAULT_EGL_DEVICE_INDEX"])
    assert seen == ["2", "3", "2"]


def test_batch_module_imports_no_qt():
    import subprocess
    import sys

    code = ("import sys, vtkvol.batch, distributed, vtkvol.engine.api\n"
            "print([m for m in sys.modules if m.startswith(('PySide6', 'pyvistaqt', 'qtpy'))])")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_existing_scheduler_renders_jobs_with_their_own_options(tmp_path, small_volume_file):
    """run_batch against a running scheduler (a LocalCluster of two worker processes started
    here, as `dask scheduler` + `dask worker` would be): 4 jobs of one volume at different
    azimuths equal render_image's images byte for byte."""
    import logging

    from distributed import LocalCluster

    from vtkvol.batch import run_batch
    from vtkvol.engine.api import render_image
    from vtkvol.io import read_volume

    azimuths = (0.0, 45.0, 90.0, 135.0)
    jobs = [RenderJob(str(small_volume_file), str(tmp_path / f"a{int(a)}.png"), None,
                      RenderOptions(size=SIZE, azimuth=a)) for a in azimuths]
    seen = []
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as cluster:
        results = run_batch(jobs, scheduler=cluster.scheduler_address,
                            progress=lambda done, total, r: seen.append((done, total)))
    assert [r.ok for r in results] == [True] * 4, [r.error for r in results]
    assert [r.job for r in results] == jobs  # in the jobs' order, whatever order they finished
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    sample = read_volume(small_volume_file)
    images = [_read_png(tmp_path / f"a{int(a)}.png") for a in azimuths]
    for a, image in zip(azimuths, images, strict=True):
        assert np.array_equal(image, render_image(sample, size=SIZE, azimuth=a)), a
    assert not np.array_equal(images[0], images[2])
