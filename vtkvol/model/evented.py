"""Evented, validated model objects: the one event mechanism every model class uses.

An :class:`EventedModel` is a pydantic model whose field assignments are validated and, when
the value really changed, announced on :attr:`EventedModel.changed` as a set of dotted field
paths (``{"crop.x"}``). Changes inside nested models bubble up to the parent with the field
name prefixed; inside a list field, with the element's index (``{"channels[1].tf.opacity"}``,
``{"lights[0].intensity"}``), while replacing the list is ``{"channels"}``. Listeners use
:func:`touches`, :func:`indices`, :func:`element_fields` and :func:`subfields` rather than
parsing strings. Several assignments inside
:meth:`EventedModel.batch` are announced once, together; :meth:`EventedModel.update` applies a
mapping that way.

Deliberately small (see docs/architecture.md, "Model"): no bytecode inference of property
dependencies, no per-field emitter objects. Listeners receive the set of paths and decide.
"""

from __future__ import annotations

import contextlib
import re
import types
import weakref
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, PrivateAttr

Paths = frozenset[str]


class Signal:
    """A minimal synchronous signal. Bound methods are held weakly, functions strongly."""

    def __init__(self) -> None:
        self._slots: list[Any] = []

    def connect(self, slot: Callable[..., Any]) -> Callable[..., Any]:
        # Bound Python methods are held weakly so a view that forgets to disconnect does not
        # keep itself alive; plain functions and builtins are held strongly.
        ref: Any = weakref.WeakMethod(slot) if isinstance(slot, types.MethodType) else slot
        self._slots.append(ref)
        return slot

    def disconnect(self, slot: Callable[..., Any]) -> None:
        self._slots = [s for s in self._slots if self._resolve(s) not in (slot, None)]

    def emit(self, *args: Any) -> None:
        for ref in list(self._slots):
            fn = self._resolve(ref)
            if fn is None:
                # A nested emit (a slot's own model edit) or a disconnect during this loop
                # may have dropped the dead slot already.
                with contextlib.suppress(ValueError):
                    self._slots.remove(ref)
            else:
                fn(*args)

    @staticmethod
    def _resolve(ref: Any) -> Callable[..., Any] | None:
        return ref() if isinstance(ref, weakref.WeakMethod) else ref

    def __len__(self) -> int:
        return len(self._slots)


class BatchedEvents:
    """``changed`` and ``batch()`` of an evented object (:class:`EventedModel`, the app's
    :class:`~vtkvol.model.document.Document`): ``changed`` emits one ``frozenset[str]`` of
    changed names (dotted paths for nested models) per change, or per outermost batch.
    The object holds ``_changed`` (a :class:`Signal`), ``_batch_depth`` and ``_pending``."""

    _changed: Signal
    _batch_depth: int
    _pending: set[str]

    @property
    def changed(self) -> Signal:
        """Emits one ``frozenset[str]`` of changed names per (batched) change."""
        return self._changed

    @contextlib.contextmanager
    def batch(self) -> Iterator[None]:
        """Group assignments so listeners see a single event with all changed names."""
        self._batch_depth += 1
        try:
            yield
        finally:
            self._batch_depth -= 1
            if self._batch_depth == 0 and self._pending:
                names, self._pending = frozenset(self._pending), set()
                self._changed.emit(names)

    def _emit(self, names: set[str] | frozenset[str]) -> None:
        if self._batch_depth:
            self._pending.update(names)
        else:
            self._changed.emit(frozenset(names))


class EventedModel(BatchedEvents, BaseModel):
    """Base for all model state: validated on assignment, emits changed field paths."""

    model_config = ConfigDict(validate_assignment=True, extra="forbid", frozen=False)

    _changed: Signal = PrivateAttr(default_factory=Signal)
    _batch_depth: int = PrivateAttr(default=0)
    _pending: set[str] = PrivateAttr(default_factory=set)
    _child_slots: dict[str, Any] = PrivateAttr(default_factory=dict)

    def model_post_init(self, __context: Any) -> None:
        for name in type(self).model_fields:
            self._adopt(name, getattr(self, name))

    # -- nested models ------------------------------------------------------------------------
    def _adopt(self, name: str, value: Any) -> None:
        """Forward the changes of a child model (or list of child models) with a prefix."""
        old = self._child_slots.pop(name, None)
        if old is not None:
            for child, slot in old:
                child.changed.disconnect(slot)
        children = [value] if isinstance(value, EventedModel) else (
            [v for v in value if isinstance(v, EventedModel)] if isinstance(value, list) else []
        )
        if not children:
            return
        slots = []
        listed = isinstance(value, list)
        for index, child in enumerate(children):
            prefix = f"{name}[{index}]" if listed else name

            def slot(paths: Paths, _prefix: str = prefix) -> None:
                self._emit({f"{_prefix}.{p}" for p in paths})

            child.changed.connect(slot)
            slots.append((child, slot))
        self._child_slots[name] = slots

    # -- assignment ---------------------------------------------------------------------------
    def __setattr__(self, name: str, value: Any) -> None:
        if name.startswith("_") or name not in type(self).model_fields:
            super().__setattr__(name, value)
            return
        old = getattr(self, name)
        super().__setattr__(name, value)
        new = getattr(self, name)
        if new is not old:
            # Equal but new child objects must still forward their future changes.
            self._adopt(name, new)
        if not _equal(old, new):
            self._emit({name})

    def update(self, values: Mapping[str, Any] | EventedModel) -> None:
        """Apply several fields at once (recursing into nested models) with one event.

        Nested models are updated in place, so views bound to ``model.crop`` stay bound.
        Lists are replaced as a whole.
        """
        if isinstance(values, EventedModel):
            values = {k: getattr(values, k) for k in type(values).model_fields}
        with self.batch():
            for key, value in values.items():
                if key not in type(self).model_fields:
                    raise ValueError(f"{type(self).__name__} has no field {key!r}")
                current = getattr(self, key)
                if isinstance(current, EventedModel) and isinstance(value, Mapping | EventedModel):
                    current.update(value)
                else:
                    setattr(self, key, value)

    def __eq__(self, other: object) -> bool:
        # Compare field values only: private event plumbing differs between equal models.
        return type(self) is type(other) and self.model_dump() == other.model_dump()  # type: ignore[union-attr]

    __hash__ = None  # type: ignore[assignment]

    def copy_state(self) -> dict[str, Any]:
        """A JSON-ready dict of all fields (what a session file stores)."""
        return self.model_dump(mode="json")


_SEGMENT = re.compile(r"\[\d+\]")


def fields_of(path: str) -> list[str]:
    """The field names along ``path``, without list indices: ``"channels[1].tf.opacity"`` →
    ``["channels", "tf", "opacity"]``."""
    return _SEGMENT.sub("", path).split(".")


def touches(paths: Iterable[str], *names: str) -> bool:
    """Whether any of ``paths`` is the field ``names`` (e.g. ``"channels", "tf"``) of any list
    element, or inside it, or replaces a field that contains it."""
    wanted = list(names)
    for path in paths:
        fields = fields_of(path)
        n = min(len(fields), len(wanted))
        if fields[:n] == wanted[:n]:
            return True
    return False


def indices(paths: Iterable[str], list_name: str) -> set[int] | None:
    """The elements of list field ``list_name`` that changed: a set of indices, or None when
    the whole list was replaced (every element may have changed)."""
    found: set[int] = set()
    pattern = re.compile(rf"^{re.escape(list_name)}\[(\d+)\]")
    for path in paths:
        if path == list_name:
            return None
        match = pattern.match(path)
        if match:
            found.add(int(match.group(1)))
    return found


def element_fields(paths: Iterable[str], list_name: str) -> dict[int, set[str]] | None:
    """For list field ``list_name``: each changed element's index → the names of its own
    fields that changed (``{"channels[1].tf.opacity"}`` → ``{1: {"tf"}}``), or None when the
    whole list was replaced (every element may have changed)."""
    found: dict[int, set[str]] = {}
    pattern = re.compile(rf"^{re.escape(list_name)}\[(\d+)\](?:\.(\w+))?")
    for path in paths:
        if path == list_name:
            return None
        match = pattern.match(path)
        if match:
            found.setdefault(int(match.group(1)), set()).add(match.group(2) or "")
    return found


def subfields(paths: Iterable[str], name: str) -> set[str] | None:
    """The fields of model field ``name`` that changed (``{"render.jitter"}`` → ``{"jitter"}``),
    or None when ``name`` itself was replaced (every field may have changed)."""
    found: set[str] = set()
    for path in paths:
        fields = fields_of(path)
        if fields[0] != name:
            continue
        if len(fields) == 1:
            return None
        found.add(fields[1])
    return found


def _equal(a: Any, b: Any) -> bool:
    try:
        result = a == b
        return bool(result)
    except (ValueError, TypeError):  # e.g. numpy arrays: ambiguous truth value
        import numpy as np

        return bool(np.array_equal(a, b))
