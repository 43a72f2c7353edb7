"""Time-lapse playback: the time slider's controller and its tool bar.

``model.volume.time_index`` is the one source of truth. The slider, the step keys and
playback write it; :class:`TimeSeriesPlayer` listens and gets that time point on screen:

* from its :class:`~vtkvol.io.time_series.TimePointCache` (an LRU bounded in bytes) at once,
  so scrubbing back to a point seen before reads nothing;
* otherwise by a read in a worker thread (:class:`~vtkvol.ui.background.Worker`, as opening a
  file does, without the dialog). One read at a time: while it runs, further requests only
  replace the wanted point, so a fast slider drag reads the point it stops at, not every
  point it passed.

Only the voxels change (``Viewport.show_voxels``): transfer functions, contrast, camera,
crop, slice weights, lights and method stay; the illumination technique recomputes for the
new voxels. Its precomputed volumes are not cached per time point: they live in the
technique's GL textures, and the technique contract has no way to hand them out or back.

**Playback** has two modes. *Real time* (the default) runs on a clock: at ``fps`` frames per
second the wanted point is ``start + elapsed·fps``. A tick shows the newest cached point up to
that one; when none is cached the tick is dropped (never queued) and the next point the clock
will reach once a read is done is read ahead. The clock never takes playback past the last
point of the current loop: when frames are slower than a whole loop, the points between are
skipped but the shown point never moves backwards (it wraps only past the last point), and
the clock starts again from the point shown. *Every point* shows each point in turn, as
fast as reading and rendering allow (at most ``fps``). In both modes a tick waits until the
view has drawn the point shown before (``view_ready``), so the effective rate (points shown
per second, over the last :data:`RATE_POINTS` points) is what the user saw. A read that fails
stops playback with a message; the shown point stays.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, Qt, QThread, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QSlider,
    QSpinBox,
    QToolButton,
    QWidget,
)

from vtkvol.io import ReadCancelled, VolumeData, read_volume
from vtkvol.io.limits import physical_memory_bytes
from vtkvol.io.time_series import (
    TimePointCache,
    default_cache_bytes,
    format_time,
    time_interval_s,
    time_point_count,
)
from vtkvol.model.evented import touches
from vtkvol.model.scene import SceneModel
from vtkvol.ui.background import Worker

#: Playback speed when the app starts (time points per second).
DEFAULT_FPS = 10.0
MIN_FPS, MAX_FPS = 0.1, 60.0
#: The effective rate is measured over the intervals between this many points shown, however
#: long they took (a time window would read 0 once one frame took longer than it).
RATE_POINTS = 6
#: A tick looks this many points back from the clock's point for a cached one to show.
MAX_LOOK_BACK = 256
MIB = 1 << 20


def max_cache_bytes() -> int:
    """The largest cache the setting allows: half this machine's memory."""
    return physical_memory_bytes() // 2


@dataclass(eq=False)
class _Read:
    """One time point being read in the worker thread."""

    index: int
    generation: int
    thread: QThread
    worker: Worker
    started: float
    prefetch: bool


class TimeSeriesPlayer(QObject):
    """Gets ``model.volume.time_index`` on screen and plays a time series (module docstring).

    Parameters
    ----------
    model
        The window's scene model.
    show
        ``show(index, data)`` puts time point ``index`` (as read) on screen; raises
        ``ValueError`` when it cannot (other shape or voxel size).
    cache_bytes
        The cache's bound (bytes); None: :func:`~vtkvol.io.time_series.default_cache_bytes`.

    Signals
    -------
    shown(int)
        Time point on screen now.
    failed(str)
        A time point could not be read or shown (one line); playback stopped.
    playingChanged(bool)
    rateChanged(float)
        Points shown per second while playing (over the last :data:`RATE_POINTS`).
    stateChanged()
        The number of time points, the cache or a pending read changed.
    """

    shown = Signal(int)
    failed = Signal(str)
    playingChanged = Signal(bool)
    rateChanged = Signal(float)
    stateChanged = Signal()

    def __init__(self, model: SceneModel, show: Callable[[int, VolumeData], None],
                 parent: QObject | None = None, *, cache_bytes: int | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self._show = show
        self.cache = TimePointCache(default_cache_bytes() if cache_bytes is None
                                    else min(int(cache_bytes), max_cache_bytes()))
        self.path: str | None = None
        self.count = 1
        self.interval_s: float | None = None
        self.shown_index = 0
        self._shape: tuple[int, ...] | None = None
        self._itemsize = 1
        self._fit = "auto"
        self._read_options: dict[str, Any] = {}
        self._generation = 0
        self._read: _Read | None = None
        self._finishing: list[_Read] = []  # cancelled reads whose threads still run
        self._wanted: int | None = None
        self._read_seconds: deque[float] = deque(maxlen=5)
        self.reads_started = 0
        # playback
        self._fps = DEFAULT_FPS
        self.loop = True
        #: Read ahead while playing (off only to measure what it brings).
        self.read_ahead = True
        self._timer = QTimer(self)
        self._timer.setTimerType(Qt.TimerType.PreciseTimer)
        self._timer.timeout.connect(self._tick)
        self._clock_start = 0.0
        self._clock_position = 0  # unwrapped position of the time point shown at the start
        self._shown_position = 0  # unwrapped position of the time point on screen
        self._frame_times: deque[float] = deque(maxlen=RATE_POINTS)
        #: Show every time point in turn instead of following the clock (skipping points).
        self.every_point = False
        #: Whether the view has drawn what it was last given (None: always): playback does
        #: not step on before it has (the main window asks its viewport).
        self.view_ready: Callable[[], bool] | None = None
        #: Since Play: timer ticks that showed nothing (the point was not read yet) and time
        #: points the clock passed without showing them.
        self.dropped_ticks = 0
        self.skipped_points = 0
        self._closed = False
        model.changed.connect(self._on_model_changed)

    # -- the data -------------------------------------------------------------------------------
    def data_opened(self, data: VolumeData, time_index: int, *,
                    memory_budget_bytes: int | None = None) -> None:
        """New data is on screen (a file or session opened, or another pyramid level or
        region shown): forget the previous reads and cache, and learn this file's time axis.
        Other time points are read the way ``data`` was: with ``memory_budget_bytes`` (the
        budget the open used) and, for a pyramid, the same level and region, so that every
        time point has the shape on screen. Call before the model's change event of the open
        goes out (inside its batch)."""
        self.pause()
        self._cancel_read()
        self._generation += 1
        self.cache.clear()
        self._wanted = None
        self._read_seconds.clear()
        self.path = data.source
        self.count = time_point_count(data.metadata) if data.source else 1
        self.interval_s = time_interval_s(data.metadata)
        self.shown_index = int(time_index)
        self._shape = tuple(data.array.shape)
        self._itemsize = data.array.dtype.itemsize
        self._fit = self.model.volume.fit
        self._read_options = {"memory_budget_bytes": memory_budget_bytes}
        if "level" in data.metadata and "levels" in data.metadata:  # a pyramid's level/region
            self._read_options.update(level=data.metadata["level"],
                                      region_um=data.metadata.get("region_um"))
        if self.count > 1:
            self.cache.put(self.shown_index, data)
        self.stateChanged.emit()

    @property
    def is_series(self) -> bool:
        """Whether the data on screen has more than one time point."""
        return self.count > 1 and self.path is not None

    @property
    def pending(self) -> bool:
        """Whether the model's time point is not on screen yet (it is being read)."""
        return self.is_series and self.model.volume.time_index != self.shown_index

    def time_text(self, index: int) -> str:
        """The time of ``index`` from the file's interval ("" when it states none)."""
        return format_time(index, self.interval_s)

    def set_cache_bytes(self, nbytes: int) -> None:
        """A new bound for the cache (at most half this machine's memory)."""
        self.cache.max_bytes = max(0, min(int(nbytes), max_cache_bytes()))
        self.stateChanged.emit()

    # -- navigation -----------------------------------------------------------------------------
    def go_to(self, index: int) -> None:
        """Show time point ``index`` (clamped to the file's range)."""
        if self.is_series:
            self.model.volume.time_index = max(0, min(int(index), self.count - 1))

    def step(self, delta: int) -> None:
        """Move by ``delta`` time points; wraps around with :attr:`loop`, stops at the ends
        without. Stops playback (a step is the user taking over)."""
        if not self.is_series:
            return
        self.pause()
        index = self.model.volume.time_index + int(delta)
        if self.loop:
            index %= self.count
        self.go_to(index)

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "volume", "time_index"):
            self._request(self.model.volume.time_index)

    def _request(self, index: int) -> None:
        if not self.is_series or self._closed:
            return
        if index == self.shown_index:
            self._wanted = None
            self.stateChanged.emit()
            return
        if not 0 <= index < self.count:
            self._fail(index, f"{Path(self.path or '').name}: time point {index} is out of "
                              f"range: the file has {self.count} time points "
                              f"(0–{self.count - 1})")
            return
        data = self.cache.get(index)
        if data is not None:
            self._wanted = None
            self._display(index, data)
            return
        self._wanted = index
        if self._read is None:
            self._start_read(index, prefetch=False)
        self.stateChanged.emit()

    def _display(self, index: int, data: VolumeData) -> None:
        try:
            self._show(index, data)
        except ValueError as exc:
            self._fail(index, str(exc))
            return
        self.shown_index = index
        if self.playing:
            self._frame_times.append(time.perf_counter())
            self.rateChanged.emit(self.effective_rate())
        self.shown.emit(index)
        self.stateChanged.emit()

    def _fail(self, index: int, message: str) -> None:
        """Stop, keep what is shown (the model goes back to it), report one line."""
        self.pause()
        self._wanted = None
        if self.model.volume.time_index != self.shown_index:
            self.model.volume.time_index = self.shown_index
        self.failed.emit(message)
        self.stateChanged.emit()

    # -- reading --------------------------------------------------------------------------------
    def _start_read(self, index: int, *, prefetch: bool) -> None:
        path, fit, options = self.path, self._fit, dict(self._read_options)
        assert path is not None

        def job(progress, cancel):
            return read_volume(path, time_index=index, fit=fit, progress=progress,
                               cancel=cancel, **options)

        thread = QThread(self)
        worker = Worker(job)
        worker.moveToThread(thread)
        read = _Read(index, self._generation, thread, worker, time.perf_counter(), prefetch)
        thread.started.connect(worker.run)
        # Bound methods of this (GUI-thread) object: the results arrive queued, on this thread.
        worker.succeeded.connect(self._on_read_succeeded)
        worker.failed.connect(self._on_read_failed)
        self._read = read
        self.reads_started += 1
        thread.start()

    def _on_read_succeeded(self, data: Any) -> None:
        read = self._finish_read()
        if read is None:
            return
        self._read_seconds.append(time.perf_counter() - read.started)
        if tuple(data.array.shape) != self._shape:
            c, z, y, x = data.array.shape
            self._fail(read.index, f"{Path(self.path or '').name}: time point {read.index} "
                                   f"has {c} channel(s) of {x}×{y}×{z} voxels, unlike the "
                                   "time point first shown")
            return
        self.cache.put(read.index, data)
        wanted = self._wanted
        if wanted == read.index:
            self._wanted = None
            self._display(read.index, data)
        elif wanted is not None:
            self._request(wanted)
        if self.playing and self._read is None:
            self._prefetch(self._clock_target(time.perf_counter()))
        self.stateChanged.emit()

    def _on_read_failed(self, exc: Any) -> None:
        read = self._finish_read()
        if read is None or isinstance(exc, ReadCancelled):
            return
        if not self.playing:
            if self._wanted is None and read.prefetch:
                return  # read ahead for a playback that has stopped: nobody waits for it
            if self._wanted is not None and self._wanted != read.index:
                self._request(self._wanted)  # the slider moved on past the broken point
                return
        self._fail(read.index, str(exc) or type(exc).__name__)

    def _finish_read(self) -> _Read | None:
        """The read whose worker just reported: its thread ends; None when it was cancelled
        (another file opened since, or the window closes)."""
        worker = self.sender()
        for read in [self._read, *self._finishing]:
            if read is not None and read.worker is worker:
                break
        else:
            return None
        read.thread.quit()
        read.thread.wait()
        read.thread.deleteLater()
        read.worker.deleteLater()
        if read is self._read:
            self._read = None
        else:
            self._finishing.remove(read)
        if read.generation != self._generation or self._closed:
            return None
        return read

    def _cancel_read(self) -> None:
        if self._read is not None:
            self._read.worker.cancel()
            self._finishing.append(self._read)
            self._read = None

    # -- playback -------------------------------------------------------------------------------
    @property
    def playing(self) -> bool:
        return self._timer.isActive()

    @property
    def fps(self) -> float:
        """Playback speed (time points per second)."""
        return self._fps

    @fps.setter
    def fps(self, value: float) -> None:
        value = float(value)
        if not (math.isfinite(value) and MIN_FPS <= value <= MAX_FPS):
            raise ValueError(f"playback speed must be {MIN_FPS}–{MAX_FPS} fps, not {value}")
        self._fps = value
        self._timer.setInterval(max(1, round(1000.0 / value)))
        if self.playing:
            self._restart_clock()

    def play(self) -> None:
        """Play from the shown time point (from the start when at the end without loop)."""
        if not self.is_series or self.playing:
            return
        if not self.loop and self.shown_index >= self.count - 1:
            self.go_to(0)
        self._frame_times.clear()
        self.dropped_ticks = self.skipped_points = 0
        self._restart_clock()
        self._timer.start(max(1, round(1000.0 / self._fps)))
        self.playingChanged.emit(True)
        self._prefetch(self._shown_position + 1)

    def pause(self) -> None:
        if self.playing:
            self._timer.stop()
            self._frame_times.clear()
            self.playingChanged.emit(False)
            self.stateChanged.emit()

    def toggle_playing(self) -> None:
        self.pause() if self.playing else self.play()

    def effective_rate(self) -> float:
        """Points shown per second over the last :data:`RATE_POINTS` shown while playing."""
        times = self._frame_times
        if len(times) < 2 or times[-1] <= times[0]:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def _restart_clock(self) -> None:
        self._clock_start = time.perf_counter()
        self._clock_position = self._shown_position = self.shown_index

    def _clock_target(self, now: float) -> int:
        """The unwrapped position the clock has reached (at least one past the shown one)."""
        position = self._clock_position + int((now - self._clock_start) * self._fps)
        return max(position, self._shown_position + 1)

    def _index_at(self, position: int) -> int | None:
        if self.loop:
            return position % self.count
        return position if position < self.count else None

    def _tick(self) -> None:
        if not self.is_series or self._closed:
            self.pause()
            return
        if not self.loop and self.shown_index >= self.count - 1:
            self.pause()  # the last time point is on screen
            return
        if self._wanted is not None or (self.view_ready is not None and not self.view_ready()):
            self.dropped_ticks += 1  # the point asked for last is still being read or drawn
            return
        now = time.perf_counter()
        if self.every_point:
            target = self._shown_position + 1
        else:
            target = self._clock_target(now)
            # Never past this loop's last point: beyond it the index would be lower than the
            # one shown (0 → 4 → 3 → 2 at one loop minus one per tick).
            lap_end = ((self._shown_position + 1) // self.count + 1) * self.count - 1
            if target > lap_end:
                target = lap_end
                self._clock_start, self._clock_position = now, lap_end
        if not self.loop:
            target = min(target, self.count - 1)
        # The newest cached point between the one shown and the clock's: drop the rest.
        lowest = max(self._shown_position + 1, target - MAX_LOOK_BACK)
        for position in range(target, lowest - 1, -1):
            index = self._index_at(position)
            if index is not None and index in self.cache:
                self.skipped_points += position - self._shown_position - 1
                self._shown_position = position
                self.model.volume.time_index = index  # shows it (a cache hit)
                break
        else:
            self.dropped_ticks += 1
            index = self._index_at(target)
            if self._read is None and index is not None:
                # Nothing read ahead (no room in the cache, or reads slower than the clock):
                # the clock's point itself, shown when its read is done.
                self.skipped_points += target - self._shown_position - 1
                self._shown_position = target
                self.model.volume.time_index = index
                return
        if self._read is None and self.playing:
            self._prefetch(target)

    def _prefetch(self, position: int) -> None:
        """Read ahead: the first uncached point from where the clock will be once a read of
        the usual duration is done."""
        if self._read is not None or not self.playing or not self.read_ahead:
            return
        frame_bytes = max(1, math.prod(self._shape or (1,)) * self._itemsize)
        room = self.cache.max_bytes // frame_bytes
        if room < 2:
            return  # a point read ahead would push out the one on screen or be dropped
        read_s = (sum(self._read_seconds) / len(self._read_seconds)) if self._read_seconds else 0
        ahead = max(0, math.ceil(read_s * self._fps) - 1)
        for position_ in range(position + ahead, position + ahead + min(room - 1, self.count)):
            index = self._index_at(position_)
            if index is None:
                return
            if index not in self.cache:
                self._start_read(index, prefetch=True)
                return

    # -- teardown -------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop playback and reads; wait for the worker threads (idempotent)."""
        if self._closed:
            return
        self.pause()
        self._cancel_read()
        self._closed = True
        for read in self._finishing:
            read.thread.quit()
            read.thread.wait()
        self._finishing.clear()
        self.model.changed.disconnect(self._on_model_changed)


class TimeBar(QWidget):
    """The time series' controls: step back, Play/Pause, step forward, the slider, the time
    point (index, and the time where the file states its interval), speed, loop and the
    cache's size. Widgets write the model (through the player); the model moves them."""

    def __init__(self, player: TimeSeriesPlayer, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.player = player
        model = player.model
        layout = QHBoxLayout(self)
        layout.setContentsMargins(6, 2, 6, 2)

        def button(text: str, tip: str, name: str) -> QToolButton:
            b = QToolButton(self)
            b.setText(text)
            b.setToolTip(tip)
            b.setObjectName(name)
            layout.addWidget(b)
            return b

        self.back_button = button("◀", "Previous time point (,)", "time_back")
        self.back_button.clicked.connect(lambda: player.step(-1))
        self.play_button = button("Play", "Play or pause the time series (P)", "time_play")
        self.play_button.setCheckable(True)
        self.play_button.toggled.connect(self._on_play_toggled)
        self.forward_button = button("▶", "Next time point (.)", "time_forward")
        self.forward_button.clicked.connect(lambda: player.step(1))

        self.slider = QSlider(Qt.Orientation.Horizontal, self)
        self.slider.setObjectName("time_slider")
        self.slider.setToolTip("Time point")
        self.slider.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.slider.setMinimumWidth(160)
        self.slider.valueChanged.connect(self._on_slider)
        layout.addWidget(self.slider, 1)

        self.index_box = QSpinBox(self)
        self.index_box.setObjectName("time_index")
        self.index_box.setToolTip("Time point index, from 0 (as vtkvol render --time and "
                                  "sessions count)")
        self.index_box.setKeyboardTracking(False)
        self.index_box.valueChanged.connect(self._on_slider)
        layout.addWidget(self.index_box)
        self.label = QLabel(self)
        self.label.setObjectName("time_label")
        layout.addWidget(self.label)

        self.fps_box = QDoubleSpinBox(self)
        self.fps_box.setObjectName("time_fps")
        self.fps_box.setRange(MIN_FPS, MAX_FPS)
        self.fps_box.setDecimals(1)
        self.fps_box.setSuffix(" fps")
        self.fps_box.setValue(player.fps)
        self.fps_box.setToolTip("Playback speed: time points per second. When reading or "
                                "rendering is slower, time points are skipped, not queued")
        self.fps_box.valueChanged.connect(self._on_fps)
        layout.addWidget(self.fps_box)
        self.loop_box = QCheckBox("Loop", self)
        self.loop_box.setObjectName("time_loop")
        self.loop_box.setChecked(player.loop)
        self.loop_box.setToolTip("Start again from the first time point after the last")
        self.loop_box.toggled.connect(self._on_loop)
        layout.addWidget(self.loop_box)
        self.every_point_box = QCheckBox("Every point", self)
        self.every_point_box.setObjectName("time_every_point")
        self.every_point_box.setChecked(player.every_point)
        self.every_point_box.setToolTip(
            "Show every time point in turn, as fast as reading and rendering allow (at most "
            "the speed set). Off: real time, skipping points when the view is slower")
        self.every_point_box.toggled.connect(self._on_every_point)
        layout.addWidget(self.every_point_box)
        self.cache_box = QSpinBox(self)
        self.cache_box.setObjectName("time_cache")
        self.cache_box.setRange(0, max(1, max_cache_bytes() // MIB))
        self.cache_box.setSuffix(" MiB")
        self.cache_box.setPrefix("cache ")
        self.cache_box.setKeyboardTracking(False)
        self.cache_box.setValue(player.cache.max_bytes // MIB)
        self.cache_box.valueChanged.connect(lambda mib: player.set_cache_bytes(mib * MIB))
        layout.addWidget(self.cache_box)

        player.stateChanged.connect(self.refresh)
        player.playingChanged.connect(self._show_playing)
        model.changed.connect(self._on_model_changed)
        self.refresh()

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "volume"):
            self.refresh()

    def refresh(self) -> None:
        """Show the model's time point and the player's state."""
        player = self.player
        last = max(player.count - 1, 0)
        index = min(player.model.volume.time_index, last)
        for widget in (self.slider, self.index_box):
            widget.blockSignals(True)
            widget.setRange(0, last)
            widget.setValue(index)
            widget.blockSignals(False)
        self.slider.setPageStep(max(1, player.count // 10))
        when = player.time_text(index)
        text = f"of {player.count}" + (f" · {when}" if when else "")
        if player.pending:
            text += " · reading…"
        self.label.setText(text)
        self.cache_box.blockSignals(True)
        self.cache_box.setValue(player.cache.max_bytes // MIB)
        self.cache_box.blockSignals(False)
        self.cache_box.setToolTip(
            "Time points kept in memory so that going back shows them without reading: "
            f"{player.cache.describe()}")

    def _on_slider(self, value: int) -> None:
        self.player.pause()
        self.player.go_to(value)

    def _on_play_toggled(self, on: bool) -> None:
        if on != self.player.playing:
            self.player.play() if on else self.player.pause()
        self._show_playing(self.player.playing)

    def _show_playing(self, playing: bool) -> None:
        self.play_button.blockSignals(True)
        self.play_button.setChecked(playing)
        self.play_button.setText("Pause" if playing else "Play")
        self.play_button.blockSignals(False)

    def _on_fps(self, value: float) -> None:
        self.player.fps = value

    def _on_every_point(self, on: bool) -> None:
        self.player.every_point = bool(on)
        if self.player.playing:
            self.player._restart_clock()

    def _on_loop(self, on: bool) -> None:
        self.player.loop = bool(on)

    def release(self) -> None:
        self.player.model.changed.disconnect(self._on_model_changed)
