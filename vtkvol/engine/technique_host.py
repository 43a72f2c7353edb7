"""The technique-facing side of the host: what :class:`~vtkvol.engine.technique.TechniqueHost`
promises techniques, served by the host's services.

:class:`~vtkvol.engine.illuminator.Illuminator` derives from :class:`ServedTechniqueHost`, so
its own file keeps the user-facing facade (setters, frame orchestration, change detection,
release) while the members a technique calls (the image's geometry, lights in dataset space,
the opacity source, texture bindings, the medium's material) are read here in one place, each
a few lines that hand the call to the service that owns it.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import vtk

if TYPE_CHECKING:
    from vtkvol.engine.bindings import Bindings
    from vtkvol.engine.gl import Texture3D
    from vtkvol.engine.lights import LightRig
    from vtkvol.engine.opacity_source import OpacitySource
    from vtkvol.engine.precompute import PrecomputeRunner
    from vtkvol.engine.shader_builder import ShaderBuilder
    from vtkvol.engine.technique import LightSpec


class ServedTechniqueHost:
    """The :class:`~vtkvol.engine.technique.TechniqueHost` members, each handed to a service.

    The deriving host sets the services and state named below in its ``__init__``."""

    volume: vtk.vtkVolume
    opacity: OpacitySource
    bindings: Bindings
    shader_builder: ShaderBuilder
    light_rig: LightRig
    precompute_runner: PrecomputeRunner
    _albedo: float
    _phase_g: float

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
        return self.light_rig.specs(self.image)

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

    @property
    def albedo(self) -> float:
        """Single-scattering albedo of the ``medium`` model (0…1)."""
        return self._albedo

    @property
    def phase_g(self) -> float:
        """Henyey–Greenstein asymmetry of the ``medium`` model (0 = isotropic)."""
        return self._phase_g

    @property
    def precomputing(self) -> bool:
        """True while :meth:`precompute` runs (between its chunks, too)."""
        return self.precompute_runner.stepping
