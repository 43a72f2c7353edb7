"""The benchmark's reference renderer: the host's shading with CPU reference visibility volumes.

"Render the same view twice in the same shader": every technique's image is compared with an
image made by :class:`ReferenceVolume`, which goes through the same host lighting
(``resources/shaders/host_lighting.glsl``) but answers ``vv_light_visibility`` with a numpy
reference transmittance and ``vv_ambient_visibility`` with 1 − reference AO
(:mod:`vtkvol.bench.references`), uploaded as float textures at the data's voxel centres. The
two images therefore differ only by the illumination the technique computed.

The technique is registered under ``bench_reference`` only while :func:`registered` is active
(inside ``vtkvol bench`` and its tests); it is not an entry point and users never see it.
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
MAX_REFERENCE_LIGHTS = 4

SPEC = TechniqueSpec(
    name=NAME,
    label="Reference (CPU volumes)",
    engine="vtkvol.bench.reference_technique:ReferenceVolume",
    description="Benchmark only: shading with numpy reference visibility.",
)


@dataclass(frozen=True, eq=False)
class ReferenceVolumes:
    """What the reference renderer shades with: float32 ``[z, y, x]`` volumes in [0, 1].

    ``visibility[i]`` is the transmittance towards the i-th enabled light; ``ambient`` is the
    ambient visibility 1 − AO (None: unoccluded). All share one shape, normally the data's.
    Compared by identity: a new object means new textures.
    """

    visibility: tuple[np.ndarray, ...]
    ambient: np.ndarray | None = None

    def __post_init__(self) -> None:
        if len(self.visibility) > MAX_REFERENCE_LIGHTS:
            raise ValueError(f"at most {MAX_REFERENCE_LIGHTS} reference light volumes")
        arrays = [*self.visibility, *([self.ambient] if self.ambient is not None else [])]
        shapes = {a.shape for a in arrays}
        if len(shapes) > 1:
            raise ValueError(f"reference volumes differ in shape: {sorted(shapes)}")
        for a in arrays:
            if a.ndim != 3 or not np.isfinite(a).all() or a.min() < 0 or a.max() > 1:
                raise ValueError("reference volumes must be finite [z, y, x] arrays in [0, 1]")

    @property
    def shape(self) -> tuple[int, int, int]:
        first = self.visibility[0] if self.visibility else self.ambient
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
        """Shade the following frames with ``volumes`` (uploaded at the next frame)."""
        cls.current = volumes

    def __init__(self, host: Any) -> None:
        super().__init__(host)
        self._uploaded: ReferenceVolumes | None = None
        self._textures: dict[str, Texture3D] = {}

    def shader_defines(self, values: Mapping[str, Any]) -> dict[str, str]:
        vols = self.current
        n = len(vols.visibility) if vols is not None else 0
        ao = vols is not None and vols.ambient is not None
        return {"VV_REF_LIGHTS": str(n), "VV_REF_AO": "1" if ao else "0"}

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


@contextmanager
def registered() -> Iterator[None]:
    """Register ``bench_reference`` for the duration of the block (it is not an entry point, so
    it never appears in a user-facing method list)."""
    with register(SPEC):
        yield

