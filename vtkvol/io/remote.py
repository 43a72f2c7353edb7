"""OME-Zarr images on a web server (``http://``, ``https://``) or in object storage (``s3://``).

The store is read through fsspec (optional extra ``remote``: fsspec, aiohttp, s3fs) by zarr,
which fetches one object per chunk it needs: the metadata of the group and of each level
(a few hundred bytes each), then the chunks that the chosen pyramid level — or the region of
it (Refine selection) — overlaps. Nothing else is downloaded; see :mod:`vtkvol.io.pyramid`
for how the level is chosen from the GPU budget.

Before zarr is involved, an HTTP(S) address is probed once with the standard library (the
group's metadata file, asked for with ``Range: bytes=0-0``), so that each way a server can
fail gets one line that says what happened, instead of a stack of aiohttp exceptions:

* the host cannot be reached (DNS failure, connection refused) — :data:`UNREACHABLE`;
* no Zarr store at the address (HTTP 404 for both ``zarr.json`` and ``.zgroup``);
* HTTP 401/403: the server refuses access;
* no answer within :data:`TIMEOUT_S` seconds;
* a server that ignores range requests (answers 200 with the whole file to a 1-byte
  ``Range``): sharded stores (NGFF 0.5) are read as byte ranges of their shard files, and a
  server that sends whole files instead would move gigabytes for a few chunks.

A store that answers but holds no ``multiscales`` metadata is reported by the OME-Zarr reader
("not an OME-Zarr image"). Addresses are named in full in every message.
"""

from __future__ import annotations

import socket
import ssl
import urllib.error
import urllib.request
from collections.abc import Sequence
from typing import Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.ome_zarr import ZarrPyramid, open_ome_zarr, read_ome_zarr
from vtkvol.io.registry import ReaderSpec

__all__ = ["SCHEMES", "TIMEOUT_S", "RemoteZarrPyramid", "fetch_progress", "is_remote",
           "open_remote_ome_zarr", "probe_http", "remote_reader"]

#: Address prefixes read as remote OME-Zarr stores.
SCHEMES = ("http://", "https://", "s3://")

#: Seconds to wait for a server's answer (connecting, and each read) before giving up.
TIMEOUT_S = 30.0


def is_remote(path: Any) -> bool:
    """Whether ``path`` is an address of a remote store (a string starting with a scheme in
    :data:`SCHEMES`), not a local file."""
    return isinstance(path, str) and path.lower().startswith(SCHEMES)


def _host(url: str) -> str:
    rest = url.split("://", 1)[1]
    return rest.split("/", 1)[0] or "(no host)"


def _reason(exc: BaseException) -> str:
    """A short phrase for an OS-level network error."""
    if isinstance(exc, socket.gaierror):
        return "the name does not resolve"
    if isinstance(exc, ConnectionRefusedError):
        return "connection refused"
    if isinstance(exc, ssl.SSLError):
        return f"TLS failed ({exc.reason or exc})"
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return text[0].lower() + text[1:] if text else type(exc).__name__


def _timed_out(exc: BaseException) -> bool:
    return isinstance(exc, (TimeoutError, socket.timeout)) or "timed out" in str(exc).lower()


def _fetch_probe(url: str) -> tuple[int, int, str]:
    """``(status, bytes received, Content-Range)`` of a 1-byte range request for ``url``;
    HTTPError for 4xx/5xx, URLError/OSError when no answer comes."""
    request = urllib.request.Request(url, headers={"Range": "bytes=0-0",
                                                   "User-Agent": "vtkvol"})
    with urllib.request.urlopen(request, timeout=TIMEOUT_S) as response:
        # Read at most a little more than asked: a server ignoring Range sends the whole file.
        body = response.read(64)
        return response.status, len(body), response.headers.get("Content-Range", "")


def probe_http(url: str) -> None:
    """Check that ``url`` (http or https) is a Zarr store on a reachable server that answers
    range requests; raises VolumeReadError naming ``url`` with the one-line reason if not."""
    base = url.rstrip("/")
    missing: list[str] = []
    for name in ("zarr.json", ".zgroup", ".zattrs"):
        try:
            status, received, content_range = _fetch_probe(f"{base}/{name}")
        except urllib.error.HTTPError as exc:
            if exc.code == 404:
                missing.append(name)
                continue
            if exc.code in (401, 403):
                raise VolumeReadError(url, f"the server refuses access (HTTP {exc.code} "
                                           f"{exc.reason}): it needs credentials or the store "
                                           "is not public") from None
            if exc.code == 416:  # an empty metadata file cannot satisfy byte 0
                raise VolumeReadError(url, f"{name} on the server is empty") from None
            raise VolumeReadError(url, f"the server answered HTTP {exc.code} {exc.reason} "
                                       f"for {name}") from None
        except urllib.error.URLError as exc:
            reason = exc.reason if isinstance(exc.reason, BaseException) else OSError(exc.reason)
            if _timed_out(reason):
                raise VolumeReadError(url, f"the server did not answer within {TIMEOUT_S:g} s "
                                           "(timeout)") from None
            raise VolumeReadError(url, f"cannot reach the host {_host(url)} "
                                       f"({_reason(reason)})") from None
        except OSError as exc:  # a timeout while reading the answer, a reset connection
            if _timed_out(exc):
                raise VolumeReadError(url, f"the server did not answer within {TIMEOUT_S:g} s "
                                           "(timeout)") from None
            raise VolumeReadError(url, f"the connection to {_host(url)} failed "
                                       f"({_reason(exc)})") from None
        if status == 200 and received > 1 and not content_range:
            raise VolumeReadError(url, "the server does not support HTTP range requests "
                                       "(it sent the whole file for 'Range: bytes=0-0'); vtkvol "
                                       "reads chunks as byte ranges and needs them")
        return
    raise VolumeReadError(url, f"no Zarr store at this address (HTTP 404 Not Found for "
                               f"{', '.join(missing)})")


def _network_problem(exc: BaseException) -> str | None:
    """The one-line reason for a network failure raised by fsspec/aiohttp/s3fs while zarr
    read metadata or chunks, or None when ``exc`` is not a network failure."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        status = getattr(exc, "status", None) or getattr(exc, "code", None)
        name = type(exc).__name__
        if isinstance(status, int) and status in (401, 403):
            return f"the server refuses access (HTTP {status}): it needs credentials"
        if isinstance(exc, PermissionError):
            return "access denied: it needs credentials or the store is not public"
        if _timed_out(exc) or name in ("ServerTimeoutError", "ConnectTimeoutError"):
            return f"the server did not answer within {TIMEOUT_S:g} s (timeout)"
        if name.startswith("ClientConnector") or isinstance(exc, ConnectionError):
            return f"the connection failed ({_reason(exc)})"
        if name in ("ClientResponseError", "ClientPayloadError", "ServerDisconnectedError"):
            return f"the server broke off the transfer ({name}: {exc})"
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return None


class RemoteZarrPyramid(ZarrPyramid):
    """A :class:`~vtkvol.io.ome_zarr.ZarrPyramid` whose chunks come over the network: a
    failed fetch is reported as a network failure, not as a corrupt chunk."""

    #: Blocks of :func:`~vtkvol.io.pyramid.read_pyramid` no larger than one row of chunks
    #: (its lower bound): progress moves per row fetched, not per 32 MiB; zarr still fetches
    #: the chunks of a row concurrently.
    slab_bytes = 64 << 10

    def read_block(self, level: int, channel: int, z: slice, y: slice, x: slice) -> np.ndarray:
        try:
            return super().read_block(level, channel, z, y, x)
        except Exception as exc:
            problem = _network_problem(exc)
            if problem is None:
                raise
            raise VolumeReadError(self.source, f"fetching level {self.levels[level].name!r}: "
                                               f"{problem}") from exc


def _storage_options(url: str) -> dict[str, Any]:
    if url.lower().startswith("s3://"):
        # Public buckets are read without credentials unless the environment has them.
        return {"anon": False, "config_kwargs": {"connect_timeout": TIMEOUT_S,
                                                 "read_timeout": TIMEOUT_S}}
    try:
        import aiohttp
    except ImportError:
        return {}
    return {"client_kwargs": {"timeout": aiohttp.ClientTimeout(
        total=None, sock_connect=TIMEOUT_S, sock_read=TIMEOUT_S)}}


def _open_group(url: str) -> Any:
    """The zarr group at ``url``, read-only, through fsspec."""
    try:
        import zarr
    except ImportError:
        raise VolumeReadError(url, "reading OME-Zarr needs the optional package 'zarr': pip "
                                   "install 'vtkvol[formats,remote]'") from None
    needed = "s3fs" if url.lower().startswith("s3://") else "aiohttp"
    for module in ("fsspec", needed):
        try:
            __import__(module)
        except ImportError:
            raise VolumeReadError(url, f"reading a remote store needs the optional package "
                                       f"{module!r}: pip install 'vtkvol[remote]'") from None
    options = _storage_options(url)
    try:
        if int(zarr.__version__.split(".")[0]) >= 3:
            from zarr.storage import FsspecStore

            store = FsspecStore.from_url(url.rstrip("/"), storage_options=options,
                                         read_only=True)
        else:  # zarr 2 (Python 3.10)
            from zarr.storage import FSStore

            store = FSStore(url.rstrip("/"), mode="r", **options)
        return zarr.open_group(store=store, mode="r")
    except VolumeReadError:
        raise
    except Exception as exc:  # zarr/fsspec raise many types
        problem = _network_problem(exc)
        if problem is None:
            problem = (f"not a readable Zarr group ({type(exc).__name__}: "
                       f"{' '.join(str(exc).split())})")
        raise VolumeReadError(url, problem) from None


def open_remote_ome_zarr(url: str, *, time_index: int = 0,
                         channels: Sequence[int | str] | None = None) -> RemoteZarrPyramid:
    """Open the OME-Zarr image at ``url`` as a pyramid (metadata only: each level's
    ``zarr.json``/``.zarray``; no chunk is fetched). Raises VolumeReadError naming ``url``."""
    if url.lower().startswith(("http://", "https://")):
        probe_http(url)
    group = _open_group(url)
    try:
        pyramid = open_ome_zarr(url, time_index=time_index, channels=channels, group=group,
                                pyramid_type=RemoteZarrPyramid)
    except VolumeReadError:
        raise
    except Exception as exc:
        problem = _network_problem(exc)
        if problem is None:
            raise
        raise VolumeReadError(url, problem) from None
    pyramid.metadata["remote"] = True
    return pyramid  # type: ignore[return-value]


def remote_reader(url: str) -> ReaderSpec:
    """A :class:`~vtkvol.io.registry.ReaderSpec` reading the remote store at ``url`` (the path
    the spec is called with is ignored: ``pathlib.Path`` would fold the ``//`` of the
    address)."""

    def open_pyramid(_path: Any, *, time_index: int = 0,
                     channels: Sequence[int | str] | None = None) -> RemoteZarrPyramid:
        return open_remote_ome_zarr(url, time_index=time_index, channels=channels)

    return ReaderSpec(
        name="ome_zarr",
        label="OME-Zarr over HTTP(S)/S3",
        filename_patterns=(),
        accepts_directories=False,
        read=read_ome_zarr,
        open_pyramid=open_pyramid,
    )


def fetch_progress(url: str, stream: Any = None) -> Any:
    """A ``progress(fraction, message)`` callback for the command line: one line per whole
    10 % of a remote read on ``stream`` (stderr), so a slow download shows that it moves."""
    import sys

    host = _host(url)
    last = [-1]

    def report(fraction: float, message: str) -> None:
        step = int(fraction * 10)
        if step == last[0]:
            return
        last[0] = step
        print(f"fetching {host}: {message} {fraction:4.0%}", file=stream or sys.stderr,
              flush=True)

    return report
