"""Renderers that draw the volume themselves, beside VTK's GPU ray caster.

:func:`set_renderer` attaches one to an :class:`~vtkvol.engine.illuminator.Illuminator` (the
host keeps classifying, following lights and reporting progress; the renderer reads its
opacity texture, lights and material) or gives the volume back to VTK's ray caster
(``"raycast"``). The mechanism is in :mod:`.base`; docs/architecture.md, "Renderers beside
the ray caster", has the decision and the measurements.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from vtkvol.engine.renderers.base import check_renderer
from vtkvol.model.renderers import RENDERERS

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.renderers.base import BesideRenderer

__all__ = ["RENDERERS", "apply_renderer", "check_renderer", "renderer_class", "set_renderer"]


def renderer_class(name: str) -> type[BesideRenderer]:
    from vtkvol.engine.renderers.half_angle import HalfAngleSlicing
    from vtkvol.engine.renderers.path_tracer import PathTracer
    from vtkvol.engine.renderers.slicing import ViewAlignedSlicing

    return {"path_tracer": PathTracer, "slicing": ViewAlignedSlicing,
            "half_angle": HalfAngleSlicing}[name]


def set_renderer(host: Illuminator, name: str, **options: Any) -> BesideRenderer | None:
    """Draw ``host``'s volume with renderer ``name`` from the next frame on (``"raycast"``:
    VTK's ray caster, the default). ``options`` go to the renderer (the path tracer's
    ``scattering``, ``samples``, ``seed``; slicing's ``slices_per_voxel``; half-angle
    slicing's ``slices_per_voxel``, ``light_resolution``, ``samples``, ``indirect_angle``,
    ``indirect_extinction``, ``tint``, ``indirect_strength``). Refused with a
    ``ValueError`` naming the reason when the combination is unsupported; the previous
    renderer then stays. Returns the renderer (None for ``"raycast"``)."""
    check_renderer(host, name)
    old = host.beside
    if old is not None:
        old.release()
        host.beside = None
    if name == "raycast":
        return None
    renderer = renderer_class(name)(host, **options)
    host.beside = renderer
    return renderer


def apply_renderer(host: Illuminator, name: str, on_refused: Any = None,
                   options: dict[str, Any] | None = None) -> str:
    """Make ``host`` draw with ``name`` if the combination is supported, else with VTK's ray
    caster, telling ``on_refused`` the one-line reason (once per reason). For views that
    follow a model (:class:`vtkvol.engine.scene.VolumeScene`): called again after every edit
    that can change what is supported (method, blend mode, lights). Returns what draws now."""
    current = host.beside.NAME if host.beside is not None else "raycast"
    try:
        check_renderer(host, name)
    except ValueError as exc:
        if host.beside is not None:
            set_renderer(host, "raycast")
        if on_refused is not None and getattr(host, "_renderer_refusal", None) != str(exc):
            on_refused(str(exc))
        host._renderer_refusal = str(exc)  # type: ignore[attr-defined]
        return "raycast"
    host._renderer_refusal = None  # type: ignore[attr-defined]
    if current != name:
        set_renderer(host, name, **(options or {}))
    return name
