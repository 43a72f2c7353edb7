"""Auto quality in the app: the illumination method picked by :func:`vtkvol.bench.choose`.

With ``model.illumination.auto`` on, :class:`AutoQuality` runs
:func:`vtkvol.bench.auto_quality.choose_measured` for the current opacity (data, TFs, crop,
slice weights), voxel size and lights, and writes the pick into ``illumination.method`` and
its parameters. The choice is CPU work of about a second to a few seconds (one reference
transmittance plus one CPU light volume per candidate tried), so it runs in a worker thread,
once the edits have settled (:data:`SETTLE_MS` after the last TF, light, crop or data
change, never during a drag), and a result that an edit has overtaken is dropped.

Costs come from :func:`~vtkvol.bench.auto_quality.default_timings`: the ``benchmarks.json``
named by ``$VTKVOL_BENCHMARKS``, else the measurements shipped with vtkvol.

Signals carry the outcome for the view (the Lights dock and the status bar show it):
``busy()`` when a choice starts, ``chosen(AutoOutcome)`` when one is applied, ``failed(str)``
when none can be made (a point light, no light on, no measured method).
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal

from vtkvol.bench.auto_quality import (
    Choice,
    Timings,
    binned_for_prediction,
    choose_measured,
    default_timings,
)
from vtkvol.model.evented import touches
from vtkvol.model.scene import SceneModel

#: Quiet time (ms) after the last edit before choosing again: a drag sends edits every
#: ~60 ms, so the choice runs once the user lets go.
SETTLE_MS = 500

#: Largest volume the prediction runs on (voxels); larger data is averaged in blocks first
#: (:func:`~vtkvol.bench.auto_quality.binned_for_prediction`), which keeps a choice to a few
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


def describe(choice: Choice, budget_ssim: float, method_label: str) -> AutoOutcome:
    """The words for ``choice`` (``method_label``: the technique's display name)."""
    label = choice.label or choice.method
    overrides = label[len(choice.method) + 2:-1] if label.startswith(f"{choice.method} (") \
        else ""
    setting = f"{method_label} ({overrides})" if overrides else method_label
    met = choice.predicted_ssim >= budget_ssim
    if met:
        summary = (f"Auto picked {setting}: predicted SSIM {choice.predicted_ssim:.3f} "
                   f"≥ {budget_ssim:g}")
    else:
        summary = (f"Budget not reachable: no method is predicted to reach SSIM "
                   f"≥ {budget_ssim:g}; using the most accurate, {setting} (predicted SSIM "
                   f"{choice.predicted_ssim:.3f})")
    cost = f", {choice.cost_ms:.0f} ms a frame there" if math.isfinite(choice.cost_ms) else ""
    summary += f"; cost from {choice.cost_source or 'the given timings'}{cost}."
    tried = "\n".join(
        f"  {c['label']}: predicted SSIM {c['predicted_ssim']:.3f}"
        + (f", cost {c['cost_ms']:.0f} ms" if math.isfinite(c["cost_ms"]) else "")
        for c in choice.considered)
    details = f"{choice.reason}\n\nTried, cheapest first:\n{tried}"
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
        self._running = True
        self.busy.emit()

        def job() -> None:
            try:
                choice = choose_measured(opacity, spacing, lights, budget_ssim=budget,
                                         timings=timings or default_timings(),
                                         unit_distance=unit_distance, voxels=voxels)
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
        self.chosen.emit(outcome)

    def _report_failure(self, message: str) -> None:
        self.last_outcome = None
        self.failed.emit(message)

    def close(self) -> None:
        """Stop choosing (the window closes); a running worker's result is dropped."""
        self._closed = True
        self._generation += 1
        self._timer.stop()
