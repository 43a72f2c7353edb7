"""Fixtures shared by the test modules (none is autouse)."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("QT_API", "pyside6")  # pyvistaqt (qtpy) must pick PySide6


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "screenshots: writes docs/screenshots/*.png (deselect with -m 'not screenshots')"
    )


@pytest.fixture(scope="session")
def small_volume():
    """A small single-channel confocal-like volume (24 × 48 × 48 voxels, uint16), cheap to
    render on a software GL."""
    from vtkvol.io import VolumeData, confocal_phantom

    sample = confocal_phantom((24, 48, 48), voxel_size_um=(0.5, 0.5, 1.0))
    return VolumeData.from_array(np.ascontiguousarray(sample.array[:1]), sample.voxel_size_um,
                                 ["nuclei"])


@pytest.fixture(scope="session")
def small_volume_file(tmp_path_factory, small_volume):
    """``small_volume`` saved as a ``.npy`` file (z, y, x)."""
    path = tmp_path_factory.mktemp("volumes") / "nuclei.npy"
    np.save(path, small_volume.array[0])
    return path


@pytest.fixture(scope="module")
def main_window(qapp, tmp_path_factory):
    """One app window per test module (900 × 700, 3-D view at most 256² so frames stay cheap
    on a software GL), with its own settings file. Closed after the module."""
    from PySide6.QtCore import QSettings

    from vtkvol.ui.app import MainWindow, configure_gl_platform

    configure_gl_platform(qapp)
    settings_file = tmp_path_factory.mktemp("settings") / "vtkvol.ini"
    window = MainWindow(settings=QSettings(str(settings_file), QSettings.Format.IniFormat))
    window.resize(900, 700)
    window.viewport.setMaximumSize(256, 256)
    window.model.render.sample_distance = 1.0
    # Every frame at the model's quality, so tests may count frames whatever this machine's
    # speed; tests/test_ui_refine.py switches the progressive refinement on.
    window.viewport.progressive_refinement = False
    window.show()
    qapp.processEvents()
    yield window
    window.close()
    qapp.processEvents()


@pytest.fixture
def opened_window(main_window, qtbot, small_volume_file):
    """``main_window`` showing ``small_volume_file`` (opened once, reused while it stays)."""
    if main_window.data is None or main_window.data.source != str(small_volume_file):
        with qtbot.waitSignal(main_window.dataShown, timeout=30_000):
            main_window.open_path(small_volume_file)
    return main_window


@pytest.fixture
def dialogs(monkeypatch):
    """Message boxes shown through ``vtkvol.ui.errors.run_dialog``, recorded, not shown."""
    from vtkvol.ui import errors

    shown = []

    def record(box):
        shown.append(box)
        return 0

    monkeypatch.setattr(errors, "run_dialog", record)
    return shown
