"""Which renderer draws the volume, and which combinations each one supports (no VTK).

``render.renderer`` chooses between VTK's GPU ray caster (``"raycast"``, every technique runs
inside it) and the renderers that draw the volume themselves beside it, in the renderer's
``EndEvent`` (:mod:`vtkvol.engine.renderers`, docs/architecture.md "Renderers beside the ray
caster"):

* ``"path_tracer"``: a progressive camera path tracer, one path per pixel per frame. It is the
  light transport itself, so the illumination *method* is not used; the medium material
  (``render.albedo``, ``render.phase_g``) and the lights are.
* ``"slicing"``: view-aligned slicing (seed 002), unshaded or with the host's local
  (Phong) lighting; only the ``local`` method.
* ``"half_angle"``: half-angle slicing (seed 001 §2.3.1, Kniss et al.) with direct and
  chromatic, blurred indirect light. Like the path tracer it is its own light transport (the
  medium material and the light are used, not the method); exactly one enabled light, since
  the slicing axis is the half vector between the view and that light.

:func:`unsupported_reason` is the one place that says what is refused and why; the engine
raises it as an error, the app greys the choice with it as the tooltip.
"""

from __future__ import annotations

from typing import Literal

RendererName = Literal["raycast", "path_tracer", "half_angle", "slicing"]
RENDERERS: tuple[str, ...] = ("raycast", "path_tracer", "half_angle", "slicing")
#: Lights a beside-renderer takes (the path tracer sums them; slicing lights with each).
MAX_LIGHTS = 4


def unsupported_reason(renderer: str, *, method: str = "local", blend_mode: str = "composite",
                       lights: int = 1, channels: int = 1) -> str | None:
    """One sentence saying why ``renderer`` cannot render this combination, or None.

    ``lights``: enabled lights; ``channels``: components of the data (1–4).
    """
    if renderer not in RENDERERS:
        return (f"renderer must be one of {', '.join(RENDERERS)}, not {renderer!r}")
    if renderer == "raycast":
        return None
    if blend_mode != "composite":
        return (f"the {renderer} renderer composites emission and absorption only; "
                f"blend mode {blend_mode!r} needs the raycast renderer")
    if not 1 <= channels <= 4:
        return f"the {renderer} renderer takes 1 to 4 channels, not {channels}"
    if renderer == "half_angle" and lights != 1:
        return (f"the half_angle renderer slices along the half vector of one light and the "
                f"view, so it takes exactly one enabled light, not {lights}")
    if lights > MAX_LIGHTS:
        return f"the {renderer} renderer takes at most {MAX_LIGHTS} lights, not {lights}"
    if renderer == "path_tracer" and lights < 1:
        return "the path_tracer renderer needs at least one enabled light"
    if renderer == "slicing" and method != "local":
        return (f"the slicing renderer shades with local lighting only; method {method!r} "
                "needs the raycast renderer")
    return None
