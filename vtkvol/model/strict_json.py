"""JSON as vtkvol's own files (sessions, keyframes, transfer functions) accept it: only finite
numbers, and a nesting depth that is counted without recursion, so that a hostile file is
refused with a message instead of a ``RecursionError`` or an infinity in the model."""

from __future__ import annotations

import json
import math
from typing import Any


def loads(text: str) -> Any:
    """``json.loads`` refusing ``NaN``, ``Infinity`` and numbers that overflow to infinity
    (``1e999``) with a ``ValueError``; deep nesting still raises ``RecursionError``, which
    callers turn into their own message."""
    return json.loads(text, parse_constant=_reject_constant, parse_float=_finite_float)


def nesting_depth(value: Any, stop_above: int = 64) -> int:
    """How deeply JSON objects and lists nest in ``value`` (counted without recursion; the
    count stops once it passes ``stop_above``)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            deepest = max(deepest, depth)
            if depth > stop_above:
                break
            children = item.values() if isinstance(item, dict) else item
            stack.extend((child, depth + 1) for child in children)
    return deepest


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number JSON allows")


def _finite_float(text: str) -> float:
    # 1e999 parses to infinity without complaint; no file of ours ever needs it.
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is too large a number")
    return value
