"""Transfer-function presets (``resources/presets/transfer_functions.json``) and colormaps.

A preset is defined over 0…1 and stretched onto the channel's contrast limits, so one preset
fits 8-bit, 12-bit and float data alike. Any matplotlib colormap name (``"viridis"``,
``"magma"``…) is also a preset: its colours with the ``linear`` opacity ramp.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

from vtkvol.model.transfer_function import RGB, TransferFunction, above

COLORMAP_SAMPLES = 9


@cache
def _table() -> dict[str, dict[str, Any]]:
    text = resources.files("vtkvol.resources").joinpath("presets", "transfer_functions.json")
    data = json.loads(text.read_text(encoding="utf-8"))
    return {k: v for k, v in data.items() if not k.startswith("_")}


def preset_names(kind: str | None = None) -> list[str]:
    """Names of the built-in presets, optionally only ``"fluorescence"`` or ``"ct"`` ones."""
    return [k for k, v in _table().items() if kind is None or v["kind"] == kind]


def preset_label(name: str) -> str:
    return _table()[name]["label"] if name in _table() else name


def _colormap(name: str):
    try:
        import matplotlib

        return matplotlib.colormaps[name]
    except (ImportError, KeyError):
        return None


def is_preset(name: str) -> bool:
    return name in _table() or _colormap(name) is not None


def apply_preset(
    tf: TransferFunction, name: str, *, tint: RGB = (1.0, 1.0, 1.0),
    limits: tuple[float, float] | None = None,
) -> None:
    """Replace ``tf``'s points by preset ``name`` stretched over ``limits`` (data units;
    default: the TF's current value span). One change event."""
    lo, hi = limits if limits is not None else tf.value_span
    if not hi > lo:
        hi = above(lo)
    table = _table()

    def at(t: float) -> float:
        return lo + t * (hi - lo)

    if name in table:
        spec = table[name]
        colors = []
        for point in spec["colors"]:
            if point[1] == "tint":
                colors.append((at(point[0]), *(min(1.0, c * point[2]) for c in tint)))
            else:
                colors.append((at(point[0]), *point[1:4]))
        opacity = [(at(t), a) for t, a in spec["opacity"]]
    else:
        cmap = _colormap(name)
        if cmap is None:
            known = ", ".join(preset_names())
            raise ValueError(f"unknown preset {name!r}; use one of {known} or a colormap name")
        steps = [i / (COLORMAP_SAMPLES - 1) for i in range(COLORMAP_SAMPLES)]
        colors = [(at(t), *(float(c) for c in cmap(t)[:3])) for t in steps]
        opacity = [(at(t), a) for t, a in table["linear"]["opacity"]]
    with tf.batch():
        tf.set_window(min(lo, tf.window[0]), max(hi, tf.window[1]))
        tf.colors = colors
        tf.opacity = opacity
