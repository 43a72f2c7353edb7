"""The app window's menus, one module per menu: each builds its actions and its menu from
the window (:class:`~vtkvol.ui.menus.host.MenuHost`) and its document.

:mod:`~vtkvol.ui.menus.file_menu` (open, recent files, sessions, screenshots, movie, quit),
:mod:`~vtkvol.ui.menus.edit_menu` (undo, redo, voxel size),
:mod:`~vtkvol.ui.menus.view_menu` (camera, overlays, time series, pyramids, docks) and
:mod:`~vtkvol.ui.menus.help_menu` (controls, about).
"""
