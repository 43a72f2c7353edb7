"""``vtkvol open``'s entry point, :func:`vtkvol.ui.app.run_app`, with the event loop replaced
by a function that waits for the data, checks the window and closes it."""

from __future__ import annotations

import os
import sys

import pytest
from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QApplication

from vtkvol.ui import app as app_module

pytestmark = pytest.mark.gui


@pytest.fixture
def run(qapp, qtbot, monkeypatch, tmp_path):
    """Call run_app; return what the window showed before it was closed."""
    settings = QSettings(str(tmp_path / "vtkvol.ini"), QSettings.Format.IniFormat)
    monkeypatch.setattr(app_module, "QSettings", lambda *args: settings)
    seen: dict = {}

    def fake_exec(self) -> int:
        window = next(w for w in QApplication.topLevelWidgets()
                      if isinstance(w, app_module.MainWindow) and w.isVisible())
        window.viewport.setMaximumSize(256, 256)
        qtbot.waitUntil(lambda: window.data is not None and window._task is None,
                        timeout=60_000)
        seen.update(data=window.data, hook=sys.excepthook, title=window.windowTitle(),
                    recent=window.recent_files())
        window.close()
        return 0

    monkeypatch.setattr(type(qapp), "exec", fake_exec)

    def call(*args, **kwargs):
        hook_before = sys.excepthook
        status = app_module.run_app(*args, **kwargs)
        seen["status"] = status
        seen["hook_restored"] = sys.excepthook is hook_before
        return seen

    return call


def test_run_app_opens_the_file_given(run, small_volume_file, monkeypatch):
    monkeypatch.setenv("PYOPENGL_PLATFORM", "egl")  # a headless habit that would break GLX
    seen = run(str(small_volume_file), sample=False, voxel_size=(0.5, 0.5, 2.0))
    assert seen["status"] == 0
    assert seen["data"].source == str(small_volume_file)
    assert tuple(seen["data"].voxel_size_um) == (0.5, 0.5, 2.0)
    assert seen["title"].startswith("nuclei.npy")
    assert seen["recent"] == [str(small_volume_file)]
    assert isinstance(seen["hook"], app_module.errors.ExceptionDialogHook)
    assert seen["hook_restored"]
    # Qt runs on X here (xcb): PyOpenGL is set for GLX in one place, the environment is not.
    from vtkvol.engine import gl as gl_module

    if gl_module._GL is None or gl_module._PLATFORM == "glx":
        assert gl_module._PLATFORM == "glx"
    else:  # an earlier test of this process loaded PyOpenGL for EGL: it cannot switch
        assert gl_module._PLATFORM == "egl"
    assert os.environ["PYOPENGL_PLATFORM"] == "egl"


def test_run_app_starts_on_the_sample(run, monkeypatch):
    original = app_module.confocal_phantom
    # The real default sample is 128 × 128 × 64 × 2 channels: too slow for a software GL.
    monkeypatch.setattr(app_module, "confocal_phantom",
                        lambda **kw: original(shape_zyx=(12, 24, 24)))
    seen = run(None, sample=True, voxel_size=None)
    assert seen["status"] == 0
    assert seen["data"].n_channels == 2 and seen["title"].startswith("sample")


def test_run_app_opens_the_time_point_given(run, tmp_path):
    from tests_support_time import write_time_lapse

    path = tmp_path / "lapse.tif"
    write_time_lapse(path, n_time=6)
    seen = run(str(path), sample=False, voxel_size=None, time_index=4)
    assert seen["status"] == 0
    assert seen["data"].metadata["time_index"] == 4
