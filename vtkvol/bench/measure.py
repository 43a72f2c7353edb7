"""GL side of the benchmark: offscreen rigs, frame and recompute timing, image grabs, checks.

Two offscreen windows live for a whole run and are reused for every scene, so each shader
variant is compiled once per run (VTK's shader cache is per context):

* :class:`Rig`: one ``vtkVolume`` lit by an :class:`~vtkvol.engine.illuminator.Illuminator`
  whose technique is switched per setting (the benchmark's own ``bench_reference`` included);
* :class:`VtkScatteringRig`: a plain VTK volume with a scene light and VTK's built-in
  volumetric scattering (``SetVolumetricScatteringBlending``), no vtkvol code at all.

Timing (per configuration): warm-up frames (shader build, uploads, precomputation), then N
frames each after a 2° camera azimuth step, each ``Render()`` followed by ``WaitForCompletion()``
(glFinish) so the GPU work is inside the measured interval. Recompute timing forces the
precomputation by moving the light a little (``set_lights``) and by ``invalidate()`` (as a
transfer-function edit would), and reads the technique's ``stats()["recompute_ms"]`` (GPU time
from a timer query: the rig turns ``Illuminator.profiling`` on).
"""

from __future__ import annotations

import math
import platform
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import vtk

from vtkvol.bench.scenes import Scene
from vtkvol.engine.gl import gl
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import front_view, grab, image_from_array, simple_volume_scene
from vtkvol.model import Light

#: Camera azimuth step between timed frames (degrees): the view changes, the lighting does not.
AZIMUTH_STEP = 2.0


class VtkErrors:
    """Captures VTK's error and warning text (shader compile and link failures) while active.

    VTK reports a failed shader build through its output window and then draws nothing; the
    benchmark installs a string output window so every configuration can say whether its
    shader built. VTK's logger would also print the same text to stderr, through the progress
    bar; it is muted while active (the text is kept in the records instead).
    """

    def __init__(self) -> None:
        self._window = vtk.vtkStringOutputWindow()
        self._previous: vtk.vtkOutputWindow | None = None
        self._verbosity: int | None = None
        self._seen = 0

    def __enter__(self) -> VtkErrors:
        self._previous = vtk.vtkOutputWindow.GetInstance()
        vtk.vtkOutputWindow.SetInstance(self._window)
        self._verbosity = vtk.vtkLogger.GetCurrentVerbosityCutoff()
        vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._previous is not None:
            vtk.vtkOutputWindow.SetInstance(self._previous)
        if self._verbosity is not None:
            vtk.vtkLogger.SetStderrVerbosity(self._verbosity)

    def new_errors(self) -> str:
        """Error text reported since the last call ("" when none); warnings are ignored unless
        they mention a shader."""
        text = self._window.GetOutput() or ""
        fresh, self._seen = text[self._seen:], len(text)
        lines = [ln for ln in fresh.splitlines()
                 if "ERROR" in ln.upper() or "shader" in ln.lower()]
        return "\n".join(lines)


def _frame_ms(rw: vtk.vtkRenderWindow) -> tuple[float, float]:
    """Wall and process CPU time (ms) of one finished frame. The CPU time counts every thread
    of this process, so on llvmpipe (which rasterises in our own threads) it measures the
    rendering work itself, largely independent of other load on a shared machine."""
    c0 = time.process_time()
    t0 = time.perf_counter()
    rw.Render()
    rw.WaitForCompletion()
    return (time.perf_counter() - t0) * 1e3, (time.process_time() - c0) * 1e3


def set_view(renderer: vtk.vtkRenderer, scene: Scene) -> None:
    """The scene's comparison view: its orbit (:func:`front_view`), projection and view
    angle."""
    cam = renderer.GetActiveCamera()
    cam.SetParallelProjection(int(scene.parallel))
    front_view(renderer, scene.azimuth, scene.elevation)  # frames at VTK's 30° view angle
    if not scene.parallel and scene.view_angle != cam.GetViewAngle():
        # The same framing through a wider (or narrower) lens: the distance to the focal point
        # scaled by tan(old/2)/tan(new/2) (ResetCamera itself puts the view angle back to 30°).
        old = math.radians(cam.GetViewAngle()) / 2
        cam.SetViewAngle(scene.view_angle)
        cam.Dolly(math.tan(math.radians(scene.view_angle) / 2) / math.tan(old))
        renderer.ResetCameraClippingRange()


def flat_spread(image: np.ndarray, region: float) -> float:
    """Spread of the brightness over the centred square of side ``region`` (fraction of the
    shorter image side): (95th − 5th percentile) / median of the mean of R, G and B, 0 for a
    flat image (0 also where the square is black: nothing to compare)."""
    h, w = image.shape[:2]
    half = max(1, round(region * min(h, w) / 2))
    cy, cx = h // 2, w // 2
    patch = image[cy - half: cy + half, cx - half: cx + half, :3].astype(np.float64).mean(axis=2)
    mid = float(np.median(patch))
    if mid <= 0.0:
        return 0.0
    lo, hi = np.percentile(patch, [5, 95])
    return float((hi - lo) / mid)


#: Largest :func:`flat_spread` a deterministic technique passes a flat stability case with.
#: Measured on llvmpipe (48³ slab views, 96² images): local 0.000, cone tracing ≤ 0.010, the
#: diffusion methods ≤ 0.012, shadow volume ≤ 0.010 and translucency ≤ 0.005 since the lookup
#: reads the near end of the sample's segment; before that 0.024–0.043 and 0.020–0.032
#: (issue 26). VTK's scattering (0.04–0.06) and progressive methods (path tracing's noise,
#: about 0.3) are recorded, not checked.
FLAT_SPREAD_LIMIT = 0.015


def _load_volume(volume: vtk.vtkVolume, scene: Scene) -> None:
    """Put ``scene``'s data, transfer function, unit distance and sample distance on a volume
    made by :func:`simple_volume_scene` (sample distance ½ of the smallest voxel edge)."""
    mapper = volume.GetMapper()
    mapper.SetInputData(image_from_array(scene.data, scene.spacing))
    mapper.SetSampleDistance(0.5 * min(scene.spacing))
    prop = volume.GetProperty()
    prop.SetScalarOpacityUnitDistance(scene.unit_distance)
    otf = prop.GetScalarOpacity()
    otf.RemoveAllPoints()
    for value, alpha in scene.opacity_points:
        otf.AddPoint(float(value), float(alpha))
    ctf = prop.GetRGBTransferFunction()
    ctf.RemoveAllPoints()
    lo = min(0.0, float(scene.opacity_points[0][0]))
    hi = max(1.0, float(scene.opacity_points[-1][0]))
    ctf.AddRGBPoint(lo, 1.0, 1.0, 1.0)
    ctf.AddRGBPoint(hi, 1.0, 1.0, 1.0)


@dataclass
class FrameTiming:
    """Frame times in ms of the timed frames (warm-up excluded): wall clock (``samples``) and
    process CPU time (``cpu_samples``)."""

    samples: list[float] = field(default_factory=list)
    cpu_samples: list[float] = field(default_factory=list)

    def add(self, wall_cpu: tuple[float, float]) -> None:
        self.samples.append(wall_cpu[0])
        self.cpu_samples.append(wall_cpu[1])

    @property
    def cpu_median(self) -> float:
        return float(np.median(self.cpu_samples)) if self.cpu_samples else math.nan

    @property
    def median(self) -> float:
        return float(np.median(self.samples)) if self.samples else math.nan

    @property
    def iqr(self) -> float:
        if len(self.samples) < 2:
            return 0.0
        q1, q3 = np.percentile(self.samples, [25, 75])
        return float(q3 - q1)


class Rig:
    """An offscreen window with one volume and one :class:`Illuminator`, reused across scenes."""

    def __init__(self, image_size: int) -> None:
        self.rw, self.renderer, self.volume = simple_volume_scene(
            np.zeros((4, 4, 4), np.float32), size=(image_size, image_size))
        self.illuminator = Illuminator(self.volume, self.renderer, method="local")
        self.scene: Scene | None = None

    def load(self, scene: Scene) -> None:
        """Show ``scene`` (data, transfer function, lights, view)."""
        _load_volume(self.volume, scene)
        self.illuminator.set_lights([Light(direction=d, size=scene.light_size_deg,
                                           intensity=scene.light_intensity)
                                     for d in scene.lights])
        self.illuminator.set_material(albedo=scene.albedo, phase_g=scene.phase_g)
        self.scene = scene
        self.reset_view()

    def reset_view(self) -> None:
        assert self.scene is not None
        set_view(self.renderer, self.scene)

    def set_method(self, method: str, values: Mapping[str, Any]) -> None:
        """Switch to technique ``method`` with exactly ``values`` (defaults + overrides)."""
        self.illuminator.set_method(method)
        self.illuminator.set_parameters(**dict(values))

    def refine(self, max_seconds: float) -> tuple[int, float]:
        """Run a progressive technique until it has converged or ``max_seconds`` have passed
        (nothing for the others): ``(its iteration count, seconds spent)``. The bench measures
        what users see once the view has stopped refining."""
        ill = self.illuminator
        t0 = time.perf_counter()
        if ill.wants_frame:
            self.reset_view()
            ill.converge(max_seconds=max_seconds)
        tech = ill.technique
        return (int(tech.iteration) if tech is not None else 0), time.perf_counter() - t0

    def image(self) -> np.ndarray:
        """The comparison image at the scene's view, ``(h, w, 3)`` uint8."""
        self.reset_view()
        return grab(self.rw)

    def time_frames(self, warmup: int, frames: int) -> FrameTiming:
        """Warm-up frames, then ``frames`` timed frames with a camera azimuth step each."""
        self.reset_view()
        for _ in range(warmup):
            _frame_ms(self.rw)
        timing = FrameTiming()
        cam = self.renderer.GetActiveCamera()
        for _ in range(frames):
            cam.Azimuth(AZIMUTH_STEP)
            timing.add(_frame_ms(self.rw))
        self.reset_view()
        return timing

    def recompute_times(self, repeats: int, *, light: bool = True,
                        opacity: bool = True) -> tuple[list[float], list[float]]:
        """``(after a light move, after an opacity change)`` recompute times in ms, as reported
        by the technique (empty lists: the technique did not recompute for that change, or
        that trigger was not asked for).

        One frame per trigger and repeat, with the volume hidden (the technique's ``prepare``
        still runs in the renderer's StartEvent, the ray casting is skipped): the light moved a
        few degrees about z; then the light restored together with an opacity invalidation (as
        a transfer-function edit), so the technique ends on its original light.
        """
        ill = self.illuminator
        tech = ill.technique
        if tech is None or "recomputes" not in tech.stats():
            return [], []
        ill.profiling = True
        base = ill.lights
        light_ms: list[float] = []
        tf_ms: list[float] = []
        for i in range(repeats):
            angle = math.radians(3.0 * (i + 1) * (-1) ** i)  # small moves about z
            c, s = math.cos(angle), math.sin(angle)
            moved = [
                lt.model_copy(update={"direction": (
                    c * lt.direction[0] - s * lt.direction[1],
                    s * lt.direction[0] + c * lt.direction[1], lt.direction[2])})
                for lt in base
            ]
            steps = []
            if light:
                steps.append((moved, light_ms, False))
            if opacity or light:  # restoring the light is a frame anyway: measure it as TF
                steps.append((base, tf_ms, opacity))
            for lights, out, invalidate in steps:
                ill.set_lights(lights)
                if invalidate:
                    ill.invalidate()
                count = int(tech.stats().get("recomputes", 0))
                # The precomputation runs in the renderer's StartEvent whether or not the
                # volume is drawn; hiding it makes these frames cost the recompute alone.
                self.volume.VisibilityOff()
                try:
                    self.rw.Render()
                finally:
                    self.volume.VisibilityOn()
                gl(self.rw).glFinish()  # the bench may wait: the timer's result is then ready
                stats = tech.stats()
                if ill.technique is tech and int(stats.get("recomputes", 0)) > count:
                    ms = float(stats.get("recompute_ms", math.nan))
                    if math.isfinite(ms):  # a technique that counts but does not time
                        out.append(ms)
        return light_ms, tf_ms if opacity else []

    def gpu_volumes(self) -> dict[str, np.ndarray]:
        """Level 0 of every 3D texture bound for the active technique (read back), by the
        uniform name its shader reads it under."""
        from vtkvol.engine.gl import Texture3D

        out: dict[str, np.ndarray] = {}
        self.rw.MakeCurrent()
        for name, texture in self.illuminator.bound_textures().items():
            if isinstance(texture, Texture3D) and texture.tex is not None:
                out[name] = texture.download(0)
        return out

    def shader_installed(self) -> bool:
        """True when the program VTK last bound (the ray caster's: nothing else is drawn)
        contains the active technique's code.

        Read from the shader cache rather than ``Illuminator.fragment_source``: that one is
        captured in ``UpdateShaderEvent``, which does not fire on frames where VTK re-selects
        the program, and it does so on every frame the camera moves (the automatic headlight
        follows the camera), i.e. on every timed frame here.
        """
        tech = self.illuminator.technique
        if tech is None:
            return False
        program = self.rw.GetShaderCache().GetLastShaderBound()
        source = program.GetFragmentShader().GetSource() if program is not None else ""
        source = source or self.illuminator.fragment_source
        # A technique that defines no hook (local shading) is the host's lighting alone.
        own = {s.origin for s in tech.sections(self.illuminator.parameters)}
        expected = own or {"host_lighting.glsl", "host_medium.glsl"}
        return any(f"vtkvol<{name}>" in source for name in expected)

    def close(self) -> None:
        self.rw.MakeCurrent()
        self.illuminator.release()
        self.rw.Finalize()


class VtkScatteringRig:
    """VTK's own volumetric scattering: a plain VTK volume lit by scene lights (no vtkvol)."""

    def __init__(self, image_size: int) -> None:
        self.rw, self.renderer, self.volume = simple_volume_scene(
            np.zeros((4, 4, 4), np.float32), size=(image_size, image_size))
        self.renderer.AutomaticLightCreationOff()
        self.scene: Scene | None = None

    def load(self, scene: Scene) -> None:
        _load_volume(self.volume, scene)
        self.renderer.RemoveAllLights()
        nz, ny, nx = scene.shape
        centre = np.array([(nx - 1) * scene.spacing[0], (ny - 1) * scene.spacing[1],
                           (nz - 1) * scene.spacing[2]]) / 2
        reach = float(np.linalg.norm(centre)) * 4 + 1.0
        for d in scene.lights:
            u = np.asarray(d, dtype=np.float64) / np.linalg.norm(d)
            light = vtk.vtkLight()
            light.SetLightTypeToSceneLight()
            light.SetPositional(False)
            light.SetFocalPoint(*centre)
            light.SetPosition(*(centre + reach * u))  # directional: light travels pos → focal
            light.SetIntensity(1.0)
            light.SetColor(1.0, 1.0, 1.0)
            light.SetAmbientColor(1.0, 1.0, 1.0)
            self.renderer.AddLight(light)
        self.scene = scene
        self.reset_view()

    def reset_view(self) -> None:
        assert self.scene is not None
        set_view(self.renderer, self.scene)

    def set_setting(self, blending: float, reach: float) -> None:
        """``SetVolumetricScatteringBlending(blending)`` (0 gradient shading … 2 volumetric) and
        ``SetGlobalIlluminationReach(reach)`` (0…1 of the volume's extent)."""
        mapper = self.volume.GetMapper()
        mapper.SetVolumetricScatteringBlending(float(blending))
        mapper.SetGlobalIlluminationReach(float(reach))

    def image(self) -> np.ndarray:
        self.reset_view()
        return grab(self.rw)

    def time_frames(self, warmup: int, frames: int) -> FrameTiming:
        self.reset_view()
        for _ in range(warmup):
            _frame_ms(self.rw)
        timing = FrameTiming()
        cam = self.renderer.GetActiveCamera()
        for _ in range(frames):
            cam.Azimuth(AZIMUTH_STEP)
            timing.add(_frame_ms(self.rw))
        self.reset_view()
        return timing

    def close(self) -> None:
        self.rw.Finalize()


def machine_info(rw: vtk.vtkRenderWindow) -> dict[str, Any]:
    """Renderer string (GL_RENDERER), GL version, VTK version, CPU, cores, OS of this run."""
    import os

    renderer = version = vendor = "unknown"
    try:
        from vtkvol.engine.gl import gl

        rw.MakeCurrent()
        GL = gl(rw)
        renderer = GL.glGetString(GL.GL_RENDERER).decode()
        version = GL.glGetString(GL.GL_VERSION).decode()
        vendor = GL.glGetString(GL.GL_VENDOR).decode()
    except Exception:  # no PyOpenGL: fall back to VTK's capability report
        report = rw.ReportCapabilities() or ""
        for line in report.splitlines():
            key, _, value = line.partition(":")
            if "renderer string" in key.lower():
                renderer = value.strip()
            elif "version string" in key.lower() and "OpenGL" in key:
                version = value.strip()
            elif "vendor string" in key.lower() and "OpenGL" in key:
                vendor = value.strip()
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "renderer": renderer,
        "gl_version": version,
        "gl_vendor": vendor,
        "gpu": "llvmpipe" not in renderer.lower() and "softpipe" not in renderer.lower(),
        "vtk_version": vtk.vtkVersion.GetVTKVersion(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "cpu": cpu or platform.machine(),
        "cores": os.cpu_count() or 0,
        "os": platform.platform(),
    }


def image_ok(image: np.ndarray, reference: np.ndarray | None = None) -> bool:
    """A rendered image is plausible: uint8-ranged, and not blank where the reference is not
    (a failed shader draws nothing). NaNs cannot survive an 8-bit framebuffer, so NaN checks
    are made on the illumination volumes instead (:func:`volume_checks`)."""
    if image.dtype != np.uint8 or image.ndim != 3:
        return False
    return not (reference is not None and reference.max() > 8 and image.max() == 0)


def volume_checks(volumes: Mapping[str, np.ndarray], unit_range: Sequence[str] = ()) -> str:
    """"" when every volume is finite and ≥ 0 (and ≤ 1 for the names in ``unit_range``),
    else a description of the first violation."""
    for name, vol in volumes.items():
        if not np.isfinite(vol).all():
            return f"{name}: {int((~np.isfinite(vol)).sum())} non-finite voxels"
        if vol.size and vol.min() < -1e-6:
            return f"{name}: negative values (min {vol.min():.3g})"
        if name in unit_range and vol.size and vol.max() > 1 + 1e-5:
            return f"{name}: values above 1 (max {vol.max():.3g})"
    return ""
