"""``plotter.vtkvol``: vtkvol's illumination as a PyVista plotter component.

PyVista (≥ 0.48) finds this module through the ``pyvista.plotter_components`` entry point and
imports it the first time a plotter's ``vtkvol`` attribute is used, so nothing needs importing::

    plotter = pv.Plotter()
    plotter.add_volume(grid, mapper="gpu")
    shadows = plotter.vtkvol.illuminate(method="shadow_volume")   # the last volume added

    actor, light = plotter.vtkvol.add_volume(grid, method="hybrid_diffusion")

Everything goes through :func:`vtkvol.illuminate`; the component only finds the volume, keeps
one :class:`~vtkvol.engine.illuminator.Illuminator` per volume and releases them all when the
plotter closes (PyVista's ``__plotter_close__`` hook).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pyvista as pv
import vtk

from vtkvol.engine.api import illuminate
from vtkvol.engine.illuminator import Illuminator
from vtkvol.model.scene import Light

if not hasattr(pv, "register_plotter_component"):  # PyVista < 0.48
    raise ImportError(f"plotter.vtkvol needs PyVista 0.48 or newer (this is {pv.__version__}); "
                      "use vtkvol.illuminate(actor, plotter, ...) instead")


@pv.register_plotter_component("vtkvol")
class VtkvolComponent:
    """vtkvol's methods on a PyVista plotter (``plotter.vtkvol``)."""

    def __init__(self, plotter: Any) -> None:
        self._plotter = plotter
        self._illuminators: dict[int, Illuminator] = {}

    def illuminate(self, volume: vtk.vtkVolume | None = None, *, method: str = "local",
                   lights: Sequence[Light] | None = None, **parameters: Any) -> Illuminator:
        """Illuminate ``volume`` (default: the volume added last to the active renderer) with
        ``method``; see :func:`vtkvol.illuminate` for ``lights`` and ``parameters``. A volume
        this plotter already illuminates switches to the new method and parameters (and
        lights, if given) instead of being illuminated twice."""
        volume = volume if volume is not None else self._last_volume()
        # vtkvol.illuminate returns a volume's existing illuminator, switched (one per volume)
        il = illuminate(volume, self._plotter, method=method, lights=lights, **parameters)
        self._illuminators[id(volume)] = il
        return il

    def add_volume(self, dataset: Any, *, method: str = "local",
                   lights: Sequence[Light] | None = None,
                   parameters: dict[str, Any] | None = None,
                   **add_volume_kwargs: Any) -> tuple[Any, Illuminator]:
        """``plotter.add_volume(dataset, mapper="gpu", **add_volume_kwargs)`` (the GPU ray
        caster our techniques extend), then :meth:`illuminate` the new volume. Returns the
        PyVista volume actor and its illuminator."""
        mapper = add_volume_kwargs.pop("mapper", "gpu")
        if mapper != "gpu":
            raise ValueError(f"vtkvol illuminates the GPU ray caster only: mapper={mapper!r} "
                             "cannot be illuminated (use mapper='gpu')")
        actor = self._plotter.add_volume(dataset, mapper="gpu", **add_volume_kwargs)
        return actor, self.illuminate(actor, method=method, lights=lights,
                                      **(parameters or {}))

    @property
    def illuminators(self) -> list[Illuminator]:
        """The illuminators this plotter holds, oldest first."""
        return [il for il in self._illuminators.values() if not il.closed]

    def release(self) -> None:
        """Release every illumination (VTK's own shading again)."""
        for il in self._illuminators.values():
            if not il.closed:
                il.release()
        self._illuminators.clear()

    def __plotter_close__(self) -> None:
        self.release()

    def _last_volume(self) -> vtk.vtkVolume:
        volumes = self._plotter.renderer.GetVolumes()
        volumes.InitTraversal()
        last = None
        for _ in range(volumes.GetNumberOfItems()):
            last = volumes.GetNextVolume()
        if last is None:
            raise ValueError("the plotter has no volume to illuminate: add one with "
                             "plotter.add_volume(grid, mapper='gpu') or "
                             "plotter.vtkvol.add_volume(grid)")
        return last
