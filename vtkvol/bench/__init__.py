"""``vtkvol bench``: speed against accuracy for every illumination method.

* :mod:`~vtkvol.bench.runner`: the command (scenes × methods × settings, stability sweeps);
* :mod:`~vtkvol.bench.scenes`: phantoms, the user's ``--data`` files, sweep cases;
* :mod:`~vtkvol.bench.references`: the one CPU reference per scene and lighting model that
  every method is measured against;
* :mod:`~vtkvol.bench.reference_technique`: the renderer of reference images (same shader,
  reference volumes);
* :mod:`~vtkvol.bench.measure`: offscreen rigs, timing, checks;
* :mod:`~vtkvol.bench.report`: ``benchmarks.json``, ``.csv``, ``.md`` and charts in the output
  folder;
* :mod:`~vtkvol.bench.loadbench`: how long :func:`~vtkvol.io.read_volume` takes on a typical
  confocal stack (the load-time row of the report);
* :func:`choose` (re-exported from the product module :mod:`vtkvol.engine.auto_quality`,
  which the app's Auto quality uses): the cheapest method that meets an error budget for a
  given scene.

Importing this package loads neither VTK nor the GL code; the submodules that need them import
them.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Choice", "choose"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from vtkvol.engine import auto_quality

        return getattr(auto_quality, name)
    raise AttributeError(f"module 'vtkvol.bench' has no attribute {name!r}")
