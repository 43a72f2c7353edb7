"""Hostile commands (issue 26): numbers no command can use (a billion turntable frames, NaN
degrees, a trillion time points, 100 000 workers, a scheduler address that is not one),
``convert`` writing into its own input or converting a store that holds nothing, and movies
and conversions killed half way. Each is refused up front in one ``vtkvol:`` line naming the
option, or, killed, leaves no hidden partial file behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from tests_support_hostile import ROOT, assert_one_line, run_child

from vtkvol.cli import main

SMALL = ["--size", "32", "32"]



def cli_child(args: list[str], *, timeout: float = 60.0, memory_gib: float | None = None,
              ) -> tuple[int, str, float]:
    """``vtkvol ARGS`` in a child process (exit code, stderr, seconds); with ``memory_gib`` the
    child gets that much address space beyond what vtkvol's imports take."""
    limit = None
    if memory_gib is not None:
        probe = run_child("import vtkvol.cli, vtkvol.batch, vtkvol.movie, numpy, vtk\n"
                          "print(open('/proc/self/status').read())")
        size_kb = next(int(line.split()[1]) for line in probe.stdout.splitlines()
                       if line.startswith("VmSize:"))
        limit = size_kb * 1024 + int(memory_gib * 2**30)
    start = time.perf_counter()
    done = run_child(f"import sys\nfrom vtkvol.cli import main\nsys.exit(main({args!r}))",
                     timeout=timeout, memory_bytes=limit, cwd=ROOT)
    return done.returncode, done.stderr, time.perf_counter() - start


# -- render: turntables -----------------------------------------------------------------------
@pytest.mark.parametrize("name", ["spin.mp4", "spin.png", "frames", "spin.tif"])
def test_a_billion_turntable_frames_are_refused_before_any_work(tmp_path, name):
    """Listing 10⁹ frame names took 1.9 GB before the first frame; to .mp4 it rendered for
    '70 days'. Now: refused at once, in a child with 1 GiB of spare address space."""
    out = tmp_path / name
    code, err, seconds = cli_child(["render", "sample", "-o", str(out), "--turntable", "360",
                                    "--frames", "1000000000", *SMALL], memory_gib=1.0)
    assert code == 2, err
    assert_one_line(err, "--frames must be at most 100000", "got 1000000000")
    assert seconds < 30
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("value", "message"), [
    ("nan", "--turntable must be a finite number of degrees, got nan"),
    ("inf", "--turntable must be a finite number of degrees, got inf"),
    ("-inf", "--turntable must be a finite number of degrees, got -inf"),
    ("1e999", "--turntable must be a finite number of degrees, got inf"),
    ("1e300", "--turntable must be at most 36000 degrees (100 turns) either way, got 1e+300"),
])
def test_a_turntable_of_no_finite_angle_is_refused(tmp_path, capsys, value, message):
    """--turntable nan exited 0 with a blank second frame."""
    out = tmp_path / "spin.png"
    assert main(["render", "sample", "-o", str(out), f"--turntable={value}", "--frames", "2",
                 *SMALL]) == 2
    assert assert_one_line(capsys.readouterr().err) == f"vtkvol: {message}"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "message"), [
    (["render", "sample", "-o", "{tmp}/a.png", "--time-budget", "nan", *SMALL],
     "--time-budget must be a finite number of seconds, got nan"),
    (["render", "sample", "-o", "{tmp}/a.png", "--param", "shadow_strength=nan", *SMALL],
     "--param shadow_strength: the value must be a finite number, got 'nan'"),
    (["render", "sample", "-o", "{tmp}/a.png", "--param", "x=-Infinity", *SMALL],
     "--param x: the value must be a finite number, got '-Infinity'"),
    (["render", "sample", "-o", "{tmp}/a.mp4", "--turntable", "90", "--fps", "inf", *SMALL],
     "--fps must be a finite number of frames per second, got inf"),
    (["batch", "sample", "-o", "{tmp}/b", "--voxel-size", "1", "nan", "1"],
     "--voxel-size X Y Z must be three positive µm values, got 1 nan 1"),
    (["batch", "sample", "-o", "{tmp}/b", "--voxel-size", "1", "-2", "1"],
     "--voxel-size X Y Z must be three positive µm values, got 1 -2 1"),
    (["batch", "sample", "-o", "{tmp}/b", "--param", "x=nan"],
     "--param x: the value must be a finite number, got 'nan'"),
    (["batch", "sample", "-o", "{tmp}/b", "--egl-devices", "0,-1"],
     "--egl-devices takes device numbers >= 0, got '0,-1'"),
    (["info", "{tmp}/v.npy", "--voxel-size", "inf", "1", "1"],
     "--voxel-size X Y Z must be three positive µm values, got inf 1 1"),
    (["info", "{tmp}/v.npy", "--voxel-size", "0", "1", "1"],
     "--voxel-size X Y Z must be three positive µm values, got 0 1 1"),
    (["convert", "{tmp}/v.npy", "{tmp}/v.zarr", "--voxel-size", "1", "1", "nan"],
     "--voxel-size X Y Z must be three positive µm values, got 1 1 nan"),
    (["bench", "-o", "{tmp}/bench", "--size", "100000"],
     "--size must be at most 512 voxels, got 100000"),
], ids=["time-budget", "param-nan", "param-inf", "fps", "batch-voxel-nan", "batch-voxel-neg",
        "batch-param", "egl", "info-voxel", "info-voxel-zero", "convert-voxel", "bench-size"])
def test_every_numeric_option_refuses_what_it_cannot_use(tmp_path, capsys, args, message):
    np.save(tmp_path / "v.npy", np.zeros((4, 4, 4), np.uint8))
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main([a.replace("{tmp}", str(tmp_path)) for a in args])
    assert code == 2
    assert assert_one_line(capsys.readouterr().err) == f"vtkvol: {message}"
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_open_refuses_a_non_finite_voxel_size_before_the_display_check(tmp_path):
    env_free = {k: v for k, v in os.environ.items()
                if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    done = subprocess.run([sys.executable, "-m", "vtkvol.cli", "open", "--voxel-size", "nan",
                           "1", "1"], capture_output=True, text=True, timeout=60, env=env_free,
                          cwd=ROOT)
    assert done.returncode == 2
    assert assert_one_line(done.stderr) == (
        "vtkvol: --voxel-size X Y Z must be three positive µm values, got nan 1 1")


@pytest.mark.parametrize(("args", "part"), [
    (["render", "sample", "-o", "x.png", "--size", "a", "b"],
     "vtkvol render: argument --size: invalid int value: 'a'"),
    (["batch", "sample", "-o", "out", "--workers", "many"],
     "vtkvol batch: argument --workers: invalid int value: 'many'"),
    (["render", "sample"], "vtkvol render: the following arguments are required: -o/--output"),
])
def test_argument_errors_are_one_line_naming_the_option(capsys, args, part):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 2
    line = assert_one_line(capsys.readouterr().err, part)
    assert line.endswith("--help)")


# -- batch ------------------------------------------------------------------------------------
@pytest.mark.parametrize(("inputs", "time", "part"), [
    (["sample"], "0:1000000000000", "--time 0:1000000000000 is 1000000000000 time points; a "
                                    "batch renders at most 100000 images"),
    (["sample"], "0:100001", "--time 0:100001 is 100001 time points"),
    (["sample", "sample2"], "0:60000", "2 input(s) × 60000 time points: a batch renders at "
                                       "most 100000 images"),
])
def test_a_batch_of_too_many_time_points_is_refused_before_listing(tmp_path, inputs, time,
                                                                   part):
    """The range was listed before it was checked: a MemoryError traceback."""
    (tmp_path / "sample2").mkdir()  # a second input that exists (never read)
    files = [str(tmp_path / f) if f != "sample" else f for f in inputs]
    code, err, _ = cli_child(["batch", *files, "-o", str(tmp_path / "out"), "--time", time],
                             memory_gib=1.0, timeout=120)
    assert code == 2, err
    assert_one_line(err, part)
    assert not (tmp_path / "out").exists()


def test_too_many_local_workers_are_refused_at_once(tmp_path):
    """--workers 100000 started (tried to) 100000 processes and hung."""
    from vtkvol.batch import max_local_workers

    code, err, seconds = cli_child(["batch", "sample", "-o", str(tmp_path / "out"),
                                    "--workers", "100000"], timeout=60)
    assert code == 2, err
    assert_one_line(err, f"--workers must be at most {max_local_workers()} (4 per CPU core",
                    "got 100000")
    assert seconds < 30 and not (tmp_path / "out").exists()
    assert max_local_workers() == 4 * (os.cpu_count() or 1)


@pytest.mark.parametrize(("address", "part"), [
    ("not a url", "--scheduler takes tcp://HOST:PORT, got 'not a url'"),
    ("tcp://host", "--scheduler takes tcp://HOST:PORT, got 'tcp://host'"),
    ("http://host:8786", "(known schemes: tcp, tls, ws, wss, ucx)"),
    ("tcp://127.0.0.1:99999", "the port must be from 1 to 65535"),
    ("tcp://127.0.0.1:0", "the port must be from 1 to 65535"),
    ("tcp://a b:8786", "--scheduler takes tcp://HOST:PORT"),
])
def test_a_scheduler_address_that_is_not_one_is_refused_without_waiting(tmp_path, address,
                                                                         part):
    """Refused before dask tries (it waited out the timeout, then printed a traceback from
    the client's destructor)."""
    code, err, seconds = cli_child(["batch", "sample", "-o", str(tmp_path / "out"),
                                    "--scheduler", address], timeout=90)
    assert code == 2, err
    assert_one_line(err, part)
    assert seconds < 15


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:8786", "127.0.0.1:8786",
                                     "tls://scheduler.example.org:8786", "[::1]:8786",
                                     "ws://node-3:1"])
def test_real_scheduler_addresses_pass_the_check(address):
    from vtkvol.batch import scheduler_address_problem

    assert scheduler_address_problem(address) is None


# -- convert ----------------------------------------------------------------------------------
zarr = pytest.importorskip("zarr")
pytest.importorskip("ome_zarr.writer")


def ome_zarr_store(path: Path, shape_zyx: tuple[int, int, int], *, chunks=(64, 256, 256),
                   stored: int = 0) -> Path:
    """An NGFF 0.5 image of one uint8 channel declaring ``shape_zyx``, with ``stored`` chunks
    actually written (the rest is the fill value)."""
    group = zarr.open_group(str(path), mode="w", zarr_format=3)
    array = group.create_array("0", shape=(1, *shape_zyx), chunks=(1, *chunks), dtype="uint8",
                               fill_value=0, dimension_names=["c", "z", "y", "x"])
    for i in range(stored):
        array[0, : chunks[0], : chunks[1], i * chunks[2]:(i + 1) * chunks[2]] = 7
    group.attrs["ome"] = {"version": "0.5", "multiscales": [{
        "axes": [{"name": "c", "type": "channel"},
                 *({"name": a, "type": "space", "unit": "micrometer"} for a in "zyx")],
        "datasets": [{"path": "0", "coordinateTransformations": [
            {"type": "scale", "scale": [1.0, 1.0, 1.0, 1.0]}]}]}]}
    return path


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.mark.parametrize("shape", [(1536, 2048, 2048), (4, 64, 64)])
def test_a_store_without_chunks_is_refused_not_converted(tmp_path, capsys, shape):
    """A store declaring 6 GB and holding no chunk was converted into 6 GB of fill value."""
    src = ome_zarr_store(tmp_path / "empty.ome.zarr", shape)
    start = time.perf_counter()
    assert main(["convert", str(src), str(tmp_path / "out.zarr")]) == 1
    assert time.perf_counter() - start < 20
    assert_one_line(capsys.readouterr().err,
                    "empty.ome.zarr: its finest level (0) stores no chunks: "
                    "every voxel is the fill value")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.ome.zarr"]


def test_a_store_with_one_chunk_is_still_converted(tmp_path):
    from vtkvol.io import read_volume

    src = ome_zarr_store(tmp_path / "sparse.ome.zarr", (8, 32, 32), chunks=(8, 32, 32),
                         stored=1)
    assert main(["convert", str(src), str(tmp_path / "out.zarr")]) == 0
    assert int(read_volume(tmp_path / "out.zarr").array.max()) == 7


@pytest.mark.parametrize(("layout", "part"), [
    ("zarr-inner", "is inside the input"),
    ("folder-out", "is inside the input"),
    ("input-in-output", "holds the input"),
])
def test_convert_never_writes_inside_its_input_nor_over_it(tmp_path, capsys, layout, part):
    """convert IN IN/inner.zarr and convert FOLDER FOLDER/out.zarr wrote into the input
    (exit 0); convert OUT/x.npy OUT --overwrite would have deleted the input's folder."""
    if layout == "zarr-inner":
        src = ome_zarr_store(tmp_path / "in.ome.zarr", (4, 32, 32), chunks=(4, 32, 32),
                             stored=1)
        out, extra = src / "inner.zarr", []
    elif layout == "folder-out":
        import tifffile

        src = tmp_path / "slices"
        src.mkdir()
        for z in range(3):
            tifffile.imwrite(src / f"s{z:02d}.tif", np.full((16, 16), z, np.uint8))
        out, extra = src / "out.zarr", []
    else:
        folder = tmp_path / "old.zarr"
        folder.mkdir()
        src = folder / "v.npy"
        np.save(src, np.ones((4, 8, 8), np.uint8))
        out, extra = folder, ["--overwrite"]
    from tests_support_hostile import snapshot

    before = snapshot(tmp_path)
    assert main(["convert", str(src), str(out), *extra]) == 2
    assert_one_line(capsys.readouterr().err, part)
    assert snapshot(tmp_path) == before


# -- killed half way --------------------------------------------------------------------------
def run_until(args: list[str], ready, *, sig: int, timeout: float = 120.0,
              ) -> tuple[int, str]:
    """Start ``vtkvol ARGS``, wait until ``ready()`` is true, send ``sig``; (code, stderr)."""
    proc = subprocess.Popen([sys.executable, "-m", "vtkvol.cli", *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + timeout
        while not ready():
            assert proc.poll() is None, f"ended before it was signalled: {proc.communicate()}"
            assert time.monotonic() < deadline, "never got going"
            time.sleep(0.05)
        time.sleep(0.3)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["TERM", "INT"])
@pytest.mark.parametrize("name", ["spin.mp4", "spin.png", "spin.tif"])
def test_a_movie_killed_half_way_leaves_no_hidden_file(tmp_path, name, sig):
    """Killed while rendering, the movie writer's temporary file (.spin.XXXX.mp4) or folder
    (.frames.XXXX) stayed behind. Now the writer cleans up and the exit code says why."""
    if name.endswith(".mp4"):
        pytest.importorskip("imageio_ffmpeg")
    out_dir = tmp_path / "movie"
    out_dir.mkdir()
    code, err = run_until(["render", "sample", "-o", str(out_dir / name), "--turntable", "360",
                           "--frames", "5000", *SMALL],
                          lambda: bool(hidden(out_dir)), sig=sig)
    assert code == (143 if sig == signal.SIGTERM else 130), err
    assert err.splitlines()[-1] in ("vtkvol: terminated; unfinished output removed",
                                    "vtkvol: interrupted; unfinished output removed"), err
    assert "Traceback" not in err
    assert list(out_dir.iterdir()) == []


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["TERM", "INT"])
def test_a_conversion_killed_half_way_leaves_no_partial_folder(tmp_path, sig):
    """A 2 GiB store with one stored chunk takes a while to convert (the fill is computed);
    killed half way, the hidden .partial folder stayed behind (SIGTERM) or was written into
    again by dask's threads after its removal (SIGINT)."""
    src = ome_zarr_store(tmp_path / "big.ome.zarr", (512, 2048, 2048), stored=1)
    out = tmp_path / "out"
    out.mkdir()

    def writing() -> bool:
        return any(p.name.startswith(".big.zarr.partial") and (p / "zarr.json").exists()
                   for p in out.iterdir())

    code, err = run_until(["convert", str(src), str(out / "big.zarr")], writing, sig=sig)
    assert code == (143 if sig == signal.SIGTERM else 130), err
    assert "Traceback" not in err
    time.sleep(1.0)  # any thread still writing would recreate the folder by now
    assert list(out.iterdir()) == []
