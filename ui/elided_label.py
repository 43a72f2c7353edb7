"""A status-bar label that elides its text on the right instead of pushing the bar wider.

The status bar's data label (name, shape, type, voxel size, memory, pyramid level) ran into the
frame label and left no room for messages at 1280 × 820 (issue 25): this label asks for at most
``max_hint_px`` pixels and draws what does not fit as "…"; ``text()`` stays the whole text,
and the tooltip holds it too.
"""

from __future__ import annotations

from PySide6.QtCore import QSize, Qt
from PySide6.QtGui import QPainter
from PySide6.QtWidgets import QLabel, QSizePolicy, QWidget

__all__ = ["ElidedLabel"]


class ElidedLabel(QLabel):
    """A one-line :class:`QLabel` drawn elided (``…``) when narrower than its text; its size
    hint is the text's width up to ``max_hint_px`` pixels."""

    def __init__(self, text: str = "", parent: QWidget | None = None, *,
                 max_hint_px: int = 420) -> None:
        super().__init__(text, parent)
        self.max_hint_px = max_hint_px
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Preferred)

    def sizeHint(self) -> QSize:
        full = super().sizeHint()
        return QSize(min(full.width(), self.max_hint_px), full.height())

    def minimumSizeHint(self) -> QSize:
        return QSize(min(60, super().minimumSizeHint().width()),
                     super().minimumSizeHint().height())

    def elided_text(self) -> str:
        """The text as drawn at the label's current width."""
        return self.fontMetrics().elidedText(self.text(), Qt.TextElideMode.ElideRight,
                                             self.contentsRect().width())

    def paintEvent(self, _event) -> None:
        painter = QPainter(self)
        painter.setPen(self.palette().color(self.foregroundRole()))
        painter.drawText(self.contentsRect(), int(self.alignment()), self.elided_text())
        painter.end()
