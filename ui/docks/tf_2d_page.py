"""The transfer-function dock's 2-D page: the value × gradient-magnitude editor, its tools
(regions, paint, erase), the selected region's colour, opacity and soft edge, proposed classes
and the gradient axis. A plain arrangement of widgets:
:class:`~vtkvol.ui.docks.transfer_function.TransferFunctionDock` binds it to the model."""

from __future__ import annotations

from PySide6.QtWidgets import QButtonGroup, QHBoxLayout, QLabel, QToolButton, QVBoxLayout, QWidget

from vtkvol.model.classification import (
    DEFAULT_OPACITY_SCALE,
    DEFAULT_RADIUS,
    OPACITY_SCALE_RANGE,
    RADIUS_RANGE,
)
from vtkvol.model.tf_paint import MAX_BRUSH_RADIUS
from vtkvol.ui.docks.base import ColorButton, number_box, push_button
from vtkvol.ui.docks.tf2d_editor import TF2DEditor


class TF2DPage(QWidget):
    """The 2-D transfer function's editor and controls (values in data units, gradients in
    data units per µm)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        self.editor_2d = TF2DEditor()
        self.editor_2d.setObjectName("tf2d_editor")
        self.editor_2d.setToolTip(
            "Value × gradient-magnitude histogram (log counts) with the 2-D transfer "
            "function over it. Regions tool: press inside a region to select and move it; "
            "drag a corner handle of the selected region to resize it; Shift/Ctrl-click or "
            "drag a box from empty space to select several, Delete removes them. Paint / "
            "Erase: drag to brush into the painted layer (dotted box).")
        layout.addWidget(self.editor_2d, 1)
        self._add_paint_tools(layout)
        self._add_region_tools(layout)
        self._add_class_tools(layout)

    def _add_paint_tools(self, layout: QVBoxLayout) -> None:
        """The tool buttons (regions, paint, erase) and the brush."""
        tools = QHBoxLayout()
        tools.setSpacing(4)
        self.tool_group = QButtonGroup(self)
        self.tool_group.setExclusive(True)
        tips = {
            "regions": "Select, move and resize rectangles and triangles",
            "paint": "Paint into the channel's painted layer (128 × 128 pixels over the axes "
                     "shown when you first paint) with the brush's colour and opacity",
            "erase": "Erase the painted layer (the regions are not affected)",
        }
        for i, tool in enumerate(("regions", "paint", "erase")):
            button = QToolButton()
            button.setText(tool.capitalize())
            button.setCheckable(True)
            button.setChecked(i == 0)
            button.setObjectName(f"tf2d_tool_{tool}")
            button.setToolTip(tips[tool])
            self.tool_group.addButton(button, i)
            tools.addWidget(button)
        tools.addSpacing(6)
        self.brush_size = number_box(
            minimum=0.5, maximum=MAX_BRUSH_RADIUS, decimals=1, step=0.5,
            object_name="tf2d_brush_size",
            tooltip="Brush radius in pixels of the painted layer (128 across each axis)")
        self.brush_size.setValue(4.0)
        self.brush_color = ColorButton("Brush colour")
        self.brush_color.setObjectName("tf2d_brush_color")
        self.brush_color.set_rgb((1.0, 1.0, 1.0))
        self.brush_opacity = number_box(
            minimum=0.0, maximum=1.0, decimals=3, step=0.05, object_name="tf2d_brush_opacity",
            tooltip="Opacity the brush paints (per opacity unit distance); a stroke moves "
                    "each pixel to it, it does not pile up")
        self.brush_opacity.setValue(0.5)
        self.clear_paint = push_button(
            "Clear paint", "tf2d_clear_paint",
            "Remove the painted layer; the next stroke starts a new one over the axes shown")
        # Two controls rows per line, not four: one line of them all made the dock at least
        # 818 px wide, a horizontal scroll bar in a 1024 × 700 window (issue 25).
        tools.addWidget(self.clear_paint)
        tools.addStretch(1)
        layout.addLayout(tools)
        brush = QHBoxLayout()
        brush.setSpacing(4)
        brush.addWidget(QLabel("brush size"))
        brush.addWidget(self.brush_size)
        brush.addWidget(self.brush_color)
        brush.addWidget(QLabel("α"))
        brush.addWidget(self.brush_opacity)
        brush.addStretch(1)
        layout.addLayout(brush)

    def _add_region_tools(self, layout: QVBoxLayout) -> None:
        """Add and delete regions; the selected region's colour, opacity and soft edge."""
        row = QHBoxLayout()
        row.setSpacing(4)
        self.add_rectangle = push_button(
            "+ Rectangle", "tf2d_add_rectangle", "Add a rectangle: a range of values and gradients")
        self.add_triangle = push_button(
            "+ Triangle", "tf2d_add_triangle",
            "Add a triangle rising from |∇I| = 0: Kniss's widget for the boundary arcs "
            "between two materials")
        self.delete_primitive = push_button("Delete", "tf2d_delete",
                                            "Remove the selected regions (Delete key)")
        self.primitive_color = ColorButton("Region colour")
        self.primitive_color.setObjectName("tf2d_color")
        self.primitive_opacity = number_box(
            minimum=0.0, maximum=1.0, decimals=3, step=0.01, object_name="tf2d_opacity",
            tooltip="Opacity of the selected region (per opacity unit distance)")
        self.primitive_soft = number_box(
            minimum=0.0, maximum=1.0, decimals=2, step=0.05, object_name="tf2d_soft_edge",
            tooltip="Soft edge: the fraction of the region's half-size over which its "
                    "opacity fades to 0 at the border (0 = hard edge)")
        for widget in (self.add_rectangle, self.add_triangle, self.delete_primitive):
            row.addWidget(widget)
        row.addStretch(1)
        layout.addLayout(row)
        row = QHBoxLayout()
        row.setSpacing(4)
        row.addWidget(QLabel("region colour"))
        row.addWidget(self.primitive_color)
        row.addWidget(QLabel("α"))
        row.addWidget(self.primitive_opacity)
        row.addWidget(QLabel("soft"))
        row.addWidget(self.primitive_soft)
        row.addStretch(1)
        layout.addLayout(row)

    def _add_class_tools(self, layout: QVBoxLayout) -> None:
        """Proposed classes (spatialized transfer function) and the gradient axis."""
        stf = QHBoxLayout()
        stf.setSpacing(4)
        self.propose_button = push_button(
            "Propose classes", "tf2d_propose",
            "Spatialized transfer function (Roettger et al.): group histogram bins whose "
            "voxels lie in the same place, colour each group, opacity growing with the "
            "gradient. Replaces this channel's regions; edit the result.")
        self.stf_radius = number_box(
            minimum=RADIUS_RANGE[0], maximum=RADIUS_RANGE[1], decimals=2, step=0.01,
            object_name="tf2d_stf_radius",
            tooltip="r: how far apart (barycentre distance + spread difference, in units of "
                    "the volume's size) two bins may be and still form one class; larger "
                    "gives fewer classes")
        self.stf_radius.setValue(DEFAULT_RADIUS)
        self.stf_opacity = number_box(
            minimum=OPACITY_SCALE_RANGE[0], maximum=OPACITY_SCALE_RANGE[1], decimals=2,
            step=0.1, object_name="tf2d_stf_opacity",
            tooltip="c_α: opacity = c_α · |∇I| / top of the gradient axis (capped at 1)")
        self.stf_opacity.setValue(DEFAULT_OPACITY_SCALE)
        self.gradient_top = number_box(
            minimum=1e-6, maximum=1e12, decimals=3, object_name="tf2d_gradient_top",
            tooltip="Top of the editor's gradient axis (data units per µm): zoom into the "
                    "low gradients where most voxels lie. The renderer's own axis ends at "
                    "¼ of the value range per mean voxel edge.")
        self.gradient_full = push_button(
            "Full", "tf2d_gradient_full", "Show the renderer's whole gradient axis again")
        stf.addWidget(self.propose_button)
        stf.addWidget(QLabel("r"))
        stf.addWidget(self.stf_radius)
        stf.addWidget(QLabel("c_α"))
        stf.addWidget(self.stf_opacity)
        stf.addStretch(1)
        layout.addLayout(stf)
        stf = QHBoxLayout()
        stf.setSpacing(4)
        stf.addWidget(QLabel("|∇I| axis"))
        stf.addWidget(self.gradient_top)
        stf.addWidget(self.gradient_full)
        stf.addStretch(1)
        layout.addLayout(stf)
