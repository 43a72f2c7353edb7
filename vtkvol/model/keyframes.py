"""Keyframe animations: scene states at times in seconds, and how to go between them.

Pure numbers (numpy), no VTK, no Qt. A :class:`Keyframe` holds what a movie animates:

* the **camera** (:class:`CameraState`, world space, µm): position, focal point, view-up,
  view angle (°), parallel projection and scale;
* optionally the **time index** (0-based time point of the data);
* optionally the **lights** (:class:`vtkvol.model.Light`, world space).

:meth:`Animation.state_at` interpolates them so that the motion looks right:

* the camera turns **about its focal point**: the camera's orientation (view direction and
  view-up together, as a rotation) is interpolated by quaternion slerp, the distance to the
  focal point and the parallel scale geometrically (a zoom by 4× goes 1×, 2×, 4×, not 1×, 2.5×,
  4×), the focal point and the view angle linearly; parallel projection is held from the
  earlier keyframe. A 90° orbit is at 45° half way;
* light **directions** by slerp on the unit sphere (they stay unit vectors), positions,
  colours, intensities and sizes linearly; a light's kind, on/off and falloff are held from the
  earlier keyframe;
* the **time index** ``"linear"`` (rounded to the nearest time point: keyframes at 0 s / t = 0
  and 5 s / t = 19 play every time point between), ``"nearest"`` (the nearer keyframe's) or
  ``"hold"`` (the earlier keyframe's until the next one is reached).

``easing="smooth"`` eases in and out of every keyframe (smoothstep of each segment's time);
``"linear"`` moves at constant speed within each segment. Before the first keyframe the first
state holds; the animation ends at the last keyframe.

A movie of an animation at ``fps`` frames per second shows frame ``i`` at ``i / fps`` seconds,
from 0 to the last keyframe's time: ``round(duration · fps) + 1`` frames, both ends included
(:meth:`Animation.frame_times`).

Keyframe files (``*.keyframes.json``, :func:`read_keyframes`, :func:`save_keyframes`) are
versioned JSON; every problem is a :class:`KeyframeError` with a one-line message naming the
file and the place, e.g. ``"spin.keyframes.json: keyframes[2].time 1.0 is not after
keyframes[1].time (1.5)"``.
"""

from __future__ import annotations

import bisect
import json
import math
import os
import stat
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import ValidationError

from vtkvol.model import strict_json
from vtkvol.model.scene import MAX_COORDINATE_UM, Camera, Light

__all__ = [
    "EASINGS",
    "KEYFRAMES_FORMAT",
    "KEYFRAMES_SUFFIX",
    "KEYFRAMES_VERSION",
    "MAX_FRAMES",
    "MAX_KEYFRAMES",
    "TIME_INDEX_MODES",
    "Animation",
    "CameraState",
    "Keyframe",
    "KeyframeError",
    "SceneState",
    "animation_from_json",
    "animation_to_json",
    "read_keyframes",
    "save_keyframes",
    "slerp_unit",
]

KEYFRAMES_FORMAT = "vtkvol-keyframes"
KEYFRAMES_VERSION = 1
KEYFRAMES_SUFFIX = ".keyframes.json"
#: Most frames an animation may have (about 55 min at 30 fps): a typo in a time (1e9 s) is
#: refused before anything renders, not discovered as a full disk.
MAX_FRAMES = 100_000
#: Most keyframes a file may hold.
MAX_KEYFRAMES = 10_000
#: Keyframe files are a few KiB; anything larger is refused unread.
MAX_FILE_BYTES = 16 * 2**20
Easing = Literal["linear", "smooth"]
EASINGS: tuple[str, ...] = ("linear", "smooth")
TimeIndexMode = Literal["linear", "nearest", "hold"]
TIME_INDEX_MODES: tuple[str, ...] = ("linear", "nearest", "hold")

Vec3 = tuple[float, float, float]
_LIGHT_FIELDS = ("kind", "direction", "position", "color", "intensity", "enabled", "size",
                 "falloff")
_CAMERA_FIELDS = ("position", "focal_point", "view_up", "view_angle", "parallel_projection",
                  "parallel_scale")


class KeyframeError(ValueError):
    """A keyframe animation or file is invalid; the message is one line naming the problem
    (and the file, when there is one)."""


# -- vector and rotation helpers ----------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def slerp_unit(a: Sequence[float], b: Sequence[float], s: float) -> np.ndarray:
    """Spherical interpolation between the directions ``a`` and ``b`` (any length > 0) at
    ``s`` ∈ [0, 1]; a unit vector. Opposite directions turn about an axis perpendicular to
    ``a`` (the same one every time)."""
    a, b = _unit(np.asarray(a, float)), _unit(np.asarray(b, float))
    dot = float(np.clip(a @ b, -1.0, 1.0))
    angle = math.acos(dot)
    if angle < 1e-9:
        return a.copy() if s < 0.5 else b.copy()
    if math.pi - angle < 1e-6:  # antipodal: no unique great circle; take one through a ⟂ axis
        helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        axis = _unit(np.cross(a, helper))
        return _unit(a * math.cos(angle * s) + np.cross(axis, a) * math.sin(angle * s))
    sin = math.sin(angle)
    return _unit(a * (math.sin((1 - s) * angle) / sin) + b * (math.sin(s * angle) / sin))


def _frame(camera: CameraState) -> np.ndarray:
    """Rotation matrix whose columns are the camera's right, up and back (focal → camera)."""
    back = _unit(np.subtract(camera.position, camera.focal_point))
    up = np.asarray(camera.view_up, float)
    up = _unit(up - (up @ back) * back)
    return np.column_stack([np.cross(up, back), up, back])


def _quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    return _unit(np.array(q))


def _matrix_from_quat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _slerp_quat(q0: np.ndarray, q1: np.ndarray, s: float) -> np.ndarray:
    dot = float(q0 @ q1)
    if dot < 0.0:  # q and −q are the same rotation: take the shorter way
        q1, dot = -q1, -dot
    if dot > 1.0 - 1e-12:
        return _unit(q0 + (q1 - q0) * s)
    angle = math.acos(min(dot, 1.0))
    sin = math.sin(angle)
    return (q0 * math.sin((1 - s) * angle) + q1 * math.sin(s * angle)) / sin


def _lerp(a: Sequence[float], b: Sequence[float], s: float) -> tuple[float, ...]:
    return tuple(float(x + (y - x) * s) for x, y in zip(a, b, strict=True))


def _geometric(a: float, b: float, s: float) -> float:
    return float(a * (b / a) ** s)


# -- states -------------------------------------------------------------------------------------
def _vec3(value: Any, what: str) -> Vec3:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 3:
        raise KeyframeError(f"{what} must be 3 numbers (x, y, z), not {_show(value)}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise KeyframeError(f"{what} must be 3 numbers (x, y, z), not {_show(value)}")
        try:
            number = float(v)
        except OverflowError:  # an integer of 400 digits (JSON allows it): too far out
            number = 2 * MAX_COORDINATE_UM if v > 0 else -2 * MAX_COORDINATE_UM
        if not math.isfinite(number):
            raise KeyframeError(f"{what} {_show(list(value))} must be finite")
        if abs(number) > MAX_COORDINATE_UM:
            raise KeyframeError(f"{what} {_show(list(value))} is too far out: each coordinate "
                                f"must lie within ±{MAX_COORDINATE_UM:g} µm")
        out.append(number)
    return (out[0], out[1], out[2])


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise KeyframeError(f"{what} must be a number, not {_show(value)}")
    try:
        number = float(value)
    except OverflowError:  # JSON allows an integer of 400 digits
        raise KeyframeError(f"{what} must be a finite number, not {_show(value)}") from None
    if not math.isfinite(number):
        raise KeyframeError(f"{what} must be finite, not {_show(value)}")
    return number


@dataclass(frozen=True)
class CameraState:
    """A camera in world space (µm): where it is, what it looks at, which way is up.

    ``view_angle`` in degrees (perspective), ``parallel_scale`` in µm (half the view's height
    in parallel projection)."""

    position: Vec3
    focal_point: Vec3
    view_up: Vec3 = (0.0, 0.0, 1.0)
    view_angle: float = 30.0
    parallel_projection: bool = False
    parallel_scale: float = 1.0

    def __post_init__(self) -> None:
        for name in ("position", "focal_point", "view_up"):
            object.__setattr__(self, name, _vec3(getattr(self, name), f"camera.{name}"))
        angle = _number(self.view_angle, "camera.view_angle")
        if not 0.0 < angle < 180.0:
            raise KeyframeError(f"camera.view_angle {angle:g}° must lie between 0 and 180")
        scale = _number(self.parallel_scale, "camera.parallel_scale")
        if not 0.0 < scale <= MAX_COORDINATE_UM:
            raise KeyframeError(f"camera.parallel_scale {scale:g} must be > 0 and at most "
                                f"{MAX_COORDINATE_UM:g} µm")
        if not isinstance(self.parallel_projection, bool):
            raise KeyframeError(f"camera.parallel_projection must be true or false, not "
                                f"{_show(self.parallel_projection)}")
        object.__setattr__(self, "view_angle", angle)
        object.__setattr__(self, "parallel_scale", scale)
        back = np.subtract(self.position, self.focal_point)
        distance = float(np.linalg.norm(back))
        if not distance > 1e-9 * max(1.0, float(np.abs(self.focal_point).max())):
            raise KeyframeError("camera.position is the focal point: the camera looks nowhere")
        up = np.asarray(self.view_up, float)
        if float(np.linalg.norm(up)) < 1e-12 or np.linalg.norm(np.cross(_unit(up),
                                                                         back / distance)) < 1e-6:
            raise KeyframeError("camera.view_up is zero or along the view direction; it must "
                                "point across it")

    @property
    def distance(self) -> float:
        """From the camera to its focal point (µm)."""
        return float(np.linalg.norm(np.subtract(self.position, self.focal_point)))

    @classmethod
    def from_model(cls, camera: Camera) -> CameraState:
        """The state of a model camera; it must be placed (``position`` set)."""
        if camera.position is None or camera.focal_point is None:
            raise KeyframeError("the camera is not placed yet (no position): show the data first")
        return cls(position=camera.position, focal_point=camera.focal_point,
                   view_up=camera.view_up, view_angle=camera.view_angle,
                   parallel_projection=camera.parallel_projection,
                   parallel_scale=camera.parallel_scale)

    def model_fields(self) -> dict[str, Any]:
        """The fields of :class:`vtkvol.model.Camera` (``camera.update(state.model_fields())``)."""
        return {name: getattr(self, name) for name in _CAMERA_FIELDS}

    def interpolate(self, other: CameraState, s: float) -> CameraState:
        """The camera ``s`` ∈ [0, 1] of the way to ``other``, turned about the focal point
        (see the module docstring). Endpoints are returned unchanged."""
        if s <= 0.0:
            return self
        if s >= 1.0:
            return other
        rotation = _matrix_from_quat(_slerp_quat(_quat_from_matrix(_frame(self)),
                                                 _quat_from_matrix(_frame(other)), s))
        focal = np.array(_lerp(self.focal_point, other.focal_point, s))
        distance = _geometric(self.distance, other.distance, s)
        return CameraState(
            position=tuple(focal + distance * rotation[:, 2]),  # type: ignore[arg-type]
            focal_point=tuple(focal),  # type: ignore[arg-type]
            view_up=tuple(rotation[:, 1]),  # type: ignore[arg-type]
            view_angle=self.view_angle + (other.view_angle - self.view_angle) * s,
            parallel_projection=self.parallel_projection,
            parallel_scale=_geometric(self.parallel_scale, other.parallel_scale, s),
        )


def _interpolate_light(a: Light, b: Light, s: float) -> Light:
    """``a`` ``s`` of the way to ``b``: direction by slerp, position, colour, intensity and size
    linearly; kind, enabled and falloff held from ``a``."""
    if s <= 0.0:
        return a.model_copy(deep=True)
    if s >= 1.0:
        return b.model_copy(deep=True)
    return Light(
        kind=a.kind, enabled=a.enabled, falloff=a.falloff,
        direction=tuple(float(v) for v in slerp_unit(a.direction, b.direction, s)),
        position=_lerp(a.position, b.position, s),
        color=tuple(min(1.0, max(0.0, c)) for c in _lerp(a.color, b.color, s)),
        intensity=a.intensity + (b.intensity - a.intensity) * s,
        size=a.size + (b.size - a.size) * s,
    )


@dataclass(frozen=True)
class SceneState:
    """What an animation sets at one moment: camera, time index (None: not animated) and
    lights (None: not animated)."""

    camera: CameraState
    time_index: int | None = None
    lights: tuple[Light, ...] | None = None


@dataclass(frozen=True)
class Keyframe:
    """The scene state at ``time`` seconds from the start of the animation."""

    time: float
    camera: CameraState
    time_index: int | None = None
    lights: tuple[Light, ...] | None = None

    def __post_init__(self) -> None:
        t = _number(self.time, "time")
        if t < 0:
            raise KeyframeError(f"time {t:g} s must be >= 0")
        object.__setattr__(self, "time", t)
        if not isinstance(self.camera, CameraState):
            raise KeyframeError("camera must be a CameraState")
        if self.time_index is not None and (
                isinstance(self.time_index, bool) or not isinstance(self.time_index, int)
                or self.time_index < 0):
            raise KeyframeError(f"time_index must be a whole number >= 0, not "
                                f"{_show(self.time_index)}")
        if self.lights is not None:
            lights = tuple(self.lights)
            if not lights:
                raise KeyframeError("lights must hold at least one light (or be left out)")
            if not all(isinstance(light, Light) for light in lights):
                raise KeyframeError("lights must be vtkvol.Light objects")
            # copies: a keyframe is a snapshot, later edits of the scene's lights do not reach it
            object.__setattr__(self, "lights", tuple(light.model_copy(deep=True)
                                                     for light in lights))

    @classmethod
    def from_model(cls, model: Any, time: float, *, time_index: bool = True,
                   lights: bool = True) -> Keyframe:
        """A snapshot of a :class:`vtkvol.model.SceneModel`'s camera, time index and lights."""
        return cls(time=time, camera=CameraState.from_model(model.camera),
                   time_index=int(model.volume.time_index) if time_index else None,
                   lights=tuple(model.lights) if lights else None)

    def with_time(self, time: float) -> Keyframe:
        return Keyframe(time=time, camera=self.camera, time_index=self.time_index,
                        lights=self.lights)


@dataclass(frozen=True)
class Animation:
    """Keyframes in increasing time, and how to go between them (module docstring)."""

    keyframes: tuple[Keyframe, ...]
    easing: Easing = "smooth"
    time_index_interpolation: TimeIndexMode = "linear"
    _times: tuple[float, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        keys = tuple(self.keyframes)
        object.__setattr__(self, "keyframes", keys)
        if not keys:
            raise KeyframeError("an animation needs at least one keyframe")
        if len(keys) > MAX_KEYFRAMES:
            raise KeyframeError(f"{len(keys)} keyframes; at most {MAX_KEYFRAMES}")
        if self.easing not in EASINGS:
            raise KeyframeError(f"easing {_show(self.easing)} is not one of "
                                f"{', '.join(EASINGS)}")
        if self.time_index_interpolation not in TIME_INDEX_MODES:
            raise KeyframeError(f"time_index_interpolation {_show(self.time_index_interpolation)}"
                                f" is not one of {', '.join(TIME_INDEX_MODES)}")
        for i in range(1, len(keys)):
            if not keys[i].time > keys[i - 1].time:
                raise KeyframeError(f"keyframes[{i}].time {keys[i].time:g} is not after "
                                    f"keyframes[{i - 1}].time ({keys[i - 1].time:g}); times "
                                    "must increase")
        for what in ("time_index", "lights"):
            given = [getattr(k, what) is not None for k in keys]
            if any(given) and not all(given):
                i = given.index(not given[0])
                raise KeyframeError(f"keyframes[{i}] {'has' if given[i] else 'lacks'} {what} "
                                    f"and keyframes[0] {'has' if given[0] else 'lacks'}; give "
                                    "it in every keyframe or in none")
        if keys[0].lights is not None:
            n = len(keys[0].lights)
            for i, key in enumerate(keys):
                if len(key.lights) != n:  # type: ignore[arg-type]
                    raise KeyframeError(f"keyframes[{i}] has {len(key.lights)} lights, "  # type: ignore[arg-type]
                                        f"keyframes[0] has {n}; every keyframe needs the same "
                                        "lights")
        object.__setattr__(self, "_times", tuple(k.time for k in keys))

    @property
    def duration(self) -> float:
        """Seconds from 0 to the last keyframe."""
        return self.keyframes[-1].time

    def frame_count(self, fps: float) -> int:
        """Frames of a movie at ``fps``: ``round(duration · fps) + 1`` (both ends shown).

        Raises :class:`KeyframeError` past :data:`MAX_FRAMES`."""
        fps = _number(fps, "fps")
        if not fps > 0:
            raise KeyframeError(f"fps must be > 0, not {fps:g}")
        # In floating point first: 1e308 s × 30 fps is infinite, which round() cannot take.
        exact = self.duration * fps
        if not exact + 1 <= MAX_FRAMES:
            count = f"{exact + 1:.4g}" if math.isfinite(exact) else "too many"
            raise KeyframeError(f"{self.duration:g} s at {fps:g} fps is {count} frames; at most "
                                f"{MAX_FRAMES} (check the keyframe times)")
        return round(exact) + 1

    def frame_times(self, fps: float) -> list[float]:
        """Seconds of each frame: ``i / fps``, the last clamped to the duration."""
        n = self.frame_count(fps)
        return [min(i / fps, self.duration) for i in range(n)]

    @property
    def animates_time(self) -> bool:
        return self.keyframes[0].time_index is not None

    def time_indices(self) -> list[int]:
        """The time indices the keyframes name (empty when the time is not animated)."""
        return [k.time_index for k in self.keyframes if k.time_index is not None]

    def _segment(self, t: float) -> tuple[int, float, float]:
        """Keyframe ``i`` before ``t``, the raw fraction ``u`` of the way to ``i + 1`` and the
        eased fraction ``s``."""
        keys = self.keyframes
        if t <= keys[0].time or len(keys) == 1:
            return 0, 0.0, 0.0
        if t >= keys[-1].time:
            return len(keys) - 2, 1.0, 1.0
        i = bisect.bisect_right(self._times, t) - 1
        u = (t - keys[i].time) / (keys[i + 1].time - keys[i].time)
        s = u * u * (3.0 - 2.0 * u) if self.easing == "smooth" else u
        return i, u, s

    def state_at(self, t: float) -> SceneState:
        """The interpolated state ``t`` seconds into the animation."""
        t = _number(t, "t")
        keys = self.keyframes
        i, u, s = self._segment(t)
        if len(keys) == 1:
            a = b = keys[0]
        else:
            a, b = keys[i], keys[i + 1]
        camera = a.camera.interpolate(b.camera, s)
        time_index = None
        if a.time_index is not None and b.time_index is not None:
            mode = self.time_index_interpolation
            if u >= 1.0:
                time_index = b.time_index
            elif mode == "hold":
                time_index = a.time_index
            elif mode == "nearest":
                time_index = a.time_index if u < 0.5 else b.time_index
            else:  # linear in the raw time: time points play at a constant rate
                time_index = math.floor(a.time_index + (b.time_index - a.time_index) * u
                                            + 0.5)
        lights = None
        if a.lights is not None and b.lights is not None:
            lights = tuple(_interpolate_light(x, y, s) for x, y in zip(a.lights, b.lights,
                                                                          strict=True))
        return SceneState(camera=camera, time_index=time_index, lights=lights)


# -- JSON ---------------------------------------------------------------------------------------
def _show(value: Any, limit: int = 40) -> str:
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _expect_keys(obj: Any, what: str, required: Sequence[str], allowed: Sequence[str]) -> None:
    if not isinstance(obj, dict):
        raise KeyframeError(f"{what} must be a JSON object, not {_show(obj)}")
    unknown = sorted(set(obj) - set(allowed))
    if unknown:
        raise KeyframeError(f"{what} has unknown key {_show(unknown[0])} (known: "
                            f"{', '.join(allowed)})")
    for key in required:
        if key not in obj:
            raise KeyframeError(f"{what} lacks {_show(key)}")


def _light_from_json(obj: Any, what: str) -> Light:
    _expect_keys(obj, what, ("direction",), _LIGHT_FIELDS)
    for name in ("direction", "position", "color"):
        if name in obj:
            _vec3(obj[name], f"{what}.{name}")
    for name in ("intensity", "size"):
        if name in obj:
            _number(obj[name], f"{what}.{name}")
    try:
        return Light.model_validate(obj)
    except ValidationError as exc:
        err = exc.errors()[0]
        place = ".".join(str(p) for p in err["loc"] if not isinstance(p, int))
        message = str(err["msg"]).removeprefix("Value error, ")
        raise KeyframeError(f"{what}.{place}: {message}" if place else f"{what}: {message}"
                            ) from None


def _keyframe_from_json(obj: Any, what: str) -> Keyframe:
    _expect_keys(obj, what, ("time", "camera"), ("time", "camera", "time_index", "lights"))
    cam = obj["camera"]
    _expect_keys(cam, f"{what}.camera", ("position", "focal_point", "view_up"), _CAMERA_FIELDS)
    lights = obj.get("lights")
    if lights is not None:
        if not isinstance(lights, list):
            raise KeyframeError(f"{what}.lights must be a list of lights, not {_show(lights)}")
        if len(lights) > 16:
            raise KeyframeError(f"{what}.lights has {len(lights)} lights; at most 16")
        lights = tuple(_light_from_json(light, f"{what}.lights[{j}]")
                       for j, light in enumerate(lights))
    try:
        camera = CameraState(**cam)
        return Keyframe(time=obj["time"], camera=camera, time_index=obj.get("time_index"),
                        lights=lights)
    except KeyframeError as exc:
        raise KeyframeError(f"{what}.{exc}") from None


def animation_from_json(raw: Any) -> Animation:
    """An :class:`Animation` from a parsed keyframe document (:class:`KeyframeError` when it
    is not one)."""
    if not isinstance(raw, dict):
        raise KeyframeError(f"is not a keyframe file (it holds a JSON {type(raw).__name__}, "
                            "not an object)")
    if raw.get("format") != KEYFRAMES_FORMAT:
        raise KeyframeError(f"is not a keyframe file (its \"format\" is {_show(raw.get('format'))}"
                            f", not \"{KEYFRAMES_FORMAT}\")")
    version = raw.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise KeyframeError(f"\"version\" must be a whole number, not {_show(version)}")
    if version > KEYFRAMES_VERSION:
        raise KeyframeError(f"is keyframe format version {version}, newer than this vtkvol "
                            f"reads ({KEYFRAMES_VERSION}); update vtkvol")
    if version < 1:
        raise KeyframeError(f"keyframe format version {version} does not exist (the first is 1)")
    _expect_keys(raw, "the file", ("keyframes",),
                 ("format", "version", "easing", "time_index_interpolation", "keyframes"))
    keys = raw["keyframes"]
    if not isinstance(keys, list):
        raise KeyframeError(f"\"keyframes\" must be a list, not {_show(keys)}")
    if len(keys) > MAX_KEYFRAMES:
        raise KeyframeError(f"{len(keys)} keyframes; at most {MAX_KEYFRAMES}")
    keyframes = tuple(_keyframe_from_json(k, f"keyframes[{i}]") for i, k in enumerate(keys))
    return Animation(keyframes, easing=raw.get("easing", "smooth"),
                     time_index_interpolation=raw.get("time_index_interpolation", "linear"))


def animation_to_json(animation: Animation) -> dict[str, Any]:
    """The keyframe document of ``animation`` (what :func:`save_keyframes` writes)."""
    keys = []
    for key in animation.keyframes:
        entry: dict[str, Any] = {"time": key.time, "camera": {
            name: list(v) if isinstance(v, tuple) else v
            for name, v in key.camera.model_fields().items()}}
        if key.time_index is not None:
            entry["time_index"] = key.time_index
        if key.lights is not None:
            entry["lights"] = [
                {name: list(v) if isinstance(v, tuple) else v
                 for name, v in light.model_dump(include=set(_LIGHT_FIELDS)).items()}
                for light in key.lights]
        keys.append(entry)
    return {"format": KEYFRAMES_FORMAT, "version": KEYFRAMES_VERSION,
            "easing": animation.easing,
            "time_index_interpolation": animation.time_index_interpolation,
            "keyframes": keys}


def read_keyframes(path: str | os.PathLike[str]) -> Animation:
    """Read a ``*.keyframes.json`` file. Every problem is a :class:`KeyframeError` whose
    one-line message starts with the file's name."""
    path = Path(path)
    name = path.name

    def fail(problem: str) -> KeyframeError:
        return KeyframeError(f"{name}: {problem}")

    try:
        info = path.stat()
        if stat.S_ISDIR(info.st_mode):
            raise fail("is a folder, not a keyframe file")
        if not stat.S_ISREG(info.st_mode):
            raise fail("is not a regular file (a pipe, socket or device)")
        if info.st_size > MAX_FILE_BYTES:
            raise fail(f"is {info.st_size / 2**20:.0f} MiB, too large for a keyframe file "
                       f"(at most {MAX_FILE_BYTES // 2**20} MiB)")
        blob = path.read_bytes()
    except FileNotFoundError:
        raise fail("no such file") from None
    except OSError as exc:
        raise fail(f"cannot be read ({exc.strerror or exc})") from None
    try:
        text = blob.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise fail(f"is not a text file (not UTF-8 at byte {exc.start})") from None
    try:
        raw = strict_json.loads(text)
    except json.JSONDecodeError as exc:
        raise fail(f"is not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}"
                   ) from None
    except ValueError as exc:
        raise fail(f"is not valid JSON: {exc}") from None
    except RecursionError:
        raise fail("is nested too deeply to be a keyframe file") from None
    if strict_json.nesting_depth(raw) > 16:
        raise fail("is nested too deeply to be a keyframe file")
    try:
        return animation_from_json(raw)
    except KeyframeError as exc:
        raise fail(str(exc)) from None


def save_keyframes(path: str | os.PathLike[str], animation: Animation, *,
                   replace: bool = True) -> Path:
    """Write ``animation`` to ``path`` as JSON, atomically (:mod:`vtkvol.io.atomic`)."""
    from vtkvol.io.atomic import write_atomic

    text = json.dumps(animation_to_json(animation), indent=2, ensure_ascii=False) + "\n"
    return write_atomic(Path(path), text, replace=replace)
