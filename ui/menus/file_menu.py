"""The File menu: open (file, folder, URL, sample, session), Open recent, save session,
screenshots, movie export and quit, with the file dialogs they ask through.

The recent-files list lives in the window's ``QSettings`` (:data:`RECENT_KEY`, newest
first, at most :data:`MAX_RECENT`); entries whose file vanished are dropped, with a message,
whenever the list is shown.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QFileDialog, QMenu, QMessageBox

from vtkvol.io import available_readers
from vtkvol.io.remote import is_remote
from vtkvol.model.session import SUFFIX as SESSION_SUFFIX
from vtkvol.model.session import session_target
from vtkvol.ui import APP_NAME, errors
from vtkvol.ui.menus.host import MenuHost, make_action

MAX_RECENT = 10
RECENT_KEY = "recentFiles"
SCREENSHOT_SCALES = (1, 2, 4)
#: Shortcut of File → Save screenshot → 1×.
SCREENSHOT_SHORTCUT = "Ctrl+Alt+S"


class FileMenu(QObject):
    """The File menu of one window, its actions (also set on the window under their old
    names: ``open_action``, ``save_session_as_action``, ``screenshot_actions``, …) and the
    dialogs behind them."""

    def __init__(self, host: MenuHost) -> None:
        window = host.window()
        super().__init__(window)
        self.host = host
        act = make_action
        self.open_action = act(window, "&Open…", self.choose_file, QKeySequence.StandardKey.Open,
                               "Open a volume file (TIFF, NumPy, raw, NRRD, VTK…)")
        self.open_folder_action = act(window, "Open &folder…", self.choose_folder, None,
                                      "Open a folder of TIFF slices, or a folder's stacks")
        self.open_url_action = act(window, "Open &URL…", self.choose_url, None,
                                   "Open an OME-Zarr image on a web server or in S3")
        self.open_sample_action = act(window, "Open &sample", lambda: host.open_sample(), None,
                                      "Open the built-in synthetic confocal stack")
        self.open_session_action = act(
            window, "Open s&ession…", self.choose_session, QKeySequence("Ctrl+Shift+O"),
            "Restore a view saved with Save session")
        self.save_session_action = act(
            window, "&Save session", self.save_session_interactive,
            QKeySequence.StandardKey.Save,
            "Save the view (settings, camera, window layout) to a session file")
        self.save_session_as_action = act(
            window, "Save session &as…", lambda: self.save_session_interactive(choose=True),
            QKeySequence.StandardKey.SaveAs, "Save the view to a new session file")
        self.movie_action = act(
            window, "Export &movie…", host.show_movie_dialog, None,
            "A turntable or keyframe animation (camera, lights, time point) to MP4, PNG frames "
            "or a TIFF stack")
        self.quit_action = act(window, "&Quit", host.request_quit,
                               QKeySequence.StandardKey.Quit)

        menu = self.menu = host.menuBar().addMenu("&File")
        menu.addAction(self.open_action)
        menu.addAction(self.open_folder_action)
        menu.addAction(self.open_url_action)
        self.recent_menu: QMenu = menu.addMenu("Open &recent")
        menu.addAction(self.open_sample_action)
        menu.addSeparator()
        menu.addAction(self.open_session_action)
        menu.addAction(self.save_session_action)
        menu.addAction(self.save_session_as_action)
        menu.addSeparator()
        self.screenshot_menu: QMenu = menu.addMenu("Save screens&hot")
        self.screenshot_actions: dict[int, QAction] = {}
        for scale in SCREENSHOT_SCALES:
            action = act(window, f"{scale}×",
                         lambda s=scale: self.save_screenshot_interactive(s))
            self.screenshot_menu.addAction(action)
            self.screenshot_actions[scale] = action
        # Not Ctrl+Shift+S: that is Save session as (QKeySequence.SaveAs), and a key bound to
        # two actions triggers neither.
        self.screenshot_actions[1].setShortcut(QKeySequence(SCREENSHOT_SHORTCUT))
        self.screenshot_menu.aboutToShow.connect(self._label_screenshot_actions)
        menu.addAction(self.movie_action)
        menu.addSeparator()
        menu.addAction(self.quit_action)
        menu.aboutToShow.connect(self.refresh_recent)

    def update_enabled(self) -> None:
        """Saving, screenshots and movies need data on screen."""
        has_data = self.host.document.data is not None
        for action in (self.save_session_action, self.save_session_as_action):
            action.setEnabled(has_data)
        self.screenshot_menu.setEnabled(has_data)
        self.movie_action.setEnabled(has_data)

    # -- opening --------------------------------------------------------------------------------
    def file_filter(self) -> str:
        """The Open dialog's filters: every reader's patterns, then sessions, then all."""
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

    def start_dir(self) -> str:
        """Where file dialogs start: the folder of the newest recent local file, else home."""
        recent = [p for p in self.recent_files() if not is_remote(p)]
        return str(Path(recent[0]).parent) if recent else str(Path.home())

    def choose_file(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self.host.window(), "Open volume",
                                              self.start_dir(), self.file_filter())
        if path:
            self.host.open_path(path)

    def choose_folder(self) -> None:
        path = QFileDialog.getExistingDirectory(self.host.window(), "Open folder of slices",
                                                self.start_dir())
        if path:
            self.host.open_path(path)

    def choose_url(self) -> None:
        """File → Open URL…: an OME-Zarr store's address, opened like a file."""
        from vtkvol.ui.open_url import OpenUrlDialog

        dialog = OpenUrlDialog(self.host.window())
        if dialog.exec():
            self.host.open_path(dialog.url())

    def choose_session(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self.host.window(), "Open session", self.start_dir(),
            f"vtkvol session (*{SESSION_SUFFIX});;All files (*)")
        if path:
            self.host.open_session(path)

    # -- saving ---------------------------------------------------------------------------------
    def save_session_interactive(self, *, choose: bool = False) -> None:
        """File → Save session (to the session's file, else asking) or Save session as."""
        document = self.host.document
        if document.data is None:
            return
        path = document.session_path
        if choose or path is None:
            suggestion = (document.session_path or Path(self.start_dir()) /
                          f"{Path(document.data_name()).stem or 'view'}{SESSION_SUFFIX}")
            chosen, _ = QFileDialog.getSaveFileName(self.host.window(), "Save session",
                                                    str(suggestion),
                                                    f"vtkvol session (*{SESSION_SUFFIX})")
            if not chosen:
                return
            target = session_target(Path(chosen))
            if target != Path(chosen) and target.exists() and not self.confirm_overwrite(target):
                return
            path = target
        self.host.save_session(path)

    def confirm_overwrite(self, path: Path) -> bool:
        """Ask before replacing ``path`` (for names the file dialog did not confirm)."""
        box = QMessageBox(self.host.window())
        box.setWindowTitle(APP_NAME)
        box.setIcon(QMessageBox.Icon.Question)
        box.setText(f"{path.name} already exists.")
        box.setInformativeText("Do you want to replace it?")
        box.setStandardButtons(QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No)
        box.setDefaultButton(QMessageBox.StandardButton.No)
        return errors.run_dialog(box) == QMessageBox.StandardButton.Yes

    def _label_screenshot_actions(self) -> None:
        plotter = self.host.viewport.plotter
        w, h = plotter.width(), plotter.height()
        ratio = plotter.devicePixelRatioF()
        for scale, action in self.screenshot_actions.items():
            width, height = round(w * ratio) * scale, round(h * ratio) * scale
            action.setText(f"{scale}× ({width} × {height} px)…")

    def save_screenshot_interactive(self, scale: int) -> None:
        """File → Save screenshot → ``scale``×: ask for a PNG file name, then save."""
        document = self.host.document
        if document.data is None:
            return
        suggestion = Path(self.start_dir()) / f"{Path(document.data_name()).stem or 'view'}.png"
        chosen, _ = QFileDialog.getSaveFileName(self.host.window(), "Save screenshot",
                                                str(suggestion), "PNG image (*.png)")
        if not chosen:
            return
        target = Path(chosen)
        if target.suffix.lower() != ".png":
            target = target.with_name(target.name + ".png")
            # The dialog confirmed the name without ".png"; confirm the real one ourselves.
            if target.exists() and not self.confirm_overwrite(target):
                return
        self.host.save_screenshot(target, scale=scale)

    # -- recent files ---------------------------------------------------------------------------
    def recent_files(self) -> list[str]:
        """The recent files and addresses, newest first."""
        value = self.host.settings.value(RECENT_KEY, [])
        if isinstance(value, str):  # QSettings returns a lone entry as a plain string
            value = [value]
        return [str(v) for v in (value or [])]

    def add_recent(self, path: str) -> None:
        """Put ``path`` first in Open recent (a local path made absolute)."""
        # An address (Open URL…) is kept as it is: Path() would fold its "//".
        absolute = path if is_remote(path) else str(Path(path).absolute())
        entries = [absolute, *(p for p in self.recent_files() if p != absolute)][:MAX_RECENT]
        self.host.settings.setValue(RECENT_KEY, entries)
        self.refresh_recent()

    def refresh_recent(self) -> None:
        """Rebuild Open recent; entries whose file vanished are removed, with a message."""
        entries = self.recent_files()
        present = [p for p in entries if is_remote(p) or Path(p).exists()]
        vanished = [p for p in entries if p not in present]
        if vanished:
            self.host.settings.setValue(RECENT_KEY, present)
            names = ", ".join(Path(p).name for p in vanished)
            self.host.statusBar().showMessage(
                f"Removed from Open recent (no longer found): {names}", 8000)
        menu = self.recent_menu
        menu.clear()
        for i, entry in enumerate(present):
            action = menu.addAction(f"&{(i + 1) % 10} {Path(entry).name}")
            action.setToolTip(entry)
            action.setStatusTip(entry)
            action.triggered.connect(lambda *_, p=entry: self.host.open_path(p))
        if present:
            menu.addSeparator()
            menu.addAction("Clear list", self.clear_recent)
        menu.setEnabled(bool(present))

    def clear_recent(self) -> None:
        self.host.settings.setValue(RECENT_KEY, [])
        self.refresh_recent()
