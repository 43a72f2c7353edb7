"""Lights: the renderer's lights as vtkvol lights, and vtkvol lights as techniques see them.

World-space :class:`vtkvol.model.Light` (the model's, or the renderer's own: headlight,
camera lights, light kits) become :class:`vtkvol.engine.technique.LightSpec` in the volume's
dataset space (µm of the image's own coordinates), once per frame by the host.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Sequence

import numpy as np
import vtk

from vtkvol.engine.technique import LightSpec
from vtkvol.model.scene import Light

#: Lights a host passes to techniques (the ``vv_lights`` uniform array holds four).
MAX_LIGHTS = 4


def check_lights(lights: Sequence[Light]) -> None:
    """Refuse more lights than :data:`MAX_LIGHTS`."""
    if len(lights) > MAX_LIGHTS:
        raise ValueError(f"at most {MAX_LIGHTS} lights are supported, not {len(lights)}")


def renderer_lights(renderer: vtk.vtkRenderer, *, fixed: bool = False) -> list[Light]:
    """The renderer's switched-on lights as world-space vtkvol lights (the headlight and
    camera lights, light kits included, placed from the current camera; scene lights
    through their transformed positions).

    ``fixed``: the lights are taken once and stay put in the world. A lone headlight then
    becomes a key light (:func:`key_light_direction`), since shadows cast along the view
    direction fall straight behind what casts them, where the viewer cannot see them.
    """
    lights = renderer.GetLights()
    lights.InitTraversal()
    switched_on = [light for light in (lights.GetNextItem()
                                       for _ in range(lights.GetNumberOfItems()))
                   if light is not None and light.GetSwitch()]
    if not switched_on and renderer.GetAutomaticLightCreation():
        # Before its first render a renderer has no lights yet: it is about to make its
        # headlight (white, intensity 1), so take that one.
        headlight = vtk.vtkLight()
        headlight.SetLightTypeToHeadlight()
        switched_on = [headlight]
    camera = renderer.GetActiveCamera()
    out: list[Light] = []
    for light in switched_on[:MAX_LIGHTS]:
        color = tuple(float(min(max(c, 0.0), 1.0)) for c in light.GetDiffuseColor())
        intensity = float(min(max(light.GetIntensity(), 0.0), 100.0))
        if fixed and len(switched_on) == 1 and light.LightTypeIsHeadlight():
            out.append(Light(direction=key_light_direction(camera), color=color,
                             intensity=intensity))
            continue
        position, focal = _light_world_geometry(light, camera)
        if light.GetPositional():
            out.append(Light(kind="point", position=tuple(position), color=color,
                             intensity=intensity))
        elif np.linalg.norm(position - focal) > 0:
            out.append(Light(direction=tuple(position - focal), color=color,
                             intensity=intensity))
    return out or [Light()]


def light_specs_in_dataset(lights: Sequence[Light], volume: vtk.vtkVolume,
                       image: vtk.vtkImageData) -> list[LightSpec]:
    """The enabled ``lights`` (world space) in ``image``'s dataset space (through ``volume``'s
    inverse matrix): directions as unit vectors, positions and sizes in dataset µm, angular
    radii in radians, colours times intensity; a point light's fall-off distance from the
    image's centre."""
    inv = vtk.vtkMatrix4x4()
    vtk.vtkMatrix4x4.Invert(volume.GetMatrix(), inv)
    linear = np.array([[inv.GetElement(i, j) for j in range(3)] for i in range(3)])
    length_scale = abs(np.linalg.det(linear)) ** (1.0 / 3.0)  # µm world → µm dataset
    bounds = image.GetBounds()
    center = np.array([(bounds[2 * a] + bounds[2 * a + 1]) / 2 for a in range(3)])
    specs = []
    for light in lights:
        if not light.enabled or light.intensity <= 0:
            continue
        color = tuple(float(c * light.intensity) for c in light.color)
        if light.kind == "point":
            p = inv.MultiplyPoint((*light.position, 1.0))
            pos = np.array(p[:3]) / p[3]
            falloff = (
                float(np.linalg.norm(pos - center)) if light.falloff == "inverse_square"
                else 0.0
            )
            specs.append(LightSpec("point", tuple(float(v) for v in pos), color,
                                   size=light.size * length_scale,
                                   falloff_distance=falloff))
        else:
            d = np.array(inv.MultiplyPoint((*light.direction, 0.0))[:3])
            d = d / max(np.linalg.norm(d), 1e-30)
            specs.append(LightSpec("directional", tuple(float(v) for v in d), color,
                                   size=math.radians(light.angular_radius_deg())))
    return specs


def _light_world_geometry(light: vtk.vtkLight,
                          camera: vtk.vtkCamera) -> tuple[np.ndarray, np.ndarray]:
    """World position and focal point of ``light`` for ``camera``'s current view.

    Computed from the camera rather than read from the light: the renderer moves its headlight
    and camera lights to the camera only inside its render, after the frame's start where the
    illuminator reads them, so the light's own transformed position is a frame behind."""
    if light.LightTypeIsHeadlight():
        return np.array(camera.GetPosition(), float), np.array(camera.GetFocalPoint(), float)
    if light.LightTypeIsCameraLight():
        matrix = camera.GetCameraLightTransformMatrix()
        position = matrix.MultiplyPoint((*light.GetPosition(), 1.0))
        focal = matrix.MultiplyPoint((*light.GetFocalPoint(), 1.0))
        return (np.array(position[:3]) / position[3], np.array(focal[:3]) / focal[3])
    return (np.array(light.GetTransformedPosition(), float),
            np.array(light.GetTransformedFocalPoint(), float))


#: Where a key light sits relative to the view (degrees): VTK's vtkLightKit's defaults, the
#: photographer's key light above and beside the camera.
KEY_LIGHT_ELEVATION_DEG = 50.0


KEY_LIGHT_AZIMUTH_DEG = 10.0


def key_light_direction(camera: vtk.vtkCamera) -> tuple[float, float, float]:
    """World direction towards a key light for ``camera``'s current view: the direction to the
    camera turned up by :data:`KEY_LIGHT_ELEVATION_DEG` (about the camera's right axis) and to
    the right by :data:`KEY_LIGHT_AZIMUTH_DEG` (about its view-up)."""
    position = np.array(camera.GetPosition(), float)
    focal = np.array(camera.GetFocalPoint(), float)
    to_camera = position - focal
    norm = np.linalg.norm(to_camera)
    to_camera = to_camera / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    up = np.array(camera.GetViewUp(), float)
    up = up - np.dot(up, to_camera) * to_camera
    if np.linalg.norm(up) < 1e-9:  # a view-up along the view: any perpendicular will do
        up = np.cross(to_camera, [1.0, 0.0, 0.0] if abs(to_camera[0]) < 0.9 else [0, 1.0, 0])
    up = up / np.linalg.norm(up)
    right = np.cross(-to_camera, up)
    elevation = math.radians(KEY_LIGHT_ELEVATION_DEG)
    azimuth = math.radians(KEY_LIGHT_AZIMUTH_DEG)
    direction = (math.cos(elevation) * (math.cos(azimuth) * to_camera + math.sin(azimuth) * right)
                 + math.sin(elevation) * up)
    return tuple(float(v) for v in direction)


class LightRig:
    """The host's lights, a service of :class:`~vtkvol.engine.illuminator.Illuminator`: the
    world-space lights it was given, or the renderer's own (followed at every frame, or taken
    once at the first frame and fixed in the world), and their dataset-space
    :class:`LightSpec` computed once per frame (the host and the technique both ask).

    ``lights``: up to :data:`MAX_LIGHTS` world-space lights, ``"renderer"`` (follow the
    renderer's switched-on lights), ``"renderer_fixed"`` (take them at the first frame) or None
    (one directional light)."""

    def __init__(self, volume: vtk.vtkVolume, renderer: vtk.vtkRenderer,
                 lights: Sequence[Light] | str | None) -> None:
        self._volume = volume
        self._renderer = renderer
        #: "renderer": follow the renderer's own (switched-on) lights at every frame.
        self.follow_renderer = lights == "renderer"
        #: "renderer_fixed": take the renderer's lights once, at the first frame, and keep them
        #: fixed in the world (a lone headlight becomes a key light; see renderer_lights).
        self.capture_renderer = lights == "renderer_fixed"
        self.lights: list[Light] = (
            [Light()] if lights is None or isinstance(lights, str) else list(lights))
        check_lights(self.lights)
        #: The frame's specs while a frame (or a precompute chunk) runs, else None.
        self.frame_specs: list[LightSpec] | None = None
        self._signature: tuple | None = None  # (geometry, colours) the technique last saw

    def set(self, lights: Sequence[Light]) -> None:
        """Fixed world-space ``lights`` from now on (the renderer's are no longer followed)."""
        lights = list(lights)
        check_lights(lights)
        self.lights = lights
        self.follow_renderer = self.capture_renderer = False

    def follow(self) -> None:
        """Follow the renderer's lights at every frame from now on."""
        self.follow_renderer, self.capture_renderer = True, False

    def take_renderer_lights(self) -> None:
        """At a frame's start: the renderer's lights, every frame when following them, once
        (the first frame, when the camera is set) when they are taken as fixed lights."""
        if self.follow_renderer:
            self.lights = renderer_lights(self._renderer)
        elif self.capture_renderer:
            self.lights = renderer_lights(self._renderer, fixed=True)
            self.capture_renderer = False

    def compute(self, image: vtk.vtkImageData) -> list[LightSpec]:
        """The enabled lights in ``image``'s dataset space, computed now."""
        return light_specs_in_dataset(self.lights, self._volume, image)

    @contextlib.contextmanager
    def frame(self, image: vtk.vtkImageData) -> Iterator[None]:
        """Inside: :meth:`specs` returns the specs computed once on entry."""
        self.frame_specs = self.compute(image)
        try:
            yield
        finally:
            self.frame_specs = None

    def specs(self, image: vtk.vtkImageData) -> list[LightSpec]:
        """The frame's specs inside :meth:`frame`, else computed anew."""
        if self.frame_specs is not None:
            return list(self.frame_specs)
        return self.compute(image)

    def changed(self, specs: Sequence[LightSpec]) -> tuple[bool, bool]:
        """``(geometry, colours_only)``: whether ``specs`` differ from those of the last call in
        geometry (kind, vector, size, fall-off; also True at the first call) or only in colour
        and intensity."""
        geometry = tuple((s.kind, s.vector, s.size, s.falloff_distance) for s in specs)
        colors = tuple(s.color for s in specs)
        previous, self._signature = self._signature, (geometry, colors)
        if previous is None or geometry != previous[0]:
            return True, False
        return False, colors != previous[1]
