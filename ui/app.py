"""The desktop app: :func:`run_app` (``vtkvol open``) and :class:`MainWindow`.

The window holds one :class:`~vtkvol.model.SceneModel` for its whole life. Opening data or a
session updates that model in place (one batched event), so the docks and the viewport stay
bound to it; the viewport's :class:`~vtkvol.engine.scene.VolumeScene` swaps its data. Long
reads run in a worker thread behind a progress dialog with Cancel; the scene changes only
after a successful read, so on an error the previous scene stays and a dialog says why
(:mod:`vtkvol.ui.errors`).
"""

from __future__ import annotations

import base64
import contextlib
import logging
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("QT_API", "pyside6")  # before pyvistaqt/qtpy are imported

import numpy as np
from PySide6.QtCore import (
    QBuffer,
    QByteArray,
    QIODevice,
    QSettings,
    Qt,
    QTimer,
    Signal,
)
from PySide6.QtGui import (
    QCloseEvent,
    QDragEnterEvent,
    QDropEvent,
    QImage,
    QShowEvent,
)
from PySide6.QtWidgets import (
    QApplication,
    QFileDialog,
    QMainWindow,
    QWidget,
)

from vtkvol.io import ReadCancelled, VolumeData, confocal_phantom, read_volume
from vtkvol.io.atomic import write_atomic
from vtkvol.io.folder import SeveralStacksError
from vtkvol.io.folder_channels import read_folder_as_channels
from vtkvol.io.volume_data import Spacing, format_bytes
from vtkvol.model.defaults import scene_for
from vtkvol.model.document import SAMPLE_KEY, Document, sample_kwargs
from vtkvol.model.labels import show_detected_labels
from vtkvol.model.scene import Camera, CropBox, SceneModel, SliceWeights
from vtkvol.model.session import (
    MissingDataError,
    SessionError,
    is_session_path,
    load_session_with_data,
    read_session,
    save_session,
)
from vtkvol.ui import APP_NAME, errors
from vtkvol.ui.auto_quality import AutoOutcome, AutoQuality
from vtkvol.ui.background import BackgroundTask
from vtkvol.ui.dock_layout import DockLayout
from vtkvol.ui.docks.base import ModelDock
from vtkvol.ui.docks.labels import note_labels
from vtkvol.ui.edit_watcher import DockEditWatcher
from vtkvol.ui.measure import MeasureTool
from vtkvol.ui.menus.edit_menu import EditMenu
from vtkvol.ui.menus.file_menu import FileMenu
from vtkvol.ui.menus.help_menu import HelpMenu
from vtkvol.ui.menus.view_menu import ViewMenu
from vtkvol.ui.movie_dialog import MovieDialog
from vtkvol.ui.pyramid_navigation import PyramidNavigation
from vtkvol.ui.pyramid_view import (
    GPU_BUDGET_KEY,
    LEVEL_WHY_KEY,
    data_centre,
    is_pyramid,
    level_text,
    offset_between,
    read_budget,
    shifted_view,
)
from vtkvol.ui.stack_chooser import offer_stacks
from vtkvol.ui.status_bar import StatusLabels
from vtkvol.ui.time_controls import TimeControls, time_cache_setting
from vtkvol.ui.time_series import TimeSeriesPlayer
from vtkvol.ui.undo import UndoRecorder, apply_state
from vtkvol.ui.view_actions import ViewActions
from vtkvol.ui.viewport import ScreenshotCancelled, Viewport
from vtkvol.ui.voxel_size import ask_voxel_size, user_note, with_voxel_size


def configure_gl_platform(app: QApplication) -> None:
    """Tell PyOpenGL which GL platform Qt's context uses, before anything imports OpenGL.

    The engine issues some GL calls through PyOpenGL in VTK's (here: Qt's) context; under X
    (Qt's ``xcb``) that context is GLX, under Wayland EGL. PyOpenGL fixes its platform at
    first import, so this must run before the first frame.
    """
    platform = app.platformName()
    gl_platform = "glx" if platform == "xcb" else ("egl" if platform.startswith("wayland")
                                                   else None)
    if gl_platform is None:
        return
    from vtkvol.engine.errors import GLUnavailableError
    from vtkvol.engine.gl import configure_gl_platform as use_gl_platform
    from vtkvol.engine.gl import load_in_background

    try:
        use_gl_platform(gl_platform)  # the one place that decides it (vtkvol.engine.gl)
    except GLUnavailableError as exc:  # PyOpenGL already loaded in this process (tests)
        logging.getLogger(__name__).warning("vtkvol: %s", exc)
        return
    # Its first import takes about a second: on a worker thread now, not in the first frame
    # that needs it (the first after opening a file froze that long).
    load_in_background()


class MainWindow(QMainWindow):
    """The app window: the 3-D view, the five docks, menus and the status bar.

    Signals
    -------
    dataShown()
        New data (from a file, the sample or a session) is on screen.
    openFailed(str)
        Opening failed or was cancelled; the previous scene stays. The text says why.
    """

    dataShown = Signal()
    openFailed = Signal(str)

    def __init__(self, *, settings: QSettings | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings if settings is not None else QSettings(APP_NAME, APP_NAME)
        #: The open document: the scene model, the data on screen, its provenance, session
        #: path, GPU budget and pyramid overview (Qt-free; the window observes it).
        self.document = Document()
        self.model = self.document.scene
        self._task: BackgroundTask | None = None
        self._closing = False
        self._confirmed_close = False
        self.setWindowTitle(APP_NAME)
        self.setAcceptDrops(True)
        self.setDockNestingEnabled(True)
        self.setCorner(Qt.Corner.BottomRightCorner, Qt.DockWidgetArea.RightDockWidgetArea)

        self.recorder = UndoRecorder(self.model, self)
        self.viewport = Viewport(self.model, self)
        # A failed method set back to local shading by the engine amends the user's choice.
        self.viewport.engine_edit = self.recorder.amending
        self.setCentralWidget(self.viewport)
        self.view_actions = ViewActions(self.model, self)
        self.time_player = TimeSeriesPlayer(self.model, self._show_time_point, self,
                                            cache_bytes=self._time_cache_setting())
        self.movie_dialog: MovieDialog | None = None
        self._make_docks()
        self._make_time_bar()
        self._make_menus()
        self._make_status_bar()
        # 3-D measurement: its dock, picks and markers.
        self.measure = MeasureTool(self, self.viewport, self.dataShown, self._start_dir)
        # The slice views are navigation, not an edit of what the 3-D view shows: they run
        # their own interaction (only while the 3-D view outlines their planes).
        self.edit_watcher = DockEditWatcher(
            [d for d in self.docks if d is not self.slice_views_dock], self.viewport, self)
        app = QApplication.instance()
        if app is not None:
            app.installEventFilter(self.edit_watcher)
        self._make_auto_quality()
        self.pyramid = PyramidNavigation(self)
        self.document.changed.connect(self._on_document_changed)
        self.resize(1280, 820)
        self._refresh_recent()

    # -- the document's state, as the window's attributes of old ---------------------------------
    @property
    def data(self) -> VolumeData | None:
        """The data on screen (``document.data``)."""
        return self.document.data

    @data.setter
    def data(self, value: VolumeData | None) -> None:
        self.document.data = value

    @property
    def session_path(self) -> Path | None:
        """The session file opened or last saved (``document.session_path``)."""
        return self.document.session_path

    @session_path.setter
    def session_path(self, value: Path | None) -> None:
        self.document.session_path = value

    @property
    def budget_override(self) -> int | None:
        """This run's GPU-memory budget in bytes (``document.budget_override``)."""
        return self.document.budget_override

    @budget_override.setter
    def budget_override(self, value: int | None) -> None:
        self.document.budget_override = value

    def _on_document_changed(self, names: frozenset[str]) -> None:
        """Status bar, title and menu states follow the document."""
        if names & {"data", "file_voxel", "voxel_size_chosen", "sample_args"}:
            self._show_data_info()
        if names & {"data", "session_path", "sample_args"}:
            self._update_title()
        if names & {"data", "overview"}:
            self._update_file_actions()

    def showEvent(self, event: QShowEvent) -> None:
        super().showEvent(event)
        if not self.dock_layout.arranged:
            self.dock_layout.arrange()
            # Keyboard focus starts in the 3-D view: a focused spin box would take Ctrl+Z
            # for its own text instead of the app's undo.
            self.viewport.plotter.setFocus()

    def arrange_docks(self) -> None:
        """The default dock layout (:meth:`DockLayout.arrange`)."""
        self.dock_layout.arrange()

    def fit_channels_dock(self, *, shrink: bool = False) -> None:
        """Make the channels dock as tall as its rows (:meth:`DockLayout.fit_channels`)."""
        self.dock_layout.fit_channels(shrink=shrink)

    # -- construction ---------------------------------------------------------------------------
    def _make_docks(self) -> None:
        self.dock_layout = layout = DockLayout(self, self.model)
        # Under the window's own names, as tests, benchmarks and the movie dialog use them.
        self.tf_dock, self.slice_dock = layout.tf_dock, layout.slice_dock
        self.channels_dock, self.lights_dock = layout.channels_dock, layout.lights_dock
        self.ranges_dock, self.slice_views_dock = layout.ranges_dock, layout.slice_views_dock
        self.labels_dock = layout.labels_dock
        self.docks: list[ModelDock] = layout.docks
        for dock in self.docks:
            dock.gestureStarted.connect(self.recorder.begin_gesture)
            dock.gestureFinished.connect(self.recorder.end_gesture)
        self.slice_views_dock.gestureStarted.connect(self._slice_drag_started)
        self.slice_views_dock.gestureFinished.connect(self._slice_drag_finished)
        self._slice_dragging = False
        self.lights_dock.currentLightChanged.connect(self.viewport.set_gizmo_light)
        self.ranges_dock.refineRequested.connect(self.refine_selection)
        self.ranges_dock.overviewRequested.connect(self.back_to_overview)
        self.viewport.set_gizmo_light(self.lights_dock.current_light)

    def _slice_drag_started(self) -> None:
        # The 3-D view follows a drag in the slice views only through the plane outlines;
        # without them it renders nothing for the cursor, so there is nothing to make coarse.
        if self.model.overlays.slice_planes:
            self._slice_dragging = True
            self.viewport.begin_interaction()

    def _slice_drag_finished(self) -> None:
        if self._slice_dragging:
            self._slice_dragging = False
            self.viewport.end_interaction()

    def _make_menus(self) -> None:
        """The menu bar, one module per menu (:mod:`vtkvol.ui.menus`)."""
        self.file_menu = FileMenu(self)
        self.edit_menu = EditMenu(self)
        self.view_menu = ViewMenu(self)
        self.help_menu = HelpMenu(self)
        self.file_menu.menu.aboutToShow.connect(self._update_file_actions)
        # The actions under the window's own names, as tests, benchmarks and the docs use them.
        file_menu, edit_menu, view_menu = self.file_menu, self.edit_menu, self.view_menu
        self.open_action = file_menu.open_action
        self.open_url_action = file_menu.open_url_action
        self.save_session_action = file_menu.save_session_action
        self.save_session_as_action = file_menu.save_session_as_action
        self.screenshot_actions = file_menu.screenshot_actions
        self.recent_menu = file_menu.recent_menu
        self.quit_action = file_menu.quit_action
        self.movie_action = file_menu.movie_action
        self.undo_action = edit_menu.undo_action
        self.redo_action = edit_menu.redo_action
        self.voxel_size_action = edit_menu.voxel_size_action
        self.reset_camera_action = view_menu.reset_camera_action
        self.gizmo_action = view_menu.gizmo_action
        self.refine_action = view_menu.refine_action
        self.overview_action = view_menu.overview_action
        self._update_file_actions()

    def _make_status_bar(self) -> None:
        """The status bar's labels (:mod:`vtkvol.ui.status_bar`) and the messages it shows."""
        self.status_labels = labels = StatusLabels(self.statusBar(), self.viewport,
                                                   self.choose_voxel_size)
        # Under the window's own names, as tests and benchmarks use them.
        self.data_label, self.frame_label = labels.data_label, labels.frame_label
        self.refine_label, self.quality_label = labels.refine_label, labels.quality_label
        self.probe_label, self.voxel_badge = labels.probe_label, labels.voxel_badge
        # Arrives from inside a frame: queued, so the dialog opens after the frame is done.
        self.viewport.illuminationFailed.connect(self._on_illumination_failed,
                                                 Qt.ConnectionType.QueuedConnection)
        self.viewport.illuminationCancelled.connect(
            lambda message: self.statusBar().showMessage(message, 15000))

    def _make_time_bar(self) -> None:
        """The time series' tool bar, View-menu actions and rate label
        (:mod:`vtkvol.ui.time_controls`)."""
        self.time_controls = controls = TimeControls(
            self, self.time_player, self.settings,
            view_ready=lambda: not self.viewport.frame_pending, on_shown=self._show_data_info)
        # Under the window's own names, as the tests use them.
        self.time_bar, self.time_toolbar = controls.time_bar, controls.toolbar
        self.time_bar_action, self.time_actions = controls.bar_action, controls.actions
        self.time_forward_action = controls.forward_action
        self.time_rate_label = controls.rate_label

    def _time_cache_setting(self) -> int | None:
        return time_cache_setting(self.settings)

    def _update_time_bar(self) -> None:
        self.time_controls.update()

    def _show_time_point(self, index: int, read: VolumeData) -> None:
        """Put time point ``index`` (as read) on screen: only the voxels change; the voxel
        size set in the app applies to it too. ``ValueError`` when it does not fit the view."""
        data = with_voxel_size(read, self.model.volume.voxel_size_um)
        self.viewport.show_voxels(data)
        self.document.time_point_shown(read, data)
        for dock in self.docks:
            dock.set_voxels(data)

    def _make_auto_quality(self) -> None:
        """Auto quality (``illumination.auto``): a pick amends the edit that caused it, so
        undo never returns to a method Auto would not pick for that state."""
        self.auto_quality = AutoQuality(
            self.model, self.viewport.opacity_snapshot, engine_edit=self.recorder.amending,
            method_labels={name: spec.label for name, spec in self.lights_dock.techniques.items()},
            parent=self)
        dock = self.lights_dock
        self.auto_quality.busy.connect(
            lambda: dock.show_auto_status("Choosing the method for this scene…"))
        self.auto_quality.chosen.connect(self._on_auto_chosen)
        self.auto_quality.failed.connect(self._on_auto_failed)
        # Auto quality quotes this machine's frames (issue 25), not another machine's.
        self.viewport.frameRendered.connect(
            lambda _ms, prepare_ms: self.auto_quality.record_frame(
                self.viewport.full_frame_ms(), prepare_ms))

    def _on_auto_chosen(self, outcome: AutoOutcome) -> None:
        self.lights_dock.show_auto_status(outcome.summary, outcome.details,
                                          warning=not outcome.met)
        self.statusBar().showMessage(outcome.summary, 15000)

    def _on_auto_failed(self, message: str) -> None:
        self.lights_dock.show_auto_status(message, warning=True)
        self.statusBar().showMessage(message, 15000)

    # -- status ---------------------------------------------------------------------------------
    def _on_illumination_failed(self, message: str) -> None:
        self.statusBar().showMessage(message, 15000)
        errors.show_message(self, "The illumination method failed", message)

    def _show_data_info(self) -> None:
        """The data label and the missing-voxel-size badge (the document, the time point)."""
        self.status_labels.show_data(self.document, self.time_player)

    def voxel_size_missing(self) -> bool:
        """Whether the data on screen uses the assumed 1 × 1 × 1 µm voxel size (see
        :meth:`Document.voxel_size_missing`)."""
        return self.document.voxel_size_missing()

    def _data_name(self) -> str:
        return self.document.data_name()

    def _update_title(self) -> None:
        parts = [APP_NAME]
        if self.session_path is not None:
            parts.insert(0, self.session_path.name)
        elif self.data is not None:
            parts.insert(0, self._data_name())
        self.setWindowTitle(" — ".join(parts))

    def _update_file_actions(self) -> None:
        """Enable what applies to the document (menus and the ranges dock's buttons)."""
        for menu in (self.file_menu, self.edit_menu, self.view_menu):
            menu.update_enabled()
        self.ranges_dock.set_pyramid_actions(self.document.can_refine(),
                                             self.document.overview is not None)

    # -- opening --------------------------------------------------------------------------------
    def recent_files(self) -> list[str]:
        """File → Open recent's entries, newest first."""
        return self.file_menu.recent_files()

    def _refresh_recent(self) -> None:
        self.file_menu.refresh_recent()

    def _add_recent(self, path: str) -> None:
        self.file_menu.add_recent(path)

    def _start_dir(self) -> str:
        """Where file dialogs start (the newest recent file's folder, else home)."""
        return self.file_menu.start_dir()

    def open_path(self, path: str | os.PathLike[str], *,
                  voxel_size: tuple[float, float, float] | None = None,
                  time_index: int | None = None, as_channels: bool = False) -> None:
        """Open a volume file or folder, or a session file (by its suffix), in the background.
        ``time_index`` (0-based) shows that time point of a time series instead of the first
        (or of the session's). ``as_channels``: ``path`` is a folder of stacks, each read as
        a channel (a folder of several stacks without it offers a chooser)."""
        text = str(path)
        if is_session_path(text):
            self.open_session(text, time_index=time_index)
            return
        name = Path(text).name or text
        index = 0 if time_index is None else int(time_index)

        budget = self.gpu_budget()

        def job(progress, cancel):
            read = read_folder_as_channels if as_channels else read_volume
            return read(text, voxel_size_um=voxel_size, time_index=index,
                        progress=progress, cancel=cancel, memory_budget_bytes=budget)

        def success(data: VolumeData) -> None:
            self.show_volume(data, voxel_size=voxel_size, time_index=index)
            self._add_recent(text)

        self.run_read(f"Reading {name}…", job, success,
                      lambda exc: self.read_failed(exc, f"Could not open {name}"))

    def open_sample(self, **sample_args: Any) -> None:
        """Show the built-in synthetic confocal stack (``confocal_phantom(**sample_args)``)."""

        def job(progress, cancel):
            progress(0.0, "generating the sample")
            return confocal_phantom(**sample_args)

        def success(data: VolumeData) -> None:
            self.show_volume(data, sample_args=dict(sample_args))

        self.run_read("Generating the sample…", job, success,
                      lambda exc: self.read_failed(exc, "Could not generate the sample"))

    def run_read(self, label: str, job: Callable[..., Any], on_success: Callable[[Any], None],
                 on_failure: Callable[[BaseException], None]) -> None:
        """Run ``job(progress, cancel)`` in the background behind a progress dialog (one read
        at a time: a second is refused with a message), then ``on_success(result)`` or
        ``on_failure(exc)`` on the GUI thread."""
        if self._task is not None:
            self.statusBar().showMessage("Still opening the previous file…", 4000)
            return
        task = BackgroundTask(self, label, job, on_success, on_failure)
        task.finished.connect(self._task_done)
        self._task = task
        task.start()

    def _task_done(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.deleteLater()

    def read_failed(self, exc: BaseException, action: str) -> None:
        """Say why a read failed (``action``: what was being done), or that it was cancelled;
        emits ``openFailed``."""
        if isinstance(exc, ReadCancelled):
            self.statusBar().showMessage("Opening cancelled; the previous view is unchanged.", 6000)
            self.openFailed.emit("cancelled")
            return
        if isinstance(exc, SeveralStacksError):  # not an error: ask which stack(s) to open
            offer_stacks(self, exc, self.open_path)
            return
        errors.show_error(self, exc, action=action)
        self.openFailed.emit(str(exc))

    def show_volume(self, data: VolumeData, *,
                    voxel_size: tuple[float, float, float] | None = None,
                    sample_args: dict[str, Any] | None = None, time_index: int = 0) -> None:
        """Show ``data`` with fresh channels, crop, weights and camera (lights, illumination
        and render settings stay: they are the user's preferences, not the data's).
        ``sample_args`` marks the built-in sample (so a session can regenerate it);
        ``time_index`` is the time point ``data`` holds."""
        fresh = scene_for(data)
        refused: list[tuple[int, str]] = []  # label images: categorical colours
        labelled = show_detected_labels(fresh, data, refused)
        fresh.volume.voxel_size_um = voxel_size
        fresh.volume.time_index = time_index
        fresh.volume.level = data.metadata.get("level") if is_pyramid(data) else None
        with self.document.batch(), self.model.batch():
            apply_state(self.model, {
                "volume": fresh.volume.model_dump(),
                "channels": [c.model_dump() for c in fresh.channels],
                "crop": CropBox().model_dump(),
                "slice_weights": SliceWeights().model_dump(),
                "camera": Camera().model_dump(),
                "cursor": None,  # the slice views start at the new data's centre
            })
            note_labels(self.model, data, labelled, refused)
            # Before the batch's event: the player must not take time point 0 for a request.
            self.time_player.data_opened(data, time_index,
                                         memory_budget_bytes=self.gpu_budget())
            # The time bar appearing resizes the 3-D view, which Qt repaints at once: before
            # the new scene exists that frame is empty, after it the new data's first frame
            # (texture upload and shader build, ~1 s on llvmpipe) ran inside this call.
            self._update_time_bar()
            self.document.opened(data, voxel_size_given=voxel_size is not None,
                                 sample_args=sample_args)
            self._show_data(data, reset_channels=False)
        self._after_open()

    def _show_data(self, data: VolumeData, *, reset_channels: bool) -> None:
        """Give the viewport and the docks ``data`` (inside the caller's model batch; the
        caller records it in the document)."""
        self.viewport.show_data(data, reset_channels=reset_channels)
        for dock in self.docks:
            dock.set_data(data)

    def _after_open(self) -> None:
        self.recorder.reset()
        # Next event-loop pass: new channel rows are shown (and measurable) only then.
        QTimer.singleShot(0, self.fit_channels_dock)
        # The document's event updated the data label, title and menus; the time series'
        # state is the player's.
        self._show_data_info()
        self._update_time_bar()
        self.auto_quality.request(delay_ms=0)  # new data: Auto (when on) chooses for it
        if self.data is not None and self.data.notes:
            # The full notes are in the data label's tooltip (describe()); the bar shows the
            # first, elided so it does not run under the permanent labels.
            more = len(self.data.notes) - 1
            text = user_note(self.data.notes[0]) + (
                f" (+{more} more: see the data's tooltip)" if more else "")
            width = max(120, self.statusBar().width() - self.data_label.sizeHint().width()
                        - self.frame_label.sizeHint().width() - 48)
            metrics = self.statusBar().fontMetrics()
            self.statusBar().showMessage(
                metrics.elidedText(text, Qt.TextElideMode.ElideRight, width), 15000)
        self.dataShown.emit()

    # -- sessions -------------------------------------------------------------------------------
    def open_session(self, path: str | os.PathLike[str], *,
                     data_path: str | os.PathLike[str] | None = None,
                     time_index: int | None = None) -> None:
        """Restore a session (view, settings, window layout) and its data, in the background.

        A bad file shows a dialog and leaves the scene untouched; a missing data file offers
        "Locate…" and retries with the located file. ``time_index`` shows that time point
        instead of the session's.
        """
        try:
            session = read_session(path)
        except SessionError as exc:
            self.read_failed(exc, "Could not open the session")
            return
        window = session.window
        notes: list[str] = []
        if session.data_path is None and data_path is None and isinstance(
                window.get(SAMPLE_KEY), dict):
            sample_args = dict(window[SAMPLE_KEY])

            def sample_job(progress, cancel):
                progress(0.0, "generating the sample")
                return session.model, confocal_phantom(**sample_kwargs(sample_args))

            self.run_read("Generating the sample…", sample_job,
                          lambda result: self._apply_session(session.path, *result, window,
                                                             session.warnings, sample_args),
                          lambda exc: self.read_failed(exc, "Could not open the session"))
            return

        def job(progress, cancel):
            return load_session_with_data(path, data_path=data_path, time_index=time_index,
                                          progress=progress, cancel=cancel,
                                          on_warning=notes.append)

        def failure(exc: BaseException) -> None:
            if isinstance(exc, MissingDataError) and exc.data_path is not None:
                if errors.ask_locate(self, exc):
                    located = self._locate_data(exc)
                    if located:
                        self.open_session(path, data_path=located, time_index=time_index)
                        return
                self.openFailed.emit(str(exc))
                return
            self.read_failed(exc, "Could not open the session")

        self.run_read(f"Opening {Path(path).name}…", job,
                      lambda result: self._apply_session(Path(path), *result, window, notes),
                      failure)

    def _locate_data(self, exc: MissingDataError) -> str:
        """Ask for the moved data file (tests replace this)."""
        start = str(exc.data_path.parent) if exc.data_path is not None else self._start_dir()
        path, _ = QFileDialog.getOpenFileName(self, "Locate the data file", start,
                                              self.file_menu.file_filter())
        return path

    def _apply_session(self, path: Path, model: SceneModel, data: VolumeData,
                       window: dict[str, Any], notes: list[str],
                       sample_args: dict[str, Any] | None = None) -> None:
        # A refined region saved in the session has no overview state to go back to; "Back
        # to overview" then shows the level the budget chooses, uncropped.
        overview = None if model.volume.region_um is None else {
            "level": None, "crop": CropBox().model_dump(),
            "slice_weights": SliceWeights().model_dump()}
        if data.metadata.get("level_reason") == "level chosen by the caller":
            data.metadata[LEVEL_WHY_KEY] = "as saved in the session"
        with self.document.batch():
            with self.model.batch():
                apply_state(self.model, model.model_dump())
                self.time_player.data_opened(data, model.volume.time_index,
                                             memory_budget_bytes=self.gpu_budget())
                self._show_data(data, reset_channels=False)
            self.document.opened(data, voxel_size_given=model.volume.voxel_size_um is not None,
                                 sample_args=sample_args, session_path=path, overview=overview)
        self._restore_window(window)
        self._add_recent(str(path))
        self._after_open()
        errors.show_warnings(self, f"{Path(path).name} was opened with notes:", notes)

    def _window_state(self) -> dict[str, Any]:
        state: dict[str, Any] = {
            "geometry": base64.b64encode(bytes(self.saveGeometry().data())).decode("ascii"),
            "state": base64.b64encode(bytes(self.saveState().data())).decode("ascii"),
        }
        state.update(self.document.window_extras())
        state.update(self.measure.window_state())  # the measured points (ui/measure.py)
        return state

    def _restore_window(self, window: dict[str, Any]) -> None:
        self.measure.restore(window)  # shown with the session's data
        for key, restore in (("geometry", self.restoreGeometry), ("state", self.restoreState)):
            text = window.get(key)
            if isinstance(text, str):
                # A damaged layout is not worth a dialog: the current one is kept.
                with contextlib.suppress(ValueError, TypeError):
                    restore(QByteArray(base64.b64decode(text.encode("ascii"), validate=True)))

    def save_session(self, path: str | os.PathLike[str]) -> Path | None:
        """Write the session (model, data reference, window layout); a dialog on failure."""
        try:
            written = save_session(path, self.model, data=self.data, window=self._window_state())
        except SessionError as exc:
            errors.show_error(self, exc, action="Could not save the session")
            return None
        self.document.saved(written)
        self.recorder.stack.setClean()
        self._add_recent(str(written))
        self.statusBar().showMessage(f"Saved {written}", 6000)
        return written

    # -- screenshots ----------------------------------------------------------------------------
    def save_screenshot(self, path: str | os.PathLike[str], *, scale: int = 1) -> Path | None:
        """Render the view ``scale`` times larger and write a PNG atomically (never a
        half-written file). Returns the path, or None after showing why it failed."""
        target = Path(path)
        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        try:
            image = self.viewport.screenshot(scale, progress=True)
            write_png(image, target)
        except ScreenshotCancelled:
            self.statusBar().showMessage("Screenshot cancelled; nothing was written.", 8000)
            return None
        except (OSError, RuntimeError, ValueError) as exc:
            errors.show_error(self, exc, action="Could not save the screenshot")
            return None
        finally:
            QApplication.restoreOverrideCursor()
        self.statusBar().showMessage(
            f"Saved {target.name} ({image.shape[1]} × {image.shape[0]} px)", 6000)
        return target

    # -- movies ---------------------------------------------------------------------------------
    def show_movie_dialog(self) -> MovieDialog | None:
        """File → Export movie…: the (not modal) movie dialog; its keyframes stay while the
        window lives."""
        if self.data is None:
            return None
        if self.movie_dialog is None:
            self.movie_dialog = MovieDialog(self)
        self.movie_dialog.show()
        self.movie_dialog.raise_()
        self.movie_dialog.activateWindow()
        return self.movie_dialog

    # -- drag and drop --------------------------------------------------------------------------
    @staticmethod
    def _dropped_paths(event: QDragEnterEvent | QDropEvent) -> list[str]:
        mime = event.mimeData()
        if not mime.hasUrls():
            return []
        return [url.toLocalFile() for url in mime.urls()
                if url.isLocalFile() and Path(url.toLocalFile()).exists()]

    def dragEnterEvent(self, event: QDragEnterEvent) -> None:
        if self._dropped_paths(event):
            event.acceptProposedAction()
        else:
            event.ignore()

    def dropEvent(self, event: QDropEvent) -> None:
        paths = self._dropped_paths(event)
        if not paths:
            event.ignore()
            return
        event.acceptProposedAction()
        if len(paths) > 1:
            self.statusBar().showMessage(
                f"Opening {Path(paths[0]).name}; one file at a time ({len(paths)} were dropped)",
                6000)
        # After the drop returns: the drag source must not wait for a whole read.
        QTimer.singleShot(0, lambda: self.open_path(paths[0]))

    # -- voxel size -----------------------------------------------------------------------------
    def choose_voxel_size(self) -> None:
        """Edit → Voxel size…: ask for (x, y, z) in µm and apply it."""
        if self.data is None:
            return
        file_voxel = self.document.file_voxel
        file_size, from_file = file_voxel if file_voxel is not None else (None, False)
        size = ask_voxel_size(self, self.data.voxel_size_um, file_size, from_file)
        if size is not None:
            self.set_voxel_size(size)

    def set_voxel_size(self, size: tuple[float, float, float]) -> None:
        """Show the same voxels with voxel size ``size`` (x, y, z µm).

        Transfer functions, channels, slice weights and illumination stay; crop ranges and the
        slice views' cursor keep the same voxels (their µm scale with the axis); the view is
        framed again. The model's
        ``volume.voxel_size_um`` records the override for sessions (None when it equals the
        file's own value). Like opening data, this starts a fresh undo history; the window
        counts it as an unsaved change.
        """
        data = self.data
        if data is None:
            return
        new = Spacing(*(float(v) for v in size))
        if tuple(new) == tuple(data.voxel_size_um):
            # Chosen even when it is the assumed one: the user saw it (the badge goes).
            self.document.voxel_size_set(None)
            return
        old = data.voxel_size_um
        file_voxel = self.document.file_voxel
        file_size = file_voxel[0] if file_voxel is not None else None
        override = None if file_size is not None and tuple(file_size) == tuple(new) else tuple(new)
        crop = {axis: None if (r := getattr(self.model.crop, axis)) is None else
                (r[0] * new[i] / old[i], r[1] * new[i] / old[i])
                for i, axis in enumerate("xyz")}
        read = self.document.as_read if self.document.as_read is not None else data
        # None (the file's own value): the data exactly as read.
        resized = with_voxel_size(read, override)
        cursor = self.model.cursor
        with self.document.batch():
            with self.model.batch():
                self.model.volume.voxel_size_um = override
                self.model.crop.update(crop)
                if cursor is not None:  # the same voxel under the slice views' cursor
                    self.model.cursor = tuple(cursor[i] * new[i] / old[i] for i in range(3))
                self.model.camera.update(Camera().model_dump())  # framed for the new shape
                self._show_data(resized, reset_channels=False)
            self.document.voxel_size_set(resized)
        # The old steps would restore crop ranges in the old µm on the new data.
        self.recorder.reset()
        self.statusBar().showMessage(f"Voxel size {new.x:.4g} × {new.y:.4g} × {new.z:.4g} µm",
                                     6000)

    # -- pyramids: budget, refine selection, back to overview ----------------------------------
    def gpu_budget(self) -> int:
        """The GPU-memory budget in bytes: the command line's for this run, else the setting
        (Edit → GPU memory budget…), else :data:`~vtkvol.io.pyramid.DEFAULT_GPU_BUDGET_BYTES`."""
        return self.document.gpu_budget(read_budget(self.settings))

    def set_gpu_budget(self, nbytes: int) -> None:
        """Store the budget (QSettings, kept across runs); it applies from the next open or
        refine. A command-line budget of this run gives way to it."""
        self.document.budget_override = None
        self.settings.setValue(GPU_BUDGET_KEY, int(nbytes))
        self.statusBar().showMessage(
            f"GPU memory budget {format_bytes(int(nbytes))}: pyramids open at the finest level "
            "that fits (from the next open or refine)", 8000)

    def refine_selection(self) -> None:
        """View → Refine selection (:meth:`PyramidNavigation.refine_selection`)."""
        self.pyramid.refine_selection()

    def back_to_overview(self) -> None:
        """View → Back to overview (:meth:`PyramidNavigation.back_to_overview`)."""
        self.pyramid.back_to_overview()

    @property
    def reading(self) -> bool:
        """Whether a background read (open, session, pyramid level) is running."""
        return self._task is not None

    def show_pyramid_level(self, new: VolumeData, *, crop: dict[str, Any],
                           slice_weights: dict[str, Any],
                           overview: dict[str, Any] | None) -> None:
        """Show another level or region of the same pyramid, keeping what is on screen in
        place (see :mod:`vtkvol.ui.pyramid_view`); a fresh undo history, like a new voxel
        size (the old steps hold crop ranges in the other level's µm). ``overview``: what
        "Back to overview" returns to afterwards (None: this is the overview)."""
        old = self.data
        assert old is not None
        shift = shifted_view(self.model, offset_between(old, new), data_centre(old))
        with self.document.batch():
            with self.model.batch():
                self.model.update(shift)
                self.model.volume.update({"level": int(new.metadata["level"]),
                                          "region_um": new.metadata.get("region_um")})
                self.model.crop.update(crop)
                self.model.slice_weights.update(slice_weights)
                self._show_data(new, reset_channels=False)
                self.time_player.data_opened(new, self.model.volume.time_index,
                                             memory_budget_bytes=self.gpu_budget())
            self.document.level_shown(new, overview=overview)
        self.recorder.reset()
        self.statusBar().showMessage(f"Showing {level_text(new)}", 15000)
        self.dataShown.emit()

    # -- closing --------------------------------------------------------------------------------
    def has_unsaved_changes(self) -> bool:
        """Whether the view changed since it was opened or saved (camera moves aside)."""
        return self.data is not None and (
            not self.recorder.stack.isClean() or self.document.unsaved_data_edit)

    def request_quit(self) -> None:
        """File → Quit: ask about unsaved changes, then close."""
        if self.confirm_discard():
            self._confirmed_close = True  # closeEvent (sent by close() at once) asks no more
            try:
                self.close()
            finally:
                self._confirmed_close = False

    def confirm_discard(self) -> bool:
        """True when the window may close: nothing unsaved, or the user saved or discarded
        it; False when the user cancelled (or the save was cancelled or failed)."""
        if not self.has_unsaved_changes():
            return True
        answer = errors.ask_unsaved_changes(self, self._data_name())
        if answer == "save":
            self.file_menu.save_session_interactive()
            return not self.has_unsaved_changes()
        return answer == "discard"

    def closeEvent(self, event: QCloseEvent) -> None:
        # The user closing the window (the title bar's button: a spontaneous event) is asked
        # about unsaved changes; File → Quit asked already. Closing from code is not asked.
        if event.spontaneous() and not self._confirmed_close and not self.confirm_discard():
            event.ignore()
            return
        if self._task is not None:
            # Readers check for cancellation at every slice or chunk, so this is short; a
            # QThread destroyed while running would abort the process.
            self._task.cancel()
            self._task.thread.wait()
        self._closing = True
        self.time_player.close()
        self.time_bar.release()
        app = QApplication.instance()
        if app is not None:
            app.removeEventFilter(self.edit_watcher)
        self.edit_watcher.release()
        self.auto_quality.close()
        self.view_actions.release()
        for dock in self.docks:
            dock.release()
        self.recorder.close()
        self.viewport.close()  # GL resources go while the context is still current
        super().closeEvent(event)


def write_png(image: np.ndarray, path: Path) -> None:
    """Write an (h, w, 3) uint8 image as PNG: encoded in memory, then written atomically (a
    failed write raises OSError, leaving any previous file as it was)."""
    rgb = np.ascontiguousarray(image[..., :3], dtype=np.uint8)
    h, w, _ = rgb.shape
    qimage = QImage(rgb.data, w, h, 3 * w, QImage.Format.Format_RGB888)
    encoded = QByteArray()
    buffer = QBuffer(encoded)
    buffer.open(QIODevice.OpenModeFlag.WriteOnly)
    if not qimage.save(buffer, "PNG"):
        raise OSError(f"{path}: the image could not be encoded as PNG")
    buffer.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, encoded.data())


def run_app(file: str | None, *, sample: bool, voxel_size: tuple | None,
            time_index: int | None = None, gpu_budget: int | None = None,
            as_channels: bool = False) -> int:
    """Start the desktop app (``vtkvol open``); returns the exit status.

    ``file`` may be a volume, a folder of slices or a session (``*.vtkvol.json``); without
    one the built-in sample is shown. ``voxel_size`` overrides the file's (x, y, z) in µm;
    ``time_index`` (0-based) opens that time point of a time series.
    ``gpu_budget`` (bytes) the GPU-memory budget setting, for this run only.
    ``as_channels``: ``file`` is a folder of stacks, each read as a channel.
    """
    app = QApplication.instance() or QApplication(sys.argv)
    configure_gl_platform(app)
    app.setOrganizationName(APP_NAME)
    app.setApplicationName(APP_NAME)
    window = MainWindow()
    window.budget_override = gpu_budget
    hook = errors.ExceptionDialogHook(window)
    hook.install()
    window.show()
    voxel = tuple(float(v) for v in voxel_size) if voxel_size else None
    if file:
        QTimer.singleShot(0, lambda: window.open_path(  # type: ignore[arg-type]
            file, voxel_size=voxel, time_index=time_index, as_channels=as_channels))
    elif sample:
        QTimer.singleShot(0, window.open_sample)
    try:
        return int(app.exec())
    finally:
        hook.uninstall()
