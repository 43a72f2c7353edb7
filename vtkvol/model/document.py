"""The app's open document: the scene model plus what the window shows it on.

A :class:`Document` holds the :class:`~vtkvol.model.scene.SceneModel` (the view's settings)
and the state around it that is not the scene: the data on screen and as read, the session
file it came from or was saved to, the built-in sample's arguments, where the voxel size came
from, the GPU-memory budget given for this run and the pyramid overview that "Back to
overview" returns to. The desktop window and its docks observe it; it imports neither Qt nor
VTK (the data is a :class:`~vtkvol.io.VolumeData`, a numpy array with metadata).

Events follow :mod:`vtkvol.model.evented`: :attr:`Document.changed` emits one
``frozenset[str]`` of the field names that really changed (``{"data", "as_read"}``);
assignments inside :meth:`Document.batch`, and each transition method (:meth:`opened`,
:meth:`saved`, …), are announced once, together.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vtkvol.model.evented import BatchedEvents, Signal, _equal
from vtkvol.model.scene import SceneModel

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: ``window["sample"]`` in a session marks the built-in sample (it has no file to point to).
SAMPLE_KEY = "sample"
#: The arguments of ``confocal_phantom`` a session may store under :data:`SAMPLE_KEY`.
SAMPLE_ARGS = ("shape_zyx", "voxel_size_um", "seed")

#: The document's fields, in the order :meth:`Document.state` lists them.
FIELDS = ("data", "as_read", "session_path", "sample_args", "file_voxel", "voxel_size_chosen",
          "unsaved_data_edit", "budget_override", "overview")

#: Fields compared by identity, not value: two reads of one file are different data, and
#: comparing arrays voxel by voxel on every assignment would cost a pass over the volume.
_BY_IDENTITY = frozenset({"data", "as_read"})


def is_pyramid(data: VolumeData | None) -> bool:
    """Whether ``data`` is one level of a multiscale file (it can be refined)."""
    return data is not None and bool(data.source) and isinstance(data.metadata.get("levels"),
                                                                 list)


def sample_window_state(sample_args: Mapping[str, Any]) -> dict[str, Any]:
    """``sample_args`` as a session stores them (JSON: tuples become lists)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in sample_args.items()}


def sample_kwargs(stored: Mapping[str, Any]) -> dict[str, Any]:
    """Arguments of ``confocal_phantom`` from a session's ``window["sample"]`` (JSON lists
    back to tuples; unknown keys dropped)."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in stored.items()
            if k in SAMPLE_ARGS}


class Document(BatchedEvents):
    """The open document of the app: scene model, data and their provenance.

    Attributes (each assignment of a different value emits its name on :attr:`changed`):

    ``data``
        The :class:`~vtkvol.io.VolumeData` on screen (None before anything is opened).
    ``as_read``
        The data as read, before a voxel size set in the app (its notes and metadata whole).
    ``session_path``
        The session file the view was opened from or last saved to, else None.
    ``sample_args``
        The ``confocal_phantom`` arguments when the built-in sample is shown, else None.
    ``file_voxel``
        The file's own voxel size ((x, y, z) in µm) and whether the file stored it; None when
        the data was opened with a voxel size given (the file's is then not known).
    ``voxel_size_chosen``
        The user chose a voxel size for the data on screen (possibly the assumed
        1 × 1 × 1 µm): the missing-voxel-size warning then goes away.
    ``unsaved_data_edit``
        Changes the undo history does not hold (a new voxel size, another pyramid level)
        since the last open or save.
    ``budget_override``
        GPU-memory budget in bytes given for this run (the command line); None: the stored
        setting applies.
    ``overview``
        What "Back to overview" returns to while a refined region is shown: the overview's
        ``level`` (None: the budget chooses), ``crop`` and ``slice_weights`` (model dumps, µm
        of the overview level); None when the overview (or no pyramid) is shown.
    """

    def __init__(self, scene: SceneModel | None = None) -> None:
        self.scene: SceneModel = scene if scene is not None else SceneModel()
        self._changed = Signal()
        self._batch_depth = 0
        self._pending: set[str] = set()
        self._values: dict[str, Any] = dict.fromkeys(FIELDS)
        self._values["voxel_size_chosen"] = False
        self._values["unsaved_data_edit"] = False

    # -- events (changed, batch: BatchedEvents) ---------------------------------------------
    def _set(self, name: str, value: Any) -> None:
        old = self._values[name]
        same = value is old if name in _BY_IDENTITY else _equal(old, value)
        self._values[name] = value
        if not same:
            self._emit({name})

    # -- fields -------------------------------------------------------------------------------
    @property
    def data(self) -> VolumeData | None:
        return self._values["data"]

    @data.setter
    def data(self, value: VolumeData | None) -> None:
        self._set("data", value)

    @property
    def as_read(self) -> VolumeData | None:
        return self._values["as_read"]

    @as_read.setter
    def as_read(self, value: VolumeData | None) -> None:
        self._set("as_read", value)

    @property
    def session_path(self) -> Path | None:
        return self._values["session_path"]

    @session_path.setter
    def session_path(self, value: str | Path | None) -> None:
        self._set("session_path", None if value is None else Path(value))

    @property
    def sample_args(self) -> dict[str, Any] | None:
        return self._values["sample_args"]

    @sample_args.setter
    def sample_args(self, value: Mapping[str, Any] | None) -> None:
        self._set("sample_args", None if value is None else dict(value))

    @property
    def file_voxel(self) -> tuple[tuple[float, float, float], bool] | None:
        return self._values["file_voxel"]

    @file_voxel.setter
    def file_voxel(self, value: tuple[tuple[float, float, float], bool] | None) -> None:
        self._set("file_voxel", value)

    @property
    def voxel_size_chosen(self) -> bool:
        return self._values["voxel_size_chosen"]

    @voxel_size_chosen.setter
    def voxel_size_chosen(self, value: bool) -> None:
        self._set("voxel_size_chosen", bool(value))

    @property
    def unsaved_data_edit(self) -> bool:
        return self._values["unsaved_data_edit"]

    @unsaved_data_edit.setter
    def unsaved_data_edit(self, value: bool) -> None:
        self._set("unsaved_data_edit", bool(value))

    @property
    def budget_override(self) -> int | None:
        return self._values["budget_override"]

    @budget_override.setter
    def budget_override(self, value: int | None) -> None:
        self._set("budget_override", None if value is None else int(value))

    @property
    def overview(self) -> dict[str, Any] | None:
        return self._values["overview"]

    @overview.setter
    def overview(self, value: Mapping[str, Any] | None) -> None:
        self._set("overview", None if value is None else dict(value))

    # -- state --------------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Every field by name (the data objects themselves, other values copied)."""
        return {name: value if name in _BY_IDENTITY else copy.deepcopy(value)
                for name, value in self._values.items()}

    def restore(self, state: Mapping[str, Any]) -> None:
        """Set the fields named in ``state`` (as :meth:`state` returns them), one event."""
        unknown = set(state) - set(FIELDS)
        if unknown:
            raise ValueError(f"Document has no field {sorted(unknown)[0]!r}")
        with self.batch():
            for name, value in state.items():
                setattr(self, name, value)

    # -- transitions --------------------------------------------------------------------------
    def opened(self, data: VolumeData, *, voxel_size_given: bool,
               sample_args: Mapping[str, Any] | None = None,
               session_path: str | Path | None = None,
               overview: Mapping[str, Any] | None = None) -> None:
        """New data is on screen (a file, the sample or a session): its provenance is fresh,
        nothing is unsaved. ``voxel_size_given``: a voxel size came with the request (the
        command line, the session), so the file's own is not known."""
        with self.batch():
            self.data = data
            self.as_read = data
            self.sample_args = sample_args
            self.file_voxel = None if voxel_size_given else (
                data.voxel_size_um, bool(data.voxel_size_from_metadata))
            self.voxel_size_chosen = False
            self.overview = overview
            self.session_path = session_path
            self.unsaved_data_edit = False

    def time_point_shown(self, read: VolumeData, shown: VolumeData) -> None:
        """Another time point of the same series is on screen: ``read`` as read, ``shown``
        with the view's voxel size."""
        with self.batch():
            self.as_read = read
            self.data = shown

    def voxel_size_set(self, resized: VolumeData | None) -> None:
        """The user chose a voxel size; ``resized`` is the data with it (None: the data on
        screen already has it). Unsaved: the undo history does not hold this change."""
        with self.batch():
            self.voxel_size_chosen = True
            if resized is not None:
                self.data = resized
                self.unsaved_data_edit = True

    def level_shown(self, data: VolumeData, *, overview: Mapping[str, Any] | None) -> None:
        """Another level or region of the same pyramid is on screen (read as is: its voxel
        size is the file's); ``overview`` is what "Back to overview" returns to."""
        with self.batch():
            self.data = data
            self.as_read = data
            self.file_voxel = (data.voxel_size_um, bool(data.voxel_size_from_metadata))
            self.overview = overview
            self.unsaved_data_edit = True

    def saved(self, path: str | Path) -> None:
        """The view was written to session file ``path``: nothing unsaved is left."""
        with self.batch():
            self.session_path = path
            self.unsaved_data_edit = False

    # -- derived ------------------------------------------------------------------------------
    def gpu_budget(self, stored: int) -> int:
        """The GPU-memory budget in bytes: this run's override, else ``stored`` (the
        setting)."""
        return self.budget_override if self.budget_override is not None else int(stored)

    def voxel_size_missing(self) -> bool:
        """Whether the data on screen uses the assumed 1 × 1 × 1 µm voxel size: the file had
        none, none was given on opening (or in the session), and none was chosen since."""
        file_voxel = self.file_voxel
        return (self.data is not None and file_voxel is not None and not file_voxel[1]
                and self.scene.volume.voxel_size_um is None and not self.voxel_size_chosen)

    def data_name(self) -> str:
        """The data's file name, ``"sample"``, ``"in-memory volume"``, or ``""`` (no data)."""
        data = self.data
        if data is None:
            return ""
        if data.source:
            return Path(data.source).name
        return "sample" if self.sample_args is not None else "in-memory volume"

    def can_refine(self) -> bool:
        """Whether Refine selection applies: a pyramid, shown at the file's voxel size."""
        return is_pyramid(self.data) and self.scene.volume.voxel_size_um is None

    def window_extras(self) -> dict[str, Any]:
        """What a session's ``window`` section stores for this document (the sample's
        arguments; a file is referenced by the session's data path instead)."""
        if self.sample_args is None:
            return {}
        return {SAMPLE_KEY: sample_window_state(self.sample_args)}
