"""File → Open URL…: the address of an OME-Zarr store on a web server or in S3.

The store is then opened like a file (:meth:`MainWindow.open_path` with the address): the GPU
budget chooses the level, only its chunks are fetched, with the usual progress dialog; Refine
selection later fetches the chunks of the region only (see :mod:`vtkvol.io.remote`).
"""

from __future__ import annotations

from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QLabel,
    QLineEdit,
    QVBoxLayout,
    QWidget,
)

from vtkvol.io.remote import SCHEMES, is_remote

__all__ = ["OpenUrlDialog", "url_problem"]


def url_problem(text: str) -> str | None:
    """What is wrong with ``text`` as a store address, or None when it can be tried."""
    text = text.strip()
    if not text:
        return "Enter the address of an OME-Zarr store."
    if not is_remote(text):
        return f"The address must start with {', '.join(SCHEMES)}."
    if not text.split("://", 1)[1].split("/", 1)[0]:
        return "The address names no host."
    return None


class OpenUrlDialog(QDialog):
    """Asks for an address; :meth:`url` is the accepted one (stripped)."""

    def __init__(self, parent: QWidget | None = None, text: str = "") -> None:
        super().__init__(parent)
        self.setWindowTitle("Open URL")
        self.setObjectName("open_url_dialog")
        layout = QVBoxLayout(self)
        layout.addWidget(QLabel("Address of an OME-Zarr image (only the chunks shown are "
                                "downloaded):"))
        self.edit = QLineEdit(text)
        self.edit.setObjectName("open_url_edit")
        self.edit.setPlaceholderText("https://example.org/data/image.ome.zarr")
        self.edit.setMinimumWidth(420)
        layout.addWidget(self.edit)
        self.problem = QLabel("")
        self.problem.setObjectName("open_url_problem")
        self.problem.setStyleSheet("color: #c0392b")
        layout.addWidget(self.problem)
        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Open
                                        | QDialogButtonBox.StandardButton.Cancel)
        self.buttons.accepted.connect(self.accept)
        self.buttons.rejected.connect(self.reject)
        layout.addWidget(self.buttons)
        self.edit.textChanged.connect(self._check)
        self._check()

    def _check(self) -> None:
        problem = url_problem(self.edit.text())
        # An empty field is not an error yet; it only keeps Open disabled.
        self.problem.setText(problem if problem and self.edit.text().strip() else "")
        self.buttons.button(QDialogButtonBox.StandardButton.Open).setEnabled(problem is None)

    def url(self) -> str:
        return self.edit.text().strip()
