"""Offscreen rendering: an EGL (or X, when a display is set) render window without Qt.

Used by ``vtkvol render``, the benchmark and the GL tests. :func:`grab` reads the back buffer
as an ``(h, w, 3)`` uint8 array, top row first.
"""

from __future__ import annotations

import os

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy


def make_render_window(size: tuple[int, int] = (256, 256)) -> vtk.vtkRenderWindow:
    """An offscreen render window: EGL when there is no X display, else X (Xvfb in tests).

    One process should stay with one kind: PyOpenGL binds to the platform of the first window.
    """
    if not os.environ.get("DISPLAY") and hasattr(vtk, "vtkEGLRenderWindow"):
        rw = vtk.vtkEGLRenderWindow()
    else:
        rw = vtk.vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    rw.SetSize(*size)
    rw.SetMultiSamples(0)
    return rw


def grab(render_window: vtk.vtkRenderWindow, *, render: bool = True) -> np.ndarray:
    """Render (optionally) and return the image as ``(h, w, 3)`` uint8, top row first."""
    if render:
        render_window.Render()
    w2i = vtk.vtkWindowToImageFilter()
    w2i.SetInput(render_window)
    w2i.ShouldRerenderOff()  # read the frame just rendered; do not render a second one
    w2i.SetInputBufferTypeToRGB()
    w2i.ReadFrontBufferOff()
    w2i.Update()
    image = w2i.GetOutput()
    w, h, _ = image.GetDimensions()
    pixels = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(h, w, -1)
    return np.ascontiguousarray(pixels[::-1, :, :3])


def image_from_array(
    array: np.ndarray, spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
) -> vtk.vtkImageData:
    """``vtkImageData`` from a ``[z, y, x]`` or ``[z, y, x, c]`` array (copied).

    ``spacing`` is (x, y, z) in µm."""
    arr = np.ascontiguousarray(array)
    nz, ny, nx = arr.shape[:3]
    ncomp = 1 if arr.ndim == 3 else arr.shape[3]
    img = vtk.vtkImageData()
    img.SetDimensions(nx, ny, nz)
    img.SetSpacing(*spacing)
    scalars = numpy_to_vtk(arr.reshape(-1, ncomp) if ncomp > 1 else arr.ravel(), deep=True)
    scalars.SetName("values")
    img.GetPointData().SetScalars(scalars)
    return img


def simple_volume_scene(
    array: np.ndarray,
    *,
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0),
    opacity: list[tuple[float, float]] | None = None,
    color: tuple[float, float, float] = (1.0, 1.0, 1.0),
    size: tuple[int, int] = (256, 256),
    sample_distance: float = 0.5,
    azimuth: float = 0.0,
    elevation: float = 0.0,
) -> tuple[vtk.vtkRenderWindow, vtk.vtkRenderer, vtk.vtkVolume]:
    """A plain-VTK scene (no vtkvol model): one volume, linear opacity ``opacity`` points
    ``(value, alpha)`` (default: 0 → 0, max → 1), constant ``color``, camera looking down −y
    (x right, z up) then rotated by ``azimuth``/``elevation`` degrees. For tests and benchmarks
    of techniques through :class:`vtkvol.engine.illuminator.Illuminator`.
    """
    img = image_from_array(array, spacing)
    rw = make_render_window(size)
    ren = vtk.vtkRenderer()
    ren.SetBackground(0, 0, 0)
    rw.AddRenderer(ren)
    mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
    mapper.SetInputData(img)
    mapper.SetAutoAdjustSampleDistances(0)
    mapper.SetSampleDistance(sample_distance * min(spacing))
    mapper.SetUseJittering(0)
    prop = vtk.vtkVolumeProperty()
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOn()
    prop.SetAmbient(0.3)
    prop.SetDiffuse(0.7)
    prop.SetSpecular(0.0)
    prop.SetScalarOpacityUnitDistance(min(spacing))
    otf = vtk.vtkPiecewiseFunction()
    hi = float(np.nanmax(array)) if np.size(array) else 1.0
    for value, alpha in opacity or [(0.0, 0.0), (max(hi, 1e-6), 1.0)]:
        otf.AddPoint(value, alpha)
    ctf = vtk.vtkColorTransferFunction()
    ctf.AddRGBPoint(0.0, *color)
    ctf.AddRGBPoint(max(hi, 1.0), *color)
    prop.SetScalarOpacity(otf)
    prop.SetColor(ctf)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    ren.AddVolume(volume)
    front_view(ren, azimuth, elevation)
    return rw, ren, volume


def front_view(renderer: vtk.vtkRenderer, azimuth: float = 0.0, elevation: float = 0.0) -> None:
    """Look along +y with z up (x to the right), orbit by ``azimuth``/``elevation`` degrees and
    zoom to fit everything in ``renderer``."""
    cam = renderer.GetActiveCamera()
    renderer.ResetCamera()
    fp = np.array(cam.GetFocalPoint())
    dist = cam.GetDistance()
    cam.SetPosition(*(fp + np.array([0.0, -dist, 0.0])))
    cam.SetViewUp(0.0, 0.0, 1.0)
    cam.Azimuth(azimuth)
    cam.Elevation(elevation)
    cam.OrthogonalizeViewUp()
    renderer.ResetCamera()
