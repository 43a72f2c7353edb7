"""The vtkvol desktop app (PySide6): a 3-D view hosting VTK's ray caster, and docks that edit
the :class:`~vtkvol.model.SceneModel`. Start it with ``vtkvol open`` or
:func:`vtkvol.ui.app.run_app`."""

from vtkvol.ui.compat import protect_none

#: The app's name: window titles, dialogs and its QSettings (organisation and application).
APP_NAME = "vtkvol"

# Before any Qt call: PySide6 6.12 on CPython < 3.12 leaks references to None (see compat).
protect_none()
