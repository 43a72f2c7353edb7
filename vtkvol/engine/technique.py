"""The engine side of an illumination technique: the hooks the host calls, and loading them.

A technique is a plugin package (``vtkvol/plugins/<name>/``): its VTK-free declaration
(:class:`vtkvol.model.techniques.TechniqueSpec`, the entry point), an engine class derived from
:class:`Technique` (named by ``spec.engine``) and its GLSL in ``shaders/``. The engine class:

* sets ``SPEC`` (the declaration) and ``SHADER`` (its fragment GLSL file in ``shaders/``);
* supplies, in that file, the GLSL hooks it changes; the host's defaults stand for the rest
  (docs/architecture.md, "Technique contract")::

      float vv_light_visibility(int light, vec3 texPos, vec3 dirDS);         // 1 = unshadowed
      vec3  vv_light_transmittance_rgb(int light, vec3 texPos, vec3 dirDS);  // coloured
      float vv_ambient_visibility(vec3 texPos, vec3 normalDS);               // 1 = unoccluded
      vec3  vv_irradiance(vec3 texPos);            // in-scattered light ("medium" model)

  (``texPos`` is VTK's texture coordinate ``g_dataPos``; directions are unit vectors in
  dataset space, µm-scaled, pointing towards the light / away from the surface);
* implements the Python hooks below. The host calls every hook with the GL context current
  (from the renderer's ``StartEvent``), so techniques never make contexts current themselves.

The host owns every uniform and texture binding: a technique returns uniform values from
:meth:`Technique.uniforms` and binds textures through ``host.bind_texture``; the host removes
all of them when the technique is switched or released. A technique releases only the GL
objects it created (textures, compute programs).

Lifecycle: ``__init__`` → (``prepare`` per frame)* → ``release``.

Long precomputations may also be written as a generator, :meth:`Technique.prepare_steps`,
that yields the fraction done between chunks of work (slabs of dispatches, one light, one
pyramid level). The host then runs the chunks one by one, outside a frame, with the context
current before each (:meth:`vtkvol.engine.illuminator.Illuminator.precompute`): an
application can keep its event loop running between them, show progress and cancel. A
technique that defines only ``prepare`` runs as one chunk; one that defines ``prepare_steps``
gets a ``prepare`` that runs every chunk in a row, so synchronous callers see no difference.
"""

from __future__ import annotations

import contextlib
import importlib
import logging
import time
import warnings
from collections.abc import Generator, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol, runtime_checkable

import numpy as np

from vtkvol.engine import shaders
from vtkvol.model.params import Invalidates, Param
from vtkvol.model.techniques import TechniqueSpec, get_spec, technique_specs

if TYPE_CHECKING:
    import vtk

    from vtkvol.engine.gl import Texture3D

logger = logging.getLogger(__name__)


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


def warn_inert(spec: TechniqueSpec, method: str, names: Iterable[str],
               values: Mapping[str, Any], warned: set[tuple[str, str]]) -> None:
    """Warn (``UserWarning``, once per method and parameter, remembered in ``warned``) for each
    of ``names`` that was just changed although its ``applies_when`` is false under
    ``values``: e.g. ``softness`` while ``softness_from`` is not ``"custom"``. Such a value is
    kept (it applies once the enabling parameter is set) but changes nothing now."""
    for name in sorted(names):
        reason = spec.parameter(name).inert_reason(values)
        if reason is not None and (method, name) not in warned:
            warned.add((method, name))
            warnings.warn(f"vtkvol: {method}: {reason}", UserWarning, stacklevel=3)


@dataclass(frozen=True)
class TechniqueStats(Mapping[str, Any]):
    """A technique's counters (:meth:`Technique.stats`), for diagnostics and the benchmark.

    Typed fields for what several techniques count, ``extra`` for a technique's own (named in
    its ``stats`` docstring). A field left None does not apply to the technique (local shading
    recomputes nothing; only progressive techniques iterate). It also reads as a read-only
    mapping of the fields that apply, then ``extra`` (``stats["recomputes"]``,
    ``stats.get("bakes")``, ``dict(stats)``), which is how scripts and the bench's JSON see it.
    """

    #: Precomputations (non-progressive techniques) or restarts (progressive ones) so far.
    recomputes: int | None = None
    #: Milliseconds of the last one: GPU time when ``host.profiling``, else the wall time of
    #: issuing it (on a numpy path its whole cost); a progressive technique's last frame.
    recompute_ms: float | None = None
    #: Where the last one ran: ``"gpu"`` (compute shaders) or ``"cpu"`` (numpy).
    backend: str | None = None
    #: Bytes of every texture the technique holds (mip levels included).
    texture_bytes: int | None = None
    #: Progressive techniques: iterations accumulated since the last restart.
    iterations: int | None = None
    #: The technique's own counters (plain numbers and strings).
    extra: Mapping[str, Any] = field(default_factory=dict)

    def _items(self) -> dict[str, Any]:
        typed = {name: getattr(self, name) for name in
                 ("recomputes", "iterations", "recompute_ms", "backend", "texture_bytes")}
        return {**{k: v for k, v in typed.items() if v is not None}, **self.extra}

    def __getitem__(self, key: str) -> Any:
        return self._items()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())


@runtime_checkable
class TechniqueHost(Protocol):
    """What a technique may use of its host (:class:`vtkvol.engine.illuminator.Illuminator`
    implements it; a test can pass any object that has these members).

    Geometry is the volume's input image: ``dims`` (nx, ny, nz) in voxels, ``spacing`` in µm
    per voxel (x, y, z), ``unit_distance`` the µm per which opacities are expressed. Every call
    happens with the GL context current (from the renderer's ``StartEvent`` or
    :meth:`~vtkvol.engine.illuminator.Illuminator.precompute`)."""

    #: The render window whose context is current during the hooks (None before a frame).
    render_window: vtk.vtkRenderWindow | None
    #: Techniques time their GPU work with timer queries only while this is True.
    profiling: bool
    #: Milliseconds of progressive work a frame may hold the thread for (None: no bound, as
    #: batch rendering wants). An application sets it so that large stacks keep it alive:
    #: progressive techniques split their iterations into chunks that fit (hybrid diffusion
    #: draws a sample in z slabs) and resume them next frame.
    work_budget_ms: float | None

    @property
    def volume(self) -> vtk.vtkVolume: ...
    @property
    def image(self) -> vtk.vtkImageData: ...
    @property
    def dims(self) -> tuple[int, int, int]: ...
    @property
    def spacing(self) -> tuple[float, float, float]: ...
    @property
    def unit_distance(self) -> float: ...
    @property
    def albedo(self) -> float: ...
    @property
    def phase_g(self) -> float: ...
    @property
    def shaded(self) -> bool: ...
    @property
    def precomputing(self) -> bool: ...
    def light_specs(self) -> list[LightSpec]: ...
    def opacity_volume(self) -> np.ndarray: ...
    def opacity_volume_steps(self) -> Generator[float, None, np.ndarray]: ...
    def opacity_texture_steps(self, quantity: str = "alpha"
                              ) -> Generator[float, None, Texture3D]: ...
    def classify_2d(self, c: int, what: Literal["alpha", "rgb"] = "alpha"
                    ) -> np.ndarray | None: ...
    def bind_texture(self, uniform: str, texture: Any, sampler: str = "sampler3D") -> None: ...
    def unbind_texture(self, uniform: str) -> None: ...


class Technique:
    """Base class: a technique that needs no precomputation and no textures."""

    SPEC: ClassVar[TechniqueSpec]
    SHADER: ClassVar[str]
    # Shortcuts to the declaration (set from SPEC for every subclass).
    NAME: ClassVar[str]
    LABEL: ClassVar[str]
    PARAMETERS: ClassVar[tuple[Param, ...]]

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        spec = cls.__dict__.get("SPEC")
        if spec is not None:
            cls.NAME, cls.LABEL, cls.PARAMETERS = spec.name, spec.label, spec.parameters

    def __init__(self, host: TechniqueHost) -> None:
        self.host = host
        #: Progressive techniques: iterations accumulated since the last reset, and whether
        #: the result is final (the host stops asking for frames). Others are always done.
        self.iteration = 0
        self.converged = not self.SPEC.has("progressive")
        self._cpu_ms: dict[str, float] = {}
        self._gpu_timers: dict[str, Any] = {}

    # -- timing -------------------------------------------------------------------------------
    @contextlib.contextmanager
    def timed(self, what: str) -> Iterator[None]:
        """Time the work inside: the wall time of issuing it, always; its GPU time with a timer
        query when ``host.profiling`` is on (:meth:`elapsed_ms` reads it without waiting)."""
        timer = None
        if getattr(self.host, "profiling", False) and self.host.render_window is not None:
            from vtkvol.engine.gl import GpuTimer

            timer = GpuTimer(self.host.render_window)
            timer.begin()
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self._cpu_ms[what] = (time.perf_counter() - t0) * 1e3
            old = self._gpu_timers.pop(what, None)
            if old is not None:
                old.release()
            if timer is not None:
                timer.end()
                self._gpu_timers[what] = timer

    def elapsed_ms(self, what: str) -> float:
        """The last ``timed(what)``: GPU milliseconds when profiled and the driver has them,
        else the wall time of issuing the work (CPU paths: the whole cost)."""
        timer = self._gpu_timers.get(what)
        if timer is not None:
            gpu = timer.result_ms()
            if gpu is not None:
                return gpu
        return self._cpu_ms.get(what, 0.0)

    def _release_timers(self) -> None:
        for timer in self._gpu_timers.values():
            timer.release()
        self._gpu_timers.clear()

    # -- hooks --------------------------------------------------------------------------------
    @classmethod
    def shader_package(cls) -> str:
        """The package whose ``shaders/`` folder holds this technique's GLSL."""
        return cls.__module__.rpartition(".")[0] or cls.__module__

    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        """Compile-time constants for the GLSL (``SHADER``-invalidating parameters)."""
        return {}

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        """The technique's GLSL sections: ``SHADER`` with :meth:`shader_defines` applied."""
        return shaders.load(self.SHADER, self.shader_defines(values), package=self.shader_package())

    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        """Bring precomputed data up to date before a frame (``changes``: what changed since the
        last ``prepare``, see :class:`Changes`). A progressive
        technique runs its iterations for this frame here, restarting when
        ``changes.reset_accumulation``, and updates :attr:`iteration` and :attr:`converged`.

        A technique that implements :meth:`prepare_steps` instead gets this default: all of
        its chunks in a row."""
        if type(self).prepare_steps is not Technique.prepare_steps:
            for _fraction in self.prepare_steps(changes, values):
                pass

    def prepare_steps(self, changes: Changes, values: Mapping[str, Any]) -> Iterator[float]:
        """:meth:`prepare` in chunks: a generator that does the same work and yields the
        fraction done (0…1) after each chunk, so that the host can let an event loop run in
        between (:meth:`Illuminator.precompute`). Between two chunks the host may run other GL
        work in the same context (it makes the context current again before resuming), so a
        chunk binds what it uses itself; GPU chunks end with ``glFinish`` (:func:`finish_gl`),
        otherwise the work would only be queued and run in whatever comes next. When the host
        stops early (cancel) it closes the generator and releases the technique.

        The default runs :meth:`prepare` as one chunk."""
        self.prepare(changes, values)
        yield 1.0

    def uniforms(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Extra per-frame uniform values (numeric declared parameters are sent already)."""
        return {}

    def release(self) -> None:
        """Release the GL objects ``prepare`` created. Context is current."""

    def stats(self) -> TechniqueStats:
        """Counters for diagnostics and the benchmark (:class:`TechniqueStats`; none for a
        technique that precomputes nothing)."""
        return TechniqueStats()

    # -- verification -------------------------------------------------------------------------
    def light_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float], light: LightSpec,
        values: Mapping[str, Any],
    ) -> np.ndarray | None:
        """This technique's own CPU path for the per-voxel light visibility (0…1, [z, y, x]),
        or None when the technique has no per-voxel light volume."""
        return None

    def ambient_visibility_cpu(
        self, opacity: np.ndarray, spacing: tuple[float, float, float],
        values: Mapping[str, Any], view_directions: Sequence[Sequence[float]],
    ) -> list[np.ndarray] | None:
        """This technique's own CPU path for the ambient light's visibility 1 − strength·AO
        (0…1, ``[z, y, x]``), one volume per direction towards the viewer in
        ``view_directions`` (dataset space; the same volume for view-independent AO), or None
        when the technique does not occlude the ambient light. Auto quality's prediction
        (:mod:`vtkvol.engine.auto_quality`) compares it with the reference AO."""
        return None

    @classmethod
    def defaults(cls) -> dict[str, Any]:
        return cls.SPEC.defaults()


def finish_gl(render_window: Any) -> None:
    """Wait until the GL work issued so far has run (ends a chunk of :meth:`prepare_steps`)."""
    from vtkvol.engine.gl import gl

    gl(render_window).glFinish()


class ComputePath:
    """The GPU half of a technique that also has a numpy path: the driver ``factory(window)``
    is made on first use when the ``backend`` parameter allows it and the context runs compute
    shaders; after a failure the technique stays on numpy (warned once)."""

    def __init__(self, name: str, factory: Any) -> None:
        self.name = name
        self.factory = factory
        self.driver: Any = None
        self.failed = False

    def get(self, host: TechniqueHost, backend: str) -> Any:
        """The driver, or None for the numpy path."""
        if backend == "cpu" or self.failed:
            self.release()
            return None
        if self.driver is None:
            from vtkvol.engine.gl import GLUnavailableError, compute_supported

            window = host.render_window
            try:
                if window is None or not compute_supported(window):
                    raise GLUnavailableError("this OpenGL context has no compute shaders")
                self.driver = self.factory(window)
            except GLUnavailableError as exc:
                self.disable(exc)
        return self.driver

    def disable(self, exc: Exception) -> None:
        if not self.failed:
            logger.warning("%s: compute path unavailable, using numpy (%s)", self.name, exc)
        self.failed = True
        self.release()

    def release(self) -> None:
        if self.driver is not None:
            self.driver.release()
            self.driver = None


def technique_class(name: str | TechniqueSpec) -> type[Technique]:
    """Import the engine class of technique ``name`` (``ValueError`` lists the known names)."""
    spec = name if isinstance(name, TechniqueSpec) else get_spec(name)
    module_name, _, attr = spec.engine.partition(":")
    try:
        module = importlib.import_module(module_name)
        cls = getattr(module, attr)
    except (ImportError, AttributeError) as exc:
        raise ValueError(
            f"illumination method {spec.name!r}: its engine {spec.engine} cannot be loaded ({exc})"
        ) from exc
    if not (isinstance(cls, type) and issubclass(cls, Technique)):
        raise TypeError(f"{spec.engine} is not a vtkvol Technique")
    if getattr(cls, "SPEC", None) is not spec:
        raise TypeError(f"{spec.engine}.SPEC is not the declaration registered as {spec.name!r}")
    if spec.has("cpu_path") and cls.light_visibility_cpu is Technique.light_visibility_cpu:
        raise TypeError(f"{spec.engine} declares a CPU path but has no light_visibility_cpu")
    return cls


def installed_techniques() -> dict[str, type[Technique]]:
    """Engine classes of every declared technique whose engine part imports cleanly (a broken
    one is reported with a ``RuntimeWarning``)."""
    out: dict[str, type[Technique]] = {}
    for name, spec in technique_specs().items():
        try:
            out[name] = technique_class(spec)
        except (ValueError, TypeError) as exc:
            warnings.warn(f"vtkvol illumination plugin {name!r} is unavailable: {exc}",
                          RuntimeWarning, stacklevel=2)
    return out
