"""The app's pyramid view: which level it shows and why, the GPU-memory budget setting, and
the geometry of "Refine selection" / "Back to overview" (pure functions on the model's
values; no VTK, the window applies them).

World space in the app has the shown data's first voxel centre at 0 (docs/architecture.md).
A refined region is read at a finer level and shown with *its* first voxel at 0; the camera,
point lights and clipping plane move by the region's offset (µm) so the object stays where
it was on screen, and move back on "Back to overview".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from PySide6.QtCore import QSettings

from vtkvol.io import VolumeData
from vtkvol.io.pyramid import DEFAULT_GPU_BUDGET_BYTES, Region, parse_bytes
from vtkvol.io.volume_data import format_bytes
from vtkvol.model.document import is_pyramid
from vtkvol.model.scene import SceneModel

__all__ = [
    "BUDGET_CHOICES", "GPU_BUDGET_KEY", "crop_region_um", "is_pyramid", "level_text", "level_words",
    "read_budget", "restrict_weights", "shifted_view",
]

#: QSettings key of the GPU-memory budget (bytes, an integer).
GPU_BUDGET_KEY = "gpuBudgetBytes"
#: Sizes offered by the budget dialog (any other size can be typed).
BUDGET_CHOICES = ("256 MiB", "512 MiB", "1 GiB", "2 GiB", "4 GiB", "8 GiB", "16 GiB", "32 GiB")


def read_budget(settings: QSettings) -> int:
    """The budget stored in ``settings`` (bytes), or the default when absent or not a
    positive size (a hand-edited or damaged setting must not stop the app)."""
    value = settings.value(GPU_BUDGET_KEY, None)
    if value is None:
        return DEFAULT_GPU_BUDGET_BYTES
    try:
        return parse_bytes(str(value))
    except ValueError:
        return DEFAULT_GPU_BUDGET_BYTES


#: Metadata key the window sets on data it read at a level it chose itself (a session's
#: level, the overview shown before Refine selection): why that level is shown, in words.
LEVEL_WHY_KEY = "level_why"


def level_words(level: int, count: int) -> str:
    """Which of ``count`` pyramid levels ``level`` (0 = finest) is, in words that cannot be
    read as counted from the coarse end: ``"finest level (0 of 0–2)"``, ``"level 1 of 0–2
    (0 = finest)"``, ``"coarsest level (2 of 0–2)"``."""
    span = f"of 0–{count - 1}"
    if count <= 1:
        return "the only level"
    if level == 0:
        return f"finest level (0 {span})"
    if level == count - 1:
        return f"coarsest level ({level} {span})"
    return f"level {level} {span} (0 = finest)"


def level_text(data: VolumeData) -> str:
    """``"level 2 of 0–4 (0 = finest), 512×512×128, finest that fits 1 GiB"`` (plus the
    region when one was read); empty for data that is not a pyramid level."""
    if not is_pyramid(data):
        return ""
    meta = data.metadata
    _, z, y, x = data.array.shape
    budget = meta.get("budget_bytes")
    reason = str(meta.get("level_reason", ""))
    if meta.get(LEVEL_WHY_KEY):
        why = str(meta[LEVEL_WHY_KEY])
    elif reason == "level chosen by the caller":
        # Read at the level already on screen (another time point of it).
        why = "the level already shown"
    elif isinstance(budget, int):
        why = f"finest that fits {format_bytes(budget)}"
    else:
        why = reason
    text = f"{level_words(int(meta['level']), len(meta['levels']))}, {x}×{y}×{z}, {why}"
    region = meta.get("region_um")
    if region:
        text += ", region " + " × ".join(
            f"{a} {lo:.4g}–{hi:.4g}" for a, (lo, hi) in zip("xyz", region, strict=True)) + " µm"
    return text


def crop_region_um(data: VolumeData, crop: Any) -> Region:
    """The crop box of the view as a region in pyramid µm, widened by half a shown voxel on
    each side (the coarse voxels' own extent, which the finer voxels fill)."""
    origin = data.metadata.get("origin_um") or [0.0, 0.0, 0.0]
    _, nz, ny, nx = data.array.shape
    region = []
    for i, (axis, n) in enumerate(zip("xyz", (nx, ny, nz), strict=True)):
        s = float(data.voxel_size_um[i])
        lo, hi = getattr(crop, axis) or (0.0, (n - 1) * s)
        lo, hi = max(0.0, lo), min((n - 1) * s, hi)
        region.append((origin[i] + lo - s / 2, origin[i] + hi + s / 2))
    return tuple(region)  # type: ignore[return-value]


def restrict_weights(points: Sequence[tuple[float, float]], lo: float, hi: float,
                     ) -> list[tuple[float, float]]:
    """The slice-weight function ``points`` (positions 0…1 over the old extent) restricted to
    the part ``lo…hi`` (fractions of the old extent), re-normalised to 0…1."""
    import numpy as np

    pts = sorted((float(p), float(w)) for p, w in points)
    xs, ws = np.array([p for p, _ in pts]), np.array([w for _, w in pts])
    span = hi - lo
    if span <= 0:
        return [(0.0, float(np.interp(lo, xs, ws))), (1.0, float(np.interp(lo, xs, ws)))]
    inner = [(float((p - lo) / span), w) for p, w in pts if lo < p < hi]
    ends = [(0.0, float(np.interp(lo, xs, ws))), (1.0, float(np.interp(hi, xs, ws)))]
    return sorted(set([ends[0], *inner, ends[1]]))


def shifted_view(model: SceneModel, offset: Sequence[float],
                 centre: Sequence[float] | None = None) -> dict[str, Any]:
    """``model.update`` mapping that moves the camera, point lights and the clipping plane by
    ``-offset`` (x, y, z µm): what sat at world position p now sits at p − offset, where the
    same object is once data whose first voxel lies ``offset`` further on is shown.
    ``centre``: the old data's centre (µm), the clipping plane's origin when it followed it."""
    ox, oy, oz = (float(v) for v in offset)

    def move(p: Sequence[float] | None) -> tuple[float, float, float] | None:
        return None if p is None else (p[0] - ox, p[1] - oy, p[2] - oz)

    cam = model.camera
    out: dict[str, Any] = {}
    if cam.position is not None and cam.focal_point is not None:
        out["camera"] = {"position": move(cam.position), "focal_point": move(cam.focal_point)}
    out["lights"] = [
        {**light.model_dump(), "position": move(light.position)} if light.kind == "point"
        else light.model_dump() for light in model.lights]
    clip = model.clip_plane
    if clip.origin is not None:
        out["clip_plane"] = {"origin": move(clip.origin)}
    elif clip.enabled and centre is not None:
        out["clip_plane"] = {"origin": move(centre)}
    return out


def offset_between(old: VolumeData, new: VolumeData) -> tuple[float, float, float]:
    """Where ``new``'s first voxel centre lies in ``old``'s world (µm): the shift of the view."""
    a = old.metadata.get("origin_um") or [0.0, 0.0, 0.0]
    b = new.metadata.get("origin_um") or [0.0, 0.0, 0.0]
    return tuple(float(q) - float(p) for p, q in zip(a, b, strict=True))  # type: ignore[return-value]


def data_centre(data: VolumeData) -> tuple[float, float, float]:
    """The centre of ``data``'s voxel-centre box in its own world (µm)."""
    _, nz, ny, nx = data.array.shape
    return tuple((n - 1) * s / 2 for n, s in  # type: ignore[return-value]
                 zip((nx, ny, nz), data.voxel_size_um, strict=True))


def weight_fractions(data: VolumeData, region: Region) -> list[tuple[float, float]]:
    """Per axis, ``region`` (pyramid µm) as fractions of ``data``'s voxel-centre extent."""
    origin = data.metadata.get("origin_um") or [0.0, 0.0, 0.0]
    _, nz, ny, nx = data.array.shape
    out = []
    for i, n in enumerate((nx, ny, nz)):
        extent = (n - 1) * float(data.voxel_size_um[i])
        lo, hi = region[i]
        if extent <= 0 or not math.isfinite(extent):
            out.append((0.0, 1.0))
            continue
        out.append((min(1.0, max(0.0, (lo - origin[i]) / extent)),
                    min(1.0, max(0.0, (hi - origin[i]) / extent))))
    return out
