"""Per-axis ranges dock: crop the volume to a box, in µm, one range slider per axis.

Edits ``model.crop`` (world µm, voxel centres from 0); the engine applies it as VTK's
cropping region. Shadows and ambient occlusion are computed from the cropped volume, so
what is cropped away neither shows nor casts shadow. An axis at its full extent is stored as
``None`` ("no crop"), so a session saved uncropped stays uncropped on other data.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)
from superqt import QDoubleRangeSlider

from vtkvol.model.evented import touches
from vtkvol.model.scene import SceneModel
from vtkvol.ui.binding import signals_blocked
from vtkvol.ui.docks.base import ModelDock, hint_label, number_box, um_decimals

AXES = ("x", "y", "z")


class RangesDock(ModelDock):
    """Three range sliders with numeric entry driving ``model.crop.x/y/z`` (µm)."""

    TITLE = "Ranges"
    OBJECT_NAME = "dock_ranges"
    #: "Refine selection" was pressed: the window loads the crop region at a finer level.
    refineRequested = Signal()
    #: "Back to overview" was pressed: the window shows the overview level again.
    overviewRequested = Signal()

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(model, parent)
        self._build()
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    def _build(self) -> None:
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.setContentsMargins(8, 6, 8, 8)
        grid = QGridLayout()
        grid.setHorizontalSpacing(6)
        grid.setVerticalSpacing(4)
        self.sliders: dict[str, QDoubleRangeSlider] = {}
        self.lo_boxes = {}
        self.hi_boxes = {}
        for row, axis in enumerate(AXES):
            name = QLabel(f"{axis.upper()} (µm)")
            name.setToolTip(f"Keep the part of the volume between these {axis} positions")
            slider = QDoubleRangeSlider(Qt.Orientation.Horizontal)
            slider.setObjectName(f"crop_slider_{axis}")
            slider.setToolTip(f"Drag the ends to crop along {axis.upper()}")
            slider.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
            lo = number_box(minimum=0, maximum=1, decimals=2, suffix="µm",
                            object_name=f"crop_min_{axis}",
                            tooltip=f"Lowest {axis} position kept (µm)")
            hi = number_box(minimum=0, maximum=1, decimals=2, suffix="µm",
                            object_name=f"crop_max_{axis}",
                            tooltip=f"Highest {axis} position kept (µm)")
            # Two rows per axis: name and numbers, then the slider at full width (a dock is
            # narrow; a slider squeezed between two number boxes would be too short to use).
            grid.addWidget(name, 2 * row, 0)
            grid.addWidget(lo, 2 * row, 1)
            grid.addWidget(QLabel("–"), 2 * row, 2)
            grid.addWidget(hi, 2 * row, 3)
            grid.addWidget(slider, 2 * row + 1, 0, 1, 4)
            grid.setRowMinimumHeight(2 * row + 1, 26)
            self.sliders[axis], self.lo_boxes[axis], self.hi_boxes[axis] = slider, lo, hi
            b = self.bindings
            b.connect_qt(slider.valueChanged, lambda v, a=axis: self._set_range(a, *v))
            b.connect_qt(lo.valueChanged,
                         lambda v, a=axis: self._set_range(a, v, self._current(a)[1]))
            b.connect_qt(hi.valueChanged,
                         lambda v, a=axis: self._set_range(a, self._current(a)[0], v))
        grid.setColumnStretch(0, 1)
        grid.setColumnStretch(1, 2)
        grid.setColumnStretch(3, 2)
        layout.addLayout(grid)
        self.reset_button = QPushButton("Reset ranges")
        self.reset_button.setObjectName("crop_reset")
        self.reset_button.setToolTip("Show the whole volume again")
        self.bindings.connect_qt(self.reset_button.clicked, self.reset)
        layout.addWidget(self.reset_button, 0, Qt.AlignmentFlag.AlignRight)
        # Pyramids (OME-Zarr, Imaris): load the crop box at a finer level, and back. The
        # window does the reading; the dock only asks (it edits the model and nothing else).
        self.refine_button = QPushButton("Refine selection")
        self.refine_button.setObjectName("crop_refine")
        self.refine_button.setToolTip("Load the crop region at the finest pyramid level that "
                                      "fits the GPU memory budget")
        self.overview_button = QPushButton("Back to overview")
        self.overview_button.setObjectName("crop_overview")
        self.overview_button.setToolTip("Show the whole pyramid again at the overview level, "
                                        "with the previous crop")
        self.bindings.connect_qt(self.refine_button.clicked, self.refineRequested.emit)
        self.bindings.connect_qt(self.overview_button.clicked, self.overviewRequested.emit)
        pyramid_row = QHBoxLayout()
        pyramid_row.addStretch(1)
        pyramid_row.addWidget(self.refine_button)
        pyramid_row.addWidget(self.overview_button)
        layout.addLayout(pyramid_row)
        self.set_pyramid_actions(False, False)
        layout.addWidget(hint_label(
            "Cropped-away parts are not drawn and cast no shadow: shadows and ambient "
            "occlusion are computed from the cropped volume."))
        layout.addStretch(1)
        self.set_body(body)

    # -- geometry -------------------------------------------------------------------------------
    def full_range(self, axis: str) -> tuple[float, float]:
        """Voxel-centre extent along ``axis`` in µm (0 … (n−1)·s), from the data."""
        if self.data is None:
            return (0.0, 1.0)
        n = self.data.shape_zyx[::-1]["xyz".index(axis)]
        size = self.data.voxel_size_um["xyz".index(axis)]
        return (0.0, float((n - 1) * size))

    def _step(self, axis: str) -> float:
        return float(self.data.voxel_size_um["xyz".index(axis)]) if self.data is not None else 0.01

    def _current(self, axis: str) -> tuple[float, float]:
        lo, hi = self.full_range(axis)
        value = getattr(self.model.crop, axis)
        return (max(lo, value[0]), min(hi, value[1])) if value is not None else (lo, hi)

    # -- model → widgets ------------------------------------------------------------------------
    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "crop"):
            self.refresh()

    def refresh(self) -> None:
        for axis in AXES:
            lo, hi = self.full_range(axis)
            usable = self.data is not None and hi > lo
            current = self._current(axis)
            step = self._step(axis)
            slider, lo_box, hi_box = self.sliders[axis], self.lo_boxes[axis], self.hi_boxes[axis]
            with signals_blocked(slider, lo_box, hi_box):
                for widget in (slider, lo_box, hi_box):
                    widget.setEnabled(usable)
                slider.setRange(lo, max(hi, lo + step))
                slider.setSingleStep(step)
                slider.setValue(current)
                decimals = um_decimals(step)
                for box, value in ((lo_box, current[0]), (hi_box, current[1])):
                    box.setDecimals(decimals)
                    box.setRange(lo, max(hi, lo + step))
                    box.setSingleStep(step)
                    box.setValue(value)

    # -- widgets → model ------------------------------------------------------------------------
    def _set_range(self, axis: str, lo: float, hi: float) -> None:
        full_lo, full_hi = self.full_range(axis)
        step = self._step(axis)
        lo, hi = max(full_lo, float(lo)), min(full_hi, float(hi))
        if hi - lo < step:  # keep at least one voxel: the crop box must not be empty
            self.refresh()
            return
        tolerance = 1e-6 * max(step, 1.0)
        value = None if lo <= full_lo + tolerance and hi >= full_hi - tolerance else (lo, hi)
        try:
            setattr(self.model.crop, axis, value)
        except ValueError:
            self.refresh()

    def set_pyramid_actions(self, can_refine: bool, can_go_back: bool) -> None:
        """Show the pyramid buttons only for multiscale data; enable what applies."""
        for button, enabled in ((self.refine_button, can_refine),
                                (self.overview_button, can_go_back)):
            button.setVisible(can_refine or can_go_back)
            button.setEnabled(enabled)

    def reset(self) -> None:
        """Uncrop all three axes (one undo step)."""
        self.model.crop.update({"x": None, "y": None, "z": None})
