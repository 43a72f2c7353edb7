"""The voxel-size dialog (Edit → Voxel size…) and the reader notes as users read them.

Microscopy files often lack the z step (plain TIFF stacks, many exports): the reader then
assumes 1 µm and says so in a note. The dialog shows the voxel size in use, the file's own
value (or that the file has none), and lets the user type the real one. The main window
applies it (:meth:`vtkvol.ui.app.MainWindow.set_voxel_size`).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence

from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFormLayout,
    QLabel,
    QVBoxLayout,
    QWidget,
)

from vtkvol.io import VolumeData
from vtkvol.io.volume_data import Spacing

Size = tuple[float, float, float]

#: Smallest and largest voxel edge the dialog accepts (µm): 0.1 nm … 10 cm.
MIN_UM, MAX_UM = 1e-4, 1e5
#: What to do about a missing voxel size, in the user's words.
ADVICE = ("The voxel size sets the proportions of the volume and every length in µm (crop "
          "ranges, scale bar, light positions). Take it from the microscope's acquisition "
          "settings: the pixel size for x and y, the z step (slice spacing) for z. TIFF files "
          "often store no z step.")
#: Library advice in reader notes → what the app's user does instead.
_NOTE_ADVICE = {
    "(pass voxel_size_um to set it)": "(set it with Edit → Voxel size…)",
    "pass voxel_size_um to set it": "set it with Edit → Voxel size…",
}

#: "using 1 × 1 × 1 µm" / "using 1 µm": a reader assumed a voxel size.
_ASSUMED = re.compile(r"using 1( × 1 × 1)? µm(?! \()")


def user_note(note: str) -> str:
    """A reader note with its advice for library callers (an argument name) phrased for the
    app's user (the menu entry that does it); a note that a voxel size was assumed gets that
    advice when it has none."""
    for api, words in _NOTE_ADVICE.items():
        note = note.replace(api, words)
    if _ASSUMED.search(note) and "Voxel size…" not in note:
        note = _ASSUMED.sub(lambda m: f"{m.group(0)} (set it with Edit → Voxel size…)", note)
    return note


def is_assumed_size_note(note: str) -> bool:
    """Whether a reader note says that it assumed a voxel size (moot once the user set one)."""
    return _ASSUMED.search(note) is not None


def format_size(size: Sequence[float]) -> str:
    """``"0.5 × 0.5 × 2 µm"``."""
    return " × ".join(f"{float(v):.4g}" for v in size) + " µm"


class VoxelSizeDialog(QDialog):
    """Three boxes (x, y, z in µm), the file's own value and the advice above."""

    def __init__(self, current: Sequence[float], file_size: Sequence[float] | None,
                 from_file: bool, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Voxel size")
        self.setObjectName("voxel_size_dialog")
        self._file_size = tuple(float(v) for v in file_size) if file_size is not None else None
        layout = QVBoxLayout(self)
        form = QFormLayout()
        self.boxes: list[QDoubleSpinBox] = []
        for axis, value in zip("xyz", current, strict=True):
            box = QDoubleSpinBox()
            box.setObjectName(f"voxel_{axis}")
            box.setDecimals(4)
            box.setRange(MIN_UM, MAX_UM)
            box.setSingleStep(0.05)
            box.setSuffix(" µm")
            box.setValue(float(value))
            box.setToolTip(f"Distance between voxel centres along {axis} (µm)")
            self.boxes.append(box)
            form.addRow(f"{axis} ({'z step' if axis == 'z' else 'pixel size'})", box)
        layout.addLayout(form)
        if self._file_size is not None and from_file:
            source = f"The file says {format_size(self._file_size)}."
        elif self._file_size is not None:
            source = (f"The file does not store a voxel size; {format_size(self._file_size)} "
                      "was assumed when it was opened.")
        else:
            source = "The file's own value is not known (a voxel size was given when opening)."
        self.source_label = QLabel(source)
        self.source_label.setObjectName("voxel_source")
        self.source_label.setWordWrap(True)
        layout.addWidget(self.source_label)
        advice = QLabel(ADVICE)
        advice.setWordWrap(True)
        advice.setStyleSheet("color: palette(placeholder-text);")
        layout.addWidget(advice)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                                   | QDialogButtonBox.StandardButton.Cancel)
        self.file_button = buttons.addButton("Use the file's value",
                                             QDialogButtonBox.ButtonRole.ResetRole)
        self.file_button.setObjectName("voxel_use_file")
        self.file_button.setEnabled(self._file_size is not None)
        self.file_button.clicked.connect(self._use_file_value)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)
        self.setMinimumWidth(380)

    def _use_file_value(self) -> None:
        if self._file_size is not None:
            for box, value in zip(self.boxes, self._file_size, strict=True):
                box.setValue(value)

    def value(self) -> Size:
        return tuple(float(b.value()) for b in self.boxes)  # type: ignore[return-value]


def ask_voxel_size(parent: QWidget, current: Sequence[float], file_size: Sequence[float] | None,
                   from_file: bool) -> Size | None:
    """Show the dialog; the chosen size, or None when cancelled (tests replace this)."""
    dialog = VoxelSizeDialog(current, file_size, from_file, parent)
    try:
        return dialog.value() if dialog.exec() == QDialog.DialogCode.Accepted else None
    finally:
        dialog.deleteLater()


def with_voxel_size(read: VolumeData, size: tuple[float, float, float] | None) -> VolumeData:
    """``read`` (data as read) with voxel size ``size`` (x, y, z µm; None: as read): the same
    voxels, the size recorded as set in the app, the reader's "assumed 1 µm" note dropped."""
    if size is None or tuple(float(v) for v in size) == tuple(read.voxel_size_um):
        return read
    return dataclasses.replace(
        read, voxel_size_um=Spacing(*(float(v) for v in size)),
        metadata={**read.metadata, "voxel_size_source": "set in the app"},
        # The reader's "assumed 1 µm" note no longer holds once the user set a size.
        notes=[n for n in read.notes if not is_assumed_size_note(n)])
