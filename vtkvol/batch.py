"""Batch rendering on Dask distributed: many sessions or time points, one PNG each.

Library code, no Qt (``vtkvol batch`` is the command-line front end). A :class:`RenderJob` names
one input (a session file ``*.vtkvol.json``, a volume file or folder, or ``"sample"``), an
optional time point and one PNG to write; :func:`run_batch` sends the jobs to a
``dask.distributed`` cluster — a :class:`distributed.LocalCluster` of worker *processes* with one
thread each by default (a VTK render window and its EGL/GLX context belong to one process, and
one thread per process keeps one context per worker), or an existing scheduler by address — and
reports each job as it finishes. Dask distributed is used rather than a home-made process pool
because the same code then runs on a workstation and on a cluster (``dask-jobqueue`` for SLURM,
see ``docs/batch.md``), with worker failure detection and a dashboard for free.

Every job renders through :func:`vtkvol.engine.api.render_image`, the same call as
``vtkvol render``, so a batch image equals the one ``vtkvol render`` makes of the same input,
and writes its PNG atomically (``vtkvol.io.atomic``: a temporary file beside the target, then
``os.replace``); an existing PNG is never replaced unless ``overwrite=True``. A job that fails
(unreadable input, a time point past the end, a crashed worker) is reported with a one-line
message naming it; the other jobs go on.

Paths are made absolute when a job is planned: workers on other machines must see the files
under the same names (a shared file system), as with any dask cluster.
"""

from __future__ import annotations

import itertools
import logging
import os
import re
import time
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vtkvol.model.session import SUFFIX as SESSION_SUFFIX
from vtkvol.model.session import is_session_path

if TYPE_CHECKING:
    import numpy as np

__all__ = [
    "BatchError",
    "JobResult",
    "RenderJob",
    "RenderOptions",
    "existing_outputs",
    "max_local_workers",
    "parse_time_range",
    "plan_jobs",
    "render_job",
    "render_job_image",
    "run_batch",
    "scheduler_address_problem",
]


#: How long to wait for an existing scheduler to answer before giving up (seconds).
DEFAULT_CONNECT_TIMEOUT_S = 10.0
#: Most images one batch renders (inputs × time points): checked before the jobs are listed
#: (``--time 0:1000000000000`` listed 10¹² jobs into a MemoryError).
MAX_JOBS = 100_000
#: Schemes of a scheduler address that dask's TCP-like transports understand.
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")

ProgressCallback = Callable[[int, int, "JobResult"], None]
"""``progress(jobs_done, jobs_total, result_of_the_job_just_finished)``."""


class BatchError(RuntimeError):
    """The batch could not start: no scheduler at the address, ``distributed`` missing, …"""


@dataclass(frozen=True)
class RenderOptions:
    """What ``vtkvol render`` lets one choose, for every job of a batch.

    ``size`` is (width, height) in pixels; ``azimuth``/``elevation`` in degrees (from the
    front view, or orbiting a session's camera); ``voxel_size`` (x, y, z) in µm overrides the
    file's (volume files only; a session keeps its own); ``max_seconds`` bounds the refinement
    of progressive methods per job.
    """

    size: tuple[int, int] = (800, 600)
    azimuth: float | None = None
    elevation: float | None = None
    method: str | None = None
    preset: str | None = None
    parameters: dict[str, Any] = field(default_factory=dict)
    blend: str | None = None
    voxel_size: tuple[float, float, float] | None = None
    iterations: int | None = None
    max_seconds: float | None = 300.0


@dataclass(frozen=True)
class RenderJob:
    """One render: ``source`` (absolute path, or ``"sample"``) at ``time_index`` (None: the
    session's time point, or 0 for a volume file) to the PNG ``output`` (absolute path)."""

    source: str
    output: str
    time_index: int | None = None
    options: RenderOptions = field(default_factory=RenderOptions)

    @property
    def name(self) -> str:
        """How messages name the job: the input's file name and the time point."""
        base = self.source if self.source == "sample" else Path(self.source).name
        return base if self.time_index is None else f"{base} t={self.time_index}"


@dataclass(frozen=True)
class JobResult:
    """What became of one job. ``error`` is one line ('' when it succeeded); ``notes`` are
    the technique's fallback messages and session warnings (the image was still written);
    ``seconds`` is the job's wall time on its worker; ``worker`` the worker's address."""

    job: RenderJob
    ok: bool
    error: str = ""
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    worker: str = ""


def parse_time_range(text: str) -> range:
    """``"3"`` → time point 3; ``"0:20"`` → 0…19 (half-open, like a Python slice);
    ``"0:20:5"`` → 0, 5, 10, 15. Raises ValueError with what is wrong."""
    match = re.fullmatch(r"\s*(\d+)\s*(?::\s*(\d+)\s*(?::\s*(\d+)\s*)?)?", text)
    if not match:
        raise ValueError(f"--time takes T or START:STOP[:STEP] (whole numbers >= 0), "
                         f"got {text!r}")
    start = int(match.group(1))
    if match.group(2) is None:
        return range(start, start + 1)
    stop, step = int(match.group(2)), int(match.group(3) or 1)
    if step < 1:
        raise ValueError(f"--time: the step must be at least 1, got {step}")
    if stop <= start:
        raise ValueError(f"--time {text}: STOP is excluded and must be greater than START")
    times = range(start, stop, step)
    if len(times) > MAX_JOBS:
        raise ValueError(f"--time {text} is {len(times)} time points; a batch renders at most "
                         f"{MAX_JOBS} images")
    return times


def max_local_workers() -> int:
    """Most worker processes of a local cluster: 4 per CPU core. Each worker is a process with
    its own render context and volume in memory; more than that only queue for the cores
    (``--workers 100000`` tried to start them all and hung)."""
    return 4 * (os.cpu_count() or 1)


def scheduler_address_problem(address: str) -> str | None:
    """What is wrong with a scheduler address (one line), or None for ``[SCHEME://]HOST:PORT``
    with SCHEME one of :data:`SCHEDULER_SCHEMES` and PORT 1…65535. Checked before connecting:
    dask takes anything, waits out the timeout and prints a traceback as it shuts down."""
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    scheme = scheme.lower()
    usage = f"--scheduler takes tcp://HOST:PORT, got {address!r}"
    if scheme not in SCHEDULER_SCHEMES:
        return f"{usage} (known schemes: {', '.join(SCHEDULER_SCHEMES)})"
    match = re.fullmatch(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?)"
                         r":(\d{1,5})/?", rest)
    if not match:
        return usage
    if not 1 <= int(match.group(2)) <= 65535:
        return f"--scheduler {address!r}: the port must be from 1 to 65535"
    return None


def _stem(source: str) -> str:
    name = Path(source).name
    if is_session_path(name):
        return name[: -len(SESSION_SUFFIX)]
    for suffix in (".ome.tiff", ".ome.tif", ".ome.zarr", ".nii.gz"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return Path(name).stem if Path(name).suffix else name


def plan_jobs(
    inputs: Sequence[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    *,
    times: Iterable[int] | None = None,
    options: RenderOptions | None = None,
) -> list[RenderJob]:
    """One job per input (and per time point with ``times``), writing
    ``out_dir/<name>.png`` (``<name>_t0003.png`` with ``times``; ``<name>`` is the file name
    without ``.vtkvol.json`` or the format's suffix).

    Raises
    ------
    FileNotFoundError
        An input does not exist (checked here, before a cluster is started).
    ValueError
        No inputs, or two jobs would write the same PNG (inputs with the same name from
        different folders).
    """
    if not inputs:
        raise ValueError("no inputs to render")
    options = options or RenderOptions()
    out = Path(out_dir).expanduser().resolve()
    # At most MAX_JOBS + 1 time points are listed: a range of 10¹² is cheap, its list is not.
    time_list = None if times is None else list(itertools.islice(times, MAX_JOBS + 1))
    if time_list is not None and len(inputs) * len(time_list) > MAX_JOBS:
        more = "+" if len(time_list) > MAX_JOBS else ""
        raise ValueError(f"{len(inputs)} input(s) × {len(time_list)}{more} time points: a batch "
                         f"renders at most {MAX_JOBS} images")
    jobs: list[RenderJob] = []
    claimed: dict[Path, str] = {}
    for item in inputs:
        text = os.fspath(item)
        if text == "sample":
            source = "sample"
        else:
            path = Path(text).expanduser()
            if not path.exists():
                raise FileNotFoundError(2, "no such file or folder", text)
            source = str(path.resolve())
        for t in time_list if time_list is not None else [None]:
            stem = _stem(source) if t is None else f"{_stem(source)}_t{t:04d}"
            target = out / f"{stem}.png"
            job = RenderJob(source, str(target), t, options)
            if target in claimed:
                raise ValueError(f"{claimed[target]} and {job.name} would both write "
                                 f"{target.name}; render them into different folders")
            claimed[target] = job.name
            jobs.append(job)
    return jobs


def existing_outputs(jobs: Iterable[RenderJob]) -> list[Path]:
    """The jobs' PNGs that exist already (a batch replaces them only with ``overwrite``)."""
    return [Path(job.output) for job in jobs if Path(job.output).exists()]


def render_job_image(job: RenderJob, on_note: Callable[[str], None] | None = None) -> np.ndarray:
    """Read ``job``'s input and render it as ``vtkvol render`` does: an ``(h, w, 3)`` uint8
    image. ``on_note`` receives technique fallbacks and session warnings."""
    from vtkvol.engine.api import render_image
    from vtkvol.files import load_input as _load

    opts = job.options
    model = None
    if is_session_path(job.source):
        from vtkvol.model.session import load_session_with_data

        model, data = load_session_with_data(job.source, time_index=job.time_index,
                                             on_warning=on_note)
    else:
        if job.source == "sample" and job.time_index:
            raise ValueError("the built-in sample has one time point (0)")
        data = _load(job.source, opts.voxel_size, job.time_index or 0)
    if opts.blend:
        from vtkvol.model.defaults import scene_for

        model = model or scene_for(data)
        model.render.blend_mode = opts.blend
    return render_image(
        data, model=model, size=tuple(opts.size), method=opts.method, preset=opts.preset,
        azimuth=opts.azimuth, elevation=opts.elevation, parameters=opts.parameters or None,
        iterations=opts.iterations, max_seconds=opts.max_seconds, on_error=on_note,
    )


def render_job(job: RenderJob, overwrite: bool = False) -> JobResult:
    """Render one job and write its PNG atomically; runs on a worker (or anywhere).

    Never raises for a failed job: the failure comes back as ``JobResult.error``, one line
    that names the job, so one bad input does not cost the others anything.
    """
    from vtkvol.files import write_png as _write_png

    t0 = time.perf_counter()
    notes: list[str] = []
    worker = _worker_address()
    try:
        target = Path(job.output)
        # Checked again here (the planner checked too): another batch may have written it.
        if target.exists() and not overwrite:
            raise FileExistsError(17, "exists; pass overwrite (--overwrite) to replace it",
                                  str(target))
        image = render_job_image(job, notes.append)
        _write_png(image, target)
    except Exception as exc:  # every failure becomes the job's one-line report
        return JobResult(job, False, _one_line(exc), tuple(notes),
                         time.perf_counter() - t0, worker)
    return JobResult(job, True, "", tuple(notes), time.perf_counter() - t0, worker)


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror and exc.filename:
        text = f"{exc.filename}: {exc.strerror}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return "local"


def _egl_device_plugin(devices: Sequence[int]):
    """A worker plugin giving worker ``i`` of a LocalCluster the EGL device
    ``devices[i % len(devices)]`` (VTK reads ``VTK_DEFAULT_EGL_DEVICE_INDEX`` when a render
    window is constructed, so setting it before the first job is enough)."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class EGLDevice(WorkerPlugin):
        name = "vtkvol-egl-device"

        def __init__(self, devices: Sequence[int]) -> None:
            self.devices = [int(d) for d in devices]

        def setup(self, worker) -> None:
            try:
                index = int(worker.name)
            except (TypeError, ValueError):
                index = abs(hash(worker.address))
            os.environ["VTK_DEFAULT_EGL_DEVICE_INDEX"] = str(
                self.devices[index % len(self.devices)])

    return EGLDevice(devices)


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise BatchError("batch rendering needs dask's 'distributed': "
                         "pip install 'vtkvol[cluster]'") from None
    return distributed


def connect(scheduler: str, timeout: float = DEFAULT_CONNECT_TIMEOUT_S):
    """A :class:`distributed.Client` of the scheduler at ``scheduler`` (``tcp://host:port``);
    :class:`BatchError` with one line if it does not answer within ``timeout`` seconds."""
    problem = scheduler_address_problem(scheduler)
    if problem:
        raise BatchError(problem)
    distributed = _import_distributed()
    try:
        return distributed.Client(scheduler, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        detail = " ".join(str(exc).split()) or type(exc).__name__
        raise BatchError(f"no dask scheduler answered at {scheduler} within {timeout:g} s "
                         f"({detail})") from None


def local_cluster(workers: int, egl_devices: Sequence[int] | None = None):
    """A :class:`distributed.LocalCluster` of ``workers`` processes, one thread each, no
    dashboard, quiet logs; with ``egl_devices`` (EGL device indices), worker ``i`` renders on
    ``egl_devices[i % len]``. Returns ``(cluster, client)``."""
    if workers < 1:
        raise ValueError(f"--workers must be at least 1, got {workers}")
    if workers > max_local_workers():
        raise ValueError(f"--workers must be at most {max_local_workers()} (4 per CPU core), "
                         f"got {workers}")
    distributed = _import_distributed()
    cluster = distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    client = distributed.Client(cluster, set_as_default=False)
    if egl_devices:
        client.register_plugin(_egl_device_plugin(egl_devices))
    return cluster, client


def run_batch(
    jobs: Sequence[RenderJob],
    *,
    client: Any = None,
    scheduler: str | None = None,
    workers: int = 2,
    egl_devices: Sequence[int] | None = None,
    overwrite: bool = False,
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S,
    progress: ProgressCallback | None = None,
) -> list[JobResult]:
    """Render ``jobs`` on a Dask cluster and return their results in the jobs' order.

    Parameters
    ----------
    client
        A :class:`distributed.Client` to use (left open). Otherwise ``scheduler`` (an address,
        ``tcp://host:port``) is connected to, or a LocalCluster of ``workers`` processes
        (one thread each; ``egl_devices``: EGL device index per worker) is started and closed
        when the batch is done.
    overwrite
        Replace PNGs that exist; without it, a job whose PNG exists fails (check beforehand
        with :func:`existing_outputs`).
    progress
        Called in the calling process as each job finishes, in the order they finish.

    Raises
    ------
    BatchError
        No scheduler answered at ``scheduler`` within ``connect_timeout`` seconds, or
        ``distributed`` is not installed. Failed jobs do not raise: see ``JobResult.error``.
    """
    distributed = _import_distributed()
    cluster = None
    own_client = client is None
    if client is None:
        if scheduler:
            client = connect(scheduler, connect_timeout)
        else:
            cluster, client = local_cluster(workers, egl_devices)
    try:
        batch_id = uuid.uuid4().hex[:8]
        futures = {
            client.submit(render_job, job, overwrite, key=f"vtkvol-render-{batch_id}-{i}",
                          pure=False): i
            for i, job in enumerate(jobs)
        }
        results: list[JobResult | None] = [None] * len(jobs)
        for done, future in enumerate(distributed.as_completed(futures, loop=client.loop),
                                                 start=1):
            i = futures[future]
            try:
                result = future.result()
            except Exception as exc:  # a dead worker (KilledWorker), a cancel
                result = JobResult(jobs[i], False, f"the worker running it failed: "
                                   f"{_one_line(exc)}")
            results[i] = result
            if progress is not None:
                progress(done, len(jobs), result)
        return [r for r in results if r is not None]
    finally:
        if own_client:
            client.close()
        if cluster is not None:
            cluster.close()
