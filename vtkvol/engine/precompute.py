"""The precompute runner: a technique's chunked precomputation, outside a frame.

One service of the technique host. It runs the chunks a technique's ``prepare_steps`` yields
with the render window's context current before each, reports progress between them (an
application's event loop may run there), cancels to local shading when asked, turns a
failure into the host's ``on_error`` instead of a lost view, and renders progressive
techniques until they converge (:meth:`PrecomputeRunner.converge`).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import time
from collections.abc import Callable, Iterator
from typing import Any

from vtkvol.engine.technique import Changes
from vtkvol.model.params import Invalidates

# Failures are logged under the host's name: applications and tests filter on it.
logger = logging.getLogger("vtkvol.engine.illuminator")


@contextlib.contextmanager
def no_collection() -> Iterator[None]:
    """No cyclic garbage collection while we run inside VTK's render: collecting a forgotten
    render window there finalises it, which leaves *no* GL context current, and every GL call
    after it (ours, and VTK's for the rest of the frame) silently does nothing."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


class PrecomputeRunner:
    """Chunks, cancel and convergence of one host's technique."""

    def __init__(self, host: Any) -> None:
        # The host (engine/illuminator.py), typed loosely: importing it here would close an
        # import circle (scripts/import_graph.py).
        self._host = host
        #: True while :meth:`run` runs its chunks (frames then touch no technique state).
        self.stepping = False

    def precompute(self, progress: Callable[[float], bool] | None = None) -> bool:
        """The host's :meth:`~vtkvol.engine.illuminator.Illuminator.precompute`: take in the
        changes, prepare the technique's chunks and :meth:`run` them."""
        host = self._host
        if (host._closed or self.stepping or host._unsupported is not None
                or host.render_window is None or host.spec.has("progressive")):
            return True
        if host.defer_precompute and host._technique is not None and not host._detach_requested:
            return True
        window = host.render_window
        with no_collection():
            window.MakeCurrent()
            host.light_rig.take_renderer_lights()
            with host.light_rig.frame(host.image):
                host._ensure_technique()
                if not host.changes.needs_prepare(host.changes.pending):
                    return True
                host._upload_weights()
                steps = host._technique.prepare_steps(host.changes.take(), host.parameters)
        return self.run(steps, progress)

    def run(self, steps: Iterator[float], progress: Callable[[float], bool] | None) -> bool:
        window = self._host.render_window
        assert window is not None
        work_s = 0.0  # the chunks' time, without the event loop's in between
        self.stepping = True
        try:
            while True:
                with no_collection():
                    window.MakeCurrent()
                    t0 = time.perf_counter()
                    try:
                        with self._host.light_rig.frame(self._host.image):
                            fraction = next(steps)
                    except StopIteration:
                        break
                    finally:
                        work_s += time.perf_counter() - t0
                    if self._host._technique is not None:
                        self._host._on_draw_end()  # units go back between chunks
                if progress is not None and not progress(min(max(float(fraction), 0.0), 1.0)):
                    steps.close()
                    self.cancel()
                    return False
                if self._host._closed:  # released while the progress callback ran an event loop
                    steps.close()
                    return False
        except Exception as exc:  # a technique's GL or numpy failure must not kill the view
            logger.exception("illumination %s failed to precompute", self._host.method)
            with no_collection():
                window.MakeCurrent()
                self._host._fail(f"failed ({type(exc).__name__}: {exc})")
                self._host._release_technique()
                self._host._detach_requested = False
        finally:
            self.stepping = False
            self._host._precomputed_ms += work_s * 1e3  # reported with the next frame
        self._host.cancelled_method = None
        return True

    def cancel(self) -> None:
        """Local shading, with nothing of the cancelled technique left bound."""
        if self._host._closed:
            return
        cancelled = self._host.method
        window = self._host.render_window
        with no_collection():
            if window is not None:
                window.MakeCurrent()
            self._host._release_technique()
            self._host._detach_requested = False
            self._host.set_method("local")
        self._host.cancelled_method = cancelled
        logger.info("illumination %s: precomputation cancelled; local shading", cancelled)

    def converge(self, max_frames: int | None = None, max_seconds: float | None = None, *,
                 iterations: int | None = None) -> int:
        """Render until the technique has converged, has reached ``iterations`` of its own
        iterations, ``max_frames`` frames have been rendered or ``max_seconds`` have passed
        (batch rendering, scripts). Returns the number of frames rendered. Non-progressive
        techniques need one frame."""
        window = self._host.renderer.GetRenderWindow()
        if window is None:
            raise RuntimeError("the renderer is not in a render window")
        t0 = time.perf_counter()
        frames = 0
        while True:
            window.Render()
            frames += 1
            if not self._host.wants_frame:
                break
            host = self._host
            tech = host.beside if host.beside is not None else host._technique
            if iterations is not None and tech is not None and tech.iteration >= iterations:
                break
            if max_frames is not None and frames >= max_frames:
                break
            if max_seconds is not None and time.perf_counter() - t0 >= max_seconds:
                break
        return frames

    def defers(self, changes: Changes) -> bool:
        """Whether this frame keeps the previous light (:attr:`defer_precompute`)."""
        if not self._host.defer_precompute or changes.first or self._host._technique is None:
            return False
        if changes.invalidates & Invalidates.SHADER:
            return False
        # What a drag changes (opacity, light geometry, parameters) waits; camera-only
        # changes of view-dependent techniques do not (they follow the view as before).
        # Progressive refinement pauses too.
        return bool(changes.opacity or changes.lights or changes.parameters
                    or changes.invalidates or not self._host._technique.converged)
