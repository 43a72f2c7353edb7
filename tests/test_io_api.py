"""Public API of vtkvol.io: read_volume, the reader registry, import hygiene, sample, bench."""

from __future__ import annotations

import importlib.metadata
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import tifffile
import tomllib

import vtkvol.io as vio
from vtkvol.bench.loadbench import time_load
from vtkvol.io import (
    ReadCancelled,
    ReaderSpec,
    VolumeData,
    VolumeReadError,
    confocal_phantom,
    get_reader,
    read_volume,
    registry,
    reload_readers,
)

ROOT = Path(__file__).parents[1]


def test_public_names():
    for name in (
        "Spacing",
        "VolumeData",
        "VolumeReadError",
        "ReadCancelled",
        "read_volume",
        "get_reader",
        "from_vtk_image",
        "fit_volume",
        "confocal_phantom",
    ):
        assert hasattr(vio, name), name
    assert issubclass(VolumeReadError, ValueError)
    assert issubclass(ReadCancelled, Exception)
    assert not issubclass(ReadCancelled, VolumeReadError)


def test_import_pulls_in_neither_vtk_nor_qt():
    code = textwrap.dedent(
        """
        import sys
        import vtkvol.io
        vtkvol.io.get_reader("x.tif")
        bad = sorted(m for m in sys.modules if m.split(".")[0] in ("vtkmodules", "vtk", "PySide6"))
        print(",".join(bad))
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert result.stdout.strip() == ""


# -- read_volume errors ----------------------------------------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(VolumeReadError, match=r"^nope\.tif: no such file or folder: .*nope\.tif"):
        read_volume(tmp_path / "nope.tif")


def test_unknown_extension(tmp_path):
    path = tmp_path / "scan.xyz"
    path.write_bytes(b"1234")
    with pytest.raises(VolumeReadError) as info:
        read_volume(path)
    message = str(info.value)
    assert message.startswith("scan.xyz: unknown file type '.xyz'; vtkvol reads ")
    assert "*.tif" in message and "*.nhdr" in message and "*.npy" in message


def test_folder_without_images(tmp_path):
    (tmp_path / "readme.txt").write_text("hi")
    with pytest.raises(VolumeReadError, match="the folder holds no file that a reader accepts"):
        read_volume(tmp_path)


# -- registry --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("name", "reader"),
    [
        ("a.tif", "tiff"),
        ("a.OME.TIFF", "tiff"),
        ("a_4x4x4_uint8.raw", "raw"),
        ("a.nhdr", "nrrd"),
        ("a.dat", "dat"),
        ("a.npy", "numpy"),
        ("a.npz", "numpy"),
        ("a.vti", "vtk"),
        ("a.mha", "vtk"),
    ],
)
def test_get_reader_by_pattern(tmp_path, name, reader):
    spec = get_reader(tmp_path / name)
    assert isinstance(spec, ReaderSpec) and spec.name == reader
    assert callable(spec)


def test_get_reader_for_folders(tmp_path):
    assert get_reader(tmp_path) is None
    tifffile.imwrite(tmp_path / "z1.tif", np.zeros((4, 4), np.uint8))
    spec = get_reader(tmp_path)
    assert spec is not None and spec.name == "tiff" and spec.accepts_directories
    assert get_reader(tmp_path / "x.unknown") is None


def test_reader_spec_returns_checked_volume(tmp_path):
    np.save(tmp_path / "v.npy", np.arange(8, dtype=np.int32).reshape(2, 2, 2))
    spec = get_reader(tmp_path / "v.npy")
    data = spec(tmp_path / "v.npy", voxel_size_um=0.5)
    assert data.array.dtype == np.uint16  # normalised
    assert data.voxel_size_um == (0.5, 0.5, 0.5)
    assert data.metadata["reader"] == "numpy"


def test_pyproject_entry_points_match_builtin_table():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    table = config["project"]["entry-points"]["vtkvol.readers"]
    assert table == registry.BUILTIN_READERS


def _plugin_module(tmp_path: Path) -> None:
    (tmp_path / "vtkvol_test_plugin.py").write_text(
        textwrap.dedent(
            """
            import numpy as np
            from vtkvol.io.registry import ReaderSpec
            from vtkvol.io.volume_data import Spacing, VolumeData

            def read(path, *, time_index, channels, progress):
                progress(1.0, "plugin read")
                arr = np.full((1, 2, 3, 4), 7, dtype=np.float64)
                return VolumeData(arr, Spacing(1, 2, 3), ["plugin"], source=str(path))

            READER = ReaderSpec("foo", "Foo files", ("*.foo",), False, read)
            NOT_A_SPEC = object()
            """
        )
    )


def test_entry_point_plugin_reader(tmp_path, monkeypatch):
    _plugin_module(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    group = registry.ENTRY_POINT_GROUP
    eps = [
        importlib.metadata.EntryPoint("foo", "vtkvol_test_plugin:READER", group),
        importlib.metadata.EntryPoint("broken", "vtkvol_test_plugin_missing:READER", group),
        importlib.metadata.EntryPoint("odd", "vtkvol_test_plugin:NOT_A_SPEC", group),
    ]
    monkeypatch.setattr(registry, "_entry_points", lambda: eps)
    reload_readers()
    try:
        with pytest.warns(RuntimeWarning) as caught:
            readers = vio.available_readers()
        messages = " ".join(str(w.message) for w in caught)
        assert "'broken'" in messages and "failed to load" in messages
        assert "'odd'" in messages and "not a vtkvol.io.registry.ReaderSpec" in messages
        assert readers[0].name == "foo"
        assert {r.name for r in readers} >= set(registry.BUILTIN_READERS)
        path = tmp_path / "x.foo"
        path.write_bytes(b"")
        assert get_reader(path).name == "foo"
        data = read_volume(path)
        assert data.array.dtype == np.float32
        assert data.channel_names == ["plugin"]
        assert data.voxel_size_um == (1, 2, 3)
        assert get_reader(tmp_path / "y.tif").name == "tiff"  # built-ins still there
    finally:
        monkeypatch.undo()
        reload_readers()


def test_registry_falls_back_to_builtins_without_metadata(monkeypatch):
    monkeypatch.setattr(registry, "_entry_points", list)
    reload_readers()
    try:
        names = [r.name for r in vio.available_readers()]
        assert names == list(registry.BUILTIN_READERS)
    finally:
        monkeypatch.undo()
        reload_readers()


# -- progress and cancel through read_volume -------------------------------------------------
def test_progress_is_monotonic_and_ends_at_one(tmp_path):
    np.save(tmp_path / "v.npy", np.arange(2 * 30 * 16 * 16, dtype=np.int32).reshape(2, 30, 16, 16))
    seen: list[float] = []
    read_volume(tmp_path / "v.npy", progress=lambda f, m: seen.append(f))
    assert seen == sorted(seen) and seen[-1] == 1.0 and seen[0] >= 0.0


def test_cancel_before_and_during(tmp_path):
    np.save(tmp_path / "v.npy", np.zeros((4, 4, 4), np.uint8))
    with pytest.raises(ReadCancelled):
        read_volume(tmp_path / "v.npy", cancel=lambda: True)
    flags = iter([False, False, True, True, True, True])
    with pytest.raises(ReadCancelled):
        read_volume(tmp_path / "v.npy", cancel=lambda: next(flags, True))


# -- sample ----------------------------------------------------------------------------------
def test_confocal_phantom_properties():
    data = confocal_phantom()
    assert isinstance(data, VolumeData)
    assert data.array.shape == (2, 64, 128, 128)
    assert data.array.dtype == np.uint16
    assert data.channel_names == ["nuclei", "membranes"]
    assert data.voxel_size_um == pytest.approx((0.2, 0.2, 0.6))
    assert data.metadata["bit_depth"] == 12
    assert int(data.array.max()) <= 4095
    nuclei, membranes = data.array.astype(np.float64)
    # Background offset plus noise everywhere; bright structures on top.
    assert 100 < np.percentile(nuclei, 5) < 200
    assert np.percentile(nuclei, 99.5) > 1500
    assert np.percentile(membranes, 99.5) > 900
    # Membranes are thin shells: a minority of voxels is bright.
    assert 0.02 < np.mean(membranes > 500) < 0.35
    # Nuclei and membranes are different structures.
    assert np.corrcoef(nuclei.ravel(), membranes.ravel())[0, 1] < 0.2
    # Noise: neighbouring background voxels differ.
    assert np.std(np.diff(nuclei[:, :, :8], axis=2)) > 2


def test_confocal_phantom_is_deterministic():
    # (no timing assert: speed lives in `vtkvol bench`, and CI machines are shared)
    first = confocal_phantom(seed=5)
    second = confocal_phantom(seed=5)
    np.testing.assert_array_equal(first.array, second.array)
    assert not np.array_equal(first.array, confocal_phantom(seed=6).array)
    small = confocal_phantom((8, 16, 24), voxel_size_um=(0.5, 0.5, 1.0))
    assert small.array.shape == (2, 8, 16, 24)


# -- load benchmark --------------------------------------------------------------------------
def test_time_load_small(tmp_path):
    result = time_load(tmp_path, shape_czyx=(2, 8, 32, 32), repeats=1)
    assert result["shape_czyx"] == (2, 8, 32, 32)
    assert result["dtype"] == "uint16"
    assert result["median_s"] > 0 and len(result["runs_s"]) == 1
    assert result["voxel_size_um"] == pytest.approx((0.2, 0.2, 0.5))
