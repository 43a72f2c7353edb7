"""Checks and repairs of a session being read (:func:`vtkvol.model.session.read_session`): the
view (camera and lights), transfer functions reduced to the engine's limit, technique
parameters against their declarations, and pydantic's errors in words a user reads. Each check
adds one line to ``notes`` for what it repaired, or raises with the message."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import pydantic

from vtkvol.model.params import Param
from vtkvol.model.scene import MAX_COORDINATE_UM, SceneModel
from vtkvol.model.session_errors import SessionError
from vtkvol.model.techniques import get_spec
from vtkvol.model.transfer_function import MAX_POINTS

_MAX_LISTED = 6  # problems named in one message before "and N more"
# -- camera and lights --------------------------------------------------------------------------


def check_view(session_path: Path, model: SceneModel, notes: list[str]) -> None:
    """Refuse a camera or light that cannot describe a view; repair a degenerate view-up.

    Refused (:class:`SessionError` naming the field): a position, focal point or parallel
    scale beyond :data:`MAX_COORDINATE_UM`, a light position beyond it, a camera at its own
    focal point (it looks in no direction). Repaired with a note: a view-up that is zero or
    along the view direction (VTK then builds a degenerate view matrix and renders nothing).
    """
    cam = model.camera
    fields = [(f"camera.{name}", getattr(cam, name)) for name in ("position", "focal_point")]
    fields += [(f"lights[{i}].position", light.position) for i, light in enumerate(model.lights)]
    for where, value in fields:
        if value is not None and max(abs(c) for c in value) > MAX_COORDINATE_UM:
            raise SessionError(
                session_path,
                f"{where} = {show_value(list(value))} lies beyond ±{MAX_COORDINATE_UM:g} µm; "
                "no view "
                "of the data is that far away",
            )
    if cam.parallel_scale > MAX_COORDINATE_UM:
        raise SessionError(
            session_path,
            f"camera.parallel_scale = {show_value(cam.parallel_scale)} is above "
            f"{MAX_COORDINATE_UM:g} µm; no view of the data is that wide",
        )
    forward = None
    if cam.position is not None and cam.focal_point is not None:
        back = [p - f for p, f in zip(cam.position, cam.focal_point, strict=True)]
        distance = math.sqrt(sum(c * c for c in back))  # < 2e12·√3: finite
        scale = max(1.0, *(abs(c) for c in cam.focal_point))
        if not distance > 1e-9 * scale:
            raise SessionError(
                session_path,
                f"camera.position = {show_value(list(cam.position))} is the "
                "camera.focal_point: the "
                "camera looks in no direction (move it away from the focal point, or remove "
                "both to frame the data)",
            )
        forward = [c / distance for c in back]
    up = _perpendicular_up(cam.view_up, forward)
    if up is not None:
        notes.append(
            f"camera.view_up = {show_value(list(cam.view_up))} is "
            f"{'zero' if not any(cam.view_up) else 'along the view direction'}; replaced by "
            f"{show_value([round(c, 6) for c in up])}"
        )
        cam.view_up = up


def _perpendicular_up(
    up: tuple[float, float, float], forward: list[float] | None
) -> tuple[float, float, float] | None:
    """A usable view-up when ``up`` is zero or (nearly) along the unit ``forward``; else None.

    The replacement is the default (0, 1, 0), or (0, 0, 1) when that is along ``forward``,
    with its part along ``forward`` removed and normalised.
    """
    largest = max(abs(c) for c in up)
    if largest > 0.0:
        scaled = [c / largest for c in up]  # no overflow for 1e200 components
        length = math.sqrt(sum(c * c for c in scaled))
        unit = [c / length for c in scaled]
        if forward is None or _cross_norm(unit, forward) > 1e-6:
            return None
    if forward is None:
        return (0.0, 1.0, 0.0)
    for candidate in ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
        along = sum(a * b for a, b in zip(candidate, forward, strict=True))
        rest = [a - along * b for a, b in zip(candidate, forward, strict=True)]
        length = math.sqrt(sum(c * c for c in rest))
        if length > 1e-3:
            return (rest[0] / length, rest[1] / length, rest[2] / length)
    return (1.0, 0.0, 0.0)  # unreachable: forward cannot be along both y and z


def _cross_norm(a: list[float], b: list[float]) -> float:
    x = a[1] * b[2] - a[2] * b[1]
    y = a[2] * b[0] - a[0] * b[2]
    z = a[0] * b[1] - a[1] * b[0]
    return math.sqrt(x * x + y * y + z * z)


def reduce_transfer_functions(model: SceneModel, notes: list[str]) -> None:
    """Sample transfer functions longer than :data:`MAX_POINTS` down to it, with a note (the
    renderer could not use more, and the app's editor would draw every point)."""
    for c, channel in enumerate(model.channels):
        reduced = channel.tf.reduced(MAX_POINTS)
        if reduced is None:
            continue
        counts = [f"{len(points)} {what}" for what, points, new in (
            ("colour", channel.tf.colors, reduced.colors),
            ("opacity", channel.tf.opacity, reduced.opacity)) if len(points) != len(new)]
        lo, hi = reduced.value_span
        notes.append(
            f"channels[{c}].tf: {' and '.join(counts)} points reduced to {MAX_POINTS} "
            f"(the function sampled evenly over {lo:g}…{hi:g}; the renderer's tables have "
            f"{MAX_POINTS} entries)"
        )
        channel.tf = reduced


# -- technique parameters -----------------------------------------------------------------------
def technique_parameters(name: str) -> tuple[tuple[Param, ...] | None, str]:
    """The declared parameters of an installed technique, or ``(None, why not)``."""
    try:
        spec = get_spec(name)
    except ValueError as exc:
        return None, str(exc)
    return spec.parameters, ""


def technique_known(name: str) -> bool:
    return technique_parameters(name)[0] is not None


def check_parameters(
    session_path: Path, stored: Mapping[str, Mapping[str, Any]], notes: list[str]
) -> dict[str, dict[str, Any]]:
    """Validate each installed technique's stored values against its ``PARAMETERS``.

    Values are checked one by one and only the stored ones are kept (the engine fills in
    defaults), so a session round-trips exactly. Names the technique no longer declares are
    dropped with a note; techniques not installed here keep their values, with a note.
    """
    out: dict[str, dict[str, Any]] = {}
    for method, values in stored.items():
        declared, why = technique_parameters(method)
        if declared is None:
            notes.append(
                f"illumination.parameters.{method}: technique not installed here ({why}); "
                "its values are kept unchecked"
            )
            out[method] = dict(values)
            continue
        by_name = {p.name: p for p in declared}
        unknown = sorted(set(values) - set(by_name))
        if unknown:
            notes.append(
                f"illumination.parameters.{method}: ignored parameter(s) the technique does "
                f"not declare: {', '.join(unknown)}"
            )
        checked: dict[str, Any] = {}
        for name, value in values.items():
            if name not in by_name:
                continue
            param = by_name[name]
            try:
                checked[name] = _check_value(param, value)
            except ValueError as exc:
                raise SessionError(
                    session_path, f"illumination.parameters.{method}: {exc}"
                ) from exc
        out[method] = checked
    return out


def _check_value(param: Param, value: Any) -> Any:
    # Param.validate is lenient (float("2") works, True counts as 1); a file is held to JSON
    # types: numbers for numeric parameters.
    numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
    if param.kind in ("float", "int") and not numeric:
        raise ValueError(f"{param.name} must be a number, not {show_value(value)}")
    return param.validate(value)


# -- messages -----------------------------------------------------------------------------------
_TYPE_WORDS = {
    "float_type": "a number",
    "float_parsing": "a number",
    "int_type": "a whole number",
    "int_parsing": "a whole number",
    "int_from_float": "a whole number",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
    "string_type": "text",
    "list_type": "an array",
    "tuple_type": "an array",
    "dict_type": "an object",
    "model_type": "an object",
    "model_attributes_type": "an object",
}


def describe_validation_error(exc: pydantic.ValidationError, prefix: str = "") -> str:
    """pydantic's errors as one line of text with the place in the file of each."""
    errors = exc.errors(include_url=False)
    parts = [_describe_one(err, prefix) for err in errors[:_MAX_LISTED]]
    if len(errors) > _MAX_LISTED:
        parts.append(f"and {len(errors) - _MAX_LISTED} more problem(s)")
    return "; ".join(parts)


def _where(loc: Iterable[Any], prefix: str) -> str:
    text = prefix
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text = f"{text}.{part}" if text else str(part)
    return text or "scene"


def _describe_one(err: Mapping[str, Any], prefix: str) -> str:
    kind, loc = err["type"], tuple(err["loc"])
    ctx = err.get("ctx") or {}
    where = _where(loc, prefix)
    shown = show_value(err.get("input"))
    if kind == "missing" and loc and isinstance(loc[-1], int):
        # A tuple with too few items reports its first absent index as a missing field.
        return f"{_where(loc[:-1], prefix)} = {shown} has too few values"
    if kind == "too_long":
        return (
            f"{where} = {shown} has {ctx.get('actual_length')} values, "
            f"at most {ctx.get('max_length')} allowed"
        )
    if kind == "too_short":
        return f"{where} = {shown} has too few values (at least {ctx.get('min_length')})"
    if kind == "greater_than_equal":
        return f"{where} = {shown} is below {_num(ctx['ge'])}"
    if kind == "less_than_equal":
        return f"{where} = {shown} is above {_num(ctx['le'])}"
    if kind == "greater_than":
        return f"{where} = {shown} must be greater than {_num(ctx['gt'])}"
    if kind == "less_than":
        return f"{where} = {shown} must be less than {_num(ctx['lt'])}"
    if kind == "value_error":
        return f"{where}: {ctx.get('error', err['msg'])}"
    if kind == "extra_forbidden":
        return f"{where} is not a known setting"
    if kind == "literal_error":
        return f"{where} = {shown} must be one of {ctx.get('expected')}"
    if kind == "string_pattern_mismatch":
        return f"{where} = {shown} is not in the expected form"
    if kind in _TYPE_WORDS:
        return f"{where} = {shown} should be {_TYPE_WORDS[kind]}"
    return f"{where}: {err['msg']}"


def _num(x: Any) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def show_value(value: Any, limit: int = 60) -> str:
    """A value as it appears in the file (JSON), shortened."""
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"
