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
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal

import numpy as np
import vtk

from vtkvol.engine import shaders
from vtkvol.engine.adaptive_sampling import AdaptiveSampler
from vtkvol.engine.bindings import Bindings, technique_uniform_values
from vtkvol.engine.changes import ChangeTracker, first_changes
from vtkvol.engine.empty_space import EmptySpaceSkipper
from vtkvol.engine.exposure import ExposureControl
from vtkvol.engine.lights import (  # noqa: F401  (re-exported)
    MAX_LIGHTS,
    LightRig,
    check_lights,
    key_light_direction,
)
from vtkvol.engine.opacity_source import OpacitySource
from vtkvol.engine.precompute import PrecomputeRunner, no_collection
from vtkvol.engine.preintegration import PreIntegrator
from vtkvol.engine.shader_builder import ShaderBuilder, source_observer
from vtkvol.engine.smart import SmartStandIn, check_mapper, input_problem, take_over
from vtkvol.engine.technique import (  # noqa: F401  (old import path)
    Changes,
    LightSpec,
    Technique,
    run_steps,
    scale_steps,
    technique_class,
    warn_inert,
)
from vtkvol.engine.technique_host import ServedTechniqueHost
from vtkvol.model.params import Invalidates
from vtkvol.model.scene import MULTICHANNEL_LIGHTINGS, Light
from vtkvol.model.techniques import TechniqueSpec

logger = logging.getLogger(__name__)


class Illuminator(ServedTechniqueHost):
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
        #: The services this host owns (plain classes; see docs/architecture.md).
        self.shader_builder = ShaderBuilder(self)  # records the user's shading flags
        self._replacements = self.shader_builder.replacements
        # Refused at the call rather than at the first frame: every shaded build replaces
        # VTK's lighting exit, so a user replacement there that drops the tag never composes.
        self._replacements.compose({key: "" for key in _REPLACED_OUTRIGHT})
        self.light_rig = LightRig(volume, renderer, lights)
        self._unsupported: str | None = None
        self._check_input(raise_error=True)
        self._values: dict[str, dict[str, Any]] = {}
        self._inert_warned: set[tuple[str, str]] = set()  # (method, parameter) warned about
        self._technique_cls: type[Technique] = technique_class(method)
        self._technique: Technique | None = None
        self._detach_requested = False
        self.changes = ChangeTracker(self)
        self._weights: np.ndarray | None = None  # (3, W) or None for identity
        self._weights_version = 0
        self.bindings = Bindings(self.shader_property)
        #: The bindings' table (uniform → (texture, sampler)); tests and diagnostics read it.
        self._textures = self.bindings.textures
        self.opacity = OpacitySource(self)
        self.empty_space = EmptySpaceSkipper(self)
        self._preintegrate = False  # RenderSettings.preintegration (engine/preintegration.py)
        self.preintegration = PreIntegrator(self)
        self._adaptive = False  # RenderSettings.adaptive_sampling (engine/adaptive_sampling.py)
        self.adaptive_sampling = AdaptiveSampler(self)
        self.exposure_control = ExposureControl(self.bindings)
        self.precompute_runner = PrecomputeRunner(self)
        self._closed = False
        self._albedo = 1.0
        self._phase_g = 0.0
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
        self._precomputed_ms = 0.0  # precompute()'s work since the last frame
        self.set_parameters(**(parameters or {}))
        #: The GPU mapper rendering in place of the user's vtkSmartVolumeMapper, if any; taken
        #: over only now that nothing of the call can be refused any more.
        self._stand_in: SmartStandIn | None = take_over(volume, mapper)
        mapper = volume.GetMapper()
        # Illumination lives in VTK's computeLighting(): the surface model needs VTK's shaded
        # variant (gradients; PyVista's add_volume leaves shading off), the medium model the
        # unshaded one (no gradient is computed). The user's setting is restored on release().
        self._apply_shade()
        self._start_tag = renderer.AddObserver(vtk.vtkCommand.StartEvent, self._on_start)
        self._error_tag = mapper.AddObserver(vtk.vtkCommand.ErrorEvent, self._on_mapper_error)
        # Keep a reference: VTK holds the observer weakly.
        self._capture = source_observer(self._on_built_source)
        self._shader_tag = mapper.AddObserver(vtk.vtkCommand.UpdateShaderEvent, self._capture)
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
            check_lights(list(lights))
        if multichannel_lighting is not None:
            check_multichannel_lighting(multichannel_lighting)
        cls = technique_class(method)
        cls.SPEC.validate({**self._values.get(cls.NAME, cls.defaults()), **(parameters or {})})
        self.set_method(method, parameters)
        if follow:
            self.light_rig.follow()
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
            self.changes.restart()
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
        self.changes.pending.parameters |= changed
        self.changes.pending.invalidates |= spec.invalidations(changed)

    @property
    def lights(self) -> list[Light]:
        return list(self.light_rig.lights)

    def set_lights(self, lights: Sequence[Light]) -> None:
        """Replace the lights (world space). Techniques are told whether the geometry changed
        (``Changes.lights``) or only colours and intensities (``Changes.light_colors``)."""
        self.light_rig.set(lights)

    def _check_input(self, *, raise_error: bool) -> bool:
        """Whether the mapper's input can be illuminated (point scalars). Cell data cannot: at
        the call that is a ``ValueError``; found later (the input arrives with the pipeline's
        first update), the illuminator stands aside once with a message."""
        mapper = self.volume.GetMapper()
        if mapper.GetInputAlgorithm() is None and mapper.GetInput() is None:
            return True  # no input yet: checked again at the first frame
        try:
            message = input_problem(self.image)
        except RuntimeError:
            return True
        if message is None:
            return True
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
        self.shader_builder.clear()  # nothing of ours is built any more
        self.shader_builder.restore_shade()
        logger.error("vtkvol: %s", message)
        if self.on_error is not None:
            self.on_error(message)

    def set_material(self, *, albedo: float | None = None, phase_g: float | None = None) -> None:
        """Scattering material of the ``medium`` lighting model: single-scattering ``albedo``
        (0…1) and the Henyey–Greenstein asymmetry ``phase_g`` (−0.99…0.99; 0 = isotropic)."""
        if albedo is not None:
            if not (math.isfinite(albedo) and 0.0 <= albedo <= 1.0):
                raise ValueError(f"albedo must lie in 0…1, not {albedo!r}")
            if albedo != self._albedo:
                self._albedo = float(albedo)
                self.changes.pending.invalidates |= Invalidates.ACCUMULATION
        if phase_g is not None:
            if not (math.isfinite(phase_g) and -0.99 <= phase_g <= 0.99):
                raise ValueError(f"phase_g must lie in −0.99…0.99, not {phase_g!r}")
            if phase_g != self._phase_g:
                self._phase_g = float(phase_g)
                self.changes.pending.invalidates |= Invalidates.ACCUMULATION

    @property
    def exposure(self) -> float:
        """The factor on the shaded colour (1 = as lit)."""
        return self.exposure_control.exposure

    @property
    def fill(self) -> float:
        """Strength of the unshadowed sky fill (0…1; 0 = none)."""
        return self.exposure_control.fill

    def set_exposure(self, exposure: float | None = None, fill: float | None = None) -> None:
        """The shaded colour's ``exposure`` factor (> 0) and the sky ``fill`` strength (0…1):
        per-frame uniforms, nothing is recomputed (they apply to frames held still too)."""
        self.exposure_control.set(exposure, fill)

    def holding_still(self) -> contextlib.AbstractContextManager[None]:
        """Frames rendered inside keep what is installed: nothing is prepared, recomputed or
        refined (as between two chunks of :meth:`precompute`); per-frame uniforms set
        meanwhile (exposure, fill) still apply."""
        return self.exposure_control.holding_still()

    def lit_as_local(self) -> contextlib.AbstractContextManager[None]:
        """Frames rendered inside are held still (:meth:`holding_still`) and lit as local
        shading: every light unobstructed, no ambient occlusion, no in-scattering, exposure 1.
        The automatic exposure's reference frame (:mod:`vtkvol.engine.exposure`)."""
        return self.exposure_control.lit_as_local()

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

    def set_preintegration(self, enabled: bool) -> None:
        """Pre-integrated classification on or off (engine/preintegration.py)."""
        self._preintegrate = bool(enabled)

    def set_adaptive_sampling(self, enabled: bool) -> None:
        """Adaptive sampling on or off (engine/adaptive_sampling.py)."""
        self._adaptive = bool(enabled)

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
        self.changes.pending.opacity = True

    @property
    def closed(self) -> bool:
        """True once :meth:`release` has run (the volume has VTK's own shading again)."""
        return self._closed

    # -- precomputation outside a frame -----------------------------------------------------------
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
        return self.changes.has_pending()

    def _ensure_technique(self) -> None:
        """Release a technique whose detach was asked for, take in what changed since the last
        frame, and create the method's technique when there is none (its first preparation)."""
        if self._detach_requested and self._technique is not None:
            self._release_technique()
        self._detach_requested = False
        self.changes.detect()
        if self._technique is None:
            self._technique = self._technique_cls(self)
            self.changes.pending.first = True

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
        # A converged accumulation that a recorded change will restart (a parameter set since
        # the last frame) is not final: its flag is stale until the next frame's prepare.
        if tech.converged and self.changes.pending.reset_accumulation:
            return self.spec.has("progressive")
        return not tech.converged

    def converge(self, max_frames: int | None = None, max_seconds: float | None = None, *,
                 iterations: int | None = None) -> int:
        """:meth:`PrecomputeRunner.converge`: render until converged, ``iterations`` reached,
        ``max_frames`` rendered or ``max_seconds`` passed; returns the frames rendered."""
        return self.precompute_runner.converge(max_frames, max_seconds, iterations=iterations)

    def _apply_shade(self) -> None:
        self.shader_builder.apply_shade(
            keep_user=self._keep_local_shading and self.method == "local")

    @property
    def fragment_source(self) -> str:
        """The last fragment shader VTK built with our replacements (for tests/diagnostics)."""
        return self.shader_builder.fragment_source

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
        # Every section, replaced VTK line and technique uniform of the last build must have
        # reached the shader VTK built (a missing VTK tag or line is an error, not a silent
        # no-op; :func:`vtkvol.engine.shader_builder.verify`).
        why = self.shader_builder.built(source)
        if why is not None:
            self._fail(why)

    # -- frame ----------------------------------------------------------------------------------
    def _install_shader(self, values: Mapping[str, Any]) -> None:
        assert self._technique is not None
        self.shader_builder.install(self._technique, values)

    def _on_start(self, _renderer: Any, _event: str) -> None:
        with no_collection():
            try:
                self._start_frame()
            except shaders.ShaderConflictError as exc:
                # The user added a replacement ours cannot compose with after the call.
                self._on_draw_end()  # preparing may have given our textures units
                self._stand_aside(str(exc).removeprefix("vtkvol: "))
            finally:
                self.light_rig.frame_specs = None

    def _start_frame(self) -> None:
        if self._closed:
            return
        if self._stand_in is not None:
            self._stand_in.sync(self.renderer.GetRenderWindow())
        if self._unsupported is not None:
            return
        if not self._check_input(raise_error=False):
            return
        self.light_rig.take_renderer_lights()
        self.light_rig.frame_specs = self.light_rig.compute(self.image)
        self.render_window = self.renderer.GetRenderWindow()
        t0 = time.perf_counter()
        if self.precompute_runner.stepping or self.exposure_control.held:
            # A repaint between two chunks of precompute(): the technique is half-way, so the
            # frame keeps what was installed and bound before (changes wait for later). The
            # same for frames held still on purpose (holding_still).
            self._on_draw_end()
            return
        self._ensure_technique()
        self._upload_weights()
        self.empty_space.update()
        self.preintegration.update()
        self.adaptive_sampling.update()
        changes = self.changes.take()
        if self.precompute_runner.defers(changes):
            # Keep the previous light: no prepare, the changes wait (merged) for later;
            # per-frame uniforms (colours, strengths) still follow.
            self.changes.keep(changes)
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
            self._prepare_and_install(first_changes())
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

    # -- empty-space skipping -------------------------------------------------------------------

    def _upload_weights(self) -> None:
        self.bindings.upload_weights(self.render_window, self._weights)

    def _upload_uniforms(self, values: Mapping[str, Any]) -> None:
        medium = (self._albedo, self._phase_g) if self.spec.lighting == "medium" else None
        self.bindings.upload(self.light_specs(), medium,
                             technique_uniform_values(self._technique, values))
        self.exposure_control.upload()

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
        self.preintegration.drop()
        self.adaptive_sampling.drop()
        self.bindings.release()
        self.shader_builder.clear()
        self.shader_builder.restore_shade()
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
