"""napari's layer properties and 3-D camera → vtkvol's data, transfer functions and camera.

No Qt and no napari import: the functions read plain attributes of napari layer and camera
objects (or of anything with the same attributes), so the mapping is tested headless too.
docs/napari.md states the mapping; in short:

* the visible image layers (1–4, same shape) are the channels, in layer-list order; their
  ``scale`` (z, y, x) is the voxel size in µm (x, y, z for vtkvol); a multiscale layer gives
  the finest level that fits the GPU budget;
* ``contrast_limits`` (lo, hi) and ``gamma`` → a ramp: transparent at lo, the colormap's
  colour at t = ((v − lo)/(hi − lo))^gamma, opacity ``layer.opacity`` × t (sampled at
  :data:`RAMP_POINTS` values);
* ``colormap`` → the colour function (its colours at those t);
* ``rendering`` → blend mode: translucent → composite, mip → mip, minip → minip, average →
  average, additive → additive, attenuated_mip → mip (vtkvol has no attenuation), iso →
  isosurface at ``iso_threshold`` (napari's per-layer mode is global in vtkvol: the first
  layer's is used);
* the camera: napari's ``view_direction``/``up_direction`` (world z, y, x) reversed into
  x, y, z; ``center`` the focal point; ``perspective`` (field of view, degrees; 0 =
  orthographic) the view angle; ``zoom`` (screen pixels per µm) the distance, so that the
  same height of the world fills the image.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vtkvol.io import VolumeData
from vtkvol.io.pyramid import DEFAULT_GPU_BUDGET_BYTES
from vtkvol.model.defaults import scene_for
from vtkvol.model.scene import Camera, SceneModel
from vtkvol.model.transfer_function import TransferFunction

__all__ = ["BLEND_MODES", "RAMP_POINTS", "MappingError", "camera_from_napari", "layers_to_scene",
           "transfer_function"]

#: Values per ramp at which the colormap and gamma are sampled.
RAMP_POINTS = 17

#: napari ``rendering`` → vtkvol ``render.blend_mode``.
BLEND_MODES = {
    "translucent": "composite", "mip": "mip", "minip": "minip", "average": "average",
    "additive": "additive", "attenuated_mip": "mip", "iso": "isosurface",
    "translucent_no_depth": "composite", "iso_categorical": "isosurface",
}

MAX_LAYERS = 4


class MappingError(ValueError):
    """The layers cannot be rendered together (the message says why, in one line)."""


def _colormap_at(colormap: Any, t: np.ndarray) -> np.ndarray:
    """RGB (n, 3) of a napari colormap at ``t`` in 0…1 (linear between its controls)."""
    colors = np.asarray(getattr(colormap, "colors", colormap), dtype=float)
    controls = getattr(colormap, "controls", None)
    if controls is None or len(controls) != len(colors):
        controls = np.linspace(0.0, 1.0, len(colors))
    controls = np.asarray(controls, dtype=float)
    return np.stack([np.interp(t, controls, colors[:, k]) for k in range(3)], axis=1)


def transfer_function(contrast_limits: tuple[float, float], colormap: Any, gamma: float = 1.0,
                      opacity: float = 1.0,
                      value_range: tuple[float, float] | None = None) -> TransferFunction:
    """vtkvol's 1-D TF for one napari image layer (see the module docstring)."""
    lo, hi = (float(v) for v in contrast_limits)
    if not hi > lo:
        hi = lo + max(abs(lo) * 1e-6, 1e-6)
    t = np.linspace(0.0, 1.0, RAMP_POINTS)
    shown = t ** float(gamma)
    rgb = _colormap_at(colormap, shown)
    values = lo + t * (hi - lo)
    rlo, rhi = value_range if value_range is not None else (min(lo, 0.0), hi)
    rlo, rhi = min(rlo, lo), max(rhi, hi)
    alpha = float(np.clip(opacity, 0.0, 1.0))
    return TransferFunction(
        colors=[(float(v), *(float(c) for c in rgb[i])) for i, v in enumerate(values)],
        opacity=[(float(v), alpha * float(shown[i])) for i, v in enumerate(values)],
        window=(float(rlo), float(rhi)),
        window_range=(float(rlo), float(rhi)),
    )


def _layer_array(layer: Any, budget_bytes: int) -> np.ndarray:
    """The layer's voxels (z, y, x): a multiscale layer's finest level within the budget."""
    if getattr(layer, "multiscale", False):
        levels = list(layer.data)
        for level in levels:
            if math.prod(level.shape) * np.dtype(level.dtype).itemsize <= budget_bytes:
                return np.asarray(level)
        return np.asarray(levels[-1])
    return np.asarray(layer.data)


def layers_to_scene(layers: list[Any], *, budget_bytes: int = DEFAULT_GPU_BUDGET_BYTES,
                    ) -> tuple[VolumeData, SceneModel]:
    """The visible napari image layers as vtkvol data (c, z, y, x) and a scene whose channels,
    transfer functions and blend mode follow the layers (camera left to
    :func:`camera_from_napari`). Raises MappingError for layers that cannot go together."""
    layers = [ly for ly in layers if getattr(ly, "visible", True)]
    if not layers:
        raise MappingError("no visible image layer to render")
    if len(layers) > MAX_LAYERS:
        raise MappingError(f"{len(layers)} visible image layers; vtkvol renders up to "
                           f"{MAX_LAYERS} channels at once: hide some")
    arrays, scales = [], []
    for ly in layers:
        array = _layer_array(ly, budget_bytes // len(layers))
        if array.ndim == 4 and array.shape[0] >= 1:  # time first: the current time point
            step = getattr(ly, "_slice_indices", None)
            array = array[int(step[0]) if step is not None else 0]
        if array.ndim != 3:
            raise MappingError(f"layer {ly.name!r} is {array.ndim}-D; a volume needs 3 axes "
                               "(z, y, x)")
        arrays.append(array)
        full = np.asarray(ly.scale, dtype=float)[-3:]
        if getattr(ly, "multiscale", False):  # a coarser level has larger voxels
            full = full * np.asarray(ly.data[0].shape[-3:]) / np.asarray(array.shape)
        scales.append(tuple(full))
    shapes = {a.shape for a in arrays}
    if len(shapes) > 1:
        raise MappingError(f"the visible layers differ in shape {sorted(shapes)}; vtkvol "
                           "renders channels of one grid")
    if any(not np.allclose(s, scales[0]) for s in scales):
        raise MappingError(f"the visible layers differ in scale {scales}; vtkvol renders "
                           "channels of one grid")
    dtype = np.result_type(*[a.dtype for a in arrays])
    stacked = np.stack([a.astype(dtype, copy=False) for a in arrays])
    sz, sy, sx = scales[0]
    sources = {getattr(ly, "metadata", {}).get("vtkvol_source") for ly in layers}
    data = VolumeData(stacked, (float(sx), float(sy), float(sz)), [ly.name for ly in layers],
                      source=sources.pop() if len(sources) == 1 else None)
    model = scene_for(data)
    for channel, ly in zip(model.channels, layers, strict=True):
        channel.tf = transfer_function(
            tuple(ly.contrast_limits), ly.colormap, getattr(ly, "gamma", 1.0),
            getattr(ly, "opacity", 1.0), value_range=data.channel_range(layers.index(ly)))
        rgb = _colormap_at(ly.colormap, np.array([1.0]))[0]
        channel.color = tuple(float(v) for v in rgb)
    rendering = str(getattr(layers[0], "rendering", "translucent"))
    model.render.blend_mode = BLEND_MODES.get(rendering, "composite")
    if model.render.blend_mode == "isosurface":
        model.render.isosurface_value = float(getattr(layers[0], "iso_threshold", 0.5))
    return data, model


def camera_from_napari(camera: Any, data: VolumeData, *, canvas_height_px: float,
                       translate_zyx: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Camera:
    """vtkvol's camera (world x, y, z µm; the data's first voxel centre at 0) for napari's 3-D
    ``camera`` (world z, y, x; ``translate_zyx`` is the layers' translate, subtracted)."""
    view = np.asarray(camera.view_direction, dtype=float)[::-1]
    up = np.asarray(camera.up_direction, dtype=float)[::-1]
    centre = np.asarray(camera.center, dtype=float)[-3:] - np.asarray(translate_zyx, float)
    focal = centre[::-1]
    half_height = canvas_height_px / (2.0 * float(camera.zoom))  # µm
    fov = float(getattr(camera, "perspective", 0.0) or 0.0)
    if fov > 0:
        distance = half_height / math.tan(math.radians(fov) / 2.0)
        return Camera(position=tuple(focal - view * distance), focal_point=tuple(focal),
                      view_up=tuple(up), view_angle=fov)
    extent = np.asarray(data.shape_zyx[::-1], float) * np.asarray(data.voxel_size_um, float)
    distance = 2.0 * float(np.linalg.norm(extent)) + 1.0  # outside the box; parallel anyway
    return Camera(position=tuple(focal - view * distance), focal_point=tuple(focal),
                  view_up=tuple(up), parallel_projection=True, parallel_scale=half_height)
