"""Lights dock: the lights, and the illumination method with its parameters.

* Lights (``model.lights``, up to four): add, remove, enable; kind (directional or point),
  direction as azimuth/elevation in degrees or position in µm, colour, intensity. The light
  selected here is the one the 3-D view's gizmo moves (``currentLightChanged``).
* Illumination (``model.illumination``): the method chooser lists **Auto** and the installed
  techniques (``vtkvol.model.techniques.technique_specs``, no VTK); each technique's
  parameters become widgets generated from its ``PARAMETERS`` declaration, with the declared
  range, step, unit, scale and doc (as the tooltip). Nothing about a parameter is written
  here. Auto sets ``illumination.auto`` and shows its error budget; the method it picked
  (``ui/auto_quality.py`` writes it into the model) is shown with its parameters read-only,
  and :meth:`LightsDock.show_auto_status` shows what was picked and why. Picking a method
  leaves Auto.

Direction convention: azimuth is measured in the x–y plane from +x towards +y, elevation
from that plane towards +z; the direction points from the volume towards the light.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from vtkvol.model.evented import touches
from vtkvol.model.params import Param
from vtkvol.model.renderers import RENDERERS
from vtkvol.model.scene import MAX_ANGULAR_RADIUS, Light, SceneModel, model_unsupported_reason
from vtkvol.model.techniques import TechniqueSpec, technique_specs
from vtkvol.ui.binding import signals_blocked
from vtkvol.ui.docks.base import ColorButton, ModelDock, hint_label, number_box

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

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

MAX_LIGHTS = 4
SLIDER_STEPS = 1000  #: resolution of the sliders next to float parameters
#: Narrowest number box (px): wide ranges (±10⁶ µm) would otherwise size the dock past its
#: default width.
NUMBER_WIDTH = 70
#: A new point light's distance from the data's centre, in half-diagonals of its box: just
#: outside the data, where the view (framed on the data) still shows its handle.
POINT_LIGHT_DISTANCE = 1.05
#: Item data of the method chooser's Auto entry (not a technique name: those are identifiers).
AUTO_CHOICE = ":auto"


# -- direction <-> angles (pure) ----------------------------------------------------------------
def direction_to_angles(direction: tuple[float, float, float]) -> tuple[float, float]:
    """(azimuth, elevation) in degrees of a direction vector (need not be unit length)."""
    x, y, z = direction
    norm = math.sqrt(x * x + y * y + z * z) or 1.0
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, z / norm))))
    azimuth = math.degrees(math.atan2(y, x)) if abs(x) + abs(y) > 1e-12 else 0.0
    return azimuth, elevation


def angles_to_direction(azimuth: float, elevation: float) -> tuple[float, float, float]:
    """Unit direction for azimuth/elevation in degrees (see the module docstring)."""
    az, el = math.radians(azimuth), math.radians(elevation)
    return (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))


def point_light_position(direction: tuple[float, float, float],
                         data: VolumeData) -> tuple[float, float, float]:
    """Where a point light goes when a light becomes one: from the data's centre along
    ``direction`` (towards the light), :data:`POINT_LIGHT_DISTANCE` half-diagonals of the
    data's box (voxel centres, µm) away."""
    z, y, x = data.shape_zyx
    extent = [(n - 1) * s for n, s in zip((x, y, z), data.voxel_size_um, strict=True)]
    centre = [0.5 * e for e in extent]
    half_diagonal = 0.5 * math.sqrt(sum(e * e for e in extent)) or 1.0
    norm = math.sqrt(sum(c * c for c in direction)) or 1.0
    return tuple(c + POINT_LIGHT_DISTANCE * half_diagonal * d / norm  # type: ignore[return-value]
                 for c, d in zip(centre, direction, strict=True))


# -- parameter widgets generated from Param declarations ------------------------------------------
def param_label(param: Param) -> str:
    """``"Shadow cone angle (°)"``: the declared label with its unit."""
    return f"{param.label} ({param.unit})" if param.unit else param.label


def param_tooltip(param: Param) -> str:
    """The declared doc, plus range, default and scale, for the widget's tooltip."""
    parts = [param.doc]
    unit = f" {param.unit}" if param.unit else ""
    if param.range is not None:
        parts.append(f"Range {param.range[0]:g}…{param.range[1]:g}{unit}; default "
                     f"{param.default}{unit}.")
    elif param.kind == "choice":
        names = ", ".join(param.choice_label(c) for c in param.choices)
        parts.append(f"One of {names}; default {param.choice_label(param.default)}.")
    else:
        parts.append(f"Default {param.default}.")
    if param.scale == "log":
        parts.append("Logarithmic slider.")
    return "\n".join(parts)


class ChoiceCombo(QComboBox):
    """A combo box of declared choices: shows labels, emits the chosen identifier."""

    choiceChanged = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.currentIndexChanged.connect(self._emit)

    def _emit(self, index: int) -> None:
        value = self.itemData(index)
        if value is not None:
            self.choiceChanged.emit(str(value))


class FloatParamWidget(QWidget):
    """A slider (linear or logarithmic, as declared) with a spin box for a float parameter."""

    valueChanged = Signal(float)

    def __init__(self, param: Param, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.param = param
        lo, hi = param.range if param.range is not None else (0.0, 1.0)
        self._lo, self._hi = float(lo), float(hi)
        self._log = param.scale == "log" and self._lo > 0
        step = param.step or (self._hi - self._lo) / 100
        decimals = max(0, min(6, -math.floor(math.log10(step)) if step < 1 else 0))
        self.spin = number_box(minimum=self._lo, maximum=self._hi, decimals=decimals, step=step,
                               suffix=param.unit)
        self.spin.setMinimumWidth(84)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, SLIDER_STEPS)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.slider, 1)
        layout.addWidget(self.spin)
        self.slider.valueChanged.connect(self._from_slider)
        self.spin.valueChanged.connect(self._from_spin)

    def _to_slider(self, value: float) -> int:
        if self._log:
            t = math.log(max(value, self._lo) / self._lo) / math.log(self._hi / self._lo)
        else:
            t = (value - self._lo) / (self._hi - self._lo) if self._hi > self._lo else 0.0
        return round(min(max(t, 0.0), 1.0) * SLIDER_STEPS)

    def _from_t(self, t: float) -> float:
        if self._log:
            return self._lo * (self._hi / self._lo) ** t
        return self._lo + t * (self._hi - self._lo)

    def _snap(self, value: float) -> float:
        step = self.param.step
        if step:
            value = self._lo + round((value - self._lo) / step) * step
        return min(max(value, self._lo), self._hi)

    def _from_slider(self, position: int) -> None:
        value = self._snap(self._from_t(position / SLIDER_STEPS))
        with signals_blocked(self.spin):
            self.spin.setValue(value)
        self.valueChanged.emit(self.spin.value())

    def _from_spin(self, value: float) -> None:
        with signals_blocked(self.slider):
            self.slider.setValue(self._to_slider(value))
        self.valueChanged.emit(float(value))

    def setValue(self, value: float) -> None:  # Qt-style name: used like a spin box
        with signals_blocked(self.spin, self.slider):
            self.spin.setValue(float(value))
            self.slider.setValue(self._to_slider(float(value)))

    def value(self) -> float:
        return float(self.spin.value())


def make_param_widget(param: Param) -> tuple[QWidget, Any, Callable[[Any], None]]:
    """A widget for one declared parameter: ``(widget, changed_signal, setter)``.

    float → slider + spin box (log slider for ``scale="log"``), int → spin box,
    bool → check box, choice → combo box. Range, step, unit and doc come from ``param``.
    """
    tooltip = param_tooltip(param)
    if param.kind == "bool":
        box = QCheckBox()
        box.setToolTip(tooltip)
        return box, box.toggled, lambda v: box.setChecked(bool(v))
    if param.kind == "choice":
        # The declared labels are shown; the stored value is the identifier (item data).
        combo = ChoiceCombo()
        for choice in param.choices:
            combo.addItem(param.choice_label(choice), choice)
        combo.setToolTip(tooltip)
        return combo, combo.choiceChanged, lambda v: combo.setCurrentIndex(
            max(0, combo.findData(str(v))))
    if param.kind == "int":
        spin = QSpinBox()
        lo, hi = param.range if param.range is not None else (-(2**31), 2**31 - 1)
        spin.setRange(int(lo), int(hi))
        spin.setSingleStep(int(param.step or 1))
        spin.setKeyboardTracking(False)
        if param.unit:
            spin.setSuffix(f" {param.unit}")
        spin.setToolTip(tooltip)
        return spin, spin.valueChanged, lambda v: spin.setValue(int(v))
    widget = FloatParamWidget(param)
    widget.setToolTip(tooltip)
    widget.spin.setToolTip(tooltip)
    widget.slider.setToolTip(tooltip)
    return widget, widget.valueChanged, lambda v: widget.setValue(float(v))


class LightsDock(ModelDock):
    """The light list and editor, and the illumination method with generated parameters."""

    TITLE = "Lights"
    OBJECT_NAME = "dock_lights"

    currentLightChanged = Signal(int)

    def __init__(self, model: SceneModel, parent: QWidget | None = None,
                 techniques: dict[str, TechniqueSpec] | None = None) -> None:
        super().__init__(model, parent)
        self.techniques = techniques if techniques is not None else technique_specs()
        self._current = 0
        self._param_setters: dict[str, Callable[[Any], None]] = {}
        self._param_widgets: dict[str, QWidget] = {}
        self._shown_method: str | None = None
        self._build()
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    # -- widgets --------------------------------------------------------------------------------
    def _build(self) -> None:
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.setContentsMargins(8, 6, 8, 8)

        lights_box = QGroupBox("Lights")
        lights_layout = QVBoxLayout(lights_box)
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
        self.size = number_box(minimum=0, maximum=MAX_ANGULAR_RADIUS, decimals=2, step=0.25,
                               suffix="°", object_name="light_size",
                               tooltip="The light's physical size, which sets how soft its "
                                       "shadows are: angular radius for a directional light "
                                       "(the sun: 0.27°), radius for a point light; 0 = ideal")
        self.falloff = QCheckBox("Inverse-square fall-off")
        self.falloff.setObjectName("light_falloff")
        self.falloff.setToolTip("Point light: brightness falls with the squared distance "
                                "(the intensity is the brightness at the volume's centre)")
        self.size.setMinimumWidth(NUMBER_WIDTH)
        form.addRow("Size", self.size)
        form.addRow("", self.falloff)
        lights_layout.addLayout(form)
        layout.addWidget(lights_box)

        # Exposure and fill (render settings): how bright the lit view is, for every method.
        exposure_box = QGroupBox("Exposure")
        exposure_form = QFormLayout(exposure_box)
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
        layout.addWidget(exposure_box)

        method_box = QGroupBox("Illumination")
        method_layout = QVBoxLayout(method_box)
        self.method = QComboBox()
        self.method.setObjectName("illum_method")
        self.method.addItem("Auto (cheapest within the error budget)", AUTO_CHOICE)
        self.method.setItemData(0, "Let vtkvol pick the cheapest method whose predicted image "
                                   "error meets the budget below, and pick again when the "
                                   "data, a transfer function or a light changes",
                                Qt.ItemDataRole.ToolTipRole)
        for name, spec in self.techniques.items():
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
        layout.addWidget(method_box)
        layout.addStretch(1)
        self.set_body(body)

        b = self.bindings
        b.connect_qt(self.light_list.currentRowChanged, self._on_row)
        b.connect_qt(self.light_list.itemChanged, self._on_item_changed)
        b.connect_qt(self.add_button.clicked, self.add_light)
        b.connect_qt(self.remove_button.clicked, self.remove_light)
        b.connect_qt(self.kind.currentIndexChanged,
                     lambda i: self._set_kind(self.kind.itemData(i)))
        b.connect_qt(self.azimuth.valueChanged, self._on_angles)
        b.connect_qt(self.elevation.valueChanged, self._on_angles)
        for box in self.position_boxes:
            b.connect_qt(box.valueChanged, self._on_position)
        b.connect_qt(self.color.colorPicked, lambda rgb: self._edit(color=tuple(rgb)))
        b.connect_qt(self.intensity.valueChanged, lambda v: self._edit(intensity=float(v)))
        b.connect_qt(self.size.valueChanged, lambda v: self._edit(size=float(v)))
        b.connect_qt(self.falloff.toggled,
                     lambda on: self._edit(falloff="inverse_square" if on else "none"))
        b.connect_qt(self.albedo.valueChanged,
                     lambda v: setattr(self.model.render, "albedo", float(v)))
        b.connect_qt(self.phase_g.valueChanged,
                     lambda v: setattr(self.model.render, "phase_g", float(v)))
        b.connect_qt(self.exposure.valueChanged,
                     lambda v: setattr(self.model.render, "exposure", float(v)))
        b.connect_qt(self.auto_exposure.toggled,
                     lambda on: setattr(self.model.render, "auto_exposure", bool(on)))
        b.connect_qt(self.fill.valueChanged,
                     lambda v: setattr(self.model.render, "fill", float(v)))
        b.connect_qt(self.method.currentIndexChanged, self._on_method)
        b.connect_qt(self.renderer.currentIndexChanged,
                     lambda i: setattr(self.model.render, "renderer", self.renderer.itemData(i)))
        b.connect_qt(self.auto_budget.valueChanged,
                     lambda v: setattr(self.model.illumination, "auto_budget_ssim", float(v)))
        b.connect_qt(self.reset_params.clicked, self._on_defaults)

    # -- lights ---------------------------------------------------------------------------------
    @property
    def current_light(self) -> int:
        return self._current

    def light(self) -> Light | None:
        lights = self.model.lights
        return lights[self._current] if 0 <= self._current < len(lights) else None

    def _edit(self, **values: Any) -> None:
        light = self.light()
        if light is None:
            return
        try:
            light.update(values)
        except ValueError:
            self._show_light()

    def _set_kind(self, kind: str) -> None:
        """Switch the light's kind; a new point light is placed where the directional light
        came from, just outside the data (not at a fixed position, off-screen for small data)."""
        light = self.light()
        if light is None:
            return
        if kind == "point" and light.kind != "point" and self.data is not None:
            self._edit(kind=kind, position=point_light_position(light.direction, self.data))
        else:
            self._edit(kind=kind)

    def _on_angles(self, _value: float) -> None:
        self._edit(direction=angles_to_direction(self.azimuth.value(), self.elevation.value()))

    def _on_position(self, _value: float) -> None:
        self._edit(position=tuple(float(b.value()) for b in self.position_boxes))

    def _on_row(self, row: int) -> None:
        if row < 0:
            return
        self._current = row
        self._show_light()
        self.currentLightChanged.emit(row)

    def _on_item_changed(self, item: QListWidgetItem) -> None:
        row = self.light_list.row(item)
        if 0 <= row < len(self.model.lights):
            self.model.lights[row].enabled = item.checkState() == Qt.CheckState.Checked

    def add_light(self) -> None:
        """Append a light (a copy of the selected one, turned 90° in azimuth)."""
        lights = self.model.lights
        if len(lights) >= MAX_LIGHTS:
            return
        base = self.light() or Light()
        azimuth, elevation = direction_to_angles(base.direction)
        new = base.model_copy(deep=True)
        new.direction = angles_to_direction(azimuth + 90.0, elevation)
        self._current = len(lights)
        self.model.lights = [*lights, Light.model_validate(new.model_dump())]

    def remove_light(self) -> None:
        """Remove the selected light; the last one stays (a scene needs one to shade)."""
        lights = self.model.lights
        if len(lights) <= 1 or not 0 <= self._current < len(lights):
            return
        remaining = [Light.model_validate(x.model_dump())
                     for i, x in enumerate(lights) if i != self._current]
        self._current = min(self._current, len(remaining) - 1)
        self.model.lights = remaining

    # -- illumination ---------------------------------------------------------------------------
    def technique(self) -> TechniqueSpec | None:
        return self.techniques.get(self.model.illumination.method)

    def _on_method(self, index: int) -> None:
        name = self.method.itemData(index)
        illumination = self.model.illumination
        if name == AUTO_CHOICE:
            illumination.auto = True
        elif name is not None:
            with self.model.batch():  # picking a method leaves Auto
                illumination.auto = False
                illumination.method = name

    def show_auto_status(self, text: str, details: str = "", *, warning: bool = False) -> None:
        """What Auto picked and why (``text``; ``details`` as the tooltip), or why it could
        not choose (``warning``: shown in the palette's link-visited colour, a second tone
        that every style has)."""
        self.auto_status.setText(text)
        self.auto_status.setToolTip(details or text)
        self.auto_status.setStyleSheet("color: palette(link-visited);" if warning else "")

    def _on_param(self, param: Param, value: Any) -> None:
        try:
            checked = param.validate(value)
        except ValueError:
            self._show_params()
            return
        self.model.illumination.set_value(param.name, checked)

    def _on_defaults(self) -> None:
        spec = self.technique()
        if spec is None:
            return
        illumination = self.model.illumination
        parameters = {k: dict(v) for k, v in illumination.parameters.items()}
        parameters[spec.name] = spec.defaults()
        illumination.parameters = parameters

    def param_widget(self, name: str) -> QWidget:
        """The generated widget of parameter ``name`` of the current method (tests, docs)."""
        return self._param_widgets[name]

    def _rebuild_params(self) -> None:
        while self.param_form.rowCount():
            self.param_form.removeRow(0)
        self._param_setters.clear()
        self._param_widgets.clear()
        spec = self.technique()
        self._shown_method = self.model.illumination.method
        if spec is None:
            self.description.setText(
                f"“{self.model.illumination.method}” is not installed here; its settings are "
                "kept in the session.")
            self.reset_params.setEnabled(False)
            return
        self.description.setText(spec.description)
        self.reset_params.setEnabled(bool(spec.parameters))
        if not spec.parameters:
            self.param_form.addRow(hint_label("This method has no parameters."))
        for param in spec.parameters:
            widget, signal, setter = make_param_widget(param)
            widget.setObjectName(f"param_{param.name}")
            label = QLabel(param_label(param))
            label.setToolTip(param_tooltip(param))
            self.param_form.addRow(label, widget)
            self.bindings.connect_qt(signal, lambda v, p=param: self._on_param(p, v))
            self._param_setters[param.name] = setter
            self._param_widgets[param.name] = widget
        self._show_params()

    def _show_params(self) -> None:
        spec = self.technique()
        if spec is None:
            return
        values = {**spec.defaults(), **self.model.illumination.values_for()}
        for param in spec.parameters:
            widget = self._param_widgets.get(param.name)
            if widget is None:
                continue
            with signals_blocked(widget):
                self._param_setters[param.name](values[param.name])
            # A parameter without effect under the other values (applies_when) is hidden.
            self.param_form.setRowVisible(widget, param.applies(values))

    # -- model → widgets ------------------------------------------------------------------------
    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "lights"):
            self._show_lights()
        if touches(paths, "illumination"):
            self._show_illumination()
        if touches(paths, "render", "albedo") or touches(paths, "render", "phase_g"):
            self._show_material()
        if touches(paths, "render") or touches(paths, "lights") or touches(paths,
                                                                           "illumination"):
            self._show_renderer()
        if any(touches(paths, "render", name) for name in ("exposure", "auto_exposure", "fill")):
            self._show_exposure()

    def refresh(self) -> None:
        self._show_lights()
        self._show_illumination()
        self._show_material()
        self._show_renderer()
        self._show_exposure()

    def _show_renderer(self) -> None:
        """The chosen renderer, each choice greyed with its reason where the scene's method,
        blend mode, lights or channels are not supported (vtkvol.model.renderers)."""
        items = self.renderer.model()
        with signals_blocked(self.renderer):
            for i in range(self.renderer.count()):
                name = self.renderer.itemData(i)
                reason = model_unsupported_reason(self.model, name)
                items.item(i).setEnabled(reason is None)
                self.renderer.setItemData(
                    i, RENDERER_TIPS[name] if reason is None else reason[0].upper() + reason[1:],
                    Qt.ItemDataRole.ToolTipRole)
            self.renderer.setCurrentIndex(self.renderer.findData(self.model.render.renderer))
        # The path tracer draws the medium material whatever the method.
        spec = self.technique()
        self.material_box.setVisible(self.model.render.renderer == "path_tracer" or (
            spec is not None and spec.lighting == "medium"))

    def _show_exposure(self) -> None:
        render = self.model.render
        with signals_blocked(self.exposure, self.auto_exposure, self.fill):
            self.exposure.setValue(render.exposure)
            self.auto_exposure.setChecked(render.auto_exposure)
            self.fill.setValue(render.fill)

    def _show_lights(self) -> None:
        lights = self.model.lights
        self._current = min(max(self._current, 0), len(lights) - 1)
        with signals_blocked(self.light_list):
            self.light_list.clear()
            for i, light in enumerate(lights):
                item = QListWidgetItem(
                    f"Light {i + 1} — {light.kind}, intensity {light.intensity:g}")
                item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
                item.setCheckState(
                    Qt.CheckState.Checked if light.enabled else Qt.CheckState.Unchecked)
                self.light_list.addItem(item)
            self.light_list.setCurrentRow(self._current)
        # As tall as its rows: the parameters below need the room more than empty list space.
        row = max(self.light_list.sizeHintForRow(0), self.fontMetrics().height() + 4)
        frame = 2 * self.light_list.frameWidth() + 2
        self.light_list.setFixedHeight(row * max(len(lights), 1) + frame)
        self.add_button.setEnabled(len(lights) < MAX_LIGHTS)
        self.remove_button.setEnabled(len(lights) > 1)
        self._show_light()
        self.currentLightChanged.emit(self._current)

    def _show_light(self) -> None:
        light = self.light()
        if light is None:
            return
        widgets = [self.kind, self.azimuth, self.elevation, self.intensity, self.size,
                   self.falloff, *self.position_boxes]
        point = light.kind == "point"
        with signals_blocked(*widgets):
            # A point light's size is a radius in µm, a directional light's an angle in °.
            self.size.setSuffix(" µm" if point else "°")
            self.size.setMaximum(1e6 if point else MAX_ANGULAR_RADIUS)
            self.size.setValue(light.size)
            self.falloff.setChecked(light.falloff == "inverse_square")
            self.kind.setCurrentIndex(self.kind.findData(light.kind))
            azimuth, elevation = direction_to_angles(light.direction)
            self.azimuth.setValue(azimuth)
            self.elevation.setValue(elevation)
            for box, value in zip(self.position_boxes, light.position, strict=True):
                box.setValue(value)
            self.intensity.setValue(light.intensity)
        self.color.set_rgb(light.color)
        self.falloff.setVisible(point)
        for w in (self.azimuth, self.elevation, self.azimuth_label, self.elevation_label):
            w.setVisible(not point)
        for w in (*self.position_boxes, *self.position_labels):
            w.setVisible(point)

    def _show_illumination(self) -> None:
        illumination = self.model.illumination
        method = illumination.method
        index = self.method.findData(method)
        with signals_blocked(self.method, self.auto_budget):
            if index < 0:  # a session's method that is not installed: show it, disabled
                self.method.addItem(f"{method} (not installed)", method)
                index = self.method.count() - 1
            self.method.setCurrentIndex(
                self.method.findData(AUTO_CHOICE) if illumination.auto else index)
            self.auto_budget.setValue(illumination.auto_budget_ssim)
        if method != self._shown_method:
            self._rebuild_params()
        else:
            self._show_params()
        spec = self.technique()
        self.material_box.setVisible(spec is not None and spec.lighting == "medium")
        # Under Auto the picked method's parameters are shown, not edited: Auto would
        # overwrite an edit at its next choice. Picking the method makes them editable.
        self.auto_box.setVisible(illumination.auto)
        self.param_form_host.setEnabled(not illumination.auto)
        self.material_box.setEnabled(not illumination.auto)
        self.reset_params.setEnabled(not illumination.auto and spec is not None
                                     and bool(spec.parameters))
        if not illumination.auto:
            self.show_auto_status("")

    def _show_material(self) -> None:
        render = self.model.render
        with signals_blocked(self.albedo, self.phase_g):
            for box, value in ((self.albedo, render.albedo), (self.phase_g, render.phase_g)):
                box.setValue(value)
