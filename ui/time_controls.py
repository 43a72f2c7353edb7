"""The app window's time-series controls: the time slider's tool bar (below the docks), the
View menu's time actions (slider, play, previous, next) and the status bar's playback rate.
They drive a :class:`~vtkvol.ui.time_series.TimeSeriesPlayer`; the time point itself is the
model's ``volume.time_index``."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, QSettings, Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QLabel, QMainWindow, QToolBar

from vtkvol.ui import errors
from vtkvol.ui.menus.host import make_action
from vtkvol.ui.time_series import MIB, TimeBar, TimeSeriesPlayer

#: Setting: the time-point cache's size in MiB (default: vtkvol.io.time_series's).
TIME_CACHE_KEY = "timeSeries/cacheMiB"


def time_cache_setting(settings: QSettings) -> int | None:
    """The time-point cache's size in bytes from ``settings``; None (the default) when unset,
    negative or damaged."""
    value = settings.value(TIME_CACHE_KEY)
    try:
        mib = int(value) if value is not None else None
    except (TypeError, ValueError):
        mib = None  # a damaged setting: the default
    return None if mib is None or mib < 0 else mib * MIB


class TimeControls(QObject):
    """The time bar, its actions and rate label in ``window``; ``view_ready()`` tells the
    player whether the last point was drawn, ``on_shown()`` runs after a point is shown."""

    def __init__(self, window: QMainWindow, player: TimeSeriesPlayer, settings: QSettings, *,
                 view_ready: Callable[[], bool], on_shown: Callable[[], None]) -> None:
        super().__init__(window)
        self.window_ = window
        self.player = player
        player.view_ready = view_ready
        self.time_bar = TimeBar(player, window)
        self.toolbar = QToolBar("Time series", window)
        self.toolbar.setObjectName("time_toolbar")
        self.toolbar.addWidget(self.time_bar)
        # Shown by the View menu's entry only: the tool-bar menu would show an empty bar
        # for data with one time point.
        self.toolbar.toggleViewAction().setVisible(False)
        window.addToolBar(Qt.ToolBarArea.BottomToolBarArea, self.toolbar)
        self.bar_action = QAction("&Time slider", window)
        self.bar_action.setCheckable(True)
        self.bar_action.setChecked(True)
        self.bar_action.setStatusTip("Show the time slider of data with several time points")
        self.bar_action.toggled.connect(lambda *_: self.update())
        self.play_action = make_action(window, "&Play / pause", player.toggle_playing,
                                       QKeySequence("P"), "Play or pause the time series")
        self.back_action = make_action(window, "Pre&vious time point", lambda: player.step(-1),
                                       QKeySequence(","))
        self.forward_action = make_action(window, "&Next time point", lambda: player.step(1),
                                          QKeySequence("."))
        #: The View menu lists them (:mod:`vtkvol.ui.menus.view_menu`).
        self.actions: list[QAction] = [self.bar_action, self.play_action, self.back_action,
                                       self.forward_action]
        self.time_bar.cache_box.valueChanged.connect(
            lambda mib: settings.setValue(TIME_CACHE_KEY, int(mib)))
        self.rate_label = QLabel("")
        self.rate_label.setObjectName("status_time_rate")
        self.rate_label.setToolTip("Time points shown per second while the time series "
                                   "plays (fewer than asked when reading or rendering is "
                                   "slower: points are skipped)")
        window.statusBar().insertPermanentWidget(0, self.rate_label)
        player.rateChanged.connect(self._on_rate)
        player.playingChanged.connect(self._on_playing)
        player.failed.connect(self._on_failed)
        player.shown.connect(lambda _index: on_shown())
        self.update()

    def update(self) -> None:
        """The bar is shown for data with more than one time point, unless the user hid it."""
        series = self.player.is_series
        for action in self.actions:
            action.setEnabled(series)
        self.toolbar.setVisible(series and self.bar_action.isChecked())
        self.time_bar.refresh()

    def _on_rate(self, rate: float) -> None:
        fps = self.player.fps
        skipped = " (time points skipped)" if rate < 0.9 * fps else ""
        self.rate_label.setText(f"playing {rate:.1f} of {fps:g} fps{skipped}")

    def _on_playing(self, playing: bool) -> None:
        if not playing:
            self.rate_label.setText("")

    def _on_failed(self, message: str) -> None:
        self.window_.statusBar().showMessage(message, 15000)
        errors.show_message(self.window_, "Could not show the time point", message)
