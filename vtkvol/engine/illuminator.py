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
import logging
import math
import time
import weakref
from collections.abc import Callable, Generator, Iterator, Mapping, Sequence
from typing import Any, Literal

import numpy as np
import vtk

from vtkvol.engine import shaders
from vtkvol.engine.bindings import Bindings
from vtkvol.engine.empty_space import EmptySpaceSkipper
from vtkvol.engine.gl import Texture3D
from vtkvol.engine.lights import (  # noqa: F401  (key_light_direction: re-exported)
    MAX_LIGHTS,
    key_light_direction,
    light_specs_in_dataset,
    renderer_lights,
)
from vtkvol.engine.opacity_source import OpacitySource
from vtkvol.engine.precompute import PrecomputeRunner, no_collection
from vtkvol.engine.shader_builder import ShaderBuild, ShaderBuilder, source_observer, verify
from vtkvol.engine.smart import SmartStandIn, check_mapper
from vtkvol.engine.technique import (  # noqa: F401  (old import path)
    Changes,
    LightSpec,
    Technique,
    run_steps,
    scale_steps,
    technique_class,
    warn_inert,
)
from vtkvol.model.params import Invalidates
from vtkvol.model.scene import MULTICHANNEL_LIGHTINGS, Light
from vtkvol.model.techniques import TechniqueSpec

logger = logging.getLogger(__name__)


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
        mapper = check_mapper(volume, renderer)
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
        self._inert_warned: set[tuple[str, str]] = set()  # (method, parameter) warned about
        self._technique_cls: type[Technique] = technique_class(method)
        self._technique: Technique | None = None
        self._detach_requested = False
        self._changes = Changes(first=True, opacity=True, lights=True)
        self._signature: tuple | None = None
        self._light_signature: tuple | None = None
        self._view_signature: tuple | None = None
        self._weights: np.ndarray | None = None  # (3, W) or None for identity
        self._weights_version = 0
        self.bindings = Bindings(self.shader_property)
        #: The bindings' table (uniform → (texture, sampler)); tests and diagnostics read it.
        self._textures = self.bindings.textures
        self._expected_build: ShaderBuild | None = None
        self._fragment_source = ""
        #: The services this host owns (plain classes; see docs/architecture.md).
        self.opacity = OpacitySource(self)
        self.empty_space = EmptySpaceSkipper(self)
        self.shader_builder = ShaderBuilder(self)
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
        self.last_prepare_ms = 0.0
        self.render_window: vtk.vtkRenderWindow | None = None
        self.profiling = False
        #: Progressive work per frame, ms (None: unbounded; the app sets one; TechniqueHost).
        self.work_budget_ms: float | None = None
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
        self.precompute_runner = PrecomputeRunner(self)
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
        # Keep a reference: VTK holds the observer weakly.
        self._capture = source_observer(self._on_built_source)
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
        warn_inert(spec, self.method, changed & set(values), merged, self._inert_warned)
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
        self._expected_build = None  # nothing of ours is built any more
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
        """:func:`vtkvol.engine.lights.renderer_lights` of this renderer."""
        return renderer_lights(self.renderer, fixed=fixed)

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
        self.bindings.upload_exposure(1.0 if self._probe else self._exposure, self._fill,
                                      self._probe)

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
        return self.shader_builder.mc_lighting_state

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
        return dict(self.empty_space.stats)

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
        return self.precompute_runner.stepping

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
        return self.precompute_runner.precompute(progress)

    @property
    def has_pending_changes(self) -> bool:
        """Whether changes wait for a prepare (deferred ones included) that may recompute."""
        return self._needs_prepare(self._changes) or (
            self._signature is not None and self.opacity.signature() != self._signature)

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
        """:meth:`PrecomputeRunner.converge`: render until converged, ``iterations`` reached,
        ``max_frames`` rendered or ``max_seconds`` passed; returns the frames rendered."""
        return self.precompute_runner.converge(max_frames, max_seconds, iterations=iterations)

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
        return light_specs_in_dataset(self._lights, self.volume, self.image)

    # -- classification on the GPU --------------------------------------------------------------

    # -- the opacity source (engine/opacity_source.py), as techniques and tests reach it -----
    def opacity_volume(self) -> np.ndarray:
        """:meth:`OpacitySource.opacity_volume`: per-voxel opacity per ``unit_distance``,
        float32 ``[z, y, x]``, cropped, clipped and slice-weighted."""
        return self.opacity.opacity_volume()

    def opacity_volume_steps(self) -> Generator[float, None, np.ndarray]:
        """:meth:`OpacitySource.opacity_volume_steps` (for ``prepare_steps``)."""
        return self.opacity.opacity_volume_steps()

    def opacity_texture(self, quantity: str = "alpha") -> Texture3D:
        """:meth:`OpacitySource.opacity_texture`: the opacity as a host-owned r32f texture."""
        return self.opacity.opacity_texture(quantity)

    def opacity_texture_steps(self, quantity: str = "alpha"
                              ) -> Generator[float, None, Texture3D]:
        """:meth:`OpacitySource.opacity_texture_steps` (for ``prepare_steps``)."""
        return self.opacity.opacity_texture_steps(quantity)

    def classify_2d(self, c: int, what: Literal["alpha", "rgb"] = "alpha") -> np.ndarray | None:
        """:meth:`OpacitySource.classify_2d`: component ``c``'s 2-D table at every voxel."""
        return self.opacity.classify_2d(c, what)

    @property
    def classification(self) -> str:
        """:attr:`OpacitySource.classification`: ``"auto"``, ``"gpu"`` or ``"cpu"``."""
        return self.opacity.classification

    @classification.setter
    def classification(self, backend: str) -> None:
        self.opacity.classification = backend

    def classification_stats(self) -> dict[str, Any]:
        """:meth:`OpacitySource.classification_stats`."""
        return self.opacity.classification_stats()

    def opacity_signature(self) -> tuple:
        """Changes whenever the classified opacity can (data, TF, crop, clipping, weights,
        placement): renderers beside the ray caster restart on it."""
        return self.opacity.signature()

    def _opacity_signature(self) -> tuple:
        return self.opacity.signature()

    # -- GL helpers for techniques --------------------------------------------------------------
    def bind_texture(self, uniform: str, texture: Any, sampler: str = "sampler3D") -> None:
        """:meth:`Bindings.bind_texture`: ``texture`` visible to GLSL as ``uniform``, removed
        when the technique is switched or released."""
        self.bindings.bind_texture(uniform, texture, sampler)

    def bound_textures(self) -> dict[str, Any]:
        """:meth:`Bindings.bound_textures`: the technique's textures by uniform name."""
        return self.bindings.bound_textures()

    def unbind_texture(self, uniform: str) -> None:
        self.bindings.unbind_texture(uniform)

    @property
    def shaded(self) -> bool:
        """:meth:`ShaderBuilder.shaded`: VTK generates its shaded ``computeLighting()``."""
        return self.shader_builder.shaded()

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

    def _on_built_source(self, source: str) -> None:
        self._fragment_source = source
        self._check_built_source(source)

    def _check_built_source(self, source: str) -> None:
        """Every section, replaced VTK line and technique uniform of the last build must have
        reached the shader VTK built (a missing VTK tag or line is an error, not a silent
        no-op; :func:`vtkvol.engine.shader_builder.verify`)."""
        pending, self._expected_build = self._expected_build, None
        if pending is None:
            return
        why = verify(pending, source)
        if why is not None:
            self._fail(why)

    # -- frame ----------------------------------------------------------------------------------
    def _install_shader(self, values: Mapping[str, Any]) -> None:
        assert self._technique is not None
        build = self.shader_builder.build(self._technique, values)
        if self._replacements.install(build.replacements):
            self._expected_build = build

    def _on_start(self, _renderer: Any, _event: str) -> None:
        with no_collection():
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
        if self.precompute_runner.stepping or self._held:
            # A repaint between two chunks of precompute(): the technique is half-way, so the
            # frame keeps what was installed and bound before (changes wait for later). The
            # same for frames held still on purpose (holding_still).
            self._on_draw_end()
            return
        self._ensure_technique()
        self._upload_weights()
        self.empty_space.update()
        changes, self._changes = self._changes, Changes()
        if self.precompute_runner.defers(changes):
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

    def _on_draw_start(self, *_args: Any) -> None:
        self.bindings.draw_start()

    def _on_draw_end(self, *_args: Any) -> None:
        self.bindings.draw_end()

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
        signature = self.opacity.signature()
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

    # -- empty-space skipping -------------------------------------------------------------------

    def _upload_weights(self) -> None:
        self.bindings.upload_weights(self.render_window, self._weights)

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
        medium = (self._albedo, self._phase_g) if self.spec.lighting == "medium" else None
        self.bindings.upload(self.light_specs(), medium, self._technique_uniform_values(values))
        self._upload_exposure()

    def _release_technique(self) -> None:
        """Release the technique and everything the host set up for it (its uniforms and
        texture bindings), so nothing of it survives a switch."""
        if self._technique is not None:
            self._technique.release()
            self._technique = None
        self.opacity.release()
        self.bindings.release_technique()

    # -- teardown -------------------------------------------------------------------------------
    def release(self) -> None:
        """Remove everything this illuminator added (replacements, uniforms, textures,
        observers). Call before the render window is finalised; safe to call twice."""
        if self._closed:
            return
        with no_collection():
            self._release()

    def _release(self) -> None:
        if self.beside is not None:
            self.beside.release()
            self.beside = None
        self._closed = True
        self.opacity.clear_caches()
        if self.render_window is not None:  # GL resources exist only after a first frame
            self.render_window.MakeCurrent()
        self._release_technique()
        self.empty_space.drop()
        self.bindings.release()
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


def check_multichannel_lighting(mode: str) -> None:
    """``ValueError`` unless ``mode`` is a multi-channel lighting ("per_channel", "shared")."""
    if mode not in MULTICHANNEL_LIGHTINGS:
        raise ValueError(f"multichannel_lighting must be 'per_channel' or 'shared', not {mode!r}")
