"""The technique base class of the light-grid methods (shadow volume, translucency): what they
share around :mod:`.light_grid` (the grid and the numpy propagation) and :mod:`.light_grid_gpu`
(the compute propagator) — the GPU-or-numpy choice, the extinction grid's validity per path, the
propagator's work textures, the grid's shader uniforms, the data's placement and the release of
all of it. A technique adds its light textures, its recomputation and its own ``stats()``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from vtkvol.engine.gl import Texture3D
from vtkvol.engine.light_grid import LightGrid
from vtkvol.engine.light_grid_gpu import GpuPropagator
from vtkvol.engine.technique import ComputePath, Technique

if TYPE_CHECKING:
    from collections.abc import Mapping

    from vtkvol.engine.illuminator import Illuminator


class LightGridTechnique(Technique):
    """Light volumes on a :class:`~vtkvol.engine.light_grid.LightGrid`, recomputed on the
    GPU (:class:`~vtkvol.engine.light_grid_gpu.GpuPropagator`) or in numpy."""

    def __init__(self, host: Illuminator) -> None:
        super().__init__(host)
        self._recomputes = 0
        self._backend = ""  # "gpu" or "cpu": the path of the last recomputation
        #: The grid of the last recomputation (None before the first).
        self.grid: LightGrid | None = None
        #: The GPU-or-numpy choice (the ``backend`` parameter; numpy for good after a failure).
        self._compute = ComputePath(self.NAME, GpuPropagator)
        self._work_tex: dict[int, Texture3D] = {}  # the propagator's per-axis work textures
        #: Whether each path's extinction grid matches the current opacity and grid.
        self._sigma_valid: dict[str, bool] = {"gpu": False, "cpu": False}
        self._light_key: tuple | None = None  # the light geometry of the last recomputation

    def uniforms(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """``vv_<NAME>_dims``: the grid's cells per axis; ``vv_<NAME>_cellTex``: one grid cell
        in data texture coordinates per axis (x, y, z). None before the first recomputation."""
        grid = self.grid
        if grid is None:
            return {}
        return {
            f"vv_{self.NAME}_dims": tuple(float(m) for m in grid.dims),
            f"vv_{self.NAME}_cellTex": tuple(
                float(st / n) for st, n in zip(grid.step, grid.data_dims, strict=True)
            ),
        }

    def release(self) -> None:
        # The host removes our uniforms and texture bindings; we release what we created.
        self._release_timers()
        for tex in self._work_tex.values():
            tex.release()
        self._work_tex = {}
        self._compute.release()
        self._sigma_valid = {"gpu": False, "cpu": False}
        self.grid = None
        self._light_key = None

    def _origin(self) -> tuple[float, float, float]:
        """The data's origin (dataset space, µm)."""
        return tuple(float(o) for o in self.host.image.GetOrigin())  # type: ignore[return-value]

    def _direction(self) -> np.ndarray:
        """The data's direction matrix (3×3: index axes to dataset space)."""
        m = self.host.image.GetDirectionMatrix()
        return np.array([[m.GetElement(i, j) for j in range(3)] for i in range(3)])
