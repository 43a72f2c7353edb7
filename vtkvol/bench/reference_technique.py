"""The benchmark's reference renderers: the host's shading with CPU reference volumes.

"Render the same view twice in the same shader": every technique's image is compared with an
image made by :class:`ReferenceVolume` (``surface`` model) or :class:`MediumReferenceVolume`
(``medium`` model), which go through the same host lighting (``host_lighting.glsl`` /
``host_medium.glsl``) but answer ``vv_light_visibility`` with a numpy reference transmittance,
``vv_ambient_visibility`` with 1 − reference AO and ``vv_irradiance`` with a Monte-Carlo
in-scattered light volume (:mod:`vtkvol.bench.references`), uploaded as float textures at the
data's voxel centres. The two images therefore differ only by the illumination the technique
computed.

The techniques are registered (``bench_reference``, ``bench_reference_medium``) only while
:func:`registered` is active (inside ``vtkvol bench`` and its tests); they are not entry points
and users never see them.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vtkvol.engine.technique import Technique
from vtkvol.model.techniques import TechniqueSpec, register

if TYPE_CHECKING:
    from vtkvol.engine.gl import Texture3D
    from vtkvol.engine.illuminator import Changes

NAME = "bench_reference"
MEDIUM_NAME = "bench_reference_medium"
MAX_REFERENCE_LIGHTS = 4

SPEC = TechniqueSpec(
    name=NAME,
    label="Reference (CPU volumes)",
    engine="vtkvol.bench.reference_technique:ReferenceVolume",
    description="Benchmark only: shading with numpy reference visibility.",
)

MEDIUM_SPEC = TechniqueSpec(
    name=MEDIUM_NAME,
    label="Reference, medium model (CPU volumes)",
    engine="vtkvol.bench.reference_technique:MediumReferenceVolume",
    description="Benchmark only: medium shading with numpy reference transmittance and "
    "Monte-Carlo in-scattered light.",
    lighting="medium",
)


@dataclass(frozen=True, eq=False)
class ReferenceVolumes:
    """What the reference renderer shades with: float32 ``[z, y, x]`` volumes.

    ``visibility[i]`` is the transmittance towards the i-th enabled light; ``ambient`` is the
    ambient visibility 1 − AO (None: unoccluded), both in [0, 1]; ``irradiance`` is the
    in-scattered light of the medium model in units of the lights' irradiance (≥ 0; ``[z, y,
    x]``, or ``[z, y, x, 3]`` for an RGB albedo; None: none). All share one grid, normally the
    data's. Compared by identity: a new object means new textures.
    """

    visibility: tuple[np.ndarray, ...]
    ambient: np.ndarray | None = None
    irradiance: np.ndarray | None = None

    def __post_init__(self) -> None:
        if len(self.visibility) > MAX_REFERENCE_LIGHTS:
            raise ValueError(f"at most {MAX_REFERENCE_LIGHTS} reference light volumes")
        arrays = [*self.visibility, *([self.ambient] if self.ambient is not None else [])]
        shapes = {a.shape for a in arrays}
        if self.irradiance is not None:
            shapes.add(self.irradiance.shape[:3])
        if len(shapes) > 1:
            raise ValueError(f"reference volumes differ in shape: {sorted(shapes)}")
        for a in arrays:
            if a.ndim != 3 or not np.isfinite(a).all() or a.min() < 0 or a.max() > 1:
                raise ValueError("reference volumes must be finite [z, y, x] arrays in [0, 1]")
        irr = self.irradiance
        if irr is not None and (irr.ndim not in (3, 4) or (irr.ndim == 4 and irr.shape[3] != 3)
                                or not np.isfinite(irr).all() or irr.min() < 0):
            raise ValueError("the irradiance must be a finite, non-negative [z, y, x] or "
                             "[z, y, x, 3] array")

    @property
    def shape(self) -> tuple[int, int, int]:
        first = self.visibility[0] if self.visibility else self.ambient
        if first is None and self.irradiance is not None:
            first = self.irradiance[..., 0] if self.irradiance.ndim == 4 else self.irradiance
        return tuple(first.shape) if first is not None else (1, 1, 1)  # type: ignore[return-value]


class ReferenceVolume(Technique):
    """Shades with :class:`ReferenceVolumes` set through :meth:`use` (class-wide: the bench
    renders one reference at a time)."""

    SPEC = SPEC
    SHADER: ClassVar[str] = "reference_volume.glsl"

    @classmethod
    def shader_package(cls) -> str:
        return "vtkvol.resources"

    #: The volumes the next frame shades with (set by :meth:`use`).
    current: ClassVar[ReferenceVolumes | None] = None

    @classmethod
    def use(cls, volumes: ReferenceVolumes) -> None:
        """Shade the following frames with ``volumes`` (uploaded at the next frame), whichever
        of the two reference techniques renders them."""
        ReferenceVolume.current = volumes

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self._uploaded: ReferenceVolumes | None = None
        self._textures: dict[str, Texture3D] = {}

    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        vols = self.current
        n = len(vols.visibility) if vols is not None else 0
        ao = vols is not None and vols.ambient is not None
        irradiance = vols is not None and vols.irradiance is not None
        return {"VV_REF_LIGHTS": str(n), "VV_REF_AO": "1" if ao else "0",
                "VV_REF_IRRADIANCE": "1" if irradiance else "0"}

    def prepare(self, changes: Changes, values: Mapping[str, Any]) -> None:
        vols = self.current
        if vols is None or vols is self._uploaded:
            return
        from vtkvol.engine.gl import Texture3D

        self._release_textures()
        named: list[tuple[str, np.ndarray]] = [
            (f"vv_bench_reference_light{i}", v) for i, v in enumerate(vols.visibility)
        ]
        if vols.ambient is not None:
            named.append(("vv_bench_reference_ambient", vols.ambient))
        for uniform, array in named:
            tex = Texture3D(self.host.render_window, array.shape, data=array)
            self._textures[uniform] = tex
            self.host.bind_texture(uniform, tex)
        if vols.irradiance is not None:
            irr = vols.irradiance
            rgba = np.zeros((*irr.shape[:3], 4), np.float32)  # 3-channel textures do not exist
            rgba[..., :3] = irr[..., None] if irr.ndim == 3 else irr
            tex = Texture3D(self.host.render_window, rgba.shape[:3], data=rgba, channels=4)
            self._textures["vv_bench_reference_irradiance"] = tex
            self.host.bind_texture("vv_bench_reference_irradiance", tex)
        self._uploaded = vols

    def uniforms(self, values: Mapping[str, Any]) -> dict[str, Any]:
        nz, ny, nx = self._uploaded.shape if self._uploaded is not None else (1, 1, 1)
        return {"vv_bench_reference_dims": (float(nx), float(ny), float(nz))}

    def _release_textures(self) -> None:
        for uniform, tex in self._textures.items():
            self.host.unbind_texture(uniform)
            tex.release()
        self._textures.clear()
        self._uploaded = None

    def release(self) -> None:
        self._release_textures()


class MediumReferenceVolume(ReferenceVolume):
    """:class:`ReferenceVolume` under the ``medium`` lighting model (its SPEC says so): the
    same textures, shaded by ``host_medium.glsl`` with the reference in-scattered light."""

    SPEC = MEDIUM_SPEC


@contextmanager
def registered() -> Iterator[None]:
    """Register both reference techniques for the duration of the block (they are not entry
    points, so they never appear in a user-facing method list)."""
    with register(SPEC), register(MEDIUM_SPEC):
        yield

