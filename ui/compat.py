"""Workarounds for bugs in the Qt binding that would crash the app; each says when it applies.

PySide6 6.12 (the ``abi3`` wheels) on CPython 3.11 and older returns ``None`` from C++
methods returning ``void`` without taking a reference. Every ``label.setText(...)``,
``painter.setPen(...)``, ``spin.setValue(...)`` therefore lowers ``None``'s reference count
by one; after some tens of thousands of calls (minutes of hovering over a function editor)
it reaches zero and CPython aborts with "Fatal Python error: none_dealloc". CPython 3.12
made ``None`` immortal (PEP 683), so the bug is invisible there.

:func:`protect_none` gives ``None`` the same protection on the affected versions: a reference
count so large that the leak can never bring it to zero. It changes nothing else.
"""

from __future__ import annotations

import ctypes
import sys

#: Added to None's reference count: at one leaked reference per microsecond this lasts
#: twelve days of continuous calls; in practice, forever.
MARGIN = 1 << 40


def affected(pyside_version: str, python: tuple[int, ...] = tuple(sys.version_info)) -> bool:
    """Whether this PySide6 and CPython combination leaks references to ``None``."""
    if python[:2] >= (3, 12):
        return False
    try:
        major, minor = (int(part) for part in pyside_version.split(".")[:2])
    except ValueError:
        return False
    return (major, minor) == (6, 12)


def protect_none() -> bool:
    """Raise ``None``'s reference count by :data:`MARGIN` where the leak exists; True if
    done. Only on CPython release builds, where ``ob_refcnt`` is an object's first field."""
    if sys.implementation.name != "cpython" or hasattr(sys, "getobjects"):
        return False  # another interpreter, or a Py_TRACE_REFS build (different layout)
    try:
        import PySide6
    except ImportError:
        return False
    if not affected(PySide6.__version__):
        return False
    refcount = ctypes.c_ssize_t.from_address(id(None))
    if refcount.value < MARGIN:  # once per process
        refcount.value += MARGIN
    return True
