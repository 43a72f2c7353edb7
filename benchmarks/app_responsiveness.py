"""How long the app's event loop stalls while a user works (issue 15's responsiveness
acceptance). Not part of the installed library; run from a checkout:

    python benchmarks/app_responsiveness.py                      # 100×256×256, two channels
    python benchmarks/app_responsiveness.py --shape 32 64 64     # a quick dry run

Without ``$DISPLAY`` it re-runs itself under ``xvfb-run``. It writes a two-point time-lapse
of a generated two-channel uint16 stack (the built-in confocal phantom at the given size, the
second point shifted) as an ImageJ TIFF, starts a 10 ms ``QTimer`` heartbeat that records the
largest gap between its ticks (the longest time the event loop could not run: no repaint, no
input, no Cancel), and scripts, through the window's public widgets and model only (so the
same script measures older versions), issue 25 §1's gestures:

1. **open a file**: ``MainWindow.open_path`` on the time-lapse (read in the background);
2. **TF drag**: a press in the transfer-function editor, 6 moves 40 ms apart, a release
   (local shading);
3. **new input during refinement**: a TF drag, then 300 ms after its release (while the
   full-quality frame or its refinement is under way) a second short drag; the row's
   ``input_to_frame_ms`` is the time from when that press was due (a frame blocking the
   event loop delays it) to the first frame after it;
4. **light drag**: the light's handle in the 3-D view dragged (4 moves, 60 ms apart);
5. **crop**: the crop box's x range halved (a model edit, as the crop dock's slider does);
6. **time step**: the time slider's next point (read in the background, then shown);
7. **method switches**: shadow volume (precomputed), a light drag with it, cone-traced AO,
   hybrid diffusion (progressive, given ``--progressive-timeout`` seconds) and back to local.

Each phase reports the longest stall *during* the scripted gesture and *after* it, until no
frame has been rendered for a while (the settle frame, the precompute), the longest stall
that overlaps no frame (work outside VTK's render: a precomputation run in chunks shows here
as its longest chunk), the longest frame (``Viewport.frameRendered``'s duration; with the
precomputation inside the frame, as older versions ran it, that includes it) and the phase's
wall time, and the time from the gesture's start to the first frame after it (the first
coarse image). Prints a markdown table; ``--json`` writes the rows too.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

#: Heartbeat interval (ms).
HEARTBEAT_MS = 10
#: A phase is over when no frame was rendered for this long (s) after its gesture ended.
QUIET_S = 1.5


def _reexec_under_xvfb() -> None:
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    runner = shutil.which("xvfb-run")
    if runner is None:
        sys.exit("no X display and no xvfb-run: run under an X server")
    args = [runner, "-a", "-s", "-screen 0 1600x1000x24", sys.executable, *sys.argv]
    sys.exit(subprocess.call(args))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--shape", type=int, nargs=3, default=(100, 256, 256),
                        metavar=("Z", "Y", "X"), help="stack size in voxels (z y x)")
    parser.add_argument("--window", type=int, nargs=2, default=(960, 640),
                        metavar=("W", "H"), help="window size in pixels")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON here")
    parser.add_argument("--phase-timeout", type=float, default=240.0,
                        help="give up waiting for one phase to settle after this many seconds")
    parser.add_argument("--frames", action="store_true", help="print every frame's duration")
    parser.add_argument("--progressive-timeout", type=float, default=60.0,
                        help="seconds given to a progressive method before moving on")
    parser.add_argument("--profile", type=Path, metavar="DIR",
                        help="write each phase's cProfile statistics to DIR/<phase>.prof "
                             "(where a stall's time goes; the profiler slows Python a little)")
    args = parser.parse_args()
    _reexec_under_xvfb()

    os.environ.setdefault("QT_API", "pyside6")
    import numpy as np
    import tifffile
    from PySide6.QtCore import QElapsedTimer, QEventLoop, QPoint, QPointF, QSettings, Qt, QTimer
    from PySide6.QtGui import QMouseEvent
    from PySide6.QtWidgets import QApplication

    from vtkvol.io import confocal_phantom
    from vtkvol.ui.app import MainWindow, configure_gl_platform

    app = QApplication.instance() or QApplication(sys.argv)
    configure_gl_platform(app)
    settings = QSettings(str(Path(tempfile.mkdtemp()) / "vtkvol.ini"),
                         QSettings.Format.IniFormat)
    window = MainWindow(settings=settings)
    window.resize(*args.window)
    window.show()
    app.processEvents()

    # -- heartbeat ---------------------------------------------------------------------------
    clock = QElapsedTimer()
    clock.start()
    state = {"last": 0.0, "max_gap": 0.0, "last_frame": 0.0, "frames": 0}
    gaps: list[tuple[float, float]] = []  # heartbeat gaps over 3 intervals (start, end), ms
    frames: list[tuple[float, float]] = []  # frames (start, end), ms

    def tick() -> None:
        now = clock.nsecsElapsed() / 1e6
        state["max_gap"] = max(state["max_gap"], now - state["last"])
        if now - state["last"] > 3 * HEARTBEAT_MS:
            gaps.append((state["last"], now))
        state["last"] = now

    def on_frame(frame_ms: float, *_: object) -> None:
        now = clock.nsecsElapsed() / 1e6
        state["last_frame"] = now
        state["frames"] += 1
        frames.append((now - frame_ms, now))
        if args.frames:  # what the view rendered (newer versions say which kind of frame)
            planned = getattr(window.viewport, "_frame", None)
            kind = "" if planned is None else f" {planned.kind} 1/{planned.image_factor:g}"
            print(f"  frame {frame_ms:.0f} ms{kind}", flush=True)

    heartbeat = QTimer()
    heartbeat.setInterval(HEARTBEAT_MS)
    heartbeat.setTimerType(Qt.TimerType.PreciseTimer)
    heartbeat.timeout.connect(tick)
    window.viewport.frameRendered.connect(on_frame)

    def reset_gap() -> None:
        state["last"] = clock.nsecsElapsed() / 1e6
        state["max_gap"] = 0.0

    def spin(ms: float) -> None:
        """Run the event loop for ``ms`` (late when a frame blocks it, like a real user)."""
        loop = QEventLoop()
        QTimer.singleShot(max(0, round(ms)), loop.quit)
        loop.exec()

    def pending() -> bool:
        """A frame or the settle frame is still to come (the view's timers; read through
        getattr so older versions, which have the same timers, are measured alike)."""
        vp = window.viewport
        timers = [getattr(vp, name, None) for name in ("_render_timer", "_settle_timer")]
        player = getattr(window, "time_player", None)
        return any(t is not None and t.isActive() for t in timers) or bool(
            getattr(vp, "busy", False) or getattr(vp.plotter, "needs_render", False)
            or getattr(player, "pending", False))  # a time point still being read

    def wait_quiet(timeout_s: float) -> bool:
        """Run the loop until nothing is pending and no frame has been rendered for
        QUIET_S."""
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < timeout_s:
            spin(100)
            idle = clock.nsecsElapsed() / 1e6 - state["last_frame"]
            if idle > QUIET_S * 1e3 and not pending():
                return True
        return False

    rows: list[dict[str, object]] = []

    marks: dict[str, float] = {}

    def phase(name: str, gesture: Callable[[], None], timeout_s: float | None = None) -> None:
        frames0 = state["frames"]
        gaps0, frame_list0 = len(gaps), len(frames)
        marks.clear()
        t0 = time.perf_counter()
        start_ms = clock.nsecsElapsed() / 1e6
        profiler = cProfile.Profile() if args.profile is not None else None
        if profiler is not None:
            profiler.enable()
        reset_gap()
        gesture()
        during = state["max_gap"]
        gesture_s = time.perf_counter() - t0
        reset_gap()
        settled = wait_quiet(args.phase_timeout if timeout_s is None else timeout_s)
        if profiler is not None:
            profiler.disable()
            args.profile.mkdir(parents=True, exist_ok=True)
            slug = "".join(c if c.isalnum() else "-" for c in name).strip("-")
            profiler.dump_stats(args.profile / f"{slug}.prof")
        after = state["max_gap"]
        total = time.perf_counter() - t0 - (QUIET_S if settled else 0.0)
        phase_frames = frames[frame_list0:]
        outside = [end - start for start, end in gaps[gaps0:]
                   if not any(start < f_end and f_start < end for f_start, f_end in phase_frames)]
        first = min((end for _s, end in phase_frames if end > start_ms), default=None)
        input_ms = marks.get("input")
        after_input = min((end for _s, end in phase_frames if input_ms is not None
                           and end > input_ms), default=None)
        row = {"phase": name, "stall_during_ms": round(during), "stall_after_ms": round(after),
               "first_frame_ms": None if first is None else round(first - start_ms),
               "input_to_frame_ms": (None if after_input is None or input_ms is None
                                     else round(after_input - input_ms)),
               "stall_outside_frames_ms": round(max(outside, default=0.0)),
               "longest_frame_ms": round(max((e - s for s, e in phase_frames), default=0.0)),
               "gesture_s": round(gesture_s, 2), "until_idle_s": round(total, 2),
               "frames": state["frames"] - frames0, "settled": settled}
        rows.append(row)
        print(json.dumps(row), flush=True)

    def send_mouse(widget, kind, pos: QPoint, button, buttons) -> None:
        event = QMouseEvent(kind, QPointF(pos), QPointF(widget.mapToGlobal(pos)), button, buttons,
                            Qt.KeyboardModifier.NoModifier)
        QApplication.sendEvent(widget, event)

    def drag(widget, points: list[QPoint], interval_ms: float) -> None:
        left = Qt.MouseButton.LeftButton
        none = Qt.MouseButton.NoButton
        send_mouse(widget, QMouseEvent.Type.MouseButtonPress, points[0], left, left)
        for p in points[1:]:
            spin(interval_ms)
            send_mouse(widget, QMouseEvent.Type.MouseMove, p, none, left)
        spin(interval_ms)
        send_mouse(widget, QMouseEvent.Type.MouseButtonRelease, points[-1], left, none)

    # -- data: a two-point, two-channel time-lapse (TCZYX) ------------------------------------
    t0 = time.perf_counter()
    data = confocal_phantom(shape_zyx=tuple(args.shape))
    stack = np.asarray(data.array)  # (C, Z, Y, X)
    lapse = np.stack([stack, np.roll(stack, stack.shape[-1] // 16, axis=-1)])
    lapse_path = Path(tempfile.mkdtemp()) / "lapse.tif"
    tifffile.imwrite(lapse_path, np.ascontiguousarray(lapse.transpose(0, 2, 1, 3, 4)),
                     imagej=True, metadata={"axes": "TZCYX", "finterval": 60.0, "unit": "um",
                                            "spacing": 1.0},
                     resolution=(1.0, 1.0))
    generate_s = time.perf_counter() - t0
    heartbeat.start()
    spin(200)

    def open_file() -> None:
        window.open_path(lapse_path)
        t_open = time.perf_counter()
        while window.viewport.scene is None and time.perf_counter() - t_open < 120:
            spin(20)

    phase("open a file", open_file)
    view = window.viewport.plotter
    print(json.dumps({"stack": list(stack.shape), "dtype": str(stack.dtype), "time_points": 2,
                      "generate_s": round(generate_s, 2),
                      "view_px": [view.width(), view.height()],
                      "load_average": os.getloadavg()}), flush=True)

    # -- phases ------------------------------------------------------------------------------
    window.tf_dock.raise_()
    editor = window.tf_dock.editor
    app.processEvents()

    def tf_drag() -> None:
        rect = editor.plot_rect()
        x = rect.left() + 0.45 * rect.width()
        ys = [0.75, 0.6, 0.45, 0.35, 0.45, 0.55, 0.5]
        points = [QPoint(round(x + 2 * i), round(rect.top() + y * rect.height()))
                  for i, y in enumerate(ys)]
        drag(editor, points, 40)

    def input_during_refinement() -> None:
        tf_drag()
        # The user's next press is due 300 ms after the release; a frame that blocks the
        # event loop delays it, which is part of the latency measured.
        marks["input"] = clock.nsecsElapsed() / 1e6 + 300
        spin(300)
        rect = editor.plot_rect()
        x = rect.left() + 0.47 * rect.width()
        drag(editor, [QPoint(round(x), round(rect.top() + y * rect.height()))
                      for y in (0.5, 0.4, 0.45)], 40)

    def crop() -> None:
        b = window.viewport.bounds
        window.model.crop.x = (b[0], b[0] + 0.5 * (b[1] - b[0]))
        spin(0)

    def time_step() -> None:
        window.time_player.step(1)
        spin(0)

    def set_method(name: str) -> Callable[[], None]:
        def gesture() -> None:
            window.model.illumination.method = name
            spin(0)
        return gesture

    def light_drag() -> None:
        vp = window.viewport
        renderer = vp.renderer
        renderer.SetWorldPoint(*vp.gizmo.handle_position(), 1.0)
        renderer.WorldToDisplay()
        hx, hy, _ = renderer.GetDisplayPoint()
        ratio = vp.plotter.devicePixelRatioF()
        start = QPoint(round(hx / ratio), round(vp.plotter.height() - hy / ratio))
        points = [start + QPoint(-10 * i, 6 * i) for i in range(5)]
        drag(vp.plotter, points, 60)

    phase("TF drag (local shading)", tf_drag)
    phase("new input during refinement (TF)", input_during_refinement)
    phase("light drag (local shading)", light_drag)
    phase("crop (x halved)", crop)
    phase("time step (unread point)", time_step)
    phase("switch to shadow volume (precompute)", set_method("shadow_volume"))
    phase("light drag (shadow volume)", light_drag)
    phase("switch to cone-traced AO (precompute)", set_method("cone_traced"))
    phase("switch to hybrid diffusion (progressive)", set_method("hybrid_diffusion"),
          timeout_s=args.progressive_timeout)
    phase("switch back to local shading", set_method("local"))

    heartbeat.stop()
    window.close()
    print()
    print(f"load average before/after: {os.getloadavg()}")
    print("| phase | longest stall during the gesture | longest stall after it | "
          "first frame after the gesture | new input → frame | longest frame | until idle | "
          "frames |")
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        cancel = "" if row["input_to_frame_ms"] is None else f"{row['input_to_frame_ms']} ms"
        first = "–" if row["first_frame_ms"] is None else f"{row['first_frame_ms']} ms"
        settled = "" if row["settled"] else " (not idle yet)"
        print(f"| {row['phase']} | {row['stall_during_ms']} ms | {row['stall_after_ms']} ms | "
              f"{first} | {cancel} | {row['longest_frame_ms']} ms | "
              f"{row['until_idle_s']} s{settled} | {row['frames']} |")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
