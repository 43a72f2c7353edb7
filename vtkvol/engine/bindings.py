"""Bindings: the host's texture units and fragment-shader uniforms.

One service of the technique host, the analogue of VTK's ``Set*ShaderParameters``: textures a
technique (or the host) binds are made visible to GLSL as samplers and hold a texture unit only
while the volume draws; lights, the medium's material, the slice weights and the technique's
uniforms are uploaded as the property's fragment custom uniforms. Everything bound or set for a
technique is removed when it is switched or released, so nothing of it survives a switch.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import vtk

from vtkvol.engine.gl import Texture2D
from vtkvol.engine.lights import MAX_LIGHTS
from vtkvol.engine.technique import LightSpec

#: Floats per light in the ``vv_lights`` uniform array (layout in host_prelude.glsl).
LIGHT_STRIDE = 12
#: Uniforms and textures the host sets for itself (not for the technique).
MEDIUM_UNIFORMS = ("vv_albedo", "vv_phaseG")
HOST_TEXTURES = frozenset({"vv_sliceWeights", "vv_essOccupancy"})
#: Host lighting's exposure, sky fill and local-shading probe switch (both lighting models).
EXPOSURE_UNIFORMS = ("vv_exposure", "vv_fill", "vv_exposureProbe")
HOST_UNIFORMS = ("vv_numLights", "vv_lights", "vv_sliceWeightsWidth", *EXPOSURE_UNIFORMS,
                 *MEDIUM_UNIFORMS)


class Bindings:
    """Texture bindings and custom uniforms on one volume's shader property."""

    def __init__(self, shader_property: vtk.vtkShaderProperty) -> None:
        self._fu = shader_property.GetFragmentCustomUniforms()
        #: GLSL uniform name → (texture, GLSL sampler type), host's and technique's.
        self.textures: dict[str, Any] = {}
        #: Custom uniforms set for the technique (removed at a switch).
        self.uniforms: set[str] = set()
        self._weights_texture: Texture2D | None = None

    def bind_texture(self, uniform: str, texture: Any, sampler: str = "sampler3D") -> None:
        """Make ``texture`` (``Texture3D``/``Texture2D``) visible to GLSL as ``uniform``.

        The texture stays active so VTK's unit manager never reuses its unit; VTK declares an
        ``int`` custom uniform holding the unit, which a post replacement retypes to a sampler
        (docs/architecture.md, "Engine"). The binding belongs to the host: it is removed
        when the technique is switched or released.
        """
        unit = texture.activate()
        self._fu.SetUniformi(uniform, unit)
        self.textures[uniform] = (texture, sampler)

    def unbind_texture(self, uniform: str) -> None:
        entry = self.textures.pop(uniform, None)
        if entry is not None:
            self._fu.RemoveUniform(uniform)

    def bound_textures(self) -> dict[str, Any]:
        """The textures bound for the active technique, by GLSL uniform name (what its shader
        reads; diagnostics and the benchmark's checks). The host's own are left out."""
        return {name: texture for name, (texture, _sampler) in self.textures.items()
                if name not in HOST_TEXTURES}

    def draw_start(self) -> None:
        """Just before the volume draws: our textures take units, the samplers name them."""
        for name, (texture, _sampler) in self.textures.items():
            if texture.tex is not None:
                self._fu.SetUniformi(name, texture.activate())

    def draw_end(self) -> None:
        """After the volume drew (and after preparing): give the units back."""
        for texture, _sampler in self.textures.values():
            if texture.tex is not None:
                texture.tex.Deactivate()

    def upload_weights(self, window: vtk.vtkRenderWindow | None,
                       weights: np.ndarray | None) -> None:
        """The slice weights ``(3, W)`` (x, y, z rows over the normalised axis) as the 2-D
        texture ``vv_sliceWeights``, or no texture for None (identity)."""
        if weights is None:
            if self._weights_texture is not None:
                self.unbind_texture("vv_sliceWeights")
                self._weights_texture.release()
                self._weights_texture = None
            return
        if self._weights_texture is None or self._weights_texture.shape != weights.shape:
            if self._weights_texture is not None:
                self._weights_texture.release()
            self._weights_texture = Texture2D(window, weights)
        else:
            self._weights_texture.upload(weights)
        self.bind_texture("vv_sliceWeights", self._weights_texture, "sampler2D")
        self._fu.SetUniformf("vv_sliceWeightsWidth", float(weights.shape[1]))

    def upload(self, specs: Sequence[LightSpec], medium: tuple[float, float] | None,
               technique_values: Mapping[str, Any]) -> None:
        """Lights (``vv_numLights``, ``vv_lights``), the medium's ``(albedo, phase g)`` (None
        for a surface technique: removed) and the technique's uniforms."""
        packed = np.zeros(LIGHT_STRIDE * MAX_LIGHTS, np.float32)
        for i, spec in enumerate(specs):
            base = LIGHT_STRIDE * i
            packed[base : base + 3] = spec.vector
            packed[base + 3] = 1.0 if spec.is_point else 0.0
            packed[base + 4 : base + 7] = spec.color
            packed[base + 7] = spec.size
            packed[base + 8] = spec.falloff_distance
        fu = self._fu
        fu.SetUniformi("vv_numLights", len(specs))
        fu.SetUniform1fv("vv_lights", len(packed), packed.tolist())
        if medium is not None:
            fu.SetUniformf("vv_albedo", medium[0])
            fu.SetUniformf("vv_phaseG", medium[1])
        else:
            for name in MEDIUM_UNIFORMS:
                fu.RemoveUniform(name)
        for name, value in technique_values.items():
            set_uniform(fu, name, value)
            self.uniforms.add(name)

    def upload_exposure(self, exposure: float, fill: float, probe: bool) -> None:
        """The lighting models' exposure factor, sky fill strength and local-shading probe
        switch (host_lighting.glsl, host_medium.glsl)."""
        self._fu.SetUniformf("vv_exposure", exposure)
        self._fu.SetUniformf("vv_fill", fill)
        self._fu.SetUniformi("vv_exposureProbe", int(probe))

    def release_technique(self) -> None:
        """Remove the technique's uniforms and texture bindings (the host's stay)."""
        for name in self.uniforms:
            self._fu.RemoveUniform(name)
        self.uniforms.clear()
        for name in [n for n in self.textures if n not in HOST_TEXTURES]:
            self.unbind_texture(name)

    def release(self) -> None:
        """Remove every binding and host uniform and free the slice-weights texture."""
        if self._weights_texture is not None:
            self._weights_texture.release()
            self._weights_texture = None
        for name in list(self.textures):
            self.unbind_texture(name)
        for name in HOST_UNIFORMS:
            self._fu.RemoveUniform(name)


def technique_uniform_values(tech: Any, values: Mapping[str, Any]) -> dict[str, Any]:
    """The fragment uniforms of technique ``tech`` for parameter ``values``: one
    ``vv_<name>_<parameter>`` per non-choice parameter declared ``uniform`` (int for int and bool
    parameters, else float), then what its :meth:`~vtkvol.engine.technique.Technique.uniforms`
    returns."""
    out: dict[str, Any] = {}
    for p in tech.PARAMETERS:
        if p.uniform and p.kind != "choice":
            value = values[p.name]
            out[f"vv_{tech.NAME}_{p.name}"] = int(value) if p.kind in ("int", "bool") else (
                float(value))
    out.update(tech.uniforms(values))
    return out


def set_uniform(fu: vtk.vtkUniforms, name: str, value: Any) -> None:
    """Set a fragment custom uniform from a Python value: bool/int → int, float → float,
    2/3/4 numbers → vec2/3/4, any other count → float array."""
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
