"""One channel's colour legend, laid out by vtkvol so that its parts never overlap.

Until issue 25 each legend was a ``vtkScalarBarActor``, whose own layout put the top value's
label half over the title (the label is centred on the bar's end, the title box ends there)
and, once the fonts no longer fitted its pixel width (a reopened session rescaled them), drew
the numbers over the bar; VTK does not expose where it put them. Now a legend is three kinds of
plain 2-D props placed here every frame, in pixels of the frame:

* the **bar**: a strip of :data:`BAR_STEPS` quads coloured by the channel's colour function
  over its value span (``lut.GetRange()``, data units), bottom = low value;
* the **title** (the channel's name) above the bar, right-aligned with the bar's right edge;
* three **labels** (low, middle, high value, ``%.4g``) right-aligned left of the bar, each
  centred on its value's height; the bar is shortened at both ends by half a label's height,
  so the top label stays below the title and the bottom one inside the box.

Every position is set in normalised viewport coordinates, which VTK scales for magnified
(tiled) screenshots. Text sizes come from ``vtkTextRenderer`` (the same metrics the text
actors draw with), so the layout holds for any font size and any label width.
"""

from __future__ import annotations

import vtk

#: Colour steps of the bar (a piecewise-linear colour function looks continuous at this).
BAR_STEPS = 64
#: Bar width as a multiple of the font size (pixels).
BAR_WIDTH_EM = 1.0
#: Gap between the title, the labels and the bar, as a multiple of the font size (at least
#: :data:`MIN_GAP_PX`: anti-aliased glyphs reach a pixel past their metric box).
GAP_EM = 0.5
MIN_GAP_PX = 3.0

Box = tuple[float, float, float, float]  #: (left, bottom, right, top) in display pixels


def text_size(prop: vtk.vtkTextProperty, text: str, dpi: int) -> tuple[int, int]:
    """(width, height) in pixels of ``text`` drawn with ``prop`` at ``dpi``."""
    bbox = [0, 0, 0, 0]
    renderer = vtk.vtkTextRenderer.GetInstance()
    if renderer is None or not text or not renderer.GetBoundingBox(prop, text, bbox, dpi):
        size = prop.GetFontSize()
        return (int(0.6 * size * len(text)), int(1.2 * size))
    return (bbox[1] - bbox[0] + 1, bbox[3] - bbox[2] + 1)


class ColorLegend:
    """The bar, title and labels of one channel (see the module docstring)."""

    def __init__(self, name: str, lut: vtk.vtkScalarsToColors) -> None:
        self.name = name
        self.lut = lut
        self._colors_mtime = -1
        self._range: tuple[float, float] | None = None

        self._points = vtk.vtkPoints()
        self._strip = vtk.vtkPolyData()
        self._strip.SetPoints(self._points)
        quads = vtk.vtkCellArray()
        for k in range(BAR_STEPS):
            quads.InsertNextCell(4, [2 * k, 2 * k + 1, 2 * k + 3, 2 * k + 2])
        self._strip.SetPolys(quads)
        self._colors = vtk.vtkUnsignedCharArray()
        self._colors.SetNumberOfComponents(3)
        self._colors.SetNumberOfTuples(BAR_STEPS)
        self._strip.GetCellData().SetScalars(self._colors)
        for _ in range(2 * (BAR_STEPS + 1)):
            self._points.InsertNextPoint(0.0, 0.0, 0.0)
        mapper = vtk.vtkPolyDataMapper2D()
        mapper.SetInputData(self._strip)
        mapper.SetColorModeToDirectScalars()
        mapper.SetScalarModeToUseCellData()
        coordinate = vtk.vtkCoordinate()
        coordinate.SetCoordinateSystemToNormalizedViewport()
        mapper.SetTransformCoordinate(coordinate)
        self.bar = vtk.vtkActor2D()
        self.bar.SetMapper(mapper)
        self.bar.PickableOff()

        self.title = self._text(name, right=True)
        self.labels = [self._text("", right=True) for _ in range(3)]
        #: The layout of the last frame, display pixels: the bar's box and each text's anchor.
        self.bar_box: Box = (0.0, 0.0, 0.0, 0.0)
        #: The box the last layout filled, display pixels.
        self.box: Box = (0.0, 0.0, 0.0, 0.0)

    @staticmethod
    def _text(text: str, *, right: bool) -> vtk.vtkTextActor:
        actor = vtk.vtkTextActor()
        actor.SetInput(text)
        actor.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        prop = actor.GetTextProperty()
        if right:
            prop.SetJustificationToRight()
        prop.ShadowOff()
        prop.BoldOff()
        prop.ItalicOff()
        actor.PickableOff()
        return actor

    # The accessors of the vtkScalarBarActor this class replaced, for its callers.
    def GetTitle(self) -> str:
        return self.name

    def GetLookupTable(self) -> vtk.vtkScalarsToColors:
        return self.lut

    def GetTitleTextProperty(self) -> vtk.vtkTextProperty:
        return self.title.GetTextProperty()

    def GetLabelTextProperty(self) -> vtk.vtkTextProperty:
        return self.labels[0].GetTextProperty()

    def GetMaximumWidthInPixels(self) -> int:
        """Width of the box of the last layout (pixels)."""
        return round(self.box[2] - self.box[0])

    @property
    def props(self) -> list[vtk.vtkProp]:
        return [self.bar, self.title, *self.labels]

    @property
    def texts(self) -> list[vtk.vtkTextActor]:
        return [self.title, *self.labels]

    def set_ink(self, rgb: tuple[float, float, float]) -> None:
        for actor in self.texts:
            actor.GetTextProperty().SetColor(*rgb)

    def set_font_size(self, px: int) -> None:
        for actor in self.texts:
            actor.GetTextProperty().SetFontSize(int(px))

    def _update_colors(self) -> None:
        lo, hi = (float(v) for v in self.lut.GetRange())
        mtime = self.lut.GetMTime()
        if mtime == self._colors_mtime and (lo, hi) == self._range:
            return
        self._colors_mtime, self._range = mtime, (lo, hi)
        rgb = [0.0, 0.0, 0.0]
        for k in range(BAR_STEPS):
            value = lo + (k + 0.5) / BAR_STEPS * (hi - lo)
            self.lut.GetColor(value, rgb)
            self._colors.SetTuple3(k, *(round(255 * min(max(c, 0.0), 1.0)) for c in rgb))
        self._colors.Modified()
        for actor, value in zip(self.labels, (lo, 0.5 * (lo + hi), hi), strict=True):
            actor.SetInput(f"{value:.4g}")

    def layout(self, box: Box, width: int, height: int, dpi: int) -> None:
        """Place the parts inside ``box`` (display pixels of a ``width`` × ``height`` frame):
        title at the top right, the bar along the right edge below it, labels left of it."""
        self._update_colors()
        self.box = box
        _left, bottom, right, top = box  # the labels may reach left of the box
        font = self.title.GetTextProperty().GetFontSize()
        gap = max(MIN_GAP_PX, GAP_EM * font)
        _, title_h = text_size(self.title.GetTextProperty(), self.name, dpi)
        label_sizes = [text_size(a.GetTextProperty(), a.GetInput(), dpi) for a in self.labels]
        label_h = max(h for _, h in label_sizes)
        bar_right = right
        bar_left = right - max(4.0, BAR_WIDTH_EM * font)
        title_bottom = top - title_h
        # A label is centred on its value's height: half of it reaches past each bar end.
        bar_top = title_bottom - gap - 0.5 * label_h
        bar_bottom = bottom + 0.5 * label_h
        if bar_top - bar_bottom < label_h:  # too little room: keep a short bar, still clear
            bar_bottom = bar_top - label_h
        self.bar_box = (bar_left, bar_bottom, bar_right, bar_top)
        for k in range(BAR_STEPS + 1):
            y = (bar_bottom + k / BAR_STEPS * (bar_top - bar_bottom)) / height
            self._points.SetPoint(2 * k, bar_left / width, y, 0.0)
            self._points.SetPoint(2 * k + 1, bar_right / width, y, 0.0)
        self._points.Modified()
        self.title.SetPosition(bar_right / width, title_bottom / height)
        self.title.GetTextProperty().SetVerticalJustificationToBottom()
        label_right = bar_left - gap
        for actor, fraction in zip(self.labels, (0.0, 0.5, 1.0), strict=True):
            y = bar_bottom + fraction * (bar_top - bar_bottom)
            actor.GetTextProperty().SetVerticalJustificationToCentered()
            actor.SetPosition(label_right / width, y / height)
