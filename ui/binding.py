"""Two-way binding between Qt widgets and evented model fields.

Follows napari's ``connect_setattr`` / ``attr_to_settr`` (style-anchors §1 and §4 item 11):

* :meth:`Bindings.connect_setattr`: a widget signal writes ``setattr(model, name, value)``;
* :meth:`Bindings.attr_to_setter`: a model change calls the widget's setter inside a
  ``QSignalBlocker``, so pushing a value into a widget never echoes back into the model;
* :meth:`Bindings.bind` does both for one field.

Every connection is recorded in a :class:`Bindings` and removed by :meth:`Bindings.clear`
(docks call it when they rebuild and when they close). The helpers hold the model and the
widget weakly, and the model's ``changed`` signal holds their bound methods weakly, so a
forgotten binding can neither keep a dock alive nor write into a dead widget.
"""

from __future__ import annotations

import contextlib
import warnings
import weakref
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import shiboken6
from PySide6.QtCore import QObject, QSignalBlocker, SignalInstance

from vtkvol.model.evented import EventedModel, touches


@contextlib.contextmanager
def signals_blocked(*widgets: QObject) -> Iterator[None]:
    """Block the signals of ``widgets`` while a view pushes model values into them, so the
    push never echoes back into the model. Each widget's previous blocking state is restored
    (``QSignalBlocker``), so nested pushes do not unblock a widget too early."""
    blockers = [QSignalBlocker(w) for w in widgets]
    try:
        yield
    finally:
        for blocker in reversed(blockers):
            blocker.unblock()


def paths_touch(paths: Iterable[str], name: str) -> bool:
    """Whether a ``changed`` event with ``paths`` concerns field ``name`` (or inside it)."""
    return touches(paths, *name.split("."))


class _ModelToWidget:
    """Pushes ``getattr(model, name)`` into a widget when the field changes."""

    def __init__(
        self,
        model: EventedModel,
        name: str,
        widgets: tuple[QObject, ...],
        setter: Callable[[Any], None],
        convert: Callable[[Any], Any] | None,
    ) -> None:
        self._model = weakref.ref(model)
        self.name = name
        self._widgets = [weakref.ref(w) for w in widgets]
        self._setter = setter
        self._convert = convert

    def on_changed(self, paths: frozenset[str]) -> None:
        if paths_touch(paths, self.name):
            self.push()

    def push(self) -> None:
        """Copy the model value into the widget(s) with their signals blocked."""
        model = self._model()
        widgets = [ref() for ref in self._widgets]
        if model is None or any(w is None or not shiboken6.isValid(w) for w in widgets):
            return
        value = getattr(model, self.name)
        if self._convert is not None:
            value = self._convert(value)
        with signals_blocked(*widgets):
            self._setter(value)


class _WidgetToModel:
    """Writes a widget's new value into ``model.name``; a rejected value is reverted."""

    def __init__(
        self,
        model: EventedModel,
        name: str,
        convert: Callable[..., Any] | None,
        revert: Callable[[], None] | None,
    ) -> None:
        self._model = weakref.ref(model)
        self.name = name
        self._convert = convert
        self._revert = revert

    def on_signal(self, *args: Any) -> None:
        model = self._model()
        if model is None:
            return
        value = self._convert(*args) if self._convert is not None else (args[0] if args else None)
        try:
            setattr(model, self.name, value)
        except ValueError:
            # pydantic's ValidationError is a ValueError: the widget shows the model again
            # rather than a value the model refused.
            if self._revert is not None:
                self._revert()


class Bindings:
    """The record of every widget↔model connection one control made; ``clear()`` undoes all."""

    def __init__(self) -> None:
        self._qt: list[tuple[SignalInstance, Callable[..., Any]]] = []
        self._model: list[tuple[weakref.ref[EventedModel], Callable[..., Any]]] = []
        self._keep: list[object] = []  # helpers whose bound methods the signals hold weakly

    # -- the two helpers ------------------------------------------------------------------------
    def connect_setattr(
        self,
        signal: SignalInstance,
        model: EventedModel,
        name: str,
        *,
        convert: Callable[..., Any] | None = None,
        revert: Callable[[], None] | None = None,
    ) -> None:
        """``signal(*args)`` → ``setattr(model, name, convert(*args))``.

        ``revert`` is called when the model rejects the value (validation error).
        """
        helper = _WidgetToModel(model, name, convert, revert)
        self.connect_qt(signal, helper.on_signal)
        self._keep.append(helper)

    def attr_to_setter(
        self,
        model: EventedModel,
        name: str,
        widget: QObject | tuple[QObject, ...],
        setter: Callable[[Any], None],
        *,
        convert: Callable[[Any], Any] | None = None,
        initial: bool = True,
    ) -> Callable[[], None]:
        """On a change of ``model.name`` call ``setter(convert(value))`` with ``widget``'s
        signals blocked. Returns the push function (call it to resynchronise)."""
        widgets = widget if isinstance(widget, tuple) else (widget,)
        helper = _ModelToWidget(model, name, widgets, setter, convert)
        self.connect_model(model, helper.on_changed)
        self._keep.append(helper)
        if initial:
            helper.push()
        return helper.push

    def bind(
        self,
        model: EventedModel,
        name: str,
        widget: QObject,
        signal: SignalInstance,
        setter: Callable[[Any], None],
        *,
        to_model: Callable[..., Any] | None = None,
        to_widget: Callable[[Any], Any] | None = None,
    ) -> None:
        """Both directions for one field (the usual case)."""
        push = self.attr_to_setter(model, name, widget, setter, convert=to_widget)
        self.connect_setattr(signal, model, name, convert=to_model, revert=push)

    # -- raw connections, still recorded --------------------------------------------------------
    def connect_qt(self, signal: SignalInstance, slot: Callable[..., Any]) -> None:
        """Connect a Qt signal and remember it for :meth:`clear`."""
        signal.connect(slot)
        self._qt.append((signal, slot))

    def connect_model(self, model: EventedModel, slot: Callable[[frozenset[str]], None]) -> None:
        """Connect ``model.changed`` and remember it for :meth:`clear`."""
        model.changed.connect(slot)
        self._model.append((weakref.ref(model), slot))

    def clear(self) -> None:
        """Disconnect everything recorded (idempotent)."""
        for signal, slot in self._qt:
            # The sender may already be gone, or Qt dropped the connection with it.
            with contextlib.suppress(RuntimeError, TypeError), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                signal.disconnect(slot)
        for ref, slot in self._model:
            model = ref()
            if model is not None:
                model.changed.disconnect(slot)
        self._qt.clear()
        self._model.clear()
        self._keep.clear()

    def __len__(self) -> int:
        return len(self._qt) + len(self._model)
