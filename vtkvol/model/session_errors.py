"""The errors and warnings of reading and loading sessions (:mod:`vtkvol.model.session`), each
a one-line message naming the file."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any


# -- errors -------------------------------------------------------------------------------------
class SessionError(ValueError):
    """A session file cannot be read or written; the message names the file and the problem.

    E.g. ``"view.vtkvol.json: lights[0].intensity = -2 is below 0"``. The app shows it
    unchanged. ``path`` is the session file, ``problem`` the text after the file name.
    """

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path.name}: {problem}")

    @property
    def session_path(self) -> Path:
        """The session file (same as ``path``)."""
        return self.path


class MissingDataError(SessionError):
    """The session's data file is gone (or the session names none); offer "Locate…".

    Retry with ``load_session_with_data(session_path, data_path=<the located file>)``.
    ``data_path`` is the absolute path that was looked for, or ``None`` when the session
    records no data file (in-memory or sample data).
    """

    def __init__(
        self,
        session_path: str | os.PathLike[str],
        data_path: Path | None,
        *,
        chosen: bool = False,
    ) -> None:
        self.data_path = data_path
        if data_path is None:
            problem = "the session names no data file (it was saved with in-memory data)"
        elif chosen:
            problem = f"the chosen data file {data_path} does not exist"
        else:
            beside = Path(session_path).absolute().parent / data_path.name
            also = (
                f" (also looked for {data_path.name} next to the session)"
                if beside.resolve() != data_path
                else ""
            )
            problem = f"the data file {data_path} is missing{also}"
        super().__init__(session_path, problem)


class DataMismatchError(SessionError):
    """The data file no longer matches the session (shape or number of channels changed).

    ``expected`` and ``found`` are ``{"shape_zyx": (z, y, x), "channels": n}``.
    """

    def __init__(
        self,
        session_path: str | os.PathLike[str],
        data_path: Path,
        expected: dict[str, Any],
        found: dict[str, Any],
    ) -> None:
        self.data_path = data_path
        self.expected = expected
        self.found = found
        super().__init__(
            session_path,
            f"the data no longer matches the session: {data_path.name} now has "
            f"{_describe_shape(found)}, the session was saved with {_describe_shape(expected)}",
        )


class SessionWarning(UserWarning):
    """Something in a session was repaired or ignored; the view still opens."""


def _describe_shape(d: Mapping[str, Any]) -> str:
    parts = []
    if d.get("shape_zyx") is not None:
        parts.append("shape (z, y, x) = ({})".format(", ".join(str(n) for n in d["shape_zyx"])))
    if d.get("channels") is not None:
        parts.append(f"{d['channels']} channel(s)")
    return " and ".join(parts) or "an unknown shape"
