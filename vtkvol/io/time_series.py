"""Time series: what a reader says about the time axis, and a byte-bounded cache of read time
points (the app's time slider keeps one so that scrubbing back shows a point without a read).

A reader reads one time point per call (``read_volume(..., time_index=i)``) and reports
``metadata["time_points"]`` (how many the file has) and, where the file states it,
``metadata["time_interval_s"]`` (seconds between consecutive time points). No Qt, no VTK.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Iterator, Mapping
from typing import Any

from vtkvol.io.limits import physical_memory_bytes
from vtkvol.io.volume_data import VolumeData, format_bytes

__all__ = [
    "DEFAULT_CACHE_FRACTION", "MAX_DEFAULT_CACHE_BYTES", "MAX_TIME_POINTS", "TimePointCache",
    "default_cache_bytes", "format_time", "time_interval_s", "time_point_count",
    "time_unit_seconds",
]

#: The time-point cache's default share of this machine's memory.
DEFAULT_CACHE_FRACTION = 1 / 8
#: The default cache never exceeds this (bytes), however much memory the machine has.
MAX_DEFAULT_CACHE_BYTES = 4 << 30
#: Largest time-point count believed from a file (a header claiming more is taken as lying).
MAX_TIME_POINTS = 10_000_000

#: Time units (as ImageJ's ``tunit`` and OME-NGFF's axis ``unit`` write them) in seconds.
_TIME_UNITS = {
    "s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0,
    "ms": 1e-3, "msec": 1e-3, "millisecond": 1e-3, "milliseconds": 1e-3,
    "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "microsecond": 1e-6, "microseconds": 1e-6,
    "ns": 1e-9, "nanosecond": 1e-9, "nanoseconds": 1e-9,
    "min": 60.0, "minute": 60.0, "minutes": 60.0,
    "h": 3600.0, "hr": 3600.0, "hour": 3600.0, "hours": 3600.0,
    "d": 86400.0, "day": 86400.0, "days": 86400.0,
}


def time_unit_seconds(unit: str | None) -> float | None:
    """Seconds per ``unit`` (``"sec"``, ``"min"``, ``"millisecond"``…); None when unknown.
    No unit means seconds (ImageJ's default)."""
    if unit is None or not str(unit).strip():
        return 1.0
    return _TIME_UNITS.get(str(unit).strip().lower())


def time_point_count(metadata: Mapping[str, Any]) -> int:
    """How many time points the file has (``metadata["time_points"]``): at least 1, and 1 for
    a value that is not a whole number in 1…:data:`MAX_TIME_POINTS`."""
    value = metadata.get("time_points", 1)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return 1
    if not (math.isfinite(value) and value == int(value) and 1 <= value <= MAX_TIME_POINTS):
        return 1
    return int(value)


def time_interval_s(metadata: Mapping[str, Any]) -> float | None:
    """Seconds between consecutive time points (``metadata["time_interval_s"]``), or None when
    the file states none (or states a value that is not a positive finite number)."""
    value = metadata.get("time_interval_s")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) and value > 0 else None


def format_time(index: int, interval_s: float | None) -> str:
    """The time of time point ``index`` (0-based) in a readable unit: ``"45 s"``,
    ``"12.5 min"``, ``"3.25 h"``, ``"180 ms"``; ``""`` without an interval."""
    if interval_s is None:
        return ""
    seconds = index * interval_s
    if seconds == 0:
        return "0 s"
    if seconds < 1:
        return f"{seconds * 1e3:.4g} ms"
    if seconds < 120:
        return f"{seconds:.4g} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.4g} min"
    return f"{seconds / 3600:.4g} h"


def default_cache_bytes() -> int:
    """The cache's default bound: :data:`DEFAULT_CACHE_FRACTION` of this machine's memory, at
    most :data:`MAX_DEFAULT_CACHE_BYTES`."""
    return int(min(physical_memory_bytes() * DEFAULT_CACHE_FRACTION, MAX_DEFAULT_CACHE_BYTES))


class TimePointCache:
    """Time points of one file, least recently used dropped first, never more than
    ``max_bytes`` of voxels in all (``VolumeData.nbytes``; a point larger than the bound is
    not kept).

    Keys are time indices (0-based). ``hits`` and ``misses`` count :meth:`get` calls.
    """

    def __init__(self, max_bytes: int) -> None:
        self._items: OrderedDict[int, VolumeData] = OrderedDict()
        self._bytes = 0
        self._max = 0
        self.hits = 0
        self.misses = 0
        self.max_bytes = max_bytes

    @property
    def max_bytes(self) -> int:
        """The bound (bytes); lowering it drops the least recently used points at once."""
        return self._max

    @max_bytes.setter
    def max_bytes(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"the time-point cache's size must be a number of bytes >= 0, "
                             f"not {value!r}")
        self._max = value
        self._evict(0)

    @property
    def nbytes(self) -> int:
        """Bytes of voxels held now (always <= :attr:`max_bytes`)."""
        return self._bytes

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, index: object) -> bool:
        return index in self._items

    def __iter__(self) -> Iterator[int]:
        """Time indices held, least recently used first."""
        return iter(list(self._items))

    def get(self, index: int) -> VolumeData | None:
        """The cached time point (now the most recently used), or None."""
        data = self._items.get(index)
        if data is None:
            self.misses += 1
            return None
        self.hits += 1
        self._items.move_to_end(index)
        return data

    def put(self, index: int, data: VolumeData) -> bool:
        """Keep ``data`` as time point ``index``, dropping the least recently used points
        until it fits. Returns False (and keeps nothing new) when it alone exceeds the bound."""
        size = int(data.nbytes)
        old = self._items.pop(index, None)
        if old is not None:
            self._bytes -= int(old.nbytes)
        if size > self._max:
            return False
        self._evict(size)
        self._items[index] = data
        self._bytes += size
        return True

    def clear(self) -> None:
        self._items.clear()
        self._bytes = 0
        self.hits = self.misses = 0

    def _evict(self, room: int) -> None:
        while self._items and self._bytes + room > self._max:
            _, dropped = self._items.popitem(last=False)
            self._bytes -= int(dropped.nbytes)

    def describe(self) -> str:
        """E.g. ``"5 time points, 2.4 MiB of 512 MiB"``."""
        n = len(self._items)
        return (f"{n} time point{'s' if n != 1 else ''}, {format_bytes(self._bytes)} of "
                f"{format_bytes(self._max)}")
