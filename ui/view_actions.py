"""View-menu actions bound to the model: the overlays, the clipping plane and the background
colour.

Each overlay (``model.overlays``: scale bar, orientation axes, bounding box, colour legend,
slice planes)
is a checkable action; ticking it writes the model, and a model change (undo, a session)
ticks it. **Background colour…** asks for a colour and writes ``model.render.background``.
The engine draws what the model says; nothing here touches VTK.
"""

from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtGui import QAction

from vtkvol.model.evented import subfields, touches
from vtkvol.model.scene import Overlays, SceneModel
from vtkvol.ui.binding import Bindings, signals_blocked
from vtkvol.ui.docks import base as dock_base

#: (field of ``Overlays``, menu text, status tip).
OVERLAYS: tuple[tuple[str, str, str], ...] = (
    ("scale_bar", "&Scale bar",
     "A bar of a round length in µm, measured at the depth of the view's centre"),
    ("orientation_axes", "&Orientation axes",
     "x (red), y (green) and z (blue) arrows in the lower-left corner"),
    ("bounding_box", "&Bounding box", "The outline of the data's box"),
    ("color_legend", "Colour &legend",
     "A colour bar per visible channel over its transfer function's values"),
    ("slice_planes", "Slice &planes",
     "Outline the slice views' three planes through the cursor (x red, y green, z blue)"),
)


class ViewActions(QObject):
    """The overlay toggles and the background-colour action of one window."""

    def __init__(self, model: SceneModel, parent: QObject) -> None:
        super().__init__(parent)
        self.model = model
        self.bindings = Bindings()
        self.overlay_actions: dict[str, QAction] = {}
        for name, text, tip in OVERLAYS:
            action = QAction(text, parent)
            action.setObjectName(f"overlay_{name}")
            action.setCheckable(True)
            action.setStatusTip(tip)
            action.setToolTip(tip)
            self.bindings.connect_qt(action.toggled,
                                     lambda on, n=name: setattr(self.model.overlays, n, bool(on)))
            self.overlay_actions[name] = action
        self.clip_action = QAction("&Clipping plane", parent)
        self.clip_action.setObjectName("clip_plane")
        self.clip_action.setCheckable(True)
        tip = ("An oblique plane that cuts the volume (drag its arrow to turn it, its plane to "
               "move it); what it cuts away casts no shadow")
        self.clip_action.setStatusTip(tip)
        self.clip_action.setToolTip(tip)
        self.bindings.connect_qt(self.clip_action.toggled,
                                 lambda on: setattr(self.model.clip_plane, "enabled", bool(on)))
        self.background_action = QAction("Back&ground colour…", parent)
        self.background_action.setObjectName("background_color")
        self.background_action.setStatusTip("The colour behind the volume (also in screenshots)")
        self.bindings.connect_qt(self.background_action.triggered,
                                 lambda *_: self.choose_background())
        self.bindings.connect_model(model, self._on_model_changed)
        self.refresh()

    def choose_background(self) -> None:
        rgb = dock_base.pick_color(None, self.model.render.background, "Background colour")
        if rgb is not None:
            self.model.render.background = tuple(float(c) for c in rgb)

    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if touches(paths, "overlays") or touches(paths, "clip_plane"):
            self.refresh()
        elif touches(paths, "render"):
            names = subfields(paths, "render")  # None: the whole settings object was replaced
            if names is None or "background" in names:
                self._show_background()

    def refresh(self) -> None:
        overlays: Overlays = self.model.overlays
        for name, action in self.overlay_actions.items():
            with signals_blocked(action):
                action.setChecked(bool(getattr(overlays, name)))
        with signals_blocked(self.clip_action):
            self.clip_action.setChecked(self.model.clip_plane.enabled)
        self._show_background()

    def _show_background(self) -> None:
        r, g, b = (round(255 * c) for c in self.model.render.background)
        self.background_action.setToolTip(f"Background colour: #{r:02x}{g:02x}{b:02x}")

    def release(self) -> None:
        self.bindings.clear()
