"""The two library calls most users need: :func:`illuminate` and :func:`render_image`."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import vtk

from vtkvol.engine.illuminator import Illuminator, check_multichannel_lighting
from vtkvol.engine.offscreen import grab, make_render_window
from vtkvol.engine.renderers import set_renderer
from vtkvol.engine.scene import VolumeScene
from vtkvol.model.defaults import scene_for
from vtkvol.model.presets import apply_preset
from vtkvol.model.scene import Light, SceneModel, model_unsupported_reason
from vtkvol.model.techniques import get_spec

if TYPE_CHECKING:
    from vtkvol.io import VolumeData


def illuminate(
    volume: vtk.vtkVolume,
    renderer: Any,
    *,
    method: str = "local",
    lights: Sequence[Light] | Literal["renderer"] | None = None,
    multichannel_lighting: str | None = None,
    volume_renderer: str | None = None,
    **parameters: Any,
) -> Illuminator:
    """Give an existing ``vtkVolume`` a vtkvol illumination technique.

    Supported: point scalars (cell data is refused with what to do), every cropping mode and
    clipping planes (what they hide casts no shadow), ``vtkSmartVolumeMapper`` (rendered through
    a GPU ray-cast mapper kept in step with it until ``release()``; with PyVista,
    ``actor.mapper`` is then PyVista's GPU mapper sharing the lookup table). ``"local"``
    lighting with the renderer's own lights keeps the property's shading flags; given
    ``lights``, or a shadow technique, switch shading on (they shade through VTK's shaded
    variant), the medium ones off, and ``release()`` restores the flags.

    Parameters
    ----------
    volume
        A ``vtkVolume`` whose mapper is a ``vtkOpenGLGPUVolumeRayCastMapper`` (with PyVista:
        ``plotter.add_volume(..., mapper="gpu")``) or a ``vtkSmartVolumeMapper`` (PyVista's
        default).
    renderer
        The ``vtkRenderer`` showing it, or a PyVista ``Plotter`` (its active renderer is used).
    method
        ``"local"``, ``"shadow_volume"``, ``"cone_traced"``, … (see
        :func:`vtkvol.model.techniques.technique_specs`).
    lights
        World-space :class:`vtkvol.Light` objects (µm). Default: the renderer's own lights
        (PyVista's light kit, VTK's headlight) as they are at the first frame, then fixed in
        the world, so turning the camera shows the shadows from another side and costs no
        recomputation of the light; a lone headlight becomes a key light 50° above and 10°
        beside the view (its shadows would fall straight behind, out of sight).
        ``"renderer"``: follow the renderer's lights at every frame (a camera light then
        recomputes precomputed illumination at every camera move).
    multichannel_lighting
        None (default): ``"per_channel"`` at the first call, unchanged at a later one. Two to
        four independent components: ``"per_channel"`` (VTK's, every component lit with its
        own normal and material) or ``"shared"`` (components classified unlit, mixed, and lit
        once per sample with the opacity-weighted normal and material: cheaper with several
        lights, ``"cone_traced"`` and ``"translucency"``, about the same cost with one light
        and ``"local"`` or ``"shadow_volume"``;
        :attr:`Illuminator.multichannel_lighting_state` says whether it applies). Later:
        ``il.set_multichannel_lighting(...)``. ``ValueError`` if neither.
    volume_renderer
        What draws the volume (``render.renderer`` of a session; named so because
        ``renderer`` is the ``vtkRenderer``): None (default) keeps the current one (VTK's ray
        caster at the first call); ``"raycast"``; ``"path_tracer"`` (progressive camera path
        tracer of the medium material, ``converge()`` refines it); ``"slicing"``
        (view-aligned slicing, ``method="local"``); ``"half_angle"`` (half-angle slicing
        with chromatic, blurred indirect light; exactly one light). An unsupported
        combination is a ``ValueError`` naming the reason
        (:func:`vtkvol.model.renderers.unsupported_reason`). Later:
        ``vtkvol.engine.renderers.set_renderer(il, name)``.
    **parameters
        Technique parameters (validated against its declaration; ``ValueError`` if bad).

    A volume already illuminated (and not released) is not illuminated twice: the call returns
    its illuminator switched to ``method``, with the given parameters set (the others keep
    their values), the given lights (None: they stay as they are) and
    ``multichannel_lighting`` (None: unchanged); illuminating it for another renderer is a
    ``ValueError``. Refused with a ``TypeError``: other mappers, ``vtkMultiVolume`` and its
    member volumes; with a ``ValueError``: a user shader replacement that replaces a VTK tag
    vtkvol replaces too (the user's own replacements are otherwise composed with ours, and
    ``release()`` puts them back exactly).

    Returns
    -------
    Illuminator
        Keep it: ``set_lights``, ``set_parameters``, ``set_method``, ``set_material``;
        ``converge()`` refines a progressive technique to the end; ``release()`` removes
        everything it added. Transfer-function, data and crop edits made on the VTK objects are
        picked up automatically at the next render.
    """
    if not isinstance(renderer, vtk.vtkRenderer):
        renderer = getattr(renderer, "renderer", None)
        if not isinstance(renderer, vtk.vtkRenderer):
            raise TypeError("renderer must be a vtkRenderer or a PyVista Plotter")
    if isinstance(lights, str) and lights != "renderer":
        raise ValueError(f"lights must be vtkvol.Light objects or 'renderer', not {lights!r}")
    existing = Illuminator.host_of(volume)
    if existing is not None:
        if existing.renderer is not renderer:
            raise ValueError("vtkvol: this volume is already illuminated in another renderer; "
                             "release() that illuminator first")
        existing.reconfigure(method, lights=lights, parameters=parameters,
                             multichannel_lighting=multichannel_lighting)
        if volume_renderer is not None:
            set_renderer(existing, volume_renderer)
        return existing
    multichannel_lighting = multichannel_lighting or "per_channel"
    check_multichannel_lighting(multichannel_lighting)  # before the volume is touched
    illuminator = Illuminator(volume, renderer, method=method,
                              lights="renderer_fixed" if lights is None else lights,
                              parameters=parameters,
                              # lights given: the caller asks for them to shade the volume
                              keep_local_shading=lights is None or lights == "renderer")
    illuminator.set_multichannel_lighting(multichannel_lighting)
    if volume_renderer is not None:
        try:
            set_renderer(illuminator, volume_renderer)
        except ValueError:
            illuminator.release()  # a refused call leaves the volume as it was
            raise
    return illuminator


def render_image(
    data: VolumeData,
    *,
    model: SceneModel | None = None,
    size: tuple[int, int] = (512, 512),
    method: str | None = None,
    preset: str | None = None,
    azimuth: float | None = None,
    elevation: float | None = None,
    parameters: dict[str, Any] | None = None,
    max_seconds: float | None = 300.0,
    iterations: int | None = None,
    on_error: Callable[[str], None] | None = None,
    on_refined: Callable[[int, bool, float], None] | None = None,
    volume_renderer: str | None = None,
) -> np.ndarray:
    """Render ``data`` offscreen and return an ``(h, w, 3)`` uint8 image.

    ``model`` (e.g. from a session file) gives the full view; otherwise a default scene is made.
    ``method``/``preset``/``parameters`` override it. ``azimuth``/``elevation`` (degrees): with a
    model whose camera is set, they orbit from that view; otherwise they place the camera from the
    front view (looking along +y, z up; default 30°/20°, the app's opening view). A progressive
    technique refines until it has converged, has run ``iterations`` iterations (which also
    becomes its ``max_iterations``, where it declares one, so it may go past its default end)
    or ``max_seconds`` have passed (None: no limit); ``on_refined(iterations, converged,
    seconds)`` is then told where it stopped. ``on_error`` receives the one-line message when
    the technique fails (the image then shows local shading). ``volume_renderer`` overrides
    the model's ``render.renderer`` (an unsupported combination: ``ValueError``).
    """
    if iterations is not None and (isinstance(iterations, bool) or int(iterations) < 1):
        raise ValueError(f"iterations must be a whole number >= 1, not {iterations!r}")
    if max_seconds is not None and not (math.isfinite(max_seconds) and max_seconds >= 0):
        raise ValueError(f"the time budget must be a finite number of seconds >= 0, "
                         f"not {max_seconds!r}")
    with offscreen_view(data, model=model, size=size, method=method, preset=preset,
                        azimuth=azimuth, elevation=elevation, parameters=parameters,
                        iterations=iterations, on_error=on_error,
                        volume_renderer=volume_renderer) as (rw, scene, _):
        image, refining_s = settled_frame(rw, scene, max_seconds=max_seconds,
                                          iterations=iterations)
        tech = scene.illuminator.technique if scene.illuminator is not None else None
        if scene.illuminator is not None and scene.illuminator.beside is not None:
            tech = scene.illuminator.beside  # a progressive renderer beside the ray caster
        if on_refined is not None and tech is not None and refining_s is not None:
            on_refined(int(tech.iteration), bool(tech.converged), refining_s)
        return image


@contextmanager
def offscreen_view(
    data: VolumeData,
    *,
    model: SceneModel | None = None,
    size: tuple[int, int] = (512, 512),
    method: str | None = None,
    preset: str | None = None,
    azimuth: float | None = None,
    elevation: float | None = None,
    parameters: dict[str, Any] | None = None,
    iterations: int | None = None,
    on_error: Callable[[str], None] | None = None,
    volume_renderer: str | None = None,
) -> Iterator[tuple[vtk.vtkRenderWindow, VolumeScene, bool]]:
    """An offscreen window showing ``data`` as :func:`render_image` describes (a copy of
    ``model`` or a default scene, the overrides applied, the camera placed); yields
    ``(window, scene, has_camera)`` (whether the model had its own camera) and releases both
    afterwards. Shared by :func:`render_image` and the movie writer."""
    model = SceneModel.model_validate(model.model_dump()) if model is not None else scene_for(data)
    if preset is not None:
        for channel in model.channels:
            apply_preset(channel.tf, preset, tint=channel.color)
    if method is not None:
        model.illumination.method = method
    for name, value in (parameters or {}).items():
        model.illumination.set_value(name, value)
    if volume_renderer is not None:
        model.render.renderer = volume_renderer
    reason = model_unsupported_reason(model)
    if reason is not None:
        raise ValueError(f"vtkvol: {reason}")
    if iterations is not None and any(p.name == "max_iterations"
                                      for p in get_spec(model.illumination.method).parameters):
        model.illumination.set_value("max_iterations", int(iterations))
    rw = make_render_window(size)
    renderer = vtk.vtkRenderer()
    rw.AddRenderer(renderer)
    has_camera = model.camera.position is not None
    scene = VolumeScene(renderer, model, data, request_render=lambda: None)
    if on_error is not None:
        scene.error.connect(on_error)
    try:
        if has_camera:
            if azimuth or elevation:
                scene.orbit(azimuth or 0.0, elevation or 0.0)
        else:
            scene.reset_camera(
                azimuth=30.0 if azimuth is None else azimuth,
                elevation=20.0 if elevation is None else elevation,
            )
        yield rw, scene, has_camera
    finally:
        scene.close()
        rw.Finalize()


def settled_frame(rw: vtk.vtkRenderWindow, scene: VolumeScene, *, max_seconds: float | None,
                  iterations: int | None = None,
                  retry_failed: bool = True) -> tuple[np.ndarray, float | None]:
    """Render one frame as users see it once the view settles: a technique that failed to
    build shows local shading in a second frame (``retry_failed``: the scene's first frame),
    a progressive one refines (to ``iterations`` or ``max_seconds``) first, and the automatic
    exposure is measured on the settled light (:meth:`VolumeScene.update_exposure`). Returns the
    ``(h, w, 3)`` uint8 image and the seconds spent refining (None: nothing to refine)."""
    image = grab(rw)
    illuminator = scene.illuminator
    if retry_failed and illuminator is not None and illuminator.failed_method is not None:
        image = grab(rw)  # the failed build showed nothing; this frame is local shading
    refining_s = None
    if illuminator is not None and illuminator.wants_frame:
        t0 = time.perf_counter()
        illuminator.converge(max_seconds=max_seconds, iterations=iterations)
        image = grab(rw, render=False)
        refining_s = time.perf_counter() - t0
    if scene.update_exposure():
        assert illuminator is not None
        with illuminator.holding_still():
            image = grab(rw)  # the same light, nothing refined: only the exposure differs
    return image, refining_s
