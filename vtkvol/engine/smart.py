"""A GPU ray-cast mapper standing in for a user's ``vtkSmartVolumeMapper`` while illuminated.

The smart mapper hides the GPU ray-cast mapper it delegates to (no accessor, and it forwards
none of its events), so our shader replacements, observers and texture bindings cannot reach
it. :class:`SmartStandIn` renders the volume through a mapper of our own, set up as the smart
mapper sets up its delegate at every render, and keeps the two **in step in both directions**
at every frame: an edit of the smart mapper (an object the user still holds, e.g. PyVista's
``plotter.mapper``) reaches the stand-in, an edit of the stand-in (``actor.mapper`` while
illuminated) reaches the smart mapper, so nothing is lost when :meth:`give_back` puts the
smart mapper back. For a PyVista mapper the stand-in is PyVista's own
``OpenGLGPUVolumeRayCastMapper`` sharing its lookup table and scalar range, so PyVista's
mapper API (``blend_mode``, ``scalar_range``, ``lookup_table``, ``dataset``) keeps working.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import vtk

logger = logging.getLogger(__name__)

_MISSING = object()


@dataclass(frozen=True)
class _Setting:
    """One mapper setting: how to read it and write it on either mapper."""

    name: str
    get: Callable[[Any], Any]
    set: Callable[[Any, Any], None]


def _vtk_setting(name: str) -> _Setting:
    return _Setting(name, lambda m: getattr(m, f"Get{name}")(),
                    lambda m, v: getattr(m, f"Set{name}")(v))


def _input(mapper: vtk.vtkVolumeMapper) -> Any:
    return mapper.GetInputConnection(0, 0) if mapper.GetNumberOfInputConnections(0) else None


def _set_input(mapper: vtk.vtkVolumeMapper, connection: Any) -> None:
    mapper.SetInputConnection(connection)


def _array(mapper: vtk.vtkVolumeMapper) -> tuple[int, str, int]:
    return (mapper.GetArrayAccessMode(), mapper.GetArrayName() or "", mapper.GetArrayId())


def _set_array(mapper: vtk.vtkVolumeMapper, value: tuple[int, str, int]) -> None:
    mode, name, index = value
    if mode == vtk.VTK_GET_ARRAY_BY_NAME:
        mapper.SelectScalarArray(name)
    else:
        mapper.SelectScalarArray(index)
    mapper.SetArrayAccessMode(mode)


#: What vtkSmartVolumeMapper copies onto its GPU delegate (VTK 9.7, ComputeRenderMode), less
#: the sample distance and its automatic adjustment, which :class:`SmartStandIn` derives.
_SETTINGS: tuple[_Setting, ...] = (
    _Setting("Input", _input, _set_input),
    _Setting("Array", _array, _set_array),
    *(_vtk_setting(name) for name in (
        "ScalarMode", "BlendMode", "Cropping", "CroppingRegionPlanes", "CroppingRegionFlags",
        "ClippingPlanes", "FinalColorWindow", "FinalColorLevel", "Transfer2DYAxisArray",
        "ComputeNormalFromOpacity", "GlobalIlluminationReach", "VolumetricScatteringBlending",
        "MaxMemoryInBytes", "MaxMemoryFraction")),
)
#: PyVista's Python-level mapper state (``_BaseVolumeMapper``): shared, not copied.
_PYVISTA_SETTINGS: tuple[_Setting, ...] = tuple(
    _Setting(name, lambda m, n=name: getattr(m, n), lambda m, v, n=name: setattr(m, n, v))
    for name in ("_lut", "_scalar_range")
)


class SmartStandIn:
    """The GPU mapper that renders ``smart``'s volume until :meth:`give_back`."""

    def __init__(self, smart: vtk.vtkSmartVolumeMapper) -> None:
        if smart.GetVectorMode() != vtk.vtkSmartVolumeMapper.DISABLED:
            raise TypeError(
                "vtkvol: a vtkSmartVolumeMapper in vector mode (SetVectorMode) cannot be "
                "illuminated; render the magnitude or component as its own scalar array")
        self.smart = smart
        pyvista_mapper = sys.modules.get("pyvista.plotting.mapper")
        if pyvista_mapper is not None and isinstance(smart, pyvista_mapper._BaseVolumeMapper):
            self.gpu = pyvista_mapper.OpenGLGPUVolumeRayCastMapper(theme=smart._theme)
            self._settings = _SETTINGS + _PYVISTA_SETTINGS
        else:
            self.gpu = vtk.vtkOpenGLGPUVolumeRayCastMapper()
            self._settings = _SETTINGS
        # As the smart mapper sets up its delegate: the sample distance follows the spacing.
        self.gpu.LockSampleDistanceToInputSpacingOn()
        #: Per setting: (smart value, stand-in value) after the last sync.
        self._last: dict[str, tuple[Any, Any]] = {}
        self.sync(None)

    def sync(self, render_window: vtk.vtkRenderWindow | None) -> None:
        """Bring the two mappers in step: a setting changed on the smart mapper since the last
        sync goes to the stand-in, else one changed on the stand-in goes to the smart mapper.
        ``render_window`` (None before the first frame) drives the interactive sample-distance
        adjustment as it drives the smart mapper's own delegate."""
        smart, gpu = self.smart, self.gpu
        for setting in self._settings:
            if setting.name.startswith("_") and not hasattr(smart, setting.name):
                continue  # a PyVista wrapper VTK recreated without its Python attributes
            s, g = setting.get(smart), setting.get(gpu)
            last_s, last_g = self._last.get(setting.name, (_MISSING, _MISSING))
            if s is not last_s and s != last_s:
                if g is not s and g != s:
                    setting.set(gpu, s)
            elif g is not last_g and g != last_g:
                setting.set(smart, g)
            self._last[setting.name] = (setting.get(smart), setting.get(gpu))
        self._sync_sample_distance()
        if smart.GetInteractiveAdjustSampleDistances() and render_window is not None:
            auto = render_window.GetDesiredUpdateRate() >= smart.GetInteractiveUpdateRate()
        else:
            auto = bool(smart.GetAutoAdjustSampleDistances())
        if bool(gpu.GetAutoAdjustSampleDistances()) != auto:
            gpu.SetAutoAdjustSampleDistances(auto)

    def _sync_sample_distance(self) -> None:
        """The smart mapper's -1 ("from the spacing", resolved at its first render) becomes
        what it would resolve to: the mean spacing / 2 (world units)."""
        smart, gpu = self.smart, self.gpu
        s, g = smart.GetSampleDistance(), gpu.GetSampleDistance()
        last_s, last_g = self._last.get("SampleDistance", (_MISSING, _MISSING))
        if g != last_g and last_g is not _MISSING and s == last_s:
            smart.SetSampleDistance(g)  # set on the stand-in: the user's
        else:
            wanted = s if s > 0 else self._spacing_distance()
            if g != wanted:
                gpu.SetSampleDistance(wanted)
        self._last["SampleDistance"] = (smart.GetSampleDistance(), gpu.GetSampleDistance())

    def _spacing_distance(self) -> float:
        image = self.gpu.GetInput()
        spacing = image.GetSpacing() if isinstance(image, vtk.vtkImageData) else (1.0, 1.0, 1.0)
        return float(sum(spacing) / 6.0)

    def give_back(self) -> None:
        """Carry the last edits of the stand-in over to the smart mapper (the caller then puts
        the smart mapper back on the volume)."""
        self.sync(None)


def take_over(volume: vtk.vtkVolume, mapper: vtk.vtkVolumeMapper) -> SmartStandIn | None:
    """For a ``vtkSmartVolumeMapper``: a :class:`SmartStandIn` installed as ``volume``'s
    mapper (the smart mapper hides its GPU mapper; vtkvol renders through its own, kept in step
    with it, until :meth:`SmartStandIn.give_back`). None for any other mapper."""
    if not isinstance(mapper, vtk.vtkSmartVolumeMapper):
        return None
    stand_in = SmartStandIn(mapper)
    volume.SetMapper(stand_in.gpu)
    logger.info("vtkvol: rendering the volume with a GPU ray-cast mapper in place of its "
                "vtkSmartVolumeMapper until release()")
    return stand_in


def input_problem(image: vtk.vtkImageData) -> str | None:
    """Why ``image`` cannot be illuminated (it has no point scalars: cell data or none),
    as one sentence; None when it can."""
    if image.GetPointData().GetScalars() is not None:
        return None
    what = "cell data" if image.GetCellData().GetScalars() is not None else "no scalars"
    return (f"the volume's image has {what}; vtkvol illumination needs point scalars "
            "(convert with vtkCellDataToPointData, in PyVista grid.cell_data_to_point_data())")


def check_mapper(volume: vtk.vtkVolume, renderer: vtk.vtkRenderer) -> vtk.vtkVolumeMapper:
    """The volume's mapper if vtkvol can illuminate it: the GPU ray caster, or a smart mapper
    (rendered through one). Anything else is a ``TypeError`` saying what to use instead."""
    if isinstance(volume, vtk.vtkMultiVolume):
        raise TypeError(
            "vtkvol: multi-volume rendering (vtkMultiVolume) cannot be illuminated: give each "
            "image its own vtkVolume and GPU ray-cast mapper")
    mapper = volume.GetMapper()
    if mapper is None:
        for other in volumes_of(renderer):
            if isinstance(other, vtk.vtkMultiVolume) and any(
                    other.GetVolume(port) is volume
                    for port in range(other.GetMapper().GetNumberOfInputPorts())):
                raise TypeError(
                    "vtkvol: this volume is a member of a multi-volume (vtkMultiVolume), "
                    "which cannot be illuminated: give each image its own vtkVolume and GPU "
                    "ray-cast mapper")
        raise TypeError("vtkvol: the volume has no mapper; give it a "
                        "vtkOpenGLGPUVolumeRayCastMapper (members of a vtkMultiVolume, "
                        "multi-volume rendering, cannot be illuminated)")
    if not isinstance(mapper, vtk.vtkGPUVolumeRayCastMapper | vtk.vtkSmartVolumeMapper):
        raise TypeError(
            "vtkvol illumination needs a GPU ray-cast mapper, not "
            f"{type(mapper).__name__}: use vtkOpenGLGPUVolumeRayCastMapper (PyVista: "
            'plotter.add_volume(..., mapper="gpu"))'
        )
    return mapper


def volumes_of(renderer: vtk.vtkRenderer) -> list[vtk.vtkVolume]:
    """The renderer's volumes (vtkMultiVolume included), in its order."""
    volumes = renderer.GetVolumes()
    volumes.InitTraversal()
    return [volumes.GetNextVolume() for _ in range(volumes.GetNumberOfItems())]
