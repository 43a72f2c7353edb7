"""`VolumeData`: what every reader returns, and the checks every volume goes through.

Conventions (docs/architecture.md): arrays are numpy ``[c, z, y, x]`` in C order (x fastest,
the memory layout VTK uses); per-axis tuples such as the voxel size are ordered (x, y, z) and
measured in µm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from vtkvol.io.errors import VolumeReadError, display_name
from vtkvol.io.progress import CancelCallback, Progress, ProgressCallback, slabs

__all__ = [
    "SUPPORTED_DTYPES",
    "Spacing",
    "VolumeData",
    "as_spacing",
    "default_channel_names",
    "format_bytes",
    "normalize_volume",
    "resolve_channels",
]

SUPPORTED_DTYPES: tuple[np.dtype, ...] = (
    np.dtype(np.uint8),
    np.dtype(np.uint16),
    np.dtype(np.int16),
    np.dtype(np.float32),
)
"""The dtypes a :class:`VolumeData` holds; everything else is converted (with a note)."""

_TWELVE_BIT_MAX = 4095
_FLOAT32_EXACT_INT = 2**24  # integers above this are not all representable in float32
_SAMPLE_VOXELS = 2_000_000  # size of the strided subsample used for percentiles


class Spacing(NamedTuple):
    """Voxel size in µm, ordered (x, y, z) like every per-axis tuple in vtkvol."""

    x: float
    y: float
    z: float


def as_spacing(value: Spacing | Sequence[float] | float, *, what: str = "voxel_size_um") -> Spacing:
    """Turn a scalar (isotropic) or an (x, y, z) sequence into a validated :class:`Spacing`.

    Raises
    ------
    ValueError
        If there are not three values or any is not a finite number > 0.
    """
    if isinstance(value, (int, float, np.integer, np.floating)):
        values = [float(value)] * 3
    else:
        values = [float(v) for v in value]
    if len(values) != 3:
        raise ValueError(f"{what} needs 3 values (x, y, z) in µm, got {len(values)}: {value!r}")
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"{what} values must be finite and > 0 µm, got {tuple(values)}")
    return Spacing(*values)


def spacing_or_default(values_um: Sequence[float], note: str,
                       notes: list[str]) -> tuple[Spacing, bool]:
    """``(spacing, from_metadata)``: the file's voxel size (x, y, z) in µm when every value is
    finite and positive; otherwise 1 × 1 × 1 µm, and ``note`` (which says so) is added."""
    values = [float(v) for v in values_um]
    if all(math.isfinite(v) and v > 0 for v in values):
        return Spacing(*values), True
    notes.append(note)
    return Spacing(1.0, 1.0, 1.0), False


def default_channel_names(n: int) -> list[str]:
    """``["ch0", "ch1", …]``: names for channels the file does not name."""
    return [f"ch{i}" for i in range(n)]


def format_bytes(n: float) -> str:
    """``1536 -> "1.5 KiB"``, ``2**30 -> "1 GiB"``: binary units, as memory is counted; one
    decimal, dropped when it is 0 so that a size reads the same as the choices a user typed."""
    value = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(value) < 1024 or unit == "TiB":
            text = f"{value:.0f}" if unit == "B" else f"{value:.1f}".removesuffix(".0")
            return f"{text} {unit}"
        value /= 1024
    raise AssertionError("unreachable")


def resolve_channels(
    channels: Sequence[int | str] | int | str | None,
    names: Sequence[str],
    source: str | None,
) -> list[int]:
    """Turn the user's ``channels`` selection into a list of channel indices.

    Parameters
    ----------
    channels
        None for all channels, or indices (negative counts from the end) and/or channel names.
    names
        The channel names of the file, one per channel.
    source
        The file, for error messages.

    Raises
    ------
    VolumeReadError
        Naming the number of channels when an index or name does not exist.
    """
    n = len(names)
    if channels is None:
        return list(range(n))
    if isinstance(channels, (int, np.integer, str)):
        channels = [channels]
    chosen: list[int] = []
    for item in channels:
        if isinstance(item, str):
            if item not in names:
                raise VolumeReadError(
                    source, f"there is no channel named {item!r}; channels are {list(names)}"
                )
            chosen.append(list(names).index(item))
            continue
        index = int(item)
        if not -n <= index < n:
            raise VolumeReadError(
                source,
                f"channel {index} is out of range: the file has {n} channel"
                f"{'s' if n != 1 else ''} (0–{n - 1})",
            )
        chosen.append(index % n)
    if not chosen:
        raise VolumeReadError(source, "no channels selected (channels=[])")
    return chosen


@dataclass(eq=False, repr=False)
class VolumeData:
    """A volume ready for display: voxels, voxel size, channel names, provenance.

    Attributes
    ----------
    array
        Always 4-D ``[c, z, y, x]``, C-contiguous (x fastest, as VTK stores voxels). May be a
        read-only ``np.memmap`` onto the file. After :func:`normalize_volume` (which
        :func:`~vtkvol.io.read_volume` and :meth:`from_array` run) the dtype is one of uint8,
        uint16, int16, float32.
    voxel_size_um
        Voxel edge lengths (x, y, z) in µm.
    channel_names
        One name per channel (``array.shape[0]`` of them).
    source
        The file or folder the data were read from; None for generated or in-memory data.
    voxel_size_from_metadata
        True when x, y (and z for more than one slice) came from the file's metadata; False
        when any of them is a default or was given by the caller.
    metadata
        Facts about the file, e.g. ``{"format": "imagej-tiff", "axes": "TZCYX",
        "bit_depth": 12, "time_points": 5, "time_index": 0}``.
    notes
        User-visible warnings: conversions, downsampling, 12-bit content, NaN voxels, …
    """

    array: np.ndarray
    voxel_size_um: Spacing
    channel_names: list[str]
    source: str | None = None
    voxel_size_from_metadata: bool = False
    metadata: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    _stats_cache: dict[tuple[Any, ...], tuple[float, float]] = field(
        default_factory=dict, init=False, repr=False
    )

    def __post_init__(self) -> None:
        if not isinstance(self.array, np.ndarray):
            self.array = np.asarray(self.array)
        if self.array.ndim != 4:
            raise ValueError(
                f"VolumeData.array must be 4-D [c, z, y, x], got shape {self.array.shape}; "
                "use VolumeData.from_array for 3-D (z, y, x) arrays"
            )
        self.voxel_size_um = as_spacing(self.voxel_size_um)
        names = [str(n) for n in (self.channel_names or [])]
        if not names:
            names = default_channel_names(self.array.shape[0])
        if len(names) != self.array.shape[0]:
            raise ValueError(
                f"{len(names)} channel names for {self.array.shape[0]} channels: {names}"
            )
        self.channel_names = names
        if self.source is not None:
            self.source = str(self.source)

    def __repr__(self) -> str:
        return (
            f"VolumeData(shape_czyx={tuple(self.array.shape)}, dtype={self.array.dtype}, "
            f"voxel_size_um={tuple(round(v, 6) for v in self.voxel_size_um)}, "
            f"channel_names={self.channel_names}, source={self.source!r})"
        )

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_array(
        cls,
        array: np.ndarray | Sequence[Any],
        voxel_size_um: Spacing | Sequence[float] | float = (1.0, 1.0, 1.0),
        channel_names: Sequence[str] | None = None,
        *,
        source: str | None = None,
        voxel_size_from_metadata: bool = False,
        metadata: dict[str, Any] | None = None,
        notes: Sequence[str] | None = None,
        progress: ProgressCallback | None = None,
        cancel: CancelCallback | None = None,
    ) -> VolumeData:
        """Wrap an array as a checked :class:`VolumeData`.

        Parameters
        ----------
        array
            3-D ``(z, y, x)`` (one channel) or 4-D ``[c, z, y, x]``. Not copied when it is
            already C-contiguous with a supported native dtype; otherwise converted (see
            :func:`normalize_volume`).
        voxel_size_um
            (x, y, z) in µm, or one number for isotropic voxels.
        channel_names
            One name per channel; default ``ch0``, ``ch1``, …

        Raises
        ------
        VolumeReadError
            Wrong number of dimensions, zero-size axes, unsupported dtype (complex, strings,
            …) or no finite value at all.
        """
        arr = array if isinstance(array, np.ndarray) else np.asarray(array)
        if arr.ndim == 3:
            arr = arr[np.newaxis]
        elif arr.ndim != 4:
            raise VolumeReadError(
                source,
                f"expected a 3-D (z, y, x) or 4-D (c, z, y, x) array, got {arr.ndim}-D shape "
                f"{arr.shape}",
            )
        data = cls(
            arr,
            as_spacing(voxel_size_um),
            list(channel_names or []),
            source=source,
            voxel_size_from_metadata=voxel_size_from_metadata,
            metadata=dict(metadata or {}),
            notes=list(notes or []),
        )
        return normalize_volume(data, Progress(progress, cancel))

    # -- simple properties ---------------------------------------------------------------
    @property
    def shape_zyx(self) -> tuple[int, int, int]:
        """Number of voxels along (z, y, x), the array's order (not the (x, y, z) of tuples)."""
        _, z, y, x = self.array.shape
        return int(z), int(y), int(x)

    @property
    def n_channels(self) -> int:
        """Number of channels (``array.shape[0]``)."""
        return int(self.array.shape[0])

    @property
    def nbytes(self) -> int:
        """Size of the voxel data in bytes (what a GPU texture of it needs)."""
        return int(self.array.nbytes)

    @property
    def extent_um(self) -> Spacing:
        """Physical size (x, y, z) in µm: voxel count × voxel size."""
        z, y, x = self.shape_zyx
        sx, sy, sz = self.voxel_size_um
        return Spacing(x * sx, y * sy, z * sz)

    # -- statistics ----------------------------------------------------------------------
    def _cache_key(self, *extra: Any) -> tuple[Any, ...]:
        # Keyed on the array object so that replacing `array` invalidates the cache.
        return (id(self.array), self.array.shape, self.array.dtype.str, *extra)

    def channel_range(self, c: int) -> tuple[float, float]:
        """Finite (min, max) of channel ``c``, ignoring NaN and ±inf; cached.

        Returns (0.0, 0.0) when the channel has no finite value.
        """
        key = self._cache_key("range", int(c))
        if key not in self._stats_cache:
            lo, hi, _ = _scan_channel(self.array[c], Progress())
            self._stats_cache[key] = (lo, hi) if lo <= hi else (0.0, 0.0)
        return self._stats_cache[key]

    def percentiles(self, c: int, lo: float = 0.5, hi: float = 99.8) -> tuple[float, float]:
        """The ``lo`` and ``hi`` percentiles (0…100) of channel ``c``'s finite values.

        Computed on a strided subsample of about two million voxels, so it takes
        milliseconds even for multi-GB (memory-mapped) volumes; cached.
        """
        key = self._cache_key("percentiles", int(c), float(lo), float(hi))
        if key not in self._stats_cache:
            vol = self.array[c]
            step = max(1, math.ceil((vol.size / _SAMPLE_VOXELS) ** (1.0 / 3.0)))
            sample = np.asarray(vol[::step, ::step, ::step]).ravel()
            if sample.dtype.kind == "f":
                sample = sample[np.isfinite(sample)]
            if sample.size == 0:
                self._stats_cache[key] = (0.0, 0.0)
            else:
                p_lo, p_hi = np.percentile(sample, [lo, hi])
                self._stats_cache[key] = (float(p_lo), float(p_hi))
        return self._stats_cache[key]

    # -- text ------------------------------------------------------------------------------
    def describe(self) -> str:
        """Multi-line human-readable summary, as printed by ``vtkvol info``.

        Lists the source, shape, axes in the file, time point, dtype and bit depth, voxel size
        (and where it came from), extent, each channel's value range and percentiles, memory
        and all notes.
        """
        md = self.metadata
        c, z, y, x = (int(v) for v in self.array.shape)
        sx, sy, sz = self.voxel_size_um
        lines = [f"source: {self.source or '(in memory)'}"]
        if md.get("format"):
            lines.append(f"format: {md['format']}")
        lines.append(
            f"shape: {x} × {y} × {z} voxels (x × y × z), {c} channel{'s' if c != 1 else ''}"
            f"; array [c, z, y, x] = {(c, z, y, x)}"
        )
        if md.get("axes"):
            lines.append(f"axes in file: {md['axes']}")
        if md.get("time_points", 1) > 1:
            lines.append(
                f"time point: index {md.get('time_index', 0)} of {md['time_points']} "
                f"(0–{md['time_points'] - 1})"
                + (f", {md['time_interval_s']:.4g} s apart"
                   if isinstance(md.get("time_interval_s"), (int, float)) else "")
            )
        dtype_line = f"dtype: {self.array.dtype}"
        bits = md.get("bit_depth")
        if bits and bits != self.array.dtype.itemsize * 8:
            dtype_line += f" ({bits}-bit content)"
        if md.get("original_dtype") and md["original_dtype"] != str(self.array.dtype):
            dtype_line += f", converted from {md['original_dtype']}"
        lines.append(dtype_line)
        origin = md.get("voxel_size_source") or (
            "from file metadata" if self.voxel_size_from_metadata else "not in file; default"
        )
        lines.append(f"voxel size: x {sx:.6g} µm, y {sy:.6g} µm, z {sz:.6g} µm ({origin})")
        ex, ey, ez = self.extent_um
        lines.append(
            f"extent: {ex:.4g} × {ey:.4g} × {ez:.4g} µm (x × y × z); z/x anisotropy {sz / sx:.3g}"
        )
        lines.append("channels:")
        for i, name in enumerate(self.channel_names):
            lo, hi = self.channel_range(i)
            p_lo, p_hi = self.percentiles(i)
            lines.append(
                f"  [{i}] {name}: range {lo:.6g} … {hi:.6g}; "
                f"0.5–99.8 % percentiles {p_lo:.6g} … {p_hi:.6g}"
            )
        where = "memory-mapped from disk" if isinstance(self.array, np.memmap) else "in RAM"
        lines.append(f"memory: {format_bytes(self.nbytes)} ({where})")
        if self.notes:
            lines.append("notes:")
            lines.extend(f"  - {note}" for note in self.notes)
        else:
            lines.append("notes: none")
        return "\n".join(lines)


# -- normalisation ------------------------------------------------------------------------------
def _scan_channel(vol: np.ndarray, progress: Progress) -> tuple[float, float, int]:
    """Finite (min, max) and the number of non-finite voxels of one ``(z, y, x)`` channel.

    Streams over z-slabs so memory-mapped data is never loaded whole. Returns
    ``(inf, -inf, n)`` when there is no finite value.
    """
    lo, hi, nonfinite = math.inf, -math.inf, 0
    is_float = vol.dtype.kind == "f"
    n_z = vol.shape[0]
    for sl in slabs(n_z, vol[0].nbytes):
        block = np.asarray(vol[sl])
        if is_float:
            finite = np.isfinite(block)
            n_finite = int(np.count_nonzero(finite))
            nonfinite += block.size - n_finite
            if n_finite == 0:
                block = None
            elif n_finite != block.size:
                block = block[finite]
        if block is not None and block.size:
            lo = min(lo, float(block.min()))
            hi = max(hi, float(block.max()))
        progress(sl.stop / n_z, "computing value ranges")
    return lo, hi, nonfinite


def _target_dtype(
    dtype: np.dtype, lo: float, hi: float, source: str | None
) -> tuple[np.dtype, str | None]:
    """The supported dtype to store ``dtype`` data with finite range [lo, hi] in, and a note."""
    native = dtype.newbyteorder("=")
    if native in SUPPORTED_DTYPES:
        return native, None
    name = dtype.name
    if dtype.kind == "b":
        return np.dtype(np.uint8), "boolean data stored as uint8 (False → 0, True → 1)"
    if dtype.kind in "ui":
        span = f"values {lo:.0f}…{hi:.0f}"
        if lo >= 0 and hi <= np.iinfo(np.uint16).max:
            return np.dtype(np.uint16), f"{name} data converted to uint16 ({span} fit exactly)"
        if lo >= np.iinfo(np.int16).min and hi <= np.iinfo(np.int16).max:
            return np.dtype(np.int16), f"{name} data converted to int16 ({span} fit exactly)"
        exact = max(abs(lo), abs(hi)) <= _FLOAT32_EXACT_INT
        return np.dtype(np.float32), (
            f"{name} data converted to float32 ({span}"
            + (" fit exactly)" if exact else f"; values beyond ±{_FLOAT32_EXACT_INT} are rounded)")
        )
    if dtype.kind == "f":
        return np.dtype(np.float32), f"{name} data converted to float32"
    raise VolumeReadError(source, f"unsupported data type {dtype}")


def _convert(arr: np.ndarray, target: np.dtype, progress: Progress) -> np.ndarray:
    """C-contiguous copy of ``arr`` as ``target``, slab by slab (progress and cancel per slab)."""
    out = np.empty(arr.shape, dtype=target)
    n_c, n_z = arr.shape[:2]
    per_z = arr[0, 0].size * max(arr.dtype.itemsize, target.itemsize)
    for c in range(n_c):
        for sl in slabs(n_z, per_z):
            # float64 → float32 may overflow to ±inf; the finite scan after this reports it.
            with np.errstate(over="ignore", invalid="ignore"):
                out[c, sl] = arr[c, sl]
            progress((c + sl.stop / n_z) / n_c, "converting voxel data")
    return out


def normalize_volume(data: VolumeData, progress: Progress | None = None) -> VolumeData:
    """Check a freshly read volume and bring it into the form the engine expects.

    - rejects zero-size axes, complex and non-numeric dtypes (:class:`VolumeReadError`);
    - converts other dtypes to uint8/uint16/int16/float32 (bool → uint8; int32 labels →
      uint16 or int16 when the range fits, else float32; float64 → float32), with a note;
    - makes the array native-endian and C-contiguous (memory-mapped arrays that already are
      stay memory-mapped);
    - computes each channel's finite range (cached for :meth:`VolumeData.channel_range`);
    - rejects data in which every voxel is NaN or ±inf, and notes partially non-finite data;
    - records ``metadata["bit_depth"]``, detecting 12-bit content in uint16 data.

    Modifies and returns ``data``.
    """
    progress = progress or Progress()
    src = data.source
    arr = data.array
    md = data.metadata
    if arr.ndim != 4 or 0 in arr.shape:
        raise VolumeReadError(
            src, f"the volume has a zero-size axis: shape (c, z, y, x) = {tuple(arr.shape)}"
        )
    kind = arr.dtype.kind
    if kind == "c":
        raise VolumeReadError(
            src,
            f"complex data ({arr.dtype.name}) is not supported; save the magnitude (abs) or "
            "the real part as float32",
        )
    if kind not in "biuf":
        raise VolumeReadError(
            src, f"unsupported data type {arr.dtype} (expected integer, float or bool voxels)"
        )

    needs_prescan = kind in "ui" and arr.dtype.newbyteorder("=") not in SUPPORTED_DTYPES
    lo = hi = 0.0
    if needs_prescan:
        lo, hi = math.inf, -math.inf
        sub = progress.sub(0.0, 0.3)
        for c in range(arr.shape[0]):
            c_lo, c_hi, _ = _scan_channel(arr[c], sub.sub(c / arr.shape[0], (c + 1) / arr.shape[0]))
            lo, hi = min(lo, c_lo), max(hi, c_hi)
    target, note = _target_dtype(arr.dtype, lo, hi, src)
    converted = target != arr.dtype or not arr.flags.c_contiguous
    if converted:
        if target != arr.dtype.newbyteorder("="):
            md.setdefault("original_dtype", str(arr.dtype.newbyteorder("=")))
        arr = _convert(arr, target, progress.sub(0.3 if needs_prescan else 0.0, 0.6))
        data.array = arr
    if note:
        data.notes.append(note)

    # Final pass: ranges (cached) and non-finite counts.
    scan = progress.sub(0.6 if converted or needs_prescan else 0.0, 1.0)
    n_c = arr.shape[0]
    total_nonfinite = 0
    ranges: list[tuple[float, float]] = []
    for c in range(n_c):
        c_lo, c_hi, bad = _scan_channel(arr[c], scan.sub(c / n_c, (c + 1) / n_c))
        total_nonfinite += bad
        ranges.append((c_lo, c_hi))
    if total_nonfinite == arr.size:
        raise VolumeReadError(src, "every voxel is NaN or infinite; nothing to display")
    if total_nonfinite:
        md["nonfinite_voxels"] = total_nonfinite
        data.notes.append(
            f"{total_nonfinite} of {arr.size} voxels ({100.0 * total_nonfinite / arr.size:.3g} %)"
            " are NaN or infinite; they are kept and rendered as the minimum"
        )
    for c, (c_lo, c_hi) in enumerate(ranges):
        if c_lo > c_hi:
            data.notes.append(
                f"channel {c} ({data.channel_names[c]!r}) has no finite value; it will be empty"
            )
            ranges[c] = (0.0, 0.0)
        data._stats_cache[data._cache_key("range", c)] = ranges[c]
    if all(r[0] == r[1] for r in ranges):
        data.notes.append(
            "every voxel of each channel has the same value "
            f"({', '.join(f'{r[0]:g}' for r in ranges)}); the volume will look uniform"
        )

    md["dtype"] = str(arr.dtype)
    md["memory_mapped"] = isinstance(arr, np.memmap)  # a conversion above loads it into RAM
    if "bit_depth" not in md:
        md["bit_depth"] = arr.dtype.itemsize * 8
        max_value = max(r[1] for r in ranges)
        # Only for data stored as uint16 (camera data), not for e.g. int32 labels converted.
        native_uint16 = "original_dtype" not in md
        if arr.dtype == np.uint16 and native_uint16 and 0 < max_value <= _TWELVE_BIT_MAX:
            md["bit_depth"] = 12
            data.notes.append(
                f"uint16 data with maximum {max_value:.0f} ≤ {_TWELVE_BIT_MAX}: treated as "
                "12-bit (value range 0–4095)"
            )
    progress(1.0, f"checked {display_name(src)}")
    return data
