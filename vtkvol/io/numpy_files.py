"""``.npy`` and ``.npz`` volumes.

``.npy`` holds a 3-D ``(z, y, x)`` or 4-D ``[c, z, y, x]`` array and is memory-mapped
(``mmap_mode="r"``), so opening a multi-GB file is instant. ``.npz`` holds the volume under
``volume`` (or as its only array), optionally with ``voxel_size_um`` (x, y, z in µm) and
``channel_names``; it is loaded into memory (zip members cannot be memory-mapped).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vtkvol.io.errors import ReadCancelled, VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.progress import Progress, slabs
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.volume_data import Spacing, VolumeData, default_channel_names, resolve_channels

__all__ = ["NUMPY_READER", "read_npy", "read_npz"]

_NPZ_VOLUME_KEYS = ("volume", "data", "image", "array")


def _as_czyx(array: np.ndarray, source: Path) -> np.ndarray:
    if array.ndim == 3:
        return array[np.newaxis]
    if array.ndim == 4:
        return array
    raise VolumeReadError(
        source,
        f"expected a 3-D (z, y, x) or 4-D (c, z, y, x) array, got {array.ndim}-D shape "
        f"{array.shape}",
    )


def _select(array: np.ndarray, chosen: list[int], progress: Progress, message: str) -> np.ndarray:
    """Selected channels, C-contiguous; a view when nothing needs copying (memmap stays)."""
    if chosen == list(range(array.shape[0])) and array.flags.c_contiguous:
        progress(1.0, message)
        return array
    out = np.empty((len(chosen), *array.shape[1:]), dtype=array.dtype)
    n_z = array.shape[1]
    for sl in slabs(n_z, array[0, 0].nbytes * len(chosen)):
        for j, c in enumerate(chosen):
            out[j, sl] = array[c, sl]
        progress(sl.stop / n_z, f"{message}: slice {sl.stop} of {n_z}")
    return out


def _check_time(time_index: int, source: Path) -> None:
    if time_index != 0:
        raise VolumeReadError(
            source, f"time_index {time_index} is out of range: the file has 1 time point (index 0)"
        )


def read_npy(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Memory-map a ``.npy`` array of shape ``(z, y, x)`` or ``[c, z, y, x]``.

    Voxel size is not stored in ``.npy`` files: 1 µm unless the caller passes one.
    Fortran-ordered arrays are copied into C order (noted), as VTK needs x fastest.
    """
    progress = progress or Progress()
    path = Path(path)
    _check_time(time_index, path)
    try:
        array = np.load(path, mmap_mode="r", allow_pickle=False)
    except OSError as exc:
        raise VolumeReadError(path, f"cannot read the file ({exc})") from exc
    except Exception as exc:  # numpy's header parser also raises SyntaxError, TokenError…
        raise VolumeReadError(path, f"not a readable .npy file ({exc})") from exc
    array = _as_czyx(array, path)
    notes: list[str] = []
    if not array.flags.c_contiguous:
        notes.append("Fortran-ordered array copied into C order (x fastest)")
    names = default_channel_names(array.shape[0])
    chosen = resolve_channels(channels, names, str(path))
    array = _select(array, chosen, progress, "reading")
    notes.append("voxel size not stored in .npy files: using 1 × 1 × 1 µm")
    return VolumeData(
        array,
        Spacing(1.0, 1.0, 1.0),
        [names[c] for c in chosen],
        source=str(path),
        metadata={
            "format": "npy",
            "memory_mapped": isinstance(array, np.memmap),
            "voxel_size_source": "not in file; default 1 µm",
        },
        notes=notes,
    )


def read_npz(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Load a ``.npz`` with a ``volume`` array (or a single array) and optional metadata."""
    progress = progress or Progress()
    path = Path(path)
    _check_time(time_index, path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            keys = list(npz.files)
            key = next((k for k in _NPZ_VOLUME_KEYS if k in keys), None)
            arrays = [k for k in keys if k not in ("voxel_size_um", "channel_names")]
            if key is None and len(arrays) == 1:
                key = arrays[0]
            if key is None:
                raise VolumeReadError(
                    path,
                    f"cannot tell which array is the volume among {keys}; name it 'volume'",
                )
            progress(0.0, f"loading {key!r}")
            _check_member_size(npz, key, path)
            array = npz[key]
            voxel = npz["voxel_size_um"] if "voxel_size_um" in keys else None
            names_array = npz["channel_names"] if "channel_names" in keys else None
    except (VolumeReadError, ReadCancelled):
        raise
    except Exception as exc:  # zip, numpy header and member errors alike: an unreadable file
        raise VolumeReadError(path, f"not a readable .npz file ({exc})") from exc
    array = _as_czyx(array, path)
    names = (
        [str(n) for n in names_array.tolist()]
        if names_array is not None
        else default_channel_names(array.shape[0])
    )
    if len(names) != array.shape[0]:
        raise VolumeReadError(
            path, f"{len(names)} channel_names for {array.shape[0]} channels: {names}"
        )
    chosen = resolve_channels(channels, names, str(path))
    array = _select(array, chosen, progress, "reading")
    metadata: dict[str, Any] = {"format": "npz", "npz_key": key}
    notes: list[str] = []
    if voxel is not None:
        try:
            values = np.asarray(voxel, dtype=float).ravel()
        except (TypeError, ValueError):
            values = np.zeros(0)  # refused just below, with the value
        if values.size == 1:
            values = np.repeat(values, 3)
        if values.size != 3 or not np.all(np.isfinite(values) & (values > 0)):
            raise VolumeReadError(
                path, f"voxel_size_um must hold 3 positive numbers (x, y, z), got {voxel!r}"
            )
        spacing, from_md = Spacing(*(float(v) for v in values)), True
        metadata["voxel_size_source"] = "npz voxel_size_um"
    else:
        spacing, from_md = Spacing(1.0, 1.0, 1.0), False
        metadata["voxel_size_source"] = "not in file; default 1 µm"
        notes.append("the .npz has no voxel_size_um: using 1 × 1 × 1 µm")
    return VolumeData(
        array,
        spacing,
        [names[c] for c in chosen],
        source=str(path),
        voxel_size_from_metadata=from_md,
        metadata=metadata,
        notes=notes,
    )


def _check_member_size(npz: Any, key: str, path: Path) -> None:
    """Read the member's .npy header and refuse sizes this machine cannot hold, before numpy
    allocates them."""
    with npz.zip.open(f"{key}.npy") as member:
        version = np.lib.format.read_magic(member)
        read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                       else np.lib.format.read_array_header_2_0)
        shape, _fortran, dtype = read_header(member, max_header_size=1 << 20)
    nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
    check_declared_bytes(path, nbytes, f"an array of shape {shape} {dtype}")


def _read_numpy(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    reader = read_npz if Path(path).suffix.lower() == ".npz" else read_npy
    return reader(path, time_index=time_index, channels=channels, progress=progress)


NUMPY_READER = ReaderSpec(
    name="numpy",
    label="NumPy array (.npy [c, z, y, x] or (z, y, x); .npz)",
    filename_patterns=("*.npy", "*.npz"),
    accepts_directories=False,
    read=_read_numpy,
)
