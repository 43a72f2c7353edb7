"""Progressive refinement of the 3-D view: every frame fits a time budget, full quality comes
in tiles while the user is idle (issue 25 §1).

On a machine without a usable GPU (Mesa llvmpipe, remote desktops, virtual machines) one
full-quality frame of a 256×256×100 two-channel stack in a ~900×500 view takes seconds to tens
of seconds, and a VTK render cannot be interrupted: the window froze that long after every
gesture. :class:`Refiner` keeps every frame under :data:`FRAME_BUDGET_MS`:

* **Cost model.** A whole-view frame's duration divided by the number of rays it cast (view
  pixels over the squared image sample distance) gives the cost of one ray, kept separately
  for interactive and full sampling along the ray. A dearer frame replaces the estimate at
  once, a cheaper one only halves the difference: underestimating freezes the window,
  overestimating only coarsens one frame. Rays through the specimen cost many times those
  through empty background, so strips are planned from a **cost per row** of the view, learned
  from the strips of the previous refinement (uniform, from the whole-view estimate, at first).
  What changed since (another illumination method, a denser transfer function) scales it up:
  by the ratio of this refinement's coarse frame to the one before at first, then by how much
  a strip cost over its prediction. The correction never goes below 1 (an over-predicted
  strip costs one more strip, an under-predicted one freezes the window).
* **Fast path.** When a full-quality frame is predicted to fit the budget (a GPU desktop), it
  is rendered as before: one frame, nothing else.
* **Coarse first.** Otherwise the first frame after a change renders the whole view with the
  smallest image sample distance of :data:`FACTORS` whose frame fits the budget.
* **Tiles while idle.** Then the view is rendered again at full quality in horizontal strips,
  one strip per frame, through the camera's scissor rectangle (VTK clears and ray-casts only
  inside it; the rest of its framebuffer keeps the coarse image and the strips done before).
  Each strip is as many rows as the cost per row predicts to fit :data:`TILE_SHARE` of the
  budget (the prediction can be off by 2× where the specimen begins); the event loop
  runs between strips, so input is handled at most one strip late. Where even the thinnest
  strip is predicted over the budget, its band is drawn in pieces side by side.
* **Cancel.** Any new frame request (a model change, a camera or gizmo move, a resize)
  drops the strips still to come (:meth:`Refiner.cancel`); the next frame starts over with a
  coarse image.

The class holds no Qt or VTK objects: the viewport asks it what the next frame is
(:meth:`Refiner.plan_frame`, :meth:`Refiner.next_tile`) and reports every frame's duration
(:meth:`Refiner.frame_done`). Pixel coordinates are VTK's display pixels (origin bottom-left).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: A frame should take at most this long (ms): the event loop then runs at least twice a
#: second even on a slow machine (issue 25's 0.5 s, with room for the frame's overhead).
FRAME_BUDGET_MS = 250.0
#: A strip is planned to this share of the budget: its rows' cost is learned from strips of
#: other heights and states (spread evenly over each strip's rows), and strips came out up to
#: twice their prediction (a quiet 2-core llvmpipe machine: 620 ms for a 250 ms plan).
TILE_SHARE = 0.6
#: Progressive illumination work (a technique's iterations) a frame may add before it renders,
#: ms: the engine's ``work_budget_ms``; the rest of the frame keeps to :data:`FRAME_BUDGET_MS`.
WORK_BUDGET_MS = 0.5 * FRAME_BUDGET_MS
#: Image sample distances (view pixels per cast ray, along each side) a coarse frame may use.
FACTORS = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0)
#: The first coarse frame, before any frame was measured.
UNMEASURED_FACTOR = 4.0
#: The least image sample distance of a frame that carries one-off GL work (see
#: :meth:`Refiner.expect_one_off`).
ONE_OFF_FACTOR = 8.0
#: The thinnest strip (rows): below this, a frame's fixed cost dominates.
MIN_TILE_ROWS = 4
#: A band of :data:`MIN_TILE_ROWS` rows predicted over the budget (rays through a dense
#: specimen on a slow or loaded machine: up to 1.5 s measured for 4 rows of a 584 px view) is
#: drawn in at most this many pieces side by side.
MAX_BAND_PIECES = 16
#: Bounds of the correction applied to the learned cost per row. Never below 1: a strip
#: predicted too dear only makes the refinement take a few more strips, one predicted too
#: cheap freezes the window (the coarse frame and a cheap strip are both poor evidence that
#: the rows to come got cheaper: a one-off cost in the last refinement's coarse frame, or
#: background rows, mislead them).
MIN_SCALE, MAX_SCALE = 1.0, 8.0


@dataclass(frozen=True)
class Frame:
    """What one frame renders.

    ``kind`` is ``"full"`` (the whole view at full quality), ``"interactive"`` (the whole
    view at the interactive sampling, coarsened to fit the budget), ``"coarse"`` (the whole
    view at full sampling along the ray, coarsened) or ``"tile"`` (a strip at full quality).
    ``image_factor`` is the mapper's image sample distance; ``tile`` the strip as
    ``(x, y, width, height)`` display pixels, None for a whole-view frame.
    """

    kind: str
    image_factor: float
    tile: tuple[int, int, int, int] | None = None

    @property
    def interactive(self) -> bool:
        return self.kind == "interactive"


class Refiner:
    """Decides each frame's quality and the strips of the refinement (see the module
    docstring)."""

    def __init__(self, budget_ms: float = FRAME_BUDGET_MS, tile_share: float = TILE_SHARE) -> None:
        self.budget_ms = float(budget_ms)
        #: Strips are planned to this share of the budget (:data:`TILE_SHARE`).
        self.tile_share = float(tile_share)
        #: ms per cast ray, for full (False) and interactive (True) sampling along the ray.
        self._ms_per_ray: dict[bool, float | None] = {False: None, True: None}
        self._view: tuple[int, int] | None = None
        #: Predicted ms of a full-quality strip per display row, top row first (learned).
        self._row_ms: np.ndarray | None = None
        #: Correction of ``_row_ms`` for what changed since it was learned (see the docstring).
        self._scale = 1.0
        #: ms per ray of this refinement's coarse frame and of the previous refinement's.
        self._coarse_ray_ms: float | None = None
        self._last_coarse_ray_ms: float | None = None
        self._tiles: list[tuple[int, int, int, int]] = []
        self._next_row = 0  # display rows from the top already planned
        #: The band drawn in pieces side by side: its top row, rows, the pieces' x ranges
        #: (display pixels), the next piece and the ms its pieces took so far.
        self._band: tuple[int, int] | None = None
        self._band_pieces: list[tuple[int, int]] = []
        self._band_next = 0
        self._band_ms = 0.0
        self._rows_done = 0
        #: The refinement in progress: a coarse image was drawn and strips are due.
        self.active = False
        #: The image sample distance of the coarse frame under the strips.
        self.coarse_factor = 1.0
        #: Whether the last frame that finished showed the view at full quality throughout.
        self.complete = True
        #: The next frame carries one-off GL work (:meth:`expect_one_off`).
        self._one_off = False

    # -- cost model -------------------------------------------------------------------------
    def predict_ms(self, interactive: bool, rays: float) -> float | None:
        """Predicted duration (ms) of a frame casting ``rays`` rays; None before any frame."""
        cost = self._ms_per_ray[interactive]
        if cost is None and interactive:
            cost = self._ms_per_ray[False]  # interactive sampling is never slower
        return None if cost is None else cost * rays

    def fit_factor(self, interactive: bool, view: tuple[int, int],
                   minimum: float = 1.0) -> float:
        """The smallest image sample distance (≥ ``minimum``) whose whole-view frame is
        predicted to fit the budget (the largest of :data:`FACTORS` when none does)."""
        pixels = float(max(1, view[0]) * max(1, view[1]))
        if self.predict_ms(interactive, pixels) is None:
            return max(minimum, UNMEASURED_FACTOR)
        for factor in FACTORS:
            if factor < minimum:
                continue
            predicted = self.predict_ms(interactive, pixels / (factor * factor))
            if predicted is not None and predicted <= self.budget_ms:
                return factor
        return max(minimum, FACTORS[-1])

    def expect_one_off(self) -> None:
        """The next frame carries one-off GL work besides its rays: a new volume texture's
        upload (a file opened, a time step) or a program's first build (another method; on
        llvmpipe LLVM compiles it inside the draw: 0.3–0.5 s measured for VTK's ray caster,
        uninterruptible). That frame is planned at least :data:`ONE_OFF_FACTOR` coarse, so
        it casts few rays besides, and its time is not learned as the cost of its rays."""
        self._one_off = True

    def frame_done(self, frame: Frame, frame_ms: float, view: tuple[int, int]) -> None:
        """Learn from a finished frame: ``frame_ms`` for the rays ``frame`` cast in a view of
        ``view`` (width, height) display pixels."""
        if frame.kind == "coarse" and self._one_off:  # its time is not the rays' cost
            self._one_off = False
            self.complete = False
            return
        if frame.tile is not None:
            rows = self._rows(view)
            _x, y, w, h = frame.tile
            top = max(0, view[1] - y - h)
            predicted = float(rows[top:top + h].sum()) * w / max(1, view[0])
            if predicted > 0 and frame_ms > 0:
                self._correct_scale(frame_ms / predicted)
            if w < view[0]:  # a piece of a band: its rows are learned when the band is done
                self._band_ms += max(frame_ms, 0.0)
                if self._band_next < len(self._band_pieces):
                    return
                frame_ms, self._band = self._band_ms, None
            self._rows_done += h
            rows[top:top + h] = max(frame_ms, 0.0) / max(1, h)
            self.complete = self._rows_done >= view[1]
            if self.complete:  # the whole view at full quality: its true cost per ray
                self._learn(False, float(rows.sum()) / (view[0] * view[1]))
            return
        rays = view[0] * view[1] / (frame.image_factor * frame.image_factor)
        if rays >= 1 and frame_ms > 0:
            self._learn(frame.interactive, frame_ms / rays)
            if frame.kind == "coarse" and self.active:
                self._coarse_ray_ms = frame_ms / rays
                before = self._last_coarse_ray_ms
                self._scale = 1.0 if before is None else min(
                    MAX_SCALE, max(MIN_SCALE, self._coarse_ray_ms / before))
        self.complete = frame.kind == "full"
        if frame.kind == "full" and self._row_ms is not None and len(self._row_ms) == view[1]:
            # The specimen's rows are unknown from one frame: spread it evenly.
            self._row_ms[:] = frame_ms / view[1]

    def _correct_scale(self, observed: float) -> None:
        """Fold one strip's measured ÷ predicted cost (``observed``, against the learned rows)
        into the correction of the rows still to come. A dearer strip raises it at once; a
        cheaper one only halves the distance and never takes it below 1: a strip comes out
        cheaper when its own rows emptied (a transfer function or crop edit), which says
        nothing of the rows below it, and shrinking the next strip's prediction for that
        made it take 2–4 budgets (measured on llvmpipe: a 22 ms background strip, then 746 ms)."""
        if observed >= self._scale:
            self._scale = min(MAX_SCALE, observed)
        else:
            self._scale = max(MIN_SCALE, 0.5 * (self._scale + observed))

    def _learn(self, interactive: bool, ms_per_ray: float) -> None:
        old = self._ms_per_ray[interactive]
        self._ms_per_ray[interactive] = (
            ms_per_ray if old is None or ms_per_ray >= old else 0.5 * (old + ms_per_ray))

    def _rows(self, view: tuple[int, int]) -> np.ndarray:
        """The cost per row for ``view``, uniform from the whole-view estimate when the view's
        height changed or nothing was learned yet."""
        if self._row_ms is None or len(self._row_ms) != view[1]:
            per_row = self.predict_ms(False, float(view[0]))
            self._row_ms = np.full(view[1], self.budget_ms / MIN_TILE_ROWS
                                   if per_row is None else per_row, dtype=np.float64)
        return self._row_ms

    # -- planning ---------------------------------------------------------------------------
    def plan_frame(self, interactive: bool, view: tuple[int, int],
                   interactive_factor: float) -> Frame:
        """The frame to render for a new request (any refinement in progress is cancelled):
        while the user moves something, the interactive sampling with an image factor of at
        least ``interactive_factor``; otherwise full quality when it fits the budget, else a
        coarse frame that starts a refinement."""
        self.cancel()
        if interactive:
            return Frame("interactive", self.fit_factor(True, view, interactive_factor))
        predicted = self.predict_ms(False, float(view[0] * view[1]))
        if predicted is not None and predicted <= self.budget_ms:
            self._one_off = False  # a machine this fast builds and uploads fast too
            return Frame("full", 1.0)
        least = ONE_OFF_FACTOR if self._one_off else 1.0
        self.coarse_factor = self.fit_factor(False, view, least)
        if self.coarse_factor <= 1.0:
            return Frame("full", 1.0)
        if self._coarse_ray_ms is not None:  # the rows were learned with that coarse frame
            self._last_coarse_ray_ms = self._coarse_ray_ms
        self._scale = 1.0
        self.active = True
        self._view = view
        self._next_row = 0
        self._rows_done = 0
        return Frame("coarse", self.coarse_factor)

    def next_tile(self, view: tuple[int, int]) -> Frame | None:
        """The next strip of the refinement (top to bottom), sized to fit the budget; None
        when the refinement is over or the view's size changed (then it is cancelled)."""
        if not self.active:
            return None
        if view != self._view:
            self.cancel()
            return None
        width, height = view
        if self._band is not None and self._band_next < len(self._band_pieces):
            top, rows = self._band
            x0, x1 = self._band_pieces[self._band_next]
            self._band_next += 1
            return Frame("tile", 1.0, (x0, height - top - rows, x1 - x0, rows))
        if self._next_row >= height:
            self.active = False
            return None
        top = self._next_row
        cost = np.cumsum(self._rows(view)[top:]) * self._scale
        target = self.tile_share * self.budget_ms
        rows = int(np.searchsorted(cost, target * (1 + 1e-9), side="right"))
        rows = min(height - top, max(MIN_TILE_ROWS, rows))
        self._next_row += rows
        pieces = min(MAX_BAND_PIECES, width, math.ceil(cost[rows - 1] / target - 1e-9))
        if pieces > 1:  # even the thinnest strip is over the budget: side by side pieces
            edges = np.linspace(0, width, pieces + 1).round().astype(int)
            self._band = (top, rows)
            self._band_pieces = list(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True))
            self._band_next, self._band_ms = 0, 0.0
            return self.next_tile(view)
        # Display pixels count rows from the bottom; the strips go down from the top.
        return Frame("tile", 1.0, (0, height - top - rows, width, rows))

    def cancel(self) -> None:
        """Forget the strips still to come."""
        self.active = False
        self._view = None
        self._band = None

    def progress(self, view: tuple[int, int]) -> float:
        """Fraction of the view refined to full quality (0…1) in the refinement in progress."""
        if not self.active or view[1] <= 0:
            return 1.0 if self.complete else 0.0
        return min(1.0, self._rows_done / view[1])

    def status_text(self, view: tuple[int, int]) -> str:
        """The "refining…" indicator: empty when the view shows full quality."""
        if not self.active:
            return ""
        done = round(100 * self.progress(view))
        return (f"Refining… {done} % at full quality "
                f"(rest at 1/{_factor_text(self.coarse_factor)} resolution)")


def _factor_text(factor: float) -> str:
    """1/2, 1/1.5, 1/16: the coarse frame's linear resolution."""
    return str(int(factor)) if math.isclose(factor, round(factor)) else f"{factor:g}"
