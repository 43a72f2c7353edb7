"""vtkvol's napari plugin (npe2 manifest ``napari.yaml``, entry point ``napari.manifest``).

* :mod:`vtkvol.napari._reader`: every format vtkvol reads → napari layers (no Qt);
* :mod:`vtkvol.napari._mapping`: napari layer properties and camera → vtkvol scene (no Qt);
* :mod:`vtkvol.napari._widget`: the "Illuminated render" dock widget and "Open in vtkvol"
  (qtpy only, never PySide6: napari may run on PyQt).

See docs/napari.md.
"""
