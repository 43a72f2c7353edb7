"""Auto quality in the app: the illumination method picked by
:func:`vtkvol.engine.auto_quality.choose_measured`.

With ``model.illumination.auto`` on, :class:`AutoQuality` runs
:func:`vtkvol.engine.auto_quality.choose_measured` for the current opacity (data, TFs, crop,
slice weights), voxel size and lights, and writes the pick into ``illumination.method`` and
its parameters. The choice is CPU work of about a second to a few seconds (one reference
transmittance plus one CPU light volume per candidate tried), so it runs in a worker thread,
once the edits have settled (:data:`SETTLE_MS` after the last TF, light, crop or data
change, never during a drag), and a result that an edit has overtaken is dropped.

Costs are this machine's: the window reports every full-quality frame
(:meth:`AutoQuality.record_frame`, the whole view's time as the progressive refiner measures
it plus the method's precomputation) into a :class:`~vtkvol.engine.auto_quality.FrameTimes`;
settings not shown yet are scaled from :func:`~vtkvol.engine.auto_quality.default_timings`
(``$VTKVOL_BENCHMARKS``, else the measurements shipped with vtkvol) by how this machine
compares on the settings it did show. Before any frame, the order comes from those figures
alone and the words say that no frame was measured here yet.

Signals carry the outcome for the view (the Lights dock and the status bar show it):
``busy()`` when a choice starts, ``chosen(AutoOutcome)`` when one is applied, ``failed(str)``
when none can be made (a point light, no light on, no measured method).
"""

from __future__ import annotations

import contextlib
import copy
import math
import threading
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal

from vtkvol.engine.auto_quality import (
    Choice,
    FrameTimes,
    Timings,
    binned_for_prediction,
    choose_measured,
    default_timings,
    duration_words,
    setting_words,
)
from vtkvol.model.evented import touches
from vtkvol.model.scene import SceneModel
from vtkvol.model.techniques import get_spec

#: Quiet time (ms) after the last edit before choosing again: a drag sends edits every
#: ~60 ms, so the choice runs once the user lets go.
SETTLE_MS = 500

#: Largest volume the prediction runs on (voxels); larger data is averaged in blocks first
#: (:func:`~vtkvol.engine.auto_quality.binned_for_prediction`), which keeps a choice to a few
#: seconds on two cores.
MAX_PREDICTION_VOXELS = 96**3

#: ``() -> (opacity [z, y, x], voxel size (x, y, z) µm, opacity unit distance µm) | None``
OpacitySource = Callable[[], "tuple[np.ndarray, tuple[float, float, float], float] | None"]


@dataclass(frozen=True)
class AutoOutcome:
    """An applied choice and how to say it.

    ``summary``: one line for the dock and the status bar (method, parameters, predicted
    SSIM against the budget, cost source); ``details``: the full reason and every candidate
    tried, for a tooltip; ``met``: whether the budget was reached.
    """

    choice: Choice
    budget_ssim: float
    method_label: str
    summary: str
    details: str
    met: bool


def _cost_words(cost_ms: float, here: bool) -> str:
    if here and math.isfinite(cost_ms):
        return f"{duration_words(cost_ms)} a frame here"
    return "ranked by another machine's measurements (no frame measured here yet)"


def describe(choice: Choice, budget_ssim: float, method_label: str = "") -> AutoOutcome:
    """The words for ``choice``, as a user reads them: the method's title and its settings'
    labels (:func:`~vtkvol.engine.auto_quality.setting_words`), the predicted similarity
    (SSIM) against the goal, and what a frame costs on this machine. ``method_label``
    replaces the method's title (the dock's name for it)."""
    setting = setting_words(choice.method, choice.parameters)
    if method_label:
        title = setting_words(choice.method, {})
        setting = method_label + setting[len(title):] if setting.startswith(title) else setting
    met = choice.predicted_ssim >= budget_ssim
    cost = _cost_words(choice.cost_ms, choice.cost_here)
    if met:
        summary = (f"Auto picked {setting}: predicted similarity to the reference "
                   f"{choice.predicted_ssim:.3f} (goal {budget_ssim:g}); {cost}.")
    else:
        summary = (f"Goal not reachable: no method is predicted to reach similarity "
                   f"{budget_ssim:g} to the reference; using the closest, {setting} "
                   f"({choice.predicted_ssim:.3f}); {cost}.")
    tried = "\n".join(
        f"  {setting_words(c.get('method', c['label']), c.get('parameters', {}))}: "
        f"similarity {c['predicted_ssim']:.3f}, "
        f"{_cost_words(c['cost_ms'], choice.cost_here)}"
        for c in choice.considered)
    details = (f"{summary}\n\nTried, cheapest first:\n{tried}\n\nCosts: "
               f"{choice.cost_source or 'the given timings'}.")
    return AutoOutcome(choice, budget_ssim, method_label, summary, details, met)


class AutoQuality(QObject):
    """Keeps ``illumination.method`` at :func:`choose_measured`'s pick while Auto is on.

    ``opacity_source`` gives what the illumination sees (``Viewport.opacity_snapshot``);
    ``engine_edit`` wraps the model writes (the undo recorder's ``amending``: a pick is a
    consequence of the user's edit, not a step of its own); ``method_labels`` maps technique
    names to display names; ``timings`` overrides :func:`default_timings` (tests).
    """

    busy = Signal()
    chosen = Signal(object)  #: AutoOutcome
    failed = Signal(str)
    _done = Signal(int, object, object)  # generation, Choice | None, error text | None

    def __init__(self, model: SceneModel, opacity_source: OpacitySource, *,
                 engine_edit: Callable[[], AbstractContextManager[None]] = nullcontext,
                 method_labels: dict[str, str] | None = None,
                 timings: Timings | None = None, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self._opacity_source = opacity_source
        self.engine_edit = engine_edit
        self.method_labels = dict(method_labels or {})
        self._timings = timings
        #: This machine's full-quality frames, per setting (see :meth:`record_frame`).
        self.frames = FrameTimes()
        #: The frame times the last applied choice was made with (a copy of :attr:`frames`).
        self.last_frames: FrameTimes | None = None
        self._frames_in_use: FrameTimes | None = None
        self._generation = 0
        self._running = False
        self._pending = False
        self._closed = False
        self.last_outcome: AutoOutcome | None = None
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(SETTLE_MS)
        self._timer.timeout.connect(self._start)
        self._done.connect(self._finished)
        model.changed.connect(self._on_model_changed)

    # -- when to choose -------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """A choice is being computed or waits for edits to settle."""
        return self._running or self._timer.isActive()

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        illumination = self.model.illumination
        if touches(paths, "illumination", "auto") or touches(
                paths, "illumination", "auto_budget_ssim"):
            if illumination.auto:
                self.request(delay_ms=0)
            else:
                self._generation += 1  # a running choice is no longer wanted
                self._timer.stop()
                self.last_outcome = None
            return
        if illumination.auto and (
                touches(paths, "channels") or touches(paths, "lights")
                or touches(paths, "crop") or touches(paths, "slice_weights")
                or touches(paths, "volume") or touches(paths, "render", "opacity_unit_distance")):
            self.request()

    def request(self, delay_ms: int = SETTLE_MS) -> None:
        """Choose again once edits have been quiet for ``delay_ms`` (ms); also after new data
        is shown."""
        if self._closed or not self.model.illumination.auto:
            return
        self._generation += 1
        self._timer.start(delay_ms)

    def record_frame(self, frame_ms: float | None, prepare_ms: float = 0.0) -> None:
        """A full-quality frame of the current method was shown: ``frame_ms`` for the whole
        view (None: unknown, e.g. an interactive frame), ``prepare_ms`` its precomputation."""
        if frame_ms is None:
            return
        illumination = self.model.illumination
        try:
            values = {**get_spec(illumination.method).defaults(), **illumination.values_for()}
        except (ValueError, KeyError):  # a method whose plugin went away
            return
        self.frames.record(illumination.method, values, frame_ms, prepare_ms)

    # -- choosing -------------------------------------------------------------------------------
    def _lights(self) -> list[Any]:
        """The lights choose sees; ValueError says why Auto cannot serve them."""
        lit = [(i, light) for i, light in enumerate(self.model.lights)
               if light.enabled and light.intensity > 0]
        if not lit:
            raise ValueError("no light is on")
        points = [i + 1 for i, light in lit if light.kind == "point"]
        if points:
            which = ", ".join(str(i) for i in points)
            raise ValueError(f"light {which} is a point light; Auto quality predicts the error "
                             "for directional lights only")
        return [light for _, light in lit]

    def _start(self) -> None:
        if self._closed or not self.model.illumination.auto:
            return
        if self._running:
            self._pending = True
            return
        generation = self._generation
        try:
            lights = self._lights()
        except ValueError as exc:
            self._report_failure(f"Auto quality: {exc}; the method stays as it is.")
            return
        snapshot = self._opacity_source()
        if snapshot is None:
            return  # no data yet: the open that brings data requests again
        full, spacing, unit_distance = snapshot
        opacity, spacing = binned_for_prediction(full, spacing, MAX_PREDICTION_VOXELS)
        voxels = int(full.size)
        budget = float(self.model.illumination.auto_budget_ssim)
        timings = self._timings
        frames = copy.deepcopy(self.frames)  # the worker reads its own copy
        self._frames_in_use = frames
        self._running = True
        self.busy.emit()

        def job() -> None:
            try:
                choice = choose_measured(opacity, spacing, lights, budget_ssim=budget,
                                         timings=timings or default_timings(),
                                         unit_distance=unit_distance, voxels=voxels,
                                         frames=frames)
            except Exception as exc:  # reported on the GUI thread as a one-line message
                result: tuple[Choice | None, str | None] = (None, str(exc) or type(exc).__name__)
            else:
                result = (choice, None)
            # The window (and this object) may have gone while choosing: nothing to tell.
            with contextlib.suppress(RuntimeError):
                self._done.emit(generation, *result)

        threading.Thread(target=job, name="vtkvol-auto-quality", daemon=True).start()

    def _finished(self, generation: int, choice: Choice | None, error: str | None) -> None:
        self._running = False
        if self._closed:
            return
        if self._pending:
            self._pending = False
            self._timer.start(0)
        if generation != self._generation or not self.model.illumination.auto:
            return  # overtaken by an edit: the next choice is on its way
        if choice is None:
            self._report_failure(f"Auto quality could not choose: {error}; the method stays "
                                 "as it is.")
            return
        outcome = describe(choice, float(self.model.illumination.auto_budget_ssim),
                           self.method_labels.get(choice.method, choice.method))
        illumination = self.model.illumination
        parameters = {k: dict(v) for k, v in illumination.parameters.items()}
        parameters[choice.method] = dict(choice.parameters)
        with self.engine_edit(), self.model.batch():
            illumination.parameters = parameters
            illumination.method = choice.method
        self.last_outcome = outcome
        self.last_frames = self._frames_in_use
        self.chosen.emit(outcome)

    def _report_failure(self, message: str) -> None:
        self.last_outcome = None
        self.failed.emit(message)

    def close(self) -> None:
        """Stop choosing (the window closes); a running worker's result is dropped."""
        self._closed = True
        self._generation += 1
        self._timer.stop()
