"""Length units found in microscopy metadata, converted to µm."""

from __future__ import annotations

import math
import re

__all__ = ["length_to_um", "unit_scale_um"]

# Exact (case-sensitive) spellings first: "Mm" (megametre) and "mm" must not be confused.
_EXACT: dict[str, float] = {
    "am": 1e-12,
    "fm": 1e-9,
    "pm": 1e-6,
    "\u00c5": 1e-4,  # LATIN CAPITAL LETTER A WITH RING ABOVE (OME's symbol)
    "\u212b": 1e-4,  # ANGSTROM SIGN
    "nm": 1e-3,
    "µm": 1.0,  # MICRO SIGN (U+00B5)
    "μm": 1.0,  # GREEK SMALL LETTER MU (U+03BC)
    "um": 1.0,
    "mm": 1e3,
    "cm": 1e4,
    "dm": 1e5,
    "m": 1e6,
    "dam": 1e7,
    "hm": 1e8,
    "km": 1e9,
    "Mm": 1e12,
}

# Case-insensitive words used by ImageJ, NRRD, LSM and friends.
_WORDS: dict[str, float] = {
    "angstrom": 1e-4,
    "angstroms": 1e-4,
    "nanometer": 1e-3,
    "nanometers": 1e-3,
    "nanometre": 1e-3,
    "nanometres": 1e-3,
    "micron": 1.0,
    "microns": 1.0,
    "micrometer": 1.0,
    "micrometers": 1.0,
    "micrometre": 1.0,
    "micrometres": 1.0,
    "millimeter": 1e3,
    "millimeters": 1e3,
    "millimetre": 1e3,
    "millimetres": 1e3,
    "centimeter": 1e4,
    "centimeters": 1e4,
    "centimetre": 1e4,
    "centimetres": 1e4,
    "meter": 1e6,
    "meters": 1e6,
    "metre": 1e6,
    "metres": 1e6,
    "in": 25400.0,
    "inch": 25400.0,
    "inches": 25400.0,
    '"': 25400.0,
    "thou": 25.4,
    "mil": 25.4,
    "ft": 304800.0,
    "feet": 304800.0,
    "foot": 304800.0,
}

_ESCAPE = re.compile(r"\\u([0-9a-fA-F]{4})")


def unit_scale_um(unit: str | None) -> float | None:
    """How many µm one ``unit`` is, or None if the unit is unknown or not a length.

    Understands SI prefixes (``nm``, ``µm``/``um``/``micron``, ``mm``, ``m``…), ImageJ's
    escaped ``\\u00B5m``, inches, and OME-XML's unit symbols. ``pixel``, empty strings and
    anything unrecognised give None, meaning "no physical size known".
    """
    if unit is None:
        return None
    # ImageJ writes non-ASCII characters as Java escapes in its description ("\u00B5m").
    text = _ESCAPE.sub(lambda m: chr(int(m.group(1), 16)), str(unit)).strip().strip("'\"")
    if not text:
        return None
    if text in _EXACT:
        return _EXACT[text]
    lowered = text.lower()
    if lowered in _EXACT:
        return _EXACT[lowered]
    return _WORDS.get(lowered)


def length_to_um(value: float | str | None, unit: str | None) -> float | None:
    """Convert ``value`` in ``unit`` to µm; None if either is missing, invalid or ≤ 0."""
    if value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    scale = unit_scale_um(unit)
    if scale is None or not math.isfinite(number) or number <= 0:
        return None
    return number * scale
