"""Zeiss ``.czi`` files (ZEN), through ``czifile`` (BSD) or ``pylibCZIrw`` (LGPL).

``czifile`` needs Python ≥ 3.12; on 3.10/3.11 the optional extra ``formats`` installs
``pylibCZIrw`` instead (ZEISS' own libCZI, LGPL, used unmodified as a separate library).
Whichever is installed is used, czifile first.

Both give the first scene's axes (``T``, ``Z``, ``C``, ``Y``, ``X``; BGR pixel types become
the channels ``red``, ``green``, ``blue``), one plane at a time. Voxel size: the XML metadata's
``Scaling/Items/Distance[@Id=X|Y|Z]/Value``, in metres by the CZI specification, converted to
µm. Channel names: ``Information/Image/Dimensions/Channels/Channel/@Name``; colours from the
display settings (``#AARRGGBB``).
"""

from __future__ import annotations

import contextlib
import importlib
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.volume_data import (
    VolumeData,
    default_channel_names,
    resolve_channels,
    spacing_or_default,
)

__all__ = ["CZI_READER", "czi_metadata", "read_czi"]

METRE_UM = 1e6
_GRAY = {"Gray8": np.uint8, "Gray16": np.uint16, "Gray32Float": np.float32}
_BGR = {"Bgr24": np.uint8, "Bgr48": np.uint16, "Bgr96Float": np.float32}


def _backend(path: Path) -> tuple[str, Any]:
    """``("czifile" | "pylibczirw", module)``, or the error naming the extra to install."""
    for name, module in (("czifile", "czifile"), ("pylibczirw", "pylibCZIrw.czi")):
        try:
            return name, importlib.import_module(module)
        except ImportError:
            continue
    needed = "czifile" if sys.version_info >= (3, 12) else "pylibCZIrw"
    raise VolumeReadError(
        path, f"reading Zeiss CZI files needs the optional package {needed!r} (czifile on "
              "Python ≥ 3.12, pylibCZIrw before): pip install 'vtkvol[formats]'")


def czi_metadata(xml_text: str | None, n_channels: int) -> tuple[
        list[float], list[str], list[tuple[float, float, float] | None]]:
    """``(voxel size (x, y, z) in µm (NaN where absent), channel names, colours)`` from the
    CZI's XML metadata."""
    spacing = [math.nan] * 3
    names = default_channel_names(n_channels)
    colors: list[tuple[float, float, float] | None] = [None] * n_channels
    if not xml_text:
        return spacing, names, colors
    try:
        root = ElementTree.fromstring(xml_text)
    except ElementTree.ParseError:
        return spacing, names, colors
    for distance in root.iter("Distance"):
        axis = {"X": 0, "Y": 1, "Z": 2}.get(str(distance.get("Id")))
        value = distance.findtext("Value")
        if axis is not None and value:
            with contextlib.suppress(ValueError):
                # 12 significant digits: 2e-07 m reads as 0.2 µm, not 0.19999999999999998
                spacing[axis] = float(f"{float(value) * METRE_UM:.12g}")
    image_channels = root.findall(".//Information/Image/Dimensions/Channels/Channel")
    if len(image_channels) == n_channels:
        found = [(ch.get("Name") or ch.findtext("Name") or ch.get("Id") or "").strip()
                 for ch in image_channels]
        if all(found):
            names = found if len(set(found)) == n_channels else [
                f"{n} ({i})" for i, n in enumerate(found)]
    display = root.findall(".//DisplaySetting/Channels/Channel")
    if len(display) == n_channels:
        for i, ch in enumerate(display):
            text = (ch.findtext("Color") or "").lstrip("#")
            if len(text) in (6, 8):
                try:
                    rgb = text[-6:]
                    colors[i] = tuple(int(rgb[j:j + 2], 16) / 255.0 for j in (0, 2, 4))  # type: ignore[assignment]
                except ValueError:
                    pass
    return spacing, names, colors


def read_czi(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read one time point of a CZI file's first scene as ``[c, z, y, x]``."""
    progress = progress or Progress()
    path = Path(path)
    name, module = _backend(path)
    progress(0.0, "reading CZI header")
    reader = _read_czifile if name == "czifile" else _read_pylibczirw
    array, names, colors, xml_text, n_time, notes = reader(
        module, path, time_index, channels, progress)
    spacing_values, _, _ = czi_metadata(xml_text, 0)
    if array.shape[1] == 1 and not spacing_values[2] > 0:
        spacing_values[2] = spacing_values[0]  # a single plane: its thickness does not matter
    spacing, from_metadata = spacing_or_default(
        spacing_values, "the CZI metadata has no scaling (Distance X/Y/Z): using 1 × 1 × 1 µm",
        notes)
    return VolumeData(
        array,
        spacing,
        names,
        source=str(path),
        voxel_size_from_metadata=from_metadata,
        metadata={
            "format": f"czi ({name})",
            "time_points": n_time,
            "time_index": time_index,
            "channel_colors": colors,
            "voxel_size_source": "CZI Scaling (m)" if from_metadata else "default 1 µm",
        },
        notes=notes,
    )


def _check_time(path: Path, time_index: int, n_time: int) -> None:
    if not 0 <= time_index < n_time:
        raise VolumeReadError(path, f"time_index {time_index} is out of range: the file has "
                                    f"{n_time} time point(s)")


def _read_pylibczirw(module: Any, path: Path, time_index: int,
                     channels: Sequence[int | str] | None, progress: Progress) -> tuple:
    notes: list[str] = []
    try:
        context = module.open_czi(str(path))
        reader = context.__enter__()
    except Exception as exc:  # libCZI raises RuntimeError for a bad header
        raise VolumeReadError(path, f"not a readable CZI file ({exc})") from exc
    try:
        try:
            box = dict(reader.total_bounding_box)
            scenes = dict(reader.scenes_bounding_rectangle)
            roi = scenes[min(scenes)] if scenes else reader.total_bounding_rectangle
            pixel_types = dict(reader.pixel_types)
            xml_text = reader.raw_metadata
        except Exception as exc:
            raise VolumeReadError(path, f"the CZI directory cannot be read ({exc})") from exc
        if len(scenes) > 1:
            notes.append(f"the file holds {len(scenes)} scenes: scene {min(scenes)} is shown")
        extra = [f"{k}={v[1] - v[0]}" for k, v in box.items()
                 if k not in ("T", "Z", "C", "X", "Y") and v[1] - v[0] > 1]
        if extra:
            raise VolumeReadError(path, f"unsupported axes {', '.join(extra)}; vtkvol reads T, "
                                        "Z, C, Y, X")
        t0, t1 = box.get("T", (0, 1))
        z0, z1 = box.get("Z", (0, 1))
        c0, c1 = box.get("C", (0, 1))
        n_time, nz, n_c = t1 - t0, z1 - z0, c1 - c0
        _check_time(path, time_index, n_time)
        types = [pixel_types.get(c, pixel_types.get(c - c0)) for c in range(n_c)] or ["Gray8"]
        if any(t in _BGR for t in types):
            if n_c != 1:
                raise VolumeReadError(path, f"{n_c} channels of BGR colour pixels are not "
                                            "supported")
            names = ["red", "green", "blue"]
            colors: list = [None] * 3
            dtype = np.dtype(_BGR[types[0]])
        else:
            unknown = [t for t in types if t not in _GRAY]
            if unknown:
                raise VolumeReadError(path, f"unsupported CZI pixel type {unknown[0]!r}")
            _, names, colors = czi_metadata(xml_text, n_c)
            dtype = np.result_type(*(_GRAY[t] for t in types))
        chosen = resolve_channels(channels, names, str(path))
        ny, nx = int(roi.h), int(roi.w)
        check_declared_bytes(path, len(chosen) * nz * ny * nx * dtype.itemsize,
                             f"{len(chosen)} × {nz} × {ny} × {nx} {dtype} voxels")
        gray_type = {np.dtype(v): k for k, v in _GRAY.items()}.get(dtype)
        out = np.empty((len(chosen), nz, ny, nx), dtype=dtype)
        for k, c in enumerate(chosen):
            for z in range(nz):
                plane = {"T": t0 + time_index, "Z": z0 + z, "C": c0 + (0 if names[0] == "red"
                                                                      else c)}
                try:
                    if names[0] == "red":  # one BGR channel: libCZI returns (y, x, 3) B, G, R
                        out[k, z] = reader.read(plane=plane, roi=roi)[:, :, 2 - c]
                    else:
                        out[k, z] = reader.read(plane=plane, roi=roi,
                                                pixel_type=gray_type)[:, :, 0]
                except Exception as exc:
                    raise VolumeReadError(path, f"plane {plane} cannot be read; the file is "
                                                f"truncated or corrupt ({exc})") from exc
                progress((k + (z + 1) / nz) / len(chosen), f"reading {names[c]}")
    finally:
        context.__exit__(None, None, None)
    return out, [names[c] for c in chosen], [colors[c] for c in chosen], xml_text, n_time, notes


def _read_czifile(module: Any, path: Path, time_index: int,
                  channels: Sequence[int | str] | None, progress: Progress) -> tuple:
    notes: list[str] = []
    try:
        handle = module.CziFile(str(path))
    except Exception as exc:  # CziFileError is a ValueError; OSError for short files
        raise VolumeReadError(path, f"not a readable CZI file ({exc})") from exc
    try:
        try:
            scenes = handle.scenes
            keys = list(scenes.keys())
            image = scenes[keys[0]] if keys else None
            if image is None:
                raise VolumeReadError(path, "the file holds no image")
            sizes = {str(k): int(v) for k, v in dict(image.sizes).items()}
            dtype = np.dtype(image.dtype)
            xml_text = handle.metadata()
        except VolumeReadError:
            raise
        except Exception as exc:
            raise VolumeReadError(path, f"the CZI directory cannot be read ({exc})") from exc
        if len(keys) > 1:
            notes.append(f"the file holds {len(keys)} scenes: scene {keys[0]} is shown")
        extra = [f"{k}={v}" for k, v in sizes.items()
                 if k not in ("T", "Z", "C", "Y", "X", "S") and v > 1]
        if extra:
            raise VolumeReadError(path, f"unsupported axes {', '.join(extra)}; vtkvol reads T, "
                                        "Z, C, Y, X")
        n_time, nz, n_c, n_s = (sizes.get(a, 1) for a in ("T", "Z", "C", "S"))
        _check_time(path, time_index, n_time)
        if n_s > 1:
            if n_c > 1:
                raise VolumeReadError(path, f"{n_c} channels of colour pixels are not supported")
            names = ["red", "green", "blue", "alpha"][:n_s]
            colors: list = [None] * n_s
        else:
            _, names, colors = czi_metadata(xml_text, n_c)
            channel_keys = [str(k) for k in dict(image.channels)]
            if len(channel_keys) == n_c and all(channel_keys) and len(set(channel_keys)) == n_c:
                names = channel_keys
        chosen = resolve_channels(channels, names, str(path))
        ny, nx = sizes["Y"], sizes["X"]
        check_declared_bytes(path, len(chosen) * nz * ny * nx * dtype.itemsize,
                             f"{len(chosen)} × {nz} × {ny} × {nx} {dtype} voxels")
        out = np.empty((len(chosen), nz, ny, nx), dtype=dtype)
        for k, c in enumerate(chosen):
            selection = {}
            if "T" in sizes:
                selection["T"] = time_index
            if "C" in sizes:
                selection["C"] = c
            try:
                block = np.asarray(image(**selection).asarray())
            except Exception as exc:
                raise VolumeReadError(path, f"channel {names[c]!r} cannot be read; the file is "
                                            f"truncated or corrupt ({exc})") from exc
            if n_s > 1:
                block = block[..., c]
            out[k] = block.reshape(nz, ny, nx)
            progress((k + 1) / len(chosen), f"reading {names[c]}")
    finally:
        handle.close()
    return out, [names[c] for c in chosen], [colors[c] for c in chosen], xml_text, n_time, notes


CZI_READER = ReaderSpec(
    name="czi",
    label="Zeiss CZI (.czi)",
    filename_patterns=("*.czi",),
    accepts_directories=False,
    read=read_czi,
)
