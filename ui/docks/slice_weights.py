"""Slice-contribution dock: seed 002 §2.11's per-axis weighting functions.

Three functions, one per axis (X, Y, Z), edited with the same
:class:`~vtkvol.ui.docks.function_editor.FunctionEditor` as the transfer function. Each is a
weight 0…1 over the position along its axis; the shader multiplies every sample's RGBA by
wX(x)·wY(y)·wZ(z) and discards samples whose weight is below 1e-10. Weights between 0 and 1
fade slabs (e.g. noisy first and last slices) rather than only cutting them; what is faded
also casts less shadow. The dock only edits ``model.slice_weights``.
"""

from __future__ import annotations

from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QButtonGroup,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QRadioButton,
    QToolButton,
    QWidget,
)

from vtkvol.model.evented import touches
from vtkvol.model.scene import SceneModel, SliceWeights
from vtkvol.ui.docks.base import ModelDock, format_um, hint_label
from vtkvol.ui.docks.function_editor import Curve, FunctionEditor

AXES = (("x", "X", (235, 80, 80)), ("y", "Y", (80, 210, 90)), ("z", "Z", (90, 140, 255)))
_IDENTITY = [(0.0, 1.0), (1.0, 1.0)]


class SliceWeightsDock(ModelDock):
    """Edits ``model.slice_weights.x/y/z`` (positions 0…1 across the volume's extent)."""

    TITLE = "Slice contribution"
    OBJECT_NAME = "dock_slice_weights"

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(model, parent)
        self._build()
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    def _build(self) -> None:
        body = QWidget()
        outer = QHBoxLayout(body)
        outer.setContentsMargins(6, 4, 6, 6)
        self.editor = FunctionEditor(min_points=2)
        self.editor.setObjectName("slice_editor")
        self.editor.set_curves([Curve(name, label, QColor(*color)) for name, label, color in AXES])
        self.editor.set_domain(0.0, 1.0)
        self.editor.set_y_title("weight")
        self.editor.set_x_formatter(self._format_position)
        outer.addWidget(self.editor, 1)

        side = QWidget()
        side.setFixedWidth(228)
        grid = QGridLayout(side)
        grid.setContentsMargins(6, 0, 0, 0)
        grid.setVerticalSpacing(4)
        grid.addWidget(QLabel("Axis"), 0, 0)
        self.axis_group = QButtonGroup(self)
        self.axis_buttons: dict[str, QToolButton] = {}
        axis_row = QHBoxLayout()
        axis_row.setSpacing(2)
        for i, (name, label, color) in enumerate(AXES):
            button = QToolButton()
            button.setText(label)
            button.setCheckable(True)
            button.setObjectName(f"slice_axis_{name}")
            button.setToolTip(f"Edit the weighting function along {label}")
            button.setStyleSheet(
                f"QToolButton:checked {{ border-bottom: 3px solid rgb{color}; font-weight: bold; }}"
            )
            self.axis_group.addButton(button, i)
            self.axis_buttons[name] = button
            axis_row.addWidget(button)
        axis_row.addStretch(1)
        self.axis_buttons["x"].setChecked(True)
        grid.addLayout(axis_row, 0, 1, 1, 2)
        grid.addWidget(QLabel("Mode"), 1, 0)
        self.mode_points = QRadioButton("Points")
        self.mode_points.setObjectName("slice_mode_points")
        self.mode_points.setToolTip("Add, drag and delete nodes (right-click deletes)")
        self.mode_curve = QRadioButton("Curve")
        self.mode_curve.setObjectName("slice_mode_curve")
        self.mode_curve.setToolTip("Draw the weighting function freehand")
        self.mode_points.setChecked(True)
        grid.addWidget(self.mode_points, 1, 1)
        grid.addWidget(self.mode_curve, 1, 2)
        self.reset_axis = QPushButton("Reset axis")
        self.reset_axis.setObjectName("slice_reset_axis")
        self.reset_axis.setToolTip("Weight 1 along the whole edited axis")
        self.reset_all = QPushButton("Reset all")
        self.reset_all.setObjectName("slice_reset_all")
        self.reset_all.setToolTip("Weight 1 everywhere: every slice contributes fully")
        grid.addWidget(self.reset_axis, 2, 0, 1, 2)
        grid.addWidget(self.reset_all, 2, 2)
        grid.addWidget(hint_label(
            "Each sample's colour and opacity are multiplied by wX·wY·wZ; where the product "
            "is 0 the volume is cut away. Use it to fade noisy edge slices."), 3, 0, 1, 3)
        grid.setRowStretch(4, 1)
        grid.setColumnStretch(2, 1)
        outer.addWidget(side)
        self.set_body(body)

        b = self.bindings
        b.connect_qt(self.axis_group.idClicked, lambda i: self.editor.set_active(AXES[i][0]))
        b.connect_qt(self.mode_points.toggled,
                     lambda on: self.editor.set_mode("points" if on else "curve"))
        b.connect_qt(self.editor.pointsEdited, self._on_points_edited)
        b.connect_qt(self.editor.editStarted, self.gestureStarted.emit)
        b.connect_qt(self.editor.editFinished, self._on_edit_finished)
        b.connect_qt(self.reset_axis.clicked, self._on_reset_axis)
        b.connect_qt(self.reset_all.clicked, self._on_reset_all)

    def _format_position(self, t: float) -> str:
        """Axis labels in µm along the edited axis when the data is known, else in %.

        The same rule as the ranges dock and the engine: positions 0…1 span the voxel
        centres, 0 … (n − 1)·s µm (the weights are applied over the data's point bounds).
        """
        axis = self.editor.active or "x"
        if self.data is None:
            return f"{100 * t:.0f} %"
        i = "xyz".index(axis)
        n = self.data.shape_zyx[::-1][i]
        size = float(self.data.voxel_size_um[i])
        return format_um(t * (n - 1) * size, size)

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "slice_weights"):
            self.refresh()

    def refresh(self) -> None:
        weights = self.model.slice_weights
        for name, _label, _color in AXES:
            self.editor.set_points(name, getattr(weights, name))

    def _on_edit_finished(self) -> None:
        self.gestureFinished.emit()
        self.refresh()

    def _on_points_edited(self, name: str, points: list[tuple[float, float]]) -> None:
        clean = [(min(max(float(x), 0.0), 1.0), min(max(float(y), 0.0), 1.0)) for x, y in points]
        try:
            setattr(self.model.slice_weights, name, clean)
        except ValueError:
            self.refresh()

    def _on_reset_axis(self) -> None:
        setattr(self.model.slice_weights, self.editor.active or "x", list(_IDENTITY))

    def _on_reset_all(self) -> None:
        self.model.slice_weights.update(SliceWeights().model_dump())
