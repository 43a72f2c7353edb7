"""`read_volume`: path in, display-ready :class:`VolumeData` out."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from pathlib import Path

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.fit import FIT_STRATEGIES, FitStrategy, fit_volume
from vtkvol.io.limits import check_path, detach_from_file, file_backed
from vtkvol.io.progress import CancelCallback, Progress, ProgressCallback
from vtkvol.io.pyramid import Region
from vtkvol.io.registry import ReaderSpec, VoxelSizeArg, available_readers, get_reader
from vtkvol.io.remote import is_remote
from vtkvol.io.volume_data import VolumeData

__all__ = ["MAX_CHANNELS", "read_volume"]

#: Channels shown at once: VTK's ray caster renders at most four independent components.
MAX_CHANNELS = 4


def read_volume(
    path: str | PathLike[str],
    *,
    voxel_size_um: VoxelSizeArg = None,
    time_index: int = 0,
    channels: Sequence[int | str] | int | str | None = None,
    fit: FitStrategy = "auto",
    max_texture_size: int | None = 2048,
    memory_budget_bytes: int | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelCallback | None = None,
    level: int | None = None,
    region_um: Region | None = None,
) -> VolumeData:
    """Read a volume file or folder into a checked, GPU-sized :class:`VolumeData`.

    Parameters
    ----------
    path
        An ``http(s)://`` or ``s3://`` address of an OME-Zarr store (:mod:`vtkvol.io.remote`;
        only the chunks needed are fetched), a file (``.tif``/``.tiff``, ``.raw``,
        ``.nhdr``/``.nrrd``, ``.dat``, ``.npy``/``.npz``,
        ``.vti``/``.vtk``/``.mha``/``.mhd``, or any pattern a ``vtkvol.readers`` plugin
        declares) or a folder of single-slice TIFFs. A folder holding exactly one stack
        reads that stack; one holding several raises
        :class:`~vtkvol.io.folder.SeveralStacksError` (see
        :func:`~vtkvol.io.folder.read_stacks_as_channels`).
    voxel_size_um
        Overrides the file's voxel size: (x, y, z) in µm, one number for isotropic voxels,
        or a tuple with None entries to keep the file's value on those axes.
    time_index
        Time point to read from files with a T axis (0-based).
    channels
        Channel indices or names to keep, in this order; default all.
    fit
        What to do when the volume exceeds ``max_texture_size`` along an axis or
        ``memory_budget_bytes`` in total: ``"auto"`` (= ``"average"``: block-mean
        downsampling), ``"subsample"``, ``"crop"`` (centred) or ``"none"`` (raise).
    max_texture_size
        Largest number of voxels per axis (the GPU's 3-D texture limit); None: no limit.
    memory_budget_bytes
        Largest size of the voxel data, all channels together; None: no limit. For a
        multiscale image (OME-Zarr, Imaris) it also chooses the pyramid level read: the finest
        that fits (None: :data:`vtkvol.io.pyramid.DEFAULT_GPU_BUDGET_BYTES`).
    progress
        ``progress(fraction, message)``, called per page/slice/chunk with the fraction of
        the whole read (0…1).
    cancel
        ``cancel() -> bool``, polled as often as ``progress``; returning True stops the read
        with :class:`~vtkvol.io.ReadCancelled`.
    level
        Multiscale images only: read this pyramid level (0 = finest) instead of choosing.
    region_um
        Multiscale images only: read only this box, ((x0, x1), (y0, y1), (z0, z1)) µm in
        pyramid space (the finest level's first voxel centre at 0; see
        :mod:`vtkvol.io.pyramid`), at the finest level where it fits the budget.

    Returns
    -------
    VolumeData
        ``array`` 4-D ``[c, z, y, x]`` (uint8/uint16/int16/float32; in memory, or
        memory-mapped when larger than a quarter of this machine's memory: then the file must
        not be overwritten in place while the data is used),
        ``voxel_size_um`` (x, y, z) in µm, channel names, metadata and user-visible notes.

    Raises
    ------
    VolumeReadError
        The file is missing, of an unknown type, corrupt, truncated, ambiguous, empty, all
        NaN, of an unsupported dtype, declares more data than this machine's memory, cannot
        be read in the memory that is free, or does not fit with ``fit="none"``. The message
        names the file and the problem.
    ReadCancelled
        ``cancel()`` returned True.
    ValueError
        Invalid arguments (voxel size ≤ 0, unknown fit strategy).
    """
    if "\x00" in str(path):
        raise VolumeReadError(None, f"the path {str(path)!r} contains a NUL byte")
    p = Path(path).expanduser()
    if fit not in FIT_STRATEGIES:  # checked before a possibly long read
        raise ValueError(f"unknown fit strategy {fit!r}; use one of {FIT_STRATEGIES}")
    prog = Progress(progress, cancel)
    if is_remote(path):  # an OME-Zarr store on a server: Path() would fold its "//"
        from vtkvol.io.remote import remote_reader

        reader = remote_reader(str(path))
    else:
        try:
            exists = p.exists()
        except OSError as exc:  # e.g. a name longer than the file system allows
            raise VolumeReadError(p, f"cannot use this path ({exc.strerror or exc})") from exc
        if not exists:
            raise VolumeReadError(p, f"no such file or folder: {p}")
        check_path(p)
        reader = get_reader(p)
        if p.is_dir() and (reader is None or reader.name == "tiff"):
            p, reader = _one_stack_of(p, reader)
        if reader is None:
            raise VolumeReadError(p, _unknown_type(p))
    try:
        data = reader(
            p,
            voxel_size_um=voxel_size_um,
            time_index=time_index,
            channels=channels,
            progress=prog.sub(0.0, 0.9),
            pyramid={"budget_bytes": memory_budget_bytes, "max_texture_size": max_texture_size,
                     "level": level, "region_um": region_um},
        )
        data = fit_volume(
            data,
            max_texture_size=max_texture_size,
            memory_budget_bytes=memory_budget_bytes,
            strategy=fit,
            progress=prog.sub(0.9, 1.0),
        )
        data.array = detach_from_file(data.array)
        data.metadata["memory_mapped"] = file_backed(data.array)
    except MemoryError as exc:  # the one failure every reader can meet; never a traceback
        raise VolumeReadError(
            p, "there is not enough free memory to read it; close other programs, or read "
               "fewer channels (channels=[...]) or a smaller part (memory_budget_bytes)",
        ) from exc
    if data.n_channels > MAX_CHANNELS:
        raise VolumeReadError(
            p,
            f"has {data.n_channels} channels ({', '.join(data.channel_names)}); vtkvol shows up "
            f"to {MAX_CHANNELS} at once: choose them with channels=[...] (--channels on the "
            "command line)",
        )
    prog(1.0, f"loaded {p.name}")
    return data


def _one_stack_of(folder: Path, reader: ReaderSpec | None) -> tuple[Path, ReaderSpec | None]:
    """A folder of slices stays as it is; a folder holding exactly one stack reads that file;
    several stacks raise :class:`~vtkvol.io.folder.SeveralStacksError` (the app offers a
    choice, the CLI lists them)."""
    from vtkvol.io.folder import SeveralStacksError, folder_stacks

    stacks = folder_stacks(folder)
    if len(stacks) > 1:
        raise SeveralStacksError(folder, stacks)
    if len(stacks) == 1:
        return stacks[0], get_reader(stacks[0])
    return folder, reader


def _unknown_type(path: Path) -> str:
    patterns = sorted({pat for spec in available_readers() for pat in spec.filename_patterns})
    if path.is_dir():
        folders = [spec.label for spec in available_readers() if spec.accepts_directories]
        return (
            "the folder holds no file that a reader accepts as a stack "
            f"({'; '.join(folders)}); expected e.g. *.tif slices"
        )
    suffix = path.suffix or "(no extension)"
    return f"unknown file type {suffix!r}; vtkvol reads {', '.join(patterns)}"
