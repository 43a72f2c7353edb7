"""Channels dock: per channel visibility, colour, contrast limits and TF link; the blending.

Edits ``model.channels[i]`` and ``model.render`` (blend mode, channel mixing, channel
lighting, isosurface value). Contrast limits are the transfer function's value span: changing
them stretches the TF's nodes (:meth:`~vtkvol.model.TransferFunction.rescale`); "Auto" sets
the limits a freshly opened channel gets (:func:`vtkvol.model.defaults.contrast_limits`:
background plus three robust standard deviations to the 99.9th percentile), so it agrees
with the first view.
"""

from __future__ import annotations

from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QFrame,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from vtkvol.model.defaults import contrast_limits
from vtkvol.model.evented import touches
from vtkvol.model.gamma import GAMMA_MAX, GAMMA_MIN
from vtkvol.model.scene import BLEND_MODES, Channel, SceneModel
from vtkvol.model.techniques import technique_specs
from vtkvol.model.transfer_function import above
from vtkvol.ui.binding import Bindings, signals_blocked
from vtkvol.ui.docks.base import ColorButton, ModelDock, hint_label, number_box

BLEND_LABELS = {
    "composite": "Composite (emission–absorption)",
    "mip": "Maximum intensity projection",
    "minip": "Minimum intensity projection",
    "average": "Average intensity",
    "additive": "Additive (sum)",
    "isosurface": "Isosurface",
}
MIXING_LABELS = {
    "additive": "Additive colours (VTK)",
    "composite": "Independent absorbers",
}
CHANNEL_LIGHTING_LABELS = {
    "per_channel": "Per channel (VTK)",
    "shared": "Shared (one lighting per sample)",
}
CHANNEL_LIGHTING_TIP = (
    "How several channels are lit. Per channel: VTK's, every channel with its own normal "
    "(exact). Shared: the channels' colours are mixed first and lit once per sample with the "
    "opacity-weighted normal of the channels — close to per channel (the same where one "
    "channel shows). Faster with several lights, cone tracing and translucency; with one "
    "light and local shading or the shadow volume about the same cost. Shaded composite "
    "blending only")
CHANNEL_LIGHTING_MEDIUM_TIP = (
    " · The current technique lights a scattering medium (no normals): shared lights the "
    "mixed colour once, which looks the same and costs less")
INTERPOLATION_LABELS = {
    "trilinear": "Trilinear",
    "corrected": "Corrected trilinear (sharper)",
    "nearest": "Nearest voxel (label images)",
}


def retint(colors: list[tuple[float, float, float, float]], old: tuple[float, float, float],
           new: tuple[float, float, float]) -> list[tuple[float, float, float, float]]:
    """Recolour TF nodes made from tint ``old`` as shades of ``new``: each node keeps its
    brightness relative to the old tint (so a dark-to-bright ramp stays one)."""
    reference = max(max(old), 1e-6)
    out = []
    for value, r, g, b in colors:
        brightness = min(max(r, g, b) / reference, 1.0)
        out.append((value, *(min(1.0, brightness * c) for c in new)))
    return out


class ChannelRow(QFrame):
    """The controls of one channel (built per channel, rebuilt when the list changes)."""

    def __init__(self, dock: ChannelsDock, index: int) -> None:
        super().__init__()
        self.dock = dock
        self.index = index
        self.bindings = Bindings()
        self.setFrameShape(QFrame.Shape.StyledPanel)
        channel = dock.model.channels[index]
        grid = QGridLayout(self)
        grid.setContentsMargins(6, 4, 6, 4)
        grid.setVerticalSpacing(3)

        self.visible = QCheckBox(channel.name)
        self.visible.setObjectName(f"channel_visible_{index}")
        self.visible.setToolTip("Show or hide this channel")
        self.color = ColorButton(f"Colour of {channel.name}")
        self.color.setObjectName(f"channel_color_{index}")
        self.link = QComboBox()
        self.link.setObjectName(f"channel_link_{index}")
        self.link.setToolTip("Use this channel's own transfer function, or follow another "
                             "channel's (edit one, both change)")
        # The same width in every row, whatever the other channels are called.
        self.link.setSizeAdjustPolicy(
            QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon)
        self.link.setMinimumContentsLength(14)
        self.link.addItem("Own TF", None)
        for j, other in enumerate(dock.model.channels):
            if j != index:
                self.link.addItem(f"TF of {other.name}", j)
        top = QHBoxLayout()
        top.addWidget(self.visible, 1)
        top.addWidget(self.link)
        top.addWidget(self.color)
        grid.addLayout(top, 0, 0, 1, 4)

        integer = dock.data is not None and dock.data.array.dtype.kind in "ui"
        decimals = 0 if integer else 3
        lo, hi = dock.value_range(index)
        tip = "Contrast limits: the data values the transfer function spans (its nodes stretch)"
        self.minimum = number_box(minimum=lo, maximum=hi, decimals=decimals, tooltip=tip,
                                  object_name=f"channel_min_{index}")
        self.maximum = number_box(minimum=lo, maximum=hi, decimals=decimals, tooltip=tip,
                                  object_name=f"channel_max_{index}")
        self.auto = QPushButton("Auto")
        self.auto.setObjectName(f"channel_auto_{index}")
        self.auto.setToolTip(
            "Contrast limits from the data, as when it was opened: from just above the "
            "background (its level plus three standard deviations of its noise) to the "
            "99.9th percentile of this channel")
        self.auto.setEnabled(dock.data is not None)
        grid.addWidget(QLabel("Contrast"), 1, 0)
        grid.addWidget(self.minimum, 1, 1)
        grid.addWidget(self.maximum, 1, 2)
        grid.addWidget(self.auto, 1, 3)
        grid.setColumnStretch(1, 1)
        grid.setColumnStretch(2, 1)
        self.gamma = number_box(
            minimum=GAMMA_MIN, maximum=GAMMA_MAX, decimals=2, step=0.05,
            object_name=f"channel_gamma_{index}",
            tooltip="Gamma on the values between the contrast limits: below 1 brightens the "
                    "mid-tones, above 1 darkens them; the limits themselves stay as they are "
                    "(as napari's and Fiji's gamma). Not for label images")
        grid.addWidget(QLabel("Gamma"), 2, 0)
        grid.addWidget(self.gamma, 2, 1)

        b = self.bindings
        b.bind(channel, "visible", self.visible, self.visible.toggled, self.visible.setChecked)
        b.attr_to_setter(channel, "color", self.color, self.color.set_rgb)
        b.connect_qt(self.color.colorPicked, self._on_color)
        b.attr_to_setter(channel, "tf_linked_to", self.link, self._show_link)
        b.connect_qt(self.link.currentIndexChanged, self._on_link)
        b.connect_qt(self.minimum.valueChanged, lambda v: self._set_limits(v, None))
        b.connect_qt(self.maximum.valueChanged, lambda v: self._set_limits(None, v))
        b.connect_qt(self.auto.clicked, self.auto_contrast)
        b.bind(channel, "gamma", self.gamma, self.gamma.valueChanged, self.gamma.setValue,
               to_model=float)
        b.attr_to_setter(channel, "labels", (self.gamma, self.minimum, self.maximum, self.auto),
                         lambda _: self._show_link(self.channel.tf_linked_to))
        self._show_limits()

    @property
    def channel(self) -> Channel:
        return self.dock.model.channels[self.index]

    def _tf(self):
        channel, channels = self.channel, self.dock.model.channels
        link = channel.tf_linked_to
        if link is not None and 0 <= link < len(channels) and link != self.index:
            return channels[link].tf
        return channel.tf

    def _show_link(self, link: int | None) -> None:
        position = self.link.findData(link)
        self.link.setCurrentIndex(max(position, 0))
        linked = link is not None
        # A label channel's values are ids: no contrast limits, no gamma (the Labels dock).
        labels = self.channel.labels is not None
        for widget in (self.minimum, self.maximum, self.auto):
            has_data = widget is not self.auto or self.dock.data is not None
            widget.setEnabled(not linked and has_data and not labels)
        self.gamma.setEnabled(not labels)

    def _on_link(self, position: int) -> None:
        self.channel.tf_linked_to = self.link.itemData(position)

    def show_limits(self) -> None:
        """Show the (possibly linked) TF's value span as the contrast limits."""
        self._show_limits()

    def _show_limits(self) -> None:
        lo, hi = self._tf().value_span
        with signals_blocked(self.minimum, self.maximum):
            for box, value in ((self.minimum, lo), (self.maximum, hi)):
                box.setMinimum(min(box.minimum(), value))
                box.setMaximum(max(box.maximum(), value))
                box.setValue(value)

    def _set_limits(self, lo: float | None, hi: float | None) -> None:
        tf = self._tf()
        span_lo, span_hi = tf.value_span
        lo = span_lo if lo is None else lo
        hi = span_hi if hi is None else hi
        if not hi > lo:
            self._show_limits()
            return
        tf.rescale(lo, hi)

    def auto_contrast(self) -> None:
        """The contrast limits a freshly opened channel gets (the same rule, so Auto after an
        edit returns to the first view's contrast)."""
        data = self.dock.data
        if data is None:
            return
        lo, hi = contrast_limits(data, min(self.index, data.n_channels - 1))
        if hi > lo:
            self._tf().rescale(lo, hi)

    def _on_color(self, rgb: tuple[float, float, float]) -> None:
        channel = self.channel
        with channel.batch():
            # A label channel keeps its categorical colours: the tint is only the list's.
            if channel.tf_linked_to is None and channel.labels is None:
                channel.tf.colors = retint(channel.tf.colors, channel.color, rgb)
            channel.color = rgb

    def release(self) -> None:
        self.bindings.clear()


class ChannelsDock(ModelDock):
    """Per-channel rows plus the blending controls."""

    TITLE = "Channels"
    OBJECT_NAME = "dock_channels"

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(model, parent)
        self.rows: list[ChannelRow] = []
        self._build()
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    def _build(self) -> None:
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.setContentsMargins(8, 6, 8, 8)
        self.rows_box = QVBoxLayout()
        self.rows_box.setSpacing(4)
        layout.addLayout(self.rows_box)

        form = QFormLayout()
        form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        self.blend = QComboBox()
        self.blend.setObjectName("render_blend_mode")
        self.blend.setToolTip("How samples along a ray combine into a pixel")
        for mode in BLEND_MODES:
            self.blend.addItem(BLEND_LABELS.get(mode, mode), mode)
        form.addRow("Blending", self.blend)
        self.mixing = QComboBox()
        self.mixing.setObjectName("render_channel_mixing")
        self.mixing.setToolTip(
            "How channels combine at one sample: VTK's opacity-weighted colour mix, or "
            "independent absorbers (opacity 1 − Π(1 − αᵢ))")
        for mode, label in MIXING_LABELS.items():
            self.mixing.addItem(label, mode)
        self.mixing_label = QLabel("Channel mixing")
        form.addRow(self.mixing_label, self.mixing)
        self.channel_lighting = QComboBox()
        self.channel_lighting.setObjectName("render_multichannel_lighting")
        self.channel_lighting.setToolTip(CHANNEL_LIGHTING_TIP)
        for mode, label in CHANNEL_LIGHTING_LABELS.items():
            self.channel_lighting.addItem(label, mode)
        self.channel_lighting_label = QLabel("Channel lighting")
        form.addRow(self.channel_lighting_label, self.channel_lighting)
        self.interpolation = QComboBox()
        self.interpolation.setObjectName("render_interpolation")
        self.interpolation.setToolTip(
            "How values between voxels are reconstructed along each ray: trilinear, or "
            "Csébfalvi's corrected trilinear (close to tricubic Catmull-Rom; composite blending "
            "only; costs little with shading, more without)")
        for mode, label in INTERPOLATION_LABELS.items():
            self.interpolation.addItem(label, mode)
        form.addRow("Interpolation", self.interpolation)
        self.skip_empty = QCheckBox("Skip empty space")
        self.skip_empty.setObjectName("render_empty_space_skipping")
        self.skip_empty.setToolTip(
            "Rays jump over 8³-voxel bricks the transfer function, crop and slice weights make "
            "fully transparent. Exact (the image does not change); faster on sparse data. "
            "Composite, additive and (with opacity rising with the value) MIP blending")
        form.addRow("", self.skip_empty)
        self.preintegration = QCheckBox("Pre-integrated classification")
        self.preintegration.setObjectName("render_preintegration")
        self.preintegration.setToolTip(
            "Each sample classifies the segment from the previous sample (a table of the "
            "transfer function integrated over the sample distance), so narrow opacity peaks "
            "are not stepped over at coarse sample distances. One to four channels, composite "
            "blending")
        form.addRow("", self.preintegration)
        self.adaptive = QCheckBox("Adaptive sampling")
        self.adaptive.setObjectName("render_adaptive_sampling")
        self.adaptive.setToolTip(
            "Larger steps (one sample for four) in 8³-voxel bricks where the transfer "
            "function's opacity is smooth, every step elsewhere: faster, close to the "
            "fixed-step image. One channel, composite blending; not with pre-integration")
        form.addRow("", self.adaptive)
        self.iso = number_box(minimum=-1e9, maximum=1e9, decimals=1, object_name="render_iso_value",
                              tooltip="Data value of the isosurface")
        self.iso_auto = QPushButton("Auto")
        self.iso_auto.setObjectName("render_iso_auto")
        self.iso_auto.setToolTip("Isosurface at the middle of the first channel's contrast limits")
        iso_row = QHBoxLayout()
        iso_row.addWidget(self.iso, 1)
        iso_row.addWidget(self.iso_auto)
        self.iso_label = QLabel("Isovalue")
        self.iso_row = QWidget()
        self.iso_row.setLayout(iso_row)
        iso_row.setContentsMargins(0, 0, 0, 0)
        form.addRow(self.iso_label, self.iso_row)
        layout.addLayout(form)
        layout.addWidget(hint_label("Contrast limits stretch the transfer function; edit its "
                                    "shape in the Transfer function dock."))
        layout.addStretch(1)
        self.set_body(body)

        render = self.model.render
        b = self.bindings
        b.bind(render, "blend_mode", self.blend, self.blend.currentIndexChanged,
               lambda mode: self.blend.setCurrentIndex(self.blend.findData(mode)),
               to_model=lambda i: self.blend.itemData(i))
        b.bind(render, "channel_mixing", self.mixing, self.mixing.currentIndexChanged,
               lambda mode: self.mixing.setCurrentIndex(self.mixing.findData(mode)),
               to_model=lambda i: self.mixing.itemData(i))
        b.bind(render, "multichannel_lighting", self.channel_lighting,
               self.channel_lighting.currentIndexChanged,
               lambda mode: self.channel_lighting.setCurrentIndex(
                   self.channel_lighting.findData(mode)),
               to_model=lambda i: self.channel_lighting.itemData(i))
        b.bind(render, "interpolation", self.interpolation,
               self.interpolation.currentIndexChanged,
               lambda mode: self.interpolation.setCurrentIndex(
                   self.interpolation.findData(mode)),
               to_model=lambda i: self.interpolation.itemData(i))
        b.bind(render, "empty_space_skipping", self.skip_empty, self.skip_empty.toggled,
               lambda on: self.skip_empty.setChecked(bool(on)))
        b.bind(render, "preintegration", self.preintegration, self.preintegration.toggled,
               lambda on: self.preintegration.setChecked(bool(on)))
        b.bind(render, "adaptive_sampling", self.adaptive, self.adaptive.toggled,
               lambda on: self.adaptive.setChecked(bool(on)))
        b.connect_qt(self.iso.valueChanged, self._on_iso)
        b.connect_qt(self.iso_auto.clicked, lambda: setattr(self.model.render,
                                                             "isosurface_value", None))

    def value_range(self, index: int) -> tuple[float, float]:
        """How far the contrast limits may go: the data's range (widened to the TF's)."""
        tf = self.model.channels[index].tf
        lo, hi = tf.window_range
        if self.data is not None and index < self.data.n_channels:
            dlo, dhi = self.data.channel_range(index)
            lo, hi = min(lo, dlo), max(hi, dhi)
        return lo, hi if hi > lo else above(lo)

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        # A new list or a renamed channel changes the rows themselves, not just their values.
        renamed = touches(paths, "channels", "name")
        if "channels" in paths or renamed or len(self.rows) != len(self.model.channels):
            self.refresh()
            return
        if touches(paths, "channels", "tf"):
            # Any TF may be the one a linked channel follows: update every row's limits.
            for row in self.rows:
                row.show_limits()
        if (touches(paths, "render") or touches(paths, "channels", "tf")
                or touches(paths, "illumination", "method")):
            self._refresh_render()

    def refresh(self) -> None:
        for row in self.rows:
            row.release()
            self.rows_box.removeWidget(row)
            row.hide()  # gone now, not when the event loop gets round to deleting it
            row.deleteLater()
        self.rows = [ChannelRow(self, i) for i in range(len(self.model.channels))]
        for row in self.rows:
            self.rows_box.addWidget(row)
            row.show()  # now, not when the event loop gets round to it
        self._refresh_render()

    def _refresh_render(self) -> None:
        render = self.model.render
        several = len(self.model.channels) > 1
        self.mixing.setVisible(several)
        self.mixing_label.setVisible(several)
        # Lighting is shared between channels only where there are several.
        self.channel_lighting.setVisible(several)
        self.channel_lighting_label.setVisible(several)
        self.channel_lighting.setEnabled(render.blend_mode == "composite")
        spec = technique_specs().get(self.model.illumination.method)
        medium = spec is not None and spec.lighting == "medium"
        self.channel_lighting.setToolTip(
            CHANNEL_LIGHTING_TIP + (CHANNEL_LIGHTING_MEDIUM_TIP if medium else ""))
        iso = render.blend_mode == "isosurface"
        self.iso_row.setVisible(iso)
        self.iso_label.setVisible(iso)
        value = render.isosurface_value
        if value is None:
            lo, hi = self.model.channels[0].tf.value_span
            value = 0.5 * (lo + hi)
        with signals_blocked(self.iso):
            self.iso.setValue(value)

    def _on_iso(self, value: float) -> None:
        self.model.render.isosurface_value = float(value)

    def release(self) -> None:
        for row in self.rows:
            row.release()
        super().release()
