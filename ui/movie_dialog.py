"""File → Export movie…: a turntable or a keyframe animation to MP4, PNG frames or a TIFF stack.

The dialog is not modal: the user moves the view (camera, lights, time point) between
**Add keyframe** clicks. Rendering goes through the library (:mod:`vtkvol.movie`): an offscreen
view of a copy of the window's model, one frame at a time on the main thread, with the event
loop pumped after each frame so the progress dialog's **Cancel** answers. The movie is written
atomically (:func:`vtkvol.movie.write_movie`): a cancel or an error leaves no file behind.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QAbstractItemView,
    QApplication,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QMessageBox,
    QProgressDialog,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from vtkvol import movie
from vtkvol.model.keyframes import (
    MAX_FRAMES,
    Animation,
    CameraState,
    Keyframe,
    KeyframeError,
    read_keyframes,
    save_keyframes,
)
from vtkvol.ui import errors

if TYPE_CHECKING:
    from PySide6.QtWidgets import QStatusBar

    from vtkvol.io import VolumeData
    from vtkvol.model.document import Document
    from vtkvol.model.scene import SceneModel
    from vtkvol.ui.viewport import Viewport


class MovieHost(Protocol):
    """The app window as the movie dialog sees it (:class:`vtkvol.ui.app.MainWindow`, which
    is not imported here: it imports this module)."""

    document: Document
    model: SceneModel
    viewport: Viewport

    @property
    def data(self) -> VolumeData | None: ...

    # QWidget's: the window itself (the dialog's parent).
    def window(self) -> QWidget: ...

    def statusBar(self) -> QStatusBar: ...

    def _start_dir(self) -> str: ...

#: Seconds between a new keyframe and the one before it.
KEYFRAME_STEP_S = 2.0
#: Longest animation the dialog sets up (s); files may say more, up to MAX_FRAMES frames.
MAX_DURATION_S = 3600.0
#: Smallest gap between two keyframes (s).
MIN_GAP_S = 0.01
_OUTPUT_FILTER = ("MP4 video (*.mp4);;PNG sequence (*.png);;TIFF stack for Fiji (*.tif);;"
                  "All files (*)")
_KEYFRAME_FILTER = "vtkvol keyframes (*.keyframes.json);;All files (*)"


def _describe_camera(camera: CameraState) -> str:
    """Where the camera looks from, in the Lights dock's angles: azimuth in the x–y plane from
    +x towards +y, elevation towards +z (degrees), and its distance from the focal point."""
    back = np.subtract(camera.position, camera.focal_point) / camera.distance
    azimuth = math.degrees(math.atan2(back[1], back[0]))
    elevation = math.degrees(math.asin(float(np.clip(back[2], -1.0, 1.0))))
    return f"azimuth {azimuth:.0f}°, elevation {elevation:.0f}°, {camera.distance:.4g} µm away"


class MovieDialog(QDialog):
    """Turntable or keyframes, frame rate, size and output file; **Export** renders.

    Signals
    -------
    frameWritten(int, int)
        ``(frames done, frames in all)`` after each frame of an export.
    """

    frameWritten = Signal(int, int)

    def __init__(self, window: MovieHost) -> None:
        super().__init__(window.window())
        self.window_ = window
        self.setWindowTitle("Export movie")
        self.setMinimumWidth(560)
        self.keyframes: list[Keyframe] = []
        self.progress: QProgressDialog | None = None
        #: Messages of the last export's rendering (an illumination method that failed).
        self._notes: list[str] = []
        self._updating = False

        self.tabs = QTabWidget()
        self.tabs.addTab(self._make_turntable_tab(), "Turntable")
        self.tabs.addTab(self._make_keyframes_tab(), "Keyframes")
        self.tabs.currentChanged.connect(lambda *_: self._update_summary())

        common = QFormLayout()
        self.fps = QDoubleSpinBox()
        self.fps.setRange(1.0, 240.0)
        self.fps.setDecimals(2)
        self.fps.setValue(30.0)
        self.fps.setSuffix(" fps")
        self.fps.valueChanged.connect(lambda *_: self._update_summary())
        common.addRow("Frame rate", self.fps)
        size_row = QHBoxLayout()
        self.width_ = QSpinBox()
        self.height_ = QSpinBox()
        for spin in (self.width_, self.height_):
            spin.setRange(16, 8192)
            spin.setSuffix(" px")
            size_row.addWidget(spin)
        size_row.insertWidget(1, QLabel("×"))
        self.set_size_from_view()
        common.addRow("Size", size_row)
        out_row = QHBoxLayout()
        self.output = QLineEdit()
        self.output.setPlaceholderText("movie.mp4, frames.png (a sequence) or stack.tif")
        self.output.setToolTip("MP4 (H.264, plays in QuickTime and PowerPoint), a PNG sequence "
                               "(movie.png → movie_0000.png…) or a multi-page TIFF for Fiji")
        browse = QPushButton("Browse…")
        browse.clicked.connect(self.choose_output)
        out_row.addWidget(self.output)
        out_row.addWidget(browse)
        common.addRow("Output", out_row)
        self.summary = QLabel("")
        self.summary.setObjectName("movie_summary")

        buttons = QDialogButtonBox()
        self.export_button = buttons.addButton("Export", QDialogButtonBox.ButtonRole.AcceptRole)
        close = buttons.addButton(QDialogButtonBox.StandardButton.Close)
        self.export_button.clicked.connect(self.export)
        close.clicked.connect(self.hide)

        layout = QVBoxLayout(self)
        layout.addWidget(self.tabs)
        layout.addLayout(common)
        layout.addWidget(self.summary)
        layout.addWidget(buttons)
        self._refresh_table()

    # -- tabs -----------------------------------------------------------------------------------
    def _make_turntable_tab(self) -> QWidget:
        tab = QWidget()
        form = QFormLayout(tab)
        self.degrees = QDoubleSpinBox()
        self.degrees.setRange(-3600.0, 3600.0)
        self.degrees.setValue(360.0)
        self.degrees.setSuffix("°")
        self.degrees.setToolTip("How far the view turns about the chosen axis (360: a loop "
                                "without a repeated frame)")
        self.frames = QSpinBox()
        self.frames.setRange(1, MAX_FRAMES)
        self.frames.setValue(120)
        for spin in (self.degrees, self.frames):
            spin.valueChanged.connect(lambda *_: self._update_summary())
        # The view-up of a tilted view made the box tumble (issue 25): the sample's own z axis
        # comes first, as `vtkvol render --turntable` turns.
        self.turn_axis = QComboBox()
        self.turn_axis.addItem("the sample's z axis (upright turntable)", "sample")
        self.turn_axis.addItem("the view's vertical (screen up)", "view")
        self.turn_axis.setToolTip("The sample's axis keeps its tilt as it turns; the view's "
                                  "vertical turns it about the screen's up direction")
        self.frame_all = QCheckBox("Keep the whole sample in frame")
        self.frame_all.setChecked(True)
        self.frame_all.setToolTip("Move the camera back where needed so that no part of the "
                                  "volume leaves the frame at any angle of the turn")
        form.addRow("Turn by", self.degrees)
        form.addRow("Frames", self.frames)
        form.addRow("Turn about", self.turn_axis)
        form.addRow(self.frame_all)
        note = QLabel("The current view turns about the chosen axis through the focal point; "
                      "360° loops without a repeated frame.")
        note.setWordWrap(True)
        form.addRow(note)
        return tab

    def _make_keyframes_tab(self) -> QWidget:
        tab = QWidget()
        layout = QVBoxLayout(tab)
        self.table = QTableWidget(0, 3)
        self.table.setHorizontalHeaderLabels(["Time (s)", "Time point", "View"])
        self.table.horizontalHeader().setSectionResizeMode(2, QHeaderView.ResizeMode.Stretch)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.itemSelectionChanged.connect(self._update_buttons)
        self.table.setToolTip("Double-click a keyframe to look at the data from its camera")
        self.table.cellDoubleClicked.connect(lambda row, _column: self.show_keyframe(row))
        self.table.setMinimumHeight(160)
        self.table.verticalHeader().setDefaultSectionSize(
            self.table.verticalHeader().defaultSectionSize())  # one line per keyframe
        self.table.setWordWrap(False)
        layout.addWidget(self.table)
        row = QHBoxLayout()
        self.add_button = QPushButton("Add keyframe")
        self.add_button.setToolTip("The view as it is now (camera, lights, time point), "
                                   f"{KEYFRAME_STEP_S:g} s after the last keyframe")
        self.add_button.clicked.connect(self.add_keyframe)
        self.replace_button = QPushButton("Replace")
        self.replace_button.setToolTip("Give the selected keyframe the view as it is now "
                                       "(its time stays)")
        self.replace_button.clicked.connect(self.replace_keyframe)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self.remove_keyframe)
        self.up_button = QPushButton("Move up")
        self.up_button.setToolTip("Swap this view with the one before it (the times stay)")
        self.up_button.clicked.connect(lambda: self.move_keyframe(-1))
        self.down_button = QPushButton("Move down")
        self.down_button.setToolTip("Swap this view with the one after it (the times stay)")
        self.down_button.clicked.connect(lambda: self.move_keyframe(1))
        for button in (self.add_button, self.replace_button, self.remove_button, self.up_button,
                       self.down_button):
            row.addWidget(button)
        layout.addLayout(row)
        form = QFormLayout()
        self.duration = QDoubleSpinBox()
        self.duration.setRange(MIN_GAP_S, MAX_DURATION_S)
        self.duration.setDecimals(2)
        self.duration.setSuffix(" s")
        self.duration.setToolTip("The last keyframe's time; changing it stretches every "
                                 "keyframe's time in proportion")
        self.duration.valueChanged.connect(self.set_duration)
        form.addRow("Duration", self.duration)
        self.easing = QComboBox()
        self.easing.addItem("Smooth (ease in and out of each keyframe)", "smooth")
        self.easing.addItem("Linear (constant speed between keyframes)", "linear")
        form.addRow("Motion", self.easing)
        self.time_mode = QComboBox()
        self.time_mode.addItem("Play the time points between keyframes", "linear")
        self.time_mode.addItem("Nearest keyframe's time point", "nearest")
        self.time_mode.addItem("Hold each keyframe's time point", "hold")
        form.addRow("Time points", self.time_mode)
        layout.addLayout(form)
        files = QHBoxLayout()
        self.save_button = QPushButton("Save keyframes…")
        self.save_button.clicked.connect(self.save_keyframes_interactive)
        load = QPushButton("Load keyframes…")
        load.clicked.connect(self.load_keyframes_interactive)
        files.addWidget(self.save_button)
        files.addWidget(load)
        files.addStretch(1)
        layout.addLayout(files)
        return tab

    # -- keyframes ------------------------------------------------------------------------------
    def animation(self) -> Animation:
        """The keyframes as an :class:`~vtkvol.model.keyframes.Animation` (KeyframeError when
        there are none)."""
        if not self.keyframes:
            raise KeyframeError("add a keyframe first (the view as it is now)")
        return Animation(tuple(self.keyframes), easing=self.easing.currentData(),
                         time_index_interpolation=self.time_mode.currentData())

    def add_keyframe(self) -> Keyframe | None:
        """Add the view as it is now, ``KEYFRAME_STEP_S`` after the last keyframe."""
        window = self.window_
        if window.data is None:
            return None
        time = self.keyframes[-1].time + KEYFRAME_STEP_S if self.keyframes else 0.0
        # The time point is animated when the data has several (or the keyframes already do).
        with_time = (self.keyframes[0].time_index is not None if self.keyframes
                     else movie.time_point_count(window.data) > 1)
        try:
            key = Keyframe.from_model(window.model, time, time_index=with_time)
        except KeyframeError as exc:
            errors.show_error(self, exc, action="Could not add the keyframe")
            return None
        self.keyframes.append(key)
        self._refresh_table(select=len(self.keyframes) - 1)
        return key

    def replace_keyframe(self) -> None:
        """Give the selected keyframe the view as it is now; its time stays."""
        row = self._selected()
        if row is None or self.window_.data is None:
            return
        old = self.keyframes[row]
        try:
            self.keyframes[row] = Keyframe.from_model(self.window_.model, old.time,
                                                      time_index=old.time_index is not None)
        except KeyframeError as exc:
            errors.show_error(self, exc, action="Could not replace the keyframe")
            return
        self._refresh_table(select=row)

    def show_keyframe(self, row: int) -> None:
        """Put the view's camera where keyframe ``row``'s was (a camera move: no undo step;
        lights and time point stay as they are)."""
        if 0 <= row < len(self.keyframes) and self.window_.data is not None:
            self.window_.model.camera.update(self.keyframes[row].camera.model_fields())

    def remove_keyframe(self) -> None:
        row = self._selected()
        if row is None:
            return
        del self.keyframes[row]
        self._refresh_table(select=min(row, len(self.keyframes) - 1))

    def move_keyframe(self, step: int) -> None:
        """Swap the selected keyframe's view with its neighbour's; the times stay in order."""
        row = self._selected()
        if row is None or not 0 <= row + step < len(self.keyframes):
            return
        a, b = self.keyframes[row], self.keyframes[row + step]
        self.keyframes[row], self.keyframes[row + step] = b.with_time(a.time), a.with_time(b.time)
        self._refresh_table(select=row + step)

    def set_keyframe_time(self, row: int, time: float) -> None:
        """Give keyframe ``row`` a new time (s), kept between its neighbours'."""
        if self._updating or not 0 <= row < len(self.keyframes):
            return
        low = self.keyframes[row - 1].time + MIN_GAP_S if row > 0 else 0.0
        high = (self.keyframes[row + 1].time - MIN_GAP_S if row + 1 < len(self.keyframes)
                else MAX_DURATION_S)
        self.keyframes[row] = self.keyframes[row].with_time(min(max(time, low), high))
        self._refresh_table(select=row)

    def set_duration(self, duration: float) -> None:
        """Stretch every keyframe's time so that the last one is at ``duration`` seconds."""
        if self._updating or len(self.keyframes) < 2:
            return
        last = self.keyframes[-1].time
        if not last > 0 or math.isclose(duration, last):
            return
        scale = duration / last
        self.keyframes = [k.with_time(k.time * scale) for k in self.keyframes]
        self._refresh_table(select=self._selected())

    def set_animation(self, animation: Animation) -> None:
        """Show ``animation``'s keyframes and settings (after Load…)."""
        self.keyframes = list(animation.keyframes)
        self.easing.setCurrentIndex(max(0, self.easing.findData(animation.easing)))
        self.time_mode.setCurrentIndex(
            max(0, self.time_mode.findData(animation.time_index_interpolation)))
        self.tabs.setCurrentIndex(1)
        self._refresh_table(select=0)

    def _selected(self) -> int | None:
        rows = self.table.selectionModel().selectedRows()
        return rows[0].row() if rows else None

    def _refresh_table(self, select: int | None = None) -> None:
        self._updating = True
        try:
            self.table.setRowCount(len(self.keyframes))
            for row, key in enumerate(self.keyframes):
                spin = self.table.cellWidget(row, 0)
                if not isinstance(spin, QDoubleSpinBox):
                    # Made once per row and kept: a replaced editor would report its old
                    # value when it loses the focus.
                    spin = QDoubleSpinBox()
                    spin.setDecimals(2)
                    spin.setRange(0.0, MAX_DURATION_S)
                    spin.setSuffix(" s")
                    spin.editingFinished.connect(
                        lambda r=row, s=spin: self.set_keyframe_time(r, s.value()))
                    self.table.setCellWidget(row, 0, spin)
                spin.setValue(key.time)
                spin.setEnabled(row > 0)  # the first keyframe starts the movie
                point = "—" if key.time_index is None else str(key.time_index)
                self.table.setItem(row, 1, QTableWidgetItem(point))
                cam = key.camera
                item = QTableWidgetItem(_describe_camera(cam))
                item.setToolTip(f"position {tuple(round(v, 3) for v in cam.position)}, view-up "
                                f"{tuple(round(v, 3) for v in cam.view_up)}")
                self.table.setItem(row, 2, item)
            if select is not None and 0 <= select < len(self.keyframes):
                self.table.selectRow(select)
            self.duration.setValue(self.keyframes[-1].time if self.keyframes else MIN_GAP_S)
            self.duration.setEnabled(len(self.keyframes) > 1)
        finally:
            self._updating = False
        self._update_buttons()
        self._update_summary()

    def _update_buttons(self) -> None:
        row = self._selected()
        self.remove_button.setEnabled(row is not None)
        self.replace_button.setEnabled(row is not None)
        self.up_button.setEnabled(row is not None and row > 0)
        self.down_button.setEnabled(row is not None and row + 1 < len(self.keyframes))
        self.save_button.setEnabled(bool(self.keyframes))

    def frame_count(self) -> int:
        """Frames the export will have (raises KeyframeError for keyframes that cannot)."""
        if self.tabs.currentIndex() == 0:
            return self.frames.value()
        return self.animation().frame_count(self.fps.value())

    def _update_summary(self) -> None:
        fps = self.fps.value()
        try:
            n = self.frame_count()
        except KeyframeError as exc:
            self.summary.setText(str(exc))
            return
        self.summary.setText(f"{n} frames, {n / fps:.2f} s at {fps:g} fps")

    # -- files ----------------------------------------------------------------------------------
    def set_size_from_view(self) -> None:
        """The view's size in pixels, rounded up to even numbers (what H.264 needs)."""
        plotter = self.window_.viewport.plotter
        ratio = plotter.devicePixelRatioF()
        w, h = movie.even_size((round(plotter.width() * ratio), round(plotter.height() * ratio)))
        self.width_.setValue(max(w, 16))
        self.height_.setValue(max(h, 16))

    def choose_output(self) -> None:
        start = self.output.text() or str(Path(self.window_._start_dir()) / "movie.mp4")
        chosen, _ = QFileDialog.getSaveFileName(self, "Export movie to", start, _OUTPUT_FILTER)
        if chosen:
            self.output.setText(chosen)

    def save_keyframes_interactive(self) -> None:
        start = str(Path(self.window_._start_dir()) / "movie.keyframes.json")
        chosen, _ = QFileDialog.getSaveFileName(self, "Save keyframes", start, _KEYFRAME_FILTER)
        if chosen:
            self.save_keyframes(chosen)

    def save_keyframes(self, path: str | Path) -> Path | None:
        """Write the keyframes to ``path`` (``.keyframes.json`` is added when missing)."""
        target = Path(path)
        if not target.name.lower().endswith(".keyframes.json"):
            target = target.with_name(target.name.removesuffix(".json") + ".keyframes.json")
        try:
            save_keyframes(target, self.animation())
        except (KeyframeError, OSError) as exc:
            errors.show_error(self, exc, action="Could not save the keyframes")
            return None
        self.window_.statusBar().showMessage(f"Saved {len(self.keyframes)} keyframes to "
                                             f"{target.name}", 6000)
        return target

    def load_keyframes_interactive(self) -> None:
        chosen, _ = QFileDialog.getOpenFileName(self, "Load keyframes",
                                                self.window_._start_dir(), _KEYFRAME_FILTER)
        if chosen:
            self.load_keyframes(chosen)

    def load_keyframes(self, path: str | Path) -> bool:
        """Replace the keyframes by a file's; a bad file shows why and changes nothing."""
        try:
            animation = read_keyframes(path)
        except KeyframeError as exc:
            errors.show_error(self, exc, action="Could not load the keyframes")
            return False
        self.set_animation(animation)
        return True

    # -- export ---------------------------------------------------------------------------------
    def export(self) -> list[Path] | None:
        """Render and write the movie; the files written, or None (failed, cancelled or
        refused; the status bar or a dialog says why)."""
        window = self.window_
        data = window.data
        if data is None:
            return None
        text = self.output.text().strip()
        if not text:
            errors.show_message(self, "Export movie", "Choose the output file first.")
            return None
        out = Path(text).expanduser()
        fps = self.fps.value()
        try:
            problem = movie.encoder_problem(out)  # also refuses unknown suffixes
            n = self.frame_count()
            animation = self.animation() if self.tabs.currentIndex() == 1 else None
        except (KeyframeError, ValueError) as exc:
            errors.show_error(self, exc, action="Cannot export the movie")
            return None
        if problem:
            errors.show_message(self, "Cannot export the movie", problem)
            return None
        size = (self.width_.value(), self.height_.value())
        if movie.movie_kind(out) == "video":
            size = movie.even_size(size)
        existing = movie.existing_outputs(out, n)
        if existing and not self._confirm_replace(existing):
            return None
        try:
            frames = self._frames(animation, n, size, fps)
        except ValueError as exc:
            errors.show_error(self, exc, action="Cannot export the movie")
            return None
        return self._write(frames, out, n, fps, size, overwrite=bool(existing))

    def _frames(self, animation: Animation | None, n: int, size: tuple[int, int],
                fps: float) -> Any:
        window = self.window_
        data, model = window.data, window.model
        assert data is not None
        messages = self._notes = []
        if animation is None:
            return movie.turntable_frames(data, frames=n, degrees=self.degrees.value(),
                                          model=model, size=size, on_error=messages.append,
                                          axis=self.turn_axis.currentData(),
                                          frame_all=self.frame_all.isChecked())
        current = int(model.volume.time_index)
        source = data.source if window.document.sample_args is None else None
        time_points = None
        if source and animation.animates_time:
            time_points = movie.TimePointCache.for_file(
                source, voxel_size_um=model.volume.voxel_size_um, fit=model.volume.fit)
            time_points.put(current, data)
        problem = movie.keyframe_problem(animation, data, current,
                                         can_read_time_points=time_points is not None)
        if problem:
            raise ValueError(problem)
        return movie.keyframe_frames(data, animation, fps=fps, model=model, size=size,
                                     time_points=time_points, on_error=messages.append)

    def _write(self, frames: Any, out: Path, n: int, fps: float, size: tuple[int, int], *,
               overwrite: bool) -> list[Path] | None:
        window = self.window_
        progress = QProgressDialog(f"Rendering {out.name}…", "Cancel", 0, n, self)
        progress.setWindowTitle("Export movie")
        progress.setWindowModality(Qt.WindowModality.ApplicationModal)
        progress.setMinimumDuration(0)
        progress.setAutoClose(False)
        progress.setAutoReset(False)
        progress.setValue(0)
        self.progress = progress
        QApplication.processEvents()

        def step(done: int, total: int) -> None:
            progress.setValue(done)
            progress.setLabelText(f"Rendering {out.name}… frame {done} of {total}")
            self.frameWritten.emit(done, total)
            QApplication.processEvents()  # paints the dialog, delivers a click on Cancel

        try:
            written = movie.write_movie(frames, out, n_frames=n, fps=fps, overwrite=overwrite,
                                        progress=step, cancel=progress.wasCanceled)
        except movie.MovieCancelled:
            window.statusBar().showMessage(
                f"Movie export cancelled; nothing was written to {out.name}", 8000)
            return None
        except (OSError, ValueError, RuntimeError) as exc:
            errors.show_error(self, exc, action=f"Could not write {out.name}")
            return None
        finally:
            self.progress = None
            progress.reset()
            progress.close()
            progress.deleteLater()
        where = out.name if len(written) == 1 else f"{written[0].name} … {written[-1].name}"
        note = f"; {self._notes[0]}" if self._notes else ""
        window.statusBar().showMessage(
            f"Wrote {where} ({n} frames, {size[0]}×{size[1]}, {n / fps:.2f} s at {fps:g} fps)"
            + note, 15000)
        return written

    def _confirm_replace(self, existing: list[Path]) -> bool:
        box = QMessageBox(self)
        box.setWindowTitle("Export movie")
        box.setIcon(QMessageBox.Icon.Question)
        more = f" and {len(existing) - 1} more frame files" if len(existing) > 1 else ""
        box.setText(f"{existing[0].name}{more} already exist.")
        box.setInformativeText("Do you want to replace them?")
        box.setStandardButtons(QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No)
        box.setDefaultButton(QMessageBox.StandardButton.No)
        return errors.run_dialog(box) == QMessageBox.StandardButton.Yes
