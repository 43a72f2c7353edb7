"""Session files: round trip, paths, atomic writes, bad files, data checks, migrations.

No GL, no Qt: data files are small ``.npy`` volumes read through :func:`vtkvol.io.read_volume`.
Fixture files live in ``tests/fixtures/sessions/`` (one per migration, plus broken ones).
"""

from __future__ import annotations

import copy
import hashlib
import json
import re
import shutil
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from vtkvol.io import read_volume
from vtkvol.model import (
    Camera,
    Channel,
    CropBox,
    Illumination,
    Light,
    Param,
    RenderSettings,
    SceneModel,
    SliceWeights,
    TransferFunction,
)
from vtkvol.model import session as session_mod
from vtkvol.model.migrations import MIGRATIONS, detect_version
from vtkvol.model.scene import ClipPlane, LabelDisplay, Overlays
from vtkvol.model.session import (
    FORMAT,
    SUFFIX,
    VERSION,
    DataMismatchError,
    MissingDataError,
    Session,
    SessionError,
    SessionWarning,
    load_session_with_data,
    migrate,
    read_session,
    save_session,
)
from vtkvol.model.techniques import TechniqueSpec, register
from vtkvol.model.tf_paint import TFPaintLayer, apply_stroke, stroke_mask
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D

FIXTURES = Path(__file__).parent / "fixtures" / "sessions"
HEADER = '{"format": "vtkvol-session", "version": 1, '
WINDOW = {"geometry": "AdnQywADAAAAAAB4", "state": "AAAA/wAAAAD9AAAA", "docks": {"tf": True}}


# -- a technique with declared parameters (the installed built-in "local" declares none) ------
FAKE_SHADOWS = TechniqueSpec(
    name="fake_shadows",
    label="Fake shadows",
    engine="nowhere.fake_shadows:FakeShadows",  # sessions never import the engine part
    parameters=(
        Param("density", 1.0, "Density", "Shadow density.", range=(0.0, 5.0), unit="voxel"),
        Param("steps", 16, "Steps", "March steps.", kind="int", range=(1, 64)),
        Param("soft", True, "Soft", "Soft shadows.", kind="bool"),
        Param("quality", "high", "Quality", "Preset.", kind="choice", choices=("low", "high")),
    ),
)


@pytest.fixture(autouse=True)
def fake_technique() -> Iterator[None]:
    """Make "fake_shadows" a registered technique for every test."""
    with register(FAKE_SHADOWS):
        yield


# -- helpers ----------------------------------------------------------------------------------
def make_data(path: Path, shape_czyx: tuple[int, ...] = (2, 4, 5, 6), seed: int = 0) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    arr = np.random.default_rng(seed).integers(0, 255, shape_czyx).astype(np.uint8)
    np.save(path, arr)
    return path


def rich_paint() -> TFPaintLayer:
    """A small painted layer: an orange dab and a half-transparent blue one (8 × 6 pixels)."""
    layer = TFPaintLayer.blank((20.0, 220.0), (0.0, 40.0), shape=(6, 8))
    pixels = apply_stroke(layer.pixels(), stroke_mask(layer.shape, [(2.0, 2.0)], 1.2),
                          (1.0, 0.5, 0.0), 0.6)
    pixels = apply_stroke(pixels, stroke_mask(layer.shape, [(6.0, 4.0)], 1.0),
                          (0.0, 0.2, 1.0), 0.3)
    return layer.with_pixels(pixels)


def rich_model() -> SceneModel:
    """A scene with every part set away from its default."""
    return SceneModel(
        channels=[
            Channel(
                name="nuclei",
                color=(0.1, 1.0, 0.3),
                tf=TransferFunction(
                    colors=[(10.0, 0.0, 0.0, 0.0), (90.0, 0.0, 0.5, 0.1), (200.0, 0.1, 1.0, 0.3)],
                    opacity=[(10.0, 0.0), (120.0, 0.25), (200.0, 0.6)],
                    window=(0.0, 230.0),
                    window_range=(0.0, 255.0),
                ),
                tf_mode="2d",
                tf2d=TransferFunction2D(
                    primitives=[
                        TFPrimitive(value_range=(40.0, 180.0), gradient_range=(0.0, 12.5),
                                    color=(0.2, 0.9, 0.4), opacity=0.3, soft_edge=0.25),
                        TFPrimitive(kind="triangle", value_range=(60.0, 220.0),
                                    gradient_range=(2.0, 40.0), color=(1.0, 0.5, 0.1),
                                    opacity=0.8),
                    ],
                    gradient_max=50.0,
                    paint=rich_paint(),
                ),
            ),
            Channel(name="membrane", visible=False, color=(1.0, 0.2, 1.0), tf_linked_to=0),
        ],
        lights=[
            Light(direction=(0.0, 0.0, 1.0), intensity=2.5, color=(1.0, 0.9, 0.8), size=0.5),
            Light(kind="point", position=(10.0, -5.0, 40.0), intensity=0.5, enabled=False,
                  size=2.0, falloff="inverse_square"),
        ],
        illumination=Illumination(
            method="fake_shadows",
            parameters={
                "fake_shadows": {"density": 2.5, "steps": 32, "soft": False, "quality": "low"},
                "local": {},
            },
            auto=True,
            auto_budget_ssim=0.95,
        ),
        crop=CropBox(x=(0.5, 3.5), z=(1.0, 2.0)),
        slice_weights=SliceWeights(z=[(0.0, 0.0), (0.5, 1.0), (1.0, 0.2)]),
        camera=Camera(
            position=(12.0, -30.0, 45.5), focal_point=(2.5, 2.0, 1.5), view_up=(0.0, 0.0, 1.0),
            view_angle=25.0, parallel_projection=True, parallel_scale=7.5,
        ),
        render=RenderSettings(
            blend_mode="mip", channel_mixing="composite", sample_distance=0.25, jitter=False,
            ambient=0.1, specular_power=64.0, opacity_unit_distance=2.0,
            background=(1.0, 1.0, 1.0), albedo=0.8, phase_g=0.3, interpolation="corrected",
            empty_space_skipping=False, multichannel_lighting="shared",
            # What files before v9 rendered with (no automatic exposure, no fill light).
            exposure=1.0, auto_exposure=False, fill=0.0,
        ),
        overlays=Overlays(scale_bar=True, orientation_axes=True, bounding_box=True,
                          color_legend=True, slice_planes=True),
        clip_plane=ClipPlane(enabled=True, origin=(2.0, 2.5, 1.0), normal=(0.6, 0.0, 0.8)),
        cursor=(1.5, 2.0, 3.0),
    )


def write_json(path: Path, doc: Any) -> Path:
    path.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    return path


def saved_doc(tmp_path: Path, **changes: Any) -> dict[str, Any]:
    """A valid current-version document (as save_session writes it), for editing."""
    path = save_session(tmp_path / "base", SceneModel())
    doc = json.loads(path.read_text(encoding="utf-8"))
    path.unlink()
    doc.update(changes)
    return doc


def tree(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` with the hash of its content (to prove what was written)."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


# -- round trip -------------------------------------------------------------------------------
def test_round_trip_restores_every_setting(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    data = read_volume(data_file)
    model = rich_model()
    path = save_session(tmp_path / "view.vtkvol.json", model, data=data, window=WINDOW)

    session = read_session(path)
    assert isinstance(session, Session)
    assert session.warnings == []
    assert session.model == model
    assert session.window == WINDOW
    assert session.path == path
    assert session.data_path == data_file.resolve()
    # Spot checks on the parts the issue names, beyond model equality.
    m = session.model
    assert m.channels[0].tf.opacity == [(10.0, 0.0), (120.0, 0.25), (200.0, 0.6)]
    assert m.slice_weights.z == [(0.0, 0.0), (0.5, 1.0), (1.0, 0.2)]
    assert m.crop.x == (0.5, 3.5) and m.crop.y is None
    assert m.lights[1].kind == "point" and m.lights[0].intensity == 2.5
    assert m.illumination.parameters["fake_shadows"] == {
        "density": 2.5, "steps": 32, "soft": False, "quality": "low"
    }
    assert m.camera.parallel_scale == 7.5 and m.render.blend_mode == "mip"

    loaded, loaded_data = load_session_with_data(path)
    assert loaded == model
    assert loaded_data.shape_zyx == data.shape_zyx
    np.testing.assert_array_equal(loaded_data.array, data.array)


def test_save_records_data_fingerprint_in_model_and_file(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    model = SceneModel(channels=[Channel(), Channel()])
    events: list[frozenset[str]] = []
    model.changed.connect(events.append)
    path = save_session(tmp_path / "v", model, data=read_volume(data_file))

    blob = data_file.read_bytes()
    vol = model.volume
    assert vol.path == str(data_file.resolve())
    assert vol.size_bytes == len(blob)
    assert vol.sha256_head == hashlib.sha256(blob[: 2**20]).hexdigest()
    assert vol.shape_zyx == (4, 5, 6) and vol.channels == 2
    assert len(events) == 1  # recorded in one batch

    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["format"] == FORMAT and doc["version"] == VERSION
    assert set(doc) == {"format", "version", "vtkvol", "saved", "data", "scene", "window"}
    assert doc["data"] == {
        "path": "cells.npy", "size_bytes": len(blob), "sha256_head": vol.sha256_head,
        "shape_zyx": [4, 5, 6], "channels": 2,
    }
    # The scene is the model's own dump: every field, no hand-kept list.
    assert set(doc["scene"]) == set(SceneModel.model_fields)


def test_apply_to_updates_target_in_one_event(tmp_path: Path) -> None:
    path = save_session(tmp_path / "v", rich_model(), window=WINDOW)
    target = SceneModel()
    crop = target.crop
    events: list[frozenset[str]] = []
    target.changed.connect(events.append)

    read_session(path).apply_to(target)

    assert target == read_session(path).model
    assert len(events) == 1
    assert target.crop is crop  # nested models updated in place: bound views stay bound


# -- paths ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("data_rel", "session_rel", "stored"),
    [
        ("cells.npy", "view.vtkvol.json", "cells.npy"),
        ("raw/day1/cells.npy", "view.vtkvol.json", "raw/day1/cells.npy"),
        ("data/cells.npy", "sessions/view.vtkvol.json", None),  # outside: absolute
    ],
)
def test_data_path_relative_when_beside_or_below(
    tmp_path: Path, data_rel: str, session_rel: str, stored: str | None
) -> None:
    data_file = make_data(tmp_path / data_rel)
    (tmp_path / session_rel).parent.mkdir(parents=True, exist_ok=True)
    path = save_session(
        tmp_path / session_rel, SceneModel(channels=[Channel()] * 2), data=read_volume(data_file)
    )
    doc = json.loads(path.read_text(encoding="utf-8"))
    expected = stored if stored is not None else str(data_file.resolve())
    assert doc["data"]["path"] == expected
    assert Path(doc["data"]["path"]).is_absolute() == (stored is None)
    assert read_session(path).data_path == data_file.resolve()


def test_relative_path_survives_moving_the_whole_folder(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "project" / "raw" / "cells.npy")
    save_session(tmp_path / "project" / "view", SceneModel(channels=[Channel()] * 2),
                 data=read_volume(data_file))
    shutil.move(tmp_path / "project", tmp_path / "moved")
    model, data = load_session_with_data(tmp_path / "moved" / "view.vtkvol.json")
    assert model.volume.path == str((tmp_path / "moved" / "raw" / "cells.npy").resolve())
    assert data.shape_zyx == (4, 5, 6)


@pytest.mark.parametrize(
    ("name", "written"),
    [
        ("view.vtkvol.json", "view.vtkvol.json"),
        ("view", "view.vtkvol.json"),
        ("view.vtkvol", "view.vtkvol.json"),
        ("view.json", "view.json.vtkvol.json"),
        ("cells.npy", "cells.npy.vtkvol.json"),  # never replaces the data it describes
    ],
)
def test_suffix_is_appended(tmp_path: Path, name: str, written: str) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    before = data_file.read_bytes()
    path = save_session(tmp_path / name, SceneModel())
    assert path == tmp_path / written
    assert path.name.endswith(SUFFIX)
    assert data_file.read_bytes() == before


# -- writing safely ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "content",
    [b"\x93NUMPY\x01\x00v\x00{'descr': '|u1'}", b'{"results": [1, 2, 3]}', b"[1, 2]", b"not json"],
)
def test_refuses_to_overwrite_a_file_that_is_not_a_session(tmp_path: Path, content: bytes) -> None:
    target = tmp_path / "results.vtkvol.json"
    target.write_bytes(content)
    with pytest.raises(SessionError, match="is not a vtkvol session; not overwriting it"):
        save_session(target, SceneModel())
    assert target.read_bytes() == content
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.vtkvol.json"]


def test_overwrites_an_existing_session_and_an_empty_file(tmp_path: Path) -> None:
    path = save_session(tmp_path / "v", SceneModel())
    save_session(path, rich_model())
    assert read_session(path).model == rich_model()
    empty = tmp_path / "empty.vtkvol.json"
    empty.touch()
    save_session(empty, SceneModel())
    assert read_session(empty).model == SceneModel()


def test_overwrites_a_v0_session(tmp_path: Path) -> None:
    target = tmp_path / "old.vtkvol.json"
    shutil.copy(FIXTURES / "v0_pre_release.vtkvol.json", target)
    save_session(target, SceneModel())
    assert json.loads(target.read_text(encoding="utf-8"))["version"] == VERSION


def test_failed_replace_keeps_old_file_and_leaves_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = save_session(tmp_path / "v", SceneModel())
    before = path.read_bytes()

    def broken_replace(src: Any, dst: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(session_mod.os, "replace", broken_replace)
    model = rich_model()
    with pytest.raises(SessionError, match="could not be written: No space left on device"):
        save_session(path, model, data=read_volume(make_data(tmp_path / "d" / "cells.npy")))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "v.vtkvol.json"]
    assert model.volume.shape_zyx is None  # a failed save records nothing in the model


def test_failure_mid_write_keeps_old_file_and_leaves_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = save_session(tmp_path / "v", SceneModel())
    before = path.read_bytes()

    def crash(fd: int) -> None:  # the temp file has been written but not renamed yet
        raise KeyboardInterrupt

    monkeypatch.setattr(session_mod.os, "fsync", crash)
    with pytest.raises(KeyboardInterrupt):
        save_session(path, rich_model())
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["v.vtkvol.json"]


def test_failed_serialisation_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = save_session(tmp_path / "v", SceneModel())
    before = path.read_bytes()

    def broken_dumps(*args: Any, **kwargs: Any) -> str:
        raise ValueError("Out of range float values are not JSON compliant")

    monkeypatch.setattr(session_mod.json, "dumps", broken_dumps)
    with pytest.raises(SessionError, match="not finite"):
        save_session(path, rich_model())
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["v.vtkvol.json"]


def test_non_finite_value_and_non_json_window_are_refused(tmp_path: Path) -> None:
    model = SceneModel()
    model.camera.position = (float("nan"), 0.0, 1.0)
    with pytest.raises(SessionError, match="not finite"):
        save_session(tmp_path / "a", model)
    with pytest.raises(SessionError, match="is not JSON data"):
        save_session(tmp_path / "b", SceneModel(), window={"geometry": b"\x01\x02"})
    odd = SceneModel()
    odd.illumination.set_value("density", object(), method="fake_shadows")
    with pytest.raises(SessionError, match="is not JSON data"):
        save_session(tmp_path / "c", odd)
    assert list(tmp_path.iterdir()) == []


def test_numpy_parameter_values_are_saved_as_numbers(tmp_path: Path) -> None:
    model = SceneModel()
    model.illumination.method = "fake_shadows"
    model.illumination.set_value("density", np.float32(2.5))
    model.illumination.set_value("steps", np.int64(8))
    session = read_session(save_session(tmp_path / "v", model))
    assert session.model.illumination.parameters == {"fake_shadows": {"density": 2.5, "steps": 8}}


def test_save_refuses_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(SessionError, match="does not exist"):
        save_session(tmp_path / "nope" / "v", SceneModel())
    assert list(tmp_path.iterdir()) == []


def test_only_the_chosen_file_is_ever_written(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    before = tree(tmp_path)
    path = save_session(tmp_path / "v", rich_model(), data=read_volume(data_file), window=WINDOW)
    after_save = tree(tmp_path)
    assert set(after_save) - set(before) == {"v.vtkvol.json"}
    assert {k: v for k, v in after_save.items() if k != "v.vtkvol.json"} == before

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_session(path)
        load_session_with_data(path)
    assert tree(tmp_path) == after_save


def test_strings_are_data_never_code(tmp_path: Path) -> None:
    doc = saved_doc(tmp_path)
    payload = "__import__('os').system('touch pwned')"
    doc["scene"]["channels"][0]["name"] = payload
    doc["window"] = {"geometry": "${HOME}", "state": payload}
    path = write_json(tmp_path / "v.vtkvol.json", doc)
    session = read_session(path)
    assert session.model.channels[0].name == payload
    assert session.window["state"] == payload


# -- bad files --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("fixture", "message"),
    [
        ("broken_invalid_json.vtkvol.json",
         "broken_invalid_json.vtkvol.json: is not valid JSON: Expecting ',' delimiter "
         "at line 5, column 3"),
        ("broken_wrong_types.vtkvol.json",
         'broken_wrong_types.vtkvol.json: channels = "nuclei" should be an array; '
         'lights[0].intensity = "bright" should be a number; camera.position = [1, 2] has too '
         'few values; render.jitter = "yes" should be true or false'),
        ("broken_light_intensity.vtkvol.json",
         "broken_light_intensity.vtkvol.json: lights[0].intensity = -2 is below 0"),
        ("broken_opacity.vtkvol.json",
         "broken_opacity.vtkvol.json: channels[0].tf.opacity: opacity point (200.0, 1.5): "
         "alpha must lie in 0…1"),
        ("broken_future_version.vtkvol.json",
         "broken_future_version.vtkvol.json: written by a newer vtkvol "
         f"(format version 99; this version reads up to {VERSION})"),
        ("broken_not_a_session.vtkvol.json",
         "broken_not_a_session.vtkvol.json: not a vtkvol session"),
        ("broken_parameter.vtkvol.json",
         "broken_parameter.vtkvol.json: illumination.parameters.fake_shadows: "
         "density = 7.5 is outside its range 0…5 voxel"),
    ],
)
def test_bad_file_gives_clear_message_and_leaves_scene_untouched(
    fixture: str, message: str
) -> None:
    current = rich_model()
    snapshot = current.model_dump()
    events: list[frozenset[str]] = []
    current.changed.connect(events.append)

    with pytest.raises(SessionError) as info:
        read_session(FIXTURES / fixture).apply_to(current)

    assert str(info.value).startswith(message), str(info.value)
    assert info.value.path == FIXTURES / fixture
    assert current.model_dump() == snapshot and events == []


def test_wrong_types_message_has_every_place(tmp_path: Path) -> None:
    doc = saved_doc(tmp_path)
    doc["scene"]["lights"][0]["intensity"] = "2"  # a number in quotes is still text
    doc["scene"]["render"]["shade"] = 1  # and 1 is not true
    doc["scene"]["volume"]["fit"] = "stretch"
    doc["scene"]["camera"]["zoom"] = 2
    path = write_json(tmp_path / "v.vtkvol.json", doc)
    with pytest.raises(SessionError) as info:
        read_session(path)
    text = str(info.value)
    assert 'lights[0].intensity = "2" should be a number' in text
    assert "render.shade = 1 should be true or false" in text
    assert "volume.fit = \"stretch\" must be one of 'auto', 'crop'" in text
    assert "camera.zoom is not a known setting" in text


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda s: s["channels"][0]["tf"]["opacity"].append([300.0, 1.5]),
         "channels[0].tf.opacity: opacity point (300.0, 1.5): alpha must lie in 0…1"),
        (lambda s: s["render"].update(sample_distance=0), "render.sample_distance = 0 must be "
         "greater than 0.01"),
        (lambda s: s["render"].update(ambient=1.5), "render.ambient = 1.5 is above 1"),
        (lambda s: s["crop"].update(x=[5.0, 1.0]),
         "crop.x: range (5.0, 1.0) µm must be increasing"),
        (lambda s: s["camera"].update(view_angle=180), "camera.view_angle = 180 must be less "
         "than 180"),
        (lambda s: s.update(channels=[s["channels"][0]] * 5),
         "scene: 1 to 4 channels are supported, not 5"),
    ],
)
def test_out_of_range_values(tmp_path: Path, edit: Any, message: str) -> None:
    doc = saved_doc(tmp_path)
    edit(doc["scene"])
    path = write_json(tmp_path / "v.vtkvol.json", doc)
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    assert message in str(info.value)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (HEADER + '"scene": {"camera": {"position": [NaN, 0, 1]}}}',
         "NaN is not a number JSON allows"),
        (HEADER + '"scene": {"camera": {"position": [1e999, 0, 1]}}}',
         "1e999 is too large a number"),
        ("", "is not valid JSON: Expecting value at line 1, column 1"),
        ('"hello"', "the file holds a JSON string, not an object"),
        ('{"format": "napari-session", "version": 1}', "not a vtkvol session (\"format\" is"),
        ('{"format": "vtkvol-session", "version": "1"}', '"version" must be a whole number'),
        ('{"format": "vtkvol-session", "version": 1, "scene": []}', '"scene" must be an object'),
        ('{"format": "vtkvol-session", "version": 1, "data": {"shape_zyx": [4, 5]}}',
         "data.shape_zyx = [4, 5] has too few values"),
        ('{"format": "vtkvol-session", "version": 1, "data": {"sha256_head": "abc"}}',
         'data.sha256_head = "abc" is not in the expected form'),
    ],
)
def test_malformed_files(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "v.vtkvol.json"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    assert message in str(info.value)


def test_unreadable_paths(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(SessionError, match=r"nope\.vtkvol\.json: no such file"):
        read_session(tmp_path / "nope.vtkvol.json")
    with pytest.raises(SessionError, match="is a folder"):
        read_session(tmp_path)
    binary = tmp_path / "cells.tif"
    binary.write_bytes(b"II*\x00\xff\xfe\x00")
    with pytest.raises(SessionError, match="is not a text file"):
        read_session(binary)
    monkeypatch.setattr(session_mod, "MAX_SESSION_BYTES", 10)
    big = write_json(tmp_path / "big.vtkvol.json", saved_doc(tmp_path))
    with pytest.raises(SessionError, match="too large for a session file"):
        read_session(big)


def test_missing_keys_take_defaults_with_a_warning(tmp_path: Path) -> None:
    session = read_session(FIXTURES / "missing_keys.vtkvol.json")
    assert session.model.camera == Camera()
    assert session.model.lights[0].color == (1.0, 1.0, 1.0)
    assert session.model.lights[0].intensity == 0.5
    assert session.window == {}
    (note,) = [w for w in session.warnings if w.startswith("missing from the file")]
    assert "camera" in note and "lights[0].color" in note and "render" in note
    assert "camera.view_up" not in note  # a missing section is named once


def test_unknown_top_level_keys_and_bad_window_are_warnings(tmp_path: Path) -> None:
    doc = saved_doc(tmp_path, plugins={"x": 1}, window=[1, 2])
    session = read_session(write_json(tmp_path / "v.vtkvol.json", doc))
    assert session.window == {}
    assert any("unknown top-level key(s): plugins" in w for w in session.warnings)
    assert any("window layout is not an object" in w for w in session.warnings)


def test_without_data_section_scene_volume_path_is_used(tmp_path: Path) -> None:
    make_data(tmp_path / "cells.npy")
    doc = saved_doc(tmp_path)
    del doc["data"]
    doc["scene"]["volume"]["path"] = "cells.npy"
    session = read_session(write_json(tmp_path / "v.vtkvol.json", doc))
    assert session.data_path == (tmp_path / "cells.npy").resolve()
    assert any("taken from scene.volume.path" in w for w in session.warnings)


# -- techniques -------------------------------------------------------------------------------
def test_unknown_technique_keeps_values_with_a_warning(tmp_path: Path) -> None:
    session = read_session(FIXTURES / "unknown_technique.vtkvol.json")
    ill = session.model.illumination
    assert ill.method == "photon_mapping"
    assert ill.parameters["photon_mapping"] == {"photons": 1000000, "radius": "adaptive"}
    text = " ".join(session.warnings)
    assert "illumination.parameters.photon_mapping: technique not installed here" in text
    assert "its values are kept unchecked" in text
    # Saved again, the values survive for the machine that has the plugin.
    again = read_session(save_session(tmp_path / "again", session.model))
    assert again.model.illumination == ill


def test_technique_parameters_are_checked_against_declarations(tmp_path: Path) -> None:
    def read_with(values: dict[str, Any]) -> Session:
        doc = saved_doc(tmp_path)
        doc["scene"]["illumination"] = {"method": "fake_shadows",
                                        "parameters": {"fake_shadows": values},
                                        "auto": False, "auto_budget_ssim": 0.98}
        return read_session(write_json(tmp_path / "v.vtkvol.json", doc))

    ok = read_with({"density": 5, "steps": 64.0, "soft": True})
    assert ok.model.illumination.parameters["fake_shadows"] == {
        "density": 5.0, "steps": 64, "soft": True
    }
    assert ok.warnings == []

    cases = {
        "steps = 65 is outside its range 1…64": {"steps": 65},
        "steps must be a whole number": {"steps": 2.5},
        'density must be a number, not "3"': {"density": "3"},
        "density must be a number, not true": {"density": True},
        "soft must be true or false": {"soft": 1},
        "quality must be one of low, high": {"quality": "ultra"},
    }
    for message, values in cases.items():
        with pytest.raises(SessionError, match=r"illumination\.parameters\.fake_shadows: ") as info:
            read_with(values)
        assert message in str(info.value), str(info.value)

    dropped = read_with({"density": 1.0, "old_name": 3})
    assert dropped.model.illumination.parameters["fake_shadows"] == {"density": 1.0}
    assert any("does not declare: old_name" in w for w in dropped.warnings)


# -- data on load -----------------------------------------------------------------------------
def test_missing_data_file_then_locate_it(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "data" / "cells.npy")
    path = save_session(tmp_path / "v", rich_model(), data=read_volume(data_file))
    located = tmp_path / "elsewhere" / "renamed.npy"
    located.parent.mkdir()
    shutil.move(data_file, located)

    with pytest.raises(MissingDataError) as info:
        load_session_with_data(path)
    err = info.value
    assert isinstance(err, SessionError)
    assert err.session_path == path
    assert err.data_path == data_file.resolve()
    assert str(err) == (
        f"v.vtkvol.json: the data file {data_file.resolve()} is missing (also looked for "
        "cells.npy next to the session)"
    )

    model, data = load_session_with_data(path, data_path=located)
    assert model.volume.path == str(located.resolve())
    assert data.shape_zyx == (4, 5, 6)
    with pytest.raises(MissingDataError) as again:
        load_session_with_data(path, data_path=tmp_path / "typo.npy")
    assert again.value.data_path == (tmp_path / "typo.npy").resolve()
    assert "the chosen data file" in str(again.value)


def test_missing_data_beside_session_message(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    path = save_session(tmp_path / "v", rich_model(), data=read_volume(data_file))
    data_file.unlink()
    with pytest.raises(MissingDataError) as info:
        load_session_with_data(path)
    assert str(info.value) == (
        f"v.vtkvol.json: the data file {data_file.resolve()} is missing"
    )


def test_session_without_data_file_is_missing_data(tmp_path: Path) -> None:
    path = save_session(tmp_path / "v", SceneModel())
    assert read_session(path).data_path is None
    with pytest.raises(MissingDataError, match="names no data file") as info:
        load_session_with_data(path)
    assert info.value.data_path is None


def test_moved_data_found_next_to_session(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "acquisitions" / "cells.npy")
    session_dir = tmp_path / "shared"
    session_dir.mkdir()
    path = save_session(session_dir / "v", rich_model(), data=read_volume(data_file))
    assert Path(json.loads(path.read_text(encoding="utf-8"))["data"]["path"]).is_absolute()
    shutil.move(data_file, session_dir / "cells.npy")

    session = read_session(path)
    assert session.data_path == session_dir / "cells.npy"
    assert any("same name, next to the session" in w for w in session.warnings)
    with pytest.warns(SessionWarning, match="same name, next to the session"):
        model, data = load_session_with_data(path)
    assert model.volume.path == str(session_dir / "cells.npy")
    assert data.n_channels == 2


@pytest.mark.parametrize(
    ("new_shape", "expected", "found"),
    [
        ((2, 4, 5, 7), {"shape_zyx": (4, 5, 6), "channels": 2}, {"shape_zyx": (4, 5, 7),
                                                                 "channels": 2}),
        ((3, 4, 5, 6), {"shape_zyx": (4, 5, 6), "channels": 2}, {"shape_zyx": (4, 5, 6),
                                                                 "channels": 3}),
    ],
)
def test_changed_shape_is_a_mismatch(
    tmp_path: Path, new_shape: tuple[int, ...], expected: dict[str, Any], found: dict[str, Any]
) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    path = save_session(tmp_path / "v", rich_model(), data=read_volume(data_file))
    make_data(data_file, new_shape)
    with pytest.raises(DataMismatchError) as info:
        load_session_with_data(path)
    err = info.value
    assert isinstance(err, SessionError)
    assert err.expected == expected and err.found == found
    assert "no longer matches the session: cells.npy now has" in str(err)


def test_changed_content_with_same_shape_is_a_warning(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "cells.npy", seed=0)
    path = save_session(tmp_path / "v", rich_model(), data=read_volume(data_file))
    make_data(data_file, seed=1)
    notes: list[str] = []
    model, data = load_session_with_data(path, on_warning=notes.append)
    assert len(notes) == 1 and "changed since the session was saved" in notes[0]
    assert data.shape_zyx == (4, 5, 6)
    assert model.volume.sha256_head != hashlib.sha256(data_file.read_bytes()).hexdigest()

    with pytest.warns(SessionWarning, match=r"^v\.vtkvol\.json: data file cells\.npy changed"):
        load_session_with_data(path)


def test_load_reads_data_with_saved_voxel_size_and_fit(tmp_path: Path) -> None:
    data_file = make_data(tmp_path / "cells.npy")
    model = rich_model()
    model.volume.voxel_size_um = (0.2, 0.2, 0.8)
    path = save_session(tmp_path / "v", model, data=read_volume(data_file))
    loaded, data = load_session_with_data(path)
    assert tuple(data.voxel_size_um) == pytest.approx((0.2, 0.2, 0.8))
    assert loaded.volume.voxel_size_um == (0.2, 0.2, 0.8)


# -- versions and migrations ------------------------------------------------------------------
def load_fixture(name: str) -> dict[str, Any]:
    return json.loads((FIXTURES / name).read_text(encoding="utf-8"))


def test_every_migration_step_has_a_fixture() -> None:
    assert sorted(MIGRATIONS) == list(range(VERSION))
    for version in MIGRATIONS:
        matching = [p for p in FIXTURES.glob("*.vtkvol.json")
                    if not p.name.startswith("broken_")
                    and detect_version(json.loads(p.read_text(encoding="utf-8"))) == version]
        assert matching, f"no fixture for migration v{version}→v{version + 1}"


def test_migrate_v0_to_v1_matches_fixture() -> None:
    raw = load_fixture("v0_pre_release.vtkvol.json")
    untouched = copy.deepcopy(raw)
    assert detect_version(raw) == 0
    assert MIGRATIONS[0](raw) == load_fixture("v0_pre_release.migrated.vtkvol.json")
    assert migrate(raw)["version"] == VERSION
    assert raw == untouched  # pure: the input is not modified


def test_migrate_v1_to_v2_matches_fixture() -> None:
    raw = load_fixture("v1_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[1](raw)
    assert out == load_fixture("v1_complete.migrated.vtkvol.json")
    assert [(x["size"], x["falloff"]) for x in out["scene"]["lights"]] == [(0.0, "none")] * 2
    assert raw == untouched


def test_v1_file_reads_without_warnings_as_ideal_lights() -> None:
    session = read_session(FIXTURES / "v1_complete.vtkvol.json")
    assert session.warnings == []
    assert [(x.size, x.falloff) for x in session.model.lights] == [(0.0, "none")] * 2


def test_migrate_v2_to_v3_matches_fixture() -> None:
    raw = load_fixture("v2_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[2](raw)
    assert out == load_fixture("v2_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    assert not any(out["scene"]["overlays"].values())  # v2 drew no overlays
    assert raw == untouched


def test_v2_file_reads_without_warnings_and_no_overlays() -> None:
    session = read_session(FIXTURES / "v2_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.overlays == Overlays()


def test_migrate_v3_to_v4_matches_fixture() -> None:
    raw = load_fixture("v3_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[3](raw)
    assert out == load_fixture("v3_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    assert out["scene"]["render"]["interpolation"] == "trilinear"  # v3 rendered trilinear
    assert raw == untouched


def test_v3_file_reads_without_warnings_as_trilinear() -> None:
    session = read_session(FIXTURES / "v3_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.render.interpolation == "trilinear"


def test_migrate_v4_to_v5_matches_fixture() -> None:
    raw = load_fixture("v4_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[4](raw)
    assert out == load_fixture("v4_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    assert out["scene"]["clip_plane"]["enabled"] is False  # v4 had no clipping plane
    assert raw == untouched


def test_v4_file_reads_without_warnings_and_no_clipping_plane() -> None:
    session = read_session(FIXTURES / "v4_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.clip_plane == ClipPlane()


def test_migrate_v5_to_v6_matches_fixture() -> None:
    raw = load_fixture("v5_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[5](raw)
    assert out == load_fixture("v5_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    scene = out["scene"]
    # v5 had no slice views: the data's centre, and no plane outlines in the 3-D view.
    assert scene["cursor"] is None and scene["overlays"]["slice_planes"] is False
    assert [c["tf_mode"] for c in scene["channels"]] == ["1d", "1d"]  # v5 was 1-D
    # v5 showed the level the budget chose and the whole image.
    assert scene["volume"]["level"] is None and scene["volume"]["region_um"] is None
    assert scene["illumination"]["auto"] is False  # v5 always showed the method it named
    assert scene["illumination"]["auto_budget_ssim"] == 0.98
    # Skipping is exact, so v5 files get the default (on) and render as v5 did.
    assert scene["render"]["empty_space_skipping"] is True
    assert raw == untouched


def test_v5_file_reads_without_warnings_as_it_was_shown() -> None:
    session = read_session(FIXTURES / "v5_complete.vtkvol.json")
    assert session.warnings == []
    model = session.model
    assert model.cursor is None and model.overlays.slice_planes is False
    assert all(c.tf_mode == "1d" and c.tf2d == TransferFunction2D() for c in model.channels)
    assert all(c.tf2d.paint is None for c in model.channels)  # nothing painted
    assert model.volume.level is None and model.volume.region_um is None
    assert model.illumination.auto is False
    assert model.illumination.method == "fake_shadows"
    assert model.render.empty_space_skipping is True


def test_migrate_v6_to_v7_matches_fixture() -> None:
    raw = load_fixture("v6_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[6](raw)
    assert out == load_fixture("v6_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    # v6 lit every channel with its own normal: the file renders as it did.
    assert out["scene"]["render"]["multichannel_lighting"] == "per_channel"
    assert raw == untouched


def test_v6_file_reads_without_warnings_as_it_was_shown() -> None:
    session = read_session(FIXTURES / "v6_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.render.multichannel_lighting == "per_channel"
    expected = rich_model()
    expected.render.multichannel_lighting = "per_channel"
    assert _same_except_volume(session.model, expected)


def test_migrate_v7_to_v8_matches_fixture() -> None:
    raw = load_fixture("v7_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[7](raw)
    assert out == load_fixture("v7_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    # VTK's ray caster drew every v7 volume: the file renders as it did.
    assert out["scene"]["render"]["renderer"] == "raycast"
    assert raw == untouched


def test_v7_file_reads_without_warnings_as_it_was_shown() -> None:
    session = read_session(FIXTURES / "v7_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.render.renderer == "raycast"
    assert _same_except_volume(session.model, rich_model())


def test_migrate_v8_to_v9_matches_fixture() -> None:
    raw = load_fixture("v8_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[8](raw)
    assert out == load_fixture("v8_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    # v8 had no exposure and no fill light: the file renders as it did.
    render = out["scene"]["render"]
    assert (render["exposure"], render["auto_exposure"], render["fill"]) == (1.0, False, 0.0)
    assert raw == untouched


def test_v8_file_reads_without_warnings_as_it_was_shown() -> None:
    session = read_session(FIXTURES / "v8_complete.vtkvol.json")
    assert session.warnings == []
    assert _same_except_volume(session.model, rich_model())


@pytest.mark.parametrize("value", ["pathtracer", "Slicing", 2, None])
def test_a_session_with_a_bad_renderer_is_refused_in_one_line(tmp_path, value) -> None:
    doc = load_fixture("v10_complete.vtkvol.json")
    doc["scene"]["render"]["renderer"] = value
    path = tmp_path / "v.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    message = str(info.value)
    assert "render.renderer" in message and "\n" not in message
    assert "path_tracer" in message and "slicing" in message  # says what is allowed


def test_a_session_with_the_path_tracer_round_trips(tmp_path) -> None:
    model = rich_model()
    model.render.renderer = "path_tracer"
    path = save_session(tmp_path / "pt.vtkvol.json", model)
    assert read_session(path).model.render.renderer == "path_tracer"


@pytest.mark.parametrize("value", ["Shared", "both", 1, None])
def test_a_session_with_a_bad_multichannel_lighting_is_refused_in_one_line(tmp_path, value
                                                                           ) -> None:
    doc = load_fixture("v10_complete.vtkvol.json")
    doc["scene"]["render"]["multichannel_lighting"] = value
    path = tmp_path / "v.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    message = str(info.value)
    assert "render.multichannel_lighting" in message and "\n" not in message
    assert "per_channel" in message and "shared" in message  # says what is allowed


def test_migrate_current_version_is_identity() -> None:
    doc = load_fixture("v12_complete.vtkvol.json")
    out = migrate(doc)
    assert out == doc and out is not doc


def test_v0_session_opens_with_its_data(tmp_path: Path) -> None:
    path = tmp_path / "old.vtkvol.json"
    shutil.copy(FIXTURES / "v0_pre_release.vtkvol.json", path)
    make_data(tmp_path / "cells.npy", (1, 4, 5, 6))

    session = read_session(path)
    m = session.model
    assert m.channels[0].name == "nuclei"
    assert m.channels[0].tf.opacity == [(10.0, 0.0), (120.0, 0.2), (200.0, 0.6)]
    assert m.lights[0].intensity == 1.5 and m.crop.x == (0.2, 0.8)
    assert m.camera.position == (1.0, 2.0, 30.0) and m.render.sample_distance == 0.25
    assert session.window["docks"] == {"channels": True, "lighting": False}
    assert any("slice_weights" in w for w in session.warnings)  # v0 files were partial

    notes: list[str] = []
    model, data = load_session_with_data(path, on_warning=notes.append)
    assert data.shape_zyx == (4, 5, 6)
    assert tuple(data.voxel_size_um) == pytest.approx((0.2, 0.2, 0.5))
    # Saved again, it is a current-version file.
    again = save_session(path, model, data=data)
    assert json.loads(again.read_text(encoding="utf-8"))["version"] == VERSION
    assert read_session(again).model == model


def test_migrate_v9_to_v10_matches_fixture() -> None:
    raw = load_fixture("v9_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[9](raw)
    assert out == load_fixture("v9_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    # v9 had no gamma and no labels display: every channel is shown as it was.
    assert [(c["gamma"], c["labels"]) for c in out["scene"]["channels"]] == [(1.0, None)] * 2
    assert raw == untouched


def test_v9_file_reads_without_warnings_as_it_was_shown() -> None:
    session = read_session(FIXTURES / "v9_complete.vtkvol.json")
    assert session.warnings == []
    assert _same_except_volume(session.model, rich_model())


def rich_model_v10() -> SceneModel:
    """:func:`rich_model` with the fields version 10 added set away from their defaults."""
    model = rich_model()
    model.channels[0].gamma = 0.5
    membrane = model.channels[1]
    membrane.gamma = 2.0
    membrane.tf_linked_to = None
    membrane.labels = LabelDisplay(opacity=0.8, hidden=[7, 3])
    return model


def test_gamma_and_labels_round_trip(tmp_path) -> None:
    model = rich_model_v10()
    path = save_session(tmp_path / "g.vtkvol.json", model)
    again = read_session(path).model
    assert again == model
    assert again.channels[1].labels == LabelDisplay(opacity=0.8, hidden=[3, 7])
    assert (again.channels[0].gamma, again.channels[1].gamma) == (0.5, 2.0)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("gamma", 0.0, "channels[0].gamma = 0.0 is below 0.1"),
    ("gamma", 11, "channels[0].gamma = 11 is above 10"),
    ("labels", {"opacity": 2.0, "hidden": []}, "channels[0].labels.opacity = 2.0 is above 1"),
    ("labels", {"opacity": 1.0, "hidden": [1.5]}, "channels[0].labels.hidden[0]"),
])
def test_a_session_with_a_bad_gamma_or_labels_is_refused_in_one_line(
        tmp_path, field, value, message) -> None:
    doc = load_fixture("v10_complete.vtkvol.json")
    doc["scene"]["channels"][0][field] = value
    path = tmp_path / "v.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_current_version_fixture_reads_cleanly() -> None:
    """The checked-in v10 file must keep reading: a guard against accidental format changes."""
    session = read_session(FIXTURES / "v10_complete.vtkvol.json")
    assert session.warnings == []
    assert _same_except_volume(session.model, rich_model_v10())
    assert session.model.volume.shape_zyx == (4, 5, 6) and session.model.volume.channels == 2
    assert session.window == WINDOW
    assert session.data_path == (FIXTURES / "cells.npy").resolve()


def _same_except_volume(a: SceneModel, b: SceneModel) -> bool:
    da, db = a.model_dump(), b.model_dump()
    da.pop("volume")
    db.pop("volume")
    return da == db


def test_version_detection_errors() -> None:
    with pytest.raises(ValueError, match="not a vtkvol session"):
        detect_version({"hello": 1})
    with pytest.raises(ValueError, match="whole number"):
        detect_version({"format": FORMAT, "version": True})
    with pytest.raises(ValueError, match=f"format version {VERSION + 1}; this version reads "
                                         f"up to {VERSION}"):
        migrate({"format": FORMAT, "version": VERSION + 1})


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda light: light.update(size=-1.0), r"lights\[0\]\.size = -1(\.0)? is below 0"),
        (lambda light: light.update(falloff="cubic"), r"lights\[0\]\.falloff"),
        (lambda light: light.update(size="big"), r"lights\[0\]\.size .*should be a number"),
    ],
    ids=["negative_size", "unknown_falloff", "size_not_a_number"],
)
def test_bad_light_size_or_falloff_is_named(tmp_path: Path, edit, message) -> None:
    doc = load_fixture("v2_complete.vtkvol.json")
    edit(doc["scene"]["lights"][0])
    path = write_json(tmp_path / "bad.vtkvol.json", doc)
    with pytest.raises(SessionError, match=message):
        read_session(path)


@pytest.mark.parametrize(("values", "message"), [
    ({"auto_budget_ssim": 1.5}, "illumination.auto_budget_ssim = 1.5 is above 1"),
    ({"auto_budget_ssim": 0}, "illumination.auto_budget_ssim = 0 must be greater than 0"),
    ({"auto_budget_ssim": float("nan")}, "is not valid JSON: NaN is not a number JSON allows"),
    ({"auto": "sometimes"}, 'illumination.auto = "sometimes" should be true or false'),
])
def test_hostile_auto_quality_values_are_refused_in_words(tmp_path: Path, values, message):
    doc = saved_doc(tmp_path)
    doc["scene"]["illumination"].update(values)
    with pytest.raises(SessionError, match=re.escape(message)):
        read_session(write_json(tmp_path / "v.vtkvol.json", doc))


def test_migrate_v10_to_v11_matches_fixture() -> None:
    raw = load_fixture("v10_complete.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[10](raw)
    assert out == load_fixture("v10_complete.migrated.vtkvol.json")
    assert migrate(raw) == migrate(out)  # the later steps follow
    # v10 post-classified every sample: the migrated file renders the same image.
    assert out["scene"]["render"]["preintegration"] is False
    assert out["scene"]["render"]["adaptive_sampling"] is False
    assert raw == untouched


def test_v11_fixture_reads_cleanly_with_preintegration() -> None:
    """The checked-in current-version file keeps reading, its render setting included."""
    session = read_session(FIXTURES / "v11_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.render.preintegration is True
    expected = rich_model_v10()
    expected.render.preintegration = True
    expected.render.adaptive_sampling = True
    assert _same_except_volume(session.model, expected)


@pytest.mark.parametrize("field", ["preintegration", "adaptive_sampling"])
@pytest.mark.parametrize("value", ["yes", 2, None])
def test_a_session_with_a_bad_preintegration_is_refused_in_one_line(tmp_path, field, value
                                                                    ) -> None:
    doc = load_fixture("v11_complete.vtkvol.json")
    doc["scene"]["render"][field] = value
    path = tmp_path / "v.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    assert f"render.{field}" in str(info.value) and "\n" not in str(info.value)


def test_migrate_v11_to_v12_matches_fixture() -> None:
    raw = load_fixture("v11_diffusion.vtkvol.json")
    untouched = copy.deepcopy(raw)
    out = MIGRATIONS[11](raw)
    assert out == load_fixture("v11_diffusion.migrated.vtkvol.json")
    assert migrate(raw) == out
    parameters = out["scene"]["illumination"]["parameters"]
    # v11 diffused the scattered light from the direct light alone: the same image
    assert parameters["hybrid_diffusion"]["traced_orders"] == 0
    # the published model has no traced orders: nothing added (it would be inert)
    assert "traced_orders" not in parameters["convection_diffusion"]
    assert raw == untouched


def test_v11_diffusion_session_reads_without_warnings_and_traces_no_orders() -> None:
    session = read_session(FIXTURES / "v11_diffusion.vtkvol.json")
    assert session.warnings == []
    illumination = session.model.illumination
    assert illumination.method == "hybrid_diffusion"
    assert illumination.parameters["hybrid_diffusion"]["traced_orders"] == 0


def test_v12_fixture_reads_cleanly() -> None:
    """The checked-in current-version file keeps reading without warnings."""
    session = read_session(FIXTURES / "v12_complete.vtkvol.json")
    assert session.warnings == []
    assert session.model.render.preintegration is True
