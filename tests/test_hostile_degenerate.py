"""Hostile inputs that used to get through (issue 28): sessions with impossible or degenerate
cameras and lights, transfer functions of 100 000 points, TIFFs whose page chain loops, folders
whose channels have different slice counts, volumes whose values all round to one float,
unusable data paths given to the library, and third-party warnings on stderr. Every file is
generated here, several variants per class."""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import tifffile
from PIL import Image
from tests_support_hostile import lying_tiff, run_child, snapshot

from vtkvol.cli import main
from vtkvol.io import VolumeReadError, read_volume
from vtkvol.model.defaults import scene_for
from vtkvol.model.session import (
    MAX_COORDINATE_UM,
    SessionError,
    load_session_with_data,
    read_session,
    save_session,
)
from vtkvol.model.transfer_function import MAX_POINTS, TransferFunction


# -- sessions: a small volume and a valid session of it, edited per test ----------------------
@pytest.fixture
def volume_file(tmp_path) -> Path:
    rng = np.random.default_rng(28)
    array = np.zeros((16, 16, 16), np.uint8)
    array[4:12, 4:12, 4:12] = 120 + rng.integers(0, 100, (8, 8, 8), dtype=np.uint8)
    path = tmp_path / "cells.npy"
    np.save(path, array)
    return path


@pytest.fixture
def document(tmp_path, volume_file) -> dict:
    """A valid session of ``volume_file`` with a placed camera (looking down -z)."""
    data = read_volume(volume_file)
    model = scene_for(data)
    model.camera.update({"position": (7.5, 7.5, 80.0), "focal_point": (7.5, 7.5, 7.5),
                         "view_up": (0.0, 1.0, 0.0)})
    path = save_session(tmp_path / "good", model, data=data)
    return json.loads(path.read_text(encoding="utf-8"))


def write(tmp_path: Path, document: dict, name: str, edit) -> Path:
    doc = json.loads(json.dumps(document))
    edit(doc["scene"])
    path = tmp_path / f"{name}.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def camera(**values):
    return lambda scene: scene["camera"].update(values)


def light(index: int = 0, **values):
    return lambda scene: scene["lights"][index].update(values)


IMPOSSIBLE = [
    ("far_position", camera(position=[1e308, 1e308, 1e308]),
     r"camera\.position = \[1e\+308, 1e\+308, 1e\+308\] lies beyond ±1e\+12 µm"),
    ("far_negative_position", camera(position=[0.0, -1e300, 5.0]),
     r"camera\.position = \[0\.0, -1e\+300, 5\.0\] lies beyond ±1e\+12 µm"),
    ("far_focal_point", camera(focal_point=[1e13, 0.0, 0.0]),
     r"camera\.focal_point = \[10000000000000\.0, 0\.0, 0\.0\] lies beyond"),
    ("at_focal_point_zero_up", camera(position=[7.5, 7.5, 7.5], view_up=[0, 0, 0]),
     r"camera\.position = \[7\.5, 7\.5, 7\.5\] is the camera\.focal_point: the camera looks in "
     r"no direction"),
    ("at_focal_point", camera(position=[7.5, 7.5, 7.5]),
     r"camera\.position = \[7\.5, 7\.5, 7\.5\] is the camera\.focal_point"),
    ("huge_parallel_scale", camera(parallel_projection=True, parallel_scale=1e300),
     r"camera\.parallel_scale = 1e\+300 is above 1e\+12 µm"),
    ("light_direction_overflows", light(direction=[1e200, 1e200, 1e200]),
     r"lights\[0\]\.direction: light direction \(1e\+200, 1e\+200, 1e\+200\) is too long "
     r"\(its squared length overflows\)"),
    ("light_direction_one_axis_overflows", light(direction=[0.0, -1e160, 0.0]),
     r"lights\[0\]\.direction: light direction \(0\.0, -1e\+160, 0\.0\) is too long"),
    ("far_point_light", light(kind="point", position=[0.0, 0.0, 1e308]),
     r"lights\[0\]\.position = \[0\.0, 0\.0, 1e\+308\] lies beyond"),
]


@pytest.mark.parametrize(("name", "edit", "message"), IMPOSSIBLE,
                         ids=[case[0] for case in IMPOSSIBLE])
def test_a_session_that_cannot_describe_a_view_is_refused_naming_the_field(
        tmp_path, document, name, edit, message):
    path = write(tmp_path, document, name, edit)
    with pytest.raises(SessionError, match=rf"^{name}\.vtkvol\.json: {message}"):
        read_session(path)


DEGENERATE_UP = [
    # (name, camera position, view_up, the repaired view_up)
    ("zero_up", [7.5, 7.5, 80.0], [0, 0, 0], (0.0, 1.0, 0.0)),
    ("up_along_the_view", [7.5, 7.5, 80.0], [0, 0, -3.0], (0.0, 1.0, 0.0)),
    ("zero_up_looking_down_y", [7.5, 90.0, 7.5], [0, 0, 0], (0.0, 0.0, 1.0)),
    ("huge_up_along_the_view", [7.5, 7.5, 80.0], [0, 0, 1e300], (0.0, 1.0, 0.0)),
    ("zero_up_oblique", [50.0, 7.5, 50.0], [0, 0, 0], (0.0, 1.0, 0.0)),
]


@pytest.mark.parametrize(("name", "position", "up", "repaired"), DEGENERATE_UP,
                         ids=[case[0] for case in DEGENERATE_UP])
def test_a_degenerate_view_up_is_repaired_with_a_note(tmp_path, document, name, position, up,
                                                      repaired):
    path = write(tmp_path, document, name, camera(position=position, view_up=up))
    session = read_session(path)
    got = session.model.camera.view_up
    assert got == pytest.approx(repaired, abs=1e-12)
    forward = np.subtract(session.model.camera.focal_point, position)
    assert abs(np.dot(got, forward)) < 1e-9 * np.linalg.norm(forward)  # across the view
    assert [n for n in session.warnings if n.startswith("camera.view_up = ")] == [
        f"camera.view_up = {json.dumps([float(c) for c in up])} is "
        f"{'zero' if not any(up) else 'along the view direction'}; replaced by "
        f"{json.dumps(list(repaired))}"]


def test_a_usable_view_up_is_kept_as_saved(tmp_path, document):
    path = write(tmp_path, document, "tilted", camera(view_up=[0.2, 3.0, 0.0]))
    session = read_session(path)
    assert session.model.camera.view_up == (0.2, 3.0, 0.0) and session.warnings == []


def test_the_coordinate_limit_leaves_real_views_alone(tmp_path, document):
    edge = MAX_COORDINATE_UM
    path = write(tmp_path, document, "edge", camera(position=[7.5, 7.5, edge]))
    assert read_session(path).model.camera.position == (7.5, 7.5, edge)


def render(args: list[str], capsys) -> tuple[int, list[str], str]:
    code = main(["render", *args, "--size", "48", "40", "--method", "local"])
    captured = capsys.readouterr()
    return code, captured.err.splitlines(), captured.out


@pytest.mark.parametrize("case", [0, 3, 6], ids=[IMPOSSIBLE[i][0] for i in (0, 3, 6)])
def test_render_refuses_an_impossible_session_in_one_line_and_writes_nothing(
        tmp_path, document, capsys, case):
    name, edit, _ = IMPOSSIBLE[case]
    path = write(tmp_path, document, name, edit)
    out = tmp_path / "view.png"
    code, err, _ = render([str(path), "-o", str(out)], capsys)
    assert code == 1 and len(err) == 1, err
    assert err[0].startswith(f"vtkvol: {name}.vtkvol.json: ")
    assert not out.exists()


def test_render_of_a_zero_view_up_draws_the_repaired_view_with_a_note(tmp_path, document,
                                                                       capsys):
    good = write(tmp_path, document, "upright", camera(view_up=[0, 1, 0]))
    zero = write(tmp_path, document, "zero", camera(view_up=[0, 0, 0]))
    assert render([str(good), "-o", str(tmp_path / "good.png")], capsys)[0] == 0
    code, err, _ = render([str(zero), "-o", str(tmp_path / "zero.png")], capsys)
    assert code == 0
    assert err == ["vtkvol: zero.vtkvol.json: camera.view_up = [0.0, 0.0, 0.0] is zero; "
                   "replaced by [0.0, 1.0, 0.0]"]
    a, b = (np.asarray(Image.open(tmp_path / f"{n}.png")) for n in ("good", "zero"))
    background = a[0, 0].astype(int)
    assert np.abs(a.astype(int) - background).max() > 40  # the cells are drawn …
    assert np.abs(a.astype(int) - b.astype(int)).mean() < 1.0  # … the same way



# -- very large transfer functions ------------------------------------------------------------
def steps(n: int) -> tuple[list, list]:
    """``n`` points alternating between transparent and opaque, colours cycling."""
    xs = np.linspace(0.0, 255.0, n)
    colors = [[float(x), (i % 3) / 2, 0.5, 1.0 - (i % 2)] for i, x in enumerate(xs)]
    return colors, [[float(x), float(i % 2)] for i, x in enumerate(xs)]


def ramp(n: int) -> tuple[list, list]:
    xs = np.linspace(40.0, 220.0, n)
    return ([[float(x), float(x) / 255, 0.2, 0.9] for x in xs],
            [[float(x), float((x - 40) / 180) ** 2] for x in xs])


LARGE_TFS = [
    ("steps_100000", *steps(100_000)),
    ("ramp_5000", *ramp(5000)),
    ("colours_only", steps(20_000)[0], [[0.0, 0.0], [255.0, 0.7]]),
    ("opacity_only", [[0.0, 0.1, 0.1, 0.1], [255.0, 1.0, 1.0, 1.0]], ramp(MAX_POINTS + 1)[1]),
]


@pytest.mark.parametrize(("name", "colors", "opacity"), LARGE_TFS,
                         ids=[case[0] for case in LARGE_TFS])
def test_a_session_with_a_huge_transfer_function_is_reduced_with_a_note(
        tmp_path, document, name, colors, opacity):
    def edit(scene):
        scene["channels"][0]["tf"].update(colors=colors, opacity=opacity)

    path = write(tmp_path, document, name, edit)
    t0 = time.perf_counter()
    session = read_session(path)
    assert time.perf_counter() - t0 < 30
    tf = session.model.channels[0].tf
    assert len(tf.colors) == min(len(colors), MAX_POINTS)
    assert len(tf.opacity) == min(len(opacity), MAX_POINTS)
    counts = [f"{len(p)} {what}" for what, p in (("colour", colors), ("opacity", opacity))
              if len(p) > MAX_POINTS]
    [note] = [n for n in session.warnings if n.startswith("channels[0].tf:")]
    assert note.startswith(f"channels[0].tf: {' and '.join(counts)} points reduced to "
                           f"{MAX_POINTS} (the function sampled evenly over ")
    # The reduced function is the original one wherever it is smooth at the new spacing.
    original = TransferFunction(colors=colors, opacity=opacity, window=tf.window,
                                window_range=tf.window_range)
    values = np.linspace(*tf.value_span, 997)
    if name.startswith("ramp") or name == "opacity_only":
        assert np.abs(tf.opacity_at(values) - original.opacity_at(values)).max() < 1e-3
    assert tf.opacity[0] == tuple(opacity[0]) and tf.opacity[-1] == tuple(opacity[-1])
    assert tf.colors[0][0] == colors[0][0] and tf.colors[-1][0] == colors[-1][0]


def test_a_huge_transfer_function_renders_in_bounded_time(tmp_path, volume_file):
    """Handing 100 000 points to VTK one by one took minutes (it re-sorts per point); the
    library's render_image of such a model (no session, no note) now takes seconds."""
    code = f"""
    import time
    import numpy as np
    from vtkvol.engine.api import render_image
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.transfer_function import TransferFunction
    data = read_volume({str(volume_file)!r})
    model = scene_for(data)
    xs = np.linspace(0.0, 255.0, 100_000)
    model.channels[0].tf = TransferFunction(
        colors=[(float(x), 1.0, 0.5, 0.2) for x in xs],
        opacity=[(float(x), 0.0 if x < 100 else 0.8) for x in xs],
        window=(0.0, 255.0), window_range=(0.0, 255.0))
    t0 = time.perf_counter()
    image = render_image(data, model=model, size=(48, 40), method="local")
    print("seconds", time.perf_counter() - t0, "spread", int(np.ptp(image)))
    """
    result = run_child(code, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    words = result.stdout.split()
    assert float(words[1]) < 60 and int(words[3]) > 40, result.stdout


# -- TIFF page chains that loop ----------------------------------------------------------------
@pytest.mark.parametrize(("pages", "loop_to"), [(1, 0), (2, 0), (3, 0), (3, 1), (3, 2), (4, 3)],
                         ids=["self_1", "first_of_2", "first_of_3", "middle_of_3", "self_3",
                              "self_4"])
def test_a_tiff_whose_page_chain_loops_is_refused_as_damaged(tmp_path, pages, loop_to):
    path = lying_tiff(tmp_path / "loop.tif", pages=pages, data=bytes(range(16)), loop_to=loop_to)
    before = snapshot(tmp_path)
    with pytest.raises(VolumeReadError, match=r"^loop\.tif: corrupt or truncated TIFF \(its "
                                              r"chain of pages loops back on itself: invalid "
                                              r"circular reference to IFD \d+"):
        read_volume(path)
    assert snapshot(tmp_path) == before


def test_a_looping_slice_in_a_folder_is_refused(tmp_path):
    folder = tmp_path / "stack"
    folder.mkdir()
    for z in range(3):
        tifffile.imwrite(folder / f"z{z}.tif", np.full((4, 4), z, np.uint8))
    lying_tiff(folder / "z1.tif", pages=1, data=bytes(16), circular=True)
    with pytest.raises(VolumeReadError, match=r"^z1\.tif: corrupt or truncated TIFF \(its chain "
                                              r"of pages loops back on itself"):
        read_volume(folder)


def test_info_refuses_a_looping_tiff_in_one_line(tmp_path, capsys):
    path = lying_tiff(tmp_path / "loop.tif", pages=3, data=bytes(16), circular=True)
    assert main(["info", str(path)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("vtkvol: loop.tif: corrupt or truncated TIFF (its chain")
    assert len(captured.err.splitlines()) == 1


# -- folders whose channels have different numbers of slices ----------------------------------
@pytest.mark.parametrize(
    ("pattern", "counts"),
    [("img_c{c}_z{z}.tif", (5, 3)), ("img_c{c}_z{z}.tif", (2, 6)),
     ("cell_ch{c}_{z:03d}.tif", (4, 4, 1)), ("C{c}-plane{z}.tif", (3, 2))],
    ids=["c0_more", "c1_more", "three_channels", "fiji_names"],
)
def test_a_folder_with_unequal_channel_slice_counts_is_refused_naming_them(tmp_path, pattern,
                                                                           counts):
    folder = tmp_path / "slices"
    folder.mkdir()
    first = 1 if pattern.startswith("C") else 0
    for c, n in enumerate(counts, start=first):
        for z in range(n):
            tifffile.imwrite(folder / pattern.format(c=c, z=z), np.full((6, 5), 10 * c, np.uint8))
    listed = ", ".join(f"c{c}: {n}" for c, n in enumerate(counts, start=first))
    with pytest.raises(VolumeReadError, match=(
            rf"^slices: the file names give {len(counts)} channels with different numbers of "
            rf"slices \({listed}\); nothing was read")):
        read_volume(folder)


def test_a_folder_with_equal_channel_slice_counts_still_reads_each_channel(tmp_path):
    folder = tmp_path / "slices"
    folder.mkdir()
    for c in range(2):
        for z in range(3):
            tifffile.imwrite(folder / f"img_c{c}_z{z}.tif", np.full((6, 5), 10 * c + z, np.uint8))
    data = read_volume(folder)
    assert data.channel_names == ["c0", "c1"] and data.shape_zyx == (3, 6, 5)
    assert data.array[1, :, 0, 0].tolist() == [10, 11, 12]


# -- volumes whose values all round to one float -----------------------------------------------
@pytest.mark.parametrize(
    "values",
    [np.full(512, 2**64 - 1, np.uint64),
     np.uint64(2**64 - 1) - np.arange(512, dtype=np.uint64),
     np.int64(2**63 - 1) - np.arange(512, dtype=np.int64),
     np.full(512, -(2**63), np.int64)],
    ids=["uint64_max", "uint64_near_max", "int64_near_max", "int64_min"],
)
def test_a_volume_whose_values_round_to_one_float_gets_a_valid_scene(tmp_path, values):
    path = tmp_path / "big.npy"
    np.save(path, values.reshape(8, 8, 8))
    data = read_volume(path)
    assert any("the same value" in n for n in data.notes)
    tf = scene_for(data).channels[0].tf
    lo, hi = tf.value_span
    assert hi > lo and tf.window[1] > tf.window[0]
    assert np.float32(hi) > np.float32(lo)  # still a range in the GPU's float32


def test_render_of_a_uint64_volume_near_2_64_is_the_constant_volume_with_a_note(tmp_path,
                                                                                capsys):
    path = tmp_path / "big.npy"
    np.save(path, np.uint64(2**64 - 1) - np.arange(512, dtype=np.uint64).reshape(8, 8, 8))
    code, err, out = render([str(path), "-o", str(tmp_path / "big.png")], capsys)
    assert code == 0, err
    assert err == ["vtkvol: big.npy: every voxel of each channel has the same value "
                   "(1.84467e+19); the volume will look uniform"]
    assert out.startswith("wrote ")


# -- unusable data paths given to the library --------------------------------------------------
@pytest.mark.parametrize(
    ("data_path", "why"),
    [("cells\0.npy", "it contains a NUL character"), ("\0", "it contains a NUL character"),
     ("x" * 5000, "file name too long"), ("/tmp/" + "y" * 300 + "/a.npy", "file name too long")],
    ids=["nul", "only_nul", "5000_chars", "long_folder_name"],
)
def test_load_session_with_an_unusable_chosen_data_path_raises_session_error(
        tmp_path, document, data_path, why):
    path = write(tmp_path, document, "view", lambda scene: None)
    with pytest.raises(SessionError) as info:
        load_session_with_data(path, data_path=data_path)
    assert str(info.value).startswith("view.vtkvol.json: the chosen data file ")
    assert str(info.value).endswith(f"is not a usable path ({why})")


@pytest.mark.parametrize(("stored", "why"), [("cells\0.npy", "it contains a NUL character"),
                                             ("z" * 5000, "file name too long")],
                         ids=["nul", "5000_chars"])
def test_a_session_storing_an_unusable_data_path_raises_session_error(tmp_path, document, stored,
                                                                      why):
    document["data"]["path"] = stored
    path = write(tmp_path, document, "view", lambda scene: None)
    for call in (read_session, load_session_with_data):
        with pytest.raises(SessionError, match=rf"^view\.vtkvol\.json: data\.path = \".+ is not "
                                               rf"a usable path \({why}\)$"):
            call(path)


def test_a_session_path_with_a_nul_raises_session_error():
    with pytest.raises(SessionError, match=r"^view\\0\.vtkvol\.json: the path contains a NUL "):
        read_session("view\0.vtkvol.json")


# -- warnings of other libraries ---------------------------------------------------------------
def nrrd(path: Path, directions: str) -> Path:
    path.write_bytes(b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n"
                     b"space dimension: 3\nspace directions: " + directions.encode()
                     + b"\n\n" + bytes(64))
    return path


@pytest.mark.parametrize(
    ("directions", "axis", "shown", "length"),
    [("(0,0,0) (0,1,0) (0,0,1)", 0, "(0.0, 0.0, 0.0)", "0"),
     ("(1,0,0) (0,0,0) (0,0,1)", 1, "(0.0, 0.0, 0.0)", "0"),
     ("(1,0,0) (0,1,0) (0,0,-0)", 2, "(0.0, 0.0, -0.0)", "0"),
     ("(1,0,0) (0,nan,0) (0,0,1)", 1, "(0.0, nan, 0.0)", "nan")],
    ids=["axis0", "axis1", "axis2_negative_zero", "nan"],
)
def test_a_zero_nrrd_space_direction_is_refused_without_a_numpy_warning(
        tmp_path, capsys, directions, axis, shown, length):
    path = nrrd(tmp_path / "zero.nrrd", directions)
    problem = (f"space direction {axis} of the NRRD header, {shown}, has length {length}: a "
               "voxel's edge must be a finite length > 0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's RuntimeWarning fails the test
        with pytest.raises(VolumeReadError) as info:
            read_volume(path)
    assert str(info.value) == f"zero.nrrd: {problem}"
    assert main(["info", str(path)]) == 1
    assert capsys.readouterr().err == f"vtkvol: zero.nrrd: {problem}\n"


def test_session_notes_on_the_command_line_are_one_line_each(tmp_path, document, capsys):
    """No multi-line SessionWarning with the source path of the call."""
    def edit(scene):
        del scene["overlays"]
        scene["camera"]["view_up"] = [0, 0, 0]

    path = write(tmp_path, document, "notes", edit)
    code, err, _ = render([str(path), "-o", str(tmp_path / "n.png")], capsys)
    assert code == 0
    assert err == [
        "vtkvol: notes.vtkvol.json: missing from the file, defaults used: overlays",
        "vtkvol: notes.vtkvol.json: camera.view_up = [0.0, 0.0, 0.0] is zero; replaced by "
        "[0.0, 1.0, 0.0]"]


def test_a_session_naming_an_unknown_method_is_refused_in_one_line(tmp_path, document, capsys):
    path = write(tmp_path, document, "unknown",
                 lambda scene: scene["illumination"].update(method="no_such_method"))
    out = tmp_path / "u.png"
    code = main(["render", str(path), "-o", str(out), "--size", "32", "32"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("vtkvol: unknown.vtkvol.json: illumination.method: unknown "
                             "illumination method 'no_such_method'; available: ")
    assert err[0].endswith("(or pass --method)") and not out.exists()


def test_a_library_warning_during_a_command_is_one_line(monkeypatch, capsys, tmp_path):
    """Whatever warns (numpy, a reader's dependency), the user sees one line; --verbose leaves
    warnings to Python (here: to pytest, which records them)."""
    import vtkvol.cli as cli

    def noisy(args):
        np.float32(1.0) / np.zeros(1, np.float32)  # RuntimeWarning: divide by zero
        warnings.warn("a dependency is\nunhappy", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(cli, "cmd_info", noisy)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["info", "x.tif"]) == 0
        assert capsys.readouterr().err.splitlines() == [
            "vtkvol: note: RuntimeWarning: divide by zero encountered in divide",
            "vtkvol: note: a dependency is unhappy"]
        with pytest.warns(RuntimeWarning, match="divide by zero"):
            assert main(["info", "x.tif", "--verbose"]) == 0
        assert "vtkvol: note" not in capsys.readouterr().err


def test_nothing_is_changed_by_a_refused_session(tmp_path, document, volume_file):
    path = write(tmp_path, document, "far", camera(position=[1e308, 0, 0]))
    before = snapshot(tmp_path)
    with pytest.raises(SessionError):
        load_session_with_data(path)
    assert snapshot(tmp_path) == before
