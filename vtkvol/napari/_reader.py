"""napari reader contribution: every format vtkvol reads, as napari layers.

No Qt here (napari calls readers from its own thread or a script). Layers, per channel:

* ``scale``: the voxel size (z, y, x) in µm (with a leading 1 for time), ``translate`` the
  pyramid offset; napari's axes are (t,) z, y, x;
* ``name``: the channel's name; ``colormap``: the file's channel colour (OME/omero, CZI…) or
  vtkvol's default colour for that channel, as a black→colour ramp; ``contrast_limits``:
  vtkvol's default window (:func:`vtkvol.model.defaults.contrast_limits`), the same the app
  starts with; ``blending`` additive, so channels add as in vtkvol;
* a pyramid (OME-Zarr, Imaris): a multiscale layer, one lazy dask array per level;
* a time series: every time point, stacked on the first axis (a pyramid: the first time point
  of each level only, as vtkvol's readers open one time point of a pyramid at a time);
* an integer image whose file or channel is named like a segmentation (``label``, ``mask``,
  ``seg``), or whose values look like one (:func:`vtkvol.model.labels.detect_labels`, what
  the app opens in labels mode): a Labels layer.

A file vtkvol refuses raises its :class:`~vtkvol.io.VolumeReadError`, whose message napari
shows as the error (one line, naming the file and the problem).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io import VolumeData, read_volume
from vtkvol.io.registry import get_reader as vtkvol_reader
from vtkvol.io.remote import is_remote, remote_reader

__all__ = ["get_reader", "layer_data", "read_layers"]

LayerData = tuple[Any, dict[str, Any], str]

#: Names that mark an integer image as a segmentation (a napari Labels layer).
LABEL_NAME = re.compile(r"(^|[^a-z])(labels?|mask|masks|seg|segmentation)([^a-z]|$)", re.I)


def get_reader(path: str | list[str]) -> Callable[[Any], list[LayerData]] | None:
    """napari's ``get_reader`` hook: :func:`read_layers` when vtkvol has a reader for ``path``
    (a file, a folder, an OME-Zarr address), else None so that napari asks other plugins."""
    first = path[0] if isinstance(path, list) and path else path
    if not isinstance(first, str):
        return None
    if is_remote(first) or vtkvol_reader(Path(first)) is not None:
        return read_layers
    return None


def read_layers(path: str | list[str]) -> list[LayerData]:
    """All layers of ``path`` (or of each path of a list)."""
    paths = path if isinstance(path, list) else [path]
    return [layer for p in paths for layer in _read_one(str(p))]


def _spec(path: str):
    return remote_reader(path) if is_remote(path) else vtkvol_reader(Path(path))


def _read_one(path: str) -> list[LayerData]:
    spec = _spec(path)
    if spec is None:
        return read_layers_of(read_volume(path, max_texture_size=None))  # says what is wrong
    if spec.open_pyramid is not None:
        opener = spec.open_pyramid
        pyramid = opener(path if is_remote(path) else Path(path), time_index=0, channels=None)
        if len(pyramid.levels) > 1:
            return _pyramid_layers(path, pyramid)
        pyramid.close()
    first = read_volume(path, max_texture_size=None)
    n_time = int(first.metadata.get("time_points", 1) or 1)
    if n_time <= 1:
        return read_layers_of(first)
    frames = [first.array] + [read_volume(path, time_index=t, max_texture_size=None).array
                              for t in range(1, n_time)]
    return read_layers_of(first, np.stack(frames, axis=1))


def _colors(data: VolumeData) -> list[tuple[float, float, float]]:
    from vtkvol.model.defaults import default_channels

    defaults = [ch.color for ch in default_channels(data)]
    file_colors = data.metadata.get("channel_colors") or []
    return [tuple(file_colors[c]) if c < len(file_colors) and file_colors[c] is not None
            else tuple(defaults[c]) for c in range(data.n_channels)]  # type: ignore[misc]


def _is_labels(data: VolumeData, c: int) -> bool:
    if not np.issubdtype(data.array.dtype, np.integer):
        return False
    from vtkvol.model.labels import detect_labels

    stem = Path(str(data.source or "")).name
    if LABEL_NAME.search(stem) or LABEL_NAME.search(data.channel_names[c]):
        return True
    # The app's detection (one function for both): ids over regions, whatever the name.
    return detect_labels(np.asarray(data.array[c])).is_labels


def layer_data(data: VolumeData, c: int, array: Any, color: tuple[float, float, float],
               *, time_axis: bool = False) -> LayerData:
    """One channel of ``data`` as napari layer data (``array`` z, y, x or t, z, y, x)."""
    from vtkvol.model.defaults import contrast_limits

    sx, sy, sz = data.voxel_size_um
    scale = ((1.0,) if time_axis else ()) + (sz, sy, sx)
    origin = data.metadata.get("origin_um")
    translate = ((0.0,) if time_axis else ()) + (
        tuple(float(v) for v in reversed(origin)) if origin else (0.0, 0.0, 0.0))
    meta = {"vtkvol_source": data.source, "vtkvol_channel": c,
            "vtkvol_voxel_size_um": tuple(data.voxel_size_um)}
    name = data.channel_names[c]
    if _is_labels(data, c):
        return array, {"name": name, "scale": scale, "translate": translate,
                       "metadata": meta}, "labels"
    lo, hi = contrast_limits(data, c)
    return array, {
        "name": name, "scale": scale, "translate": translate,
        "colormap": _colormap(name, color),
        "contrast_limits": (float(lo), float(hi)),
        "blending": "additive",
        "metadata": meta,
    }, "image"


def _colormap(name: str, color: tuple[float, float, float]) -> dict[str, Any]:
    """A napari colormap: black → ``color`` (vtkvol's channel colour)."""
    return {"name": f"vtkvol {name}", "colors": [[0.0, 0.0, 0.0, 1.0], [*color, 1.0]]}


def read_layers_of(data: VolumeData, stacked: np.ndarray | None = None) -> list[LayerData]:
    """Layers of ``data``, one per channel; ``stacked`` (c, t, z, y, x) adds the time axis."""
    colors = _colors(data)
    return [layer_data(data, c, data.array[c] if stacked is None else stacked[c], colors[c],
                       time_axis=stacked is not None) for c in range(data.n_channels)]


def _pyramid_layers(path: str, pyramid: Any) -> list[LayerData]:
    """A multiscale layer per channel: each level a lazy dask array (z, y, x); contrast
    limits and colours from the coarsest level, read whole (it is small)."""
    from vtkvol.io.pyramid import read_pyramid

    coarsest = read_pyramid(pyramid, level=len(pyramid.levels) - 1)
    coarsest.source = path
    # The pyramid stays open (an Imaris HDF5 handle, a remote store) as long as the layers'
    # dask arrays live: napari computes their chunks while the user browses.
    levels = [pyramid.to_dask(i) for i in range(len(pyramid.levels))]
    base = pyramid.levels[0]
    data = VolumeData(coarsest.array, base.voxel_size_um, list(pyramid.channel_names),
                      source=path, metadata=dict(coarsest.metadata))
    data.metadata["origin_um"] = [0.0, 0.0, 0.0]
    colors = _colors(data)
    layers = []
    for c in range(data.n_channels):
        arrays = [level[c] for level in levels]
        array, kwargs, kind = layer_data(data, c, arrays, colors[c])
        kwargs["multiscale"] = True
        # The contrast limits come from the coarsest level, which has the same values.
        layers.append((array, kwargs, kind))
    return layers
