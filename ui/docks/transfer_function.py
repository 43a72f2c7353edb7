"""Transfer-function dock: colour and opacity of each channel over its data values.

Seed 002 §2.9–2.10 and seed 000 §5, on :class:`~vtkvol.model.TransferFunction`:

* the :class:`~vtkvol.ui.docks.function_editor.FunctionEditor` edits the opacity curve and
  the red, green and blue curves (points or freehand), over a displayed value window that can
  zoom into part of a 16-bit range, with the data's histogram (linear or log counts) behind;
* opacity can be shown on seed 002's log axis;
* presets (fluorescence, CT, matplotlib colormaps), load/save of one TF on its own, and a
  colour-bar preview on a checkerboard (double-click it to set a colour at a value).

Edits are written into the model (the engine re-renders from the model event); mouse drags
are throttled by the editor and grouped into one undo step through ``gestureStarted`` /
``gestureFinished``.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import ValidationError
from PySide6.QtWidgets import (
    QFileDialog,
    QHBoxLayout,
    QInputDialog,
    QStackedWidget,
    QWidget,
)

from vtkvol.io.atomic import write_atomic
from vtkvol.model import strict_json
from vtkvol.model.classification import (
    FeatureSample,
    classes_to_tf,
    feature_sample,
    histogram2d,
    spatialized_classes,
)
from vtkvol.model.evented import touches
from vtkvol.model.gradient import gradient_axis_max
from vtkvol.model.presets import apply_preset
from vtkvol.model.scene import SceneModel
from vtkvol.model.tf_paint import TFPaintLayer, apply_stroke, stroke_mask
from vtkvol.model.transfer_function import (
    TFPrimitive,
    TransferFunction,
    TransferFunction2D,
    above,
    paint_from_1d,
)
from vtkvol.ui import errors
from vtkvol.ui.binding import signals_blocked
from vtkvol.ui.docks import base as dock_base
from vtkvol.ui.docks.base import ModelDock
from vtkvol.ui.docks.function_editor import format_value
from vtkvol.ui.docks.tf_1d_page import CURVES, TF1DPage
from vtkvol.ui.docks.tf_2d_page import TF2DPage
from vtkvol.ui.docks.tf_controls import ASK_COLORMAP, DIMENSIONS, TFControls

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

TF_FILE_FORMAT = "vtkvol-transfer-function"
TF_FILE_VERSION = 1
TF_FILE_FILTER = "Transfer function (*.tf.json);;JSON (*.json)"
HISTOGRAM_BINS = 256
HISTOGRAM_SAMPLE = 1_000_000  #: voxels per channel the histogram is computed from (strided)
HISTOGRAM_2D_BINS = (96, 192)  #: gradient × value bins of the 2-D editor's histogram


# -- pure helpers (unit-tested) ------------------------------------------------------------------
def merge_color_curve(
    colors: list[tuple[float, float, float, float]],
    component: int,
    points: list[tuple[float, float]],
) -> list[tuple[float, float, float, float]]:
    """Replace one colour component's curve (0 red, 1 green, 2 blue) and re-join the three
    into ``(value, r, g, b)`` nodes.

    Nodes are placed at every x any component has, each component interpolated there, so
    the other two curves keep their exact shape; nodes where all three are straight lines
    through their neighbours are then dropped.
    """
    curves = [[(float(c[0]), float(c[k + 1])) for c in colors] for k in range(3)]
    curves[component] = [(float(x), min(max(float(y), 0.0), 1.0)) for x, y in points]
    xs = np.array(sorted({x for curve in curves for x, _ in curve}), dtype=np.float64)
    channels = []
    for curve in curves:
        cx, cy = (np.array(v, dtype=np.float64) for v in zip(*curve, strict=True))
        channels.append(np.interp(xs, cx, cy))
    merged = np.column_stack([xs, *channels])
    keep = [0]
    for i in range(1, len(merged) - 1):
        a, b, c = merged[keep[-1]], merged[i], merged[i + 1]
        t = (b[0] - a[0]) / (c[0] - a[0]) if c[0] != a[0] else 0.0
        if np.any(np.abs(a[1:] + t * (c[1:] - a[1:]) - b[1:]) > 1e-6):
            keep.append(i)
    if len(merged) > 1:
        keep.append(len(merged) - 1)
    return [tuple(float(v) for v in merged[i]) for i in keep]  # type: ignore[misc]


class HistogramCache:
    """Histograms of a volume's channels over any value window, from a strided subsample
    (so a 2 GB memory-mapped stack costs one strided read, once)."""

    def __init__(self) -> None:
        self._key: int | None = None
        self._samples: dict[int, np.ndarray] = {}

    def counts(self, data: VolumeData, channel: int, lo: float, hi: float,
               bins: int = HISTOGRAM_BINS) -> np.ndarray:
        if self._key != id(data):
            self._key, self._samples = id(data), {}
        if channel not in self._samples:
            vol = data.array[channel]
            step = max(1, math.ceil((vol.size / HISTOGRAM_SAMPLE) ** (1.0 / 3.0)))
            sample = np.asarray(vol[::step, ::step, ::step], dtype=np.float32).ravel()
            self._samples[channel] = sample[np.isfinite(sample)]
        counts, _ = np.histogram(self._samples[channel], bins=bins, range=(lo, hi))
        return counts


class FeatureCache:
    """Each channel's (value, |∇I|) sample (:func:`vtkvol.model.classification.feature_sample`),
    read once per data set: the 2-D histogram and the proposed classes share it."""

    def __init__(self) -> None:
        self._key: int | None = None
        self._samples: dict[int, FeatureSample] = {}

    def sample(self, data: VolumeData, channel: int) -> FeatureSample:
        if self._key != id(data):
            self._key, self._samples = id(data), {}
        if channel not in self._samples:
            self._samples[channel] = feature_sample(data.array[channel],
                                                    tuple(data.voxel_size_um))
        return self._samples[channel]


def write_tf_file(path: str | os.PathLike[str], tf: TransferFunction) -> Path:
    """Save one transfer function as JSON, atomically (vtkvol.io.atomic: a failed write raises
    OSError and leaves any previous file as it was)."""
    target = Path(path)
    document = {"format": TF_FILE_FORMAT, "version": TF_FILE_VERSION, **tf.copy_state()}
    return write_atomic(target, json.dumps(document, indent=2) + "\n")


#: Transfer-function files are a few KiB; anything larger is refused unread.
TF_FILE_MAX_BYTES = 4 * 2**20
#: Deepest nesting of JSON objects and lists a transfer-function file may have (real: 3).
TF_FILE_MAX_NESTING = 16


def read_tf_file(path: str | os.PathLike[str]) -> TransferFunction:
    """Read a file written by :func:`write_tf_file`; ``ValueError`` says what is wrong, in one
    line starting with the file's name (``OSError`` when it cannot be read at all)."""
    name = Path(path).name
    if Path(path).stat().st_size > TF_FILE_MAX_BYTES:
        raise ValueError(f"{name}: too large for a transfer-function file (at most "
                         f"{TF_FILE_MAX_BYTES // 2**20} MiB)")
    try:
        text = Path(path).read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{name}: not a text file (not UTF-8 at byte {exc.start})") from None
    try:
        # no NaN, Infinity or 1e999 (the model would refuse them less clearly)
        document = strict_json.loads(text)
    except json.JSONDecodeError as exc:
        where = f"line {exc.lineno}, column {exc.colno}"
        raise ValueError(f"{name}: not valid JSON ({where})") from None
    except ValueError as exc:
        raise ValueError(f"{name}: not valid JSON ({exc})") from None
    except RecursionError:
        # json's C parser recurses once per bracket: 100 000 of them exhaust the stack
        raise ValueError(f"{name}: nested too deeply to be a transfer-function file") from None
    if strict_json.nesting_depth(document) > TF_FILE_MAX_NESTING:
        raise ValueError(f"{name}: nested too deeply to be a transfer-function file")
    if not isinstance(document, dict) or document.get("format") != TF_FILE_FORMAT:
        raise ValueError(f"{name}: not a vtkvol transfer-function file")
    if document.get("version") != TF_FILE_VERSION:
        raise ValueError(f"{name}: unsupported version {document.get('version')!r}")
    fields = {k: v for k, v in document.items() if k not in ("format", "version")}
    try:
        return TransferFunction.model_validate(fields)
    except ValidationError as exc:
        # pydantic's text spans several lines; the first problem, with its place, is enough
        err = exc.errors()[0]
        place = ".".join(str(p) for p in err["loc"])
        message = str(err["msg"]).removeprefix("Value error, ")
        raise ValueError(f"{name}: {place + ': ' if place else ''}{message}") from None
    except ValueError as exc:
        raise ValueError(f"{name}: {' '.join(str(exc).split())}") from None


class TransferFunctionDock(ModelDock):
    """Edits ``model.channels[i].tf`` (the linked channel's TF when ``tf_linked_to`` is set)."""

    TITLE = "Transfer function"
    OBJECT_NAME = "dock_transfer_function"

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(model, parent)
        self._channel = 0
        self._tf: TransferFunction | None = None
        self._histograms = HistogramCache()
        self._features = FeatureCache()
        self._histogram_2d_key: tuple[Any, ...] | None = None
        #: The painted layer as it was when the current brush stroke began (None between).
        self._stroke_base: TFPaintLayer | None = None
        self._editing = False
        self._histogram_key: tuple[Any, ...] | None = None
        self._build()
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    # -- widgets --------------------------------------------------------------------------------
    def _build(self) -> None:
        body = QWidget()
        outer = QHBoxLayout(body)
        outer.setContentsMargins(6, 4, 6, 6)
        self.page_1d = TF1DPage()
        self.page_2d = TF2DPage()
        self.pages = QStackedWidget()
        self.pages.setObjectName("tf_pages")
        self.pages.addWidget(self.page_1d)
        self.pages.addWidget(self.page_2d)
        outer.addWidget(self.pages, 1)
        self.controls = TFControls()
        outer.addWidget(self.controls)
        self.set_body(body)
        self._name_widgets()
        self._bind()

    def _name_widgets(self) -> None:
        """The pages' and controls' widgets under the dock's own names (its methods and the
        tests use these)."""
        one, two, side = self.page_1d, self.page_2d, self.controls
        self.editor, self.colorbar = one.editor, one.colorbar
        self.window_min, self.window_slider, self.window_max, self.window_full = (
            one.window_min, one.window_slider, one.window_max, one.window_full)
        self.channel_combo, self.link_label, self.dimension_combo = (
            side.channel_combo, side.link_label, side.dimension_combo)
        self.curve_group, self.curve_buttons = side.curve_group, side.curve_buttons
        self.mode_points, self.mode_curve = side.mode_points, side.mode_curve
        self.log_opacity, self.histogram_log = side.log_opacity, side.histogram_log
        self.preset_button, self.preset_menu = side.preset_button, side.preset_menu
        self.load_button, self.save_button = side.load_button, side.save_button
        self._controls_1d = side.controls_1d
        self.editor_2d, self.tool_group = two.editor_2d, two.tool_group
        self.brush_size, self.brush_color, self.brush_opacity, self.clear_paint = (
            two.brush_size, two.brush_color, two.brush_opacity, two.clear_paint)
        self.add_rectangle, self.add_triangle, self.delete_primitive = (
            two.add_rectangle, two.add_triangle, two.delete_primitive)
        self.primitive_color, self.primitive_opacity, self.primitive_soft = (
            two.primitive_color, two.primitive_opacity, two.primitive_soft)
        self.propose_button, self.stf_radius, self.stf_opacity = (
            two.propose_button, two.stf_radius, two.stf_opacity)
        self.gradient_top, self.gradient_full = two.gradient_top, two.gradient_full

    def _bind(self) -> None:
        """Widgets → model (the model → widgets direction is :meth:`refresh`)."""
        b = self.bindings
        b.connect_qt(self.preset_menu.triggered, self._on_preset_action)
        b.connect_qt(self.channel_combo.currentIndexChanged, self._on_channel_chosen)
        b.connect_qt(self.curve_group.idClicked, self._on_curve_chosen)
        b.connect_qt(self.mode_points.toggled, self._on_mode)
        b.connect_qt(self.log_opacity.toggled, self.editor.set_log_scale)
        b.connect_qt(self.histogram_log.toggled, self.editor.set_histogram_log)
        b.connect_qt(self.editor.pointsEdited, self._on_points_edited)
        b.connect_qt(self.editor.editStarted, self._on_edit_started)
        b.connect_qt(self.editor.editFinished, self._on_edit_finished)
        b.connect_qt(self.colorbar.colorRequested, self._on_color_requested)
        b.connect_qt(self.colorbar.stopRemoveRequested, self._on_stop_remove)
        b.connect_qt(self.window_min.valueChanged, self._on_window_min)
        b.connect_qt(self.window_max.valueChanged, self._on_window_max)
        b.connect_qt(self.window_slider.valueChanged, self._on_window_slider)
        b.connect_qt(self.window_full.clicked, self._on_window_full)
        b.connect_qt(self.load_button.clicked, self._on_load)
        b.connect_qt(self.save_button.clicked, self._on_save)
        b.connect_qt(self.dimension_combo.currentIndexChanged, self._on_dimension)
        b.connect_qt(self.editor_2d.selectionChanged, self._on_2d_selection)
        b.connect_qt(self.editor_2d.primitiveMoved, self._on_2d_moved)
        b.connect_qt(self.editor_2d.editStarted, self._on_edit_started)
        b.connect_qt(self.editor_2d.editFinished, self._on_2d_edit_finished)
        b.connect_qt(self.add_rectangle.clicked, lambda: self.add_primitive("rectangle"))
        b.connect_qt(self.add_triangle.clicked, lambda: self.add_primitive("triangle"))
        b.connect_qt(self.delete_primitive.clicked, self._on_delete_primitive)
        b.connect_qt(self.editor_2d.deleteRequested, self._on_delete_primitive)
        b.connect_qt(self.primitive_color.colorPicked, self._on_primitive_color)
        b.connect_qt(self.primitive_opacity.valueChanged,
                     lambda v: self._set_selected(opacity=float(v)))
        b.connect_qt(self.primitive_soft.valueChanged,
                     lambda v: self._set_selected(soft_edge=float(v)))
        b.connect_qt(self.propose_button.clicked, self.propose_classes)
        b.connect_qt(self.tool_group.idClicked, self._on_tool)
        b.connect_qt(self.editor_2d.strokeMoved, self._on_stroke)
        b.connect_qt(self.brush_size.valueChanged,
                     lambda v: self.editor_2d.set_brush_radius(float(v)))
        b.connect_qt(self.brush_color.colorPicked, self.brush_color.set_rgb)
        b.connect_qt(self.clear_paint.clicked, self._on_clear_paint)
        b.connect_qt(self.gradient_top.valueChanged, self._on_gradient_top)
        b.connect_qt(self.gradient_full.clicked, self._on_gradient_full)

    def _on_preset_action(self, action) -> None:
        name = action.data()
        if name == ASK_COLORMAP:
            name, ok = QInputDialog.getText(self, "Colormap", "Matplotlib colormap name:")
            if not ok or not name.strip():
                return
            name = name.strip()
        if name:
            self.apply_preset(name)

    # -- model access ---------------------------------------------------------------------------
    @property
    def channel_index(self) -> int:
        return self._channel

    def set_channel(self, index: int) -> None:
        """Edit channel ``index`` (what the channel combo does)."""
        self.channel_combo.setCurrentIndex(index)

    def _effective_index(self) -> int:
        channels = self.model.channels
        link = channels[self._channel].tf_linked_to
        if link is not None and 0 <= link < len(channels) and link != self._channel:
            return link
        return self._channel

    def current_tf(self) -> TransferFunction:
        """The transfer function being edited (the linked one when the channel follows)."""
        return self.model.channels[self._effective_index()].tf

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "channels"):
            # The channel list, names, tints and links change the combo box and link label.
            structural = any(touches(paths, "channels", name)
                             for name in ("tf_linked_to", "name", "color"))
            self.refresh(structural=structural)

    def refresh(self, *, structural: bool = True) -> None:
        channels = self.model.channels
        self._channel = min(self._channel, len(channels) - 1)
        if structural:
            combo = self.channel_combo
            with signals_blocked(combo):
                combo.clear()
                for c in channels:
                    combo.addItem(c.name)
                combo.setCurrentIndex(self._channel)
            combo.setEnabled(len(channels) > 1)
            effective = self._effective_index()
            self.link_label.setVisible(effective != self._channel)
            if effective != self._channel:
                self.link_label.setText(
                    f"“{channels[self._channel].name}” follows the transfer function of "
                    f"“{channels[effective].name}”: edits here change both.")
        self._tf = self.current_tf()
        self._show_tf()
        self._show_2d()

    def _show_tf(self) -> None:
        tf = self._tf
        if tf is None:
            return
        colors = tf.colors
        self.editor.set_points("opacity", tf.opacity)
        for k, name in enumerate(("red", "green", "blue")):
            self.editor.set_points(name, [(c[0], c[k + 1]) for c in colors])
        lo, hi = tf.window
        self.editor.set_domain(lo, hi)
        self.colorbar.set_function(colors, tf.opacity, (lo, hi))
        integer = self.data is not None and self.data.array.dtype.kind in "ui"
        decimals = 0 if integer else 3
        rlo, rhi = tf.window_range
        with signals_blocked(self.window_min, self.window_max, self.window_slider):
            for box, value in ((self.window_min, lo), (self.window_max, hi)):
                box.setDecimals(decimals)
                box.setRange(rlo, rhi)
                box.setSingleStep(max(10.0 ** -decimals, (rhi - rlo) / 100))
                box.setValue(value)
            self.window_slider.setRange(rlo, rhi)
            self.window_slider.setValue((lo, hi))
        self.editor.set_x_formatter(format_value)
        self._update_histogram()

    def set_voxels(self, data: VolumeData) -> None:
        """Another time point: the curves stay, the histogram shows the new values."""
        self.data = data
        self._update_histogram()

    def _update_histogram(self) -> None:
        if self.data is None or self._tf is None:
            self._histogram_key = None
            self.editor.set_histogram(None)
            return
        index = min(self._channel, self.data.n_channels - 1)
        lo, hi = self._tf.window
        key = (id(self.data), index, lo, hi)
        if key != self._histogram_key:  # edits of the curves leave the histogram as it is
            self._histogram_key = key
            self.editor.set_histogram(self._histograms.counts(self.data, index, lo, hi))

    # -- 2-D transfer function ------------------------------------------------------------------
    def current_channel(self):
        """The channel whose transfer functions are edited (the linked one when following)."""
        return self.model.channels[self._effective_index()]

    def current_tf2d(self) -> TransferFunction2D:
        return self.current_channel().tf2d

    def axes_2d(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """(values in data units, |∇I| in data units per µm) of the 2-D editor: the data's
        value range and the renderer's gradient axis (docs/transfer-functions-2d.md)."""
        tf2d = self.current_tf2d()
        if self.data is None:
            lo, hi = self.current_tf().window_range
            return (lo, hi), (0.0, tf2d.gradient_max or 1.0)
        index = min(self._channel, self.data.n_channels - 1)
        lo, hi = self.data.channel_range(index)
        if hi <= lo:
            hi = above(lo)
        top = tf2d.gradient_max or gradient_axis_max((lo, hi), tuple(self.data.voxel_size_um))
        return (lo, hi), (0.0, top)

    def _show_2d(self) -> None:
        channel = self.current_channel()
        two_d = channel.tf_mode == "2d"
        with signals_blocked(self.dimension_combo):
            self.dimension_combo.setCurrentIndex(1 if two_d else 0)
        self.pages.setCurrentIndex(1 if two_d else 0)
        for widget in self._controls_1d:
            widget.setVisible(not two_d)
        if not two_d:
            return
        values, gradients = self.axes_2d()
        self.editor_2d.set_axes(values, gradients)
        with signals_blocked(self.gradient_top):
            self.gradient_top.setValue(gradients[1])
        self.gradient_full.setEnabled(channel.tf2d.gradient_max is not None)
        self.clear_paint.setEnabled(channel.tf2d.paint is not None)
        self.editor_2d.set_function(channel.tf2d)
        self._update_histogram_2d()
        self._show_selected()

    def _update_histogram_2d(self) -> None:
        if self.data is None:
            self._histogram_2d_key = None
            self.editor_2d.set_histogram(None)
            return
        index = min(self._channel, self.data.n_channels - 1)
        values, gradients = self.editor_2d.axes
        key = (id(self.data), index, values, gradients)
        if key != self._histogram_2d_key:
            self._histogram_2d_key = key
            sample = self._features.sample(self.data, index)
            self.editor_2d.set_histogram(histogram2d(sample, values, gradients,
                                                     HISTOGRAM_2D_BINS))

    def _show_selected(self) -> None:
        prims = self.current_tf2d().primitives
        index = self.editor_2d.selected
        has = 0 <= index < len(prims)
        for widget in (self.delete_primitive, self.primitive_color, self.primitive_opacity,
                       self.primitive_soft):
            widget.setEnabled(has)
        if has:
            prim = prims[index]
            with signals_blocked(self.primitive_opacity, self.primitive_soft):
                self.primitive_opacity.setValue(prim.opacity)
                self.primitive_soft.setValue(prim.soft_edge)
            self.primitive_color.set_rgb(prim.color)

    def _on_gradient_top(self, value: float) -> None:
        self.current_tf2d().gradient_max = float(value)

    def _on_gradient_full(self) -> None:
        self.current_tf2d().gradient_max = None

    def _on_tool(self, index: int) -> None:
        self.editor_2d.set_tool(("regions", "paint", "erase")[index])

    def _on_stroke(self, points: list[tuple[float, float]]) -> None:
        """Write the stroke so far into the painted layer. Every write starts from the layer
        as it was when the stroke began, so a throttled stroke ends exactly as one write of
        all its points (and the drag is one undo step: editStarted/editFinished)."""
        tf2d = self.current_tf2d()
        erase = self.editor_2d.tool == "erase"
        if self._stroke_base is None:
            if tf2d.paint is None and erase:
                return  # nothing painted: nothing to erase
            values, gradients = self.axes_2d()
            self._stroke_base = tf2d.paint or TFPaintLayer.blank(values, gradients)
        base = self._stroke_base
        xs, ys = base.pixel_coords(np.array([p[0] for p in points]),
                                   np.array([p[1] for p in points]))
        try:
            mask = stroke_mask(base.shape, zip(xs.tolist(), ys.tolist(), strict=True),
                               self.brush_size.value())
            pixels = apply_stroke(base.pixels(), mask, self.brush_color.rgb(),
                                  self.brush_opacity.value(), erase=erase)
            tf2d.paint = base.with_pixels(pixels)
        except ValueError as exc:
            errors.show_error(self, exc, action="Could not paint")

    def _on_clear_paint(self) -> None:
        with self._step():
            self.current_tf2d().paint = None

    def _on_dimension(self, index: int) -> None:
        channel = self.current_channel()
        mode = DIMENSIONS[index][0]
        tf2d = channel.tf2d
        if mode == "2d" and not tf2d.primitives and (tf2d.paint is None or tf2d.paint.empty):
            # An empty 2-D TF shows nothing: start from the 1-D TF's equivalent, painted over
            # the editor's axes (Clear paint empties it), in the same undo step.
            values, gradients = self.axes_2d()
            with self._step():
                tf2d.paint = paint_from_1d(self.current_tf(), values, gradients)
                channel.tf_mode = mode
            return
        channel.tf_mode = mode

    def add_primitive(self, kind: str) -> None:
        """Add a rectangle or triangle in the middle of the editor's axes and select it."""
        (v0, v1), (_g0, g1) = self.axes_2d()
        span = v1 - v0
        tint = self.current_channel().color
        prim = TFPrimitive(kind=kind, value_range=(v0 + span / 3, v0 + 2 * span / 3),
                           gradient_range=(0.0, g1 * (0.5 if kind == "rectangle" else 0.9)),
                           color=tint, opacity=0.3, soft_edge=0.2)
        tf2d = self.current_tf2d()
        try:
            with self._step():
                tf2d.primitives = [*tf2d.primitives, prim]
        except ValueError as exc:
            errors.show_error(self, exc, action="Could not add the region")
            return
        self.editor_2d.select(len(tf2d.primitives) - 1)

    @contextlib.contextmanager
    def _step(self) -> Iterator[None]:
        """One undo step of its own (not merged with a quick edit just before it)."""
        self.gestureStarted.emit()
        try:
            yield
        finally:
            self.gestureFinished.emit()

    def _on_delete_primitive(self) -> None:
        """Delete every selected region (one undo step)."""
        tf2d = self.current_tf2d()
        doomed = {i for i in self.editor_2d.selected_indices if i < len(tf2d.primitives)}
        if doomed:
            self.editor_2d.select(-1)
            with self._step():
                tf2d.primitives = [p for i, p in enumerate(tf2d.primitives) if i not in doomed]

    def _on_2d_selection(self, _index: int) -> None:
        self._show_selected()

    def _on_2d_moved(self, index: int, values: tuple[float, float],
                     gradients: tuple[float, float]) -> None:
        prims = self.current_tf2d().primitives
        if 0 <= index < len(prims):
            try:
                prims[index].update({"value_range": values, "gradient_range": gradients})
            except ValueError:
                self._show_2d()

    def _on_2d_edit_finished(self) -> None:
        self._stroke_base = None
        self._editing = False
        self.gestureFinished.emit()
        self._show_2d()

    def _on_primitive_color(self, rgb: tuple[float, float, float]) -> None:
        self._set_selected(color=rgb)

    def _set_selected(self, **values: Any) -> None:
        prims = self.current_tf2d().primitives
        index = self.editor_2d.selected
        if 0 <= index < len(prims):
            prims[index].update(values)

    def propose_classes(self) -> None:
        """Replace the channel's regions by spatialized classes (one undoable step)."""
        if self.data is None:
            return
        index = min(self._channel, self.data.n_channels - 1)
        values, gradients = self.axes_2d()
        try:
            classes = spatialized_classes(self._features.sample(self.data, index), values,
                                          gradients, radius=self.stf_radius.value())
            # One region per class, the background class left out (issue 25: ~60 small
            # rectangles, and a blue fog of background noise over the volume).
            proposed = classes_to_tf(classes, opacity_scale=self.stf_opacity.value(),
                                     one_per_class=True, background=False)
        except ValueError as exc:
            errors.show_error(self, exc, action="Could not propose classes")
            return
        self.editor_2d.select(-1)
        with self._step():
            self.current_tf2d().primitives = proposed.primitives

    # -- widget → model -------------------------------------------------------------------------
    def _on_channel_chosen(self, index: int) -> None:
        if 0 <= index < len(self.model.channels):
            self._channel = index
            self.refresh()

    def _on_curve_chosen(self, button_id: int) -> None:
        self.editor.set_active(CURVES[button_id][0])

    def _on_mode(self, points: bool) -> None:
        self.editor.set_mode("points" if points else "curve")

    def _on_edit_started(self) -> None:
        self._editing = True
        self.gestureStarted.emit()

    def _on_edit_finished(self) -> None:
        self._editing = False
        self.gestureFinished.emit()
        self._show_tf()  # the editor ignored echoes during the drag; show the final state

    def _on_points_edited(self, name: str, points: list[tuple[float, float]]) -> None:
        tf = self.current_tf()
        try:
            if name == "opacity":
                tf.opacity = [(float(x), min(max(float(y), 0.0), 1.0)) for x, y in points]
            else:
                component = ("red", "green", "blue").index(name)
                tf.colors = merge_color_curve(tf.colors, component, points)
        except ValueError:
            self._show_tf()

    def _on_color_requested(self, value: float) -> None:
        tf = self.current_tf()
        current = tuple(float(c) for c in tf.color_at(np.array([value]))[0])
        # Looked up on the module at call time so that tests can answer the dialog.
        chosen = dock_base.pick_color(self, current, f"Colour at value {format_value(value)}")
        if chosen is None:
            return
        self.set_color_at(value, chosen)

    def set_color_at(self, value: float, rgb: tuple[float, float, float]) -> None:
        """Set the colour at ``value``: replace a node within 0.5 % of the window, else add."""
        tf = self.current_tf()
        lo, hi = tf.window
        tolerance = 0.005 * (hi - lo)
        colors = list(tf.colors)
        near = [i for i, c in enumerate(colors) if abs(c[0] - value) <= tolerance]
        if near:
            colors[near[0]] = (colors[near[0]][0], *rgb)
        else:
            colors.append((float(value), *rgb))
        tf.colors = colors

    def _on_stop_remove(self, index: int) -> None:
        tf = self.current_tf()
        if len(tf.colors) > 1:
            tf.colors = [c for i, c in enumerate(tf.colors) if i != index]

    def _on_window_min(self, value: float) -> None:
        self._set_window(value, self.current_tf().window[1])

    def _on_window_max(self, value: float) -> None:
        self._set_window(self.current_tf().window[0], value)

    def _on_window_slider(self, value: tuple[float, float]) -> None:
        self._set_window(*value)

    def _on_window_full(self) -> None:
        self._set_window(*self.current_tf().window_range)

    def _set_window(self, lo: float, hi: float) -> None:
        tf = self.current_tf()
        if not hi > lo:
            self._show_tf()  # a window must be increasing: show the model's window again
            return
        tf.set_window(lo, hi)

    def apply_preset(self, name: str) -> None:
        """Replace the TF by preset ``name`` stretched over its current value span."""
        tint = self.model.channels[self._effective_index()].color
        try:
            apply_preset(self.current_tf(), name, tint=tint)
        except ValueError as exc:
            errors.show_error(self, exc, action=f"Could not apply the preset “{name}”")

    def _on_save(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save transfer function",
                                              "transfer-function.tf.json", TF_FILE_FILTER)
        if path:
            self.save_tf(path)

    def save_tf(self, path: str | os.PathLike[str]) -> None:
        try:
            write_tf_file(path, self.current_tf())
        except OSError as exc:
            errors.show_error(self, exc, action="Could not save the transfer function")

    def _on_load(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Load transfer function", "", TF_FILE_FILTER)
        if path:
            self.load_tf(path)

    def load_tf(self, path: str | os.PathLike[str]) -> None:
        """Replace the current TF's points by a saved one (one undoable step)."""
        try:
            loaded = read_tf_file(path)
        except (OSError, ValueError) as exc:
            errors.show_error(self, exc, action="Could not load the transfer function")
            return
        tf = self.current_tf()
        values: dict[str, Any] = {"colors": loaded.colors, "opacity": loaded.opacity}
        with tf.batch():
            tf.update(values)
            span_lo, span_hi = tf.value_span
            lo, hi = tf.window
            tf.set_window(min(lo, span_lo), max(hi, span_hi))


