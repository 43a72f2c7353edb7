"""The View menu: camera, light handle, interactive quality, overlays, clipping plane, the
time series, pyramid navigation (refine, overview, GPU-memory budget) and the docks."""

from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QInputDialog

from vtkvol.io.pyramid import parse_bytes
from vtkvol.io.volume_data import format_bytes
from vtkvol.ui import errors
from vtkvol.ui.menus.host import MenuHost, make_action
from vtkvol.ui.pyramid_view import BUDGET_CHOICES


class ViewMenu(QObject):
    """The View menu of one window and its own actions (the overlay and clipping actions are
    the window's :class:`~vtkvol.ui.view_actions.ViewActions`; the time actions its time
    bar's)."""

    def __init__(self, host: MenuHost) -> None:
        window = host.window()
        super().__init__(window)
        self.host = host
        viewport = host.viewport
        self.reset_camera_action = make_action(
            window, "&Reset view", viewport.reset_camera, QKeySequence("Ctrl+R"),
            "Frame what is visible (voxels the transfer functions do not make transparent) "
            "from the default angle")
        self.budget_action = make_action(
            window, "GPU memory &budget…", self.choose_gpu_budget, None,
            "The most voxel data shown at once; pyramids (OME-Zarr, Imaris) open at the finest "
            "level that fits")
        self.refine_action = make_action(
            window, "Re&fine selection", host.refine_selection, QKeySequence("Ctrl+Shift+R"),
            "Load the crop region at the finest pyramid level that fits the GPU memory budget")
        self.overview_action = make_action(
            window, "Back to &overview", host.back_to_overview, None,
            "Show the whole pyramid again at the overview level, with the previous crop")
        self.gizmo_action = QAction("Light &handle", window)
        self.gizmo_action.setCheckable(True)
        self.gizmo_action.setChecked(True)
        self.gizmo_action.setStatusTip("Show the draggable handle of the selected light")
        self.gizmo_action.toggled.connect(viewport.set_gizmo_visible)
        self.reduce_action = QAction("Faster while &moving", window)
        self.reduce_action.setCheckable(True)
        self.reduce_action.setChecked(True)
        self.reduce_action.setStatusTip(
            "Coarser sampling while the camera moves; full quality when it stops")
        self.reduce_action.toggled.connect(self._on_reduce_toggled)

        view = self.menu = host.menuBar().addMenu("&View")
        view.addAction(self.reset_camera_action)
        view.addAction(self.gizmo_action)
        view.addAction(self.reduce_action)
        view.addSeparator()
        for action in host.view_actions.overlay_actions.values():
            view.addAction(action)
        view.addAction(host.view_actions.background_action)
        view.addSeparator()
        view.addAction(host.view_actions.clip_action)
        view.addSeparator()
        for action in host.time_actions:
            view.addAction(action)
        view.addAction(self.refine_action)
        view.addAction(self.overview_action)
        view.addAction(self.budget_action)
        view.addSeparator()
        for dock in host.docks:
            view.addAction(dock.toggleViewAction())

    def update_enabled(self) -> None:
        """Refine needs a pyramid at the file's voxel size; Back to overview a refined
        region (see :class:`~vtkvol.model.document.Document`)."""
        document = self.host.document
        self.refine_action.setEnabled(document.can_refine())
        self.overview_action.setEnabled(document.overview is not None)

    def _on_reduce_toggled(self, on: bool) -> None:
        self.host.viewport.reduce_while_moving = on

    def choose_gpu_budget(self) -> None:
        """View → GPU memory budget…: pick or type a size (e.g. 1.5 GiB)."""
        current = format_bytes(self.host.gpu_budget())
        choices = list(BUDGET_CHOICES)
        if current not in choices:
            choices.insert(0, current)
        text, ok = QInputDialog.getItem(
            self.host.window(), "GPU memory budget",
            "The most voxel data shown at once (all channels). Pyramids (OME-Zarr, Imaris)\n"
            "open at the finest level that fits, and Refine selection loads the crop\n"
            "region at the finest level where it fits.", choices, choices.index(current), True)
        if not ok:
            return
        try:
            nbytes = parse_bytes(text)
        except ValueError as exc:
            errors.show_message(self.host.window(), "Not a size",
                                f"{exc}. Enter a size such as 512 MiB or 2 GiB.")
            return
        self.host.set_gpu_budget(nbytes)
