"""Automatic exposure: keep an illuminated view about as bright as local shading.

Shadows, ambient occlusion and attenuation take light away; a view with the shadow volume on
is often half as bright as with local shading, and users read that as "darker data". The
automatic exposure measures it on two coarse frames of the same view (same window, same
technique state, nothing recomputed):

* the method's own light, at exposure 1;
* the same lights unobstructed (:meth:`Illuminator.lit_as_local`: transmittance 1, no ambient
  occlusion, no in-scattering): what local shading shows.

Over the object's pixels (those that differ from the background in either frame) it compares
the mean luminance (Rec. 709 weights, on the 8-bit frame) and raises the exposure until the
method's mean is :data:`TARGET` of the reference's. It never lowers the exposure (a method
that adds light keeps it) and stops at :data:`MAX_FACTOR`, so a view that is dark because the
object is buried in its own shadow does not turn into noise. Shadowed parts stay darker than
lit ones: the exposure is one factor for the whole frame.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import vtk

from vtkvol.engine.offscreen import grab

#: The method's mean brightness as a fraction of local shading's that the exposure aims at.
TARGET = 0.9
#: The largest automatic factor.
MAX_FACTOR = 4.0
#: Longest edge of the measuring frames, in pixels (the mapper's image sample distance is
#: raised to get there; the window is not resized).
PROBE_EDGE = 64
#: A pixel belongs to the object where a channel differs from the background by more than this
#: (8-bit levels).
OBJECT_LEVELS = 3
#: Fewer object pixels than this: nothing to measure (factor 1).
MIN_PIXELS = 16


@dataclass(frozen=True)
class ExposureMeasurement:
    """One measurement. ``factor``: the automatic exposure (1…:data:`MAX_FACTOR`);
    ``method_mean`` and ``local_mean``: mean luminance (0…255) of the object's pixels with the
    method's light and lit as local shading; ``pixels``: how many object pixels there were."""

    factor: float
    method_mean: float
    local_mean: float
    pixels: int


def _luminance(image: np.ndarray) -> np.ndarray:
    return image[..., :3].astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])


def factor_from_frames(method: np.ndarray, local: np.ndarray,
                       background: tuple[float, float, float]) -> ExposureMeasurement:
    """The automatic exposure from two ``(h, w, 3)`` uint8 frames of the same view: the
    method's (at exposure 1) and the same view lit as local shading; ``background`` in 0…1."""
    bg = np.round(np.asarray(background, np.float64) * 255.0)
    differs = lambda im: (np.abs(im[..., :3].astype(np.float64) - bg) > OBJECT_LEVELS).any(-1)  # noqa: E731
    mask = differs(method) | differs(local)
    pixels = int(mask.sum())
    if pixels < MIN_PIXELS:
        return ExposureMeasurement(1.0, 0.0, 0.0, pixels)
    method_mean = float(_luminance(method)[mask].mean())
    local_mean = float(_luminance(local)[mask].mean())
    if method_mean <= 0.0:
        factor = MAX_FACTOR if local_mean > 0.0 else 1.0
    else:
        factor = float(np.clip(TARGET * local_mean / method_mean, 1.0, MAX_FACTOR))
    return ExposureMeasurement(factor, method_mean, local_mean, pixels)


def measure_auto_exposure(renderer: vtk.vtkRenderer, volume: vtk.vtkVolume,
                          illuminator) -> ExposureMeasurement:
    """Render the two coarse frames of :func:`factor_from_frames` in ``renderer``'s window and
    measure. A progressive technique is held still (:meth:`Illuminator.holding_still`), so
    measuring is none of its iterations: call it once its light is up to date. Other props
    (overlays, geometry) are hidden meanwhile and the frames are not shown (buffers are not
    swapped); the mapper's image sample distance, the props' visibility and the
    illuminator's exposure are restored afterwards. ``illuminator``: the volume's
    :class:`~vtkvol.engine.illuminator.Illuminator`."""
    rw = renderer.GetRenderWindow()
    mapper = volume.GetMapper()
    w, h = rw.GetSize()
    sample_distance = mapper.GetImageSampleDistance()
    hidden = []
    props = renderer.GetViewProps()
    props.InitTraversal()
    for _ in range(props.GetNumberOfItems()):
        prop = props.GetNextProp()
        if prop is not volume and prop.GetVisibility():
            prop.VisibilityOff()
            hidden.append(prop)
    swap = rw.GetSwapBuffers()
    exposure = illuminator.exposure
    try:
        rw.SwapBuffersOff()
        mapper.SetImageSampleDistance(max(1.0, max(w, h) / PROBE_EDGE))
        illuminator.set_exposure(1.0)
        # The method's frame brings the light up to date (what the next frame would do
        # anyway), except for a progressive technique: measuring must not count as one of its
        # iterations, so its frame holds it still.
        progressive = illuminator.spec.has("progressive")
        with illuminator.holding_still() if progressive else contextlib.nullcontext():
            method = grab(rw)
        with illuminator.lit_as_local():
            local = grab(rw)
    finally:
        illuminator.set_exposure(exposure)
        mapper.SetImageSampleDistance(sample_distance)
        rw.SetSwapBuffers(swap)
        for prop in hidden:
            prop.VisibilityOn()
    return factor_from_frames(method, local, renderer.GetBackground())


class ExposureControl:
    """The host's exposure factor and sky fill, and the two frame modes the automatic exposure
    needs: a service of :class:`~vtkvol.engine.illuminator.Illuminator`, uploaded through its
    :class:`~vtkvol.engine.bindings.Bindings` (per-frame uniforms: nothing is recomputed)."""

    def __init__(self, bindings: Any) -> None:
        self._bindings = bindings
        self.exposure = 1.0  #: the factor on the shaded colour (manual × automatic)
        self.fill = 0.0  #: strength of the unshadowed sky fill (0…1)
        self.probe = False  #: frames lit as local shading (measure_auto_exposure)
        self.held = False  #: frames keep what is installed (holding_still)

    def set(self, exposure: float | None = None, fill: float | None = None) -> None:
        """Validate and upload ``exposure`` (> 0) and ``fill`` (0…1); None keeps a value."""
        if exposure is not None:
            if not (math.isfinite(exposure) and exposure > 0.0):
                raise ValueError(f"exposure must be a finite number > 0, not {exposure!r}")
            self.exposure = float(exposure)
        if fill is not None:
            if not (math.isfinite(fill) and 0.0 <= fill <= 1.0):
                raise ValueError(f"fill must lie in 0…1, not {fill!r}")
            self.fill = float(fill)
        self.upload()

    def upload(self) -> None:
        """The uniforms as they stand (exposure 1 while lit as local shading)."""
        self._bindings.upload_exposure(1.0 if self.probe else self.exposure, self.fill,
                                       self.probe)

    @contextlib.contextmanager
    def holding_still(self) -> Iterator[None]:
        """Frames rendered inside keep what is installed (the host prepares nothing)."""
        held, self.held = self.held, True
        try:
            yield
        finally:
            self.held = held

    @contextlib.contextmanager
    def lit_as_local(self) -> Iterator[None]:
        """Frames rendered inside are held still and lit as local shading (exposure 1)."""
        with self.holding_still():
            self.probe = True
            self.upload()
            try:
                yield
            finally:
                self.probe = False
                self.upload()
