"""The chooser shown when an opened folder holds several stacks (File → Open folder, a drop,
``vtkvol open``): open one of them, or all of them as the channels of one volume.

:func:`vtkvol.io.read_volume` refuses such a folder with
:class:`~vtkvol.io.folder.SeveralStacksError`, which carries the stacks; the main window hands
it to :func:`offer_stacks` instead of an error dialog. Choosing one opens that file as if it had
been opened itself; "all as channels" reads them with
:func:`~vtkvol.io.folder.read_stacks_as_channels`, whose own message says which stack does not
match (shape or voxel size) when they cannot be combined.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtWidgets import (
    QAbstractItemView,
    QDialog,
    QDialogButtonBox,
    QLabel,
    QListWidget,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from vtkvol.io.folder import SeveralStacksError
from vtkvol.io.read import MAX_CHANNELS

#: Names listed in the dialog; a folder of 10⁵ files lists these and says how many more.
MAX_LISTED = 1000


class StackChooser(QDialog):
    """Lists a folder's stacks; ``Open`` opens the selected one, ``Open all as channels``
    (offered for 2…:data:`~vtkvol.io.read.MAX_CHANNELS` stacks) all of them together.

    After it closes, :attr:`choice` is the selected stack's path, the folder with
    :attr:`as_channels` True, or None (cancelled).
    """

    def __init__(self, folder: Path, stacks: tuple[Path, ...],
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.folder = folder
        self.stacks = stacks
        self.choice: Path | None = None
        self.as_channels = False
        self.setWindowTitle("Open folder")
        layout = QVBoxLayout(self)
        listed = stacks[:MAX_LISTED]
        more = len(stacks) - len(listed)
        intro = (f"{folder.name or folder} holds {len(stacks)} stacks, not the slices of one. "
                 "Open one of them:")
        if more:
            intro += f" (the first {len(listed)} are listed; {more} more are not)"
        self.intro = QLabel(intro)
        self.intro.setWordWrap(True)
        layout.addWidget(self.intro)
        self.list = QListWidget()
        self.list.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.list.addItems([p.name for p in listed])
        self.list.setCurrentRow(0)
        self.list.itemDoubleClicked.connect(lambda _item: self._open_selected())
        layout.addWidget(self.list)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Cancel)
        self.open_button = QPushButton("Open")
        self.open_button.setDefault(True)
        self.channels_button = QPushButton("Open all as channels")
        if 2 <= len(stacks) <= MAX_CHANNELS:
            self.channels_button.setToolTip(
                "Read every stack as one channel of a single volume; they must have the same "
                "shape and voxel size.")
        else:
            self.channels_button.setEnabled(False)
            self.channels_button.setToolTip(
                f"vtkvol shows up to {MAX_CHANNELS} channels at once; this folder holds "
                f"{len(stacks)} stacks.")
        buttons.addButton(self.open_button, QDialogButtonBox.ButtonRole.AcceptRole)
        buttons.addButton(self.channels_button, QDialogButtonBox.ButtonRole.AcceptRole)
        self.open_button.clicked.connect(self._open_selected)
        self.channels_button.clicked.connect(self._open_as_channels)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)

    def _open_selected(self) -> None:
        row = self.list.currentRow()
        if row < 0:
            return
        self.choice = self.stacks[row]
        self.as_channels = False
        self.done(QDialog.DialogCode.Accepted)

    def _open_as_channels(self) -> None:
        self.choice = self.folder
        self.as_channels = True
        self.done(QDialog.DialogCode.Accepted)


def offer_stacks(parent: QWidget, error: SeveralStacksError,
                 open_path: Callable[..., None]) -> StackChooser:
    """Show a :class:`StackChooser` for ``error``'s folder (window-modal, without blocking);
    on a choice call ``open_path(path)`` or ``open_path(folder, as_channels=True)``."""
    dialog = StackChooser(Path(error.source or "."), error.stacks, parent)

    def chosen(result: int) -> None:
        if result == QDialog.DialogCode.Accepted and dialog.choice is not None:
            if dialog.as_channels:
                open_path(dialog.choice, as_channels=True)
            else:
                open_path(dialog.choice)
        dialog.deleteLater()

    dialog.finished.connect(chosen)
    dialog.open()
    return dialog
