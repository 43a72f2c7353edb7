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

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from pathlib import Path
from typing import Any

__version__ = "0.1.0"

# The design card's layout keeps ui/, plugins/ and resources/ beside this folder; installed,
# they are vtkvol.ui, vtkvol.plugins and vtkvol.resources (pyproject.toml's package-dir). Run
# from a source checkout — the project's editable install (the checkout on sys.path), or Python
# started inside the clone, where its vtkvol/ comes first — a finder for exactly these three
# names finds them there; nothing else of the checkout becomes part of the package.
_CHECKOUT = Path(__file__).resolve().parent.parent
_SOURCE_PARTS = {f"vtkvol.{name}": _CHECKOUT / name for name in ("ui", "plugins", "resources")}


class _CheckoutParts(importlib.abc.MetaPathFinder):
    """Finds ``vtkvol.ui``, ``vtkvol.plugins`` and ``vtkvol.resources`` in a source checkout."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None
                  ) -> importlib.machinery.ModuleSpec | None:
        folder = _SOURCE_PARTS.get(fullname)
        if folder is None or not folder.is_dir():
            return None
        init = folder / "__init__.py"
        if init.is_file():
            return importlib.util.spec_from_file_location(
                fullname, init, submodule_search_locations=[str(folder)])
        spec = importlib.machinery.ModuleSpec(fullname, None, is_package=True)
        spec.submodule_search_locations = [str(folder)]
        return spec


if ((_CHECKOUT / "pyproject.toml").is_file() and not (Path(__file__).parent / "ui").exists()
        and not any(isinstance(f, _CheckoutParts) for f in sys.meta_path)):
    sys.meta_path.append(_CheckoutParts())

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
