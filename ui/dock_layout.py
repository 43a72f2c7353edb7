"""The app window's docks: which there are, where they go, and the default layout
(:class:`DockLayout`)."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QMainWindow, QScrollArea

from vtkvol.model.scene import SceneModel
from vtkvol.ui.docks.base import ModelDock
from vtkvol.ui.docks.channels import ChannelsDock
from vtkvol.ui.docks.labels import LabelsDock
from vtkvol.ui.docks.lights import LightsDock
from vtkvol.ui.docks.ranges import RangesDock
from vtkvol.ui.docks.slice_views import SliceViewsDock
from vtkvol.ui.docks.slice_weights import SliceWeightsDock
from vtkvol.ui.docks.transfer_function import TransferFunctionDock


class DockLayout:
    """The seven docks of ``window``, each bound to ``model``, placed in their areas."""

    def __init__(self, window: QMainWindow, model: SceneModel) -> None:
        self.window = window
        #: Whether :meth:`arrange` ran (the window does it when first shown).
        self.arranged = False
        self.tf_dock = TransferFunctionDock(model, window)
        self.slice_dock = SliceWeightsDock(model, window)
        self.channels_dock = ChannelsDock(model, window)
        self.lights_dock = LightsDock(model, window)
        self.ranges_dock = RangesDock(model, window)
        self.slice_views_dock = SliceViewsDock(model, window)
        self.labels_dock = LabelsDock(model, window)
        self.docks: list[ModelDock] = [self.tf_dock, self.slice_dock, self.channels_dock,
                                       self.lights_dock, self.ranges_dock,
                                       self.slice_views_dock, self.labels_dock]
        bottom = Qt.DockWidgetArea.BottomDockWidgetArea
        right = Qt.DockWidgetArea.RightDockWidgetArea
        window.addDockWidget(bottom, self.tf_dock)
        window.addDockWidget(bottom, self.slice_dock)
        window.tabifyDockWidget(self.tf_dock, self.slice_dock)
        window.addDockWidget(right, self.channels_dock)
        window.addDockWidget(right, self.lights_dock)
        window.addDockWidget(right, self.ranges_dock)
        window.addDockWidget(right, self.labels_dock)
        window.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, self.slice_views_dock)
        self.slice_views_dock.hide()

    def arrange(self) -> None:
        """The default layout: TF and slice editors tabbed below, channels above tabbed
        lights and ranges on the right; the slice views (left of the 3-D view) are hidden
        until View → Slice views shows them. Done once the window is shown: Qt 6.12 leaves a
        stray tab bar in the middle of the window when docks are tabified before that."""
        self.arranged = True
        for dock in self.docks:
            dock.setFloating(False)
            dock.setVisible(dock is not self.slice_views_dock)
        self.window.tabifyDockWidget(self.tf_dock, self.slice_dock)
        self.window.tabifyDockWidget(self.lights_dock, self.ranges_dock)
        self.window.tabifyDockWidget(self.ranges_dock, self.labels_dock)
        self.tf_dock.raise_()
        self.lights_dock.raise_()
        self.window.resizeDocks([self.tf_dock], [270], Qt.Orientation.Vertical)
        self.window.resizeDocks([self.channels_dock], [370], Qt.Orientation.Horizontal)
        self.fit_channels(shrink=True)

    def fit_channels(self, *, shrink: bool = False) -> None:
        """Make the channels dock as tall as its rows (the lights dock gives or takes the
        room). Without ``shrink`` it only grows: the user may have made it taller."""
        dock = self.channels_dock
        if dock.isFloating() or not dock.isVisible():
            return
        scroll = dock.widget()
        content = scroll.widget() if isinstance(scroll, QScrollArea) else scroll
        content.adjustSize()
        wanted = content.sizeHint().height() + 12  # a little slack: no scroll bar for 2 px
        have = scroll.viewport().height() if isinstance(scroll, QScrollArea) else dock.height()
        if wanted > have or (shrink and wanted < have):
            extra = wanted - have
            self.window.resizeDocks(
                [dock, self.lights_dock],
                [dock.height() + extra, max(self.lights_dock.height() - extra, 120)],
                Qt.Orientation.Vertical)
