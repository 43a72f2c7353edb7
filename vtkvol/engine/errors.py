"""Engine exceptions that code without VTK catches: importing this module loads no VTK.

The app's error dialogs (``vtkvol.ui.errors``) tell a graphics failure from a data problem by
type; were the type defined beside the GL code (``engine/gl.py`` imports ``vtk``), every dock
that shows an error would load VTK.
"""

from __future__ import annotations


class GLUnavailableError(RuntimeError):
    """The GL feature needed (compute shaders, PyOpenGL) is not available in this context."""
