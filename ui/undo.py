"""Undo and redo for model edits: a ``QUndoStack`` of before/after model snapshots.

The recorder listens to ``SceneModel.changed``; every edit (from any dock, a preset, a loaded
transfer function) becomes one command holding the JSON state of the touched top-level
fields before and after. Undo applies the "before" dict with in-place updates
(:func:`apply_state`), so docks bound to ``model.crop`` or ``model.channels[0].tf`` stay bound.

Merging (so a slider drag is one step, not fifty):

* between :meth:`UndoRecorder.begin_gesture` and :meth:`UndoRecorder.end_gesture` (docks call
  these on mouse press and release in the function editors) all edits merge into one command;
* outside a gesture, consecutive edits of the same fields within :data:`MERGE_WINDOW_S`
  merge (spin-box arrows, slider drags, typing).

The camera, the slice views' cursor and the data source are not edits: they are recorded in
the snapshot (so undo never reverts them) but never make a command.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from PySide6.QtCore import QObject
from PySide6.QtGui import QUndoCommand, QUndoStack

from vtkvol.model.evented import EventedModel, fields_of
from vtkvol.model.scene import SceneModel

#: Top-level fields whose changes are view state or provenance, not undoable edits.
NOT_EDITS = frozenset({"camera", "volume", "cursor"})
#: Edits of the same fields closer together than this merge into one undo step (seconds).
MERGE_WINDOW_S = 0.8
_COMMAND_ID = 0x7654  # any constant: QUndoStack only merges commands with equal ids

_LABELS = (
    ("overlays", "Toggle overlay"),  # before "color": "overlays.color_legend" contains it
    ("render.background", "Change background colour"),
    ("tf.opacity", "Edit opacity"),
    ("tf.colors", "Edit colours"),
    ("tf.window", "Change displayed value range"),
    ("tf", "Edit transfer function"),
    ("visible", "Toggle channel visibility"),
    ("color", "Change channel colour"),
    ("tf_linked_to", "Link transfer function"),
    ("clip_plane.enabled", "Toggle clipping plane"),
    ("clip_plane", "Move clipping plane"),
    ("crop", "Change crop ranges"),
    ("slice_weights", "Edit slice contribution"),
    ("lights", "Edit lights"),
    ("illumination.method", "Change illumination method"),
    ("illumination", "Change illumination parameter"),
    ("render.blend_mode", "Change blending mode"),
    ("render", "Change rendering settings"),
    ("channels", "Edit channels"),
)


def describe(paths: frozenset[str]) -> str:
    """A short label for the Edit menu ("Undo Edit opacity") from changed dotted paths."""
    dotted = [".".join(fields_of(p)) for p in paths]
    for needle, label in _LABELS:
        if any(needle in p for p in dotted):
            return label
    return "Edit"


def apply_state(model: EventedModel, state: Mapping[str, Any]) -> None:
    """Set ``model``'s fields from a JSON-style ``state`` dict in one event, in place.

    Nested models are updated recursively; a list of models of the same length is updated
    element by element (so a dock bound to ``channels[0]`` keeps its binding); anything else
    is assigned (and validated) as a whole. The app uses this rather than
    ``EventedModel.update`` for whole-scene changes (opening data or a session): ``update``
    replaces lists of models by new objects, and when those are equal to the old ones the
    model neither emits nor re-connects to them, so later edits of them would go unseen.
    """
    with model.batch():
        for key, value in state.items():
            current = getattr(model, key)
            if isinstance(current, EventedModel) and isinstance(value, Mapping):
                apply_state(current, value)
            elif (
                isinstance(current, list)
                and isinstance(value, list)
                and current
                and len(current) == len(value)
                and all(isinstance(c, EventedModel) for c in current)
                and all(isinstance(v, Mapping) for v in value)
            ):
                for child, child_state in zip(current, value, strict=True):
                    apply_state(child, child_state)
            else:
                setattr(model, key, copy.deepcopy(value))


class SnapshotCommand(QUndoCommand):
    """One undoable edit: the touched top-level fields before and after."""

    def __init__(
        self,
        recorder: UndoRecorder,
        before: dict[str, Any],
        after: dict[str, Any],
        paths: frozenset[str],
        gesture: int | None,
        epoch: int,
    ) -> None:
        super().__init__(describe(paths))
        self._recorder = recorder
        self.before = before
        self.after = after
        self.keys = frozenset(before)
        self.gesture = gesture
        self.epoch = epoch  # bumped by every undo/redo: never merge across one
        self.stamp = time.monotonic()
        self._pushed = False  # QUndoStack.push() calls redo(); the edit is already applied

    def id(self) -> int:
        return _COMMAND_ID

    def redo(self) -> None:
        if not self._pushed:
            self._pushed = True
            return
        self._recorder.restore(self.after)

    def undo(self) -> None:
        self._recorder.restore(self.before)

    def mergeWith(self, other: QUndoCommand) -> bool:
        if not isinstance(other, SnapshotCommand) or other.epoch != self.epoch:
            return False
        same_gesture = self.gesture is not None and other.gesture == self.gesture
        quick_repeat = (
            self.gesture is None
            and other.gesture is None
            and other.keys == self.keys
            and other.stamp - self.stamp < MERGE_WINDOW_S
        )
        if not (same_gesture or quick_repeat):
            return False
        for key, value in other.before.items():
            self.before.setdefault(key, value)
        self.after.update(other.after)
        self.keys = frozenset(self.before)
        self.stamp = other.stamp
        if self.before == self.after:
            self.setObsolete(True)  # the gesture ended where it began: nothing to undo
        return True


class UndoRecorder(QObject):
    """Turns every edit of ``model`` into a command on :attr:`stack`."""

    def __init__(self, model: SceneModel, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.stack = QUndoStack(self)
        self._state: dict[str, Any] = model.copy_state()
        self._restoring = False
        self._amending = 0
        self._gesture_depth = 0
        self._gesture_serial = 0
        self._epoch = 0
        model.changed.connect(self._on_changed)

    # -- recording ------------------------------------------------------------------------------
    def _on_changed(self, paths: frozenset[str]) -> None:
        tops = {fields_of(p)[0] for p in paths}
        new_state = self.model.copy_state()
        old_state, self._state = self._state, new_state
        edits = tops - NOT_EDITS
        if self._restoring or not edits:
            return
        if self._amending:
            self._amend(edits, old_state, new_state)
            return
        before = {k: old_state[k] for k in edits}
        after = {k: new_state[k] for k in edits}
        if before == after:
            return
        gesture = self._gesture_serial if self._gesture_depth else None
        edit_paths = frozenset(p for p in paths if fields_of(p)[0] in edits)
        self.stack.push(SnapshotCommand(self, before, after, edit_paths, gesture, self._epoch))

    @contextmanager
    def amending(self) -> Iterator[None]:
        """Changes made inside are not edits of their own but corrections by the engine (a
        failed illumination method set back to local shading): they amend the latest step's
        after-state, so undoing the user's choice returns to what was shown before it, and
        undo never retries the broken method. With no step to amend they are only absorbed."""
        self._amending += 1
        try:
            yield
        finally:
            self._amending -= 1

    def _amend(self, keys: set[str], old_state: dict[str, Any],
               new_state: dict[str, Any]) -> None:
        index = self.stack.index()
        top = self.stack.command(index - 1) if index > 0 else None
        if not isinstance(top, SnapshotCommand):
            return
        for key in keys:
            top.before.setdefault(key, old_state[key])
            top.after[key] = new_state[key]
        top.keys = frozenset(top.before)
        if top.before == top.after:
            top.setObsolete(True)  # e.g. local → broken → local: nothing left to undo

    def begin_gesture(self) -> None:
        """Edits until the matching :meth:`end_gesture` become one undo step."""
        if self._gesture_depth == 0:
            self._gesture_serial += 1
        self._gesture_depth += 1

    def end_gesture(self) -> None:
        self._gesture_depth = max(0, self._gesture_depth - 1)

    @contextmanager
    def gesture(self) -> Iterator[None]:
        self.begin_gesture()
        try:
            yield
        finally:
            self.end_gesture()

    # -- applying -------------------------------------------------------------------------------
    def restore(self, state: Mapping[str, Any]) -> None:
        """Apply a snapshot without recording it as a new edit."""
        self._restoring = True
        self._epoch += 1
        try:
            apply_state(self.model, state)
        finally:
            self._restoring = False
            self._state = self.model.copy_state()

    def reset(self) -> None:
        """Forget history (after opening data or a session: old steps no longer apply)."""
        self.stack.clear()
        self._state = self.model.copy_state()

    def close(self) -> None:
        self.model.changed.disconnect(self._on_changed)
        self.stack.clear()
