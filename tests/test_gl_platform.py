"""PyOpenGL's platform is chosen in one place (``vtkvol.engine.gl``) and never leaks into the
environment: child processes (batch workers) and other GL users see ``PYOPENGL_PLATFORM`` as
it was. Each case runs in a fresh interpreter, since PyOpenGL fixes its platform at import."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, os
from vtkvol.engine import gl as engine_gl
{setup}
engine_gl.gl()
import OpenGL.platform
print(json.dumps({{"env": os.environ.get("PYOPENGL_PLATFORM"),
                  "loaded": type(OpenGL.platform.PLATFORM).__name__}}))
"""


def probe(setup: str = "", **env: str) -> dict:
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("PYOPENGL_PLATFORM", "DISPLAY")}
    environment.update(env)
    done = subprocess.run([sys.executable, "-c", PROBE.format(setup=setup)], env=environment,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_without_a_display_gl_loads_egl_and_leaves_the_environment_alone():
    assert probe() == {"env": None, "loaded": "EGLPlatform"}


def test_the_environment_variable_is_honoured_and_kept():
    assert probe(PYOPENGL_PLATFORM="glx") == {"env": "glx", "loaded": "GLXPlatform"}


def test_the_configured_platform_overrides_the_environment_without_changing_it():
    """The app's case: Qt runs on X (GLX) while the shell exported a headless EGL habit."""
    found = probe('engine_gl.configure_gl_platform("glx")', PYOPENGL_PLATFORM="egl")
    assert found == {"env": "egl", "loaded": "GLXPlatform"}


def test_an_unknown_platform_or_a_switch_after_loading_is_refused():
    from vtkvol.engine.gl import GLUnavailableError, configure_gl_platform

    with pytest.raises(ValueError, match="GL platform must be one of egl, glx, got 'wgl'"):
        configure_gl_platform("wgl")
    code = ("from vtkvol.engine import gl as g\n"
            "g.configure_gl_platform('egl'); g.gl(); g.configure_gl_platform('egl')\n"
            "try:\n    g.configure_gl_platform('glx')\n"
            "except g.GLUnavailableError as exc:\n    print(exc)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.stdout.strip() == "PyOpenGL is already loaded for egl; it cannot switch to glx"
    assert GLUnavailableError.__module__ == "vtkvol.engine.errors"


def test_loading_in_the_background_imports_pyopengl_for_the_configured_platform():
    """The app starts PyOpenGL's ~1 s first import on a worker thread, so that no frame pays
    for it; the platform is the configured one and the environment is left as it was."""
    found = probe('engine_gl.configure_gl_platform("glx")\n'
                  'import sys\n'
                  'assert "OpenGL.GL" not in sys.modules\n'
                  'engine_gl.load_in_background().join(120)\n'
                  'assert "OpenGL.GL" in sys.modules and engine_gl._GL is not None',
                  PYOPENGL_PLATFORM="egl")
    assert found == {"env": "egl", "loaded": "GLXPlatform"}
