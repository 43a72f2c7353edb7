"""What every dock shares: the model, the data it describes, its bindings, small helpers.

A dock edits the model and nothing else; it never imports VTK and never calls the engine
(style-anchors §4 item 11). The main window gives it the :class:`~vtkvol.io.VolumeData` on
screen for what only the data knows (histograms, value ranges, extents, percentiles).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QColorDialog,
    QDockWidget,
    QDoubleSpinBox,
    QFrame,
    QLabel,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QWidget,
)

from vtkvol.model.scene import SceneModel
from vtkvol.ui.binding import Bindings

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

RGB = tuple[float, float, float]


def pick_color(parent: QWidget | None, initial: RGB, title: str) -> RGB | None:
    """Ask the user for a colour (None if cancelled). Tests replace this function."""
    color = QColorDialog.getColor(QColor.fromRgbF(*initial), parent, title)
    return color.getRgbF()[:3] if color.isValid() else None


def rgb_to_qcolor(rgb: RGB) -> QColor:
    return QColor.fromRgbF(*(min(max(float(c), 0.0), 1.0) for c in rgb))


class ColorButton(QPushButton):
    """A button showing a colour swatch; clicking asks for a new colour (``colorPicked``)."""

    colorPicked = Signal(tuple)

    def __init__(self, title: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._rgb: RGB = (1.0, 1.0, 1.0)
        self._title = title
        self.setFixedSize(38, 22)
        self.setCursor(Qt.CursorShape.PointingHandCursor)
        self.clicked.connect(self._ask)

    def set_rgb(self, rgb: RGB) -> None:
        self._rgb = tuple(float(c) for c in rgb)  # type: ignore[assignment]
        color = rgb_to_qcolor(self._rgb)
        self.setStyleSheet(
            f"QPushButton {{ background-color: {color.name()}; border: 1px solid #555;"
            " border-radius: 3px; }"
        )
        self.setToolTip(f"{self._title}: {color.name()} (click to change)")

    def rgb(self) -> RGB:
        return self._rgb

    def _ask(self) -> None:
        chosen = pick_color(self, self._rgb, self._title)  # a global: tests can replace it
        if chosen is not None:
            self.colorPicked.emit(tuple(float(c) for c in chosen))


def push_button(text: str, object_name: str, tooltip: str) -> QPushButton:
    """A ``QPushButton`` with its object name (what tests and style sheets find it by) and
    tooltip."""
    button = QPushButton(text)
    button.setObjectName(object_name)
    button.setToolTip(tooltip)
    return button


def number_box(
    *,
    minimum: float,
    maximum: float,
    decimals: int = 2,
    step: float | None = None,
    suffix: str = "",
    tooltip: str = "",
    object_name: str = "",
) -> QDoubleSpinBox:
    """A ``QDoubleSpinBox`` that commits on Enter/focus loss rather than on every keystroke
    (typing "1200" must not render at 1, 12 and 120 first)."""
    box = QDoubleSpinBox()
    box.setDecimals(decimals)
    box.setRange(minimum, maximum)
    if step is None:
        step = max(10.0**-decimals, (maximum - minimum) / 100)
    box.setSingleStep(step)
    box.setKeyboardTracking(False)
    box.setAccelerated(True)
    if suffix:
        box.setSuffix(f" {suffix}")
    if tooltip:
        box.setToolTip(tooltip)
    if object_name:
        box.setObjectName(object_name)
    box.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
    return box


def um_decimals(voxel_um: float) -> int:
    """Decimals for positions in µm along an axis with voxels ``voxel_um`` apart: the ranges
    dock and the slice-contribution axis write positions the same way."""
    return 2 if voxel_um >= 0.01 else 3


def format_um(value: float, voxel_um: float) -> str:
    """``"25.40 µm"``: a position along an axis, with :func:`um_decimals` decimals."""
    return f"{value:.{um_decimals(voxel_um)}f} µm"


def hint_label(text: str) -> QLabel:
    """A small, wrapped explanatory label."""
    label = QLabel(text)
    label.setWordWrap(True)
    label.setStyleSheet("color: palette(placeholder-text); font-size: 11px;")
    return label


class ModelDock(QDockWidget):
    """Base of the app's docks.

    Subclasses build their widgets in ``__init__`` and implement :meth:`refresh` (push the
    whole model state into the widgets). Connections go through :attr:`bindings` so that
    :meth:`release` removes all of them.

    Signals
    -------
    gestureStarted(), gestureFinished()
        A continuous edit (a drag in a function editor) begins / ends; the main window groups
        the edits in between into one undo step.
    """

    gestureStarted = Signal()
    gestureFinished = Signal()

    TITLE = ""
    OBJECT_NAME = ""

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(self.TITLE, parent)
        self.setObjectName(self.OBJECT_NAME)
        self.setFeatures(
            QDockWidget.DockWidgetFeature.DockWidgetClosable
            | QDockWidget.DockWidgetFeature.DockWidgetMovable
            | QDockWidget.DockWidgetFeature.DockWidgetFloatable
        )
        self.model = model
        self.data: VolumeData | None = None
        self.bindings = Bindings()

    def set_body(self, body: QWidget) -> None:
        """Install the dock's content in a scroll area, so that a small screen can shrink
        the dock below the content's natural size instead of the window growing past it."""
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QFrame.Shape.NoFrame)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAsNeeded)
        scroll.setWidget(body)
        self.setWidget(scroll)

    def set_data(self, data: VolumeData | None) -> None:
        """The volume on screen changed (its model changes arrive as events)."""
        self.data = data
        self.refresh()

    def set_voxels(self, data: VolumeData) -> None:
        """Other voxels of the same geometry are on screen (another time point): shape,
        channels and voxel size are unchanged, so nothing structural is rebuilt. Docks that
        show something of the values (histograms) override this."""
        self.data = data

    def refresh(self) -> None:
        """Show the current model state (override)."""

    def release(self) -> None:
        """Disconnect from the model (the window is closing); idempotent."""
        self.bindings.clear()
