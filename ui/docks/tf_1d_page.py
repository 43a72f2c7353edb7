"""The transfer-function dock's 1-D page: the curve editor (opacity and the red, green and
blue curves over data values), the colour bar and the displayed value window. A plain
arrangement of widgets: :class:`~vtkvol.ui.docks.transfer_function.TransferFunctionDock`
binds it to the model."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QHBoxLayout, QLabel, QSizePolicy, QVBoxLayout, QWidget
from superqt import QDoubleRangeSlider

from vtkvol.ui.docks.base import number_box, push_button
from vtkvol.ui.docks.function_editor import ColorBar, Curve, FunctionEditor

#: The editor's curves: (name, label, colour as RGB 0–255).
CURVES = (("opacity", "Opacity", (235, 235, 235)), ("red", "Red", (235, 80, 80)),
          ("green", "Green", (80, 210, 90)), ("blue", "Blue", (90, 140, 255)))


class TF1DPage(QWidget):
    """The 1-D transfer function's editor, colour bar and value window (data units)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        left = QVBoxLayout(self)
        left.setContentsMargins(0, 0, 0, 0)
        left.setSpacing(2)
        self.editor = FunctionEditor()
        self.editor.setObjectName("tf_editor")
        self.editor.set_curves([Curve(n, label, QColor(*c), log_axis=(n == "opacity"))
                                for n, label, c in CURVES])
        self.editor.set_y_title("opacity / colour")
        left.addWidget(self.editor, 1)
        self.colorbar = ColorBar()
        self.colorbar.setObjectName("tf_colorbar")
        left.addWidget(self.colorbar)

        window_row = QHBoxLayout()
        window_row.addWidget(QLabel("Displayed values"))
        self.window_min = number_box(minimum=0, maximum=1, decimals=0, object_name="tf_window_min",
                                     tooltip="Lowest data value shown in the editor")
        self.window_slider = QDoubleRangeSlider(Qt.Orientation.Horizontal)
        self.window_slider.setObjectName("tf_window_slider")
        self.window_slider.setToolTip(
            "Zoom the editor into part of the data range: set a rough function over the whole "
            "range, then refine it part by part.")
        self.window_slider.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.window_max = number_box(minimum=0, maximum=1, decimals=0, object_name="tf_window_max",
                                     tooltip="Highest data value shown in the editor")
        for box in (self.window_min, self.window_max):
            box.setMinimumWidth(80)
            box.setSizePolicy(QSizePolicy.Policy.Fixed, QSizePolicy.Policy.Fixed)
        self.window_full = push_button(
            "Full range", "tf_window_full", "Show the data's whole value range")
        window_row.addWidget(self.window_min)
        window_row.addWidget(self.window_slider, 1)
        window_row.addWidget(self.window_max)
        window_row.addWidget(self.window_full)
        left.addLayout(window_row)
