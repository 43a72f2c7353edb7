"""What an illumination technique *is*, readable without VTK: its declaration and the registry.

A technique is a package ``vtkvol/plugins/<name>/`` (or any third-party package) whose
``__init__`` holds a :class:`TechniqueSpec` and nothing that imports VTK. The spec names the
engine class (``"module:Class"``, imported only when something renders), declares the
parameters, the lighting model and the capabilities, and lists benchmark settings as data.
The model, session files, the docs generator and the lights dock read specs only; the engine
(:mod:`vtkvol.engine.technique`) imports the engine part on demand.

Registration::

    [project.entry-points."vtkvol.techniques"]
    my_method = "my_package.my_method:TECHNIQUE"

or, from code and tests, :func:`register` (also a context manager that unregisters on exit).
A plugin that fails to load is reported with a :class:`RuntimeWarning` naming it and the error;
it never disappears silently.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from vtkvol.model.params import Invalidates, Param, defaults, invalidations, validate_values

__all__ = [
    "CAPABILITIES",
    "ENTRY_POINT_GROUP",
    "LIGHTING_MODELS",
    "BenchSetting",
    "Registration",
    "TechniqueSpec",
    "broken_techniques",
    "get_spec",
    "register",
    "reload_techniques",
    "technique_specs",
]

ENTRY_POINT_GROUP = "vtkvol.techniques"

LightingModel = Literal["surface", "medium"]
#: ``surface``: gradient-shaded Blinn–Phong with visibility terms; ``medium``: emission–absorption
#: with single scattering towards each light (phase function) plus in-scattered irradiance.
#: Both are written out as formulas in docs/architecture.md ("Lighting models").
LIGHTING_MODELS: tuple[str, ...] = ("surface", "medium")

#: What a technique can declare about itself:
#:
#: * ``progressive``: refines over frames; the host keeps asking for frames until it is done,
#:   resets on data/TF/crop/light/parameter changes and never on camera moves;
#: * ``view_dependent``: its precomputation depends on the camera; the host tells it when the
#:   view changed (every other technique is guaranteed never to recompute on camera moves);
#: * ``rgb``: provides coloured light transmittance (``vv_light_transmittance_rgb``);
#: * ``cpu_path``: has a numpy path that computes the same per-voxel light as its GPU path
#:   (fallback without compute shaders, and the oracle its tests compare against).
#: ``adds_light``: the technique's lighting adds light that local shading does not have
#: (indirect, in-scattered), so it is not darker than local shading and the automatic exposure
#: (vtkvol/engine/exposure.py) leaves it at 1.
CAPABILITIES: frozenset[str] = frozenset({"progressive", "view_dependent", "rgb", "cpu_path",
                                          "adds_light"})


@dataclass(frozen=True)
class BenchSetting:
    """One setting the benchmark measures: parameter values (over the declared defaults) and a
    short label for charts. ``quick`` settings are also measured by ``vtkvol bench --quick``."""

    values: Mapping[str, Any]
    label: str = ""
    quick: bool = False


@dataclass(frozen=True)
class TechniqueSpec:
    """The VTK-free declaration of one illumination technique.

    Attributes
    ----------
    name
        Identifier stored in sessions and given on the command line (``"shadow_volume"``).
    label, description
        Shown in the method chooser and in ``docs/techniques.md``.
    engine
        ``"module:Class"`` of its :class:`vtkvol.engine.technique.Technique` subclass.
    parameters
        Declared :class:`~vtkvol.model.params.Param` (the only place defaults, ranges and units
        are written).
    lighting
        ``"surface"`` or ``"medium"`` (see :data:`LIGHTING_MODELS`).
    capabilities
        A subset of :data:`CAPABILITIES`.
    bench
        Settings the benchmark measures; empty = the declared defaults only.
    stability
        Settings the stability sweep runs (each on every stress case); empty = defaults only.
    cpu_path_values
        Parameter values (over each benchmarked setting's) with which the benchmark runs the
        CPU light path for its per-voxel error: a stochastic path's sample count, so that
        check costs seconds per scene instead of the tens of minutes a converged numpy
        estimate takes; empty = the setting's own values.
    """

    name: str
    label: str
    engine: str
    description: str = ""
    parameters: tuple[Param, ...] = ()
    lighting: LightingModel = "surface"
    capabilities: frozenset[str] = field(default_factory=frozenset)
    bench: tuple[BenchSetting, ...] = ()
    stability: tuple[BenchSetting, ...] = ()
    cpu_path_values: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"technique name {self.name!r} must be a Python identifier")
        if self.lighting not in LIGHTING_MODELS:
            raise ValueError(
                f"technique {self.name!r}: lighting must be one of {', '.join(LIGHTING_MODELS)}, "
                f"not {self.lighting!r}"
            )
        object.__setattr__(self, "capabilities", frozenset(self.capabilities))
        unknown = sorted(self.capabilities - CAPABILITIES)
        if unknown:
            raise ValueError(
                f"technique {self.name!r}: unknown capabilities {', '.join(unknown)}; "
                f"known: {', '.join(sorted(CAPABILITIES))}"
            )
        if ":" not in self.engine:
            raise ValueError(f"technique {self.name!r}: engine must be 'module:Class'")
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"technique {self.name!r} declares a parameter twice")
        for p in self.parameters:
            for other, _ in p.applies_when:
                if other not in names:
                    raise ValueError(
                        f"technique {self.name!r}: {p.name} applies when {other!r}, "
                        "which is not one of its parameters"
                    )
        for setting in (*self.bench, *self.stability):
            self.validate(setting.values)
        self.validate(self.cpu_path_values)

    def has(self, capability: str) -> bool:
        return capability in self.capabilities

    def defaults(self) -> dict[str, Any]:
        return defaults(self.parameters)

    def validate(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Complete values: declared defaults overridden by ``values``; ``ValueError`` if bad."""
        return validate_values(self.parameters, values)

    def invalidations(self, names: Iterable[str]) -> Invalidates:
        """What changing the parameters ``names`` requires, merged."""
        return invalidations(self.parameters, names)

    def parameter(self, name: str) -> Param:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"technique {self.name!r} has no parameter {name!r}")


# -- registry -----------------------------------------------------------------------------------
_registered: dict[str, TechniqueSpec] = {}


class Registration:
    """Handle returned by :func:`register`: ``unregister()``, or use it as a context manager."""

    def __init__(self, spec: TechniqueSpec, replaced: TechniqueSpec | None) -> None:
        self.spec = spec
        self._replaced = replaced

    def unregister(self) -> None:
        if _registered.get(self.spec.name) is self.spec:
            del _registered[self.spec.name]
            if self._replaced is not None:
                _registered[self.spec.name] = self._replaced

    def __enter__(self) -> TechniqueSpec:
        return self.spec

    def __exit__(self, *exc: object) -> None:
        self.unregister()


def register(spec: TechniqueSpec) -> Registration:
    """Make ``spec`` available under ``spec.name`` (over an installed one of the same name)."""
    if not isinstance(spec, TechniqueSpec):
        raise TypeError(f"register() needs a TechniqueSpec, not {type(spec).__name__}")
    replaced = _registered.get(spec.name)
    _registered[spec.name] = spec
    return Registration(spec, replaced)


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    try:
        return list(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP))
    except Exception as exc:  # broken metadata of an unrelated distribution
        warnings.warn(f"vtkvol: could not read technique entry points: {exc}", RuntimeWarning,
                      stacklevel=3)
        return []


@functools.lru_cache(maxsize=1)
def _installed() -> tuple[dict[str, TechniqueSpec], dict[str, str]]:
    """(specs by name, errors by entry-point name) of the installed entry points."""
    specs: dict[str, TechniqueSpec] = {}
    errors: dict[str, str] = {}
    for ep in _entry_points():
        try:
            obj = ep.load()
        except Exception as exc:
            errors[ep.name] = f"{ep.value} failed to load: {type(exc).__name__}: {exc}"
            continue
        if not isinstance(obj, TechniqueSpec):
            errors[ep.name] = f"{ep.value} is a {type(obj).__name__}, not a TechniqueSpec"
            continue
        if obj.name != ep.name:
            errors[ep.name] = f"{ep.value} declares the name {obj.name!r}"
            continue
        specs[ep.name] = obj
    for name, why in errors.items():
        warnings.warn(f"vtkvol illumination plugin {name!r} is unavailable: {why}",
                      RuntimeWarning, stacklevel=4)
    return specs, errors


def technique_specs() -> dict[str, TechniqueSpec]:
    """Every available technique by name: installed entry points, then :func:`register`-ed."""
    installed, _ = _installed()
    return {**installed, **_registered}


def broken_techniques() -> dict[str, str]:
    """Entry points that failed to load, with the reason (shown by the app and ``vtkvol info``)."""
    return dict(_installed()[1])


def get_spec(name: str) -> TechniqueSpec:
    """The declaration of technique ``name``; ``ValueError`` names the known ones."""
    specs = technique_specs()
    if name in specs:
        return specs[name]
    broken = broken_techniques()
    if name in broken:
        raise ValueError(f"illumination method {name!r} is installed but broken: {broken[name]}")
    raise ValueError(f"unknown illumination method {name!r}; available: {', '.join(specs)}")


def reload_techniques() -> None:
    """Forget the cached entry points (after installing a plugin, or in tests)."""
    _installed.cache_clear()
