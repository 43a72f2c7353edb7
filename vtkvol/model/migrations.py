"""Session-file versions and the step-wise migrations between them (pure functions on dicts).

A session file carries ``"format": "vtkvol-session"`` and an integer ``"version"``. Reading
runs :func:`migrate`, which applies one migration per version step (``v0→v1``, later
``v1→v2``, …) until the file has the layout this vtkvol writes, and only then validates it.
Each migration is a pure function ``dict -> dict`` (no I/O, no clock, input untouched) with a
fixture in ``tests/fixtures/sessions/`` that pins its behaviour. See docs/session-format.md.

Adding version 2: write ``_v1_to_v2``, register it in :data:`MIGRATIONS`, bump
:data:`VERSION`, add a v1 fixture and its expected v2 output, and document the change.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

__all__ = ["FORMAT", "MIGRATIONS", "V0_SCENE_KEYS", "VERSION", "detect_version", "migrate"]

FORMAT = "vtkvol-session"
"""The value of the top-level ``"format"`` key: what makes a JSON file a vtkvol session."""

VERSION = 12
"""The format version this vtkvol writes, and the newest it reads."""

V0_SCENE_KEYS: tuple[str, ...] = (
    "volume", "channels", "lights", "illumination", "crop", "slice_weights", "camera", "render",
)
"""Top-level keys of a version-0 (pre-release) file: the scene's fields, frozen as they were.

This list is history, not a description of the current model, so it is kept by hand on
purpose: it must not change when :class:`~vtkvol.model.SceneModel` gains fields.
"""

_DATA_RECORD_KEYS = ("size_bytes", "sha256_head", "shape_zyx", "channels")

Migration = Callable[[dict[str, Any]], dict[str, Any]]


def detect_version(raw: dict[str, Any]) -> int:
    """The format version of a parsed session file.

    Version 0 is the pre-release layout: no ``"format"``/``"version"`` keys, the scene's fields
    directly at the top level.

    Raises
    ------
    ValueError
        If ``raw`` is not a vtkvol session at all, or its version is not a whole number ≥ 0.
    """
    if "format" not in raw:
        if any(key in raw for key in V0_SCENE_KEYS):
            return 0
        raise ValueError(
            f'not a vtkvol session (no "format": "{FORMAT}" key and no scene settings)'
        )
    if raw["format"] != FORMAT:
        raise ValueError(
            f'not a vtkvol session ("format" is {raw["format"]!r}, expected {FORMAT!r})'
        )
    version = raw.get("version")
    # bool is an int subclass; "version": true is a broken file, not version 1.
    if isinstance(version, bool) or not isinstance(version, int) or version < 0:
        raise ValueError(f'"version" must be a whole number ≥ 0, not {version!r}')
    return version


def _v0_to_v1(raw: dict[str, Any]) -> dict[str, Any]:
    """v0 → v1: move the scene under ``"scene"``, add the envelope and the ``"data"`` record.

    v0 kept the data file only in ``volume.path`` (absolute, or relative to the session's
    folder, the same rule as v1). v1 copies it, and whatever fingerprint ``volume`` recorded,
    into ``"data"``. An optional v0 ``"window"`` object is kept; other top-level keys are kept
    as they are, so the reader can warn about them.
    """
    scene = {key: raw[key] for key in V0_SCENE_KEYS if key in raw}
    volume = scene.get("volume") if isinstance(scene.get("volume"), dict) else {}
    data: dict[str, Any] = {"path": volume.get("path")}
    data.update({key: volume.get(key) for key in _DATA_RECORD_KEYS})
    rest = {key: value for key, value in raw.items() if key not in V0_SCENE_KEYS}
    rest.pop("window", None)
    return {
        "format": FORMAT,
        "version": 1,
        "vtkvol": None,  # v0 files did not record the writer
        "saved": None,
        "data": data,
        "scene": scene,
        "window": raw.get("window", {}),
        **rest,
    }


def _v1_to_v2(raw: dict[str, Any]) -> dict[str, Any]:
    """v1 → v2: lights gained a physical ``size`` and a distance ``falloff``; render settings
    gained the ``medium`` material (``albedo``, ``phase_g``). v1 lights were ideal (size 0) and
    did not fall off with distance, which the new defaults state exactly; v1 had no medium
    techniques, so the material's defaults change nothing."""
    out = copy.deepcopy(raw)
    out["version"] = 2
    scene = out.get("scene")
    render = scene.get("render") if isinstance(scene, dict) else None
    if isinstance(render, dict):
        render.setdefault("albedo", 1.0)
        render.setdefault("phase_g", 0.0)
    lights = scene.get("lights") if isinstance(scene, dict) else None
    if isinstance(lights, list):
        for light in lights:
            if isinstance(light, dict):
                light.setdefault("size", 0.0)
                light.setdefault("falloff", "none")
    return out


def _v2_to_v3(raw: dict[str, Any]) -> dict[str, Any]:
    """v2 → v3: the scene gained ``overlays`` (scale bar, orientation axes, bounding box,
    colour legend). v2 drew none of them, which the all-off section states exactly."""
    out = copy.deepcopy(raw)
    out["version"] = 3
    scene = out.get("scene")
    if isinstance(scene, dict):
        scene.setdefault("overlays", {"scale_bar": False, "orientation_axes": False,
                                      "bounding_box": False, "color_legend": False})
    return out


def _v3_to_v4(raw: dict[str, Any]) -> dict[str, Any]:
    """v3 → v4: render settings gained ``interpolation`` (the scalar reconstruction filter).
    v3 rendered with the GPU's trilinear filter, which ``"trilinear"`` states exactly."""
    out = copy.deepcopy(raw)
    out["version"] = 4
    scene = out.get("scene")
    render = scene.get("render") if isinstance(scene, dict) else None
    if isinstance(render, dict):
        render.setdefault("interpolation", "trilinear")
    return out


def _v4_to_v5(raw: dict[str, Any]) -> dict[str, Any]:
    """v4 → v5: the scene gained ``clip_plane`` (the oblique clipping plane). v4 had none,
    which a disabled plane states exactly."""
    out = copy.deepcopy(raw)
    out["version"] = 5
    scene = out.get("scene")
    if isinstance(scene, dict):
        scene.setdefault("clip_plane", {"enabled": False, "origin": None,
                                        "normal": [0.0, 0.0, 1.0]})
    return out


def _v5_to_v6(raw: dict[str, Any]) -> dict[str, Any]:
    """v5 → v6: new settings, each filled with the value that states exactly what v5 showed.

    * the scene gained the slice views' ``cursor`` (world µm; ``null``: the data's centre) and
      the overlays ``slice_planes`` (off: v5 had no slice views);
    * each channel gained ``tf_mode`` and ``tf2d``, the 2-D transfer function over value ×
      gradient magnitude with its painted layer ``paint`` (``"1d"`` and an empty 2-D TF, nothing
      painted: v5 classified by the 1-D ``tf``);
    * ``volume`` gained ``level`` and ``region_um``, the pyramid level and refined region
      shown (``null``: the level the budget chooses, the whole image);
    * ``illumination`` gained ``auto`` and ``auto_budget_ssim``, the app's Auto quality (off:
      v5 showed the method it named; the budget's default, SSIM 0.98);
    * ``render`` gained ``empty_space_skipping`` (on: skipping is exact, the image is the one
      v5 rendered within one 8-bit level).
    """
    out = copy.deepcopy(raw)
    out["version"] = 6
    scene = out.get("scene")
    if not isinstance(scene, dict):
        return out
    scene.setdefault("cursor", None)
    if isinstance(scene.get("overlays"), dict):
        scene["overlays"].setdefault("slice_planes", False)
    if isinstance(scene.get("channels"), list):
        for channel in scene["channels"]:
            if isinstance(channel, dict):
                channel.setdefault("tf_mode", "1d")
                channel.setdefault("tf2d", {"primitives": [], "gradient_max": None,
                                          "paint": None})
    if isinstance(scene.get("volume"), dict):
        scene["volume"].setdefault("level", None)
        scene["volume"].setdefault("region_um", None)
    if isinstance(scene.get("illumination"), dict):
        scene["illumination"].setdefault("auto", False)
        scene["illumination"].setdefault("auto_budget_ssim", 0.98)
    if isinstance(scene.get("render"), dict):
        scene["render"].setdefault("empty_space_skipping", True)
    return out


def _v6_to_v7(raw: dict[str, Any]) -> dict[str, Any]:
    """v6 → v7: ``render`` gained ``multichannel_lighting``, filled with ``"per_channel"``:
    every channel lit with its own normal, which is how v6 rendered (the same image)."""
    out = copy.deepcopy(raw)
    out["version"] = 7
    scene = out.get("scene")
    if isinstance(scene, dict) and isinstance(scene.get("render"), dict):
        scene["render"].setdefault("multichannel_lighting", "per_channel")
    return out


def _v7_to_v8(raw: dict[str, Any]) -> dict[str, Any]:
    """v7 → v8: ``render`` gained ``renderer``, filled with ``"raycast"``: VTK's ray caster
    drew every v7 volume (the same image)."""
    out = copy.deepcopy(raw)
    out["version"] = 8
    scene = out.get("scene")
    if isinstance(scene, dict) and isinstance(scene.get("render"), dict):
        scene["render"].setdefault("renderer", "raycast")
    return out


def _v8_to_v9(raw: dict[str, Any]) -> dict[str, Any]:
    """v8 → v9: ``render`` gained ``exposure``, ``auto_exposure`` and ``fill``, filled with 1,
    off and 0: no exposure change and no fill light, which is how v8 rendered (new sessions
    get automatic exposure and a little fill). The diffusion techniques lost
    ``convection_extinction`` (their old diffusion is gone, docs/multiple-scattering.md):
    ``"paper"`` (seed 003's absorption-only convection) becomes ``diffusion_model:
    "published"``, the other value is dropped (the new default model takes its place)."""
    out = copy.deepcopy(raw)
    out["version"] = 9
    scene = out.get("scene")
    if not isinstance(scene, dict):
        return out
    if isinstance(scene.get("render"), dict):
        scene["render"].setdefault("exposure", 1.0)
        scene["render"].setdefault("auto_exposure", False)
        scene["render"].setdefault("fill", 0.0)
    illumination = scene.get("illumination")
    parameters = illumination.get("parameters") if isinstance(illumination, dict) else None
    if isinstance(parameters, dict):
        for method in ("convection_diffusion", "hybrid_diffusion"):
            values = parameters.get(method)
            if (isinstance(values, dict) and "convection_extinction" in values
                    and values.pop("convection_extinction") == "paper"):
                values.setdefault("diffusion_model", "published")
    return out


def _v9_to_v10(raw: dict[str, Any]) -> dict[str, Any]:
    """v9 → v10: every channel gained ``gamma``, filled with 1 (the transfer function as
    drawn), and ``labels``, filled with null (values shown as intensities): how v9 showed
    them (the same image; a v9 file saved from ``vtkvol render --labels`` holds the label
    colours in its transfer function already)."""
    out = copy.deepcopy(raw)
    out["version"] = 10
    scene = out.get("scene")
    channels = scene.get("channels") if isinstance(scene, dict) else None
    if isinstance(channels, list):
        for channel in channels:
            if isinstance(channel, dict):
                channel.setdefault("gamma", 1.0)
                channel.setdefault("labels", None)
    return out


def _v10_to_v11(raw: dict[str, Any]) -> dict[str, Any]:
    """v10 → v11: render settings gained ``preintegration`` and ``adaptive_sampling``, both
    filled with false (every sample post-classified, every step taken: how v10 rendered)."""
    out = copy.deepcopy(raw)
    out["version"] = 11
    scene = out.get("scene")
    render = scene.get("render") if isinstance(scene, dict) else None
    if isinstance(render, dict):
        render.setdefault("preintegration", False)
        render.setdefault("adaptive_sampling", False)
    return out


def _v11_to_v12(raw: dict[str, Any]) -> dict[str, Any]:
    """v11 → v12: the grid-diffusion techniques gained ``traced_orders`` (default 3: the first
    scattering orders traced per voxel). Their parameters in a v11 file get ``traced_orders:
    0`` where it applies (the source model, the default, with diffusion steps), the diffusion
    from the direct light alone: how v11 rendered them."""
    out = copy.deepcopy(raw)
    out["version"] = 12
    scene = out.get("scene")
    illumination = scene.get("illumination") if isinstance(scene, dict) else None
    parameters = illumination.get("parameters") if isinstance(illumination, dict) else None
    if isinstance(parameters, dict):
        for method in ("convection_diffusion", "hybrid_diffusion"):
            values = parameters.get(method)
            if (isinstance(values, dict)
                    and values.get("diffusion_model", "source") == "source"
                    and values.get("diffusion_steps", 1) != 0):
                values.setdefault("traced_orders", 0)
    return out


MIGRATIONS: dict[int, Migration] = {0: _v0_to_v1, 1: _v1_to_v2, 2: _v2_to_v3, 3: _v3_to_v4,
                                    4: _v4_to_v5, 5: _v5_to_v6, 6: _v6_to_v7, 7: _v7_to_v8,
                                    8: _v8_to_v9, 9: _v9_to_v10,
                                    10: _v10_to_v11, 11: _v11_to_v12}
"""``{from_version: step}``: each step turns version ``n`` into version ``n + 1``."""


def migrate(raw: dict[str, Any]) -> dict[str, Any]:
    """Bring a parsed session file to the current :data:`VERSION`, one step at a time.

    Pure: ``raw`` is not modified (it is deep-copied first) and nothing is read or written.
    A file already at :data:`VERSION` comes back as an equal copy.

    Raises
    ------
    ValueError
        If ``raw`` is not a session, or was written by a newer vtkvol (its version is above
        :data:`VERSION`); the message says so in words, for the user.
    """
    version = detect_version(raw)
    if version > VERSION:
        raise ValueError(
            f"written by a newer vtkvol (format version {version}; "
            f"this version reads up to {VERSION})"
        )
    out = copy.deepcopy(raw)
    while version < VERSION:
        out = MIGRATIONS[version](out)
        version += 1
        # A step that forgets to stamp its version would loop or skip silently; fail loudly.
        if out.get("version") != version:
            raise AssertionError(f"migration to version {version} did not set it")
    return out
