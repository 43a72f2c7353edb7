"""Development study of time-lapse playback in the app (not part of the installed library):
how many time points per second the app shows while playing, with and without read-ahead,
cold (every point read) and from the time-point cache, and how long a step takes.

Run from the checkout under an X server (the app's view is a Qt OpenGL widget)::

    xvfb-run -a -s "-screen 0 1280x1024x24" python benchmarks/time_playback.py

It writes two ImageJ TZYX stacks to a temporary folder (20 time points each: 12 × 32 × 32
and 32 × 128 × 128 uint16), opens each in a :class:`vtkvol.ui.app.MainWindow` with a
256 × 256 view, and prints markdown tables. Every row plays the series once (no loop) at
``FPS``; "cold" rows start with only the first point in the cache, "cached" rows after every
point was read.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import tifffile

os.environ.setdefault("QT_API", "pyside6")

#: Requested playback speed (time points per second).
FPS = 5.0
SHAPES = ((12, 32, 32), (32, 128, 128))
N_TIME = 20


def write_stack(path: Path, shape_zyx: tuple[int, int, int]) -> None:
    """A ball moving along x over noise, ``N_TIME`` points, 30 s apart."""
    rng = np.random.default_rng(1)
    nz, ny, nx = shape_zyx
    z, y, x = np.mgrid[0:nz, 0:ny, 0:nx].astype(np.float32)
    stack = np.empty((N_TIME, *shape_zyx), np.uint16)
    for t in range(N_TIME):
        cx = nx * (0.2 + 0.6 * t / N_TIME)
        r = nx / 8
        ball = np.exp(-(((x - cx) / r) ** 2 + ((y - ny / 2) / r) ** 2
                        + ((z - nz / 2) / (nz / 4)) ** 2))
        stack[t] = (100 + 3000 * ball + rng.normal(0, 10, shape_zyx)).clip(0).astype(np.uint16)
    tifffile.imwrite(path, stack, imagej=True,
                     metadata={"axes": "TZYX", "finterval": 30.0, "tunit": "sec"})


def wait(app, condition, timeout: float = 60.0) -> None:
    end = time.perf_counter() + timeout
    while not condition():
        if time.perf_counter() > end:
            raise TimeoutError("the app did not get there in time")
        app.processEvents()
        time.sleep(0.001)


def play_row(app, window, *, cold: bool, read_ahead: bool) -> dict[str, float]:
    """One pass over the series (no loop) at ``FPS``, from time point 0."""
    player = window.time_player
    player.pause()
    player.go_to(0)
    wait(app, lambda: player.shown_index == 0 and not player.pending)
    if cold:
        player.cache.clear()
        player.cache.put(0, window.document.as_read)
    player.read_ahead = read_ahead
    player.loop = False
    player.fps = FPS
    shown: list[int] = []
    frame_ms: list[float] = []
    reads_s: list[float] = []
    player.shown.connect(shown.append)

    def on_frame(ms: float, _light_ms: float) -> None:
        frame_ms.append(ms)

    window.viewport.frameRendered.connect(on_frame)
    reads = player.reads_started
    t0 = time.perf_counter()
    player.play()
    wait(app, lambda: not player.playing, timeout=N_TIME / FPS + 60)
    elapsed = time.perf_counter() - t0
    reads_s.extend(player._read_seconds)
    player.shown.disconnect(shown.append)
    window.viewport.frameRendered.disconnect(on_frame)
    return {"shown_per_s": len(shown) / elapsed, "reads": player.reads_started - reads,
            "skipped": player.skipped_points,
            "read_ms": statistics.median(reads_s) * 1e3 if cold and reads_s else float("nan"),
            "frame_ms": statistics.median(frame_ms) if frame_ms else float("nan")}


def step_ms(app, window, index: int) -> float:
    """From the request to the end of the first frame that shows time point ``index``."""
    player = window.time_player
    frames: list[float] = []

    def rendered(*_):
        if player.shown_index == index:
            frames.append(time.perf_counter())

    window.viewport.frameRendered.connect(rendered)
    t0 = time.perf_counter()
    player.go_to(index)
    wait(app, lambda: bool(frames))
    window.viewport.frameRendered.disconnect(rendered)
    return (frames[0] - t0) * 1e3


def main() -> int:
    from PySide6.QtCore import QSettings
    from PySide6.QtWidgets import QApplication

    from vtkvol.ui.app import MainWindow, configure_gl_platform

    app = QApplication.instance() or QApplication(sys.argv)
    configure_gl_platform(app)
    folder = Path(tempfile.mkdtemp(prefix="vtkvol-time-"))
    window = MainWindow(settings=QSettings(str(folder / "s.ini"), QSettings.Format.IniFormat))
    window.resize(900, 700)
    window.viewport.setMaximumSize(256, 256)
    window.show()
    print(f"| stack (z×y×x, 20 points) | method | one pass at {FPS:g} fps | shown/s | reads | "
          "points skipped | median read, to the GUI thread (ms) | median frame (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    steps = []
    for shape in SHAPES:
        path = folder / f"lapse_{'x'.join(map(str, shape))}.tif"
        write_stack(path, shape)
        window.open_path(path)
        wait(app, lambda p=path: window.data is not None and window.data.source == str(p)
             and window._task is None)
        for method in ("local", "shadow_volume"):
            window.model.illumination.method = method
            window.viewport.render_now()
            for label, cold, ahead in (("cold, read-ahead", True, True),
                                       ("cold, no read-ahead", True, False),
                                       ("cached", False, True)):
                if not cold:  # fill the cache first
                    for i in range(N_TIME):
                        step_ms(app, window, i)
                row = play_row(app, window, cold=cold, read_ahead=ahead)
                print(f"| {'×'.join(map(str, shape))} | {method} | {label} | "
                      f"{row['shown_per_s']:.1f} | {row['reads']} | {row['skipped']} | "
                      f"{row['read_ms']:.0f} | {row['frame_ms']:.0f} |")
            player = window.time_player
            player.cache.clear()
            player.cache.put(player.shown_index, window.document.as_read)
            cold_ms = step_ms(app, window, (player.shown_index + 1) % N_TIME)
            back_ms = step_ms(app, window, (player.shown_index - 1) % N_TIME)
            steps.append((shape, method, cold_ms, back_ms))
    print()
    print("| stack | method | step to an unread point (ms) | step back to a cached point (ms) |")
    print("|---|---|---|---|")
    for shape, method, cold_ms, back_ms in steps:
        print(f"| {'×'.join(map(str, shape))} | {method} | {cold_ms:.0f} | {back_ms:.0f} |")
    window.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
