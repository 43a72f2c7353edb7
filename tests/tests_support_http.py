"""A real HTTP server on 127.0.0.1 for the remote OME-Zarr tests: serves a folder, answers
single byte ranges (206), counts every body byte it sends, per path, and can misbehave
(refuse with 403, ignore ranges, answer late)."""

from __future__ import annotations

import threading
import time
from collections import Counter
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np


class CountingServer:
    """Serves ``root`` at ``http://127.0.0.1:<port>/``; use as a context manager.

    ``sent`` counts body bytes per URL path (errors' bodies included), ``requests`` the
    requests per path. ``mode``: ``"ok"``, ``"forbidden"`` (403 everywhere), ``"no_range"``
    (200 and the whole file whatever the Range header says); ``delay_s`` delays each answer.
    """

    def __init__(self, root: Path, *, mode: str = "ok", delay_s: float = 0.0) -> None:
        self.root = Path(root)
        self.mode = mode
        self.delay_s = delay_s
        self.sent: Counter[str] = Counter()
        self.requests: Counter[str] = Counter()
        self._lock = threading.Lock()
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: object) -> None:  # quiet
                pass

            def _body(self, status: int, body: bytes, headers: dict[str, str]) -> None:
                self.send_response(status)
                for k, v in headers.items():
                    self.send_header(k, v)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                if self.command != "HEAD":
                    try:
                        self.wfile.write(body)
                    except (BrokenPipeError, ConnectionResetError):
                        return
                    server._count(self.path, len(body))

            def do_HEAD(self) -> None:
                self.do_GET()

            def do_GET(self) -> None:
                path = unquote(urlsplit(self.path).path)
                with server._lock:
                    server.requests[path] += 1
                if server.delay_s:
                    time.sleep(server.delay_s)
                if server.mode == "forbidden":
                    self._body(403, b"forbidden", {})
                    return
                file = (server.root / path.lstrip("/")).resolve()
                if server.root.resolve() not in file.parents or not file.is_file():
                    self._body(404, b"not found", {})
                    return
                data = file.read_bytes()
                ranged = self.headers.get("Range", "")
                if server.mode != "no_range" and ranged.startswith("bytes="):
                    first, _, last = ranged[6:].partition("-")
                    if not first:  # suffix range: the last N bytes
                        start, end = max(0, len(data) - int(last)), len(data) - 1
                    else:
                        start = int(first)
                        end = min(len(data) - 1, int(last)) if last else len(data) - 1
                    if start >= len(data):
                        self._body(416, b"", {"Content-Range": f"bytes */{len(data)}"})
                        return
                    self._body(206, data[start:end + 1], {
                        "Content-Range": f"bytes {start}-{end}/{len(data)}",
                        "Accept-Ranges": "bytes"})
                    return
                headers = {} if server.mode == "no_range" else {"Accept-Ranges": "bytes"}
                self._body(200, data, headers)

        self._server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)

    def _count(self, raw_path: str, n: int) -> None:
        with self._lock:
            self.sent[unquote(urlsplit(raw_path).path)] += n

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        return f"http://{host}:{port}"

    def total(self) -> int:
        with self._lock:
            return sum(self.sent.values())

    def reset(self) -> None:
        with self._lock:
            self.sent.clear()
            self.requests.clear()

    def __enter__(self) -> CountingServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(5)


METADATA_NAMES = {"zarr.json", ".zarray", ".zattrs", ".zgroup", ".zmetadata"}


def chunk_files(level_folder: Path) -> dict[tuple[int, ...], Path]:
    """The chunk files of one level of a Zarr v2 store written with ``/`` separators:
    ``{(c, z, y, x) chunk index: file}``."""
    out = {}
    for f in level_folder.rglob("*"):
        if f.is_file() and f.name not in METADATA_NAMES:
            parts = f.relative_to(level_folder).parts
            if parts and parts[0] == "c":  # Zarr v3 default keys: c/…
                parts = parts[1:]
            out[tuple(int(p) for p in parts)] = f
    return out


SIDE = 64
CHUNK = 16
VOXEL = {"z": 1.0, "y": 0.5, "x": 0.5}
WINDOW = {"start": 0, "end": 4000, "min": 0, "max": 65535}


def phantom() -> np.ndarray:
    """2 channels of 64³ uint16 (the writer halves x and y per level, not z): noise (so that
    chunks do not compress to nothing) on an off-centre ball in channel 0 and a slab in
    channel 1."""
    rng = np.random.default_rng(3)
    z, y, x = np.mgrid[:SIDE, :SIDE, :SIDE]
    ball = ((x - 20) ** 2 + (y - 40) ** 2 + (z - 30) ** 2 < 15 ** 2) * 3000
    slab = (x > 44) * 2000
    noise = rng.integers(0, 400, size=(2, SIDE, SIDE, SIDE))
    return (np.stack([ball, slab]) + noise).astype(np.uint16)


def write_served_stores(root: Path) -> Path:
    """``cells.ome.zarr`` (NGFF 0.4, 5 levels, 16³ chunks) and ``plain.zarr`` (a Zarr group
    that is not an OME-Zarr image) in one served folder."""
    import ome_zarr.format as ome_format
    import ome_zarr.writer as writer
    import zarr

    fmt = ome_format.FormatV04()
    group = zarr.open_group(str(root / "cells.ome.zarr"), mode="w", zarr_format=2)
    writer.write_image(
        phantom(), group, axes="czyx", fmt=fmt, scale_factors=(2, 4, 8, 16),
        scale={"c": 1.0, **VOXEL}, axes_units={a: "micrometer" for a in "zyx"},
        storage_options={"chunks": (1, CHUNK, CHUNK, CHUNK)},
        omero={"channels": [{"label": label, "color": color, "window": WINDOW}
                            for label, color in (("DAPI", "0000FF"), ("GFP", "00FF00"))]},
    )
    plain = zarr.open_group(str(root / "plain.zarr"), mode="w", zarr_format=2)
    plain.create_array("data", shape=(4, 4), dtype="u1")
    return root
