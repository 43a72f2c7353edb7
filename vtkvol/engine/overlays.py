"""Annotations over the volume: scale bar, orientation axes, bounding box, colour legend.

:class:`SceneOverlays` owns the VTK props of ``SceneModel.overlays``; the
:class:`~vtkvol.engine.scene.VolumeScene` tells it what changed. Everything is an ordinary
prop of the scene's render window, so screenshots contain it too. Nothing here changes the
volume or its illumination.

* **Bounding box**: a ``vtkOutlineSource`` over the data's bounds (voxel centres, µm), an
  opaque actor in the volume's renderer, so the volume hides its far edges.
* **Orientation axes**: a ``vtkAxesActor`` in a small renderer in the lower-left corner (a
  layer above the volume's), whose camera looks along the main camera's direction before
  each frame. No interactor is needed, so offscreen renders (``vtkvol render``) have it too.
* **Scale bar**: a 2-D bar of a round length (1, 2 or 5 × 10ⁿ µm, about a fifth of the
  view's width) measured in the plane through the camera's focal point, with its length
  above it; recomputed before each frame from the camera.
* **Colour legend**: a :class:`~vtkvol.engine.legend.ColorLegend` per visible channel (a
  colour bar over its colour function's value span, data units, titled with the channel's
  name, three value labels), one above the other along the right edge, laid out every frame
  so that no title, label or bar overlaps another.
* **Slice planes**: the outlines of the three orthogonal slice planes through the slice
  views' cursor (world µm), each in its normal axis's colour (x red, y green, z blue, as the
  orientation axes), spanning the data's box.

Line and text colours follow the background's brightness (light on dark, dark on light).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import vtk

from vtkvol.engine.legend import ColorLegend
from vtkvol.engine.slices import PLANE_COLORS
from vtkvol.model.scene import RGB, Overlays

#: Width of the scale bar, as a share of the view's width, before rounding its length.
SCALE_BAR_SHARE = 0.2
#: Corner viewport of the orientation axes (share of the view's width/height).
AXES_VIEWPORT = (0.0, 0.0, 0.2, 0.2)
#: Margin of the scale bar from the view's lower-right corner, pixels.
MARGIN_PX = 14
#: Font size of the scale bar's label, pixels (at :data:`REFERENCE_PX`).
FONT_PX = 14
#: Font size of the colour legends' titles and labels, pixels (at :data:`REFERENCE_PX`).
LEGEND_FONT_PX = 12
#: Widest colour legend, pixels (at :data:`REFERENCE_PX`).
LEGEND_MAX_WIDTH_PX = 90
#: Shorter side of the frame (pixels) at which the pixel sizes above hold; other frames scale
#: them by :func:`overlay_scale`, so a legend takes the same share of a 320 × 240 movie frame
#: as of the app's view (it took a fifth of small frames, issue 25).
REFERENCE_PX = 600
#: Bounds of :func:`overlay_scale` (text below ~6 px is unreadable; above 3× is a poster).
OVERLAY_SCALE_RANGE = (0.45, 3.0)


def overlay_scale(width: int, height: int) -> float:
    """Factor of the overlays' pixel sizes (fonts, legend width, margin) for a frame of
    ``width`` × ``height`` pixels: the shorter side over :data:`REFERENCE_PX`, clamped to
    :data:`OVERLAY_SCALE_RANGE`."""
    lo, hi = OVERLAY_SCALE_RANGE
    return min(hi, max(lo, min(width, height) / REFERENCE_PX))


def round_length(length: float) -> float:
    """The largest 1, 2 or 5 × 10ⁿ not above ``length`` (> 0)."""
    exponent = math.floor(math.log10(length))
    base = 10.0**exponent
    for step in (5.0, 2.0, 1.0):
        if step * base <= length * (1 + 1e-9):
            return step * base
    return base


def format_length(length_um: float) -> str:
    """``"50 µm"``, ``"2 mm"``, ``"500 nm"``: the unit that keeps the number readable."""
    if length_um >= 1000.0:
        return f"{length_um / 1000.0:g} mm"
    if length_um < 1.0:
        return f"{length_um * 1000.0:g} nm"
    return f"{length_um:g} µm"


def ink_for(background: RGB) -> RGB:
    """Line and text colour readable on ``background``."""
    r, g, b = background
    return (0.1, 0.1, 0.1) if 0.2126 * r + 0.7152 * g + 0.0722 * b > 0.5 else (0.92, 0.92, 0.92)


class SceneOverlays:
    """The overlay props of one scene (see the module docstring)."""

    def __init__(self, renderer: vtk.vtkRenderer) -> None:
        self.renderer = renderer
        self._state = Overlays()
        self._ink: RGB = (0.92, 0.92, 0.92)
        #: :func:`overlay_scale` of the last frame.
        self._scale = 1.0

        self._outline = vtk.vtkOutlineSource()
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputConnection(self._outline.GetOutputPort())
        self.box_actor = vtk.vtkActor()
        self.box_actor.SetMapper(mapper)
        self.box_actor.PickableOff()
        self.box_actor.GetProperty().SetLineWidth(1.5)
        self.box_actor.GetProperty().LightingOff()

        self.axes_actor = vtk.vtkAxesActor()
        self.axes_actor.SetShaftTypeToCylinder()
        self.axes_actor.SetTotalLength(1.0, 1.0, 1.0)
        self.axes_renderer = vtk.vtkRenderer()
        self.axes_renderer.SetViewport(*AXES_VIEWPORT)
        self.axes_renderer.SetLayer(1)
        self.axes_renderer.InteractiveOff()  # clicks in the corner still move the main camera
        self.axes_renderer.AddActor(self.axes_actor)

        # A 2-D axis without ticks or labels: a line between its two position coordinates,
        # which tiled (magnified) screenshots scale with the image, unlike polygon points.
        self.bar_actor = vtk.vtkAxisActor2D()
        for coordinate in (self.bar_actor.GetPositionCoordinate(),
                           self.bar_actor.GetPosition2Coordinate()):
            coordinate.SetCoordinateSystemToNormalizedViewport()
        self.bar_actor.TickVisibilityOff()
        self.bar_actor.LabelVisibilityOff()
        self.bar_actor.TitleVisibilityOff()
        self.bar_actor.GetProperty().SetLineWidth(4.0)
        self.bar_actor.PickableOff()
        self.bar_text = vtk.vtkTextActor()
        text = self.bar_text.GetTextProperty()
        text.SetFontSize(FONT_PX)
        text.SetJustificationToCentered()
        text.SetVerticalJustificationToBottom()
        self.bar_text.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        self.bar_text.PickableOff()
        #: Length (µm) and pixel length of the bar in the last frame (tests read them).
        self.bar_length_um = 0.0
        self.bar_length_px = 0.0
        self._hold = False

        self._bounds: tuple[float, ...] = (0.0, 1.0, 0.0, 1.0, 0.0, 1.0)
        self._cursor: tuple[float, float, float] = (0.5, 0.5, 0.5)
        self._planes = vtk.vtkPolyData()
        planes_mapper = vtk.vtkPolyDataMapper()
        planes_mapper.SetInputData(self._planes)
        planes_mapper.SetScalarModeToUseCellData()
        planes_mapper.SetColorModeToDirectScalars()
        self.planes_actor = vtk.vtkActor()
        self.planes_actor.SetMapper(planes_mapper)
        self.planes_actor.PickableOff()
        self.planes_actor.GetProperty().SetLineWidth(2.0)
        self.planes_actor.GetProperty().LightingOff()
        self._build_planes()

        self.legends: list[ColorLegend] = []
        self._legend_sources: list[tuple[str, vtk.vtkScalarsToColors]] = []
        self._tag = renderer.AddObserver(vtk.vtkCommand.StartEvent, self._before_frame)

    # -- state ----------------------------------------------------------------------------------
    @property
    def state(self) -> Overlays:
        return self._state

    def set_bounds(self, bounds: Sequence[float]) -> None:
        """The data's box (xmin, xmax, ymin, ymax, zmin, zmax) in µm."""
        self._outline.SetBounds(*(float(b) for b in bounds))
        self._bounds = tuple(float(b) for b in bounds)
        self._build_planes()

    def set_cursor(self, cursor_um: Sequence[float]) -> None:
        """The point (x, y, z world µm) the slice planes pass through."""
        self._cursor = tuple(float(c) for c in cursor_um)  # type: ignore[assignment]
        self._build_planes()

    @property
    def plane_outlines(self) -> np.ndarray:
        """The slice planes' corners, ``[3 planes (normal x, y, z), 4 corners, xyz µm]``."""
        b, c = self._bounds, self._cursor
        out = np.empty((3, 4, 3))
        for normal in range(3):
            u, v = (a for a in range(3) if a != normal)
            for corner, (su, sv) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
                out[normal, corner, normal] = c[normal]
                out[normal, corner, u] = b[2 * u + su]
                out[normal, corner, v] = b[2 * v + sv]
        return out

    def _build_planes(self) -> None:
        corners = self.plane_outlines
        points = vtk.vtkPoints()
        lines = vtk.vtkCellArray()
        colors = vtk.vtkUnsignedCharArray()
        colors.SetNumberOfComponents(3)
        for normal in range(3):
            ids = [points.InsertNextPoint(*corners[normal, k]) for k in range(4)]
            lines.InsertNextCell(5, [*ids, ids[0]])
            colors.InsertNextTuple3(*(round(255 * v) for v in PLANE_COLORS[normal]))
        self._planes.SetPoints(points)
        self._planes.SetLines(lines)
        self._planes.GetCellData().SetScalars(colors)
        self._planes.Modified()

    def set_background(self, background: RGB) -> None:
        self._ink = ink_for(background)
        self.box_actor.GetProperty().SetColor(*self._ink)
        self.bar_actor.GetProperty().SetColor(*self._ink)
        self.bar_text.GetTextProperty().SetColor(*self._ink)
        for legend in self.legends:
            legend.set_ink(self._ink)

    def set_legend_channels(self, channels: Sequence[tuple[str, vtk.vtkScalarsToColors]]) -> None:
        """The visible channels' names and colour functions, in order."""
        channels = list(channels)
        same = len(channels) == len(self._legend_sources) and all(
            name == old_name and lut is old_lut
            for (name, lut), (old_name, old_lut) in zip(channels, self._legend_sources,
                                                         strict=True))
        if same:
            return  # the bars follow their colour functions' in-place edits by themselves
        self._legend_sources = channels
        self._build_legends()

    def apply(self, state: Overlays) -> None:
        """Show what ``state`` asks for."""
        self._state = state.model_copy()
        ren = self.renderer
        _show(ren, self.box_actor, state.bounding_box)
        _show(ren, self.planes_actor, state.slice_planes)
        _show(ren, self.bar_actor, state.scale_bar)
        _show(ren, self.bar_text, state.scale_bar)
        self._build_legends()
        window = ren.GetRenderWindow()
        has_axes = window is not None and window.HasRenderer(self.axes_renderer)
        if state.orientation_axes and not has_axes and window is not None:
            # The volume's renderer stays on layer 0; the corner is drawn over it.
            window.SetNumberOfLayers(max(window.GetNumberOfLayers(), 2))
            window.AddRenderer(self.axes_renderer)
        elif not state.orientation_axes and has_axes:
            window.RemoveRenderer(self.axes_renderer)

    def _build_legends(self) -> None:
        for legend in self.legends:
            for prop in legend.props:
                self.renderer.RemoveViewProp(prop)
        self.legends = []
        if not self._state.color_legend:
            return
        for name, lut in self._legend_sources:
            legend = ColorLegend(name, lut)
            legend.set_ink(self._ink)
            legend.set_font_size(max(6, round(LEGEND_FONT_PX * self._scale)))
            for prop in legend.props:
                self.renderer.AddViewProp(prop)
            self.legends.append(legend)
        self._place_legends()

    def legend_boxes(self, width: int, height: int) -> list[tuple[float, float, float, float]]:
        """Each legend's box (left, bottom, right, top) in display pixels of a ``width`` ×
        ``height`` frame: one above the other along the right edge (side by side, the labels
        would collide), from near the top down to above the scale bar."""
        count = max(len(self.legends), 1)
        margin = MARGIN_PX * self._scale
        band = 0.8 / count
        right = width - margin
        left = right - LEGEND_MAX_WIDTH_PX * self._scale
        return [(left, height * (0.97 - band * (k + 1) + 0.02), right,
                 height * (0.97 - band * k)) for k in range(len(self.legends))]

    def _place_legends(self) -> None:
        width, height = self.renderer.GetSize()
        if width < 2 or height < 2 or not self.legends:
            return
        window = self.renderer.GetRenderWindow()
        dpi = window.GetDPI() if window is not None else 72
        for legend, box in zip(self.legends, self.legend_boxes(width, height), strict=True):
            legend.layout(box, width, height, dpi)

    # -- per frame ------------------------------------------------------------------------------
    def magnify(self, scale: int) -> None:
        """Prepare a screenshot ``scale`` times the view's size (1: back to normal).

        A magnified screenshot renders the view in tiles with a narrowed camera, and VTK
        moves and scales the 2-D props (given in normalised viewport coordinates) from the
        layout of the last normal frame; so the per-frame updates pause meanwhile. (The scale
        bar's label keeps its pixel size there: VTK does not scale that font.)
        """
        self._hold = scale > 1

    def _before_frame(self, *_: object) -> None:
        if self._hold:
            return
        self._scale_to_frame()
        self._place_legends()
        if self._state.orientation_axes:
            self._orient_axes()
        if self._state.scale_bar:
            self._place_scale_bar()

    def _scale_to_frame(self) -> None:
        """Fonts, legend width and margin in proportion to the frame (:func:`overlay_scale`)."""
        width, height = self.renderer.GetSize()
        if width < 2 or height < 2:
            return
        scale = overlay_scale(width, height)
        self._scale = scale
        self.bar_text.GetTextProperty().SetFontSize(max(6, round(FONT_PX * scale)))
        for legend in self.legends:
            legend.set_font_size(max(6, round(LEGEND_FONT_PX * scale)))

    def _orient_axes(self) -> None:
        main = self.renderer.GetActiveCamera()
        cam = self.axes_renderer.GetActiveCamera()
        direction = np.subtract(main.GetPosition(), main.GetFocalPoint())
        norm = float(np.linalg.norm(direction)) or 1.0
        cam.SetFocalPoint(0.0, 0.0, 0.0)
        cam.SetPosition(*(direction / norm * 5.0))
        cam.SetViewUp(*main.GetViewUp())
        cam.SetParallelProjection(0)
        cam.SetViewAngle(30.0)
        self.axes_renderer.ResetCamera(-0.6, 0.6, -0.6, 0.6, -0.6, 0.6)

    def _place_scale_bar(self) -> None:
        width, height = self.renderer.GetSize()
        if width < 2 or height < 2:
            return
        cam = self.renderer.GetActiveCamera()
        if cam.GetParallelProjection():
            world_height = 2.0 * cam.GetParallelScale()
        else:
            world_height = 2.0 * cam.GetDistance() * math.tan(math.radians(cam.GetViewAngle()) / 2)
        um_per_px = world_height / height
        if not um_per_px > 0.0:
            return
        length = round_length(SCALE_BAR_SHARE * width * um_per_px)
        pixels = length / um_per_px
        margin = MARGIN_PX * self._scale
        x1 = width - margin
        x0 = x1 - pixels
        y = margin
        # Normalised viewport coordinates: what tiled screenshots place and scale correctly.
        self.bar_actor.GetPositionCoordinate().SetValue(x0 / width, y / height, 0.0)
        self.bar_actor.GetPosition2Coordinate().SetValue(x1 / width, y / height, 0.0)
        self.bar_text.SetInput(format_length(length))
        self.bar_text.SetPosition(0.5 * (x0 + x1) / width, (y + 5) / height)
        self.bar_length_um, self.bar_length_px = length, pixels

    def close(self) -> None:
        self.renderer.RemoveObserver(self._tag)
        for actor in (self.box_actor, self.planes_actor):
            self.renderer.RemoveActor(actor)
        for actor in (self.bar_actor, self.bar_text,
                      *(p for legend in self.legends for p in legend.props)):
            self.renderer.RemoveViewProp(actor)
        self.legends = []
        window = self.renderer.GetRenderWindow()
        if window is not None and window.HasRenderer(self.axes_renderer):
            window.RemoveRenderer(self.axes_renderer)


def _show(renderer: vtk.vtkRenderer, prop: vtk.vtkProp, visible: bool) -> None:
    present = bool(renderer.HasViewProp(prop))
    if visible and not present:
        renderer.AddViewProp(prop)
    elif not visible and present:
        renderer.RemoveViewProp(prop)
