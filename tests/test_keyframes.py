"""Keyframe animations (vtkvol.model.keyframes): the interpolation's geometry, frame timing,
the keyframe file's round trip and its refusals of hostile files (one line each)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from vtkvol.model import Light, SceneModel
from vtkvol.model.keyframes import (
    MAX_FRAMES,
    Animation,
    CameraState,
    Keyframe,
    KeyframeError,
    animation_to_json,
    read_keyframes,
    save_keyframes,
    slerp_unit,
)

FOCAL = (10.0, 20.0, 5.0)


def _camera(azimuth_deg: float, distance: float = 100.0, focal=FOCAL, **kw) -> CameraState:
    """A camera on the horizontal circle about ``focal``, z up."""
    a = math.radians(azimuth_deg)
    pos = (focal[0] + distance * math.sin(a), focal[1] - distance * math.cos(a), focal[2])
    return CameraState(position=pos, focal_point=focal, view_up=(0.0, 0.0, 1.0), **kw)


def _angle(u, v) -> float:
    u, v = np.asarray(u, float), np.asarray(v, float)
    return math.degrees(math.acos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1)))


def _offset(camera: CameraState) -> np.ndarray:
    return np.subtract(camera.position, camera.focal_point)


def test_endpoints_are_exact_and_a_90_degree_orbit_is_at_45_half_way():
    a, b = _camera(0.0), _camera(90.0)
    anim = Animation((Keyframe(0.0, a), Keyframe(2.0, b)), easing="linear")
    assert anim.state_at(0.0).camera == a and anim.state_at(2.0).camera == b
    mid = anim.state_at(1.0).camera
    assert _angle(_offset(mid), _offset(a)) == pytest.approx(45.0, abs=1e-9)
    assert _angle(_offset(mid), _offset(b)) == pytest.approx(45.0, abs=1e-9)
    assert mid.distance == pytest.approx(100.0)  # on the orbit, not across the chord
    assert mid.focal_point == pytest.approx(FOCAL)
    assert mid.view_up == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
    # a quarter of the way: 22.5°, at constant speed ("linear")
    assert _angle(_offset(anim.state_at(0.5).camera), _offset(a)) == pytest.approx(22.5)


def test_smooth_easing_starts_and_ends_slowly_and_meets_linear_half_way():
    a, b = _camera(0.0), _camera(90.0)
    smooth = Animation((Keyframe(0.0, a), Keyframe(1.0, b)), easing="smooth")
    linear = Animation((Keyframe(0.0, a), Keyframe(1.0, b)), easing="linear")

    def turned(anim, t):
        return _angle(_offset(anim.state_at(t).camera), _offset(a))

    assert turned(smooth, 0.5) == pytest.approx(45.0)
    assert turned(smooth, 0.1) < 0.5 * turned(linear, 0.1)  # 2.8° instead of 9°
    assert turned(smooth, 0.1) == pytest.approx(90 * 0.1 * 0.1 * (3 - 0.2))


def test_zoom_is_geometric_and_the_focal_point_moves_linearly():
    a = _camera(0.0, distance=10.0, focal=(0.0, 0.0, 0.0))
    b = _camera(0.0, distance=40.0, focal=(8.0, 0.0, 0.0))
    mid = Animation((Keyframe(0, a), Keyframe(1, b)), easing="linear").state_at(0.5).camera
    assert mid.distance == pytest.approx(20.0)  # 10 → 20 → 40: the same zoom factor per step
    assert mid.focal_point == pytest.approx((4.0, 0.0, 0.0))
    assert _angle(_offset(mid), _offset(a)) == pytest.approx(0.0, abs=1e-6)


def test_a_half_turn_goes_round_the_view_up_and_roll_is_interpolated():
    a, b = _camera(0.0), _camera(180.0)
    mid = Animation((Keyframe(0, a), Keyframe(1, b)), easing="linear").state_at(0.5).camera
    assert _angle(_offset(mid), _offset(a)) == pytest.approx(90.0)
    assert mid.view_up == pytest.approx((0.0, 0.0, 1.0), abs=1e-9)  # not over the top
    rolled = CameraState(position=a.position, focal_point=FOCAL, view_up=(1.0, 0.0, 0.0))
    mid = Animation((Keyframe(0, a), Keyframe(1, rolled)), easing="linear").state_at(0.5)
    assert mid.camera.view_up == pytest.approx((math.sqrt(0.5), 0.0, math.sqrt(0.5)))
    assert mid.camera.position == pytest.approx(a.position)


def test_light_directions_slerp_on_the_unit_sphere_intensities_and_colours_linearly():
    a = Light(direction=(0.0, 0.0, 2.0), intensity=1.0, color=(1.0, 0.0, 0.0))
    b = Light(direction=(3.0, 0.0, 0.0), intensity=3.0, color=(0.0, 0.0, 1.0), kind="point")
    cam = _camera(0.0)
    anim = Animation((Keyframe(0, cam, lights=(a,)), Keyframe(1, cam, lights=(b,))),
                     easing="linear")
    for t in np.linspace(0.0, 1.0, 11)[1:-1]:
        light = anim.state_at(float(t)).lights[0]
        assert np.linalg.norm(light.direction) == pytest.approx(1.0)
        assert _angle(light.direction, (0, 0, 1)) == pytest.approx(90.0 * t)
        assert light.intensity == pytest.approx(1.0 + 2.0 * t)
        assert light.color == pytest.approx((1 - t, 0.0, t))
        assert light.kind == "directional"  # held from the earlier keyframe
    assert anim.state_at(1.0).lights[0].kind == "point"
    assert anim.state_at(0.0).lights[0].direction == (0.0, 0.0, 2.0)  # the endpoint as given
    # opposite directions still give unit vectors, turning by 90° half way
    half = slerp_unit((0, 0, 1), (0, 0, -1), 0.5)
    assert np.linalg.norm(half) == pytest.approx(1.0) and half[2] == pytest.approx(0.0)


def test_time_index_linear_nearest_and_hold():
    cam = _camera(0.0)
    keys = (Keyframe(0.0, cam, time_index=0), Keyframe(4.0, cam, time_index=8))

    def indices(mode):
        anim = Animation(keys, easing="smooth", time_index_interpolation=mode)
        return [anim.state_at(t).time_index for t in (0.0, 0.9, 1.0, 2.1, 3.9, 4.0)]

    # linear follows the raw time (not the easing): time points play at a steady rate
    assert indices("linear") == [0, 2, 2, 4, 8, 8]
    assert indices("nearest") == [0, 0, 0, 8, 8, 8]
    assert indices("hold") == [0, 0, 0, 0, 0, 8]


def test_frame_timing_and_absurd_frame_counts():
    keys = (Keyframe(0.0, _camera(0)), Keyframe(2.0, _camera(90)))
    anim = Animation(keys)
    assert anim.frame_count(30) == 61 and anim.frame_times(2) == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert Animation(keys[:1]).frame_count(30) == 1
    long = Animation((Keyframe(0.0, _camera(0)), Keyframe(1e9, _camera(90))))
    with pytest.raises(KeyframeError, match=f"at most {MAX_FRAMES}"):
        long.frame_count(30)
    with pytest.raises(KeyframeError, match="fps must be > 0"):
        anim.frame_count(0)


def test_from_model_snapshots_camera_lights_and_time_point():
    model = SceneModel()
    with pytest.raises(KeyframeError, match="not placed"):
        Keyframe.from_model(model, 0.0)
    model.camera.position, model.camera.focal_point = (0.0, -50.0, 0.0), (0.0, 0.0, 0.0)
    model.camera.view_up = (0.0, 0.0, 1.0)
    model.volume.time_index = 3
    key = Keyframe.from_model(model, 1.5)
    model.lights[0].intensity = 7.0  # later edits do not reach the keyframe
    assert key.time == 1.5 and key.time_index == 3 and key.lights[0].intensity == 1.0
    assert key.camera.position == (0.0, -50.0, 0.0)


def test_file_round_trip(tmp_path):
    keys = (Keyframe(0.0, _camera(0), time_index=0, lights=(Light(),)),
            Keyframe(1.5, _camera(60, parallel_projection=True, parallel_scale=3.0),
                     time_index=2, lights=(Light(direction=(1, 0, 0), color=(0.5, 1, 1)),)))
    anim = Animation(keys, easing="linear", time_index_interpolation="hold")
    path = save_keyframes(tmp_path / "a.keyframes.json", anim)
    back = read_keyframes(path)
    assert animation_to_json(back) == animation_to_json(anim)
    assert back.state_at(0.7) == anim.state_at(0.7)


def _document(**changes) -> dict:
    doc = {"format": "vtkvol-keyframes", "version": 1, "keyframes": [
        {"time": 0.0, "camera": {"position": [0, -10, 0], "focal_point": [0, 0, 0],
                                 "view_up": [0, 0, 1]}},
        {"time": 1.0, "camera": {"position": [10, 0, 0], "focal_point": [0, 0, 0],
                                 "view_up": [0, 0, 1]}}]}
    doc.update(changes)
    return doc


def _second(**fields) -> dict:
    doc = _document()
    doc["keyframes"][1].update(fields)
    return doc


@pytest.mark.parametrize(("content", "message"), [
    ("{not json", r"bad\.keyframes\.json: is not valid JSON: .* at line 1, column 2"),
    (b"\xff\xfe\x00garbage", "is not a text file"),
    ("[1, 2]", "is not a keyframe file"),
    (_document(format="vtkvol-session"), "is not a keyframe file"),
    (_document(version=2), "version 2, newer than this vtkvol reads"),
    (_document(version="1"), '"version" must be a whole number'),
    (_document(keyframes=[]), "at least one keyframe"),
    (_document(keyframes={"time": 0}), '"keyframes" must be a list'),
    (_document(easing="bouncy"), "easing \"bouncy\" is not one of linear, smooth"),
    (_document(extra=1), 'unknown key "extra"'),
    (_second(time=0.0), r"keyframes\[1\]\.time 0 is not after keyframes\[0\]\.time"),
    (_second(time=-1), r"keyframes\[1\]\.time -1 s must be >= 0"),
    (_second(time="soon"), r"keyframes\[1\]\.time must be a number"),
    (_second(time_index=2), r"keyframes\[1\] has time_index and keyframes\[0\] lacks"),
    (_second(time_index=-1), r"time_index must be a whole number >= 0"),
    (_second(time_index=1.5), r"time_index must be a whole number >= 0"),
    (_second(camera={"position": [0, 0, 0], "focal_point": [0, 0, 0], "view_up": [0, 0, 1]}),
     r"keyframes\[1\]\.camera\.position is the focal point"),
    (_second(camera={"position": [0, 0, 5], "focal_point": [0, 0, 0], "view_up": [0, 0, 1]}),
     "view_up is zero or along the view direction"),
    (_second(camera={"position": [1, 2], "focal_point": [0, 0, 0], "view_up": [0, 0, 1]}),
     r"camera\.position must be 3 numbers"),
    (_second(camera={"position": [1, 2, 3], "focal_point": [0, 0, 0]}),
     r"keyframes\[1\]\.camera lacks \"view_up\""),
    (_second(camera={"position": [0, -1, 0], "focal_point": [0, 0, 0], "view_up": [0, 0, 1],
                     "view_angle": 200}), "view_angle 200° must lie between 0 and 180"),
    (_second(lights=[{"direction": [0, 0, 1]}]),
     r"keyframes\[1\] has lights and keyframes\[0\] lacks"),
    ('{"format": "vtkvol-keyframes", "version": 1, "keyframes": [{"time": NaN, "camera": {}}]}',
     "NaN is not a number JSON allows"),
    ('{"format": "vtkvol-keyframes", "version": 1, "keyframes": [{"time": 1e999}]}',
     "1e999 is too large a number"),
    ("[" * 5000 + "]" * 5000, "nested too deeply"),
])
def test_bad_keyframe_files_are_refused_with_one_line(tmp_path, content, message):
    path = tmp_path / "bad.keyframes.json"
    if isinstance(content, dict):
        content = json.dumps(content)
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(KeyframeError, match=message) as info:
        read_keyframes(path)
    text = str(info.value)
    assert "\n" not in text and text.startswith("bad.keyframes.json: ")


def test_bad_lights_in_files(tmp_path):
    doc = _document()
    for i, key in enumerate(doc["keyframes"]):
        key["lights"] = [{"direction": [0, 0, 1]}] * (i + 1)
    path = tmp_path / "l.keyframes.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(KeyframeError, match=r"keyframes\[1\] has 2 lights, keyframes\[0\] has 1"):
        read_keyframes(path)
    doc["keyframes"][1]["lights"] = [{"direction": [0, 0, 1], "intensity": -3}]
    path.write_text(json.dumps(doc))
    with pytest.raises(KeyframeError, match=r"keyframes\[1\]\.lights\[0\]\.intensity"):
        read_keyframes(path)
    doc["keyframes"][1]["lights"] = [{"direction": [0, 0, 0]}]
    path.write_text(json.dumps(doc))
    with pytest.raises(KeyframeError, match="must not be the zero vector"):
        read_keyframes(path)


def test_missing_folder_and_huge_files(tmp_path):
    with pytest.raises(KeyframeError, match=r"nope\.keyframes\.json: no such file"):
        read_keyframes(tmp_path / "nope.keyframes.json")
    with pytest.raises(KeyframeError, match="is a folder"):
        read_keyframes(tmp_path)
    big = tmp_path / "big.keyframes.json"
    with open(big, "wb") as f:
        f.truncate(17 * 2**20)
    with pytest.raises(KeyframeError, match="too large for a keyframe file"):
        read_keyframes(big)


def test_the_documented_keyframe_file_is_valid(tmp_path):
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "app.md").read_text(encoding="utf-8")
    section = page.split("### Keyframe files", 1)[1]
    example = re.search(r"```json\n(.*?)```", section, re.S).group(1)
    path = tmp_path / "doc.keyframes.json"
    path.write_text(example)
    anim = read_keyframes(path)
    assert anim.duration == 4.0 and anim.time_indices() == [0, 19]
    assert anim.state_at(2.0).time_index == 10 and len(anim.state_at(2.0).lights) == 1
