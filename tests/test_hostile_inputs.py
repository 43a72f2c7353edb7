"""Hostile files of the newer readers and documents (issue 26): NIfTI headers that lie or are
damaged, Imaris files with the wrong kind of HDF5 object or unnumbered names, MRC axis maps
that cannot be, keyframe files with numbers too large to compute with, transfer-function files
nested 100 000 deep. Each is refused (or read with a note) with one line naming the file, and
nothing from a third-party library reaches stderr."""

from __future__ import annotations

import gzip
import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tests_support_hostile import ROOT, assert_one_line, read_in_child

from vtkvol.io import VolumeReadError, read_volume

nib = pytest.importorskip("nibabel")
mrcfile = pytest.importorskip("mrcfile")
h5py = pytest.importorskip("h5py")


def cli(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """``vtkvol ARGS`` in a child process, as a user runs it (stderr as the user sees it)."""
    return subprocess.run([sys.executable, "-m", "vtkvol.cli", *args], capture_output=True,
                          text=True, timeout=timeout, cwd=ROOT)



# -- NIfTI ------------------------------------------------------------------------------------
def nifti_bytes(shape=(4, 5, 6), dtype=np.uint8) -> bytes:
    """A valid single-file NIfTI-1 (header, 4 bytes of extension flag, voxels), as nibabel
    writes it."""
    image = nib.Nifti1Image(np.arange(np.prod(shape)).astype(dtype).reshape(shape), np.eye(4))
    image.header.set_xyzt_units("micron", "sec")
    return bytes(image.to_bytes())


def edited_nifti(path: Path, edits: list[tuple[int, str, tuple]], *, compress: bool = False,
                 voxels: bytes | None = None) -> Path:
    """A NIfTI-1 file with header fields overwritten at their byte offsets (little endian;
    dim at 40, datatype at 70, pixdim at 76, vox_offset at 108, scl_slope/inter at 112/116);
    ``voxels`` replaces the voxel bytes after the 352-byte header."""
    blob = bytearray(nifti_bytes())
    for offset, fmt, values in edits:
        struct.pack_into("<" + fmt, blob, offset, *values)
    if voxels is not None:
        blob = blob[:352] + voxels
    path.write_bytes(gzip.compress(bytes(blob)) if compress else bytes(blob))
    return path


@pytest.mark.parametrize(("dim0", "compress"), [(9, False), (-3, False), (0, True), (8, True)])
def test_nifti_with_a_bad_dim0_is_refused_in_one_line(tmp_path, dim0, compress):
    """nibabel takes dim[0] outside 1…7 for the other byte order: it logged two lines about
    sizeof_hdr and vox_offset and refused the file for the wrong reason."""
    name = "bad.nii.gz" if compress else "bad.nii"
    path = edited_nifti(tmp_path / name, [(40, "h", (dim0,))], compress=compress)
    done = cli("info", str(path))
    assert done.returncode == 1
    assert_one_line(done.stderr, f"{name}: dim[0] = {dim0} is not a number of dimensions")
    assert "sizeof_hdr" not in done.stderr


@pytest.mark.parametrize(("offset", "value", "field"),
                         [(112, np.inf, "scl_slope = inf"), (112, -np.inf, "scl_slope = -inf"),
                          (116, np.inf, "scl_inter = inf")])
def test_nifti_with_an_infinite_scale_is_refused(tmp_path, offset, value, field):
    """scl_slope = inf was ignored without a word (the raw values shown as if unscaled)."""
    edits = [(offset, "f", (value,))] + ([(112, "f", (2.0,))] if offset == 116 else [])
    path = edited_nifti(tmp_path / "scaled.nii", edits)
    with pytest.raises(VolumeReadError, match=rf"^scaled\.nii: {field} is not a finite"):
        read_volume(path)


def test_nifti_scaling_of_nan_still_means_unscaled(tmp_path):
    """nibabel itself writes NaN slopes for unscaled data: those read as before."""
    path = edited_nifti(tmp_path / "nan.nii", [(112, "2f", (np.nan, np.nan))])
    data = read_volume(path)
    assert data.array.shape == (1, 6, 5, 4) and int(data.array.max()) == 119


@pytest.mark.parametrize("pixdim", [(-2.0, 3.0, 4.0), (2.0, -3.0, -4.0)])
def test_negative_nifti_pixdim_is_used_with_a_note_and_no_log_line(tmp_path, pixdim):
    path = edited_nifti(tmp_path / "flip.nii", [(80, "3f", pixdim)])
    data = read_volume(path)
    assert tuple(data.voxel_size_um) == tuple(abs(v) for v in pixdim)
    shown = ", ".join(f"{v:g}" for v in pixdim)
    assert f"NIfTI pixdim ({shown}) has negative sizes: their magnitudes are used" in " | ".join(
        data.notes)
    done = cli("info", str(path))
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert "negative sizes" in done.stdout


@pytest.mark.parametrize(("dims", "datatype", "bitpix"),
                         [((3, 1500, 1000, 1000), 512, 16),  # 3 GB of uint16
                          ((4, 1000, 1000, 200, 5), 2, 8),  # 1 GB of uint8 in 5 time points
                          ((3, 700, 700, 700), 16, 32)])  # 1.4 GB of float32
def test_a_tiny_nifti_gzip_declaring_gigabytes_is_refused_before_allocating(tmp_path, dims,
                                                                            datatype, bitpix):
    """A 1 KiB .nii.gz declaring gigabytes: refused from the gzip stream's size, in a child
    limited to 1 GiB more address space (the old reader allocated the whole volume, then
    failed 30–46 s later)."""
    full = (*dims, *([1] * (8 - len(dims))))
    path = edited_nifti(tmp_path / "bomb.nii.gz",
                        [(40, "8h", full), (70, "2h", (datatype, bitpix))], compress=True,
                        voxels=bytes(600))
    assert path.stat().st_size < 1024
    done = read_in_child(path, timeout=60, memory_bytes=_child_limit())
    assert done.returncode == 3, (done.stdout, done.stderr)
    assert "REFUSED bomb.nii.gz: the header declares" in done.stdout
    assert "but the gzip data hold only 952" in done.stdout
    assert done.stderr == ""


def _child_limit() -> int:
    """Address space for a reading child: what the interpreter with vtkvol's readers needs,
    plus 1 GiB."""
    probe = subprocess.run([sys.executable, "-c", "import vtkvol.io, nibabel, h5py, mrcfile\n"
                            "print(open('/proc/self/status').read())"],
                           capture_output=True, text=True, check=True)
    size_kb = next(int(line.split()[1]) for line in probe.stdout.splitlines()
                   if line.startswith("VmSize:"))
    return size_kb * 1024 + 2**30


def test_a_nifti_gzip_of_several_members_is_counted_not_refused(tmp_path):
    """The gzip size check does not refuse a real file whose last member's size field is not
    the whole size (two concatenated members): the stream is counted instead."""
    blob = nifti_bytes((8, 8, 8), np.uint16)
    path = tmp_path / "two.nii.gz"
    path.write_bytes(gzip.compress(blob[:500]) + gzip.compress(blob[500:]))
    data = read_volume(path)
    assert data.array.shape == (1, 8, 8, 8) and int(data.array.max()) == 511


def test_an_uncompressed_nifti_shorter_than_declared_is_refused(tmp_path):
    path = edited_nifti(tmp_path / "short.nii", [(40, "4h", (3, 400, 400, 400))])
    with pytest.raises(VolumeReadError, match=r"^short\.nii: the header declares 64000352 "
                                              r"bytes .* but the file has 472$"):
        read_volume(path)


# -- Imaris -----------------------------------------------------------------------------------
def chars(text: str) -> np.ndarray:
    return np.array([c.encode() for c in text], dtype="S1")


def ims(path: Path, *, level0: str = "group", time_name: str = "TimePoint 0",
        channel_name: str = "Channel 0", more_times: tuple[str, ...] = ()) -> Path:
    """A small Imaris file; ``level0="dataset"`` stores ResolutionLevel 0 as a dataset."""
    with h5py.File(path, "w") as f:
        image = f.create_group("DataSetInfo/Image")
        for key, value in (("X", 4), ("Y", 3), ("Z", 2)):
            image.attrs[key] = chars(str(value))
        if level0 == "dataset":
            f.create_dataset("DataSet/ResolutionLevel 0", data=np.zeros((2, 3, 4), np.uint8))
            return path
        for name in (time_name, *more_times):
            target = f"DataSet/ResolutionLevel 0/{name}/{channel_name}"
            if level0 == "channel-dataset":
                f.create_dataset(target, data=np.zeros((2, 3, 4), np.uint8))
            else:
                f.create_dataset(f"{target}/Data", data=np.zeros((2, 3, 4), np.uint8))
    return path


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"level0": "dataset"}, "/DataSet/ResolutionLevel 0 is an HDF5 dataset, not the group"),
        ({"level0": "channel-dataset"},
         "/DataSet/ResolutionLevel 0/TimePoint 0/Channel 0 is an HDF5 dataset, not the group"),
        ({"time_name": "TimePoint zero"},
         "/DataSet/ResolutionLevel 0/TimePoint zero: expected TimePoint followed by a whole "
         "number"),
        ({"more_times": ("TimePoint 1a",)}, "TimePoint 1a: expected TimePoint followed by"),
        ({"channel_name": "Channel A"},
         "/DataSet/ResolutionLevel 0/TimePoint 0/Channel A: expected Channel followed by a "
         "whole number"),
    ],
    ids=["level-dataset", "channel-dataset", "time-word", "time-suffix", "channel-letter"],
)
def test_imaris_files_of_the_wrong_shape_are_refused_with_their_name(tmp_path, kwargs, message):
    """These raised AttributeError or a builtin ValueError without the file's name."""
    path = ims(tmp_path / "odd.ims", **kwargs)
    with pytest.raises(VolumeReadError) as info:
        read_volume(path)
    assert str(info.value) == f"odd.ims: {message}" or (
        str(info.value).startswith("odd.ims: ") and message in str(info.value)), str(info.value)


def test_a_coarser_imaris_level_that_is_a_dataset_is_refused(tmp_path):
    path = ims(tmp_path / "lvl.ims")
    with h5py.File(path, "a") as f:
        f.create_dataset("DataSet/ResolutionLevel 1", data=np.zeros(3, np.uint8))
    with pytest.raises(VolumeReadError, match=r"^lvl\.ims: /DataSet/ResolutionLevel 1 is an "
                                              r"HDF5 dataset, not the group"):
        read_volume(path)


# -- MRC --------------------------------------------------------------------------------------
def mrc_with_axes(path: Path, axes: tuple[int, int, int]) -> Path:
    with mrcfile.new(str(path), overwrite=True) as mrc:
        mrc.set_data(np.arange(60, dtype=np.int16).reshape(3, 4, 5))
        mrc.voxel_size = 10.0
    blob = bytearray(path.read_bytes())
    struct.pack_into("<3i", blob, 64, *axes)  # mapc, mapr, maps (words 17–19)
    path.write_bytes(bytes(blob))
    return path


@pytest.mark.parametrize("axes", [(1, 1, 7), (0, 0, 0), (3, 3, 3), (1, 2, 4)])
def test_an_impossible_mrc_axis_map_is_refused(tmp_path, axes):
    path = mrc_with_axes(tmp_path / "axes.mrc", axes)
    with pytest.raises(VolumeReadError, match=rf"^axes\.mrc: impossible axis map \(mapc, mapr, "
                                              rf"maps\) = \({axes[0]}, {axes[1]}, {axes[2]}\)"):
        read_volume(path)


@pytest.mark.parametrize("axes", [(3, 2, 1), (2, 1, 3)])
def test_a_permuted_mrc_axis_map_is_read_with_a_note(tmp_path, axes):
    data = read_volume(mrc_with_axes(tmp_path / "perm.mrc", axes))
    assert data.array.shape == (1, 3, 4, 5)
    assert any(f"axis map (mapc, mapr, maps) = {axes}, not (1, 2, 3)" in n for n in data.notes)


# -- keyframes --------------------------------------------------------------------------------
def keyframe_document(**changes) -> dict:
    camera = {"position": [0.0, -100.0, 0.0], "focal_point": [0.0, 0.0, 0.0],
              "view_up": [0.0, 0.0, 1.0]}
    later = {"time": 2.0, "camera": dict(camera, position=[100.0, 0.0, 0.0])}
    doc = {"format": "vtkvol-keyframes", "version": 1,
           "keyframes": [{"time": 0.0, "camera": camera}, later]}
    for key, value in changes.items():
        if key == "time":
            later["time"] = value
        else:
            later["camera"][key] = value
    return doc


@pytest.mark.parametrize("seconds", ["1e308", "1.7976931348623157e308", "1e20"])
def test_a_keyframe_duration_too_long_to_count_is_refused(tmp_path, seconds):
    """1e308 s × 30 fps is infinite: round() raised OverflowError (a traceback)."""
    from vtkvol.model.keyframes import KeyframeError, read_keyframes

    path = tmp_path / "long.keyframes.json"
    path.write_text(json.dumps(keyframe_document(time=float(seconds))))
    animation = read_keyframes(path)
    with pytest.raises(KeyframeError, match=r"s at 30 fps is .* frames; at most 100000"):
        animation.frame_count(30)
    done = cli("render", "sample", "-o", str(tmp_path / "m.png"), "--keyframes", str(path))
    assert done.returncode == 2
    assert_one_line(done.stderr, "long.keyframes.json", "frames; at most 100000")


@pytest.mark.parametrize(
    ("field", "value"),
    [("position", [1e308, 0.0, 0.0]), ("focal_point", [0.0, -1e308, 0.0]),
     ("position", [0.0, 0.0, 10**400]), ("view_up", [0.0, 1e300, 1e300])],
    ids=["position", "focal", "huge-int", "view-up"])
def test_camera_coordinates_too_far_out_are_refused_without_numpy_warnings(tmp_path, field,
                                                                           value):
    """1e308 overflowed numpy (RuntimeWarnings on stderr) into 'view_up is along the view
    direction', which it was not."""
    path = tmp_path / "far.keyframes.json"
    path.write_text(json.dumps(keyframe_document(**{field: value})))
    done = cli("render", "sample", "-o", str(tmp_path / "m.png"), "--keyframes", str(path))
    assert done.returncode == 2, done.stderr
    assert_one_line(done.stderr, f"far.keyframes.json: keyframes[1].camera.{field}",
                    "is too far out: each coordinate must lie within ±1e+12 µm")


def test_a_keyframe_light_direction_too_large_is_refused(tmp_path):
    from vtkvol.model.keyframes import KeyframeError, read_keyframes

    doc = keyframe_document()
    for key in doc["keyframes"]:
        key["lights"] = [{"direction": [1e308, 1e308, 0.0]}]
    path = tmp_path / "light.keyframes.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(KeyframeError, match=r"^light\.keyframes\.json: keyframes\[0\]"
                                            r"\.lights\[0\]\.direction .* is too far out"):
        read_keyframes(path)


# -- transfer-function files ------------------------------------------------------------------
@pytest.mark.parametrize(("depth", "bracket"), [(100_000, "["), (100_000, '{"a":'), (50, "[")])
def test_a_deeply_nested_tf_file_is_refused_in_one_line(tmp_path, depth, bracket):
    """json recursed once per bracket: RecursionError, a traceback in the app's TF dock."""
    pytest.importorskip("PySide6")
    from vtkvol.ui.docks.transfer_function import read_tf_file

    close = "]" if bracket == "[" else "}"
    path = tmp_path / "deep.tf.json"
    path.write_text(bracket * depth + "0" + close * depth)
    with pytest.raises(ValueError) as info:
        read_tf_file(path)
    assert str(info.value) == "deep.tf.json: nested too deeply to be a transfer-function file"


@pytest.mark.parametrize(("text", "message"), [
    ('{"format": "vtkvol-transfer-function", "version": 1, "opacity": [[0, NaN]]}',
     "not valid JSON (NaN is not a number JSON allows)"),
    ('{"format": "vtkvol-transfer-function", "version": 1, "opacity": [[0, 1e999]]}',
     "not valid JSON (1e999 is too large a number)"),
    ('{"format": "vtkvol-transfer-function", "version": 1, "opacity": [[0.0, 2.0]]}',
     "opacity"),
], ids=["nan", "overflow", "validation"])
def test_tf_file_problems_are_one_line(tmp_path, text, message):
    pytest.importorskip("PySide6")
    from vtkvol.ui.docks.transfer_function import read_tf_file

    path = tmp_path / "bad.tf.json"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        read_tf_file(path)
    assert str(info.value).startswith("bad.tf.json: ") and message in str(info.value)
    assert "\n" not in str(info.value)


def test_the_tf_dock_shows_a_deep_file_as_an_error_not_a_traceback(tmp_path, qtbot,
                                                                   monkeypatch):
    """The dock's Load… path: the message box gets the one-line reason; the TF is unchanged."""
    from vtkvol.model.scene import SceneModel
    from vtkvol.ui import errors
    from vtkvol.ui.docks.transfer_function import TransferFunctionDock

    shown: list[str] = []
    monkeypatch.setattr(errors, "show_error",
                        lambda parent, exc, action="": shown.append(f"{action}: {exc}"))
    model = SceneModel()
    dock = TransferFunctionDock(model)
    qtbot.addWidget(dock)
    before = dock.current_tf().copy_state() if dock.current_tf() is not None else None
    path = tmp_path / "deep.tf.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    dock.load_tf(path)
    assert shown == ["Could not load the transfer function: deep.tf.json: nested too deeply "
                     "to be a transfer-function file"]
    after = dock.current_tf().copy_state() if dock.current_tf() is not None else None
    assert after == before
