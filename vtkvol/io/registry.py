"""Reader discovery: the ``vtkvol.readers`` entry points, with a built-in fallback table.

A reader is a :class:`ReaderSpec`: a name, the filename patterns it handles, whether it
accepts directories, and a ``read`` function. Third-party packages add readers by declaring
an entry point that names a ``ReaderSpec`` object::

    [project.entry-points."vtkvol.readers"]
    mrc = "my_package.mrc:MRC_READER"

The registry is never a ``switch`` on extensions: :data:`BUILTIN_READERS` mirrors vtkvol's
own entry points (a test checks they agree with pyproject.toml) and is only used so that an
uninstalled checkout still finds its readers.
"""

from __future__ import annotations

import fnmatch
import functools
import importlib
import importlib.metadata
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any, Protocol

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.progress import CancelCallback, Progress, ProgressCallback
from vtkvol.io.volume_data import Spacing, VolumeData, as_spacing, normalize_volume

__all__ = [
    "BUILTIN_READERS",
    "ENTRY_POINT_GROUP",
    "ReadFunction",
    "ReaderSpec",
    "available_readers",
    "get_reader",
    "reload_readers",
]

ENTRY_POINT_GROUP = "vtkvol.readers"

BUILTIN_READERS: dict[str, str] = {
    "tiff": "vtkvol.io.tiff:TIFF_READER",
    "raw": "vtkvol.io.raw:RAW_READER",
    "nrrd": "vtkvol.io.raw:NRRD_READER",
    "dat": "vtkvol.io.raw:DAT_READER",
    "numpy": "vtkvol.io.numpy_files:NUMPY_READER",
    "vtk": "vtkvol.io.vti:VTK_READER",
    "nifti": "vtkvol.io.nifti:NIFTI_READER",
    "mrc": "vtkvol.io.mrc:MRC_READER",
    "imaris": "vtkvol.io.imaris:IMARIS_READER",
    "ome_zarr": "vtkvol.io.ome_zarr:OME_ZARR_READER",
    "nd2": "vtkvol.io.nd2:ND2_READER",
    "lif": "vtkvol.io.lif:LIF_READER",
    "czi": "vtkvol.io.czi:CZI_READER",
    # Last on purpose: it claims only files no other reader takes, and only with bioio installed.
    "bioio": "vtkvol.io.bioio_fallback:BIOIO_READER",
}
"""Entry-point name → ``"module:attribute"`` of vtkvol's own readers (same as pyproject.toml)."""


class ReadFunction(Protocol):
    """What a reader implements.

    It returns the voxels as read (any numeric dtype, 4-D ``[c, z, y, x]``); the
    :class:`ReaderSpec` then applies a caller's voxel size and :func:`normalize_volume`.
    It must apply ``time_index`` and ``channels`` itself (so that unread data is never
    loaded), call ``progress(fraction, message)`` per page/slice/chunk (which raises
    :class:`~vtkvol.io.ReadCancelled` on cancel) and raise
    :class:`~vtkvol.io.VolumeReadError` for bad input.
    """

    def __call__(
        self,
        path: Path,
        *,
        time_index: int,
        channels: Sequence[int | str] | None,
        progress: Progress,
    ) -> VolumeData: ...


VoxelSizeArg = Spacing | Sequence[float | None] | float | None


@dataclass(frozen=True)
class ReaderSpec:
    """One reader: what it opens and how.

    Calling the spec reads a file into a checked :class:`VolumeData` (normalised dtype,
    validated values) without fitting it to a texture size; :func:`vtkvol.io.read_volume`
    adds that step.

    Attributes
    ----------
    name
        Short identifier, the entry-point name (``"tiff"``).
    label
        Human-readable, for file dialogs (``"TIFF / OME-TIFF / ImageJ"``).
    filename_patterns
        Lower-case glob patterns matched against the file name (``"*.tif"``).
    accepts_directories
        Whether a folder can be opened; it is offered to this reader when it holds at least
        one file matching ``filename_patterns``.
    read
        The :class:`ReadFunction`.
    """

    name: str
    label: str
    filename_patterns: tuple[str, ...]
    accepts_directories: bool
    read: ReadFunction
    #: ``open_pyramid(path, *, time_index, channels) -> Pyramid`` for formats with resolution
    #: levels (OME-Zarr, Imaris); None for single-resolution formats.
    open_pyramid: Callable[..., Any] | None = None

    def matches(self, path: str | PathLike[str]) -> bool:
        """Whether this reader handles ``path`` (a file by name, a folder by its contents)."""
        p = Path(path)
        if p.is_dir():
            if not self.accepts_directories:
                return False
            try:
                return any(
                    child.is_file() and self._matches_name(child.name) for child in p.iterdir()
                )
            except OSError:
                return False
        return self._matches_name(p.name)

    def _matches_name(self, name: str) -> bool:
        lowered = name.lower()
        return any(fnmatch.fnmatchcase(lowered, pattern) for pattern in self.filename_patterns)

    def __call__(
        self,
        path: str | PathLike[str],
        *,
        voxel_size_um: VoxelSizeArg = None,
        time_index: int = 0,
        channels: Sequence[int | str] | int | str | None = None,
        progress: ProgressCallback | Progress | None = None,
        cancel: CancelCallback | None = None,
        pyramid: Mapping[str, Any] | None = None,
    ) -> VolumeData:
        """Read ``path`` into a checked :class:`VolumeData`.

        Parameters are those of :func:`vtkvol.io.read_volume` (without the fitting ones);
        ``pyramid`` holds the keyword arguments of :func:`vtkvol.io.pyramid.read_pyramid`
        (``budget_bytes``, ``max_texture_size``, ``level``, ``region_um``) for a reader with
        resolution levels; given to another reader, a ``level`` or ``region_um`` is an error.
        """
        override = _voxel_override(voxel_size_um)
        prog = Progress.wrap(progress, cancel)
        prog.check_cancelled()
        if isinstance(channels, (int, str)):
            channels = [channels]
        options = dict(pyramid or {})
        if self.open_pyramid is not None:
            from vtkvol.io.pyramid import read_pyramid

            opened = self.open_pyramid(Path(path), time_index=int(time_index), channels=channels)
            try:
                data = read_pyramid(opened, progress=prog.sub(0.0, 0.8), **options)
            finally:
                opened.close()
        else:
            if options.get("level") is not None or options.get("region_um") is not None:
                raise VolumeReadError(Path(path), f"is not a multiscale image ({self.label}): "
                                                  "it has no pyramid level or region to read")
            data = self.read(
                Path(path), time_index=int(time_index), channels=channels,
                progress=prog.sub(0.0, 0.8),
            )
        data.metadata.setdefault("reader", self.name)
        data.metadata.setdefault("time_points", 1)
        data.metadata.setdefault("time_index", 0)
        if override is None or None in override:
            _check_plausible_voxel_size(data)
        if override is not None:
            _apply_voxel_override(data, override)
        return normalize_volume(data, prog.sub(0.8, 1.0))


#: Voxel sizes a file may declare (µm): 1 pm to 1 m, at most 10⁴ times larger on one axis
#: than on another. Outside them the header is wrong (1e30 µm, a unit mistaken by 10⁹), and the
#: renderer's steps and camera would be meaningless.
PLAUSIBLE_VOXEL_UM = (1e-6, 1e6)
MAX_ANISOTROPY = 1e4


def _check_plausible_voxel_size(data: VolumeData) -> None:
    """Replace an implausible voxel size from the file by 1 × 1 × 1 µm, with a note."""
    size = data.voxel_size_um
    lo, hi = PLAUSIBLE_VOXEL_UM
    if all(lo <= v <= hi for v in size) and max(size) <= MAX_ANISOTROPY * min(size):
        return
    data.notes.append(
        f"the file's voxel size ({size.x:g}, {size.y:g}, {size.z:g}) µm is not plausible "
        f"(each axis 1 pm … 1 m, at most {MAX_ANISOTROPY:g}× another): using 1 × 1 × 1 µm "
        "(pass voxel_size_um to set it)"
    )
    data.voxel_size_um = Spacing(1.0, 1.0, 1.0)
    data.voxel_size_from_metadata = False


def _voxel_override(value: VoxelSizeArg) -> tuple[float | None, float | None, float | None] | None:
    """Validate a caller's voxel size early (before any reading); None entries keep the file's."""
    if value is None:
        return None
    if isinstance(value, (int, float)):
        spacing = as_spacing(value)
        return spacing.x, spacing.y, spacing.z
    values = list(value)
    if len(values) != 3:
        raise ValueError(f"voxel_size_um needs 3 values (x, y, z) in µm, got {values!r}")
    checked: list[float | None] = []
    for v in values:
        if v is None:
            checked.append(None)
            continue
        v = float(v)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"voxel_size_um values must be finite and > 0 µm, got {values!r}")
        checked.append(v)
    return checked[0], checked[1], checked[2]


def _apply_voxel_override(
    data: VolumeData, override: tuple[float | None, float | None, float | None]
) -> None:
    old = data.voxel_size_um
    new = Spacing(*(o if o is not None else f for o, f in zip(override, old, strict=True)))
    given = [axis for axis, o in zip("xyz", override, strict=True) if o is not None]
    if data.voxel_size_from_metadata and new != old:
        data.notes.append(
            f"voxel size ({new.x:g}, {new.y:g}, {new.z:g}) µm given by the caller replaces "
            f"({old.x:g}, {old.y:g}, {old.z:g}) µm from the file"
        )
    data.voxel_size_um = new
    if len(given) == 3:
        data.voxel_size_from_metadata = False
        data.metadata["voxel_size_source"] = "given by the caller"
    else:
        previous = data.metadata.get("voxel_size_source", "file")
        data.metadata["voxel_size_source"] = (
            f"{', '.join(given)} given by the caller; others: {previous}"
        )
        data.voxel_size_from_metadata = False


def _load_object(target: str) -> object:
    module, _, attr = target.partition(":")
    obj: object = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    try:
        return list(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP))
    except Exception:  # broken metadata of an unrelated distribution must not stop reading
        return []


@functools.lru_cache(maxsize=1)
def _readers() -> tuple[ReaderSpec, ...]:
    plugins: list[ReaderSpec] = []
    overrides: dict[str, ReaderSpec] = {}
    for ep in _entry_points():
        try:
            obj = ep.load()
        except Exception as exc:
            warnings.warn(
                f"vtkvol reader entry point {ep.name!r} ({ep.value}) failed to load: {exc}",
                RuntimeWarning,
                stacklevel=2,
            )
            continue
        if not isinstance(obj, ReaderSpec):
            warnings.warn(
                f"vtkvol reader entry point {ep.name!r} ({ep.value}) is a "
                f"{type(obj).__name__}, not a vtkvol.io.registry.ReaderSpec; ignored",
                RuntimeWarning,
                stacklevel=2,
            )
            continue
        if ep.name in BUILTIN_READERS:
            overrides[ep.name] = obj
        elif all(p.name != obj.name for p in plugins):
            plugins.append(obj)
    builtins: list[ReaderSpec] = []
    for name, target in BUILTIN_READERS.items():
        spec = overrides.get(name)
        if spec is None:
            loaded = _load_object(target)
            assert isinstance(loaded, ReaderSpec), target
            spec = loaded
        builtins.append(spec)
    # Plugins first: a plugin that claims a pattern vtkvol also handles wins, on purpose.
    return (*plugins, *builtins)


def available_readers() -> tuple[ReaderSpec, ...]:
    """All readers, in the order :func:`get_reader` tries them (plugins before built-ins)."""
    return _readers()


def reload_readers() -> None:
    """Forget the cached registry (after installing a plugin, or in tests)."""
    _readers.cache_clear()


def get_reader(path: str | PathLike[str]) -> ReaderSpec | None:
    """The reader for ``path``, or None if no reader claims it.

    The returned :class:`ReaderSpec` is callable: ``get_reader(p)(p, time_index=1)``
    returns a checked :class:`VolumeData`.
    """
    for spec in _readers():
        if spec.matches(path):
            return spec
    return None
