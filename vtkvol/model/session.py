"""Session files (``*.vtkvol.json``): everything the user set for a view, saved and restored.

A session is a versioned JSON dump of the :class:`~vtkvol.model.SceneModel` (generated from the
model, never from a hand-kept list of keys) plus a reference to the data file (path, size and
a checksum of its first MiB; the voxels are never embedded) and the window layout, which is
opaque UI state. The format is described in docs/session-format.md.

Safety properties, each relied on by the app:

* **No code runs.** Files are parsed with :func:`json.loads` and validated by pydantic; the
  only names looked up are illumination techniques, in the registry of installed ones.
* **Only the chosen file is written.** Saving writes a temporary file beside the target and
  renames it over the target (:func:`os.replace`), so a failed save leaves the previous file
  intact and no temporary file behind. It never overwrites a file that is not a session.
* **Nothing is applied half-way.** :func:`read_session` returns a new model or raises, so
  the caller's scene is untouched by a bad file. Apply a good one in one batch with
  :meth:`Session.apply_to` (one event, one engine rebuild).

Paths to data are stored relative to the session's folder when the data lies in it or below
(so a folder moved or shared as a whole keeps working), absolute otherwise.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import pydantic
from pydantic import BaseModel, ConfigDict, Field

from vtkvol.io.atomic import write_atomic
from vtkvol.io.remote import is_remote
from vtkvol.model import strict_json
from vtkvol.model.migrations import FORMAT, VERSION, migrate
from vtkvol.model.scene import MAX_COORDINATE_UM, SceneModel  # noqa: F401 (the limit it enforces)
from vtkvol.model.session_checks import (
    check_parameters,
    check_view,
    describe_validation_error,
    reduce_transfer_functions,
    show_value,
    technique_known,
)
from vtkvol.model.session_errors import (
    DataMismatchError,
    MissingDataError,
    SessionError,
    SessionWarning,
)

if TYPE_CHECKING:
    from vtkvol.io import VolumeData
    from vtkvol.io.progress import CancelCallback, ProgressCallback

__all__ = [
    "FORMAT",
    "SUFFIX",
    "VERSION",
    "DataMismatchError",
    "MissingDataError",
    "Session",
    "SessionError",
    "SessionWarning",
    "load_session_with_data",
    "migrate",
    "read_session",
    "save_session",
]

SUFFIX = ".vtkvol.json"
"""The file-name ending of session files; :func:`save_session` appends it when missing."""

MAX_SESSION_BYTES = 16 * 2**20
"""Sessions are a few KiB; anything above this is refused unread (probably a data file)."""

HEAD_BYTES = 2**20
"""How much of the data file the recorded checksum covers (enough to notice a new file)."""

_MAX_LISTED = 6  # problems / missing keys named in one message before "and N more"
_TOP_LEVEL_KEYS = frozenset({"format", "version", "vtkvol", "saved", "data", "scene", "window"})


# -- the result of reading ----------------------------------------------------------------------
@dataclass
class Session:
    """A session file, read, migrated and validated.

    Attributes
    ----------
    model
        A new :class:`SceneModel`; ``model.volume.path`` is ``data_path`` as a string.
    data_path
        Absolute path of the data, resolved against the session's folder; ``None`` when the
        session names no data file. It may not exist (see :func:`load_session_with_data`).
    window
        Opaque UI state as saved (e.g. ``{"geometry": ..., "state": ..., "docks": {...}}``).
    path
        The session file.
    warnings
        What was repaired or ignored (missing keys given defaults, unknown techniques, …).
    """

    model: SceneModel
    data_path: Path | None
    window: dict[str, Any]
    path: Path
    warnings: list[str] = field(default_factory=list)

    def apply_to(self, target: SceneModel) -> None:
        """Make ``target`` equal to this session's model with one ``changed`` event.

        Nested models are updated in place (views bound to ``target.crop`` stay bound), lists
        are replaced, and the engine rebuilds once.
        """
        target.update(self.model.model_dump())


# -- saving -------------------------------------------------------------------------------------
def save_session(
    path: str | os.PathLike[str],
    model: SceneModel,
    *,
    data: VolumeData | None = None,
    window: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``model`` (and the window layout) to a session file, atomically.

    Parameters
    ----------
    path
        The session file. ``.vtkvol.json`` is appended when the name does not end with it, so
        a session never replaces a file of another kind; the path really written is returned.
    model
        The scene. With ``data``, its ``volume`` record (``path``, ``size_bytes``,
        ``sha256_head``, ``shape_zyx``, ``channels``) is updated to describe ``data`` once the
        file is written.
    data
        The volume on screen. Its ``source`` file is referenced (relative to the session's
        folder when it lies in it or below) with its size and the SHA-256 of its first MiB.
        Without it, ``model.volume`` is saved as it is.
    window
        Opaque, JSON-serialisable UI state (geometry, dock state) restored as-is.

    Returns
    -------
    Path
        The file written (absolute).

    Raises
    ------
    SessionError
        The target exists and is not a vtkvol session, its folder does not exist, the state
        cannot be represented as JSON (a non-finite number, a non-JSON window value), or the
        write failed. In every case the previous file, if any, is unchanged.
    """
    target = session_target(Path(path).expanduser()).absolute()
    folder = target.parent
    if not folder.is_dir():
        raise SessionError(target, f"cannot save: the folder {folder} does not exist")
    if target.is_dir():
        raise SessionError(target, "cannot save: a folder has this name")
    if target.exists() and not _is_replaceable(target):
        raise SessionError(
            target, "exists and is not a vtkvol session; not overwriting it (choose another name)"
        )
    if window is not None and not isinstance(window, Mapping):
        raise SessionError(
            target, f"cannot save: window must be a dict, not {type(window).__name__}"
        )

    record = _data_record(model, data)
    session_dir = folder.resolve()
    data_abs = None if record["path"] is None else Path(record["path"])
    stored_path = None if data_abs is None else (
        record["path"] if is_remote(record["path"]) else _stored_path(data_abs, session_dir))

    # Technique values are the model's only free-form (Any) field; pydantic cannot dump a
    # numpy scalar a slider may have put there, so they are converted separately.
    scene = model.model_dump(mode="json", exclude={"illumination": {"parameters"}})
    scene["illumination"]["parameters"] = _plain(model.illumination.parameters)
    data_section = {"path": stored_path, **{k: v for k, v in record.items() if k != "path"}}
    scene["volume"].update(data_section)  # the same text as "data": one rule, one place
    from vtkvol import __version__

    document = {
        "format": FORMAT,
        "version": VERSION,
        "vtkvol": __version__,
        "saved": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "data": data_section,
        "scene": scene,
        "window": dict(window or {}),
    }
    # Serialise completely before touching the disk, so a bad value costs nothing.
    try:
        text = _dumps(document) + "\n"
    except ValueError as exc:
        raise SessionError(
            target, f"cannot save: a value is not finite (NaN or infinity): {exc}"
        ) from exc
    except TypeError as exc:
        raise SessionError(target, f"cannot save: a value is not JSON data ({exc})") from exc

    try:
        write_atomic(target, text)
    except OSError as exc:
        raise SessionError(target, f"could not be written: {exc.strerror or exc}") from exc

    if data is not None:
        # Record only after a successful write, so a refused save leaves the model as it was.
        model.update({"volume": record})
    return target


def _plain(value: Any) -> Any:
    """``value`` with numpy scalars turned into Python numbers (containers copied)."""
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if type(value).__module__ == "numpy" and hasattr(value, "item"):
        return value.item()
    return value


def _dumps(value: Any, level: int = 0) -> str:
    """JSON with objects indented and short arrays on one line (``[0.3, 0.5, 0.8]``).

    ``json.dumps(indent=2)`` puts every number of every point on its own line, which makes
    sessions long and hard to read or diff. Raises ``ValueError`` for NaN/infinity and
    ``TypeError`` for anything that is not JSON data, like :func:`json.dumps`.
    """
    pad, inner = "  " * level, "  " * (level + 1)
    if isinstance(value, dict):
        if not value:
            return "{}"
        items = []
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"keys must be strings, not {key!r}")
            items.append(f"{inner}{json.dumps(key, ensure_ascii=False)}: {_dumps(item, level + 1)}")
        return "{\n" + ",\n".join(items) + f"\n{pad}}}"
    if isinstance(value, (list, tuple)):
        if not any(isinstance(v, dict) for v in value):
            flat = json.dumps(value, ensure_ascii=False, allow_nan=False)
            if len(flat) + len(inner) <= 96:
                return flat
        if not value:
            return "[]"
        items = [f"{inner}{_dumps(item, level + 1)}" for item in value]
        return "[\n" + ",\n".join(items) + f"\n{pad}]"
    return json.dumps(value, ensure_ascii=False, allow_nan=False)


def is_session_path(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a session file: its name ends with ``.vtkvol.json`` in any case
    (the one test the CLI, batch rendering and the app use)."""
    return Path(path).name.lower().endswith(SUFFIX)


def session_target(path: str | os.PathLike[str]) -> Path:
    """The file :func:`save_session` writes for ``path``: ``path`` itself when it is a session
    name (:func:`is_session_path`), else with ``.json`` or ``.vtkvol.json`` appended."""
    path = Path(path)
    name = path.name
    if is_session_path(path):
        return path
    if name.lower().endswith(".vtkvol"):
        return path.with_name(name + ".json")
    return path.with_name(name + SUFFIX)


def _is_replaceable(path: Path) -> bool:
    """Whether ``path`` may be overwritten: an empty file or a readable vtkvol session."""
    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):
            return False
        size = info.st_size
        if size == 0:
            return True
        if size > MAX_SESSION_BYTES:
            return False
        raw = json.loads(path.read_bytes().decode("utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return False
    if not isinstance(raw, dict):
        return False
    from vtkvol.model.migrations import detect_version

    try:
        detect_version(raw)
    except ValueError:
        return False
    return True


def _data_record(model: SceneModel, data: VolumeData | None) -> dict[str, Any]:
    """``path`` (absolute or None) and the fingerprint fields to store for the data."""
    vol = model.volume
    if data is None:
        # Keep what was recorded when the data was loaded: re-hashing the file now would
        # hide a change made to it since.
        path = None if vol.path is None else (
            vol.path if is_remote(vol.path) else str(Path(vol.path).expanduser().resolve()))
        return {
            "path": path,
            "size_bytes": vol.size_bytes,
            "sha256_head": vol.sha256_head,
            "shape_zyx": None if vol.shape_zyx is None else list(vol.shape_zyx),
            "channels": vol.channels,
        }
    if is_remote(data.source):  # an address: kept as it is, no file to fingerprint
        return {"path": data.source, "size_bytes": None, "sha256_head": None,
                "shape_zyx": [int(n) for n in data.shape_zyx], "channels": int(data.n_channels)}
    source = None if data.source is None else Path(data.source).expanduser().resolve()
    size, digest = _fingerprint(source) if source is not None and source.exists() else (None, None)
    return {
        "path": None if source is None else str(source),
        "size_bytes": size,
        "sha256_head": digest,
        "shape_zyx": [int(n) for n in data.shape_zyx],
        "channels": int(data.n_channels),
    }


def _stored_path(data_abs: Path, session_dir: Path) -> str:
    """Relative (POSIX separators) when the data is in or below the session's folder."""
    try:
        return data_abs.relative_to(session_dir).as_posix()
    except ValueError:
        return str(data_abs)


def _fingerprint(path: Path) -> tuple[int, str]:
    """``(size in bytes, SHA-256 hex of the first MiB)`` of a file.

    For a folder (a series of slices): the total size of the files directly in it, and the
    checksum of the first MiB of the first of them by name.
    """
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.is_file())
        size = sum(p.stat().st_size for p in files)
        head = files[0] if files else None
    else:
        size, head = path.stat().st_size, path
    digest = hashlib.sha256()
    if head is not None:
        with head.open("rb") as fh:
            digest.update(fh.read(HEAD_BYTES))
    return size, digest.hexdigest()


# -- reading ------------------------------------------------------------------------------------
class _DataRecord(BaseModel):
    """The ``"data"`` section: where the voxels are and how to recognise them."""

    model_config = ConfigDict(extra="forbid", strict=True)

    path: str | None = None
    size_bytes: int | None = Field(None, ge=0)
    sha256_head: str | None = Field(None, pattern=r"^[0-9a-f]{64}$")
    shape_zyx: tuple[Annotated[int, Field(ge=1)], ...] | None = Field(
        None, min_length=3, max_length=3
    )
    channels: int | None = Field(None, ge=1)


_FROM_DATA_SECTION = frozenset(f"volume.{name}" for name in _DataRecord.model_fields)


def read_session(path: str | os.PathLike[str]) -> Session:
    """Parse, migrate and validate a session file; the data file is not read.

    Missing keys take their defaults and unknown techniques keep their stored values, each
    with a note in :attr:`Session.warnings`. Technique parameters are checked against the
    technique's declared ``PARAMETERS`` when it is installed.

    Raises
    ------
    SessionError
        Unreadable file, invalid JSON (with line and column), not a session, written by a
        newer vtkvol, or a wrong type or out-of-range value (with its place in the file,
        e.g. ``lights[0].intensity = -2 is below 0``).
    """
    session_path = Path(path).expanduser().absolute()
    raw = _load_json(session_path)
    try:
        doc = migrate(raw)
    except ValueError as exc:
        raise SessionError(session_path, str(exc)) from exc

    notes: list[str] = []
    unknown = sorted(set(doc) - _TOP_LEVEL_KEYS)
    if unknown:
        notes.append(f"ignored unknown top-level key(s): {', '.join(unknown)}")

    # -- data record
    data_raw = doc.get("data")
    if data_raw is not None and not isinstance(data_raw, dict):
        raise SessionError(session_path, f'"data" must be an object, not {show_value(data_raw)}')
    try:
        record = _DataRecord.model_validate_json(json.dumps(data_raw or {}))
    except pydantic.ValidationError as exc:
        raise SessionError(session_path, describe_validation_error(exc, "data")) from exc

    # -- scene
    scene_raw = doc.get("scene", {})
    if "scene" not in doc:
        notes.append('no "scene" section: every setting takes its default')
    if not isinstance(scene_raw, dict):
        raise SessionError(session_path, f'"scene" must be an object, not {show_value(scene_raw)}')
    try:
        # Strict JSON validation: "2" is not a number and 1 is not true, yet arrays are
        # accepted for tuples, as JSON has no tuples.
        model = SceneModel.model_validate_json(json.dumps(scene_raw), strict=True)
    except pydantic.ValidationError as exc:
        raise SessionError(session_path, describe_validation_error(exc)) from exc
    missing = _missing_paths(scene_raw, model.model_dump(mode="json"))
    if "data" in doc:
        # These come from the "data" section, so their absence from the scene is no loss.
        missing = [m for m in missing if m not in _FROM_DATA_SECTION]
    if missing:
        # Whole sections first: "camera" says more than "lights[0].color".
        missing.sort(key=lambda p: p.count(".") + p.count("["))
        notes.append("missing from the file, defaults used: " + _listing(missing, 10))

    check_view(session_path, model, notes)
    reduce_transfer_functions(model, notes)
    parameters = check_parameters(session_path, model.illumination.parameters, notes)
    if model.illumination.method not in parameters and not technique_known(
        model.illumination.method
    ):
        notes.append(
            f"illumination method {model.illumination.method!r} is not installed here; "
            "its settings are kept"
        )

    # -- data path: the "data" section is authoritative; a hand-written file may only have
    # scene.volume.path.
    stored = record.path if "data" in doc else model.volume.path
    if "data" not in doc:
        notes.append(
            'no "data" section: the data file is taken from scene.volume.path'
            if stored
            else 'no "data" section: the session names no data file'
        )
    data_path = None
    if stored:
        try:
            data_path = _resolve_data_path(stored, session_path.parent.resolve(), notes)
        except (ValueError, OSError) as exc:  # a NUL character, a name too long for the OS
            where = "data.path" if "data" in doc else "volume.path"
            raise SessionError(
                session_path,
                f"{where} = {show_value(stored)} is not a usable path ({_path_error(exc)})"
            ) from exc

    window = doc.get("window", {})
    if not isinstance(window, dict):
        notes.append(f"window layout is not an object ({show_value(window)}); ignored")
        window = {}

    with model.batch():  # a fresh model has no listeners; batch keeps it one logical step
        model.illumination.parameters = parameters
        if "data" in doc:
            model.volume.update(record.model_dump(exclude={"path"}))
        model.volume.path = None if data_path is None else str(data_path)
    return Session(model=model, data_path=data_path, window=window, path=session_path,
                   warnings=notes)


def _load_json(path: Path) -> dict[str, Any]:
    """The parsed top-level object of a session file, or a :class:`SessionError`."""
    if "\x00" in str(path):  # pathlib raises a bare ValueError for it
        raise SessionError(str(path).replace("\x00", "\\0"),
                           "the path contains a NUL character, which no file name has")
    try:
        if path.is_dir():
            raise SessionError(path, "is a folder, not a session file")
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):  # a pipe would block the read forever
            raise SessionError(path, "is not a regular file (a pipe, socket or device)")
        size = info.st_size
        if size > MAX_SESSION_BYTES:
            raise SessionError(
                path,
                f"is {size / 2**20:.0f} MiB, too large for a session file "
                f"(at most {MAX_SESSION_BYTES // 2**20} MiB); is this a data file?",
            )
        blob = path.read_bytes()
    except FileNotFoundError as exc:
        raise SessionError(path, "no such file") from exc
    except OSError as exc:
        raise SessionError(path, f"cannot be read ({exc.strerror or exc})") from exc
    try:
        text = blob.decode("utf-8-sig")  # tolerate a BOM added by a Windows editor
    except UnicodeDecodeError as exc:
        raise SessionError(
            path, f"is not a text file (not UTF-8 at byte {exc.start}); is this a data file?"
        ) from exc
    try:
        raw = strict_json.loads(text)
    except json.JSONDecodeError as exc:
        raise SessionError(
            path, f"is not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}"
        ) from exc
    except ValueError as exc:  # from the two hooks above
        raise SessionError(path, f"is not valid JSON: {exc}") from exc
    except RecursionError as exc:
        raise SessionError(path, "is nested too deeply to be a session file") from exc
    if strict_json.nesting_depth(raw, MAX_NESTING) > MAX_NESTING:
        # copying and validating a deeper document recurses past Python's limit
        raise SessionError(path, f"is nested more than {MAX_NESTING} levels deep, which no "
                                 "session file is")
    if not isinstance(raw, dict):
        raise SessionError(
            path,
            f"is not a vtkvol session (the file holds a JSON {_json_kind(raw)}, not an object)",
        )
    return raw


#: Deepest nesting of objects and lists a session file may have (real ones have under 10).
MAX_NESTING = 64


def _json_kind(value: Any) -> str:
    return {list: "array", str: "string", bool: "boolean", type(None): "null"}.get(
        type(value), "number"
    )


def _resolve_data_path(stored: str, session_dir: Path, notes: list[str]) -> Path:
    """Absolute data path; falls back to a same-named file next to the session. An address
    (http(s)://, s3://) is returned as it is, a string."""
    if is_remote(stored):
        return stored  # type: ignore[return-value]
    candidate = Path(stored).expanduser()
    if not candidate.is_absolute():
        candidate = session_dir / candidate
    candidate = candidate.resolve()
    if candidate.exists():
        return candidate
    # Data moved (or the session was sent along with its data): look beside the session.
    # Backslashes: the file may have been saved on Windows.
    name = stored.replace("\\", "/").rstrip("/").rsplit("/", 1)[-1]
    beside = session_dir / name
    if name and beside.exists() and beside != candidate:
        notes.append(
            f"data file {candidate} not found; using {beside} (same name, next to the session)"
        )
        return beside
    return candidate


def _missing_paths(raw: Any, full: Any, prefix: str = "") -> list[str]:
    """Dotted paths present in the validated model but absent from the file.

    Derived from the model's own dump, so it follows the model as fields are added. A missing
    section is named once, not field by field.
    """
    out: list[str] = []
    if isinstance(raw, dict) and isinstance(full, dict):
        for key, value in full.items():
            where = f"{prefix}.{key}" if prefix else key
            if key not in raw:
                out.append(where)
            else:
                out.extend(_missing_paths(raw[key], value, where))
    elif isinstance(raw, list) and isinstance(full, list) and len(raw) == len(full):
        for i, (r, f) in enumerate(zip(raw, full, strict=True)):
            out.extend(_missing_paths(r, f, f"{prefix}[{i}]"))
    return out


def _listing(items: list[str], limit: int = _MAX_LISTED) -> str:
    shown = ", ".join(items[:limit])
    more = len(items) - limit
    return f"{shown} and {more} more" if more > 0 else shown


# -- loading with the data ----------------------------------------------------------------------
def load_session_with_data(
    path: str | os.PathLike[str],
    *,
    data_path: str | os.PathLike[str] | None = None,
    time_index: int | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelCallback | None = None,
    on_warning: Callable[[str], None] | None = None,
) -> tuple[SceneModel, VolumeData]:
    """Read a session and its data, read the way it was when the session was saved.

    Parameters
    ----------
    path
        The session file.
    data_path
        Use this data file instead of the recorded one (the answer to "Locate…").
    time_index
        Read this time point instead of the recorded one (``vtkvol batch --time``: one view
        rendered over a time series); ``model.volume.time_index`` says which was read.
    progress, cancel
        Passed to :func:`vtkvol.io.read_volume`.
    on_warning
        Called with each note (session repairs, changed checksum). Default: issued as a
        :class:`SessionWarning` through :func:`warnings.warn`.

    Returns
    -------
    (SceneModel, VolumeData)
        ``model.volume.path`` is the data file actually read.

    Raises
    ------
    SessionError
        As :func:`read_session`; also for a ``data_path`` the operating system cannot use (a
        NUL character, a name too long).
    MissingDataError
        The data file does not exist, or the session names none; retry with ``data_path``.
    DataMismatchError
        The data's shape (z, y, x) or number of channels differs from what was recorded. A
        different size or checksum with the same shape is only a warning.
    vtkvol.io.VolumeReadError
        The data file exists but cannot be read.
    """
    session = read_session(path)
    model = session.model
    try:
        target = (
            Path(data_path).expanduser().resolve() if data_path is not None else session.data_path
        )
        exists = target is not None and (is_remote(target) or target.exists())
    except (ValueError, OSError) as exc:  # a NUL character, a name too long for the OS
        raise SessionError(
            session.path,
            f"the chosen data file {show_value(str(data_path))} is not a usable path "
            f"({_path_error(exc)})",
        ) from exc
    if target is None or not exists:
        raise MissingDataError(session.path, target, chosen=data_path is not None)

    vol = model.volume
    changed = _fingerprint_change(target, vol.size_bytes, vol.sha256_head)

    from vtkvol.io import read_volume

    data = read_volume(
        target,
        voxel_size_um=vol.voxel_size_um,
        time_index=vol.time_index if time_index is None else time_index,
        fit=vol.fit,
        progress=progress,
        cancel=cancel,
        level=vol.level,
        region_um=vol.region_um,
    )
    expected = {"shape_zyx": vol.shape_zyx, "channels": vol.channels}
    found = {"shape_zyx": tuple(int(n) for n in data.shape_zyx), "channels": int(data.n_channels)}
    if any(v is not None and _as_tuple(v) != _as_tuple(found[k]) for k, v in expected.items()):
        raise DataMismatchError(session.path, target, expected, found)

    notes = list(session.warnings)
    if changed:
        notes.append(
            f"data file {target.name} changed since the session was saved ({changed}); "
            "its shape and channels match, so the view is restored"
        )
    model.volume.path = str(target)
    if time_index is not None:
        model.volume.time_index = time_index
    for note in notes:
        if on_warning is not None:
            on_warning(note)
        else:
            warnings.warn(f"{session.path.name}: {note}", SessionWarning, stacklevel=2)
    return model, data


def _path_error(exc: ValueError | OSError) -> str:
    """Why the operating system refused a path, in words."""
    if isinstance(exc, OSError):
        return str(exc.strerror or exc).lower()
    return "it contains a NUL character" if "null" in str(exc) else str(exc)


def _as_tuple(value: Any) -> Any:
    """Lists and tuples compare equal by content (JSON gives lists, readers give tuples)."""
    return tuple(value) if isinstance(value, (list, tuple)) else value


def _fingerprint_change(path: Path, size: int | None, digest: str | None) -> str:
    """What differs from the recorded size and checksum, in words ('' when nothing does)."""
    if size is None and digest is None:
        return ""
    if not (path.is_file() or path.is_dir()):
        return ""  # a pipe or device: reading it could block; read_volume says what it is
    try:
        now_size, now_digest = _fingerprint(path)
    except OSError:
        return ""  # unreadable here; read_volume will say why
    if size is not None and size != now_size:
        return f"size {size} → {now_size} bytes"
    if digest is not None and digest != now_digest:
        return "different content at the start of the file"
    return ""
