"""The transfer-function dock's controls beside the editor: channel, 1-D or 2-D
classification, which curve is edited and how, the axes' scales, presets, load and save. A
plain arrangement of widgets: :class:`~vtkvol.ui.docks.transfer_function.TransferFunctionDock`
binds it to the model."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QComboBox,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QMenu,
    QRadioButton,
    QToolButton,
    QWidget,
)

from vtkvol.model.presets import is_preset, preset_label, preset_names
from vtkvol.ui.docks.base import hint_label, push_button
from vtkvol.ui.docks.tf_1d_page import CURVES

#: The classification choices: (model value, label).
DIMENSIONS = (("1d", "Value (1-D)"), ("2d", "Value × gradient (2-D)"))
COLORMAPS = ("gray", "viridis", "magma", "inferno", "plasma", "cividis", "turbo", "hot",
             "bone", "copper", "cubehelix")
ASK_COLORMAP = "\0ask"  #: menu data of "By name…" (not a valid preset or colormap name)


class TFControls(QWidget):
    """The controls column of the transfer-function dock (``controls_1d``: the widgets that
    apply to the 1-D editor only, hidden while the channel is classified in 2-D)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setFixedWidth(228)
        grid = QGridLayout(self)
        grid.setContentsMargins(6, 0, 0, 0)
        grid.setVerticalSpacing(4)
        row = 0
        grid.addWidget(QLabel("Channel"), row, 0)
        self.channel_combo = QComboBox()
        self.channel_combo.setObjectName("tf_channel")
        self.channel_combo.setToolTip("The channel whose transfer function is edited")
        grid.addWidget(self.channel_combo, row, 1, 1, 3)
        row += 1
        self.link_label = hint_label("")
        self.link_label.setVisible(False)
        grid.addWidget(self.link_label, row, 0, 1, 4)
        row += 1
        grid.addWidget(QLabel("Classify"), row, 0)
        self.dimension_combo = QComboBox()
        self.dimension_combo.setObjectName("tf_dimension")
        for _, label in DIMENSIONS:
            self.dimension_combo.addItem(label)
        self.dimension_combo.setToolTip(
            "Classify the channel by its values (1-D transfer function) or by value and "
            "gradient magnitude (2-D): boundaries between materials have large gradients. "
            "Switching keeps both functions.")
        grid.addWidget(self.dimension_combo, row, 1, 1, 3)
        row += 1
        first_1d_row = row
        grid.addWidget(QLabel("Edit"), row, 0)
        self.curve_group = QButtonGroup(self)
        self.curve_buttons: dict[str, QToolButton] = {}
        curve_row = QHBoxLayout()
        curve_row.setSpacing(2)
        for i, (name, label, color) in enumerate(CURVES):
            button = QToolButton()
            button.setText(label if name == "opacity" else label[0])
            button.setCheckable(True)
            button.setObjectName(f"tf_curve_{name}")
            button.setToolTip(f"Edit the {label.lower()} curve")
            button.setStyleSheet(
                f"QToolButton:checked {{ border-bottom: 3px solid rgb{color}; "
                "font-weight: bold; }")
            self.curve_group.addButton(button, i)
            self.curve_buttons[name] = button
            curve_row.addWidget(button)
        self.curve_buttons["opacity"].setChecked(True)
        grid.addLayout(curve_row, row, 1, 1, 3)
        row += 1
        grid.addWidget(QLabel("Mode"), row, 0)
        self.mode_points = QRadioButton("Points")
        self.mode_points.setObjectName("tf_mode_points")
        self.mode_points.setToolTip("Add, drag and delete nodes (right-click deletes)")
        self.mode_curve = QRadioButton("Curve")
        self.mode_curve.setObjectName("tf_mode_curve")
        self.mode_curve.setToolTip("Draw the curve freehand")
        self.mode_points.setChecked(True)
        grid.addWidget(self.mode_points, row, 1)
        grid.addWidget(self.mode_curve, row, 2, 1, 2)
        row += 1
        self.log_opacity = QCheckBox("Log opacity axis")
        self.log_opacity.setObjectName("tf_log_opacity")
        self.log_opacity.setToolTip(
            "Spread low opacities (0.001–0.05) over most of the editor's height "
            "(Potts & Möller's logarithmic scale, seed 002 §5.1.3)")
        grid.addWidget(self.log_opacity, row, 0, 1, 4)
        row += 1
        self.histogram_log = QCheckBox("Log histogram counts")
        self.histogram_log.setObjectName("tf_histogram_log")
        self.histogram_log.setChecked(True)
        self.histogram_log.setToolTip("Show the histogram's counts on a log scale, so rare "
                                      "bright values are visible next to the background peak")
        grid.addWidget(self.histogram_log, row, 0, 1, 4)
        row += 1
        self.preset_button = QToolButton()
        self.preset_button.setObjectName("tf_presets")
        self.preset_button.setText("Preset")
        self.preset_button.setToolTip("Replace this channel's transfer function by a preset, "
                                      "stretched over its current value span")
        self.preset_button.setPopupMode(QToolButton.ToolButtonPopupMode.InstantPopup)
        self.preset_button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        self.preset_menu = self._preset_menu()
        self.preset_button.setMenu(self.preset_menu)
        self.load_button = push_button(
            "Load…", "tf_load", "Load a transfer function saved with Save…")
        self.save_button = push_button(
            "Save…", "tf_save", "Save this channel's transfer function to a file")
        buttons = QHBoxLayout()
        buttons.setSpacing(4)
        buttons.addWidget(self.preset_button)
        buttons.addWidget(self.load_button)
        buttons.addWidget(self.save_button)
        grid.addLayout(buttons, row, 0, 1, 4)
        row += 1
        # The 1-D editor's controls: hidden while the channel is classified in 2-D.
        self.controls_1d = [
            item.widget() for r in range(first_1d_row, row) for c in range(4)
            if (item := grid.itemAtPosition(r, c)) is not None and item.widget() is not None
        ] + [*self.curve_buttons.values(), self.preset_button, self.load_button,
             self.save_button]
        grid.setRowStretch(row, 1)
        grid.setColumnStretch(3, 1)

    def _preset_menu(self) -> QMenu:
        """Presets by kind, then colormaps; each action's data is the preset's name
        (:data:`ASK_COLORMAP` for \"By name…\")."""
        menu = QMenu(self)
        for kind, title in (("fluorescence", "Fluorescence"), ("ct", "CT")):
            menu.addSection(title)
            for name in preset_names(kind):
                action = menu.addAction(preset_label(name))
                action.setData(name)
        maps = [name for name in COLORMAPS if is_preset(name)]
        if maps:
            sub = menu.addMenu("Colormaps")
            for name in maps:
                action = sub.addAction(name)
                action.setData(name)
            sub.addSeparator()
            other = sub.addAction("By name…")
            other.setToolTip("Any matplotlib colormap, e.g. twilight, Blues, RdPu")
            other.setData(ASK_COLORMAP)
        return menu
