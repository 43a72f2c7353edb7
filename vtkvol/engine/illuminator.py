"""The technique host: gives any ``vtkVolume`` a vtkvol illumination technique.

This is both the engine's own mechanism and the public integration call
(:func:`vtkvol.illuminate`). It works on a volume built by :class:`VolumeScene`, by a plain VTK
script or by ``pyvista.Plotter.add_volume``: it only needs the ``vtkVolume`` (mapper must be a
``vtkOpenGLGPUVolumeRayCastMapper``) and the ``vtkRenderer`` showing it.

All GL work happens in the renderer's ``StartEvent`` (the context is current there): installing
shader replacements, creating textures, running precomputation and uploading uniforms. What
changed since the last frame is found by comparing cheap signatures (VTK modification times of
the input image, opacity functions and cropping; the volume matrix; lights; parameters), so
camera moves never trigger a recompute and transfer-function edits always do, whether they came
through vtkvol's model or from user code touching the VTK objects directly.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from vtkvol.engine import shaders
from vtkvol.engine.gl import Texture2D
from vtkvol.engine.technique import Technique, technique_class
from vtkvol.model.params import Invalidates, validate_values
from vtkvol.model.scene import Light

logger = logging.getLogger(__name__)

MAX_LIGHTS = 4
WEIGHT_TABLE_WIDTH = 256


@dataclass(frozen=True)
class LightSpec:
    """A light as techniques see it: **dataset space** (the image's own µm coordinates)."""

    kind: str  #: "directional" or "point"
    vector: tuple[float, float, float]  #: unit direction towards the light, or position (µm)
    color: tuple[float, float, float]  #: colour × intensity

    @property
    def is_point(self) -> bool:
        return self.kind == "point"


@dataclass
class Changes:
    """What changed since the technique's last ``prepare`` (merged over skipped frames)."""

    opacity: bool = False  #: data, transfer function, crop, slice weights or volume placement
    lights: bool = False
    parameters: set[str] = field(default_factory=set)
    first: bool = False  #: first frame after attach

    def any_parameter(self, params: Iterable[Any], flag: Invalidates) -> bool:
        return any(p.name in self.parameters and p.invalidates & flag for p in params)


class Illuminator:
    """Installs one illumination technique on a ``vtkVolume`` and keeps it up to date.

    Parameters
    ----------
    volume
        The ``vtkVolume`` to light (its mapper must be the OpenGL GPU ray-cast mapper).
    renderer
        The ``vtkRenderer`` that renders it.
    method
        Technique name (``vtkvol.engine.technique.available_techniques()``), e.g. ``"local"``,
        ``"shadow_volume"``, ``"cone_traced"``.
    lights
        Up to four :class:`vtkvol.model.Light` in world space. Default: one directional light.
    parameters
        Technique parameter values; missing ones take the declared defaults.
    """

    def __init__(
        self,
        volume: vtk.vtkVolume,
        renderer: vtk.vtkRenderer,
        *,
        method: str = "local",
        lights: Sequence[Light] | None = None,
        parameters: Mapping[str, Any] | None = None,
    ) -> None:
        mapper = volume.GetMapper()
        if not isinstance(mapper, vtk.vtkGPUVolumeRayCastMapper):
            raise TypeError(
                "vtkvol illumination needs a GPU ray-cast mapper "
                f"(vtkOpenGLGPUVolumeRayCastMapper), not {type(mapper).__name__}"
            )
        self.volume = volume
        self.renderer = renderer
        self.shader_property = volume.GetShaderProperty()
        self._replacements = shaders.ReplacementSet(self.shader_property)
        self._lights: list[Light] = [Light()] if lights is None else list(lights)
        self._check_lights(self._lights)
        self._values: dict[str, dict[str, Any]] = {}
        self._technique_cls: type[Technique] = technique_class(method)
        self._technique: Technique | None = None
        self._detach_requested = False
        self._changes = Changes(first=True, opacity=True, lights=True)
        self._signature: tuple | None = None
        self._weights: np.ndarray | None = None  # (3, W) or None for identity
        self._weights_version = 0
        self._weights_texture: Texture2D | None = None
        self._textures: dict[str, Any] = {}
        self._opacity_cache: tuple[tuple, np.ndarray] | None = None
        self._fragment_source = ""
        self._closed = False
        self.last_prepare_ms = 0.0
        self.render_window: vtk.vtkRenderWindow | None = None
        self.set_parameters(**(parameters or {}))
        # Illumination lives in VTK's shaded computeLighting(): switch shading on (PyVista's
        # add_volume leaves it off) and restore the user's setting on release().
        prop = volume.GetProperty()
        self._user_shade = [prop.GetShade(c) for c in range(4)]
        for c in range(4):
            prop.SetShade(c, 1)
        self._start_tag = renderer.AddObserver(vtk.vtkCommand.StartEvent, self._on_start)
        self.last_error: str | None = None
        self.on_error: Callable[[str], None] | None = None  # e.g. the app's error dialog
        self._error_tag = mapper.AddObserver(vtk.vtkCommand.ErrorEvent, self._on_mapper_error)
        self._capture = _capture_source(self)  # keep a reference: VTK holds it weakly
        self._shader_tag = volume.GetMapper().AddObserver(
            vtk.vtkCommand.UpdateShaderEvent, self._capture
        )

    # -- public state ---------------------------------------------------------------------------
    @property
    def method(self) -> str:
        return self._technique_cls.NAME

    @property
    def technique(self) -> Technique | None:
        """The attached technique instance (None until the first frame)."""
        return self._technique

    def set_method(self, method: str, parameters: Mapping[str, Any] | None = None) -> None:
        """Switch technique; its resources are released at the next frame."""
        cls = technique_class(method)
        if cls is not self._technique_cls:
            self._detach_requested = True
            self._technique_cls = cls
            self._changes = Changes(first=True, opacity=True, lights=True)
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
        current = self._values.get(self.method, self._technique_cls.defaults())
        merged = validate_values(self._technique_cls.PARAMETERS, {**current, **values})
        changed = {k for k in merged if merged[k] != current.get(k)}
        self._values[self.method] = merged
        self._changes.parameters |= changed

    @property
    def lights(self) -> list[Light]:
        return list(self._lights)

    def set_lights(self, lights: Sequence[Light]) -> None:
        lights = list(lights)
        self._check_lights(lights)
        self._lights = lights
        self._changes.lights = True

    @staticmethod
    def _check_lights(lights: Sequence[Light]) -> None:
        if len(lights) > MAX_LIGHTS:
            raise ValueError(f"at most {MAX_LIGHTS} lights are supported, not {len(lights)}")

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
        """Enabled lights converted to dataset space (through the volume's inverse matrix)."""
        inv = vtk.vtkMatrix4x4()
        vtk.vtkMatrix4x4.Invert(self.volume.GetMatrix(), inv)
        specs = []
        for light in self._lights:
            if not light.enabled or light.intensity <= 0:
                continue
            color = tuple(float(c * light.intensity) for c in light.color)
            if light.kind == "point":
                p = inv.MultiplyPoint((*light.position, 1.0))
                pos = np.array(p[:3]) / p[3]
                specs.append(LightSpec("point", tuple(float(v) for v in pos), color))
            else:
                d = np.array(inv.MultiplyPoint((*light.direction, 0.0))[:3])
                d = d / max(np.linalg.norm(d), 1e-30)
                specs.append(LightSpec("directional", tuple(float(v) for v in d), color))
        return specs

    def opacity_volume(self) -> np.ndarray:
        """Per-voxel opacity (per ``unit_distance`` µm) as the ray caster sees it.

        float32 ``[z, y, x]``: every visible component's scalar opacity function applied to its
        values and combined as independent absorbers (α = 1 − Π(1 − α_c)), then zeroed outside
        the cropping box and multiplied by the slice weights, so what is cropped away casts no
        shadow. Gradient opacity is not included. Cached until an input changes.
        """
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
        u0 = prop.GetScalarOpacityUnitDistance(0)
        transparency = np.ones((nz, ny, nx), np.float32)
        comps = range(ncomp) if independent else [ncomp - 1]
        for c in comps:
            fc = c if independent else 0
            weight = prop.GetComponentWeight(fc) if independent and ncomp > 1 else 1.0
            if weight <= 0:
                continue
            alpha = _evaluate_piecewise(prop.GetScalarOpacity(fc), values[..., c]) * weight
            uc = prop.GetScalarOpacityUnitDistance(fc)
            if uc != u0:  # express every component per the same unit distance
                alpha = 1.0 - np.power(1.0 - np.clip(alpha, 0, 1), u0 / uc)
            transparency *= 1.0 - np.clip(alpha, 0.0, 1.0)
        opacity = 1.0 - transparency
        self._apply_crop(opacity)
        if self._weights is not None:
            opacity *= _axis_weights(self._weights, (nz, ny, nx))
        opacity = np.ascontiguousarray(opacity, dtype=np.float32)
        self._opacity_cache = (key, opacity)
        return opacity

    def _apply_crop(self, opacity: np.ndarray) -> None:
        mapper = self.volume.GetMapper()
        if not mapper.GetCropping():
            return
        img = self.image
        planes = mapper.GetCroppingRegionPlanes()
        origin, spacing = img.GetOrigin(), img.GetSpacing()
        nz, ny, nx = opacity.shape
        sl = []
        for axis, n in enumerate((nx, ny, nz)):
            lo = (planes[2 * axis] - origin[axis]) / spacing[axis]
            hi = (planes[2 * axis + 1] - origin[axis]) / spacing[axis]
            sl.append((max(0, int(np.ceil(lo - 1e-6))), min(n, int(np.floor(hi + 1e-6)) + 1)))
        keep = np.zeros_like(opacity, dtype=bool)
        keep[sl[2][0] : sl[2][1], sl[1][0] : sl[1][1], sl[0][0] : sl[0][1]] = True
        opacity[~keep] = 0.0

    # -- GL helpers for techniques --------------------------------------------------------------
    def bind_texture(self, uniform: str, texture: Any, sampler: str = "sampler3D") -> None:
        """Make ``texture`` (``Texture3D``/``Texture2D``) visible to GLSL as ``uniform``.

        The texture stays active so VTK's unit manager never reuses its unit; VTK declares an
        ``int`` custom uniform holding the unit, which a post replacement retypes to a sampler
        (the robust recipe of FINDINGS §2a).
        """
        unit = texture.activate()
        self.shader_property.GetFragmentCustomUniforms().SetUniformi(uniform, unit)
        self._textures[uniform] = (texture, sampler)

    def unbind_texture(self, uniform: str) -> None:
        entry = self._textures.pop(uniform, None)
        if entry is not None:
            self.shader_property.GetFragmentCustomUniforms().RemoveUniform(uniform)

    @property
    def shaded(self) -> bool:
        """True when VTK generates its shaded ``computeLighting()`` (where our lighting hooks in):
        shading on for a component and a composite or isosurface blend. MIP, MinIP, average and
        additive blends, and unshaded composite, show no illumination."""
        prop = self.volume.GetProperty()
        blend = self.volume.GetMapper().GetBlendMode()
        shading_blends = (vtk.vtkVolumeMapper.COMPOSITE_BLEND, vtk.vtkVolumeMapper.ISOSURFACE_BLEND)
        scalars = self.image.GetPointData().GetScalars()
        ncomp = scalars.GetNumberOfComponents() if scalars is not None else 1
        # VTK generates the shaded code when any *used* component is shaded (component 0 for
        # dependent components).
        used = range(ncomp) if prop.GetIndependentComponents() else range(1)
        return blend in shading_blends and any(prop.GetShade(c) for c in used)

    @property
    def fragment_source(self) -> str:
        """The last fragment shader VTK built with our replacements (for tests/diagnostics)."""
        return self._fragment_source

    # -- frame ----------------------------------------------------------------------------------
    def _on_mapper_error(self, _mapper: Any, _event: str, *_args: Any) -> None:
        # The mapper reports "Shader failed to compile" (the GLSL log goes to VTK's output
        # window). A technique whose shader does not build on this GPU/driver must not leave
        # the view black: fall back to local shading at the next frame and tell the user.
        if self.method == "local":
            return
        failed = self.method
        self.last_error = (
            f"The {self._technique_cls.LABEL!r} illumination could not be compiled by this "
            "OpenGL driver; showing local shading instead. The driver's message is in the log."
        )
        self.set_method("local")
        if self.on_error is not None:
            self.on_error(self.last_error)
        logger.error("illumination %s failed to compile; fell back to local shading", failed)

    def _on_start(self, _renderer: Any, _event: str) -> None:
        if self._closed:
            return
        self.render_window = self.renderer.GetRenderWindow()
        t0 = time.perf_counter()
        if self._detach_requested and self._technique is not None:
            self._technique.release()
            self._technique = None
        self._detach_requested = False
        signature = self._opacity_signature()
        if signature != self._signature:
            self._signature = signature
            self._changes.opacity = True
        values = self.parameters
        first_attach = self._technique is None
        if first_attach:
            self._technique = self._technique_cls(self)
        self._upload_weights()
        changes, self._changes = self._changes, Changes()
        changes.first = changes.first or first_attach
        self._technique.prepare(changes, values)  # type: ignore[union-attr]
        # After prepare: textures bound there must be retyped to samplers in this very build.
        self._install_shader(values)
        self._upload_uniforms(values)
        # Keep our textures bound to their units (another pass may have re-bound units).
        fu = self.shader_property.GetFragmentCustomUniforms()
        for name, (texture, _sampler) in self._textures.items():
            fu.SetUniformi(name, texture.activate())
        self.last_prepare_ms = (time.perf_counter() - t0) * 1e3

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
        sections += tech.sections(values)
        if self.shaded:
            sections += shaders.load("host_lighting.glsl")
        replacements = shaders.compose(sections)
        for name, (_texture, sampler) in self._textures.items():
            replacements[(f"uniform int {name};", "post")] = f"uniform {sampler} {name};"
        self._replacements.install(replacements)

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

    def _upload_uniforms(self, values: Mapping[str, Any]) -> None:
        fu = self.shader_property.GetFragmentCustomUniforms()
        specs = self.light_specs()
        packed = np.zeros(8 * MAX_LIGHTS, np.float32)
        for i, spec in enumerate(specs):
            packed[8 * i : 8 * i + 3] = spec.vector
            packed[8 * i + 3] = 1.0 if spec.is_point else 0.0
            packed[8 * i + 4 : 8 * i + 7] = spec.color
        fu.SetUniformi("vv_numLights", len(specs))
        fu.SetUniform1fv("vv_lights", len(packed), packed.tolist())
        tech = self._technique
        assert tech is not None
        for p in tech.PARAMETERS:
            if not p.uniform or p.kind == "choice":
                continue
            name = f"vv_{tech.NAME}_{p.name}"
            value = values[p.name]
            if p.kind in ("int", "bool"):
                fu.SetUniformi(name, int(value))
            else:
                fu.SetUniformf(name, float(value))
        for name, value in tech.uniforms(values).items():
            _set_uniform(fu, name, value)

    # -- signatures -----------------------------------------------------------------------------
    def _opacity_signature(self) -> tuple:
        mapper = self.volume.GetMapper()
        prop = self.volume.GetProperty()
        img = self.image
        ncomp = img.GetPointData().GetScalars().GetNumberOfComponents() if img else 0
        funcs = tuple(prop.GetScalarOpacity(c).GetMTime() for c in range(max(1, ncomp)))
        weights = tuple(prop.GetComponentWeight(c) for c in range(max(1, ncomp)))
        units = tuple(prop.GetScalarOpacityUnitDistance(c) for c in range(max(1, ncomp)))
        matrix = self.volume.GetMatrix()
        return (
            img.GetMTime(),
            funcs,
            weights,
            units,
            bool(prop.GetIndependentComponents()),
            bool(mapper.GetCropping()),
            tuple(mapper.GetCroppingRegionPlanes()),
            tuple(matrix.GetElement(i, j) for i in range(4) for j in range(4)),
            self._weights_version,
        )

    # -- teardown -------------------------------------------------------------------------------
    def release(self) -> None:
        """Remove everything this illuminator added (replacements, uniforms, textures,
        observers). Call before the render window is finalised; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        if self.render_window is not None:  # GL resources exist only after a first frame
            self.render_window.MakeCurrent()
        if self._technique is not None:
            self._technique.release()
            self._technique = None
        if self._weights_texture is not None:
            self._weights_texture.release()
            self._weights_texture = None
        fu = self.shader_property.GetFragmentCustomUniforms()
        for name in list(self._textures):
            self.unbind_texture(name)
        for name in ("vv_numLights", "vv_lights", "vv_sliceWeightsWidth"):
            fu.RemoveUniform(name)
        for p in self._technique_cls.PARAMETERS:
            fu.RemoveUniform(f"vv_{self._technique_cls.NAME}_{p.name}")
        self._replacements.clear()
        prop = self.volume.GetProperty()
        for c, shade in enumerate(self._user_shade):
            prop.SetShade(c, shade)
        self.renderer.RemoveObserver(self._start_tag)
        self.volume.GetMapper().RemoveObserver(self._shader_tag)
        self.volume.GetMapper().RemoveObserver(self._error_tag)


def _capture_source(illuminator: Illuminator) -> Callable[..., None]:
    """Observer for UpdateShaderEvent, whose call data is the bound vtkShaderProgram. It does not
    fire on the frame a program is (re)built (FINDINGS §1), only on the frames after."""

    @vtk.calldata_type(vtk.VTK_OBJECT)
    def capture(_mapper: Any, _event: str, program: Any = None) -> None:
        if program is not None:
            illuminator._fragment_source = program.GetFragmentShader().GetSource()

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


def _axis_weights(weights: np.ndarray, shape_zyx: tuple[int, int, int]) -> np.ndarray:
    """Outer product wZ(z)·wY(y)·wX(x) sampled at voxel centres; shape ``shape_zyx``."""
    nz, ny, nx = shape_zyx
    width = weights.shape[1]
    grid = np.linspace(0.0, 1.0, width)

    def sample(row: np.ndarray, n: int) -> np.ndarray:
        return np.interp(np.linspace(0.0, 1.0, n), grid, row).astype(np.float32)

    wx, wy, wz = (sample(weights[i], n) for i, n in enumerate((nx, ny, nz)))
    return wz[:, None, None] * wy[None, :, None] * wx[None, None, :]
