"""Builders of lying files (headers that claim what the bytes are not) and a runner that reads
a file in a child process, so that a crash (``std::bad_alloc``, SIGBUS, a segfault) or a hang
fails one test instead of killing pytest."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def assert_one_line(stderr: str, *parts: str) -> str:
    """``stderr`` is exactly one ``vtkvol:`` line holding every part (no log line, no
    traceback); returns that line."""
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("vtkvol: "), stderr
    for part in parts:
        assert part in lines[0], stderr
    return lines[0]


def lying_tiff(
    path: Path,
    *,
    width: int = 4,
    height: int = 4,
    pages: int = 1,
    bits: int = 8,
    samples: int = 1,
    compression: int = 1,
    rows_per_strip: int | None = None,
    strip_offset: int | None = None,
    strip_bytes: int | None = None,
    data: bytes = b"\0" * 64,
    circular: bool = False,
    loop_to: int | None = None,
) -> Path:
    """A little-endian classic TIFF whose pages each have one strip pointing at ``data``; every
    tag says what the arguments say, whatever ``data`` really holds. ``circular``: the last
    page's next-page offset points back at the first page; ``loop_to``: at that page instead
    (the last page itself for ``pages - 1``)."""
    out = bytearray(b"II*\x00\x00\x00\x00\x00")
    data_offset = len(out)
    out += data
    entries = [
        (256, 4, width), (257, 4, height), (258, 3, bits), (259, 3, compression), (262, 3, 1),
        (273, 4, data_offset if strip_offset is None else strip_offset), (277, 3, samples),
        (278, 4, height if rows_per_strip is None else rows_per_strip),
        (279, 4, len(data) if strip_bytes is None else strip_bytes), (284, 3, 1),
    ]
    ifds = []
    for _ in range(pages):
        out += b"\0" * (len(out) % 2)
        ifds.append(len(out))
        out += struct.pack("<H", len(entries))
        for tag, kind, value in entries:
            packed = struct.pack("<HH", value & 0xFFFF, 0) if kind == 3 else struct.pack(
                "<I", value & 0xFFFFFFFF)
            out += struct.pack("<HHI", tag, kind, 1) + packed
        out += b"\0\0\0\0"
    struct.pack_into("<I", out, 4, ifds[0])
    if loop_to is not None:
        circular, ifds_loop = True, ifds[loop_to % pages]
    else:
        ifds_loop = ifds[0]
    following = [*ifds[1:], ifds_loop if circular else 0]
    for ifd, nxt in zip(ifds, following, strict=True):
        struct.pack_into("<I", out, ifd + 2 + 12 * len(entries), nxt)
    path.write_bytes(bytes(out))
    return path


def npy_with_header(path: Path, header: str, payload: bytes = b"", version: int = 1) -> Path:
    """A ``.npy`` file with this header text (padded as numpy pads it) and payload."""
    text = header.encode("utf-8")
    prefix = 10 if version == 1 else 12
    pad = (-(prefix + len(text) + 1)) % 64
    text = text + b" " * pad + b"\n"
    size = struct.pack("<H", len(text)) if version == 1 else struct.pack("<I", len(text))
    path.write_bytes(b"\x93NUMPY" + bytes([version, 0]) + size + text + payload)
    return path


def snapshot(folder: Path) -> dict[str, tuple[int, bytes]]:
    """Every file below ``folder``: its mode and bytes (to assert nothing else changed)."""
    return {
        str(p.relative_to(folder)): (p.stat().st_mode, p.read_bytes())
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink()
    }


@dataclass
class ChildResult:
    returncode: int
    stdout: str
    stderr: str

    @property
    def died_of(self) -> str | None:
        """The signal that killed the child (``"SIGBUS"``), or None."""
        if self.returncode < 0:
            return signal.Signals(-self.returncode).name
        return None


def run_child(code: str, *, timeout: float = 60.0, memory_bytes: int | None = None,
              file_size_bytes: int | None = None, cwd: Path | None = None) -> ChildResult:
    """Run ``code`` in a fresh interpreter (optionally under RLIMIT_AS / RLIMIT_FSIZE). A hang
    past ``timeout`` is reported as a result with returncode ``-9`` and 'timed out' in stderr.
    """
    limits = {"RLIMIT_AS": memory_bytes, "RLIMIT_FSIZE": file_size_bytes}
    prelude = "import resource, signal\n"
    if file_size_bytes is not None:
        # Past the limit write() fails with EFBIG instead of killing the process with SIGXFSZ.
        prelude += "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
    for name, value in limits.items():
        if value is not None:
            prelude += f"resource.setrlimit(resource.{name}, ({value}, {value}))\n"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "tests")}
    try:
        done = subprocess.run(
            [sys.executable, "-c", prelude + textwrap.dedent(code)], capture_output=True,
            text=True, timeout=timeout, env=env, cwd=cwd,
        )
    except subprocess.TimeoutExpired as exc:
        stderr = _text(exc.stderr) + f"\ntimed out after {timeout} s"
        return ChildResult(-9, _text(exc.stdout), stderr)
    return ChildResult(done.returncode, done.stdout, done.stderr)


def _text(value: bytes | str | None) -> str:
    if value is None:
        return ""
    return value.decode(errors="replace") if isinstance(value, bytes) else value


#: Child code: read the volume at argv-like ``PATH``; print ``REFUSED <message>`` (exit 3) for
#: a VolumeReadError, ``OK <shape>`` (exit 0) for a volume, and let anything else escape.
READ_CHILD = """
import sys
from vtkvol.io import VolumeReadError, read_volume
try:
    data = read_volume({path})
except VolumeReadError as exc:
    print("REFUSED", exc)
    sys.exit(3)
print("OK", tuple(data.array.shape))
"""


def read_in_child(path: Path, *, timeout: float = 60.0, memory_bytes: int | None = None,
                  extra: str = "") -> ChildResult:
    """``read_volume(path)`` in a child process (see :data:`READ_CHILD`); ``extra`` runs after a
    successful read with ``data`` bound (e.g. to touch the voxels)."""
    code = READ_CHILD.format(path=json.dumps(str(path))) + textwrap.dedent(extra)
    return run_child(code, timeout=timeout, memory_bytes=memory_bytes)
