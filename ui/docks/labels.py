"""Labels dock: a channel shown as a label image (segmentation), and which labels show.

Edits ``model.channels[i].labels`` and the channel's transfer function through
:func:`vtkvol.model.labels.apply_labels` (categorical glasbey colours, nearest-voxel
sampling) and :func:`~vtkvol.model.labels.show_intensities` (back to a grey ramp over the
channel's contrast limits). The list holds one row per label id of the channel's data, with
its colour swatch and a check box: unchecked ids are transparent and cast no shadow.

A label image over its raw data is a channel marked as labels beside intensity channels of
the same file, or one added with File → Add labels… (docs/app.md, "Labels").
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import Qt
from PySide6.QtGui import QColor, QIcon, QPixmap
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QHBoxLayout,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from vtkvol.model.defaults import default_transfer_function
from vtkvol.model.evented import touches
from vtkvol.model.labels import (
    LabelImageError,
    apply_labels,
    label_colors,
    label_ids,
    show_intensities,
)
from vtkvol.model.scene import SceneModel
from vtkvol.ui.binding import signals_blocked
from vtkvol.ui.docks.base import ModelDock, hint_label, number_box

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: Side of a label's colour swatch in the list (logical pixels).
SWATCH = 12


class LabelsDock(ModelDock):
    """Choose a channel, show it as labels or intensities, its opacity, its visible ids."""

    TITLE = "Labels"
    OBJECT_NAME = "dock_labels"

    def __init__(self, model: SceneModel, parent: QWidget | None = None) -> None:
        super().__init__(model, parent)
        #: Label ids per (data object, channel): np.unique over a large stack takes a while.
        self._ids: dict[tuple[int, int], list[int]] = {}
        self._build()
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    # -- construction ---------------------------------------------------------------------------
    def _build(self) -> None:
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.setContentsMargins(8, 6, 8, 8)
        form = QFormLayout()
        self.channel = QComboBox()
        self.channel.setObjectName("labels_channel")
        self.channel.setToolTip("The channel this dock shows and edits")
        form.addRow("Channel", self.channel)
        self.enabled = QCheckBox("Show as labels")
        self.enabled.setObjectName("labels_enabled")
        self.enabled.setToolTip(
            "Each integer id in its own colour (0 = background, transparent), sampled at the "
            "nearest voxel so that boundaries show no id that is not there. Off: the values "
            "are intensities, through a grey ramp")
        form.addRow("", self.enabled)
        self.opacity = number_box(minimum=0.0, maximum=1.0, decimals=2, step=0.05,
                                  object_name="labels_opacity",
                                  tooltip="Opacity of every shown label (per opacity unit "
                                          "distance; 1 = opaque within about one voxel)")
        form.addRow("Opacity", self.opacity)
        layout.addLayout(form)
        self.message = hint_label("")
        self.message.setObjectName("labels_message")
        layout.addWidget(self.message)
        self.list = QListWidget()
        self.list.setObjectName("labels_list")
        self.list.setToolTip("Uncheck a label to hide it (it then casts no shadow either)")
        self.list.setUniformItemSizes(True)  # thousands of ids: rows laid out lazily
        layout.addWidget(self.list, 1)
        buttons = QHBoxLayout()
        self.show_all = QPushButton("Show all")
        self.show_all.setObjectName("labels_show_all")
        self.hide_all = QPushButton("Hide all")
        self.hide_all.setObjectName("labels_hide_all")
        buttons.addWidget(self.show_all)
        buttons.addWidget(self.hide_all)
        buttons.addStretch(1)
        layout.addLayout(buttons)
        self.set_body(body)

        b = self.bindings
        b.connect_qt(self.channel.currentIndexChanged, lambda _: self._show_channel())
        b.connect_qt(self.enabled.toggled, self.set_labels_mode)
        b.connect_qt(self.opacity.valueChanged, self._on_opacity)
        b.connect_qt(self.list.itemChanged, self._on_item)
        b.connect_qt(self.show_all.clicked, lambda: self.set_hidden([]))
        b.connect_qt(self.hide_all.clicked, lambda: self.set_hidden(self.ids() or []))

    # -- state ----------------------------------------------------------------------------------
    @property
    def index(self) -> int:
        """The channel shown in the dock."""
        return max(self.channel.currentIndex(), 0)

    def ids(self) -> list[int] | None:
        """The label ids of the shown channel's data (ascending, no 0), or None when the data
        cannot be labels (:attr:`message` then says why)."""
        data, c = self.data, self.index
        if data is None or c >= data.n_channels:
            return None
        key = (id(data), c)
        if key not in self._ids:
            try:
                # The file names a single channel; a channel's name, one of several.
                name = (Path(data.source).name if data.n_channels == 1 and data.source
                        else f"channel {data.channel_names[c]!r}")
                self._ids = {key: label_ids(data.array[c], name)}
            except LabelImageError as exc:
                self.message.setText(f"Cannot show as labels: {exc}.")
                return None
        return self._ids[key]

    def set_labels_mode(self, on: bool) -> None:
        """Show the shown channel as labels (``on``) or as intensities again."""
        data, c = self.data, self.index
        if data is None or c >= len(self.model.channels):
            return
        channel = self.model.channels[c]
        if not on:
            if channel.labels is not None:
                show_intensities(self.model, c,
                                 default_transfer_function(data, c, channel.color))
            return
        ids = self.ids()
        if ids is None:
            with signals_blocked(self.enabled):
                self.enabled.setChecked(False)
            return
        if channel.labels is None:
            apply_labels(self.model, ids, channel=c)

    def set_hidden(self, hidden: list[int]) -> None:
        """Hide exactly the ids ``hidden`` of the shown label channel."""
        self._apply(hidden=hidden)

    def _apply(self, *, hidden: list[int] | None = None, opacity: float | None = None) -> None:
        c = self.index
        if c >= len(self.model.channels):
            return
        display = self.model.channels[c].labels
        ids = self.ids()
        if display is None or ids is None:
            return
        apply_labels(self.model, ids, channel=c,
                     opacity=display.opacity if opacity is None else opacity,
                     hidden=display.hidden if hidden is None else hidden)

    def _on_opacity(self, value: float) -> None:
        self._apply(opacity=float(value))

    def _on_item(self, item: QListWidgetItem) -> None:
        display = self.model.channels[self.index].labels if self.model.channels else None
        if display is None:
            return
        label = int(item.data(Qt.ItemDataRole.UserRole))
        hidden = set(display.hidden)
        if item.checkState() == Qt.CheckState.Checked:
            hidden.discard(label)
        else:
            hidden.add(label)
        self._apply(hidden=sorted(hidden))

    # -- model → widgets ------------------------------------------------------------------------
    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if ("channels" in paths or touches(paths, "channels", "name")
                or self.channel.count() != len(self.model.channels)):
            self.refresh()
        elif touches(paths, "channels", "labels"):
            self._show_channel()

    def refresh(self) -> None:
        names = [f"{c + 1}: {ch.name}" for c, ch in enumerate(self.model.channels)]
        current = self.index
        with signals_blocked(self.channel):
            self.channel.clear()
            self.channel.addItems(names)
            labelled = [c for c, ch in enumerate(self.model.channels) if ch.labels is not None]
            # A label channel first: that is what the dock is for.
            wanted = current if current < len(names) and not labelled else (
                labelled[0] if labelled else 0)
            self.channel.setCurrentIndex(min(wanted, len(names) - 1))
        self._show_channel()

    def _show_channel(self) -> None:
        c = self.index
        display = self.model.channels[c].labels if c < len(self.model.channels) else None
        on = display is not None
        self.message.setText("")
        with signals_blocked(self.enabled, self.opacity, self.list):
            self.enabled.setChecked(on)
            self.enabled.setEnabled(self.data is not None)
            self.opacity.setEnabled(on)
            self.opacity.setValue(display.opacity if on else 1.0)
            self.list.clear()
            self.show_all.setEnabled(on)
            self.hide_all.setEnabled(on)
            if not on:
                self.list.setEnabled(False)
                return
            ids = self.ids()
            self.list.setEnabled(ids is not None)
            if ids is None:
                return
            hidden = set(display.hidden)
            for label, rgb in zip(ids, label_colors(ids), strict=True):
                item = QListWidgetItem(_swatch(rgb), f"label {label}")
                item.setData(Qt.ItemDataRole.UserRole, label)
                item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
                item.setCheckState(Qt.CheckState.Unchecked if label in hidden
                                   else Qt.CheckState.Checked)
                self.list.addItem(item)
        shown = len(ids) - len(hidden & set(ids))
        self.message.setText(f"{len(ids)} labels, {shown} shown.")


def _swatch(rgb) -> QIcon:
    """A square icon of colour ``rgb`` (0…1)."""
    pixmap = QPixmap(SWATCH, SWATCH)
    pixmap.fill(QColor.fromRgbF(*(float(v) for v in rgb)))
    return QIcon(pixmap)



def note_labels(model: SceneModel, data: VolumeData, labelled: list[tuple[int, str]],
                refused: list[tuple[int, str]] = ()) -> None:
    """After opening ``data``: nearest-voxel sampling when some channel was detected as a
    label image (``labelled``, from :func:`~vtkvol.model.labels.show_detected_labels`), and a
    note saying so (the status bar shows it; the Labels dock turns it off), or why a channel
    that looks like labels is shown as intensities (``refused``); trilinear again when no
    channel is labels and the last data's labels left nearest on."""
    for _, why in refused:
        data.notes.insert(0, f"{why}; shown as intensities")
    if labelled:
        model.render.interpolation = "nearest"
        for c, reason in labelled:
            data.notes.insert(0, f"channel {data.channel_names[c]!r} shown as labels ({reason}); "
                                 "the Labels dock turns this off")
    elif model.render.interpolation == "nearest":
        model.render.interpolation = "trilinear"
