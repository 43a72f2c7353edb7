"""Writing a file so that it is either the old one or the new one, never half of each.

Every file vtkvol writes for the user (PNG renders and screenshots, transfer functions,
sessions) goes through :func:`write_atomic`: the bytes go to a temporary file beside the target,
are flushed to disk, and the temporary file is renamed over the target. A failure at any point
(a full disk, a file-size limit, a vanished folder) raises :class:`OSError` and leaves the
target as it was and no temporary file behind. New files get the permissions of any new file
(``0o666`` less the umask: 0644 under umask 022, not ``mkstemp``'s 0600); a replaced file keeps
its own permissions.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
from pathlib import Path

__all__ = ["write_atomic"]


def write_atomic(target: str | os.PathLike[str], content: bytes | str, *,
                 replace: bool = True) -> Path:
    """Write ``content`` (text is UTF-8 with ``\\n`` line ends) to ``target`` atomically.

    With ``replace=False`` an existing ``target`` is never replaced, even one that appeared
    while the content was being made: the file is put in place with a hard link, which fails
    if the name is taken (:class:`FileExistsError`, nothing written).

    Returns
    -------
    Path
        ``target``.

    Raises
    ------
    OSError
        The write failed (``errno`` says why: ``ENOSPC`` for a full disk, ``EFBIG`` past a
        file-size limit); ``target`` is unchanged and no temporary file is left.
    """
    target = Path(target)
    data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(6)}.tmp")
    # O_EXCL: never follow or reuse something already there. Mode 0o666 lets the umask decide.
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except OSError as exc:
        raise type(exc)(exc.errno, exc.strerror, str(target)) from exc
    try:
        try:
            _write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        with contextlib.suppress(FileNotFoundError):
            info = target.stat()
            if stat.S_ISREG(info.st_mode):
                os.chmod(tmp, stat.S_IMODE(info.st_mode))  # replacing keeps the permissions
        if replace:
            os.replace(tmp, target)
        else:
            _place_new(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.errno is not None:
            # Name the file the user chose, not the temporary one (or none, from os.write).
            raise type(exc)(exc.errno, exc.strerror, str(target)) from exc
        raise
    # Make the rename itself durable; not possible (nor needed) on every platform.
    with contextlib.suppress(OSError, AttributeError):
        dir_fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return target


def _place_new(tmp: Path, target: Path) -> None:
    """Rename ``tmp`` to ``target`` unless ``target`` exists (FileExistsError)."""
    try:
        os.link(tmp, target)  # atomic, and refuses an existing name
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS):
            raise
        # a file system without hard links: check, then rename (a narrow race remains)
        if target.exists() or target.is_symlink():
            raise FileExistsError(errno.EEXIST, "File exists", str(target)) from None
        os.replace(tmp, target)
        return
    os.unlink(tmp)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]
