"""The Lights dock's widgets (:class:`~vtkvol.ui.docks.lights.LightsDock` binds them to the
model): the light list and editor, exposure and fill, and the illumination method's box.

They hold no model and write nothing: each is a plain arrangement of widgets whose values
the dock sets and reads.
"""

from __future__ import annotations

from collections.abc import Mapping

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from vtkvol.model.renderers import RENDERERS
from vtkvol.model.scene import MAX_ANGULAR_RADIUS
from vtkvol.model.techniques import TechniqueSpec
from vtkvol.ui.docks.base import ColorButton, hint_label, number_box

MAX_LIGHTS = 4
#: Narrowest number box (px): wide ranges (±10⁶ µm) would otherwise size the dock past its
#: default width.
NUMBER_WIDTH = 70
#: Item data of the method chooser's Auto entry (not a technique name: those are identifiers).
AUTO_CHOICE = ":auto"
#: What the renderer chooser shows, and each choice's tooltip where it is available.
RENDERER_LABELS = {"raycast": "Ray caster (with the method)", "path_tracer": "Path tracer",
                   "half_angle": "Half-angle slicing", "slicing": "View-aligned slicing"}
RENDERER_TIPS = {
    "raycast": "VTK's GPU ray caster, lit by the illumination method",
    "path_tracer": "Progressive camera path tracer of the medium material (albedo, g) and "
                   "the lights; refines over frames, restarts when the view or scene changes",
    "half_angle": "Half-angle slicing (seed 001, Kniss): one light, direct plus blurred, "
                  "colour-shifted indirect light of the medium material; refines over 8 "
                  "jittered frames",
    "slicing": "View-aligned slices composited front to back, local lighting",
}


class LightEditor(QGroupBox):
    """The light list (tick: on; select: edit), Add / Remove, and the selected light's kind,
    direction (azimuth and elevation in degrees) or position (µm), colour, intensity, size
    (degrees) and fall-off."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Lights", parent)
        lights_layout = QVBoxLayout(self)
        self.light_list = QListWidget()
        self.light_list.setObjectName("lights_list")
        self.light_list.setToolTip("Tick to switch a light on; select one to edit it and to "
                                   "move it with the handle in the 3-D view")
        lights_layout.addWidget(self.light_list)
        row = QHBoxLayout()
        self.add_button = QPushButton("Add")
        self.add_button.setObjectName("lights_add")
        self.add_button.setToolTip(f"Add a light (at most {MAX_LIGHTS})")
        self.remove_button = QPushButton("Remove")
        self.remove_button.setObjectName("lights_remove")
        self.remove_button.setToolTip("Remove the selected light (one light always remains)")
        row.addWidget(self.add_button)
        row.addWidget(self.remove_button)
        row.addStretch(1)
        lights_layout.addLayout(row)

        form = QFormLayout()
        form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        self.kind = QComboBox()
        self.kind.setObjectName("light_kind")
        self.kind.addItem("Directional", "directional")
        self.kind.addItem("Point", "point")
        self.kind.setToolTip("Directional: parallel light from far away. Point: light from a "
                             "position in the scene")
        form.addRow("Kind", self.kind)
        self.azimuth = number_box(minimum=-180, maximum=180, decimals=1, step=5, suffix="°",
                                  object_name="light_azimuth",
                                  tooltip="Direction towards the light in the x–y plane, "
                                          "from +x towards +y")
        self.elevation = number_box(minimum=-90, maximum=90, decimals=1, step=5, suffix="°",
                                    object_name="light_elevation",
                                    tooltip="Height of the light above the x–y plane (+z up)")
        self.azimuth.setWrapping(True)
        self.azimuth_label, self.elevation_label = QLabel("Azimuth"), QLabel("Elevation")
        form.addRow(self.azimuth_label, self.azimuth)
        form.addRow(self.elevation_label, self.elevation)
        # One row per axis, in the rows azimuth and elevation use for a directional light:
        # three boxes side by side do not fit the dock's width.
        self.position_boxes = []
        self.position_labels = []
        for axis in "xyz":
            box = number_box(minimum=-1e6, maximum=1e6, decimals=2, step=1, suffix="µm",
                             object_name=f"light_pos_{axis}",
                             tooltip=f"{axis} position of the point light (µm)")
            box.setMinimumWidth(NUMBER_WIDTH)
            label = QLabel(f"Position {axis}")
            self.position_boxes.append(box)
            self.position_labels.append(label)
            form.addRow(label, box)
        self.color = ColorButton("Light colour")
        self.color.setObjectName("light_color")
        self.intensity = number_box(minimum=0, maximum=100, decimals=2, step=0.1,
                                    object_name="light_intensity",
                                    tooltip="Brightness multiplier of the light (1 = nominal)")
        self.intensity.setMinimumWidth(NUMBER_WIDTH)
        color_row = QHBoxLayout()
        color_row.addWidget(self.color)
        color_row.addWidget(QLabel("Intensity"))
        color_row.addWidget(self.intensity, 1)
        form.addRow("Colour", color_row)
        # Not ``size``: that is QWidget.size().
        self.size_box = number_box(minimum=0, maximum=MAX_ANGULAR_RADIUS, decimals=2, step=0.25,
                               suffix="°", object_name="light_size",
                               tooltip="The light's physical size, which sets how soft its "
                                       "shadows are: angular radius for a directional light "
                                       "(the sun: 0.27°), radius for a point light; 0 = ideal")
        self.falloff = QCheckBox("Inverse-square fall-off")
        self.falloff.setObjectName("light_falloff")
        self.falloff.setToolTip("Point light: brightness falls with the squared distance "
                                "(the intensity is the brightness at the volume's centre)")
        self.size_box.setMinimumWidth(NUMBER_WIDTH)
        form.addRow("Size", self.size_box)
        form.addRow("", self.falloff)
        lights_layout.addLayout(form)


class ExposureBox(QGroupBox):
    """Exposure and fill (render settings): how bright the lit view is, for every method."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Exposure", parent)
        exposure_form = QFormLayout(self)
        self.exposure = number_box(minimum=0.05, maximum=16, decimals=2, step=0.1, suffix="×",
                                   object_name="render_exposure",
                                   tooltip="Brightness factor on the lit colour (1 = as lit). "
                                           "With Automatic on, it multiplies the automatic "
                                           "factor")
        self.auto_exposure = QCheckBox("Automatic")
        self.auto_exposure.setObjectName("render_auto_exposure")
        self.auto_exposure.setToolTip(
            "Shadows and ambient occlusion take light away: keep the view about as bright as "
            "with local shading (the exposure rises, at most 4×; shadowed parts stay darker)")
        self.fill = number_box(minimum=0, maximum=1, decimals=2, step=0.05,
                               object_name="render_fill",
                               tooltip="Sky fill: light from all around that no shadow or "
                                       "occlusion takes away, so shadowed parts are not black "
                                       "(0 = none)")
        exposure_form.addRow("Exposure", self.exposure)
        exposure_form.addRow("", self.auto_exposure)
        exposure_form.addRow("Fill light", self.fill)


class IlluminationBox(QGroupBox):
    """The illumination method chooser (Auto first, then ``techniques``), what draws the
    volume, Auto's error budget and status, the method's description, the medium material,
    the method's parameter form (filled by the dock) and Defaults."""

    def __init__(self, techniques: Mapping[str, TechniqueSpec],
                 parent: QWidget | None = None) -> None:
        super().__init__("Illumination", parent)
        method_layout = QVBoxLayout(self)
        self.method = QComboBox()
        self.method.setObjectName("illum_method")
        self.method.addItem("Auto (cheapest within the error budget)", AUTO_CHOICE)
        self.method.setItemData(0, "Let vtkvol pick the cheapest method whose predicted image "
                                   "error meets the budget below, and pick again when the "
                                   "data, a transfer function or a light changes",
                                Qt.ItemDataRole.ToolTipRole)
        for name, spec in techniques.items():
            self.method.addItem(spec.label, name)
            self.method.setItemData(self.method.count() - 1, spec.description,
                                    Qt.ItemDataRole.ToolTipRole)
        method_layout.addWidget(self.method)
        # What draws the volume: VTK's ray caster (with the method) or a renderer beside it;
        # combinations a renderer cannot draw are greyed, the reason in the item's tooltip.
        renderer_row = QFormLayout()
        renderer_row.setContentsMargins(0, 0, 0, 0)
        self.renderer = QComboBox()
        self.renderer.setObjectName("render_renderer")
        for name in RENDERERS:
            self.renderer.addItem(RENDERER_LABELS[name], name)
        renderer_row.addRow("Drawn by", self.renderer)
        method_layout.addLayout(renderer_row)
        # Auto: its error budget and what it picked, and why.
        self.auto_box = QWidget()
        auto_column = QVBoxLayout(self.auto_box)
        auto_column.setContentsMargins(0, 0, 0, 0)
        auto_layout = QFormLayout()
        auto_column.addLayout(auto_layout)
        self.auto_budget = number_box(
            minimum=0.5, maximum=1.0, decimals=3, step=0.005, object_name="illum_auto_budget",
            tooltip="Error budget: the smallest predicted SSIM (structural similarity, 1 = "
                    "identical) of the image against the reference lighting that Auto accepts")
        auto_layout.addRow("Error budget: SSIM ≥", self.auto_budget)
        self.auto_status = QLabel("")
        self.auto_status.setObjectName("illum_auto_status")
        self.auto_status.setWordWrap(True)
        # In the column, not a form row: a form row does not grow for wrapped lines.
        auto_column.addWidget(self.auto_status)
        method_layout.addWidget(self.auto_box)
        self.description = hint_label("")
        method_layout.addWidget(self.description)
        # The medium lighting model's material (render settings, shared by medium methods).
        self.material_box = QWidget()
        material = QFormLayout(self.material_box)
        material.setContentsMargins(0, 0, 0, 0)
        self.albedo = number_box(minimum=0, maximum=1, decimals=2, step=0.05,
                                 object_name="medium_albedo",
                                 tooltip="Single-scattering albedo: the share of extinguished "
                                         "light that is scattered rather than absorbed")
        self.phase_g = number_box(minimum=-0.99, maximum=0.99, decimals=2, step=0.05,
                                  object_name="medium_phase_g",
                                  tooltip="Henyey–Greenstein asymmetry: 0 scatters equally in "
                                          "all directions, > 0 forwards, < 0 backwards")
        material.addRow("Scattering albedo", self.albedo)
        material.addRow("Phase asymmetry g", self.phase_g)
        method_layout.addWidget(self.material_box)
        # The parameters are part of the dock's body, which scrolls as a whole: a scroll area
        # of its own would show them a few rows at a time inside the scrolling dock.
        self.param_form_host = QWidget()
        self.param_form = QFormLayout(self.param_form_host)
        self.param_form.setContentsMargins(0, 0, 0, 0)
        self.param_form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        method_layout.addWidget(self.param_form_host)
        self.reset_params = QPushButton("Defaults")
        self.reset_params.setObjectName("illum_defaults")
        self.reset_params.setToolTip("Set this method's parameters to their declared defaults")
        method_layout.addWidget(self.reset_params, 0, Qt.AlignmentFlag.AlignRight)
