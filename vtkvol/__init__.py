"""vtkvol: volume rendering of microscopy data with real illumination, inside VTK's ray caster.

The library never imports Qt. Its public calls are loaded lazily, so ``import vtkvol.model``
stays free of VTK::

    import vtkvol
    data = vtkvol.read_volume("cells.tif")                     # VolumeData, [c, z, y, x]
    image = vtkvol.render_image(data, method="shadow_volume")   # (h, w, 3) uint8, offscreen

    # give an existing VTK / PyVista volume our illumination:
    actor = plotter.add_volume(grid, mapper="gpu")
    vtkvol.illuminate(actor, plotter, method="shadow_volume")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__version__ = "0.1.0"

# The design card's layout keeps ui/, plugins/ and resources/ beside this folder; installed,
# they are vtkvol.ui, vtkvol.plugins and vtkvol.resources (pyproject.toml's package-dir). Run
# from a source checkout — the project's editable install (a path to the checkout), or Python
# started inside the clone, where its vtkvol/ comes first — the checkout's root is searched
# for vtkvol's subpackages too, so they are found without any installed finder.
_checkout = Path(__file__).resolve().parent.parent
if (_checkout / "pyproject.toml").is_file() and (_checkout / "plugins").is_dir():
    __path__.append(str(_checkout))

_LAZY = {
    "read_volume": ("vtkvol.io", "read_volume"),
    "VolumeData": ("vtkvol.io", "VolumeData"),
    "SceneModel": ("vtkvol.model", "SceneModel"),
    "Light": ("vtkvol.model", "Light"),
    "illuminate": ("vtkvol.engine.api", "illuminate"),
    "render_image": ("vtkvol.engine.api", "render_image"),
    "Illuminator": ("vtkvol.engine.illuminator", "Illuminator"),
    "VolumeScene": ("vtkvol.engine.scene", "VolumeScene"),
}

__all__ = [*_LAZY, "__version__"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'vtkvol' has no attribute {name!r}")
