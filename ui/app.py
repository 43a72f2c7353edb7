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
import dataclasses
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
    QEvent,
    QIODevice,
    QObject,
    QSettings,
    Qt,
    QThread,
    QTimer,
    Signal,
)
from PySide6.QtGui import (
    QAction,
    QCloseEvent,
    QDragEnterEvent,
    QDropEvent,
    QImage,
    QKeySequence,
    QShowEvent,
)
from PySide6.QtWidgets import (
    QApplication,
    QFileDialog,
    QInputDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QProgressDialog,
    QPushButton,
    QScrollArea,
    QToolBar,
    QWidget,
)

from vtkvol.io import ReadCancelled, VolumeData, available_readers, confocal_phantom, read_volume
from vtkvol.io.atomic import write_atomic
from vtkvol.io.pyramid import parse_bytes
from vtkvol.io.remote import is_remote
from vtkvol.io.volume_data import Spacing, format_bytes
from vtkvol.model.defaults import scene_for
from vtkvol.model.labels import show_detected_labels
from vtkvol.model.scene import Camera, CropBox, SceneModel, SliceWeights
from vtkvol.model.session import (
    SUFFIX as SESSION_SUFFIX,
)
from vtkvol.model.session import (
    MissingDataError,
    SessionError,
    is_session_path,
    load_session_with_data,
    read_session,
    save_session,
    session_target,
)
from vtkvol.ui import errors
from vtkvol.ui.auto_quality import AutoOutcome, AutoQuality
from vtkvol.ui.background import Worker
from vtkvol.ui.docks.base import ModelDock
from vtkvol.ui.docks.channels import ChannelsDock
from vtkvol.ui.docks.labels import LabelsDock, note_labels
from vtkvol.ui.docks.lights import LightsDock
from vtkvol.ui.docks.ranges import RangesDock
from vtkvol.ui.docks.slice_views import SliceViewsDock
from vtkvol.ui.docks.slice_weights import SliceWeightsDock
from vtkvol.ui.docks.transfer_function import TransferFunctionDock
from vtkvol.ui.elided_label import ElidedLabel
from vtkvol.ui.movie_dialog import MovieDialog
from vtkvol.ui.pyramid_view import (
    BUDGET_CHOICES,
    GPU_BUDGET_KEY,
    LEVEL_WHY_KEY,
    crop_region_um,
    data_centre,
    is_pyramid,
    level_text,
    level_words,
    offset_between,
    read_budget,
    restrict_weights,
    shifted_view,
    weight_fractions,
)
from vtkvol.ui.time_series import MIB, TimeBar, TimeSeriesPlayer
from vtkvol.ui.undo import UndoRecorder, apply_state
from vtkvol.ui.view_actions import ViewActions
from vtkvol.ui.viewport import ScreenshotCancelled, Viewport
from vtkvol.ui.voxel_size import ask_voxel_size, is_assumed_size_note, user_note

APP_NAME = "vtkvol"
MAX_RECENT = 10
RECENT_KEY = "recentFiles"
#: Setting: the time-point cache's size in MiB (default: vtkvol.io.time_series's).
TIME_CACHE_KEY = "timeSeries/cacheMiB"
SCREENSHOT_SCALES = (1, 2, 4)
#: Shortcut of File → Save screenshot → 1×.
SCREENSHOT_SHORTCUT = "Ctrl+Alt+S"
#: Progress dialogs appear only for reads longer than this (ms): quick opens do not flash.
PROGRESS_DELAY_MS = 400
#: ``window["sample"]`` in a session marks the built-in sample (it has no file to point to).
SAMPLE_KEY = "sample"


def configure_gl_platform(app: QApplication) -> None:
    """Tell PyOpenGL which GL platform Qt's context uses, before anything imports OpenGL.

    The engine issues some GL calls through PyOpenGL in VTK's (here: Qt's) context; under X
    (Qt's ``xcb``) that context is GLX, under Wayland EGL. PyOpenGL fixes its platform at
    first import, so this must run before the first frame.
    """
    platform = app.platformName()
    if platform == "xcb":
        os.environ["PYOPENGL_PLATFORM"] = "glx"
    elif platform.startswith("wayland"):
        os.environ["PYOPENGL_PLATFORM"] = "egl"


# -- background reads ------------------------------------------------------------------------------
#: The worker of background reads (kept under its old name for code that imports it here).
_Worker = Worker


class BackgroundTask(QObject):
    """A read in a ``QThread`` with a ``QProgressDialog``; Cancel makes ``cancel()`` True, so
    the reader raises ``ReadCancelled`` at its next progress call."""

    finished = Signal()

    def __init__(self, parent: QWidget, label: str, job: Callable[..., Any],
                 on_success: Callable[[Any], None], on_failure: Callable[[BaseException], None]):
        super().__init__(parent)
        self._on_success, self._on_failure = on_success, on_failure
        self.dialog = QProgressDialog(label, "Cancel", 0, 1000, parent)
        self.dialog.setWindowTitle(APP_NAME)
        self.dialog.setWindowModality(Qt.WindowModality.WindowModal)
        self.dialog.setMinimumDuration(PROGRESS_DELAY_MS)
        self.dialog.setAutoClose(False)
        self.dialog.setAutoReset(False)
        self.dialog.setValue(0)
        self.thread = QThread(self)
        self.worker = Worker(job)
        self.worker.moveToThread(self.thread)
        self.thread.started.connect(self.worker.run)
        self.worker.progressed.connect(self._on_progress)
        self.worker.succeeded.connect(self._on_succeeded)
        self.worker.failed.connect(self._on_failed)
        # Through this object (GUI thread), not to the worker directly: a queued call into the
        # worker's thread would wait for the read to finish, which is what Cancel must stop.
        self.dialog.canceled.connect(self.cancel)
        self._label = label
        self._done = False

    def start(self) -> None:
        self.thread.start()

    def cancel(self) -> None:
        """Ask the read to stop (thread-safe: sets an event the reader polls)."""
        self.worker.cancel()

    def _on_progress(self, fraction: float, message: str) -> None:
        if self._done:
            return
        self.dialog.setValue(int(fraction * 1000))
        if message:
            self.dialog.setLabelText(f"{self._label}\n{message}")

    def _finish(self) -> None:
        self._done = True
        self.thread.quit()
        self.thread.wait()

    def _close_dialog(self) -> None:
        # reset() also stops the dialog's show-after-minimumDuration timer.
        self.dialog.reset()
        self.dialog.close()
        self.dialog.deleteLater()

    # ``finished`` goes out before the callback: the window forgets this task first, so a
    # callback may start the next one (the retry after "Locate…").
    def _on_succeeded(self, result: Any) -> None:
        self._finish()
        if self.dialog.isVisible():
            # The new view is built on this thread next (seconds for a large stack: its
            # statistics, textures, first frame). A dialog closed now stays on screen until
            # the event loop runs again, unpainted: a blank window. So it says what is
            # happening, painted at once, and closes when the view is there.
            self.dialog.setCancelButton(None)  # nothing to cancel on this thread
            self.dialog.setValue(self.dialog.maximum())
            self.dialog.setLabelText(f"{self._label}\nPreparing the view…")
            self.dialog.repaint()
        self.finished.emit()
        try:
            self._on_success(result)
        finally:
            self._close_dialog()

    def _on_failed(self, exc: BaseException) -> None:
        self._finish()
        self._close_dialog()
        self.finished.emit()
        self._on_failure(exc)


class DockEditWatcher(QObject):
    """Tells the 3-D view when the user drags something in a dock.

    A mouse press inside a dock (a curve in an editor, a range slider, a parameter slider, a
    spin box's held arrow) starts an edit, the release ends it
    (:meth:`Viewport.begin_edit` / :meth:`Viewport.end_edit`); a wheel step over a dock is a
    short edit of its own. The view renders at the interactive quality meanwhile and at full
    quality once the edit settles, as for camera moves. An application-wide event filter: it
    sees widgets the docks create later (the technique parameters) and releases that land
    elsewhere (a popup, outside the window)."""

    def __init__(self, docks: list[ModelDock], viewport: Viewport,
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._docks = docks
        self._viewport = viewport
        self._pressed = False

    def _in_dock(self, obj: QObject) -> bool:
        widget = obj if isinstance(obj, QWidget) else None
        while widget is not None:
            if widget in self._docks:
                return True
            widget = widget.parentWidget()
        return False

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        kind = event.type()
        if kind == QEvent.Type.MouseButtonPress and not self._pressed:
            if self._in_dock(watched):
                self._pressed = True
                self._viewport.begin_edit()
        elif kind == QEvent.Type.MouseButtonRelease and self._pressed:
            self._pressed = False
            self._viewport.end_edit()
        elif kind == QEvent.Type.Wheel and not self._pressed and self._in_dock(watched):
            self._viewport.begin_edit()
            self._viewport.end_edit()
        return False

    def release(self) -> None:
        if self._pressed:
            self._pressed = False
            self._viewport.end_edit()


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
        self.model = SceneModel()
        self.data: VolumeData | None = None
        self.session_path: Path | None = None
        self._sample_args: dict[str, Any] | None = None
        self._task: BackgroundTask | None = None
        self._closing = False
        #: The file's own voxel size (x, y, z µm) and whether the file stored it; None when
        #: the data was opened with a voxel size given (the file's is then not known).
        self._file_voxel: tuple[Spacing, bool] | None = None
        #: The user chose a voxel size for the data on screen (Edit → Voxel size…), possibly
        #: the assumed 1 × 1 × 1 µm: the missing-voxel-size badge then goes away.
        self._voxel_size_chosen = False
        #: The data as read (before a voxel size set in the app), its notes and metadata whole.
        self._as_read: VolumeData | None = None
        #: Changes the undo history does not hold (a new voxel size) since the last save.
        self._unsaved_data_edit = False
        #: GPU-memory budget given on the command line (this run only); None: the setting.
        self.budget_override: int | None = None
        #: What "Back to overview" returns to while a refined region is shown: the overview's
        #: level, crop and slice weights; None when the overview (or no pyramid) is shown.
        self._overview: dict[str, Any] | None = None
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
        self._make_docks()
        self._make_actions()
        self._make_time_bar()
        self._make_menus()
        self._make_status_bar()
        # The slice views are navigation, not an edit of what the 3-D view shows: they run
        # their own interaction (only while the 3-D view outlines their planes).
        self.edit_watcher = DockEditWatcher(
            [d for d in self.docks if d is not self.slice_views_dock], self.viewport, self)
        app = QApplication.instance()
        if app is not None:
            app.installEventFilter(self.edit_watcher)
        self._make_auto_quality()
        self.resize(1280, 820)
        self._refresh_recent()

    def showEvent(self, event: QShowEvent) -> None:
        super().showEvent(event)
        if not self._docks_arranged:
            self._docks_arranged = True
            self.arrange_docks()
            # Keyboard focus starts in the 3-D view: a focused spin box would take Ctrl+Z
            # for its own text instead of the app's undo.
            self.viewport.plotter.setFocus()

    def arrange_docks(self) -> None:
        """The default layout: TF and slice editors tabbed below, channels above tabbed
        lights and ranges on the right; the slice views (left of the 3-D view) are hidden
        until View → Slice views shows them. Done once the window is shown: Qt 6.12 leaves a
        stray tab bar in the middle of the window when docks are tabified before that."""
        for dock in self.docks:
            dock.setFloating(False)
            dock.setVisible(dock is not self.slice_views_dock)
        self.tabifyDockWidget(self.tf_dock, self.slice_dock)
        self.tabifyDockWidget(self.lights_dock, self.ranges_dock)
        self.tabifyDockWidget(self.ranges_dock, self.labels_dock)
        self.tf_dock.raise_()
        self.lights_dock.raise_()
        self.resizeDocks([self.tf_dock], [270], Qt.Orientation.Vertical)
        self.resizeDocks([self.channels_dock], [370], Qt.Orientation.Horizontal)
        self.fit_channels_dock(shrink=True)

    def fit_channels_dock(self, *, shrink: bool = False) -> None:
        """Make the channels dock as tall as its rows (the lights dock gives or takes the
        room). Without ``shrink`` it only grows: the user may have made it taller."""
        dock = self.channels_dock
        if dock.isFloating() or not dock.isVisible():
            return
        scroll = dock.widget()
        content = scroll.widget() if isinstance(scroll, QScrollArea) else scroll
        content.adjustSize()
        wanted = content.sizeHint().height() + 12  # a little slack: no scroll bar for 2 px
        have = scroll.viewport().height() if isinstance(scroll, QScrollArea) else dock.height()
        if wanted > have or (shrink and wanted < have):
            extra = wanted - have
            self.resizeDocks([dock, self.lights_dock],
                             [dock.height() + extra, max(self.lights_dock.height() - extra, 120)],
                             Qt.Orientation.Vertical)

    # -- construction ---------------------------------------------------------------------------
    def _make_docks(self) -> None:
        self.tf_dock = TransferFunctionDock(self.model, self)
        self.slice_dock = SliceWeightsDock(self.model, self)
        self.channels_dock = ChannelsDock(self.model, self)
        self.lights_dock = LightsDock(self.model, self)
        self.ranges_dock = RangesDock(self.model, self)
        self.slice_views_dock = SliceViewsDock(self.model, self)
        self.labels_dock = LabelsDock(self.model, self)
        self.docks: list[ModelDock] = [self.tf_dock, self.slice_dock, self.channels_dock,
                                       self.lights_dock, self.ranges_dock,
                                       self.slice_views_dock, self.labels_dock]
        bottom = Qt.DockWidgetArea.BottomDockWidgetArea
        right = Qt.DockWidgetArea.RightDockWidgetArea
        self.addDockWidget(bottom, self.tf_dock)
        self.addDockWidget(bottom, self.slice_dock)
        self.tabifyDockWidget(self.tf_dock, self.slice_dock)
        self.addDockWidget(right, self.channels_dock)
        self.addDockWidget(right, self.lights_dock)
        self.addDockWidget(right, self.ranges_dock)
        self.addDockWidget(right, self.labels_dock)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, self.slice_views_dock)
        self.slice_views_dock.hide()
        self._docks_arranged = False  # tabs are made when first shown (see showEvent)
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

    def _action(self, text: str, slot: Callable[..., Any], shortcut: Any = None,
                tip: str = "") -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcut(shortcut)
        if tip:
            action.setStatusTip(tip)
            action.setToolTip(tip)
        action.triggered.connect(lambda *_: slot())
        return action

    def _make_actions(self) -> None:
        self.open_action = self._action("&Open…", self.choose_file, QKeySequence.StandardKey.Open,
                                        "Open a volume file (TIFF, NumPy, raw, NRRD, VTK…)")
        self.open_folder_action = self._action("Open &folder…", self.choose_folder, None,
                                               "Open a folder of single-slice TIFF files")
        self.open_url_action = self._action("Open &URL…", self.choose_url, None,
                                            "Open an OME-Zarr image on a web server or in S3")
        self.open_sample_action = self._action("Open &sample", self.open_sample, None,
                                               "Open the built-in synthetic confocal stack")
        self.open_session_action = self._action(
            "Open s&ession…", self.choose_session, QKeySequence("Ctrl+Shift+O"),
            "Restore a view saved with Save session")
        self.save_session_action = self._action(
            "&Save session", self.save_session_interactive, QKeySequence.StandardKey.Save,
            "Save the view (settings, camera, window layout) to a session file")
        self.save_session_as_action = self._action(
            "Save session &as…", lambda: self.save_session_interactive(choose=True),
            QKeySequence.StandardKey.SaveAs, "Save the view to a new session file")
        self.movie_action = self._action(
            "Export &movie…", self.show_movie_dialog, None,
            "A turntable or keyframe animation (camera, lights, time point) to MP4, PNG frames "
            "or a TIFF stack")
        self.movie_dialog: MovieDialog | None = None
        self.quit_action = self._action("&Quit", self.request_quit, QKeySequence.StandardKey.Quit)
        self.undo_action = self.recorder.stack.createUndoAction(self, "&Undo")
        self.undo_action.setShortcuts([QKeySequence.StandardKey.Undo])
        self.redo_action = self.recorder.stack.createRedoAction(self, "&Redo")
        self.redo_action.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")])
        self.reset_camera_action = self._action(
            "&Reset view", self.viewport.reset_camera, QKeySequence("Ctrl+R"),
            "Frame what is visible (voxels the transfer functions do not make transparent) "
            "from the default angle")
        self.voxel_size_action = self._action(
            "&Voxel size…", self.choose_voxel_size, None,
            "The distance between voxel centres along x, y and z (µm)")
        self.budget_action = self._action(
            "GPU memory &budget…", self.choose_gpu_budget, None,
            "The most voxel data shown at once; pyramids (OME-Zarr, Imaris) open at the finest "
            "level that fits")
        self.refine_action = self._action(
            "Re&fine selection", self.refine_selection, QKeySequence("Ctrl+Shift+R"),
            "Load the crop region at the finest pyramid level that fits the GPU memory budget")
        self.overview_action = self._action(
            "Back to &overview", self.back_to_overview, None,
            "Show the whole pyramid again at the overview level, with the previous crop")
        self.gizmo_action = QAction("Light &handle", self)
        self.gizmo_action.setCheckable(True)
        self.gizmo_action.setChecked(True)
        self.gizmo_action.setStatusTip("Show the draggable handle of the selected light")
        self.gizmo_action.toggled.connect(self.viewport.set_gizmo_visible)
        self.reduce_action = QAction("Faster while &moving", self)
        self.reduce_action.setCheckable(True)
        self.reduce_action.setChecked(True)
        self.reduce_action.setStatusTip(
            "Coarser sampling while the camera moves; full quality when it stops")
        self.reduce_action.toggled.connect(self._on_reduce_toggled)
        self.about_action = self._action("&About vtkvol", self.show_about)
        self.controls_action = self._action("&Mouse and keyboard", self.show_controls,
                                            QKeySequence.StandardKey.HelpContents)

    def _make_menus(self) -> None:
        bar = self.menuBar()
        file_menu = bar.addMenu("&File")
        file_menu.addAction(self.open_action)
        file_menu.addAction(self.open_folder_action)
        file_menu.addAction(self.open_url_action)
        self.recent_menu = file_menu.addMenu("Open &recent")
        file_menu.addAction(self.open_sample_action)
        file_menu.addSeparator()
        file_menu.addAction(self.open_session_action)
        file_menu.addAction(self.save_session_action)
        file_menu.addAction(self.save_session_as_action)
        file_menu.addSeparator()
        self.screenshot_menu = file_menu.addMenu("Save screens&hot")
        self.screenshot_actions: dict[int, QAction] = {}
        for scale in SCREENSHOT_SCALES:
            action = self._action(f"{scale}×", lambda s=scale: self.save_screenshot_interactive(s))
            self.screenshot_menu.addAction(action)
            self.screenshot_actions[scale] = action
        # Not Ctrl+Shift+S: that is Save session as (QKeySequence.SaveAs), and a key bound to
        # two actions triggers neither.
        self.screenshot_actions[1].setShortcut(QKeySequence(SCREENSHOT_SHORTCUT))
        self.screenshot_menu.aboutToShow.connect(self._label_screenshot_actions)
        file_menu.addAction(self.movie_action)
        file_menu.addSeparator()
        file_menu.addAction(self.quit_action)
        file_menu.aboutToShow.connect(self._refresh_recent)
        file_menu.aboutToShow.connect(self._update_file_actions)

        edit = bar.addMenu("&Edit")
        edit.addAction(self.undo_action)
        edit.addAction(self.redo_action)
        edit.addSeparator()
        edit.addAction(self.voxel_size_action)

        view = bar.addMenu("&View")
        view.addAction(self.reset_camera_action)
        view.addAction(self.gizmo_action)
        view.addAction(self.reduce_action)
        view.addSeparator()
        for action in self.view_actions.overlay_actions.values():
            view.addAction(action)
        view.addAction(self.view_actions.background_action)
        view.addSeparator()
        view.addAction(self.view_actions.clip_action)
        view.addSeparator()
        for action in (self.time_bar_action, self.time_play_action, self.time_back_action,
                       self.time_forward_action):
            view.addAction(action)
        view.addAction(self.refine_action)
        view.addAction(self.overview_action)
        view.addAction(self.budget_action)
        view.addSeparator()
        for dock in self.docks:
            view.addAction(dock.toggleViewAction())

        help_menu = bar.addMenu("&Help")
        help_menu.addAction(self.controls_action)
        help_menu.addAction(self.about_action)
        self._update_file_actions()

    def _make_status_bar(self) -> None:
        status = self.statusBar()
        self.data_label = ElidedLabel("No data")
        self.data_label.setObjectName("status_data")
        self.frame_label = QLabel("")
        self.frame_label.setObjectName("status_frame")
        self.frame_label.setToolTip("Last frame's render time and the illumination "
                                    "technique's last precomputation time")
        # Room for the widest value, so the bar does not re-layout (or clip) every frame.
        self.frame_label.setMinimumWidth(
            self.frame_label.fontMetrics().horizontalAdvance("frame 99999 ms · light 99999 ms"))
        self.frame_label.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        self.refine_label = QLabel("")
        self.refine_label.setObjectName("status_refine")
        self.refine_label.setToolTip("A progressive illumination method is refining the light; "
                                     "moving the camera does not restart it")
        self.quality_label = QLabel("")
        self.quality_label.setObjectName("status_quality")
        self.quality_label.setToolTip("This machine renders a full-quality frame slower than the "
                                      "window may wait: a coarse image is shown first and full "
                                      "quality is drawn in strips while you are idle")
        self.viewport.refinementChanged.connect(self.quality_label.setText)
        self.probe_label = QLabel("")
        self.probe_label.setObjectName("status_probe")
        self.probe_label.setToolTip("Intensity probe: the first visible voxel under the mouse "
                                    "pointer (position in µm, voxel index, every channel's "
                                    "value)")
        self.viewport.probed.connect(self.probe_label.setText)
        status.addWidget(self.probe_label)
        status.addPermanentWidget(self.quality_label)
        # A file without a voxel size is shown at 1 × 1 × 1 µm, which distorts anisotropic
        # stacks; a note in the (truncated) data label was easy to miss (issue 25), so a
        # badge stays until a voxel size is chosen.
        self.voxel_badge = QPushButton("⚠ Voxel size unknown — set…")
        self.voxel_badge.setObjectName("status_voxel_badge")
        self.voxel_badge.setFlat(True)
        self.voxel_badge.setStyleSheet("color: #b35c00; font-weight: bold;")
        self.voxel_badge.setToolTip("The file stores no voxel size: it is shown as 1 × 1 × 1 µm "
                                    "voxels, so lengths and the z/xy aspect may be wrong. "
                                    "Click to set the voxel size (Edit → Voxel size…).")
        self.voxel_badge.clicked.connect(self.choose_voxel_size)
        self.voxel_badge.hide()
        status.addPermanentWidget(self.voxel_badge)
        status.addPermanentWidget(self.refine_label)
        status.addPermanentWidget(self.data_label)
        status.addPermanentWidget(self.frame_label)
        self.viewport.frameRendered.connect(self._on_frame)
        # Both arrive from inside a frame: queued, so dialogs open after the frame is done.
        queued = Qt.ConnectionType.QueuedConnection
        self.viewport.illuminationFailed.connect(self._on_illumination_failed, queued)
        self.viewport.illuminationProgress.connect(self._on_illumination_progress, queued)
        self.viewport.illuminationCancelled.connect(
            lambda message: self.statusBar().showMessage(message, 15000))

    def _make_time_bar(self) -> None:
        """The time series' tool bar (below the docks) and its View-menu actions."""
        player = self.time_player
        player.view_ready = lambda: not self.viewport.frame_pending
        self.time_bar = TimeBar(player, self)
        self.time_toolbar = QToolBar("Time series", self)
        self.time_toolbar.setObjectName("time_toolbar")
        self.time_toolbar.addWidget(self.time_bar)
        # Shown by the View menu's entry only: the tool-bar menu would show an empty bar
        # for data with one time point.
        self.time_toolbar.toggleViewAction().setVisible(False)
        self.addToolBar(Qt.ToolBarArea.BottomToolBarArea, self.time_toolbar)
        self.time_bar_action = QAction("&Time slider", self)
        self.time_bar_action.setCheckable(True)
        self.time_bar_action.setChecked(True)
        self.time_bar_action.setStatusTip("Show the time slider of data with several time points")
        self.time_bar_action.toggled.connect(lambda *_: self._update_time_bar())
        self.time_play_action = self._action("&Play / pause", player.toggle_playing,
                                             QKeySequence("P"), "Play or pause the time series")
        self.time_back_action = self._action("Pre&vious time point", lambda: player.step(-1),
                                             QKeySequence(","))
        self.time_forward_action = self._action("&Next time point", lambda: player.step(1),
                                                QKeySequence("."))
        self.time_bar.cache_box.valueChanged.connect(
            lambda mib: self.settings.setValue(TIME_CACHE_KEY, int(mib)))
        self.time_rate_label = QLabel("")
        self.time_rate_label.setObjectName("status_time_rate")
        self.time_rate_label.setToolTip("Time points shown per second while the time series "
                                        "plays (fewer than asked when reading or rendering is "
                                        "slower: points are skipped)")
        self.statusBar().insertPermanentWidget(0, self.time_rate_label)
        player.rateChanged.connect(self._on_time_rate)
        player.playingChanged.connect(self._on_time_playing)
        player.failed.connect(self._on_time_failed)
        player.shown.connect(lambda _index: self._show_data_info())
        self._update_time_bar()

    def _time_cache_setting(self) -> int | None:
        value = self.settings.value(TIME_CACHE_KEY)
        try:
            mib = int(value) if value is not None else None
        except (TypeError, ValueError):
            mib = None  # a damaged setting: the default
        return None if mib is None or mib < 0 else mib * MIB

    def _update_time_bar(self) -> None:
        """The bar is shown for data with more than one time point, unless the user hid it."""
        series = self.time_player.is_series
        for action in (self.time_bar_action, self.time_play_action, self.time_back_action,
                       self.time_forward_action):
            action.setEnabled(series)
        self.time_toolbar.setVisible(series and self.time_bar_action.isChecked())
        self.time_bar.refresh()

    def _on_time_rate(self, rate: float) -> None:
        fps = self.time_player.fps
        skipped = " (time points skipped)" if rate < 0.9 * fps else ""
        self.time_rate_label.setText(f"playing {rate:.1f} of {fps:g} fps{skipped}")

    def _on_time_playing(self, playing: bool) -> None:
        if not playing:
            self.time_rate_label.setText("")

    def _on_time_failed(self, message: str) -> None:
        self.statusBar().showMessage(message, 15000)
        errors.show_message(self, "Could not show the time point", message)

    def _show_time_point(self, index: int, read: VolumeData) -> None:
        """Put time point ``index`` (as read) on screen: only the voxels change; the voxel
        size set in the app applies to it too. ``ValueError`` when it does not fit the view."""
        data = with_voxel_size(read, self.model.volume.voxel_size_um)
        self.viewport.show_voxels(data)
        self._as_read = read
        self.data = data
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

    def _on_auto_chosen(self, outcome: AutoOutcome) -> None:
        self.lights_dock.show_auto_status(outcome.summary, outcome.details,
                                          warning=not outcome.met)
        self.statusBar().showMessage(outcome.summary, 15000)

    def _on_auto_failed(self, message: str) -> None:
        self.lights_dock.show_auto_status(message, warning=True)
        self.statusBar().showMessage(message, 15000)

    # -- status ---------------------------------------------------------------------------------
    def _on_frame(self, frame_ms: float, illumination_ms: float) -> None:
        self.frame_label.setText(f"frame {frame_ms:.0f} ms · light {illumination_ms:.0f} ms")

    def _on_illumination_failed(self, message: str) -> None:
        self.statusBar().showMessage(message, 15000)
        errors.show_message(self, "The illumination method failed", message)

    def _on_illumination_progress(self, iteration: int, converged: bool) -> None:
        self.refine_label.setText("" if converged else f"Refining lighting — iteration {iteration}")

    def _show_data_info(self) -> None:
        data = self.data
        self.voxel_badge.setVisible(self.voxel_size_missing())
        if data is None:
            self.data_label.setText("No data")
            return
        c, z, y, x = data.array.shape
        sx, sy, sz = data.voxel_size_um
        name = self._data_name()
        channels = f", {c} channels" if c > 1 else ""
        if self.time_player.is_series:
            channels += f", time point {self.time_player.shown_index} of {self.time_player.count}"
        level = level_text(data)
        where = " · " + level_words(int(data.metadata["level"]),
                                    len(data.metadata["levels"])) + (
            " (refined region)" if data.metadata.get("region_um") else "") if level else ""
        self.data_label.setText(
            f"{name} — {x}×{y}×{z}{channels}, {data.array.dtype}, voxel {sx:.3g}×{sy:.3g}×"
            f"{sz:.3g} µm, {format_bytes(data.nbytes)}{where}")
        tip = user_note(data.describe())
        self.data_label.setToolTip(f"{level[:1].upper()}{level[1:]}\n\n{tip}" if level else tip)

    def voxel_size_missing(self) -> bool:
        """Whether the data on screen uses the assumed 1 × 1 × 1 µm voxel size: the file had
        none, none was given on opening (or in the session), and none was chosen since."""
        return (self.data is not None and self._file_voxel is not None
                and not self._file_voxel[1] and self.model.volume.voxel_size_um is None
                and not self._voxel_size_chosen)

    def _data_name(self) -> str:
        if self.data is None:
            return ""
        if self.data.source:
            return Path(self.data.source).name
        return "sample" if self._sample_args is not None else "in-memory volume"

    def _update_title(self) -> None:
        parts = [APP_NAME]
        if self.session_path is not None:
            parts.insert(0, self.session_path.name)
        elif self.data is not None:
            parts.insert(0, self._data_name())
        self.setWindowTitle(" — ".join(parts))

    def _update_file_actions(self) -> None:
        has_data = self.data is not None
        for action in (self.save_session_action, self.save_session_as_action):
            action.setEnabled(has_data)
        self.screenshot_menu.setEnabled(has_data)
        self.movie_action.setEnabled(has_data)
        self.voxel_size_action.setEnabled(has_data)
        can_refine = is_pyramid(self.data) and self.model.volume.voxel_size_um is None
        self.refine_action.setEnabled(can_refine)
        self.overview_action.setEnabled(self._overview is not None)
        self.ranges_dock.set_pyramid_actions(can_refine, self._overview is not None)

    def _on_reduce_toggled(self, on: bool) -> None:
        self.viewport.reduce_while_moving = on

    # -- opening --------------------------------------------------------------------------------
    def _file_filter(self) -> str:
        patterns: list[str] = []
        entries = []
        try:
            readers = available_readers()
        except Exception:  # a broken reader plugin must not take the Open dialog down
            readers = ()
        for spec in readers:
            pats = " ".join(spec.filename_patterns)
            patterns.extend(spec.filename_patterns)
            entries.append(f"{spec.label} ({pats})")
        everything = f"Volumes and sessions ({' '.join(patterns)} *{SESSION_SUFFIX})"
        return ";;".join([everything, *entries, f"vtkvol session (*{SESSION_SUFFIX})",
                          "All files (*)"])

    def _start_dir(self) -> str:
        recent = [p for p in self.recent_files() if not is_remote(p)]
        return str(Path(recent[0]).parent) if recent else str(Path.home())

    def choose_file(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open volume", self._start_dir(),
                                              self._file_filter())
        if path:
            self.open_path(path)

    def choose_folder(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Open folder of slices", self._start_dir())
        if path:
            self.open_path(path)

    def choose_url(self) -> None:
        """File → Open URL…: an OME-Zarr store's address, opened like a file."""
        from vtkvol.ui.open_url import OpenUrlDialog

        dialog = OpenUrlDialog(self)
        if dialog.exec():
            self.open_path(dialog.url())

    def choose_session(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open session", self._start_dir(),
                                              f"vtkvol session (*{SESSION_SUFFIX});;All files (*)")
        if path:
            self.open_session(path)

    def open_path(self, path: str | os.PathLike[str], *,
                  voxel_size: tuple[float, float, float] | None = None,
                  time_index: int | None = None) -> None:
        """Open a volume file or folder, or a session file (by its suffix), in the background.
        ``time_index`` (0-based) shows that time point of a time series instead of the first
        (or of the session's)."""
        text = str(path)
        if is_session_path(text):
            self.open_session(text, time_index=time_index)
            return
        name = Path(text).name or text
        index = 0 if time_index is None else int(time_index)

        budget = self.gpu_budget()

        def job(progress, cancel):
            return read_volume(text, voxel_size_um=voxel_size, time_index=index,
                               progress=progress, cancel=cancel, memory_budget_bytes=budget)

        def success(data: VolumeData) -> None:
            self.show_volume(data, voxel_size=voxel_size, time_index=index)
            self._add_recent(text)

        self._run(f"Reading {name}…", job, success,
                  lambda exc: self._open_failed(exc, f"Could not open {name}"))

    def open_sample(self, **sample_args: Any) -> None:
        """Show the built-in synthetic confocal stack (``confocal_phantom(**sample_args)``)."""

        def job(progress, cancel):
            progress(0.0, "generating the sample")
            return confocal_phantom(**sample_args)

        def success(data: VolumeData) -> None:
            self.show_volume(data, sample_args=dict(sample_args))

        self._run("Generating the sample…", job, success,
                  lambda exc: self._open_failed(exc, "Could not generate the sample"))

    def _run(self, label: str, job: Callable[..., Any], on_success: Callable[[Any], None],
             on_failure: Callable[[BaseException], None]) -> None:
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

    def _open_failed(self, exc: BaseException, action: str) -> None:
        if isinstance(exc, ReadCancelled):
            self.statusBar().showMessage("Opening cancelled; the previous view is unchanged.", 6000)
            self.openFailed.emit("cancelled")
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
        self._file_voxel = (None if voxel_size is not None
                            else (data.voxel_size_um, data.voxel_size_from_metadata))
        self._voxel_size_chosen = False
        self._as_read = data
        self._overview = None
        fresh.volume.level = data.metadata.get("level") if is_pyramid(data) else None
        with self.model.batch():
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
            self._set_data(data, reset_channels=False, sample_args=sample_args)
        self.session_path = None
        self._after_open()

    def _set_data(self, data: VolumeData, *, reset_channels: bool,
                  sample_args: dict[str, Any] | None = None) -> None:
        """Give the viewport and the docks ``data`` (inside the caller's model batch)."""
        self._sample_args = sample_args
        self.data = data
        self.viewport.show_data(data, reset_channels=reset_channels)
        for dock in self.docks:
            dock.set_data(data)

    def _after_open(self) -> None:
        self.recorder.reset()
        self._unsaved_data_edit = False
        # Next event-loop pass: new channel rows are shown (and measurable) only then.
        QTimer.singleShot(0, self.fit_channels_dock)
        self._show_data_info()
        self._update_title()
        self._update_file_actions()
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
            self._open_failed(exc, "Could not open the session")
            return
        window = session.window
        notes: list[str] = []
        if session.data_path is None and data_path is None and isinstance(
                window.get(SAMPLE_KEY), dict):
            sample_args = dict(window[SAMPLE_KEY])

            def sample_job(progress, cancel):
                progress(0.0, "generating the sample")
                return session.model, confocal_phantom(**_sample_kwargs(sample_args))

            self._run("Generating the sample…", sample_job,
                      lambda result: self._apply_session(session.path, *result, window,
                                                         session.warnings, sample_args),
                      lambda exc: self._open_failed(exc, "Could not open the session"))
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
            self._open_failed(exc, "Could not open the session")

        self._run(f"Opening {Path(path).name}…", job,
                  lambda result: self._apply_session(Path(path), *result, window, notes),
                  failure)

    def _locate_data(self, exc: MissingDataError) -> str:
        """Ask for the moved data file (tests replace this)."""
        start = str(exc.data_path.parent) if exc.data_path is not None else self._start_dir()
        path, _ = QFileDialog.getOpenFileName(self, "Locate the data file", start,
                                              self._file_filter())
        return path

    def _apply_session(self, path: Path, model: SceneModel, data: VolumeData,
                       window: dict[str, Any], notes: list[str],
                       sample_args: dict[str, Any] | None = None) -> None:
        # A refined region saved in the session has no overview state to go back to; "Back
        # to overview" then shows the level the budget chooses, uncropped.
        self._overview = None if model.volume.region_um is None else {
            "level": None, "crop": CropBox().model_dump(),
            "slice_weights": SliceWeights().model_dump()}
        if data.metadata.get("level_reason") == "level chosen by the caller":
            data.metadata[LEVEL_WHY_KEY] = "as saved in the session"
        with self.model.batch():
            apply_state(self.model, model.model_dump())
            self.time_player.data_opened(data, model.volume.time_index,
                                         memory_budget_bytes=self.gpu_budget())
            self._set_data(data, reset_channels=False, sample_args=sample_args)
        self._file_voxel = (None if model.volume.voxel_size_um is not None
                            else (data.voxel_size_um, data.voxel_size_from_metadata))
        self._voxel_size_chosen = False
        self._as_read = data
        self.session_path = Path(path)
        self._restore_window(window)
        self._add_recent(str(path))
        self._after_open()
        errors.show_warnings(self, f"{Path(path).name} was opened with notes:", notes)

    def _window_state(self) -> dict[str, Any]:
        state: dict[str, Any] = {
            "geometry": base64.b64encode(bytes(self.saveGeometry().data())).decode("ascii"),
            "state": base64.b64encode(bytes(self.saveState().data())).decode("ascii"),
        }
        if self._sample_args is not None:
            state[SAMPLE_KEY] = {k: list(v) if isinstance(v, tuple) else v
                                 for k, v in self._sample_args.items()}
        return state

    def _restore_window(self, window: dict[str, Any]) -> None:
        for key, restore in (("geometry", self.restoreGeometry), ("state", self.restoreState)):
            text = window.get(key)
            if isinstance(text, str):
                # A damaged layout is not worth a dialog: the current one is kept.
                with contextlib.suppress(ValueError, TypeError):
                    restore(QByteArray(base64.b64decode(text.encode("ascii"), validate=True)))

    def save_session_interactive(self, *, choose: bool = False) -> None:
        if self.data is None:
            return
        path = self.session_path
        if choose or path is None:
            suggestion = (self.session_path or Path(self._start_dir()) /
                          f"{Path(self._data_name()).stem or 'view'}{SESSION_SUFFIX}")
            chosen, _ = QFileDialog.getSaveFileName(self, "Save session", str(suggestion),
                                                    f"vtkvol session (*{SESSION_SUFFIX})")
            if not chosen:
                return
            target = _session_target(Path(chosen))
            if target != Path(chosen) and target.exists() and not self._confirm_overwrite(target):
                return
            path = target
        self.save_session(path)

    def save_session(self, path: str | os.PathLike[str]) -> Path | None:
        """Write the session (model, data reference, window layout); a dialog on failure."""
        try:
            written = save_session(path, self.model, data=self.data, window=self._window_state())
        except SessionError as exc:
            errors.show_error(self, exc, action="Could not save the session")
            return None
        self.session_path = written
        self.recorder.stack.setClean()
        self._unsaved_data_edit = False
        self._add_recent(str(written))
        self._update_title()
        self.statusBar().showMessage(f"Saved {written}", 6000)
        return written

    def _confirm_overwrite(self, path: Path) -> bool:
        box = QMessageBox(self)
        box.setWindowTitle(APP_NAME)
        box.setIcon(QMessageBox.Icon.Question)
        box.setText(f"{path.name} already exists.")
        box.setInformativeText("Do you want to replace it?")
        box.setStandardButtons(QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No)
        box.setDefaultButton(QMessageBox.StandardButton.No)
        return errors.run_dialog(box) == QMessageBox.StandardButton.Yes

    # -- screenshots ----------------------------------------------------------------------------
    def _label_screenshot_actions(self) -> None:
        w, h = self.viewport.plotter.width(), self.viewport.plotter.height()
        ratio = self.viewport.plotter.devicePixelRatioF()
        for scale, action in self.screenshot_actions.items():
            width, height = round(w * ratio) * scale, round(h * ratio) * scale
            action.setText(f"{scale}× ({width} × {height} px)…")

    def save_screenshot_interactive(self, scale: int) -> None:
        if self.data is None:
            return
        suggestion = Path(self._start_dir()) / f"{Path(self._data_name()).stem or 'view'}.png"
        chosen, _ = QFileDialog.getSaveFileName(self, "Save screenshot", str(suggestion),
                                                "PNG image (*.png)")
        if not chosen:
            return
        target = Path(chosen)
        if target.suffix.lower() != ".png":
            target = target.with_name(target.name + ".png")
            # The dialog confirmed the name without ".png"; confirm the real one ourselves.
            if target.exists() and not self._confirm_overwrite(target):
                return
        self.save_screenshot(target, scale=scale)

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

    # -- recent files ---------------------------------------------------------------------------
    def recent_files(self) -> list[str]:
        value = self.settings.value(RECENT_KEY, [])
        if isinstance(value, str):  # QSettings returns a lone entry as a plain string
            value = [value]
        return [str(v) for v in (value or [])]

    def _add_recent(self, path: str) -> None:
        # An address (Open URL…) is kept as it is: Path() would fold its "//".
        absolute = path if is_remote(path) else str(Path(path).absolute())
        entries = [absolute, *(p for p in self.recent_files() if p != absolute)][:MAX_RECENT]
        self.settings.setValue(RECENT_KEY, entries)
        self._refresh_recent()

    def _refresh_recent(self) -> None:
        """Rebuild Open recent; entries whose file vanished are removed, with a message."""
        entries = self.recent_files()
        present = [p for p in entries if is_remote(p) or Path(p).exists()]
        vanished = [p for p in entries if p not in present]
        if vanished:
            self.settings.setValue(RECENT_KEY, present)
            names = ", ".join(Path(p).name for p in vanished)
            self.statusBar().showMessage(f"Removed from Open recent (no longer found): {names}",
                                         8000)
        menu = self.recent_menu
        menu.clear()
        for i, entry in enumerate(present):
            action = menu.addAction(f"&{(i + 1) % 10} {Path(entry).name}")
            action.setToolTip(entry)
            action.setStatusTip(entry)
            action.triggered.connect(lambda *_, p=entry: self.open_path(p))
        if present:
            menu.addSeparator()
            menu.addAction("Clear list", self._clear_recent)
        menu.setEnabled(bool(present))

    def _clear_recent(self) -> None:
        self.settings.setValue(RECENT_KEY, [])
        self._refresh_recent()

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

    # -- help -----------------------------------------------------------------------------------
    def show_about(self) -> None:
        from vtkvol import __version__

        QMessageBox.about(self, f"About {APP_NAME}",
                          f"<b>{APP_NAME} {__version__}</b><br>Volume rendering of microscopy "
                          "data with real illumination, inside VTK's GPU ray caster.")

    def show_controls(self) -> None:
        QMessageBox.information(
            self, "Mouse and keyboard",
            "<b>3-D view</b><br>Left drag: rotate · Shift+left or middle drag: pan · "
            "Right drag or wheel: zoom · Ctrl+left drag: spin<br>Drag the light's handle to "
            "move the light selected in the Lights dock.<br><br><b>Slice views</b><br>"
            "Click or drag: move the cursor · wheel or PageUp/PageDown: next slice<br><br>"
            "<b>Function editors</b><br>"
            "Points mode: click to add a node, drag to move, right-click or Delete to remove."
            "<br>Curve mode: press and drag to draw.<br>Double-click the colour bar to set a "
            "colour.<br><br><b>Keys</b><br>Ctrl+Z / Ctrl+Shift+Z: undo / redo · Ctrl+R: reset "
            "view · Ctrl+O: open · Ctrl+S: save session · Ctrl+Shift+S: save session as · "
            f"{SCREENSHOT_SHORTCUT}: screenshot<br><br><b>Time series</b><br>, / .: previous / "
            "next time point · P: play or pause")

    # -- voxel size -----------------------------------------------------------------------------
    def choose_voxel_size(self) -> None:
        """Edit → Voxel size…: ask for (x, y, z) in µm and apply it."""
        if self.data is None:
            return
        file_size, from_file = self._file_voxel if self._file_voxel is not None else (None, False)
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
        self._voxel_size_chosen = True  # even when it is the assumed one: the user saw it
        if tuple(new) == tuple(data.voxel_size_um):
            self._show_data_info()
            return
        old = data.voxel_size_um
        file_size = self._file_voxel[0] if self._file_voxel is not None else None
        override = None if file_size is not None and tuple(file_size) == tuple(new) else tuple(new)
        crop = {axis: None if (r := getattr(self.model.crop, axis)) is None else
                (r[0] * new[i] / old[i], r[1] * new[i] / old[i])
                for i, axis in enumerate("xyz")}
        read = self._as_read if self._as_read is not None else data
        # None (the file's own value): the data exactly as read.
        resized = with_voxel_size(read, override)
        cursor = self.model.cursor
        with self.model.batch():
            self.model.volume.voxel_size_um = override
            self.model.crop.update(crop)
            if cursor is not None:  # the same voxel under the slice views' cursor
                self.model.cursor = tuple(cursor[i] * new[i] / old[i] for i in range(3))
            self.model.camera.update(Camera().model_dump())  # framed again for the new shape
            self._set_data(resized, reset_channels=False, sample_args=self._sample_args)
        # The old steps would restore crop ranges in the old µm on the new data.
        self.recorder.reset()
        self._unsaved_data_edit = True
        self._show_data_info()
        self.statusBar().showMessage(f"Voxel size {new.x:.4g} × {new.y:.4g} × {new.z:.4g} µm",
                                     6000)

    # -- pyramids: budget, refine selection, back to overview ----------------------------------
    def gpu_budget(self) -> int:
        """The GPU-memory budget in bytes: the command line's for this run, else the setting
        (Edit → GPU memory budget…), else :data:`~vtkvol.io.pyramid.DEFAULT_GPU_BUDGET_BYTES`."""
        return self.budget_override if self.budget_override is not None else read_budget(
            self.settings)

    def set_gpu_budget(self, nbytes: int) -> None:
        """Store the budget (QSettings, kept across runs); it applies from the next open or
        refine. A command-line budget of this run gives way to it."""
        self.budget_override = None
        self.settings.setValue(GPU_BUDGET_KEY, int(nbytes))
        self.statusBar().showMessage(
            f"GPU memory budget {format_bytes(int(nbytes))}: pyramids open at the finest level "
            "that fits (from the next open or refine)", 8000)

    def choose_gpu_budget(self) -> None:
        """View → GPU memory budget…: pick or type a size (e.g. 1.5 GiB)."""
        current = format_bytes(self.gpu_budget())
        choices = list(BUDGET_CHOICES)
        if current not in choices:
            choices.insert(0, current)
        text, ok = QInputDialog.getItem(
            self, "GPU memory budget",
            "The most voxel data shown at once (all channels). Pyramids (OME-Zarr, Imaris)\n"
            "open at the finest level that fits, and Refine selection loads the crop\n"
            "region at the finest level where it fits.", choices, choices.index(current), True)
        if not ok:
            return
        try:
            nbytes = parse_bytes(text)
        except ValueError as exc:
            errors.show_message(self, "Not a size", f"{exc}. Enter a size such as 512 MiB or "
                                                    "2 GiB.")
            return
        self.set_gpu_budget(nbytes)

    def refine_selection(self) -> None:
        """Load the crop region at the finest pyramid level that fits the budget.

        The region is the crop box (µm) widened by half a shown voxel on each side. The new
        data is shown with its first voxel at the world origin and the camera, point lights
        and clipping plane shifted by the region's offset, so the object stays where it was;
        TFs, lights, method and camera are kept, the crop becomes the whole (new) extent."""
        data = self.data
        if not is_pyramid(data) or self._task is not None:
            return
        assert data is not None
        if self.model.volume.voxel_size_um is not None:
            self.statusBar().showMessage("Refine selection reads the file's own voxel sizes: "
                                         "use Edit → Voxel size → Use the file's value first",
                                         8000)
            return
        region = crop_region_um(data, self.model.crop)
        budget = self.gpu_budget()
        source = str(data.source)
        time_index = self.model.volume.time_index
        current = int(data.metadata["level"])

        def job(progress, cancel):
            return read_volume(source, time_index=time_index, region_um=region,
                               memory_budget_bytes=budget, progress=progress, cancel=cancel)

        def success(new: VolumeData) -> None:
            if int(new.metadata["level"]) >= current:
                self.statusBar().showMessage(
                    f"Refine selection: level {current} is already the finest level at which "
                    f"this region fits {format_bytes(budget)}; crop a smaller region or raise "
                    "the GPU memory budget", 10000)
                return
            if self._overview is None:
                self._overview = {"level": current, "crop": self.model.crop.model_dump(),
                                  "slice_weights": self.model.slice_weights.model_dump()}
            fractions = weight_fractions(data, new.metadata["region_um"])
            weights = {axis: restrict_weights(getattr(self.model.slice_weights, axis), lo, hi)
                       for axis, (lo, hi) in zip("xyz", fractions, strict=True)}
            self._show_pyramid_data(new, crop=CropBox().model_dump(), slice_weights=weights)

        self._run("Refining the selection…", job, success,
                  lambda exc: self._open_failed(exc, "Could not refine the selection"))

    def back_to_overview(self) -> None:
        """Show the overview level again, whole, with the crop and slice weights it had."""
        data, overview = self.data, self._overview
        if data is None or overview is None or self._task is not None:
            return
        budget = self.gpu_budget()
        source = str(data.source)
        time_index = self.model.volume.time_index

        def job(progress, cancel):
            return read_volume(source, time_index=time_index, level=overview["level"],
                               memory_budget_bytes=budget, progress=progress, cancel=cancel)

        def success(new: VolumeData) -> None:
            self._overview = None
            if overview["level"] is not None:  # else the budget chose it, and says so
                new.metadata[LEVEL_WHY_KEY] = "the overview shown before Refine selection"
            self._show_pyramid_data(new, crop=overview["crop"],
                                    slice_weights=overview["slice_weights"])

        self._run("Reading the overview…", job, success,
                  lambda exc: self._open_failed(exc, "Could not show the overview"))

    def _show_pyramid_data(self, new: VolumeData, *, crop: dict[str, Any],
                           slice_weights: dict[str, Any]) -> None:
        """Show another level or region of the same pyramid, keeping what is on screen in
        place (see :mod:`vtkvol.ui.pyramid_view`); a fresh undo history, like a new voxel
        size (the old steps hold crop ranges in the other level's µm)."""
        old = self.data
        assert old is not None
        shift = shifted_view(self.model, offset_between(old, new), data_centre(old))
        with self.model.batch():
            self.model.update(shift)
            self.model.volume.update({"level": int(new.metadata["level"]),
                                      "region_um": new.metadata.get("region_um")})
            self.model.crop.update(crop)
            self.model.slice_weights.update(slice_weights)
            self._set_data(new, reset_channels=False)
            self.time_player.data_opened(new, self.model.volume.time_index,
                                         memory_budget_bytes=self.gpu_budget())
        self._as_read = new
        self._file_voxel = (new.voxel_size_um, new.voxel_size_from_metadata)
        self.recorder.reset()
        self._unsaved_data_edit = True
        self._show_data_info()
        self._update_file_actions()
        self.statusBar().showMessage(f"Showing {level_text(new)}", 15000)
        self.dataShown.emit()

    # -- closing --------------------------------------------------------------------------------
    def has_unsaved_changes(self) -> bool:
        """Whether the view changed since it was opened or saved (camera moves aside)."""
        return self.data is not None and (
            not self.recorder.stack.isClean() or self._unsaved_data_edit)

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
            self.save_session_interactive()
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


def _session_target(path: Path) -> Path:
    """The file ``save_session`` will really write for ``path`` (it appends the suffix)."""
    return session_target(path)


def _sample_kwargs(stored: dict[str, Any]) -> dict[str, Any]:
    """Arguments of ``confocal_phantom`` from a session's ``window["sample"]`` (JSON lists)."""
    allowed = {"shape_zyx", "voxel_size_um", "seed"}
    return {k: tuple(v) if isinstance(v, list) else v for k, v in stored.items() if k in allowed}


def with_voxel_size(read: VolumeData, size: tuple[float, float, float] | None) -> VolumeData:
    """``read`` (data as read) with voxel size ``size`` (x, y, z µm; None: as read): the same
    voxels, the size recorded as set in the app, the reader's "assumed 1 µm" note dropped."""
    if size is None or tuple(float(v) for v in size) == tuple(read.voxel_size_um):
        return read
    return dataclasses.replace(
        read, voxel_size_um=Spacing(*(float(v) for v in size)),
        metadata={**read.metadata, "voxel_size_source": "set in the app"},
        # The reader's "assumed 1 µm" note no longer holds once the user set a size.
        notes=[n for n in read.notes if not is_assumed_size_note(n)])


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
            time_index: int | None = None, gpu_budget: int | None = None) -> int:
    """Start the desktop app (``vtkvol open``); returns the exit status.

    ``file`` may be a volume, a folder of slices or a session (``*.vtkvol.json``); without
    one the built-in sample is shown. ``voxel_size`` overrides the file's (x, y, z) in µm;
    ``time_index`` (0-based) opens that time point of a time series.
    ``gpu_budget`` (bytes) the GPU-memory budget setting, for this run only.
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
            file, voxel_size=voxel, time_index=time_index))
    elif sample:
        QTimer.singleShot(0, window.open_sample)
    try:
        return int(app.exec())
    finally:
        hook.uninstall()
