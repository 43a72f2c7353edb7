"""The technique host: gives any ``vtkVolume`` a vtkvol illumination technique.

This is both the engine's own mechanism and the public integration call
(:func:`vtkvol.illuminate`). It works on a volume built by :class:`VolumeScene`, by a plain VTK
script or by ``pyvista.Plotter.add_volume``: it only needs the ``vtkVolume`` (mapper: a
``vtkOpenGLGPUVolumeRayCastMapper``, or a ``vtkSmartVolumeMapper`` rendered through one,
:mod:`vtkvol.engine.smart`) and the ``vtkRenderer`` showing it. One illuminator per volume.

All GL work happens in the renderer's ``StartEvent`` (the context is current there): installing
shader replacements, creating textures, running precomputation and uploading uniforms. What
changed since the last frame is found by comparing cheap signatures (VTK modification times of
the input image, opacity functions and cropping; the volume matrix; lights; parameters), so
camera moves never trigger a recompute and transfer-function edits always do, whether they came
through vtkvol's model or from user code touching the VTK objects directly.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import logging
import math
import re
import time
import weakref
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from vtkvol.engine import classify, occupancy, shaders, tf2d
from vtkvol.engine.gl import GLUnavailableError, Texture2D, Texture3D, compute_supported, gl
from vtkvol.engine.smart import SmartStandIn
from vtkvol.engine.technique import Technique, technique_class
from vtkvol.model.params import Invalidates
from vtkvol.model.scene import MULTICHANNEL_LIGHTINGS, Light
from vtkvol.model.techniques import TechniqueSpec

logger = logging.getLogger(__name__)

MAX_LIGHTS = 4
#: Voxels per chunk of :meth:`Illuminator.opacity_volume_steps` (about 0.1 s of numpy).
OPACITY_SLAB_VOXELS = 1 << 21
#: Floats per light in the ``vv_lights`` uniform array (layout in host_prelude.glsl).
LIGHT_STRIDE = 12
#: GLSL hooks a technique may define; the host supplies defaults for the others
#: (resources/shaders/host_hooks.glsl).
HOOKS: dict[str, str] = {
    "vv_light_visibility": "VV_HAS_LIGHT_VISIBILITY",
    "vv_light_transmittance_rgb": "VV_HAS_LIGHT_TRANSMITTANCE_RGB",
    "vv_ambient_visibility": "VV_HAS_AMBIENT_VISIBILITY",
    "vv_irradiance": "VV_HAS_IRRADIANCE",
}
_HOOK_DEFINITION = re.compile(r"\b(?:float|vec3)\s+(vv_\w+)\s*\(")


@dataclass(frozen=True)
class LightSpec:
    """A light as techniques see it: **dataset space** (the image's own µm coordinates)."""

    kind: str  #: "directional" or "point"
    vector: tuple[float, float, float]  #: unit direction towards the light, or position (µm)
    color: tuple[float, float, float]  #: colour × intensity
    #: Physical extent: angular radius in **radians** (directional) or radius in µm (point);
    #: 0 = ideal light.
    size: float = 0.0
    #: Inverse-square fall-off: irradiance × (d0/r)², d0 (µm) = distance to the volume's centre;
    #: 0 = no fall-off.
    falloff_distance: float = 0.0

    @property
    def is_point(self) -> bool:
        return self.kind == "point"


@dataclass
class Changes:
    """What changed since the technique's last ``prepare`` (merged over skipped frames)."""

    opacity: bool = False  #: data, transfer function, crop, slice weights or volume placement
    lights: bool = False  #: light geometry: kind, direction, position, size, enabled, fall-off
    light_colors: bool = False  #: colour or intensity only (never a reason to recompute)
    parameters: set[str] = field(default_factory=set)
    #: Merged :class:`Invalidates` of the changed parameters.
    invalidates: Invalidates = field(default_factory=lambda: Invalidates(0))
    view: bool = False  #: camera or viewport changed (told to view-dependent techniques only)
    first: bool = False  #: first frame after attach

    def merge(self, later: Changes) -> Changes:
        """These changes followed by ``later`` (what a technique must catch up on when it
        skipped a prepare: the host deferred it)."""
        return Changes(
            opacity=self.opacity or later.opacity,
            lights=self.lights or later.lights,
            light_colors=self.light_colors or later.light_colors,
            parameters=self.parameters | later.parameters,
            invalidates=self.invalidates | later.invalidates,
            view=self.view or later.view,
            first=self.first or later.first,
        )

    def any_parameter(self, params: Iterable[Any], flag: Invalidates) -> bool:
        return any(p.name in self.parameters and p.invalidates & flag for p in params)

    @property
    def reset_accumulation(self) -> bool:
        """Whether a progressive technique must restart: anything but the camera changed."""
        restart = Invalidates.ACCUMULATION | Invalidates.ILLUMINATION | Invalidates.SHADER
        return (self.first or self.opacity or self.lights or self.light_colors
                or bool(self.invalidates & restart))


class Illuminator:
    """Installs one illumination technique on a ``vtkVolume`` and keeps it up to date.

    Parameters
    ----------
    volume
        The ``vtkVolume`` to light (its mapper: the OpenGL GPU ray-cast mapper, or a smart
        mapper, rendered through one until :meth:`release`).
    renderer
        The ``vtkRenderer`` that renders it.
    method
        Technique name (``vtkvol.model.techniques.technique_specs()``), e.g. ``"local"``,
        ``"shadow_volume"``, ``"cone_traced"``.
    lights
        Up to four :class:`vtkvol.model.Light` in world space; ``"renderer"``: the renderer's
        own switched-on lights (its headlight or light kit), followed at every frame;
        ``"renderer_fixed"``: those lights taken at the first frame and fixed in the world from
        then on (a lone headlight becomes a key light above and beside the camera). Default:
        one directional light.
    parameters
        Technique parameter values; missing ones take the declared defaults.
    keep_local_shading
        With ``"local"`` lighting, leave the property's shading flags as they were (VTK's own
        shading is the local model); otherwise shading is switched on for surface techniques
        and off for medium ones. Either way ``release()`` restores the flags.

    Attributes
    ----------
    on_error
        Called with a one-line, user-facing message when the technique fails (its shader does
        not compile, or its GL work fails); the illuminator has then switched itself to
        ``"local"`` (:attr:`failed_method` names the method) and does not retry it until
        :meth:`set_method` is called with it again.
    on_progress
        Called after each frame of a progressive technique with ``(iteration, converged)``.
    profiling
        When True, techniques time their precomputation on the GPU (timer queries) and report
        it in ``technique.stats()``; off by default so that nothing waits for the GPU.
    defer_precompute
        While True, frames keep the technique's previous precomputed light (no ``prepare``)
        and the changes wait, merged, for the first frame or :meth:`precompute` after it is
        set back to False. Applications set it while the user drags an edit (a TF curve, a
        light), so the frames of the drag cost what a frame costs; a change of the shader
        (a new method, a ``SHADER``-invalidating parameter) is never deferred.
    cancelled_method
        The method whose :meth:`precompute` was cancelled last (local shading is shown
        since); None after a precomputation that ran to its end.
    """

    def __init__(
        self,
        volume: vtk.vtkVolume,
        renderer: vtk.vtkRenderer,
        *,
        method: str = "local",
        lights: Sequence[Light] | Literal["renderer", "renderer_fixed"] | None = None,
        parameters: Mapping[str, Any] | None = None,
        keep_local_shading: bool = False,
    ) -> None:
        self._keep_local_shading = keep_local_shading
        if Illuminator.host_of(volume) is not None:
            raise ValueError(
                "vtkvol: this volume is already illuminated; release() its illuminator first, "
                "or call vtkvol.illuminate(), which returns that illuminator switched to the "
                "new method")
        mapper = _check_mapper(volume, renderer)
        self.volume = volume
        self.renderer = renderer
        self.shader_property = volume.GetShaderProperty()
        self._replacements = shaders.ReplacementSet(self.shader_property)
        # Refused at the call rather than at the first frame: every shaded build replaces
        # VTK's lighting exit, so a user replacement there that drops the tag never composes.
        self._replacements.compose({key: "" for key in _REPLACED_OUTRIGHT})
        #: "renderer": follow the renderer's own (switched-on) lights at every frame.
        self._follow_renderer = lights == "renderer"
        #: "renderer_fixed": take the renderer's lights once, at the first frame, and keep them
        #: fixed in the world (a lone headlight becomes a key light; see _renderer_lights).
        self._capture_renderer = lights == "renderer_fixed"
        self._lights: list[Light] = (
            [Light()] if lights is None or isinstance(lights, str) else list(lights)
        )
        self._check_lights(self._lights)
        self._unsupported: str | None = None
        self._frame_specs: list[LightSpec] | None = None
        self._check_input(raise_error=True)
        self._values: dict[str, dict[str, Any]] = {}
        self._technique_cls: type[Technique] = technique_class(method)
        self._technique: Technique | None = None
        self._detach_requested = False
        self._changes = Changes(first=True, opacity=True, lights=True)
        self._signature: tuple | None = None
        self._light_signature: tuple | None = None
        self._view_signature: tuple | None = None
        self._weights: np.ndarray | None = None  # (3, W) or None for identity
        self._weights_version = 0
        self._weights_texture: Texture2D | None = None
        self._textures: dict[str, Any] = {}
        self._uniforms: set[str] = set()  # custom uniforms set for the technique (host-owned)
        self._expected_markers: tuple[set[str], set[str]] | None = None
        self._opacity_cache: tuple[tuple, np.ndarray] | None = None
        #: Classification backend of :meth:`opacity_texture` ("auto", "gpu", "cpu").
        self._classification = "auto"
        self._classifier: classify.GpuClassifier | None = None
        self._classify_failed = ""  # why the GPU classification is off for good ("" = not)
        self._opacity_texture: Texture3D | None = None
        self._opacity_texture_key: tuple | None = None
        self._classify_stats: dict[str, Any] = classify.stats_template()
        #: Per component, VTK's table coordinates (s, t) of every voxel: they depend on the
        #: data only, so a 2-D TF edit pays the lookup, not the gradient.
        self._coords_cache: dict[int, tuple[tuple, tuple[np.ndarray, np.ndarray]]] = {}
        self._fragment_source = ""
        self._closed = False
        self._albedo = 1.0
        self._phase_g = 0.0
        self._exposure = 1.0  # the factor on the shaded colour (manual × automatic)
        self._fill = 0.0
        self._probe = False  # frames lit as local shading (exposure.measure_auto_exposure)
        self._held = False  # frames keep what is installed (holding_still)
        self._interpolation = "trilinear"
        self._skip_empty = True
        self._multichannel_lighting = "per_channel"
        #: What the last shader build did with multi-channel lighting (multichannel_lighting_state).
        self._mc_lighting_state = "per_channel"
        #: (key, per-brick ranges, ms the pass took): computed once per data set.
        self._ess_ranges: tuple[tuple, occupancy.BrickRanges, float] | None = None
        self._ess_key: tuple | None = None
        self._ess_texture: Texture3D | None = None
        self._ess_stats: dict[str, Any] = {"active": False, "reason": "not rendered yet"}
        self.last_prepare_ms = 0.0
        self.render_window: vtk.vtkRenderWindow | None = None
        self.profiling = False
        #: Multi-channel data: classify and shade the components with constant indices and
        #: shared gradient fetches (host_multichannel.glsl; the same image as VTK's loop, at a
        #: fraction of its cost on llvmpipe). False keeps VTK's own per-component loop: the
        #: reference the tests and the benchmark compare with.
        self.multichannel_sample = True
        self.last_error: str | None = None
        self.failed_method: str | None = None
        self.on_error: Callable[[str], None] | None = None
        self.on_progress: Callable[[int, bool], None] | None = None
        self.defer_precompute = False
        self.cancelled_method: str | None = None
        #: The renderer drawing this volume beside VTK's ray caster (vtkvol.engine.renderers),
        #: None while VTK's ray caster draws it.
        self.beside: Any = None
        #: True while :meth:`precompute` runs its chunks (frames then touch no technique state).
        self._stepping = False
        self._precomputed_ms = 0.0  # precompute()'s work since the last frame
        self.set_parameters(**(parameters or {}))
        #: The GPU mapper rendering in place of the user's vtkSmartVolumeMapper, if any.
        self._stand_in: SmartStandIn | None = None
        if isinstance(mapper, vtk.vtkSmartVolumeMapper):
            # The smart mapper hides its GPU mapper; render through our own, kept in step with
            # it, and give the user's back on release(). Swapped only now that nothing of the
            # call can be refused any more.
            self._stand_in = SmartStandIn(mapper)
            mapper = self._stand_in.gpu
            volume.SetMapper(mapper)
            logger.info("vtkvol: rendering the volume with a GPU ray-cast mapper in place of its "
                        "vtkSmartVolumeMapper until release()")
        # Illumination lives in VTK's computeLighting(): the surface model needs VTK's shaded
        # variant (gradients; PyVista's add_volume leaves shading off), the medium model the
        # unshaded one (no gradient is computed). The user's setting is restored on release().
        prop = volume.GetProperty()
        self._user_shade = [prop.GetShade(c) for c in range(4)]
        self._apply_shade()
        self._start_tag = renderer.AddObserver(vtk.vtkCommand.StartEvent, self._on_start)
        self._error_tag = mapper.AddObserver(vtk.vtkCommand.ErrorEvent, self._on_mapper_error)
        self._capture = _capture_source(self)  # keep a reference: VTK holds it weakly
        self._shader_tag = volume.GetMapper().AddObserver(
            vtk.vtkCommand.UpdateShaderEvent, self._capture
        )
        # Our textures hold texture units only while this volume draws: units are one budget
        # for the whole window (32 on llvmpipe), and eight illuminated volumes holding theirs
        # all frame long left VTK none for its own textures (every volume went black).
        self._draw_tags = (
            mapper.AddObserver(vtk.vtkCommand.VolumeMapperRenderStartEvent, self._on_draw_start),
            mapper.AddObserver(vtk.vtkCommand.VolumeMapperRenderEndEvent, self._on_draw_end),
        )
        _HOSTS[id(volume)] = self

    @classmethod
    def host_of(cls, volume: vtk.vtkVolume) -> Illuminator | None:
        """The illuminator lighting ``volume`` now (None if none, or released)."""
        host = _HOSTS.get(id(volume))
        return host if host is not None and not host.closed and host.volume is volume else None

    def reconfigure(self, method: str, *,
                    lights: Sequence[Light] | Literal["renderer"] | None = None,
                    parameters: Mapping[str, Any] | None = None,
                    multichannel_lighting: str | None = None) -> None:
        """What a second :func:`vtkvol.illuminate` on this volume does: switch to ``method``
        and set the given ``parameters`` (the others keep their values), ``lights`` (and, as
        at the first call, shading for them; ``"renderer"``: follow the renderer's lights
        from now on; None: the lights stay as they are) and ``multichannel_lighting`` (None:
        unchanged)."""
        follow = isinstance(lights, str) and lights == "renderer"
        if lights is not None and not follow:
            self._check_lights(list(lights))
        if multichannel_lighting is not None:
            check_multichannel_lighting(multichannel_lighting)
        cls = technique_class(method)
        cls.SPEC.validate({**self._values.get(cls.NAME, cls.defaults()), **(parameters or {})})
        self.set_method(method, parameters)
        if follow:
            self._follow_renderer, self._capture_renderer = True, False
        elif lights is not None:
            self.set_lights(lights)  # type: ignore[arg-type]
            self._keep_local_shading = False  # lights given: the caller asks them to shade
            self._apply_shade()
        if multichannel_lighting is not None:
            self.set_multichannel_lighting(multichannel_lighting)

    # -- public state ---------------------------------------------------------------------------
    @property
    def method(self) -> str:
        return self._technique_cls.NAME

    @property
    def spec(self) -> TechniqueSpec:
        """The active technique's declaration."""
        return self._technique_cls.SPEC

    @property
    def technique(self) -> Technique | None:
        """The attached technique instance (None until the first frame)."""
        return self._technique

    def set_method(self, method: str, parameters: Mapping[str, Any] | None = None) -> None:
        """Switch technique; its resources are released at the next frame. Choosing a method
        that failed before tries it again."""
        cls = technique_class(method)
        if cls is not self._technique_cls:
            self._detach_requested = True
            self._technique_cls = cls
            self._changes = Changes(first=True, opacity=True, lights=True)
            self._apply_shade()
        if method == self.failed_method:
            self.failed_method = None
        if parameters:
            self.set_parameters(**parameters)
        else:
            self._values.setdefault(cls.NAME, cls.defaults())

    @property
    def parameters(self) -> dict[str, Any]:
        """Current (validated) parameter values of the active technique."""
        return dict(self._values.setdefault(self.method, self._technique_cls.defaults()))

    def set_parameters(self, **values: Any) -> None:
        """Validate and set parameter values of the active technique (``ValueError`` if bad)."""
        spec = self._technique_cls.SPEC
        current = self._values.get(self.method, spec.defaults())
        merged = spec.validate({**current, **values})
        changed = {k for k in merged if merged[k] != current.get(k)}
        self._values[self.method] = merged
        self._changes.parameters |= changed
        self._changes.invalidates |= spec.invalidations(changed)

    @property
    def lights(self) -> list[Light]:
        return list(self._lights)

    def set_lights(self, lights: Sequence[Light]) -> None:
        """Replace the lights (world space). Techniques are told whether the geometry changed
        (``Changes.lights``) or only colours and intensities (``Changes.light_colors``)."""
        lights = list(lights)
        self._check_lights(lights)
        self._lights = lights
        self._follow_renderer = self._capture_renderer = False

    def _check_input(self, *, raise_error: bool) -> bool:
        """Whether the mapper's input can be illuminated (point scalars). Cell data cannot: at
        the call that is a ``ValueError``; found later (the input arrives with the pipeline's
        first update), the illuminator stands aside once with a message."""
        mapper = self.volume.GetMapper()
        if mapper.GetInputAlgorithm() is None and mapper.GetInput() is None:
            return True  # no input yet: checked again at the first frame
        try:
            img = self.image
        except RuntimeError:
            return True
        if img.GetPointData().GetScalars() is not None:
            return True
        what = "cell data" if img.GetCellData().GetScalars() is not None else "no scalars"
        message = (
            f"the volume's image has {what}; vtkvol illumination needs point scalars "
            "(convert with vtkCellDataToPointData, in PyVista grid.cell_data_to_point_data())"
        )
        if raise_error:
            raise ValueError(message)
        self._stand_aside(message)
        return False

    def _stand_aside(self, message: str) -> None:
        """Stop illuminating for good (VTK renders the volume its own way, the user's shading
        flags and shader replacements as they were) and say why, once."""
        if self._unsupported is not None:
            return
        self._unsupported = message
        self._replacements.clear()
        self._expected_markers = None  # nothing of ours is built any more
        prop = self.volume.GetProperty()
        for c, shade in enumerate(self._user_shade):
            prop.SetShade(c, shade)
        logger.error("vtkvol: %s", message)
        if self.on_error is not None:
            self.on_error(message)

    def _take_renderer_lights(self) -> None:
        """At a frame's start: the renderer's lights, every frame when following them, once
        (the first frame, when the camera is set) when they are taken as fixed lights."""
        if self._follow_renderer:
            self._lights = self._renderer_lights()
        elif self._capture_renderer:
            self._lights = self._renderer_lights(fixed=True)
            self._capture_renderer = False

    def _renderer_lights(self, *, fixed: bool = False) -> list[Light]:
        """The renderer's switched-on lights as world-space vtkvol lights (the headlight and
        camera lights, light kits included, placed from the current camera; scene lights
        through their transformed positions).

        ``fixed``: the lights are taken once and stay put in the world. A lone headlight then
        becomes a key light (:func:`key_light_direction`), since shadows cast along the view
        direction fall straight behind what casts them, where the viewer cannot see them.
        """
        lights = self.renderer.GetLights()
        lights.InitTraversal()
        switched_on = [light for light in (lights.GetNextItem()
                                           for _ in range(lights.GetNumberOfItems()))
                       if light is not None and light.GetSwitch()]
        if not switched_on and self.renderer.GetAutomaticLightCreation():
            # Before its first render a renderer has no lights yet: it is about to make its
            # headlight (white, intensity 1), so take that one.
            headlight = vtk.vtkLight()
            headlight.SetLightTypeToHeadlight()
            switched_on = [headlight]
        camera = self.renderer.GetActiveCamera()
        out: list[Light] = []
        for light in switched_on[:MAX_LIGHTS]:
            color = tuple(float(min(max(c, 0.0), 1.0)) for c in light.GetDiffuseColor())
            intensity = float(min(max(light.GetIntensity(), 0.0), 100.0))
            if fixed and len(switched_on) == 1 and light.LightTypeIsHeadlight():
                out.append(Light(direction=key_light_direction(camera), color=color,
                                 intensity=intensity))
                continue
            position, focal = _light_world_geometry(light, camera)
            if light.GetPositional():
                out.append(Light(kind="point", position=tuple(position), color=color,
                                 intensity=intensity))
            elif np.linalg.norm(position - focal) > 0:
                out.append(Light(direction=tuple(position - focal), color=color,
                                 intensity=intensity))
        return out or [Light()]

    @staticmethod
    def _check_lights(lights: Sequence[Light]) -> None:
        if len(lights) > MAX_LIGHTS:
            raise ValueError(f"at most {MAX_LIGHTS} lights are supported, not {len(lights)}")

    @property
    def albedo(self) -> float:
        """Single-scattering albedo of the ``medium`` model (0…1)."""
        return self._albedo

    @property
    def phase_g(self) -> float:
        """Henyey–Greenstein asymmetry of the ``medium`` model (0 = isotropic)."""
        return self._phase_g

    def set_material(self, *, albedo: float | None = None, phase_g: float | None = None) -> None:
        """Scattering material of the ``medium`` lighting model: single-scattering ``albedo``
        (0…1) and the Henyey–Greenstein asymmetry ``phase_g`` (−0.99…0.99; 0 = isotropic)."""
        if albedo is not None:
            if not (math.isfinite(albedo) and 0.0 <= albedo <= 1.0):
                raise ValueError(f"albedo must lie in 0…1, not {albedo!r}")
            if albedo != self._albedo:
                self._albedo = float(albedo)
                self._changes.invalidates |= Invalidates.ACCUMULATION
        if phase_g is not None:
            if not (math.isfinite(phase_g) and -0.99 <= phase_g <= 0.99):
                raise ValueError(f"phase_g must lie in −0.99…0.99, not {phase_g!r}")
            if phase_g != self._phase_g:
                self._phase_g = float(phase_g)
                self._changes.invalidates |= Invalidates.ACCUMULATION

    @property
    def exposure(self) -> float:
        """The factor on the shaded colour (1 = as lit)."""
        return self._exposure

    @property
    def fill(self) -> float:
        """Strength of the unshadowed sky fill (0…1; 0 = none)."""
        return self._fill

    def set_exposure(self, exposure: float | None = None, fill: float | None = None) -> None:
        """The shaded colour's ``exposure`` factor (> 0) and the sky ``fill`` strength (0…1):
        per-frame uniforms, nothing is recomputed (they apply to frames held still too)."""
        if exposure is not None:
            if not (math.isfinite(exposure) and exposure > 0.0):
                raise ValueError(f"exposure must be a finite number > 0, not {exposure!r}")
            self._exposure = float(exposure)
        if fill is not None:
            if not (math.isfinite(fill) and 0.0 <= fill <= 1.0):
                raise ValueError(f"fill must lie in 0…1, not {fill!r}")
            self._fill = float(fill)
        self._upload_exposure()

    def _upload_exposure(self) -> None:
        fu = self.shader_property.GetFragmentCustomUniforms()
        fu.SetUniformf("vv_exposure", 1.0 if self._probe else self._exposure)
        fu.SetUniformf("vv_fill", self._fill)
        fu.SetUniformi("vv_exposureProbe", int(self._probe))

    @contextlib.contextmanager
    def holding_still(self) -> Iterator[None]:
        """Frames rendered inside keep what is installed: nothing is prepared, recomputed or
        refined (as between two chunks of :meth:`precompute`); per-frame uniforms set
        meanwhile (exposure, fill) still apply."""
        held, self._held = self._held, True
        try:
            yield
        finally:
            self._held = held

    @contextlib.contextmanager
    def lit_as_local(self) -> Iterator[None]:
        """Frames rendered inside are held still (:meth:`holding_still`) and lit as local
        shading: every light unobstructed, no ambient occlusion, no in-scattering, exposure 1.
        The automatic exposure's reference frame (:mod:`vtkvol.engine.exposure`)."""
        with self.holding_still():
            self._probe = True
            self._upload_exposure()
            try:
                yield
            finally:
                self._probe = False
                self._upload_exposure()

    @property
    def interpolation(self) -> str:
        """Scalar reconstruction of the ray's samples: ``"trilinear"`` (the GPU's) or
        ``"corrected"`` (Csébfalvi's corrected trilinear, docs/reconstruction.md)."""
        return self._interpolation

    def set_interpolation(self, interpolation: str) -> None:
        """Choose the scalar reconstruction filter (``"trilinear"`` or ``"corrected"``).

        ``corrected`` applies to composite blending of one component or independent
        components (elsewhere VTK's trilinear sample is kept). Precomputed illumination is
        unaffected: it is evaluated at voxel centres, where both filters return the samples."""
        if interpolation not in ("trilinear", "corrected"):
            raise ValueError(
                f"interpolation must be 'trilinear' or 'corrected', not {interpolation!r}"
            )
        self._interpolation = interpolation

    @property
    def multichannel_lighting(self) -> str:
        """How two to four independent channels are lit (RenderSettings.multichannel_lighting):
        ``"per_channel"`` (VTK's: every channel lit with its own normal and material) or
        ``"shared"`` (the channels classified unlit, mixed, and lit once per sample with the
        opacity-weighted normal and material; host_multichannel_lighting.glsl)."""
        return self._multichannel_lighting

    def set_multichannel_lighting(self, mode: str) -> None:
        """Choose ``"per_channel"`` or ``"shared"`` multi-channel lighting. ``shared`` applies
        to two to four independent components on a composite blend where the sample is lit
        (shaded surface lighting without gradient opacity, volumetric scattering or a 2-D
        transfer function; or a ``medium`` technique); elsewhere, one channel included, the
        image is unchanged (:attr:`multichannel_lighting_state` says what the last build did)."""
        check_multichannel_lighting(mode)
        self._multichannel_lighting = mode

    @property
    def multichannel_lighting_state(self) -> str:
        """What the last shader build did: ``"shared"``, ``"per_channel"``, or
        ``"per_channel (<why shared does not apply>)"`` when ``shared`` was asked for."""
        return self._mc_lighting_state

    @property
    def empty_space_skipping(self) -> bool:
        """Whether rays jump over bricks in which no sample can be visible
        (docs/empty-space-skipping.md). Exact: the image does not change."""
        return self._skip_empty

    def set_empty_space_skipping(self, enabled: bool) -> None:
        """Switch empty-space skipping on or off (on by default). It applies to composite
        and additive blending, and to maximum-intensity projection with non-decreasing opacity
        functions and no slice weights; elsewhere rays march the whole box
        (:meth:`empty_space_stats` says why)."""
        self._skip_empty = bool(enabled)

    def empty_space_stats(self) -> dict[str, Any]:
        """The last frame's occupancy: ``active`` (bool), ``reason`` (why not, or ""),
        ``bricks`` (x, y, z), ``brick_voxels`` (x, y, z), ``empty_fraction`` (0…1) and
        ``ranges_ms`` / ``occupancy_ms`` (wall time of the per-data min/max pass and of the
        per-edit lookup)."""
        return dict(self._ess_stats)

    @property
    def slice_weights(self) -> np.ndarray | None:
        """The (3, W) slice weights set by :meth:`set_slice_weights` (None: none)."""
        return self._weights

    def set_slice_weights(self, weights: np.ndarray | None) -> None:
        """Per-axis slice-contribution weights, shape (3, W) for x, y, z over 0…1 (or None)."""
        if weights is not None:
            weights = np.asarray(weights, np.float32)
            if weights.ndim != 2 or weights.shape[0] != 3:
                raise ValueError(f"slice weights must have shape (3, W), not {weights.shape}")
            if not np.isfinite(weights).all() or weights.min() < 0 or weights.max() > 1:
                raise ValueError("slice weights must be finite and lie in 0…1")
            if np.all(weights == 1.0):
                weights = None
        if (weights is None) != (self._weights is None) or (
            weights is not None and not np.array_equal(weights, self._weights)
        ):
            self._weights = weights
            self._weights_version += 1

    def invalidate(self) -> None:
        """Force a recompute of precomputed light at the next frame (rarely needed: changes to
        the input image, opacity functions, cropping and volume matrix are detected)."""
        self._changes.opacity = True

    @property
    def closed(self) -> bool:
        """True once :meth:`release` has run (the volume has VTK's own shading again)."""
        return self._closed

    # -- precomputation outside a frame -----------------------------------------------------------
    @property
    def precomputing(self) -> bool:
        """True while :meth:`precompute` runs (between its chunks, too)."""
        return self._stepping

    def precompute(self, progress: Callable[[float], bool] | None = None) -> bool:
        """Bring the technique's precomputed light up to date now, outside a frame, in the
        chunks its :meth:`~vtkvol.engine.technique.Technique.prepare_steps` yields.

        After every chunk ``progress(fraction)`` is called (fraction done, 0…1); it may run an
        event loop (the context is made current again before the next chunk) and returns
        False to cancel. A cancelled precomputation leaves a consistent state: the technique
        is released, local shading is shown, :attr:`cancelled_method` names the method and
        False is returned. Returns True otherwise, also when there was nothing to do: no
        frame yet (the first frame precomputes), :attr:`defer_precompute` set, a progressive
        technique (it refines over frames) or nothing changed. The next frame then only
        installs the shader and uploads uniforms. Frames rendered between two chunks (an
        application's repaint) leave the technique alone and show the previous light.

        Scripts need not call this: every frame brings the light up to date by itself.
        """
        if (self._closed or self._stepping or self._unsupported is not None
                or self.render_window is None or self.spec.has("progressive")):
            return True
        if self.defer_precompute and self._technique is not None and not self._detach_requested:
            return True
        window = self.render_window
        with _no_collection():
            window.MakeCurrent()
            self._take_renderer_lights()
            self._frame_specs = self._compute_light_specs()
            try:
                self._ensure_technique()
                if not self._needs_prepare(self._changes):
                    return True
                self._upload_weights()
                changes, self._changes = self._changes, Changes()
                steps = self._technique.prepare_steps(changes, self.parameters)
            finally:
                self._frame_specs = None
        return self._run_steps(steps, progress)

    @property
    def has_pending_changes(self) -> bool:
        """Whether changes wait for a prepare (deferred ones included) that may recompute."""
        return self._needs_prepare(self._changes) or (
            self._signature is not None and self._opacity_signature() != self._signature)

    def _ensure_technique(self) -> None:
        """Release a technique whose detach was asked for, take in what changed since the last
        frame, and create the method's technique when there is none (its first preparation)."""
        if self._detach_requested and self._technique is not None:
            self._release_technique()
        self._detach_requested = False
        self._detect_changes()
        if self._technique is None:
            self._technique = self._technique_cls(self)
            self._changes.first = True

    def _needs_prepare(self, changes: Changes) -> bool:
        """Whether ``changes`` may make a (non-progressive) technique recompute."""
        return bool(changes.first or changes.opacity or changes.lights or changes.parameters
                    or changes.view or changes.invalidates)

    def _run_steps(self, steps: Iterator[float], progress: Callable[[float], bool] | None) -> bool:
        window = self.render_window
        assert window is not None
        work_s = 0.0  # the chunks' time, without the event loop's in between
        self._stepping = True
        try:
            while True:
                with _no_collection():
                    window.MakeCurrent()
                    t0 = time.perf_counter()
                    self._frame_specs = self._compute_light_specs()
                    try:
                        fraction = next(steps)
                    except StopIteration:
                        break
                    finally:
                        self._frame_specs = None
                        work_s += time.perf_counter() - t0
                    if self._technique is not None:
                        self._on_draw_end()  # units go back between chunks
                if progress is not None and not progress(min(max(float(fraction), 0.0), 1.0)):
                    steps.close()
                    self._cancel_precompute()
                    return False
                if self._closed:  # released while the progress callback ran an event loop
                    steps.close()
                    return False
        except Exception as exc:  # a technique's GL or numpy failure must not kill the view
            logger.exception("illumination %s failed to precompute", self.method)
            with _no_collection():
                window.MakeCurrent()
                self._fail(f"failed ({type(exc).__name__}: {exc})")
                self._release_technique()
                self._detach_requested = False
        finally:
            self._stepping = False
            self._precomputed_ms += work_s * 1e3  # reported with the next frame
        self.cancelled_method = None
        return True

    def _cancel_precompute(self) -> None:
        """Local shading, with nothing of the cancelled technique left bound."""
        if self._closed:
            return
        cancelled = self.method
        window = self.render_window
        with _no_collection():
            if window is not None:
                window.MakeCurrent()
            self._release_technique()
            self._detach_requested = False
            self.set_method("local")
        self.cancelled_method = cancelled
        logger.info("illumination %s: precomputation cancelled; local shading", cancelled)

    # -- progressive techniques -----------------------------------------------------------------
    @property
    def wants_frame(self) -> bool:
        """True while a progressive technique has not converged (render again to refine)."""
        if self._closed or self.failed_method == self.method:
            return False
        if self.beside is not None:  # a progressive renderer beside the ray caster
            return not self.beside.converged
        tech = self._technique
        if tech is None or self._detach_requested:
            return self.spec.has("progressive")
        return not tech.converged

    def converge(self, max_frames: int | None = None, max_seconds: float | None = None, *,
                 iterations: int | None = None) -> int:
        """Render until the technique has converged, has reached ``iterations`` of its own
        iterations, ``max_frames`` frames have been rendered or ``max_seconds`` have passed
        (batch rendering, scripts). Returns the number of frames rendered. Non-progressive
        techniques need one frame."""
        window = self.renderer.GetRenderWindow()
        if window is None:
            raise RuntimeError("the renderer is not in a render window")
        t0 = time.perf_counter()
        frames = 0
        while True:
            window.Render()
            frames += 1
            if not self.wants_frame:
                break
            tech = self.beside if self.beside is not None else self._technique
            if iterations is not None and tech is not None and tech.iteration >= iterations:
                break
            if max_frames is not None and frames >= max_frames:
                break
            if max_seconds is not None and time.perf_counter() - t0 >= max_seconds:
                break
        return frames

    # -- what techniques read -------------------------------------------------------------------
    @property
    def image(self) -> vtk.vtkImageData:
        mapper = self.volume.GetMapper()
        mapper.Update() if mapper.GetInputAlgorithm() is not None else None
        img = mapper.GetInput()
        if img is None:
            raise RuntimeError("the volume's mapper has no input image")
        return img

    @property
    def dims(self) -> tuple[int, int, int]:
        """(nx, ny, nz) voxels."""
        return tuple(int(d) for d in self.image.GetDimensions())  # type: ignore[return-value]

    @property
    def spacing(self) -> tuple[float, float, float]:
        """(sx, sy, sz) µm (dataset space)."""
        return tuple(float(s) for s in self.image.GetSpacing())  # type: ignore[return-value]

    @property
    def unit_distance(self) -> float:
        """Opacity unit distance (µm) of component 0: TF opacity is per this thickness."""
        return float(self.volume.GetProperty().GetScalarOpacityUnitDistance(0))

    def light_specs(self) -> list[LightSpec]:
        """Enabled lights converted to dataset space (through the volume's inverse matrix).

        Computed once per frame (the host and the technique both ask); outside a frame, anew."""
        if self._frame_specs is not None:
            return list(self._frame_specs)
        return self._compute_light_specs()

    def _compute_light_specs(self) -> list[LightSpec]:
        inv = vtk.vtkMatrix4x4()
        vtk.vtkMatrix4x4.Invert(self.volume.GetMatrix(), inv)
        linear = np.array([[inv.GetElement(i, j) for j in range(3)] for i in range(3)])
        length_scale = abs(np.linalg.det(linear)) ** (1.0 / 3.0)  # µm world → µm dataset
        bounds = self.image.GetBounds()
        center = np.array([(bounds[2 * a] + bounds[2 * a + 1]) / 2 for a in range(3)])
        specs = []
        for light in self._lights:
            if not light.enabled or light.intensity <= 0:
                continue
            color = tuple(float(c * light.intensity) for c in light.color)
            if light.kind == "point":
                p = inv.MultiplyPoint((*light.position, 1.0))
                pos = np.array(p[:3]) / p[3]
                falloff = (
                    float(np.linalg.norm(pos - center)) if light.falloff == "inverse_square"
                    else 0.0
                )
                specs.append(LightSpec("point", tuple(float(v) for v in pos), color,
                                       size=light.size * length_scale,
                                       falloff_distance=falloff))
            else:
                d = np.array(inv.MultiplyPoint((*light.direction, 0.0))[:3])
                d = d / max(np.linalg.norm(d), 1e-30)
                specs.append(LightSpec("directional", tuple(float(v) for v in d), color,
                                       size=math.radians(light.angular_radius_deg())))
        return specs

    def opacity_volume(self) -> np.ndarray:
        """Per-voxel opacity (per ``unit_distance`` µm) as the ray caster sees it.

        float32 ``[z, y, x]``: every visible component classified as VTK's shader does and
        combined as independent absorbers (α = 1 − Π(1 − α_c)), then zeroed outside the
        cropping box and multiplied by the slice weights, so what is cropped away casts no
        shadow. Classification (docs/transfer-functions-2d.md): in 1-D mode the scalar
        opacity function times the gradient-opacity function, if one is set; in 2-D mode the
        component's (value, gradient magnitude) table, looked up bilinearly at VTK's
        coordinates. Gradients are VTK's central differences at the voxel centres. Cached
        until an input changes.
        """
        return run_steps(self.opacity_volume_steps())

    def opacity_volume_steps(self) -> Generator[float, None, np.ndarray]:
        """:meth:`opacity_volume` in slabs of z slices (for ``prepare_steps``): yields the
        fraction done after each slab of about :data:`OPACITY_SLAB_VOXELS` voxels and returns
        the volume (``opacity = yield from host.opacity_volume_steps()``). A cached volume
        returns at once."""
        key = self._opacity_signature()
        if self._opacity_cache is not None and self._opacity_cache[0] == key:
            return self._opacity_cache[1]
        img = self.image
        nx, ny, nz = img.GetDimensions()
        scalars = img.GetPointData().GetScalars()
        if scalars is None:
            raise RuntimeError("the volume's input image has no point scalars")
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1)
        prop = self.volume.GetProperty()
        ncomp = values.shape[-1]
        independent = ncomp == 1 or bool(prop.GetIndependentComponents())
        two_d = prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D
        if two_d and not independent:
            raise ValueError(
                "2-D transfer functions need independent components: VTK classifies "
                f"dependent {ncomp}-component data (RGB/RGBA colour) without a 2-D table")
        spacing = self.spacing
        step = float(self.volume.GetMapper().GetSampleDistance())
        u0 = prop.GetScalarOpacityUnitDistance(0)
        comps = range(ncomp) if independent else [ncomp - 1]
        # What classifies each component, over the whole volume: gradients need the
        # neighbouring slices, which a slab does not hold.
        tables: dict[int, np.ndarray] = {}
        coords: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        gradients: dict[int, np.ndarray] = {}  # |g| in data units, for gradient opacity
        for c in comps:
            fc = c if independent else 0
            value_range = scalars.GetRange(c)
            if two_d and prop.GetTransferFunction2D(fc) is not None:
                tables[c] = tf2d.unit_alpha_table(prop.GetTransferFunction2D(fc), step,
                                                  prop.GetScalarOpacityUnitDistance(fc))
                coords[c] = self._table_coords(c, values[..., c], spacing, value_range)
            elif _gradient_opacity_on(prop, fc):
                # VTK's table spans |g| in 0…¼·range and |g| is clamped to it.
                span = float(value_range[1] - value_range[0]) or 1.0
                gradients[c] = tf2d.normalised_gradient(values[..., c], spacing, value_range) * (
                    np.float32(tf2d.GRADIENT_RANGE_FRACTION * span))
        weights = _axis_weight_vectors(self._weights, (nz, ny, nx)) if (
            self._weights is not None) else None
        opacity = np.empty((nz, ny, nx), np.float32)
        slab = max(1, OPACITY_SLAB_VOXELS // max(1, nx * ny))
        for z0 in range(0, nz, slab):
            z1 = min(nz, z0 + slab)
            transparency = np.ones((z1 - z0, ny, nx), np.float32)
            for c in comps:
                fc = c if independent else 0
                weight = prop.GetComponentWeight(fc) if independent and ncomp > 1 else 1.0
                if weight <= 0:
                    continue
                if c in tables:
                    s, t = coords[c]
                    alpha = tf2d.lookup(tables[c], s[z0:z1], t[z0:z1])
                else:
                    alpha = _evaluate_piecewise(prop.GetScalarOpacity(fc), values[z0:z1, ..., c])
                    if c in gradients:
                        alpha = alpha * _evaluate_piecewise(prop.GetGradientOpacity(fc),
                                                            gradients[c][z0:z1])
                alpha = alpha * weight
                uc = prop.GetScalarOpacityUnitDistance(fc)
                if uc != u0:  # express every component per the same unit distance
                    alpha = 1.0 - np.power(1.0 - np.clip(alpha, 0, 1), u0 / uc)
                transparency *= 1.0 - np.clip(alpha, 0.0, 1.0)
            part = opacity[z0:z1]
            np.subtract(1.0, transparency, out=part)
            self._apply_crop(part, z0)
            if weights is not None:
                wx, wy, wz = weights
                part *= wz[z0:z1, None, None] * wy[None, :, None] * wx[None, None, :]
            yield z1 / nz
        self._opacity_cache = (key, opacity)
        return opacity

    # -- classification on the GPU --------------------------------------------------------------
    @property
    def classification(self) -> str:
        """Backend of :meth:`opacity_texture`: ``"auto"`` (the compute shader where the
        context runs compute shaders and the volume allows it, else numpy with one logged
        warning), ``"gpu"`` (the compute shader or an error) or ``"cpu"`` (numpy, uploaded).
        An engine choice, not a session setting; :meth:`opacity_volume` is always numpy."""
        return self._classification

    @classification.setter
    def classification(self, backend: str) -> None:
        if backend not in ("auto", "gpu", "cpu"):
            raise ValueError(f"classification must be 'auto', 'gpu' or 'cpu', not {backend!r}")
        if backend != self._classification:
            self._classification = backend
            self._opacity_texture_key = None  # the next request classifies anew
            self._changes.opacity = True  # and the technique recomputes from it

    def classification_stats(self) -> dict[str, Any]:
        """The opacity texture's classification: ``backend`` of the last one ("gpu"/"cpu"),
        ``reason`` (why not on the GPU, or ""), counters ``gpu_classifications``,
        ``cpu_classifications``, ``scalar_uploads`` (data sets uploaded for the shader),
        ``opacity_uploads`` (numpy volumes uploaded), ``classify_ms`` (wall time of the last
        classification, issuing only unless chunked), ``scalar_upload_ms`` and
        ``scalar_bytes`` (GPU memory of the scalar copy)."""
        return dict(self._classify_stats)

    def opacity_texture(self, quantity: str = "alpha") -> Texture3D:
        """:meth:`opacity_volume` as a host-owned r32f 3-D texture of the data's shape (voxel
        centres at texel centres; context current), classified on the GPU
        (:attr:`classification`). ``quantity``: ``"alpha"`` (the opacity per unit distance)
        or ``"optical_depth"``, s = −ln(1 − α) with α clamped at 1 − 10⁻⁶ (the extinction
        grid of the shadow volume, converted in the same pass). Cached until an input or
        the quantity changes; valid until the next call, the technique's release or
        :meth:`release`. Techniques read it, never release it."""
        return run_steps(self.opacity_texture_steps(quantity))

    def opacity_texture_steps(self, quantity: str = "alpha"
                              ) -> Generator[float, None, Texture3D]:
        """:meth:`opacity_texture` in chunks (for ``prepare_steps``; each chunk waited for
        while :attr:`precomputing`): ``tex = yield from host.opacity_texture_steps()``."""
        if quantity not in classify.QUANTITIES:
            raise ValueError(f"quantity must be one of {classify.QUANTITIES}, not {quantity!r}")
        key = (self._opacity_signature(), self._classification, quantity)
        tex = self._opacity_texture
        if tex is not None and tex.tex is not None and key == self._opacity_texture_key:
            return tex
        window = self.render_window
        if window is None:
            raise RuntimeError("the opacity texture needs a rendered frame (a GL context)")
        nx, ny, nz = self.dims
        if tex is None or tex.tex is None or tex.shape != (nz, ny, nx):
            if tex is not None:
                tex.release()
            self._opacity_texture = tex = None
            self._opacity_texture_key = None
            tex = Texture3D(window, (nz, ny, nx))
            self._opacity_texture = tex
        chunked = self._stepping
        stats = self._classify_stats
        t0 = time.perf_counter()
        classifier = self._gpu_classifier()
        if classifier is not None:
            uploads = classifier.scalar_uploads
            try:
                plan = self._classification_plan(quantity)
                yield from classifier.run_steps(plan, self.image, tex, chunked=chunked)
            except GLUnavailableError as exc:
                if self._classification == "gpu":
                    raise
                self._disable_gpu_classification(str(exc).splitlines()[0])
                classifier = None
            else:
                stats.update(backend="gpu", reason="",
                             gpu_classifications=stats["gpu_classifications"] + 1,
                             scalar_uploads=stats["scalar_uploads"]
                             + classifier.scalar_uploads - uploads,
                             scalar_upload_ms=classifier.upload_ms,
                             scalar_bytes=classifier.scalar_bytes)
        if classifier is None:
            opacity = yield from self.opacity_volume_steps()
            if quantity == "optical_depth":
                opacity = classify.optical_depth(opacity)
            if chunked:
                slab = max(1, OPACITY_SLAB_VOXELS // max(1, nx * ny))
                for z0 in range(0, nz, slab):
                    tex.upload_slab(opacity[z0:z0 + slab], z0)
                    gl(window).glFinish()
                    yield min(1.0, (z0 + slab) / nz)
            else:
                tex.upload(opacity)
            tex.tex.Deactivate()
            stats.update(backend="cpu", cpu_classifications=stats["cpu_classifications"] + 1,
                         opacity_uploads=stats["opacity_uploads"] + 1)
        stats["classify_ms"] = (time.perf_counter() - t0) * 1e3
        self._opacity_texture_key = key
        return tex

    def _release_classification(self) -> None:
        """Free the opacity texture and the classifier's scalars, tables and programs (with the
        technique that used them: local shading holds no data-sized GPU memory of ours)."""
        if self._opacity_texture is not None:
            self._opacity_texture.release()
            self._opacity_texture = None
        self._opacity_texture_key = None
        if self._classifier is not None:
            self._classifier.release()
            self._classifier = None

    def _gpu_classifier(self) -> classify.GpuClassifier | None:
        """The GPU classifier when :attr:`classification` and this volume allow it (else None,
        with the reason in the stats: one warning per reason)."""
        stats = self._classify_stats
        if self._classification == "cpu":
            stats["reason"] = "classification = 'cpu'"
            return None
        reason = self._classify_failed or classify.unsupported_reason(self.volume, self.image)
        if reason:
            return self._numpy_classification(reason)
        if self._classifier is None:
            window = self.render_window
            assert window is not None
            if not compute_supported(window):
                self._disable_gpu_classification("this OpenGL context has no compute shaders")
                return self._gpu_classifier()
            self._classifier = classify.GpuClassifier(window)
        too_large = self._classifier.unsupported(self.image)
        if too_large:
            return self._numpy_classification(too_large)
        return self._classifier

    def _numpy_classification(self, reason: str) -> None:
        """The GPU cannot classify this volume for ``reason``: an error when
        :attr:`classification` is ``"gpu"``, else numpy classifies (one warning per reason)."""
        if self._classification == "gpu":
            raise GLUnavailableError(f"GPU classification is not possible: {reason}")
        if self._classify_stats["reason"] != reason:
            logger.warning("vtkvol: classification on the CPU (numpy): %s", reason)
        self._classify_stats["reason"] = reason

    def _disable_gpu_classification(self, why: str) -> None:
        self._classify_failed = why
        if self._classifier is not None:
            self._classifier.release()
            self._classifier = None
        logger.warning("vtkvol: GPU classification unavailable, classifying with numpy (%s)",
                       why)
        self._classify_stats["reason"] = why

    def _classification_plan(self, quantity: str = "alpha") -> classify.Plan:
        """Tables and per-axis rows of the current transfer functions, crop and weights."""
        mapper = self.volume.GetMapper()
        img = self.image
        nx, ny, nz = img.GetDimensions()
        weights = _axis_weight_vectors(self._weights, (nz, ny, nx)) if (
            self._weights is not None) else None
        regions = None
        flags = 0
        if mapper.GetCropping():
            regions = tuple(self._crop_regions(axis, n, 0)
                            for axis, n in enumerate((nx, ny, nz)))
            flags = int(mapper.GetCroppingRegionFlags())
        return classify.build_plan(self.volume, img, weights, regions, flags,
                                   self._clip_coefficients(), quantity)

    def _crop_regions(self, axis: int, n: int, first: int) -> np.ndarray:
        """Cropping region (0 below the first plane, 1 between, 2 above) of the voxel indices
        ``first…first + n`` along ``axis``."""
        img = self.image
        origin, spacing = img.GetOrigin(), img.GetSpacing()
        planes = self.volume.GetMapper().GetCroppingRegionPlanes()
        coord = origin[axis] + spacing[axis] * np.arange(first, first + n)
        lo, hi = planes[2 * axis], planes[2 * axis + 1]
        tol = 1e-6 * spacing[axis]
        return (coord >= lo - tol).astype(np.int64) + (coord > hi + tol).astype(np.int64)

    def _clip_coefficients(self) -> list[tuple[float, float, float, float]]:
        """Each clipping plane's side as ``a·i + b·j + c·k + d`` of the voxel index (i, j, k)
        (world space through the volume's matrix; VTK keeps side ≥ 0), in float64."""
        clipping = self.volume.GetMapper().GetClippingPlanes()
        if clipping is None or not clipping.GetNumberOfItems():
            return []
        img = self.image
        origin, spacing = np.array(img.GetOrigin()), np.array(img.GetSpacing())
        matrix = self.volume.GetMatrix()
        m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
        out = []
        for k in range(clipping.GetNumberOfItems()):
            plane = clipping.GetItem(k)
            o, n = np.array(plane.GetOrigin()), np.array(plane.GetNormal())
            per_index = (n @ m[:3, :3]) * spacing
            const = float(n @ (m[:3, :3] @ origin + m[:3, 3] - o))
            out.append((*(float(v) for v in per_index), const))
        return out

    def classify_2d(self, c: int, what: Literal["alpha", "rgb"] = "alpha") -> np.ndarray | None:
        """Component ``c``'s 2-D table read at every voxel as VTK's shader reads it (its
        gradient, its texture coordinates, bilinear): ``"alpha"`` per ``unit_distance`` of the
        component, float32 ``[z, y, x]``, or ``"rgb"`` in 0…1, ``[z, y, x, 3]``. ``None`` when
        the property is not in 2-D mode or holds no table for ``c``. The opacity volume (slab by
        slab) and every technique that needs the colour (translucency's tint) read the tables
        at the same cached coordinates (``_table_coords``), so they agree voxel for voxel
        (docs/transfer-functions-2d.md)."""
        prop = self.volume.GetProperty()
        image = prop.GetTransferFunction2D(c)
        if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_2D or image is None:
            return None
        img = self.image
        nx, ny, nz = img.GetDimensions()
        scalars = img.GetPointData().GetScalars()
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1)[..., c]
        if what == "rgb":
            table = tf2d.rgb_table(image)
        else:
            step = float(self.volume.GetMapper().GetSampleDistance())
            table = tf2d.unit_alpha_table(image, step, prop.GetScalarOpacityUnitDistance(c))
        return self._lookup_2d(table, c, values, scalars.GetRange(c))

    def _lookup_2d(self, table: np.ndarray, c: int, values: np.ndarray,
                   value_range: tuple[float, float]) -> np.ndarray:
        """``table`` ``(h, w[, k])`` read bilinearly at component ``c``'s VTK coordinates."""
        return tf2d.lookup(table, *self._table_coords(c, values, self.spacing, value_range))

    def _table_coords(self, c: int, values: np.ndarray, spacing: tuple[float, float, float],
                      value_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """VTK's 2-D table coordinates (s, t) of component ``c``'s voxels, cached per data."""
        key = (self.image.GetMTime(), values.shape, spacing, tuple(value_range))
        cached = self._coords_cache.get(c)
        if cached is None or cached[0] != key:
            coords = (tf2d.normalised_values(values, value_range),
                      tf2d.normalised_gradient(values, spacing, value_range))
            if values.size > _COORDS_CACHE_VOXELS:
                return coords  # 8 bytes a voxel: large volumes recompute instead
            self._coords_cache[c] = cached = (key, coords)
        return cached[1]

    def _apply_crop(self, opacity: np.ndarray, z0: int = 0) -> None:
        """Zero what the mapper does not show: its cropping regions (any of VTK's 27-region
        flags, not only the sub-volume) and its clipping planes. ``opacity`` holds the z
        slices from ``z0`` on."""
        mapper = self.volume.GetMapper()
        img = self.image
        origin, spacing = img.GetOrigin(), img.GetSpacing()
        nz, ny, nx = opacity.shape
        if mapper.GetCropping():
            flags = int(mapper.GetCroppingRegionFlags())
            region = [self._crop_regions(axis, n, z0 if axis == 2 else 0)
                      for axis, n in enumerate((nx, ny, nz))]
            index = (region[0][None, None, :] + 3 * region[1][None, :, None]
                     + 9 * region[2][:, None, None])
            visible = np.array([(flags >> i) & 1 for i in range(27)], bool)
            opacity[~visible[index]] = 0.0
        clipping = mapper.GetClippingPlanes()
        if clipping is not None and clipping.GetNumberOfItems():
            # Clipping planes are in world space; VTK keeps the side the normal points to.
            matrix = self.volume.GetMatrix()
            m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
            x = origin[0] + spacing[0] * np.arange(nx)
            y = origin[1] + spacing[1] * np.arange(ny)
            z = origin[2] + spacing[2] * np.arange(z0, z0 + nz)
            world = [m[i, 0] * x[None, None, :] + m[i, 1] * y[None, :, None]
                     + m[i, 2] * z[:, None, None] + m[i, 3] for i in range(3)]
            for k in range(clipping.GetNumberOfItems()):
                plane = clipping.GetItem(k)
                o, n = plane.GetOrigin(), plane.GetNormal()
                side = sum((world[i] - o[i]) * n[i] for i in range(3))
                opacity[np.broadcast_to(side < 0, opacity.shape)] = 0.0

    # -- GL helpers for techniques --------------------------------------------------------------
    def bind_texture(self, uniform: str, texture: Any, sampler: str = "sampler3D") -> None:
        """Make ``texture`` (``Texture3D``/``Texture2D``) visible to GLSL as ``uniform``.

        The texture stays active so VTK's unit manager never reuses its unit; VTK declares an
        ``int`` custom uniform holding the unit, which a post replacement retypes to a sampler
        (docs/architecture.md, "Engine"). The binding belongs to the host: it is removed
        when the technique is switched or released.
        """
        unit = texture.activate()
        self.shader_property.GetFragmentCustomUniforms().SetUniformi(uniform, unit)
        self._textures[uniform] = (texture, sampler)

    def bound_textures(self) -> dict[str, Any]:
        """The textures bound for the active technique, by GLSL uniform name (what its shader
        reads; diagnostics and the benchmark's checks). The host's own are left out."""
        return {name: texture for name, (texture, _sampler) in self._textures.items()
                if name not in _HOST_TEXTURES}

    def unbind_texture(self, uniform: str) -> None:
        entry = self._textures.pop(uniform, None)
        if entry is not None:
            self.shader_property.GetFragmentCustomUniforms().RemoveUniform(uniform)

    @property
    def shaded(self) -> bool:
        """True when VTK generates its shaded ``computeLighting()`` (where the ``surface``
        lighting hooks in): shading on for a used component and a composite or isosurface
        blend. MIP, MinIP, average and additive blends, and unshaded composite, show no
        surface illumination."""
        prop = self.volume.GetProperty()
        scalars = self.image.GetPointData().GetScalars()
        ncomp = scalars.GetNumberOfComponents() if scalars is not None else 1
        # VTK generates the shaded code when any *used* component is shaded (component 0 for
        # dependent components).
        used = range(ncomp) if prop.GetIndependentComponents() else range(1)
        return self._compositing() and any(prop.GetShade(c) for c in used)

    def _compositing(self) -> bool:
        blend = self.volume.GetMapper().GetBlendMode()
        return blend in (vtk.vtkVolumeMapper.COMPOSITE_BLEND, vtk.vtkVolumeMapper.ISOSURFACE_BLEND)

    def _apply_shade(self) -> None:
        # surface: VTK's shaded variant computes the gradient we shade with; medium: the
        # unshaded variant skips it (the medium model uses no gradient).
        prop = self.volume.GetProperty()
        shade = 1 if self.spec.lighting == "surface" else 0
        keep = self._keep_local_shading and self.method == "local"
        for c in range(4):
            prop.SetShade(c, self._user_shade[c] if keep else shade)

    @property
    def fragment_source(self) -> str:
        """The last fragment shader VTK built with our replacements (for tests/diagnostics)."""
        return self._fragment_source

    # -- failures -------------------------------------------------------------------------------
    def _fail(self, why: str) -> None:
        """Switch to local shading, remember the failed method and tell the user once."""
        if self.method == "local":
            logger.error("local shading failed: %s", why)
            return
        failed, label = self.method, self._technique_cls.LABEL
        self.last_error = f"The {label!r} illumination {why}; showing local shading instead."
        self.set_method("local")
        self.failed_method = failed
        logger.error("illumination %s failed (%s); fell back to local shading", failed, why)
        if self.on_error is not None:
            self.on_error(self.last_error)

    def _on_mapper_error(self, _mapper: Any, _event: str, *_args: Any) -> None:
        # The mapper reports "Shader failed to compile" (the GLSL log goes to VTK's output
        # window). A technique whose shader does not build on this GPU/driver must not leave
        # the view black: fall back to local shading at the next frame.
        self._fail("could not be compiled by this OpenGL driver (the driver's message is in "
                   "the log)")

    def _check_built_source(self, source: str) -> None:
        """Every section must have reached the shader VTK built (a missing VTK tag is an
        error, not a silent no-op) and every uniform set for the technique must be used."""
        pending, self._expected_markers = self._expected_markers, None
        if pending is None:
            return
        markers, uniforms = pending
        missing = sorted(m for m in markers if m not in source)
        if missing:
            self._fail(f"targets a VTK shader tag this VTK does not have ({', '.join(missing)})")
            return
        unused = sorted(u for u in uniforms if len(re.findall(rf"\b{u}\b", source)) < 2)
        if unused:
            self._fail(f"sets uniforms its shader never reads ({', '.join(unused)})")

    # -- frame ----------------------------------------------------------------------------------
    def _on_start(self, _renderer: Any, _event: str) -> None:
        with _no_collection():
            try:
                self._start_frame()
            except shaders.ShaderConflictError as exc:
                # The user added a replacement ours cannot compose with after the call.
                self._on_draw_end()  # preparing may have given our textures units
                self._stand_aside(str(exc).removeprefix("vtkvol: "))
            finally:
                self._frame_specs = None

    def _start_frame(self) -> None:
        if self._closed:
            return
        if self._stand_in is not None:
            self._stand_in.sync(self.renderer.GetRenderWindow())
        if self._unsupported is not None:
            return
        if not self._check_input(raise_error=False):
            return
        self._take_renderer_lights()
        self._frame_specs = self._compute_light_specs()
        self.render_window = self.renderer.GetRenderWindow()
        t0 = time.perf_counter()
        if self._stepping or self._held:
            # A repaint between two chunks of precompute(): the technique is half-way, so the
            # frame keeps what was installed and bound before (changes wait for later). The
            # same for frames held still on purpose (holding_still).
            self._on_draw_end()
            return
        self._ensure_technique()
        self._upload_weights()
        self._update_empty_space()
        changes, self._changes = self._changes, Changes()
        if self._deferring(changes):
            # Keep the previous light: no prepare, the changes wait (merged) for later;
            # per-frame uniforms (colours, strengths) still follow.
            self._changes = changes.merge(self._changes)
            values = self.parameters
            self._install_shader(values)
            self._upload_uniforms(values)
            self._on_draw_end()
            return
        try:
            self._prepare_and_install(changes)
        except shaders.ShaderConflictError:
            raise  # not the technique's failure: local shading would meet the same conflict
        except Exception as exc:  # a technique's GL or numpy failure must not kill the view
            logger.exception("illumination %s failed to prepare", self.method)
            self._fail(f"failed ({type(exc).__name__}: {exc})")
            self._release_technique()
            self._detach_requested = False
            self._technique = self._technique_cls(self)
            self._prepare_and_install(Changes(first=True, opacity=True, lights=True))
        self._on_draw_end()  # preparing activated them; they get units again to draw
        self.last_prepare_ms = (time.perf_counter() - t0) * 1e3 + self._precomputed_ms
        self._precomputed_ms = 0.0

    def _deferring(self, changes: Changes) -> bool:
        """Whether this frame keeps the previous light (:attr:`defer_precompute`)."""
        if not self.defer_precompute or changes.first or self._technique is None:
            return False
        if changes.invalidates & Invalidates.SHADER:
            return False
        # What a drag changes (opacity, light geometry, parameters) waits; camera-only
        # changes of view-dependent techniques do not (they follow the view as before).
        # Progressive refinement pauses too.
        return bool(changes.opacity or changes.lights or changes.parameters
                    or changes.invalidates or not self._technique.converged)

    def _on_draw_start(self, *_args: Any) -> None:
        """Just before the volume draws: our textures take units, the samplers name them."""
        fu = self.shader_property.GetFragmentCustomUniforms()
        for name, (texture, _sampler) in self._textures.items():
            if texture.tex is not None:
                fu.SetUniformi(name, texture.activate())

    def _on_draw_end(self, *_args: Any) -> None:
        """After the volume drew (and after preparing): give the units back."""
        for texture, _sampler in self._textures.values():
            if texture.tex is not None:
                texture.tex.Deactivate()

    def _prepare_and_install(self, changes: Changes) -> None:
        tech = self._technique
        assert tech is not None
        values = self.parameters
        tech.prepare(changes, values)
        if tech.SPEC.has("progressive") and self.on_progress is not None:
            self.on_progress(tech.iteration, tech.converged)
        # After prepare: textures bound there must be retyped to samplers in this very build.
        self._install_shader(values)
        self._upload_uniforms(values)

    def _detect_changes(self) -> None:
        signature = self._opacity_signature()
        if signature != self._signature:
            self._signature = signature
            self._changes.opacity = True
        specs = self.light_specs()
        geometry = tuple((s.kind, s.vector, s.size, s.falloff_distance) for s in specs)
        colors = tuple(s.color for s in specs)
        if self._light_signature is None or geometry != self._light_signature[0]:
            self._changes.lights = True
        elif colors != self._light_signature[1]:
            self._changes.light_colors = True
        self._light_signature = (geometry, colors)
        if self.spec.has("view_dependent"):
            view = self._camera_signature()
            if view != self._view_signature:
                self._view_signature = view
                self._changes.view = True

    def _camera_signature(self) -> tuple:
        cam = self.renderer.GetActiveCamera()
        return (
            tuple(cam.GetPosition()), tuple(cam.GetFocalPoint()), tuple(cam.GetViewUp()),
            cam.GetViewAngle(), cam.GetParallelProjection(), cam.GetParallelScale(),
            tuple(self.renderer.GetSize()),
        )

    def _install_shader(self, values: Mapping[str, Any]) -> None:
        tech = self._technique
        assert tech is not None
        sections = shaders.load("host_prelude.glsl")
        if self._weights is not None:
            img = self.image
            ncomp = img.GetPointData().GetScalars().GetNumberOfComponents()
            independent = ncomp > 1 and bool(self.volume.GetProperty().GetIndependentComponents())
            sections += shaders.load(
                "host_slice_weights.glsl", {"VV_INDEPENDENT": "1"} if independent else None
            )
        interpolation = self._interpolation_sections()
        sections += interpolation
        multichannel, shared_lighting = self._multichannel_sections(
            shares_gradient=any("#define VV_IP_SHARE_GRADIENT" in s.code for s in interpolation),
            lighting=tech.SPEC.lighting)
        sections += multichannel
        if self._ess_stats.get("active"):
            bz, by, bx = self._ess_stats["brick_voxels_zyx"]
            sections += shaders.load("host_empty_space.glsl", {
                "VV_ESS_BRICK": f"vec3({float(bx):.1f}, {float(by):.1f}, {float(bz):.1f})"})
        own = tech.sections(values)
        defined = _defined_functions(tuple(s.code for s in own))
        hooks = {define: "1" for hook, define in HOOKS.items() if hook in defined}
        if tech.SPEC.has("rgb") != ("vv_light_transmittance_rgb" in defined):
            # The capability is what the dock and the benchmark read; it must not lie.
            raise ValueError(
                f"technique {tech.NAME!r}: declaring the 'rgb' capability and defining "
                "vv_light_transmittance_rgb go together"
            )
        sections += own
        lighting = {"surface": "host_lighting.glsl", "medium": "host_medium.glsl"}[
            tech.SPEC.lighting
        ]
        if self.shaded or (tech.SPEC.lighting == "medium" and self._compositing()):
            sections += shaders.load("host_hooks.glsl", hooks)
            # Multi-channel, shaded surface lighting per channel: one transmittance per light
            # and sample (shared lighting evaluates the lights once anyway).
            share_light = (bool(multichannel) and not shared_lighting and self.shaded
                           and tech.SPEC.lighting == "surface")
            sections += shaders.load(lighting, {"VV_MC_SHARE_LIGHT": "1"} if share_light
                                     else None)
        replacements = shaders.compose(sections)
        if multichannel:
            # VTK's classification loop: its body moves to vv_mcClassify (constant component
            # indices), called where the loop starts; the emptied loop compiles away.
            for line, text in _MULTICHANNEL_LINES.items():
                replacements[(line, "post")] = text
        for name, (_texture, sampler) in self._textures.items():
            replacements[(f"uniform int {name};", "post")] = f"uniform {sampler} {name};"
        if self._replacements.install(replacements):
            markers = {shaders.marker(s) for s in sections}
            self._expected_markers = (markers, set(self._technique_uniform_values(values)))

    def _multichannel_sections(self, *, shares_gradient: bool, lighting: str
                               ) -> tuple[list[shaders.Section], bool]:
        """The multi-channel sample's sections (``host_multichannel.glsl``: VTK's per-component
        work with constant indices, one set of gradient fetches; with shared lighting also
        ``host_multichannel_lighting.glsl``), or none; and whether the lighting is shared.
        For two to four independent components on a composite blend; ``shares_gradient``: the
        corrected trilinear filter already shares its fetches with the gradient; ``lighting``:
        the technique's lighting model."""
        self._mc_lighting_state = "per_channel"
        scalars = self.image.GetPointData().GetScalars()
        ncomp = scalars.GetNumberOfComponents() if scalars is not None else 1
        prop = self.volume.GetProperty()
        mapper = self.volume.GetMapper()
        if not (self.multichannel_sample and 2 <= ncomp <= 4 and prop.GetIndependentComponents()
                and mapper.GetBlendMode() == vtk.vtkVolumeMapper.COMPOSITE_BLEND):
            return [], False
        defines = {"VV_MC_COMPONENTS": str(ncomp)}
        share_gradient = (self.shaded and not shares_gradient
                          and not any(prop.HasGradientOpacity(c) for c in range(ncomp))
                          and mapper.GetVolumetricScatteringBlending() == 0)
        if share_gradient:
            # As for the corrected filter: VTK's gradient-opacity variant returns a magnitude
            # and its volumetric shadows take gradients away from the sample.
            defines["VV_MC_SHARE_GRADIENT"] = "1"
        why_not = self._why_not_shared_lighting(
            lighting, gradient_shared=share_gradient or shares_gradient)
        if why_not is not None:
            if self._multichannel_lighting == "shared":
                self._mc_lighting_state = f"per_channel ({why_not})"
            return shaders.load("host_multichannel.glsl", defines), False
        defines["VV_MC_SHARED_LIGHTING"] = "1"
        self._mc_lighting_state = "shared"
        light_defines = None
        if lighting == "surface":
            light_defines = {"VV_MC_SHARED_NORMAL": "1", "VV_MC_CHANNEL_GRADIENT":
                             "vv_ipGradient" if shares_gradient else "vv_mcGradient"}
        return (shaders.load("host_multichannel.glsl", defines)
                + shaders.load("host_multichannel_lighting.glsl", light_defines), True)

    def _why_not_shared_lighting(self, lighting: str, *, gradient_shared: bool) -> str | None:
        """None when the multi-channel sample lights its channels once (shared lighting asked
        for, and a lit sample whose normal can come from the shared fetches); else why not."""
        if self._multichannel_lighting != "shared":
            return "per channel asked for"
        prop = self.volume.GetProperty()
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            return "2-D transfer functions colour from the gradient per channel"
        if lighting == "medium":
            return None  # lit on every composited sample, no normal
        if not self.shaded:
            return "unshaded: nothing is lit"
        if not gradient_shared:
            return "gradient opacity or volumetric scattering take gradients per channel"
        return None

    def _interpolation_sections(self) -> list[shaders.Section]:
        """The corrected-trilinear filter's sections (after the slice weights: both wrap
        ``computeOpacity``), or none. Only composite blending samples the scalar where the
        wrappers can correct it (MIP and the other blends classify a reduced value)."""
        if self._interpolation != "corrected":
            return []
        if self.volume.GetMapper().GetBlendMode() != vtk.vtkVolumeMapper.COMPOSITE_BLEND:
            return []
        prop = self.volume.GetProperty()
        if prop.GetInterpolationType() == vtk.VTK_NEAREST_INTERPOLATION:
            return []  # the correction assumes trilinear fetches (label data use nearest)
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            # VTK's 2-D colour lookup reads the uncorrected scalar and its own gradient; a
            # corrected opacity beside it would classify one sample two ways.
            return []
        ncomp = self.image.GetPointData().GetScalars().GetNumberOfComponents()
        independent = ncomp > 1 and bool(prop.GetIndependentComponents())
        if ncomp > 1 and not independent:
            return []  # dependent components (RGBA data): colour is not a filtered scalar
        defines = {"VV_INDEPENDENT": "1"} if independent else {}
        used = range(ncomp) if independent else range(1)
        mapper = self.volume.GetMapper()
        if (self.shaded and not any(prop.HasGradientOpacity(c) for c in used)
                and mapper.GetVolumetricScatteringBlending() == 0):
            # The shading gradient reuses the correction's six fetches. Not with gradient
            # opacity (VTK's variant returns a magnitude) or VTK's volumetric shadows (they
            # take gradients away from the sample).
            defines["VV_IP_SHARE_GRADIENT"] = "1"
        return shaders.load("host_interpolation.glsl", defines)

    # -- empty-space skipping -------------------------------------------------------------------
    def _update_empty_space(self) -> None:
        """Recompute the occupancy grid when what decides it changed (data, TFs, crop, slice
        weights, blend mode, filter, the switch) and bind it; camera moves cost nothing."""
        mapper = self.volume.GetMapper()
        prop = self.volume.GetProperty()
        key = (self._signature, self._skip_empty, int(mapper.GetBlendMode()),
               self._interpolation, int(prop.GetTransferFunctionMode()),
               mapper.GetMaskInput() is not None)
        if key == self._ess_key:
            return
        self._ess_key = key
        try:
            stats, grid = self._occupancy_grid()
            if grid is not None:
                self._upload_occupancy(grid)
        except Exception as exc:  # never lose the view to an optimisation
            logger.exception("empty-space skipping failed; rays march the whole volume")
            stats, grid = {"active": False, "reason": f"failed ({type(exc).__name__}: {exc})"}, None
        self._ess_stats = stats
        if grid is None:
            self._drop_occupancy()

    def _upload_occupancy(self, grid: np.ndarray) -> None:
        data = grid.astype(np.float32)
        if self._ess_texture is None or self._ess_texture.shape != data.shape:
            if self._ess_texture is not None:
                self._ess_texture.release()
                self._ess_texture = None
            self._ess_texture = Texture3D(self.render_window, data.shape, data=data)
        else:
            self._ess_texture.upload(data)
        self.bind_texture("vv_essOccupancy", self._ess_texture)
        nz, ny, nx = (int(n) for n in self.image.GetDimensions()[::-1])
        bz, by, bx = data.shape
        fu = self.shader_property.GetFragmentCustomUniforms()
        fu.SetUniform3f("vv_essTexDims", [float(nx), float(ny), float(nz)])
        fu.SetUniform3f("vv_essBricks", [float(bx), float(by), float(bz)])

    def _drop_occupancy(self) -> None:
        self.unbind_texture("vv_essOccupancy")
        fu = self.shader_property.GetFragmentCustomUniforms()
        for name in _ESS_UNIFORMS:
            fu.RemoveUniform(name)
        if self._ess_texture is not None:
            self._ess_texture.release()
            self._ess_texture = None

    def _occupancy_grid(self) -> tuple[dict[str, Any], np.ndarray | None]:
        """``(stats, grid)``: the occupancy (bool ``[bz, by, bx]``) the shader reads, or None
        with the reason skipping does not apply to this volume's settings."""
        def off(reason: str) -> tuple[dict[str, Any], None]:
            return {"active": False, "reason": reason}, None

        if not self._skip_empty:
            return off("switched off")
        mapper = self.volume.GetMapper()
        prop = self.volume.GetProperty()
        if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_1D:
            return off("2-D transfer functions are not supported")
        if mapper.GetMaskInput() is not None:
            return off("masked volumes are not supported")
        blend = mapper.GetBlendMode()
        img = self.image
        nx, ny, nz = img.GetDimensions()
        scalars = img.GetPointData().GetScalars()
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1)
        ncomp = values.shape[-1]
        independent = ncomp == 1 or bool(prop.GetIndependentComponents())
        functions: list[tuple[np.ndarray, np.ndarray] | None] = [None] * ncomp
        for c in range(ncomp) if independent else [ncomp - 1]:
            fc = c if independent else 0
            if independent and ncomp > 1 and prop.GetComponentWeight(fc) <= 0:
                continue  # VTK multiplies this component's contribution by 0
            function = prop.GetScalarOpacity(fc)
            nodes = np.array([_node(function, i)[:2] for i in range(function.GetSize())])
            functions[c] = (nodes[:, 0], nodes[:, 1]) if len(nodes) else (
                np.zeros(1), np.zeros(1))
        composite = (vtk.vtkVolumeMapper.COMPOSITE_BLEND, vtk.vtkVolumeMapper.ADDITIVE_BLEND)
        if blend == vtk.vtkVolumeMapper.MAXIMUM_INTENSITY_BLEND:
            # The maximum of the samples left equals the full maximum, or both map to
            # opacity 0, only if zero opacity is a prefix of the value axis; the final
            # classification reads the slice weight at the ray's last position, which a jump
            # moves.
            if not all(f is None or occupancy.non_decreasing(f) for f in functions):
                return off("maximum-intensity projection needs non-decreasing opacity")
            if self._weights is not None:
                return off("maximum-intensity projection with slice weights")
        elif blend not in composite:
            return off("average, minimum-intensity and isosurface blending count or compare "
                       "every sample")
        apron = 2 if self._interpolation_sections() else 1
        brick = occupancy.brick_for_spacing(img.GetSpacing())
        range_key = (img.GetMTime(), scalars.GetMTime(), apron, brick)
        if self._ess_ranges is None or self._ess_ranges[0] != range_key:
            t0 = time.perf_counter()
            computed = occupancy.brick_ranges(values, apron=apron, brick=brick)
            self._ess_ranges = (range_key, computed, (time.perf_counter() - t0) * 1e3)
        _key, ranges, ranges_ms = self._ess_ranges
        t1 = time.perf_counter()
        # VTK samples each opacity table over the component's scalar range (the data's).
        table_range = []
        for c in range(ncomp):
            finite_lo = ranges.lo[c][np.isfinite(ranges.lo[c])]
            finite_hi = ranges.hi[c][np.isfinite(ranges.hi[c])]
            table_range.append((float(finite_lo.min()), float(finite_hi.max()))
                               if finite_lo.size and finite_hi.size else (np.nan, np.nan))
        if apron == 2:
            ranges = occupancy.widen_for_corrected(ranges)
        grid = occupancy.transfer_occupancy(ranges, functions, table_range)
        if mapper.GetCropping():
            grid &= occupancy.crop_occupancy(
                (nz, ny, nx), img.GetOrigin(), img.GetSpacing(),
                mapper.GetCroppingRegionPlanes(), int(mapper.GetCroppingRegionFlags()),
                brick=brick)
        if self._weights is not None and blend != vtk.vtkVolumeMapper.MAXIMUM_INTENSITY_BLEND:
            grid &= occupancy.weight_occupancy((nz, ny, nx), self._weights, brick=brick)
        empty = float(1.0 - grid.mean())
        stats = {
            "active": empty >= occupancy.MIN_EMPTY_FRACTION,
            "reason": "" if empty >= occupancy.MIN_EMPTY_FRACTION else (
                f"only {100 * empty:.0f} % of the bricks are empty (below "
                f"{100 * occupancy.MIN_EMPTY_FRACTION:.0f} %: the check per sample would cost "
                "more than the jumps save)"),
            "bricks": tuple(int(n) for n in grid.shape[::-1]),
            "brick_voxels": tuple(brick[::-1]),
            "brick_voxels_zyx": brick,
            "empty_fraction": empty,
            "ranges_ms": ranges_ms,
            "occupancy_ms": (time.perf_counter() - t1) * 1e3,
        }
        return stats, grid if stats["active"] else None

    def _upload_weights(self) -> None:
        if self._weights is None:
            if self._weights_texture is not None:
                self.unbind_texture("vv_sliceWeights")
                self._weights_texture.release()
                self._weights_texture = None
            return
        if self._weights_texture is None or self._weights_texture.shape != self._weights.shape:
            if self._weights_texture is not None:
                self._weights_texture.release()
            self._weights_texture = Texture2D(self.render_window, self._weights)
        else:
            self._weights_texture.upload(self._weights)
        self.bind_texture("vv_sliceWeights", self._weights_texture, "sampler2D")
        self.shader_property.GetFragmentCustomUniforms().SetUniformf(
            "vv_sliceWeightsWidth", float(self._weights.shape[1])
        )

    def _technique_uniform_values(self, values: Mapping[str, Any]) -> dict[str, Any]:
        tech = self._technique
        assert tech is not None
        out: dict[str, Any] = {}
        for p in tech.PARAMETERS:
            if p.uniform and p.kind != "choice":
                value = values[p.name]
                out[f"vv_{tech.NAME}_{p.name}"] = int(value) if p.kind in ("int", "bool") else (
                    float(value)
                )
        out.update(tech.uniforms(values))
        return out

    def _upload_uniforms(self, values: Mapping[str, Any]) -> None:
        fu = self.shader_property.GetFragmentCustomUniforms()
        specs = self.light_specs()
        packed = np.zeros(LIGHT_STRIDE * MAX_LIGHTS, np.float32)
        for i, spec in enumerate(specs):
            base = LIGHT_STRIDE * i
            packed[base : base + 3] = spec.vector
            packed[base + 3] = 1.0 if spec.is_point else 0.0
            packed[base + 4 : base + 7] = spec.color
            packed[base + 7] = spec.size
            packed[base + 8] = spec.falloff_distance
        fu.SetUniformi("vv_numLights", len(specs))
        fu.SetUniform1fv("vv_lights", len(packed), packed.tolist())
        self._upload_exposure()
        if self.spec.lighting == "medium":
            fu.SetUniformf("vv_albedo", self._albedo)
            fu.SetUniformf("vv_phaseG", self._phase_g)
        else:
            for name in _MEDIUM_UNIFORMS:
                fu.RemoveUniform(name)
        for name, value in self._technique_uniform_values(values).items():
            _set_uniform(fu, name, value)
            self._uniforms.add(name)

    def _release_technique(self) -> None:
        """Release the technique and everything the host set up for it (its uniforms and
        texture bindings), so nothing of it survives a switch."""
        if self._technique is not None:
            self._technique.release()
            self._technique = None
        self._release_classification()
        fu = self.shader_property.GetFragmentCustomUniforms()
        for name in self._uniforms:
            fu.RemoveUniform(name)
        self._uniforms.clear()
        for name in [n for n in self._textures if n not in _HOST_TEXTURES]:
            self.unbind_texture(name)

    # -- signatures -----------------------------------------------------------------------------
    def opacity_signature(self) -> tuple:
        """Changes whenever the classified opacity can (data, TF, crop, clipping, weights,
        placement): renderers beside the ray caster restart on it."""
        return self._opacity_signature()

    def _opacity_signature(self) -> tuple:
        mapper = self.volume.GetMapper()
        prop = self.volume.GetProperty()
        img = self.image
        ncomp = img.GetPointData().GetScalars().GetNumberOfComponents() if img else 0
        funcs = tuple(prop.GetScalarOpacity(c).GetMTime() for c in range(max(1, ncomp)))
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            tables = tuple(
                tf2d.unit_alpha_mtime(prop.GetTransferFunction2D(c))
                if prop.GetTransferFunction2D(c) is not None else None
                for c in range(max(1, ncomp)))
            # A foreign table holds alpha per step: its conversion depends on the step.
            classification: tuple = ("2d", tables, float(mapper.GetSampleDistance()) if any(
                prop.GetTransferFunction2D(c) is not None and prop.GetTransferFunction2D(c)
                .GetPointData().GetArray(tf2d.UNIT_ALPHA_ARRAY) is None
                for c in range(max(1, ncomp))) else None)
        else:
            classification = ("1d", tuple(
                prop.GetGradientOpacity(c).GetMTime() if _gradient_opacity_on(prop, c) else None
                for c in range(max(1, ncomp))))
        weights = tuple(prop.GetComponentWeight(c) for c in range(max(1, ncomp)))
        units = tuple(prop.GetScalarOpacityUnitDistance(c) for c in range(max(1, ncomp)))
        matrix = self.volume.GetMatrix()
        return (
            img.GetMTime(),
            funcs,
            classification,
            weights,
            units,
            bool(prop.GetIndependentComponents()),
            bool(mapper.GetCropping()),
            tuple(mapper.GetCroppingRegionPlanes()),
            int(mapper.GetCroppingRegionFlags()),
            _clipping_signature(mapper),
            tuple(matrix.GetElement(i, j) for i in range(4) for j in range(4)),
            self._weights_version,
        )

    # -- teardown -------------------------------------------------------------------------------
    def release(self) -> None:
        """Remove everything this illuminator added (replacements, uniforms, textures,
        observers). Call before the render window is finalised; safe to call twice."""
        if self._closed:
            return
        with _no_collection():
            self._release()

    def _release(self) -> None:
        if self.beside is not None:
            self.beside.release()
            self.beside = None
        self._closed = True
        self._coords_cache.clear()
        if self.render_window is not None:  # GL resources exist only after a first frame
            self.render_window.MakeCurrent()
        self._release_technique()
        if self._weights_texture is not None:
            self._weights_texture.release()
            self._weights_texture = None
        self._drop_occupancy()
        fu = self.shader_property.GetFragmentCustomUniforms()
        for name in list(self._textures):
            self.unbind_texture(name)
        for name in ("vv_numLights", "vv_lights", "vv_sliceWeightsWidth", *_EXPOSURE_UNIFORMS,
                     *_MEDIUM_UNIFORMS):
            fu.RemoveUniform(name)
        self._replacements.clear()
        prop = self.volume.GetProperty()
        for c, shade in enumerate(self._user_shade):
            prop.SetShade(c, shade)
        self.renderer.RemoveObserver(self._start_tag)
        self.volume.GetMapper().RemoveObserver(self._shader_tag)
        self.volume.GetMapper().RemoveObserver(self._error_tag)
        for tag in self._draw_tags:
            self.volume.GetMapper().RemoveObserver(tag)
        if self._stand_in is not None:
            self._stand_in.give_back()  # edits made on the stand-in reach the user's mapper
            self.volume.SetMapper(self._stand_in.smart)
            self._stand_in = None
        if _HOSTS.get(id(self.volume)) is self:
            del _HOSTS[id(self.volume)]


#: The live illuminator of each volume, by id(volume) (an illuminator holds its volume, so the
#: id is not reused while the entry lives); weak, so a forgotten illuminator can still go.
_HOSTS: weakref.WeakValueDictionary[int, Illuminator] = weakref.WeakValueDictionary()
#: Replacements whose code takes the place of VTK's (the tag is not kept): host_lighting.glsl's
#: and host_medium.glsl's ``//VTK::ComputeLighting::Exit``.
_REPLACED_OUTRIGHT: tuple[tuple[str, shaders.Phase], ...] = (
    ("//VTK::ComputeLighting::Exit", "post"),)
#: Uniforms and textures the host sets for itself (not for the technique).
_MEDIUM_UNIFORMS = ("vv_albedo", "vv_phaseG")
#: Host lighting's exposure, sky fill and local-shading probe switch (both lighting models).
_EXPOSURE_UNIFORMS = ("vv_exposure", "vv_fill", "vv_exposureProbe")
#: Lines of VTK 9.7's independent-component composite loop (post replacements, see
#: host_multichannel.glsl): the classification loop's body becomes one vv_mcClassify call.
_MULTICHANNEL_LINES = {
    "float totalAlpha = 0.0;":
        "float totalAlpha = 0.0;\n      vv_mcClassify(scalar, color, totalAlpha);",
    "color[i][3] = computeOpacity(scalar, i);": "",
    "color[i] = computeColor(scalar, color[i][3], i);": "",
    "totalAlpha += color[i][3] * in_componentWeight[i];": "",
}
_HOST_TEXTURES = frozenset({"vv_sliceWeights", "vv_essOccupancy"})
_ESS_UNIFORMS = ("vv_essTexDims", "vv_essBricks")


@functools.lru_cache(maxsize=64)
def _defined_functions(codes: tuple[str, ...]) -> frozenset[str]:
    """The ``vv_`` functions a technique's GLSL defines (asked every frame; parsed once)."""
    return frozenset(m for code in codes for m in _HOOK_DEFINITION.findall(code))


@contextlib.contextmanager
def _no_collection() -> Iterator[None]:
    """No cyclic garbage collection while we run inside VTK's render: collecting a forgotten
    render window there finalises it, which leaves *no* GL context current, and every GL call
    after it (ours, and VTK's for the rest of the frame) silently does nothing."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def check_multichannel_lighting(mode: str) -> None:
    """``ValueError`` unless ``mode`` is a multi-channel lighting ("per_channel", "shared")."""
    if mode not in MULTICHANNEL_LIGHTINGS:
        raise ValueError(f"multichannel_lighting must be 'per_channel' or 'shared', not {mode!r}")


def _light_world_geometry(light: vtk.vtkLight,
                          camera: vtk.vtkCamera) -> tuple[np.ndarray, np.ndarray]:
    """World position and focal point of ``light`` for ``camera``'s current view.

    Computed from the camera rather than read from the light: the renderer moves its headlight
    and camera lights to the camera only inside its render, after the frame's start where the
    illuminator reads them, so the light's own transformed position is a frame behind."""
    if light.LightTypeIsHeadlight():
        return np.array(camera.GetPosition(), float), np.array(camera.GetFocalPoint(), float)
    if light.LightTypeIsCameraLight():
        matrix = camera.GetCameraLightTransformMatrix()
        position = matrix.MultiplyPoint((*light.GetPosition(), 1.0))
        focal = matrix.MultiplyPoint((*light.GetFocalPoint(), 1.0))
        return (np.array(position[:3]) / position[3], np.array(focal[:3]) / focal[3])
    return (np.array(light.GetTransformedPosition(), float),
            np.array(light.GetTransformedFocalPoint(), float))


#: Where a key light sits relative to the view (degrees): VTK's vtkLightKit's defaults, the
#: photographer's key light above and beside the camera.
KEY_LIGHT_ELEVATION_DEG = 50.0
KEY_LIGHT_AZIMUTH_DEG = 10.0


def key_light_direction(camera: vtk.vtkCamera) -> tuple[float, float, float]:
    """World direction towards a key light for ``camera``'s current view: the direction to the
    camera turned up by :data:`KEY_LIGHT_ELEVATION_DEG` (about the camera's right axis) and to
    the right by :data:`KEY_LIGHT_AZIMUTH_DEG` (about its view-up)."""
    position = np.array(camera.GetPosition(), float)
    focal = np.array(camera.GetFocalPoint(), float)
    to_camera = position - focal
    norm = np.linalg.norm(to_camera)
    to_camera = to_camera / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    up = np.array(camera.GetViewUp(), float)
    up = up - np.dot(up, to_camera) * to_camera
    if np.linalg.norm(up) < 1e-9:  # a view-up along the view: any perpendicular will do
        up = np.cross(to_camera, [1.0, 0.0, 0.0] if abs(to_camera[0]) < 0.9 else [0, 1.0, 0])
    up = up / np.linalg.norm(up)
    right = np.cross(-to_camera, up)
    elevation = math.radians(KEY_LIGHT_ELEVATION_DEG)
    azimuth = math.radians(KEY_LIGHT_AZIMUTH_DEG)
    direction = (math.cos(elevation) * (math.cos(azimuth) * to_camera + math.sin(azimuth) * right)
                 + math.sin(elevation) * up)
    return tuple(float(v) for v in direction)


def _check_mapper(volume: vtk.vtkVolume, renderer: vtk.vtkRenderer) -> vtk.vtkVolumeMapper:
    """The volume's mapper if vtkvol can illuminate it: the GPU ray caster, or a smart mapper
    (rendered through one). Anything else is a ``TypeError`` saying what to use instead."""
    if isinstance(volume, vtk.vtkMultiVolume):
        raise TypeError(
            "vtkvol: multi-volume rendering (vtkMultiVolume) cannot be illuminated: give each "
            "image its own vtkVolume and GPU ray-cast mapper")
    mapper = volume.GetMapper()
    if mapper is None:
        for other in _volumes_of(renderer):
            if isinstance(other, vtk.vtkMultiVolume) and any(
                    other.GetVolume(port) is volume
                    for port in range(other.GetMapper().GetNumberOfInputPorts())):
                raise TypeError(
                    "vtkvol: this volume is a member of a multi-volume (vtkMultiVolume), "
                    "which cannot be illuminated: give each image its own vtkVolume and GPU "
                    "ray-cast mapper")
        raise TypeError("vtkvol: the volume has no mapper; give it a "
                        "vtkOpenGLGPUVolumeRayCastMapper (members of a vtkMultiVolume, "
                        "multi-volume rendering, cannot be illuminated)")
    if not isinstance(mapper, vtk.vtkGPUVolumeRayCastMapper | vtk.vtkSmartVolumeMapper):
        raise TypeError(
            "vtkvol illumination needs a GPU ray-cast mapper, not "
            f"{type(mapper).__name__}: use vtkOpenGLGPUVolumeRayCastMapper (PyVista: "
            'plotter.add_volume(..., mapper="gpu"))'
        )
    return mapper


def _volumes_of(renderer: vtk.vtkRenderer) -> list[vtk.vtkVolume]:
    volumes = renderer.GetVolumes()
    volumes.InitTraversal()
    return [volumes.GetNextVolume() for _ in range(volumes.GetNumberOfItems())]


def _clipping_signature(mapper: vtk.vtkVolumeMapper) -> tuple:
    planes = mapper.GetClippingPlanes()
    if planes is None:
        return ()
    return tuple(
        (tuple(planes.GetItem(k).GetOrigin()), tuple(planes.GetItem(k).GetNormal()))
        for k in range(planes.GetNumberOfItems())
    )


def _capture_source(illuminator: Illuminator) -> Callable[..., None]:
    """Observer for UpdateShaderEvent, whose call data is the bound vtkShaderProgram. It does not
    fire on the frame a program is (re)built (docs/architecture.md, "Engine"), only on the
    frames after: the first of those checks the build."""

    @vtk.calldata_type(vtk.VTK_OBJECT)
    def capture(_mapper: Any, _event: str, program: Any = None) -> None:
        if program is not None:
            with _no_collection():
                source = program.GetFragmentShader().GetSource()
                illuminator._fragment_source = source
                illuminator._check_built_source(source)

    return capture


def _set_uniform(fu: vtk.vtkUniforms, name: str, value: Any) -> None:
    if isinstance(value, bool | int | np.integer):
        fu.SetUniformi(name, int(value))
    elif isinstance(value, float | np.floating):
        fu.SetUniformf(name, float(value))
    else:
        arr = np.asarray(value, dtype=np.float32).ravel()
        if arr.size == 3:
            fu.SetUniform3f(name, arr.tolist())
        elif arr.size == 2:
            fu.SetUniform2f(name, arr.tolist())
        elif arr.size == 4:
            fu.SetUniform4f(name, arr.tolist())
        else:
            fu.SetUniform1fv(name, int(arr.size), arr.tolist())


#: Largest component (voxels) whose 2-D table coordinates are kept between TF edits (256 MB).
_COORDS_CACHE_VOXELS = 32 * 1024 * 1024


def _gradient_opacity_on(prop: vtk.vtkVolumeProperty, c: int) -> bool:
    """True when VTK multiplies component ``c``'s opacity by a gradient-opacity function
    (1-D mode; VTK ignores it in 2-D mode)."""
    return bool(prop.HasGradientOpacity(c)) and not prop.GetDisableGradientOpacity(c)


def _evaluate_piecewise(function: vtk.vtkPiecewiseFunction, values: np.ndarray) -> np.ndarray:
    """Evaluate a (linear) piecewise function on an array; integer data through a lookup table."""
    n = function.GetSize()
    if n == 0:
        return np.zeros(values.shape, np.float32)
    nodes = np.array([_node(function, i) for i in range(n)])
    xs, ys = nodes[:, 0], nodes[:, 1]
    if values.dtype.kind in "ui" and values.dtype.itemsize <= 2:
        info = np.iinfo(values.dtype)
        table = np.interp(np.arange(info.min, info.max + 1, dtype=np.float64), xs, ys)
        table = table.astype(np.float32)
        return table[values.astype(np.int64) - info.min] if info.min else table[values]
    finite = np.where(np.isfinite(values), values, xs[0])
    return np.interp(finite, xs, ys).astype(np.float32)


def _node(function: vtk.vtkPiecewiseFunction, i: int) -> list[float]:
    node = [0.0] * 4
    function.GetNodeValue(i, node)
    return node


def _axis_weight_vectors(weights: np.ndarray, shape_zyx: tuple[int, int, int]
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """wX(x), wY(y), wZ(z) sampled at voxel centres."""
    nz, ny, nx = shape_zyx
    grid = np.linspace(0.0, 1.0, weights.shape[1])

    def sample(row: np.ndarray, n: int) -> np.ndarray:
        return np.interp(np.linspace(0.0, 1.0, n), grid, row).astype(np.float32)

    return sample(weights[0], nx), sample(weights[1], ny), sample(weights[2], nz)


def run_steps(steps: Generator[Any, None, Any]) -> Any:
    """Run a chunked computation (a generator) to its end; returns its return value."""
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            return stop.value


def scale_steps(steps: Generator[float, None, Any], lo: float, hi: float
                ) -> Generator[float, None, Any]:
    """``steps``' fractions mapped onto ``lo…hi`` (a part of a larger progress); returns
    its return value (``x = yield from scale_steps(...)``)."""
    while True:
        try:
            fraction = next(steps)
        except StopIteration as stop:
            return stop.value
        yield lo + (hi - lo) * fraction
