"""Readers whose format library is an optional extra (``pip install 'vtkvol[formats]'``)."""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

from vtkvol.io.errors import VolumeReadError

__all__ = ["require"]


def require(module: str, what: str, path: Path) -> ModuleType:
    """Import ``module`` or say which extra to install, naming the file and the format."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise VolumeReadError(
            path,
            f"reading {what} needs the optional package {module.split('.')[0]!r}: "
            "pip install 'vtkvol[formats]'",
        ) from None
