"""What a TIFF says about its voxels (:mod:`vtkvol.io.tiff`'s metadata half): voxel size from
OME-XML, ImageJ's description, LSM's tags or plain resolution tags (in that order, with the
unit conversions and the "no size given" defaults), channel names, bit depth and the format's
name. Package-private: the TIFF reader is its only user."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from contextlib import suppress
from dataclasses import dataclass, field
from typing import Any

import tifffile

from vtkvol.io.units import length_to_um, unit_scale_um
from vtkvol.io.volume_data import Spacing, default_channel_names

#: Resolutions (dots per inch) that scanners and editors write by default: not a pixel size.
_DEFAULT_DPI = {1.0, 72.0, 96.0, 150.0, 300.0, 600.0}

# -- metadata --------------------------------------------------------------------------------
@dataclass
class _VoxelInfo:
    x: float | None = None
    y: float | None = None
    z: float | None = None
    sources: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _tag_value(page: Any, name: str) -> Any:
    tag = page.tags.get(name)
    return None if tag is None else tag.value


def _pixels_per_unit(value: Any) -> float | None:
    if value is None:
        return None
    try:
        if isinstance(value, (tuple, list)):
            num, den = float(value[0]), float(value[1])
            ppu = num / den if den else 0.0
        else:
            ppu = float(value)
    except (TypeError, ValueError, IndexError):
        return None
    return ppu if math.isfinite(ppu) and ppu > 0 else None


def _resolution_um(page: Any, unit_um: float | None) -> tuple[float | None, float | None]:
    """Pixel size (x, y) in µm from X/YResolution (pixels per unit) and a unit in µm."""
    if unit_um is None:
        return None, None
    xppu = _pixels_per_unit(_tag_value(page, "XResolution"))
    yppu = _pixels_per_unit(_tag_value(page, "YResolution"))
    x = unit_um / xppu if xppu else None
    y = unit_um / yppu if yppu else None
    return x, (y if y is not None else x)


def _resolution_unit_um(page: Any) -> float | None:
    value = _tag_value(page, "ResolutionUnit")
    try:
        code = int(value) if value is not None else 2  # TIFF default: inch
    except (TypeError, ValueError):
        return None
    # 1 none, 2 inch, 3 cm; 4 mm and 5 µm are tifffile extensions seen in the wild.
    return {2: 25400.0, 3: 1e4, 4: 1e3, 5: 1.0}.get(code)


def _ome_pixels(tif: tifffile.TiffFile, series_index: int) -> ET.Element | None:
    text = tif.ome_metadata
    if not text:
        return None
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return None
    images = [el for el in root if el.tag.rsplit("}", 1)[-1] == "Image"]
    if not images:
        return None
    image = images[min(series_index, len(images) - 1)]
    for el in image:
        if el.tag.rsplit("}", 1)[-1] == "Pixels":
            return el
    return None


def _ome_voxel(pixels: ET.Element) -> _VoxelInfo:
    info = _VoxelInfo()
    for axis in "XYZ":
        raw = pixels.get(f"PhysicalSize{axis}")
        if raw is None:
            continue
        unit = pixels.get(f"PhysicalSize{axis}Unit", "µm")  # OME's default unit is µm
        value = length_to_um(raw, unit)
        if value is None:
            info.notes.append(
                f"OME PhysicalSize{axis}={raw} {unit} is not a usable length; ignored"
            )
            continue
        setattr(info, axis.lower(), value)
    if info.x or info.y or info.z:
        info.sources.append("OME PhysicalSize")
    return info


def _ome_channel_names(pixels: ET.Element) -> list[str]:
    names: list[str] = []
    for el in pixels:
        if el.tag.rsplit("}", 1)[-1] != "Channel":
            continue
        name = el.get("Name") or el.get("Fluor") or ""
        samples = int(el.get("SamplesPerPixel", "1") or 1)
        names.extend([name] if samples == 1 else [f"{name} {i}" for i in range(samples)])
    return names


def _imagej_voxel(tif: tifffile.TiffFile, page: Any) -> _VoxelInfo:
    info = _VoxelInfo()
    ij = tif.imagej_metadata or {}
    unit = ij.get("unit")
    assume_um = False
    if unit is not None:
        unit_um = unit_scale_um(unit)  # None for "pixel": not calibrated
    elif _tag_value(page, "ResolutionUnit") not in (None, 1):
        unit_um = _resolution_unit_um(page)
    else:
        # Calibrated ImageJ files always name a unit; writers that leave it out mean µm.
        unit_um, assume_um = 1.0, True
    x, y = _resolution_um(page, unit_um)
    if x is not None and not (assume_um and x == 1.0 and y == 1.0):
        info.x, info.y = x, y
        info.sources.append("TIFF resolution tags (x, y)")
    spacing = ij.get("spacing")
    zunit = ij.get("zunit", unit)
    z_scale = 1.0 if zunit is None and assume_um else unit_scale_um(zunit)
    z = length_to_um(spacing, "um") if spacing is not None and z_scale else None
    if z is not None and z_scale:
        info.z = z * z_scale
        info.sources.append("ImageJ spacing (z)")
    if assume_um and (info.sources):
        info.notes.append("the ImageJ metadata names no unit; µm assumed")
    return info


def _lsm_voxel(tif: tifffile.TiffFile) -> _VoxelInfo:
    info = _VoxelInfo()
    lsm = tif.lsm_metadata or {}
    for axis in "XYZ":
        value = length_to_um(lsm.get(f"VoxelSize{axis}"), "m")  # LSM stores metres
        setattr(info, axis.lower(), value)
    if info.x or info.y or info.z:
        info.sources.append("Zeiss LSM voxel sizes")
    return info


def _plain_voxel(page: Any) -> _VoxelInfo:
    info = _VoxelInfo()
    unit_um = _resolution_unit_um(page)
    x, y = _resolution_um(page, unit_um)
    if x is None:
        return info
    if (
        unit_um == 25400.0
        and y is not None
        and {round(25400.0 / x, 3), round(25400.0 / y, 3)} <= _DEFAULT_DPI
    ):
        info.notes.append(
            f"resolution {25400.0 / x:g} dpi ignored: a display/print default, not a pixel size"
        )
        return info
    info.x, info.y = x, y
    info.sources.append("TIFF resolution tags (x, y)")
    return info


def _voxel_info(tif: tifffile.TiffFile, page: Any, series_index: int) -> _VoxelInfo:
    pixels = _ome_pixels(tif, series_index) if tif.is_ome else None
    if pixels is not None:
        info = _ome_voxel(pixels)
        if info.x or info.y or info.z:
            return info
    if tif.is_imagej:
        return _imagej_voxel(tif, page)
    if tif.is_lsm:
        info = _lsm_voxel(tif)
        if info.x or info.y:
            return info
    return _plain_voxel(page)


def _finish_voxel_size(info: _VoxelInfo, n_z: int) -> tuple[Spacing, bool, str, list[str]]:
    """Fill gaps (y from x, z from x) and say where each value came from."""
    notes = list(info.notes)
    x, y, z = info.x, info.y, info.z
    if x is None and y is not None:
        x = y
    if y is None and x is not None:
        y = x
    from_metadata = x is not None
    source_text = "; ".join(info.sources)
    if x is None:
        x = y = 1.0
        if z is None:
            notes.append(
                "voxel size not stored in the file: using 1 × 1 × 1 µm (pass voxel_size_um to "
                "set it)"
            )
            return Spacing(1.0, 1.0, 1.0), False, "not in file; default 1 µm", notes
        notes.append("x/y pixel size not stored in the file: using 1 µm")
        source_text = f"x, y default 1 µm; {source_text}"
    if z is None:
        z = x
        if n_z > 1:
            from_metadata = False
            notes.append(f"z spacing not stored in the file: assumed equal to x ({x:g} µm)")
            source_text = f"{source_text}; z assumed equal to x"
    assert y is not None
    return Spacing(float(x), float(y), float(z)), from_metadata, source_text, notes


def _channel_names(
    tif: tifffile.TiffFile, series: Any, plan: Any, series_index: int
) -> list[str]:
    """The channel names of ``series`` (OME's, ImageJ's labels, or defaults); ``plan`` is the
    reader's axis plan (``vtkvol.io.tiff._AxisPlan``: ``n_channels`` is read)."""
    n = plan.n_channels
    if tif.is_ome:
        pixels = _ome_pixels(tif, series_index)
        if pixels is not None:
            names = _ome_channel_names(pixels)
            if len(names) == n and all(names):
                return names
    page = series.keyframe
    c_axes = [a for a, r in zip(plan.axes, plan.roles, strict=True) if r == "c"]
    photometric = int(getattr(page, "photometric", 0) or 0)
    if c_axes == ["S"] and photometric == 2 and n in (3, 4):  # RGB(A)
        return ["red", "green", "blue", "alpha"][:n]
    return default_channel_names(n)


def _bit_depth(tif: tifffile.TiffFile, page: Any, series_index: int) -> int | None:
    bits = int(getattr(page, "bitspersample", 0) or 0)
    itemsize_bits = page.dtype.itemsize * 8 if page.dtype is not None else 0
    if 0 < bits < itemsize_bits:
        return bits
    if tif.is_ome:
        pixels = _ome_pixels(tif, series_index)
        if pixels is not None:
            with suppress(TypeError, ValueError):
                significant = int(pixels.get("SignificantBits", "0"))
                if 0 < significant < itemsize_bits:
                    return significant
    return None


def _format_name(tif: tifffile.TiffFile) -> str:
    if tif.is_ome:
        return "ome-tiff"
    if tif.is_imagej:
        return "imagej-tiff"
    if tif.is_lsm:
        return "zeiss-lsm"
    return "tiff"
