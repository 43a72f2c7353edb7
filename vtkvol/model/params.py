"""Parameter declarations for illumination techniques (pure data, no VTK, no Qt).

Every technique declares its parameters once, as a tuple of :class:`Param`. The model validates
against it, the lighting dock generates its widgets from it, the session schema stores values
keyed by it, and ``docs/techniques.md`` is generated from it. No default, range or step is
written anywhere else.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal


class Invalidates(enum.Flag):
    """What must be redone when a value changes. The technique host merges the flags of every
    parameter changed since the last frame into ``Changes.invalidates``: SHADER rebuilds the
    program, ILLUMINATION recomputes precomputed light, ACCUMULATION restarts progressive
    refinement (ILLUMINATION implies it), FRAME only uploads uniforms."""

    FRAME = enum.auto()  #: upload uniforms and render again
    ACCUMULATION = enum.auto()  #: restart progressive refinement
    ILLUMINATION = enum.auto()  #: recompute precomputed light (shadow volume, filtered opacity)
    SHADER = enum.auto()  #: replacement text changed: the program is rebuilt


@dataclass(frozen=True)
class Param:
    """One declared technique parameter.

    ``kind`` is ``"float"``, ``"int"``, ``"bool"`` or ``"choice"``. ``range`` is inclusive.
    ``unit`` is shown in labels (``"voxel"``, ``"°"``, ``""``). ``scale="log"`` asks the UI for
    a logarithmic slider. ``choice_labels`` (optional, one per choice) are the words the app
    shows for a ``"choice"`` parameter's values; the values stay the stored identifiers.
    ``applies_when`` lists ``(other parameter, values)`` pairs that must
    all hold for this parameter to have an effect (the dock hides it otherwise), e.g.
    ``(("ao_mode", ("view_cone",)),)``.
    """

    name: str
    default: Any
    label: str
    doc: str
    kind: Literal["float", "int", "bool", "choice"] = "float"
    range: tuple[float, float] | None = None
    step: float | None = None
    unit: str = ""
    scale: Literal["linear", "log"] = "linear"
    choices: tuple[str, ...] = ()
    choice_labels: tuple[str, ...] = ()
    invalidates: Invalidates = Invalidates.FRAME
    uniform: bool = field(default=True)  # uploaded as vv_<technique>_<name> when numeric
    applies_when: tuple[tuple[str, tuple[Any, ...]], ...] = ()

    def __post_init__(self) -> None:
        if self.choice_labels and len(self.choice_labels) != len(self.choices):
            raise ValueError(f"{self.name}: {len(self.choice_labels)} choice labels for "
                             f"{len(self.choices)} choices")

    def choice_label(self, value: Any) -> str:
        """The declared label of choice ``value`` (the value itself when none is declared)."""
        if self.choice_labels and value in self.choices:
            return self.choice_labels[self.choices.index(value)]
        return str(value)

    def applies(self, values: Mapping[str, Any]) -> bool:
        """Whether this parameter has an effect given the technique's other ``values``."""
        return all(values.get(other) in allowed for other, allowed in self.applies_when)

    def inert_reason(self, values: Mapping[str, Any]) -> str | None:
        """Why this parameter has no effect given ``values`` (one sentence naming the
        parameter that would enable it), or None when it applies."""
        for other, allowed in self.applies_when:
            if values.get(other) not in allowed:
                wanted = " or ".join(f"{other}={a!r}" for a in allowed)
                return (f"{self.name} has no effect while {other} is {values.get(other)!r}; "
                        f"set {wanted}")
        return None

    def validate(self, value: Any) -> Any:
        """Return ``value`` coerced to this parameter's type, or raise ``ValueError``."""
        if self.kind == "bool":
            if isinstance(value, bool):
                return value
            raise ValueError(f"{self.name} must be true or false, not {value!r}")
        if self.kind == "choice":
            if value in self.choices:
                return value
            raise ValueError(f"{self.name} must be one of {', '.join(self.choices)}; got {value!r}")
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{self.name} must be a number, not {value!r}") from None
        if not math.isfinite(number):
            raise ValueError(f"{self.name} must be finite, not {value!r}")
        if self.kind == "int":
            if number != int(number):
                raise ValueError(f"{self.name} must be a whole number, not {value!r}")
            number = int(number)
        if self.range is not None:
            lo, hi = self.range
            if not lo <= number <= hi:
                unit = f" {self.unit}" if self.unit else ""
                raise ValueError(
                    f"{self.name} = {value!r} is outside its range {lo:g}…{hi:g}{unit}"
                )
        return number


def backend_param(invalidates: Invalidates) -> Param:
    """The ``backend`` parameter of a technique with a GPU and a numpy path."""
    return Param(
        "backend", "auto", "Compute on",
        "auto: compute shaders when the OpenGL context has them, else numpy; cpu: always numpy "
        "(verification).",
        kind="choice", choices=("auto", "cpu"), choice_labels=("GPU when available", "CPU (numpy)"),
        invalidates=invalidates, uniform=False,
    )


def defaults(params: Iterable[Param]) -> dict[str, Any]:
    return {p.name: p.default for p in params}


def validate_values(params: Iterable[Param], values: Mapping[str, Any]) -> dict[str, Any]:
    """Validate ``values`` against ``params``; missing ones take defaults, unknown ones raise."""
    declared = {p.name: p for p in params}
    unknown = sorted(set(values) - set(declared))
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}; known: {', '.join(declared)}")
    return {name: p.validate(values.get(name, p.default)) for name, p in declared.items()}


def invalidations(params: Iterable[Param], names: Iterable[str]) -> Invalidates:
    """The merged :class:`Invalidates` of the parameters ``names`` (unknown names: nothing)."""
    declared = {p.name: p for p in params}
    result = Invalidates(0)
    for name in names:
        if name in declared:
            result |= declared[name].invalidates
    return result
