"""The 3-D view: a widget that *contains* a pyvistaqt ``QtInteractor`` and owns the
:class:`~vtkvol.engine.scene.VolumeScene`.

This is the only module of the app that talks to VTK (style-anchors §4 items 11 and 12):

* **Render on request, coalesced.** The scene calls :meth:`Viewport.request_render`; a
  single-shot zero-interval ``QTimer`` turns any number of requests in one event-loop pass
  into one repaint. pyvistaqt's widget renders inside every ``paintGL``, so renders asked for
  by VTK itself (the camera style, the light gizmo) are redirected into a repaint too:
  one frame per request instead of two (see :meth:`Viewport._install_render_redirect`).
* **Only what changed renders.** The widget renders in its paint only when a frame was
  asked for (a render request, VTK's own render call, a resize); any other repaint (a menu
  or dialog closing over the view, the window re-exposed) shows the last frame again
  (:class:`ViewWidget`).
* **Reduced quality while moving.** Camera and gizmo interaction, and every drag in a dock
  (:meth:`Viewport.begin_edit` / :meth:`Viewport.end_edit`), switch the scene to its
  interactive sampling (seed 002's "Reduce") and defer the illumination's precomputation
  (the previous light volume stays); a short settle timer after the last interaction syncs
  the camera into the model and renders one full-quality frame with the light brought up
  to date.
* **Every frame within a time budget.** Each frame's image sample distance comes from
  :class:`~vtkvol.ui.refine.Refiner`: full quality at once when this machine renders it
  within :data:`~vtkvol.ui.refine.FRAME_BUDGET_MS` (a GPU desktop), otherwise a coarse frame
  that fits, then full quality in strips (the camera's scissor rectangle), one per
  event-loop pass, while the user is idle; any new frame request cancels the strips.
  :attr:`Viewport.refinementChanged` carries the "refining…" text for the status bar.
* **Long precomputation keeps the window alive.** Before a frame, the illumination's
  precomputation runs outside the render, in the technique's chunks, with the event loop
  running between them and a progress dialog with Cancel once it takes longer than half a
  second (:meth:`Viewport._precompute`). Cancel shows local shading (the model says so) and
  a status message. Tiled screenshots show the same dialog; Cancel writes nothing.
* **Nothing renders after close.** :meth:`Viewport.close` stops the timers, removes the
  gizmo and releases the scene's GL resources while the context is current, then closes
  the interactor.
* **Light gizmo.** A draggable handle for the light selected in the lights dock; dragging it
  writes ``model.lights[i].direction`` (or ``.position`` for a point light), and the engine
  recomputes shadows from the model change.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from typing import TYPE_CHECKING, Any

os.environ.setdefault("QT_API", "pyside6")  # pyvistaqt (through qtpy) must pick PySide6

import numpy as np
import vtk
from PySide6.QtCore import QEvent, QObject, QRect, Qt, QTimer, Signal
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor

from vtkvol.engine.probe import ProbeResult, probe
from vtkvol.engine.scene import VolumeScene
from vtkvol.model.evented import touches
from vtkvol.model.scene import ClipPlane, SceneModel
from vtkvol.model.techniques import get_spec
from vtkvol.ui.light_handle import handle_sphere
from vtkvol.ui.progress import ChunkProgress
from vtkvol.ui.refine import WORK_BUDGET_MS, Frame, Refiner

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: After the last camera/gizmo interaction, wait this long before the full-quality frame, so
#: a series of wheel steps does not pay for a full frame each (ms).
SETTLE_MS = 180
#: The intensity probe reads the voxel under the pointer once it rests this long (ms).
PROBE_DELAY_MS = 80
#: Work before a frame (the automatic exposure's measuring frames) longer than this (ms)
#: leaves the frame to the next event-loop pass.
SPLIT_WORK_MS = 50.0


class ScreenshotCancelled(Exception):
    """The user cancelled a tiled screenshot (nothing was written)."""


class ViewWidget(QtInteractor):
    """pyvistaqt's widget, rendering in its paint only when a frame is due.

    pyvistaqt renders in every ``paintGL``, and Qt repaints the widget for reasons that change
    nothing in the scene: a menu or dialog closing over it, the window re-exposed. Then the
    last frame, still in VTK's display framebuffer, is shown again (a blit) instead of
    rendering anew; :attr:`needs_render` (set by the viewport for every render request and
    VTK render call, and by a resize) makes the next paint render. While :attr:`hold` is set
    (precomputation or a tiled screenshot in progress) paints only show the last frame. Relies
    on pyvistaqt's ``_blit`` and ``_RenderWindow``; without them every paint renders, which is
    correct, only slower.
    """

    def __init__(self, parent: QWidget | None = None, **kwargs: Any) -> None:
        super().__init__(parent, **kwargs)
        self.needs_render = True
        self.hold = False
        #: Set while a tiled screenshot is rendered: VTK's buffers hold a tile, so a paint
        #: then draws nothing (the view is rendered again afterwards).
        self.hold_blank = False
        self.can_reuse_frame = all(hasattr(self, name)
                                   for name in ("_blit", "_RenderWindow", "_in_paint"))
        #: Called in a paint that renders, just before the frame, with the context current
        #: (the viewport measures the automatic exposure there); when it returns True the
        #: frame is left to the next paint, so the event loop runs in between.
        self.before_frame: Callable[[], bool] | None = None
        #: Set while a caller needs the frame drawn in this paint (``Viewport.render_now``).
        self.synchronous = False

    def initializeGL(self) -> None:
        super().initializeGL()
        self.needs_render = True

    def resizeGL(self, w: int, h: int) -> None:
        super().resizeGL(w, h)
        self.needs_render = True

    def paintGL(self) -> None:
        rw = getattr(self, "_RenderWindow", None)
        reusable = (self.can_reuse_frame and rw is not None and rw.GetReadyForRendering()
                    and not self._in_paint)
        if reusable and self.hold_blank:
            self.needs_render = True
            return
        if reusable and (self.hold or not self.needs_render):
            self._show_last_frame(rw)
            return
        self.needs_render = False
        ready = rw is not None and rw.GetReadyForRendering()
        if (self.before_frame is not None and ready and self.before_frame() and reusable
                and not self.synchronous):
            # The work before the frame took a while: the frame in a pass of its own.
            self.needs_render = True
            self._show_last_frame(rw)
            # Through a zero timer, not update(): Qt sends posted events before timers that
            # are overdue, so the repaint would follow at once and the loop still not run.
            QTimer.singleShot(0, self.update)
            return
        super().paintGL()

    def _show_last_frame(self, rw: vtk.vtkRenderWindow) -> None:
        state = rw.GetState()
        state.Reset()  # Qt touched GL since VTK's last call: resync VTK's cache
        state.Push()
        try:
            self.makeCurrent()
            ratio = self.devicePixelRatioF()
            rect = QRect(0, 0, max(1, round(self.width() * ratio)),
                         max(1, round(self.height() * ratio)))
            self._blit(self.defaultFramebufferObject(), rect)
        finally:
            state.Pop()


class LightGizmo:
    """A draggable handle showing one light: at ``centre + R·direction`` for a directional
    light, at ``position`` for a point light, with a line from the volume's centre.

    The gizmo only reports where the user dragged the handle (``on_moved(world_xyz)``); the
    viewport turns that into a model change.
    """

    def __init__(self, interactor: vtk.vtkRenderWindowInteractor, renderer: vtk.vtkRenderer,
                 viewport: Viewport) -> None:
        self._renderer = renderer
        self._viewport = viewport
        self.rep = vtk.vtkSphereHandleRepresentation()
        self.rep.SetHandleSize(14.0)
        self.rep.GetSelectedProperty().SetColor(1.0, 1.0, 1.0)
        self.widget = vtk.vtkHandleWidget()
        self.widget.SetInteractor(interactor)
        self.widget.SetRepresentation(self.rep)
        self.widget.SetDefaultRenderer(renderer)
        self.widget.SetPriority(1.0)  # above the camera style: a press on the handle is ours
        self._tags = [
            self.widget.AddObserver(vtk.vtkCommand.StartInteractionEvent, self._on_start),
            self.widget.AddObserver(vtk.vtkCommand.InteractionEvent, self._on_move),
            self.widget.AddObserver(vtk.vtkCommand.EndInteractionEvent, self._on_end),
        ]
        self._line = vtk.vtkLineSource()
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputConnection(self._line.GetOutputPort())
        self.line_actor = vtk.vtkActor()
        self.line_actor.SetMapper(mapper)
        self.line_actor.GetProperty().SetLineWidth(1.5)
        self.line_actor.GetProperty().SetOpacity(0.7)
        self.line_actor.PickableOff()
        self.line_actor.VisibilityOff()
        renderer.AddActor(self.line_actor)
        self.dragging = False
        self._enabled = False

    def place(self, centre: np.ndarray, handle: np.ndarray, color: tuple[float, float, float],
              *, enabled: bool) -> None:
        """Put the handle at ``handle`` (µm) with a line from ``centre``."""
        self.rep.SetWorldPosition(tuple(float(v) for v in handle))
        dim = tuple(0.35 + 0.65 * c for c in color) if enabled else (0.45, 0.45, 0.45)
        self.rep.GetProperty().SetColor(*dim)
        self._line.SetPoint1(*(float(v) for v in centre))
        self._line.SetPoint2(*(float(v) for v in handle))
        self.line_actor.GetProperty().SetColor(*dim)

    def set_visible(self, visible: bool) -> None:
        if visible == self._enabled:
            return
        self._enabled = visible
        self.widget.SetEnabled(int(visible))
        self.line_actor.SetVisibility(int(visible))

    @property
    def visible(self) -> bool:
        return self._enabled

    def handle_position(self) -> np.ndarray:
        return np.array(self.rep.GetWorldPosition(), dtype=np.float64)

    def _on_start(self, *_: Any) -> None:
        self.dragging = True
        self._viewport._interaction_started()

    def _on_move(self, *_: Any) -> None:
        self._viewport._gizmo_moved(self.handle_position())

    def _on_end(self, *_: Any) -> None:
        self.dragging = False
        self._viewport._interaction_ended()

    def close(self) -> None:
        for tag in self._tags:
            self.widget.RemoveObserver(tag)
        self.widget.SetEnabled(0)
        self.widget.SetInteractor(None)
        self._renderer.RemoveActor(self.line_actor)


class ClipPlaneWidget:
    """VTK's implicit-plane widget showing ``model.clip_plane`` in the view: drag the plane to
    move it along its normal, the arrow to turn it. ``on_moved(origin, normal)`` (world µm)
    is called when a drag ends (the model is written then, not on every mouse move: each
    change recomputes the illumination)."""

    def __init__(self, interactor: vtk.vtkRenderWindowInteractor, renderer: vtk.vtkRenderer,
                 on_moved: Callable[[tuple[float, float, float], tuple[float, float, float]],
                                    None]) -> None:
        rep = vtk.vtkImplicitPlaneRepresentation()
        rep.SetPlaceFactor(1.0)
        rep.OutlineTranslationOff()  # the data's box stays where it is
        rep.ScaleEnabledOff()
        rep.SetDrawOutline(False)
        rep.GetPlaneProperty().SetOpacity(0.12)
        rep.GetSelectedPlaneProperty().SetOpacity(0.25)
        self.representation = rep
        self.widget = vtk.vtkImplicitPlaneWidget2()
        self.widget.SetInteractor(interactor)
        self.widget.SetRepresentation(rep)
        self.widget.SetCurrentRenderer(renderer)
        self._on_moved = on_moved
        self._tag = self.widget.AddObserver(vtk.vtkCommand.EndInteractionEvent, self._on_end)

    def place(self, bounds: Sequence[float], origin: Sequence[float],
              normal: Sequence[float]) -> None:
        self.representation.PlaceWidget(list(bounds))
        self.representation.SetOrigin(*origin)
        self.representation.SetNormal(*normal)

    def set_visible(self, visible: bool) -> None:
        self.widget.SetEnabled(int(visible))

    @property
    def visible(self) -> bool:
        return bool(self.widget.GetEnabled())

    def _on_end(self, *_: Any) -> None:
        rep = self.representation
        self._on_moved(tuple(rep.GetOrigin()), tuple(rep.GetNormal()))  # type: ignore[arg-type]

    def close(self) -> None:
        self.widget.RemoveObserver(self._tag)
        self.widget.SetEnabled(0)
        self.widget.SetInteractor(None)


class Viewport(QWidget):
    """The 3-D view of one :class:`SceneModel` (see the module docstring).

    Signals
    -------
    frameRendered(frame_ms, illumination_ms)
        After every frame: its duration and the illumination technique's last
        precomputation time (``scene.illuminator.last_prepare_ms``).
    illuminationFailed(message)
        The illumination technique failed and local shading is shown (the model says so).
        Emitted from inside a frame: connect with a queued connection to show dialogs.
    illuminationProgress(iteration, converged)
        A progressive technique refined (its next frame is already requested).
    probed(text)
        The intensity probe: the position, voxel and channel values of the first visible
        material under the resting mouse pointer ("" when there is none).
    illuminationCancelled(message)
        The user cancelled a precomputation: local shading is shown (the model says so).
    refinementChanged(text)
        The "refining…" indicator: how much of the view has reached full quality, "" once
        all of it has (or the frame was full quality at once).
    """

    frameRendered = Signal(float, float)
    illuminationFailed = Signal(str)
    illuminationProgress = Signal(int, bool)
    probed = Signal(str)
    illuminationCancelled = Signal(str)
    refinementChanged = Signal(str)

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.scene: VolumeScene | None = None
        #: Handed to the scene as its ``engine_edit`` (set before data is shown).
        self.engine_edit: Callable[[], AbstractContextManager[None]] = nullcontext
        self.reduce_while_moving = True
        self._closed = False
        self._frame_start = 0.0
        self.last_frame_ms = 0.0
        #: Frames rendered so far (tests and the responsiveness benchmark count them).
        self.frame_count = 0
        #: Nesting of precomputation / tiled screenshot in progress (no frame starts then).
        self._busy = 0
        self._render_after_busy = False
        self._precompute_cancelled = False
        #: Whether a reduced-quality frame was drawn since the last full-quality one.
        self._reduced_shown = False
        self._edits = 0  # drags in progress in the docks (begin_edit/end_edit)
        self._camera_moved = False  # the camera style moved the camera since the last settle
        #: Each frame's quality (see the module docstring); False renders every frame at
        #: the model's quality, as before issue 25.
        self.progressive_refinement = True
        self.refiner = Refiner()
        #: The (method, renderer) the last planned frame drew with.
        self._planned_look: tuple[str, str] | None = None
        #: What the next frame renders (set before each paint that renders).
        self._frame = Frame("full", 1.0)
        self._frame_fresh = False  # _frame was planned for the next frame, not rendered yet
        self._frame_sticky = False  # a screenshot: every frame whole, at full quality
        self._refine_text = ""
        #: Makes the progress callback of precomputation (tests replace it).
        self.progress_factory: Callable[[str], ChunkProgress] = (
            lambda label: ChunkProgress(self.window(), label))

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        # auto_update=False: no 5 Hz timer; this widget renders only when asked (§4 item 12).
        self.plotter = ViewWidget(self, auto_update=False)
        self.plotter.before_frame = self._before_frame
        self._measuring = False  # the automatic exposure's frames are rendering
        self.plotter.setAcceptDrops(False)  # dropped files go to the main window, not pyvista
        layout.addWidget(self.plotter)
        self.setMinimumSize(160, 120)

        self.render_window: vtk.vtkRenderWindow = self.plotter.render_window
        self.renderer: vtk.vtkRenderer = self.plotter.renderer
        self.interactor: vtk.vtkRenderWindowInteractor = self.plotter.iren.interactor
        self._vtk_tags: list[tuple[vtk.vtkObject, int]] = []
        self._setup_interaction()
        self._install_render_redirect()
        self._observe(self.render_window, vtk.vtkCommand.StartEvent, self._on_frame_start)
        self._observe(self.render_window, vtk.vtkCommand.EndEvent, self._on_frame_end)

        self._render_timer = QTimer(self)
        self._render_timer.setSingleShot(True)
        self._render_timer.setInterval(0)
        self._render_timer.timeout.connect(self._render_now)
        self._settle_timer = QTimer(self)
        self._settle_timer.setSingleShot(True)
        self._settle_timer.setInterval(SETTLE_MS)
        self._settle_timer.timeout.connect(self._settle)
        # The next strip of a refinement, after the events that came during the last one.
        self._refine_timer = QTimer(self)
        self._refine_timer.setSingleShot(True)
        self._refine_timer.setInterval(0)
        self._refine_timer.timeout.connect(self._render_tile)

        # The intensity probe runs once the pointer rests (picking casts a CPU ray).
        self._probe_timer = QTimer(self)
        self._probe_timer.setSingleShot(True)
        self._probe_timer.setInterval(PROBE_DELAY_MS)
        self._probe_timer.timeout.connect(self._probe)
        self._probe_at: tuple[float, float] | None = None

        self.clip_widget = ClipPlaneWidget(self.interactor, self.renderer, self._clip_moved)

        self._gizmo = LightGizmo(self.interactor, self.renderer, self)
        # Sees the view's mouse events first: a handle drag whose release was lost ends here.
        self.plotter.installEventFilter(self)
        self._gizmo_light: int | None = 0
        self._gizmo_wanted = True
        self._gizmo_radius = 1.0
        self._gizmo_centre = np.zeros(3)  # of the handle's sphere, world µm (_update_gizmo)
        model.changed.connect(self._on_model_changed)

    # -- setup ----------------------------------------------------------------------------------
    def _observe(self, obj: vtk.vtkObject, event: Any, callback: Any,
                 priority: float = 0.0) -> None:
        self._vtk_tags.append((obj, obj.AddObserver(event, callback, priority)))

    def _setup_interaction(self) -> None:
        """Trackball camera; no VTK or pyvista keyboard shortcuts (their 'q' quits, 'w'
        switches to wireframe, 'f' flies the camera outside the model; the app's own
        actions replace the useful ones)."""
        style = vtk.vtkInteractorStyleTrackballCamera()
        self.interactor.SetInteractorStyle(style)
        self.interactor.RemoveObservers(vtk.vtkCommand.CharEvent)
        self.interactor.RemoveObservers(vtk.vtkCommand.KeyPressEvent)
        self._style = style
        self._observe(style, vtk.vtkCommand.StartInteractionEvent, self._on_style_start)
        self._observe(style, vtk.vtkCommand.EndInteractionEvent, self._on_style_end)

    def _install_render_redirect(self) -> None:
        """Make every VTK-initiated render a widget repaint.

        pyvistaqt's ``paintGL`` always renders, and a direct ``Render()`` schedules a
        repaint that renders again: two frames per request. With the interactor's own
        rendering disabled, VTK still announces ``RenderEvent``; outside a paint it becomes
        ``update()`` (coalesced by Qt), inside the paint it is the one real render. Relies on
        pyvistaqt's ``_in_paint`` flag; without it (another pyvistaqt) the default
        behaviour is kept, which is correct, only slower.
        """
        if not hasattr(self.plotter, "_in_paint"):
            return
        self.interactor.EnableRenderOff()
        self._observe(self.interactor, vtk.vtkCommand.RenderEvent, self._on_render_event)

    def _on_render_event(self, *_: Any) -> None:
        if self._closed:
            return
        if self.plotter._in_paint:
            self.render_window.Render()
        else:
            self._plan_frame()  # VTK's own request (camera, gizmo): new input, replan
            self.plotter.needs_render = True
            self.plotter.update()

    # -- data -----------------------------------------------------------------------------------
    def show_data(self, data: VolumeData, *, reset_channels: bool | None = None) -> None:
        """Show ``data`` with the current model (the scene is created on first use)."""
        if self._closed:
            return
        if self.scene is None:
            # The first view and "reset view" frame what is visible, not the empty box.
            self.scene = VolumeScene(self.renderer, self.model, data,
                                     request_render=self.request_render, framing="visible")
            self.scene.engine_edit = self.engine_edit
            self.scene.error.connect(self.illuminationFailed.emit)
            self.scene.progress.connect(self.illuminationProgress.emit)
        else:
            self.scene.set_data(data, reset_channels=reset_channels)
        self.refiner.expect_one_off()  # the new texture's upload (and the first shader build)
        self._update_gizmo()
        self._update_clip_widget()
        self.request_render()

    def show_voxels(self, data: VolumeData) -> None:
        """Show another time point of the shown data (same shape, channels and voxel size):
        only the voxels change (:meth:`VolumeScene.set_voxels`)."""
        if self._closed or self.scene is None:
            return
        self.scene.set_voxels(data)
        self.refiner.expect_one_off()  # the new voxels' texture upload
        self.request_render()

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """World bounds (µm) of the data, voxel centres."""
        return self.scene.bounds if self.scene is not None else (0.0, 1.0, 0.0, 1.0, 0.0, 1.0)

    def opacity_snapshot(self) -> tuple[np.ndarray, tuple[float, float, float], float] | None:
        """What the illumination sees, for CPU work off the GUI thread (Auto quality): a copy
        of the per-voxel opacity ``[z, y, x]`` (TFs, crop and slice weights applied), the voxel
        size (x, y, z) in µm and the opacity unit distance in µm; None without data."""
        illum = self.scene.illuminator if self.scene is not None else None
        if self._closed or illum is None:
            return None
        return (illum.opacity_volume().copy(), tuple(float(s) for s in illum.spacing),
                float(illum.unit_distance))

    # -- rendering ------------------------------------------------------------------------------
    def request_render(self) -> None:
        """Ask for a frame; many requests in one event-loop pass give one frame. A
        refinement in progress stops (the frame starts a new one)."""
        if not self._closed:
            self._refine_timer.stop()
            self.refiner.cancel()
            self._render_timer.start()

    def _render_now(self) -> None:
        if self._closed or self.scene is None:
            return
        if self._busy:
            self._render_after_busy = True  # asked again once the work is over
            return
        if not self._precompute():
            return
        self._plan_frame()
        self.plotter.needs_render = True
        self.plotter.update()  # the paint renders (see _install_render_redirect)

    def render_now(self) -> None:
        """Render synchronously (tests, screenshots); normal code calls request_render."""
        if self._closed or self.scene is None or self._busy:
            return
        self._render_timer.stop()
        if not self._precompute():
            return
        self._plan_full()
        self.plotter.needs_render = True
        self.plotter.synchronous = True
        try:
            self.plotter.repaint()
        finally:
            self.plotter.synchronous = False

    # -- progressive refinement (vtkvol.ui.refine) ---------------------------------------------
    def full_frame_ms(self) -> float | None:
        """What the last frame says a whole view at full quality costs on this machine (ms):
        its own duration when it was one, else the refiner's estimate from the strips and
        coarse frames measured (None before any, and for interactive frames, which sample
        more coarsely along the ray)."""
        if self._frame.interactive:
            return None
        if self._frame.kind == "full" and self._frame.image_factor == 1.0:
            return self.last_frame_ms
        width, height = self._view_px()
        return self.refiner.predict_ms(False, float(width * height))

    def _view_px(self) -> tuple[int, int]:
        width, height = self.render_window.GetSize()
        return (max(1, int(width)), max(1, int(height)))

    def _plan_frame(self) -> None:
        """Choose the next frame's quality for a new request (cancels any refinement)."""
        self._refine_timer.stop()
        # Another method or renderer: its programs are built in its first frame.
        look = (self.model.illumination.method, self.model.render.renderer)
        new_look, self._planned_look = look != self._planned_look, look
        if self.scene is None or not self.progressive_refinement:
            self._plan_full()
            return
        if new_look:
            self.refiner.expect_one_off()
        self._frame = self.refiner.plan_frame(
            self.scene.interactive, self._view_px(),
            float(self.model.render.interactive_image_factor))
        self._frame_fresh = True

    def _plan_full(self) -> None:
        """The next frames render at the scene's own quality, whole (screenshots, tests)."""
        self._refine_timer.stop()
        self.refiner.cancel()
        interactive = self.scene is not None and self.scene.interactive
        factor = float(self.model.render.interactive_image_factor) if interactive else 1.0
        self._frame = Frame("interactive" if interactive else "full", factor)
        self._frame_fresh = True

    def _render_tile(self) -> None:
        """Render the refinement's next strip (the timer runs it between event-loop passes)."""
        if self._closed or self.scene is None or self._busy:
            return
        frame = self.refiner.next_tile(self._view_px())
        if frame is None:
            self._set_refine_text("")
            if not self.refiner.complete:
                self.request_render()  # the view was resized meanwhile: start over
            return
        self._frame = frame
        self._frame_fresh = True
        self.plotter.needs_render = True
        self.plotter.update()

    def _apply_frame(self) -> None:
        """At the start of every frame: the image sample distance and scissor strip of the
        planned frame. A frame nobody planned (a resize, an exposure, the first frame) is
        planned now: a strip drawn twice, or a coarse frame over the strips, would leave the
        view coarse, and an unplanned full-quality frame could freeze the window."""
        if self.scene is None:
            return
        if not self._frame_fresh and not self._frame_sticky:
            self._plan_frame()
        self._frame_fresh = False
        self.scene.mapper.SetImageSampleDistance(self._frame.image_factor)
        if self._frame.tile is not None:
            camera = self.renderer.GetActiveCamera()
            camera.SetScissorRect(vtk.vtkRecti(*self._frame.tile))
            camera.SetUseScissor(True)  # VTK resets it after this frame

    def _set_refine_text(self, text: str) -> None:
        if text != self._refine_text:
            self._refine_text = text
            self.refinementChanged.emit(text)

    @property
    def frame_pending(self) -> bool:
        """A frame was asked for and not drawn yet (time-lapse playback waits for it)."""
        # A hidden view paints nothing: it would hold playback for ever.
        return self._render_timer.isActive() or self._busy > 0 or (
            self.plotter.needs_render and self.plotter.isVisible())

    @property
    def refining(self) -> bool:
        """True while full quality is still being rendered in strips."""
        return self.refiner.active

    @property
    def refinement_text(self) -> str:
        """The "refining…" indicator's text ("" at full quality)."""
        return self._refine_text

    @property
    def busy(self) -> bool:
        """True while a precomputation or a tiled screenshot runs (with the event loop
        running between its chunks)."""
        return self._busy > 0

    def _begin_busy(self) -> None:
        self._busy += 1
        self.plotter.hold = True

    def _end_busy(self) -> None:
        self._busy -= 1
        if self._busy == 0:
            self.plotter.hold = False
            if self._render_after_busy and not self._closed:
                self._render_after_busy = False
                self.request_render()

    def _precompute(self) -> bool:
        """Bring precomputed illumination up to date before a frame, in chunks, the event
        loop running between them; a progress dialog with Cancel appears after half a second
        (:class:`~vtkvol.ui.progress.ChunkProgress`). Returns False when the view closed
        meanwhile (nothing to render)."""
        self._precompute_cancelled = False
        scene = self.scene
        illuminator = scene.illuminator if scene is not None else None
        if scene is None or illuminator is None or illuminator.render_window is None:
            return not self._closed
        self._begin_busy()
        progress = self.progress_factory(f"Computing the lighting: {illuminator.spec.label}…")
        try:
            done = scene.precompute(progress)
        finally:
            progress.close()
            self._end_busy()
        self._precompute_cancelled = not done
        if self._closed:
            return False
        if not done:
            label = illuminator.cancelled_method or "The illumination"
            with contextlib.suppress(ValueError):
                label = get_spec(label).label
            self.illuminationCancelled.emit(
                f"{label} cancelled: showing local shading. Choose it again under "
                "Illumination to compute it.")
        return True

    def _before_frame(self) -> bool:
        """A full-quality frame is about to render: measure the automatic exposure first if
        the light changed (two coarse frames, not shown; not while the view moves). Returns
        True when the measurement took long enough that the frame should wait for the next
        event-loop pass (the two together held the loop 0.65 s with the shadow volume on a
        loaded llvmpipe machine)."""
        scene = self.scene
        if self._closed or scene is None or scene.interactive:
            return False
        # The measuring frames are not the view's: no planned strip or image factor applies
        # to them, and they count neither as frames nor in the refiner's cost per row.
        self._measuring = True
        t0 = time.perf_counter()
        try:
            scene.update_exposure()
        except Exception:  # a failed measurement keeps the last exposure; the view must draw
            logging.getLogger(__name__).exception("automatic exposure failed")
        finally:
            self._measuring = False
        return (time.perf_counter() - t0) * 1e3 > SPLIT_WORK_MS

    def _on_frame_start(self, *_: Any) -> None:
        if self._measuring:
            return
        self._frame_start = time.perf_counter()
        if self.scene is not None and self.scene.illuminator is not None:
            # Progressive iterations in bounded chunks: a hybrid-diffusion sample of a large
            # stack is drawn over several frames instead of holding the event loop for it.
            self.scene.illuminator.work_budget_ms = WORK_BUDGET_MS
        self._apply_frame()

    def _on_frame_end(self, *_: Any) -> None:
        if self._measuring:
            return
        self.last_frame_ms = (time.perf_counter() - self._frame_start) * 1e3
        self.frame_count += 1
        if self.scene is not None:
            view = self._view_px()
            self.refiner.frame_done(self._frame, self.last_frame_ms, view)
            if self.refiner.active and not self._closed:
                self._refine_timer.start()
            self._set_refine_text(self.refiner.status_text(view))
        if self.scene is not None and self.scene.interactive:
            self._reduced_shown = True
        illum = self.scene.illuminator if self.scene is not None else None
        self.frameRendered.emit(self.last_frame_ms, illum.last_prepare_ms if illum else 0.0)

    def screenshot(self, scale: int = 1, *, progress: bool = False) -> np.ndarray:
        """The view at full quality as an ``(h, w, 3)`` uint8 array, ``scale`` times the
        widget's size (offscreen magnification: the image is rendered in tiles). The light
        gizmo is left out.

        With ``progress``, the illumination's precomputation and the tiles (scale > 1) run
        with the event loop going between them and a progress dialog with Cancel after half
        a second; Cancel raises :class:`ScreenshotCancelled` (the view is left as it was;
        a cancelled precomputation shows local shading, as it does before a frame)."""
        if self._closed or self.scene is None:
            raise RuntimeError("the view is closed")
        if scale not in (1, 2, 3, 4):
            raise ValueError(f"screenshot scale must be 1, 2, 3 or 4, not {scale}")
        if self._busy:
            raise RuntimeError("the view is still computing; try again when it is done")
        gizmo = self._gizmo.visible
        self._gizmo.set_visible(False)
        self._settle_timer.stop()
        self.scene.set_interactive(False)
        self._plan_full()
        self._frame_sticky = True  # every render of the screenshot (tiles too) at full quality
        illuminator = self.scene.illuminator
        if illuminator is not None:
            illuminator.defer_precompute = False
        tiles = scale * scale
        rendered = 0
        cancelled = False
        chunks = self.progress_factory(f"Rendering the {scale}× screenshot…") if (
            progress and scale > 1) else None

        def tile_done(*_: Any) -> None:
            nonlocal rendered, cancelled
            rendered += 1
            if chunks is None or cancelled:
                return
            if not chunks(min(rendered / tiles, 1.0), f"tile {min(rendered, tiles)} of {tiles}"):
                cancelled = True
                self.scene.volume.VisibilityOff()  # the remaining tiles cost nothing

        tag = None
        volume_visible = self.scene.volume.GetVisibility()
        try:
            if progress:
                if not self._precompute():
                    raise RuntimeError("the view is closed")
                if self._precompute_cancelled:
                    # No picture with lighting other than the one asked for.
                    raise ScreenshotCancelled("the illumination was cancelled")
            # A fresh full-quality frame first, synchronously: at scale 1 the image is read
            # back from VTK's last frame, which may be a reduced one drawn while the camera
            # moved, or none yet if the widget was resized since (its buffers are new).
            self._render_timer.stop()
            self.plotter.render()
            # Tiles keep the overlays' layout of that frame (VTK scales it to the image).
            self.scene.overlays.magnify(scale)
            if chunks is not None:
                self._begin_busy()
                self.plotter.hold_blank = True  # tiles are in VTK's buffers meanwhile
                tag = self.render_window.AddObserver(vtk.vtkCommand.EndEvent, tile_done)
            try:
                image = self.plotter.screenshot(None, return_img=True, scale=scale)
            finally:
                if tag is not None:
                    self.render_window.RemoveObserver(tag)
                    self.plotter.hold_blank = False
                    self._end_busy()
            if cancelled:
                raise ScreenshotCancelled(f"the {scale}× screenshot was cancelled")
        finally:
            if chunks is not None:
                chunks.close()
            if self.scene is not None:
                self.scene.volume.SetVisibility(volume_visible)
                self.scene.overlays.magnify(1)
            self._frame_sticky = False
            self._gizmo.set_visible(gizmo)
            self.request_render()
        return np.ascontiguousarray(image[..., :3], dtype=np.uint8)

    # -- camera ---------------------------------------------------------------------------------
    def reset_camera(self) -> None:
        """Frame the visible content (voxels with non-zero opacity, inside the crop) from the
        default direction (the model's camera follows)."""
        if self.scene is not None:
            self.scene.reset_camera()
            self.request_render()

    def _on_style_start(self, *_: Any) -> None:
        self._camera_moved = True
        self._interaction_started()

    def _on_style_end(self, *_: Any) -> None:
        self._interaction_ended()

    def begin_interaction(self) -> None:
        """Another control moves what the view shows (a drag in the slice views while their
        planes are drawn): render coarser until :meth:`end_interaction`, as for a camera
        move."""
        self._interaction_started()

    def end_interaction(self) -> None:
        """The drag of :meth:`begin_interaction` ended: one full-quality frame once settled."""
        self._interaction_ended()

    def _interaction_started(self) -> None:
        self._settle_timer.stop()
        if self.scene is not None and self.reduce_while_moving:
            self.scene.set_interactive(True)
            if self.scene.illuminator is not None:
                # Keep the previous light volume while the user drags (see _settle).
                self.scene.illuminator.defer_precompute = True

    def _interaction_ended(self) -> None:
        self._settle_timer.start()

    def begin_edit(self) -> None:
        """A drag in a dock began (a curve, a range slider, a parameter slider): frames
        render at the interactive quality, precomputed illumination keeps its previous light,
        until :meth:`end_edit` and the settle time after it. Calls nest."""
        self._edits += 1
        self._interaction_started()

    def end_edit(self) -> None:
        """The drag :meth:`begin_edit` announced ended: full quality once it settles."""
        if self._edits == 0:
            return
        self._edits -= 1
        if self._edits == 0:
            self._interaction_ended()

    @property
    def editing(self) -> bool:
        """True between :meth:`begin_edit` and the matching :meth:`end_edit`."""
        return self._edits > 0

    def _settle(self) -> None:
        """The camera or the edit stopped: store the camera in the model, and render once at
        full quality with the illumination brought up to date, if a reduced frame was shown
        or the illumination waited. Nothing renders after a press that changed nothing."""
        if self._closed or self.scene is None:
            return
        if self._edits or self._gizmo.dragging:
            return  # still held (a press whose release has not come): settle after it
        if self._camera_moved:
            self._camera_moved = False
            self.scene.sync_camera_to_model()
        self.scene.set_interactive(False)
        illuminator = self.scene.illuminator
        waited = False
        if illuminator is not None and illuminator.defer_precompute:
            illuminator.defer_precompute = False
            waited = illuminator.has_pending_changes
        if self._reduced_shown or waited:
            self._reduced_shown = False
            self._update_gizmo()  # placed anew once its drag is over; requests the frame
            self.request_render()

    # -- light gizmo ----------------------------------------------------------------------------
    def set_gizmo_light(self, index: int | None) -> None:
        """Show the gizmo for ``model.lights[index]`` (None: for no light)."""
        self._gizmo_light = index
        self._update_gizmo()

    def set_gizmo_visible(self, visible: bool) -> None:
        self._gizmo_wanted = bool(visible)
        self._update_gizmo()

    @property
    def gizmo(self) -> LightGizmo:
        return self._gizmo

    def _update_gizmo(self) -> None:
        if self._closed or self._gizmo.dragging:
            return
        i = self._gizmo_light
        lights = self.model.lights
        show = self._gizmo_wanted and self.scene is not None and i is not None and i < len(lights)
        if show:
            light = lights[i]
            # Around the centre of the current framing, as far out as the view shows whole
            # (a time-lapse frames a small object in a large box: ui/light_handle.py).
            centre, self._gizmo_radius = handle_sphere(self.renderer, self.bounds)
            self._gizmo_centre = centre
            if light.kind == "point":
                handle = np.array(light.position, dtype=np.float64)
            else:
                d = np.array(light.direction, dtype=np.float64)
                handle = centre + self._gizmo_radius * d / max(np.linalg.norm(d), 1e-12)
            self._gizmo.place(centre, handle, light.color, enabled=light.enabled)
        self._gizmo.set_visible(bool(show))
        self.request_render()

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        """End a handle drag whose left-button release never reached VTK.

        VTK's handle widget keeps the mouse from its press until the left button's release;
        when that release is lost (a dialog took the mouse, the button came up outside the
        window), every later move dragged the light, with no button held, instead of
        turning the camera. A move without the left button, or a new left press, while a
        drag is on means the release was lost: send VTK the release first.
        """
        if (watched is self.plotter and event.type() == QEvent.Type.MouseMove
                and not event.buttons()):  # type: ignore[attr-defined]
            pos = event.position()  # type: ignore[attr-defined]
            self._probe_at = (float(pos.x()), float(pos.y()))
            self._probe_timer.start()
        elif watched is self.plotter and event.type() == QEvent.Type.Leave:
            self._probe_at = None
            self._probe_timer.start()
        if watched is self.plotter and self._gizmo.dragging:
            kind = event.type()
            moved = kind == QEvent.Type.MouseMove and not (
                event.buttons() & Qt.MouseButton.LeftButton)  # type: ignore[attr-defined]
            pressed = kind == QEvent.Type.MouseButtonPress and (
                event.button() == Qt.MouseButton.LeftButton)  # type: ignore[attr-defined]
            if moved or pressed:
                self._end_lost_drag()
        return super().eventFilter(watched, event)

    def probe_at(self, x: float, y: float) -> ProbeResult | None:
        """The first visible voxel under widget pixel (x, y) (Qt coordinates: logical pixels
        from the top-left), or None."""
        scene = self.scene
        if scene is None or scene.data is None or self._closed:
            return None
        ratio = self.plotter.devicePixelRatioF()
        height = self.render_window.GetSize()[1]
        labels = tuple(channel.labels is not None for channel in self.model.channels)
        return probe(self.renderer, scene.volume, scene.data, x * ratio,
                     height - 1 - y * ratio, labels)

    def _probe(self) -> None:
        result = self.probe_at(*self._probe_at) if self._probe_at is not None else None
        self.probed.emit(result.text() if result is not None else "")

    def _end_lost_drag(self) -> None:
        self.interactor.LeftButtonReleaseEvent()  # the widget ends its drag, lets the mouse go
        if self._gizmo.dragging:  # the widget was not in a drag after all: forget ours
            self._gizmo.dragging = False
            self._interaction_ended()

    def _gizmo_moved(self, handle: np.ndarray) -> None:
        """The user dragged the handle: write the light's direction or position."""
        i = self._gizmo_light
        if i is None or i >= len(self.model.lights):
            return
        light = self.model.lights[i]
        centre = self._gizmo_centre  # where _update_gizmo placed the handle's sphere
        if light.kind == "point":
            light.position = tuple(float(v) for v in handle)
        else:
            d = handle - centre
            norm = float(np.linalg.norm(d))
            if norm > 1e-9 * self._gizmo_radius:
                light.direction = tuple(float(v) for v in d / norm)
        self._gizmo.place(centre, handle, light.color, enabled=light.enabled)

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "lights") or touches(paths, "camera"):
            self._update_gizmo()  # the handle's sphere follows the framing
        if touches(paths, "clip_plane"):
            self._update_clip_widget()

    # -- clipping plane -------------------------------------------------------------------------
    def _update_clip_widget(self) -> None:
        """The plane widget shows ``model.clip_plane`` (hidden while it is off or no data)."""
        clip = self.model.clip_plane
        scene = self.scene
        if scene is None or scene.data is None or self._closed:
            self.clip_widget.set_visible(False)
            return
        self.clip_widget.place(self.bounds, scene.clip_plane_origin(), clip.normal)
        self.clip_widget.set_visible(clip.enabled)
        self.request_render()

    def _clip_moved(self, origin: tuple[float, float, float],
                    normal: tuple[float, float, float]) -> None:
        """A drag of the plane widget ended: one model edit (one undo step)."""
        self.model.clip_plane = ClipPlane(
            enabled=self.model.clip_plane.enabled, origin=tuple(float(v) for v in origin),
            normal=tuple(float(v) for v in normal))

    # -- teardown -------------------------------------------------------------------------------
    def close(self) -> bool:  # type: ignore[override]
        """Stop timers, release GL resources with the context current, close the interactor.

        Idempotent. Returns QWidget.close()'s answer."""
        if self._closed:
            return True
        self._closed = True
        self._render_timer.stop()
        self._settle_timer.stop()
        self._refine_timer.stop()
        self.plotter.removeEventFilter(self)
        self.model.changed.disconnect(self._on_model_changed)
        rw = self.render_window
        if rw is not None:
            rw.MakeCurrent()
        self._gizmo.close()
        self.clip_widget.close()
        if self.scene is not None:
            self.scene.close()
            self.scene = None
        for obj, tag in self._vtk_tags:
            obj.RemoveObserver(tag)
        self._vtk_tags.clear()
        self.plotter.close()
        return super().close()

    @property
    def closed(self) -> bool:
        return self._closed
