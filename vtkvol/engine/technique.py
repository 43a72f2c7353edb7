"""The shape every illumination technique has, and the registry that finds them.

One technique = one module in ``plugins/`` + one GLSL file in ``resources/shaders/``, registered
under the ``vtkvol.techniques`` entry point. A technique:

* declares ``NAME``, ``LABEL``, ``DESCRIPTION``, ``PARAMETERS`` (:class:`vtkvol.model.Param`)
  and ``SHADER`` (file name);
* supplies the GLSL functions the host's lighting code calls for every shaded sample::

      float vv_light_visibility(int light, vec3 texPos, vec3 dirDS);  // 1 = unshadowed
      float vv_ambient_visibility(vec3 texPos, vec3 normalDS);         // 1 = unoccluded

  (``texPos`` is VTK's texture coordinate ``g_dataPos``; directions are unit vectors in
  dataset space, µm-scaled, pointing towards the light / away from the surface);
* implements the hooks below. The host calls every hook with the GL context current (from the
  renderer's ``StartEvent``), so techniques never make contexts current themselves.

Lifecycle (mirrored): ``attach`` → (``prepare`` per frame)* → ``release``.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from importlib import metadata
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtkvol.engine import shaders
from vtkvol.model.params import Param, defaults

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Changes, Illuminator, LightSpec

ENTRY_POINT_GROUP = "vtkvol.techniques"

# Used when the package metadata is not installed (running from a source checkout).
_BUILTIN = {
    "local": "vtkvol.plugins.local_shading:LocalShading",
    "shadow_volume": "vtkvol.plugins.shadow_volume:ShadowVolume",
    "cone_traced": "vtkvol.plugins.cone_traced:ConeTraced",
}


class Technique:
    """Base class: a technique that needs no precomputation and no textures."""

    NAME: ClassVar[str]
    LABEL: ClassVar[str]
    DESCRIPTION: ClassVar[str] = ""
    PARAMETERS: ClassVar[tuple[Param, ...]] = ()
    SHADER: ClassVar[str]

    def __init__(self, host: Illuminator) -> None:
        self.host = host

    # -- hooks --------------------------------------------------------------------------------
    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        """Compile-time constants for the GLSL (``SHADER``-invalidating parameters)."""
        return {}

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        """The technique's GLSL sections: ``SHADER`` with :meth:`shader_defines` applied."""
        return shaders.load(self.SHADER, self.shader_defines(values))

    def attach(self) -> None:
        """Create GL resources (textures, compute programs). Context is current."""

    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        """Bring precomputed data up to date before a frame. ``changes`` says what changed
        since the last frame: ``opacity`` (data, TF, crop, weights, placement), ``lights``,
        ``parameters`` (names), ``first``."""

    def uniforms(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Extra per-frame uniform values (numeric declared parameters are sent already)."""
        return {}

    def release(self) -> None:
        """Release everything ``attach``/``prepare`` created. Context is current."""

    # -- verification -------------------------------------------------------------------------
    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray | None:
        """This technique's own CPU path for the per-voxel light visibility (0…1, [z, y, x]),
        or None when the technique has no per-voxel light volume."""
        return None

    @classmethod
    def defaults(cls) -> dict[str, Any]:
        return defaults(cls.PARAMETERS)


def available_techniques() -> dict[str, str]:
    """``{name: "module:Class"}`` of every registered technique (entry points + built-ins)."""
    found = dict(_BUILTIN)
    try:
        for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
            found[ep.name] = ep.value
    except Exception:  # broken metadata must not take the app down
        pass
    return found


def get_technique(name: str) -> type[Technique]:
    """The technique class registered as ``name``; ``ValueError`` lists the known names."""
    table = available_techniques()
    if name not in table:
        raise ValueError(f"unknown illumination method {name!r}; available: {', '.join(table)}")
    module_name, _, attr = table[name].partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        raise ValueError(f"illumination method {name!r} is not installed ({exc})") from exc
    cls = getattr(module, attr)
    if not (isinstance(cls, type) and issubclass(cls, Technique)):
        raise TypeError(f"{table[name]} is not a vtkvol Technique")
    return cls


def installed_techniques() -> dict[str, type[Technique]]:
    """Every technique that imports cleanly, by name (what the method chooser offers)."""
    out: dict[str, type[Technique]] = {}
    for name in available_techniques():
        try:
            out[name] = get_technique(name)
        except (ValueError, TypeError, ImportError):
            continue
    return out
