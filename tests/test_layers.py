"""Import direction is the architecture: the library never imports Qt; io and model no VTK."""

from __future__ import annotations

import subprocess
import sys

import pytest


def imported_after(modules: list[str]) -> set[str]:
    code = (
        "import importlib, sys\n"
        f"for m in {modules!r}:\n"
        "    importlib.import_module(m)\n"
        "print('\\n'.join(sys.modules))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return set(result.stdout.split())


def test_library_never_imports_qt():
    from vtkvol.engine.technique import installed_techniques

    library = [
        "vtkvol", "vtkvol.io", "vtkvol.model", "vtkvol.engine.api", "vtkvol.engine.scene",
        "vtkvol.reference", "vtkvol.cli",
        *(cls.__module__ for cls in installed_techniques().values()),
    ]
    loaded = imported_after(library)
    qt = sorted(m for m in loaded if m.startswith(("PySide6", "pyvistaqt", "qtpy", "superqt")))
    assert qt == []


@pytest.mark.parametrize("package", ["vtkvol.io", "vtkvol.model", "vtkvol.reference"])
def test_io_model_and_references_do_not_import_vtk(package):
    loaded = imported_after([package])
    assert not any(m == "vtk" or m.startswith("vtkmodules") for m in loaded)


def test_slice_views_do_not_import_vtk():
    """ui/viewport.py is the only ui module that touches VTK: the slice views paint numpy
    slices (vtkvol.engine.slices, pure numpy) with Qt."""
    loaded = imported_after(["vtkvol.engine.slices", "vtkvol.ui.docks.slice_views"])
    assert "vtkvol.ui.docks.slice_views" in loaded
    assert not any(m == "vtk" or m.startswith("vtkmodules") for m in loaded)


def test_only_the_viewport_and_the_app_load_vtk_in_the_ui():
    """Every ui module but the viewport (and the app, which holds it) binds widgets to the
    model without VTK: the error dialogs catch ``GLUnavailableError`` from the VTK-free
    ``vtkvol.engine.errors``, so the docks that show errors load no VTK either."""
    from pathlib import Path

    ui = Path(__file__).resolve().parents[1] / "ui"  # installed as vtkvol.ui
    modules = sorted(
        "vtkvol." + ".".join(p.relative_to(ui.parent).with_suffix("").parts).removesuffix(
            ".__init__")
        for p in ui.rglob("*.py"))
    # The window's own parts reach the 3-D view (menus, measurement, light handle, status and
    # time bars, the edit watcher): they are the app, split into modules.
    window_parts = ("vtkvol.ui.viewport", "vtkvol.ui.app", "vtkvol.ui.measure",
                    "vtkvol.ui.light_handle", "vtkvol.ui.edit_watcher", "vtkvol.ui.time_controls",
                    "vtkvol.ui.status_bar")
    others = [m for m in modules
              if m not in window_parts and not m.startswith("vtkvol.ui.menus")]
    assert {"vtkvol.ui.errors", "vtkvol.ui.docks.transfer_function",
            "vtkvol.ui.movie_dialog"} <= set(others)
    loaded = imported_after(others)
    assert not any(m == "vtk" or m.startswith("vtkmodules") for m in loaded)
    assert "vtkmodules.vtkRenderingCore" in imported_after(["vtkvol.ui.viewport"])
