"""Turntable and keyframe movies rendered offscreen: MP4 (H.264), PNG sequences, multi-page
TIFF for Fiji.

Library code, no Qt. :func:`turntable_frames` (a turn about the vertical axis) and
:func:`keyframe_frames` (camera, time point and lights interpolated between keyframes,
:mod:`vtkvol.model.keyframes`) render the frames through one loop on the same path as
:func:`vtkvol.engine.api.render_image` (one scene, built once; a progressive technique refines
each frame until it converges or ``max_seconds`` pass); :func:`write_movie` encodes either by
the output's suffix:

* ``.mp4``, ``.mov``, ``.m4v``: H.264 in yuv420p (what QuickTime, PowerPoint and browsers play)
  through ``imageio-ffmpeg``, which ships its own ffmpeg (optional extra ``movie``). H.264 in
  yuv420p needs even frame sizes: odd sizes are rounded up by :func:`even_size`.
* ``.png``: one PNG per frame. ``spin.png`` writes ``spin_0000.png``, ``spin_0001.png``…; a name
  with a printf field (``spin_%03d.png``) chooses the numbering.
* no suffix: a folder of ``frame_0000.png``….
* ``.tif``/``.tiff``: one multi-page RGB ImageJ TIFF (Fiji opens it as a stack).

Every output is written atomically: into a temporary file (or folder) beside the target, moved
into place when the last frame is done, and removed on error or cancel. An existing output is
replaced only with ``overwrite=True``.

The turntable turns the camera around a vertical axis through the focal point. ``axis="sample"``
(the default for the default view, and what the app offers first): the data's z axis, so the
elevation stays constant and the sample turns like on a real turntable even when the view is
tilted. ``axis="view"``: the camera's view-up (the default for a session's camera, as before;
a tilted view then tumbles the box). ``frame_all=True`` moves the camera back, where needed,
until the sphere about the focal point that holds the whole volume fits the frame: the data
stays in every frame of the turn. ``degrees / frames`` separate two frames, so a 360° turn
loops without a repeated frame.

A keyframe animation of ``T`` seconds at ``fps`` has ``round(T · fps) + 1`` frames, frame ``i``
at ``i / fps`` s (both the first and the last keyframe are shown). Time points other than the
one given are read per frame through ``time_points(index)``, e.g. a :class:`TimePointCache`
over :func:`vtkvol.io.read_volume` that keeps the last few.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import shutil
import tempfile
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from vtkvol.files import write_png

if TYPE_CHECKING:
    from vtkvol.engine.scene import VolumeScene
    from vtkvol.io import VolumeData
    from vtkvol.model.keyframes import Animation
    from vtkvol.model.scene import SceneModel

__all__ = [
    "MOVIE_SUFFIXES",
    "MovieCancelled",
    "TimePointCache",
    "encoder_problem",
    "even_size",
    "existing_outputs",
    "has_video_encoder",
    "keyframe_frames",
    "keyframe_problem",
    "movie_kind",
    "time_point_count",
    "turntable_frames",
    "write_movie",
]

#: Suffixes encoded as H.264 video.
MOVIE_SUFFIXES = (".mp4", ".mov", ".m4v")
_PRINTF = re.compile(r"%0?(\d*)d")

ProgressCallback = Callable[[int, int], None]
"""``progress(frames_done, frames_total)``."""


class MovieCancelled(Exception):
    """``cancel()`` returned True; nothing was written."""


def even_size(size: tuple[int, int]) -> tuple[int, int]:
    """``(w, h)`` rounded up to even numbers (H.264 in yuv420p subsamples colour 2 × 2)."""
    w, h = (int(v) for v in size)
    return w + (w % 2), h + (h % 2)


def movie_kind(path: str | os.PathLike[str]) -> str:
    """``"video"``, ``"png"``, ``"tiff"`` or ``"folder"`` (a folder of PNGs), by suffix."""
    suffix = Path(path).suffix.lower()
    if suffix in MOVIE_SUFFIXES:
        return "video"
    if suffix == ".png":
        return "png"
    if suffix in (".tif", ".tiff"):
        return "tiff"
    if suffix == "":
        return "folder"
    raise ValueError(f"{Path(path).name}: unknown movie format {suffix!r}; use "
                     f"{', '.join(MOVIE_SUFFIXES)}, .png (a sequence), .tif (a stack) or a folder")


def has_video_encoder() -> bool:
    """Whether ``imageio-ffmpeg`` (the optional extra ``movie``) is installed."""
    import importlib.util

    return importlib.util.find_spec("imageio_ffmpeg") is not None


def encoder_problem(path: str | os.PathLike[str]) -> str | None:
    """Why a movie cannot be written to ``path`` with what is installed (one line), or None.
    PNG and TIFF need nothing extra; MP4 needs ``imageio-ffmpeg``."""
    if movie_kind(path) == "video" and not has_video_encoder():
        return (f"{Path(path).name}: writing MP4 needs the optional package 'imageio-ffmpeg': "
                "pip install 'vtkvol[movie]' (PNG sequences and TIFF stacks need nothing more)")
    return None


def _check_frame_count(n: int, name: str) -> None:
    """A movie has 1 to :data:`~vtkvol.model.keyframes.MAX_FRAMES` frames, checked before any
    work (a list of 10⁹ frame names alone filled 2 GB)."""
    from vtkvol.model.keyframes import MAX_FRAMES

    if not 1 <= n <= MAX_FRAMES:
        raise ValueError(f"{name} must be from 1 to {MAX_FRAMES}, got {n}")


def _frame_names(path: Path, n: int) -> tuple[Path, list[str]]:
    """The folder and the file names of a PNG sequence (see the module docstring)."""
    if movie_kind(path) == "folder":
        return path, [f"frame_{i:04d}.png" for i in range(n)]
    width = max(4, len(str(n - 1)))
    match = _PRINTF.search(path.name)
    if match:
        pattern = path.name[:match.start()] + "{:0" + str(int(match.group(1) or 0)) + "d}" + \
            path.name[match.end():]
        return path.parent, [pattern.format(i) for i in range(n)]
    return path.parent, [f"{path.stem}_{i:0{width}d}.png" for i in range(n)]


def existing_outputs(path: Path, n: int) -> list[Path]:
    """The files that writing ``n`` frames to ``path`` would replace (none: safe to write)."""
    kind = movie_kind(path)
    if kind in ("video", "tiff"):
        return [path] if path.exists() else []
    folder, names = _frame_names(path, n)
    return [folder / name for name in names if (folder / name).exists()]


def turntable_frames(
    data: VolumeData,
    *,
    frames: int,
    degrees: float = 360.0,
    model: SceneModel | None = None,
    size: tuple[int, int] = (800, 600),
    method: str | None = None,
    preset: str | None = None,
    azimuth: float | None = None,
    elevation: float | None = None,
    parameters: dict[str, Any] | None = None,
    max_seconds: float | None = 60.0,
    on_error: Callable[[str], None] | None = None,
    axis: str | None = None,
    frame_all: bool = False,
) -> Iterator[np.ndarray]:
    """Yield ``frames`` images ``(h, w, 3)`` uint8 of a turn by ``degrees`` about ``axis``
    (``"sample"``: the data's z axis, ``"view"``: the camera's view-up, ``None``: z for the
    default view, view-up for a given camera; see the module docstring). ``frame_all``: move
    back so the whole volume stays in frame at every angle. Other arguments as
    :func:`vtkvol.engine.api.render_image`; ``max_seconds`` bounds the refinement of each
    frame of a progressive technique.
    """
    _check_frame_count(frames, "frames")
    if not math.isfinite(degrees):
        raise ValueError(f"degrees must be a finite number, got {degrees}")
    if axis not in (None, "sample", "view"):
        raise ValueError(f"axis must be 'sample' or 'view', got {axis!r}")
    start: dict[str, Any] = {}
    aspect = size[0] / max(1, size[1])

    def turn(scene: VolumeScene, i: int, has_camera: bool) -> None:
        cam = scene.renderer.GetActiveCamera()
        if i == 0:
            if frame_all:
                fit_turn(cam, scene.renderer.ComputeVisiblePropBounds(), aspect)
            start.update(focal=np.array(cam.GetFocalPoint()),
                         position=np.array(cam.GetPosition()), up=np.array(cam.GetViewUp()))
            by_view = axis == "view" or (axis is None and has_camera)
            start["axis"] = start["up"] if by_view else np.array([0.0, 0.0, 1.0])
            scene.renderer.ResetCameraClippingRange()
            return
        position, up = turned_camera(start["position"], start["focal"], start["up"],
                                     start["axis"], i * float(degrees) / frames)
        cam.SetPosition(*position)
        cam.SetViewUp(*up)
        scene.renderer.ResetCameraClippingRange()
        scene.sync_camera_to_model()  # lights that follow the camera follow it here too

    yield from _rendered_frames(
        data, frames, turn, model=model, size=size, method=method, preset=preset,
        azimuth=azimuth, elevation=elevation, parameters=parameters, max_seconds=max_seconds,
        on_error=on_error)


def turned_camera(position: Sequence[float], focal: Sequence[float], up: Sequence[float],
                  axis: Sequence[float], degrees: float,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Camera position and view-up (world µm, unit vector) after turning by ``degrees``
    (right-handed) about ``axis`` through ``focal``: the turntable's motion."""
    import vtk

    rotation = vtk.vtkTransform()
    rotation.RotateWXYZ(float(degrees), *(float(v) for v in axis))
    offset = rotation.TransformVector(*(np.asarray(position, float) - np.asarray(focal, float)))
    return (np.asarray(focal, float) + np.array(offset),
            np.array(rotation.TransformVector(*(float(v) for v in up))))


def fit_turn(camera: Any, bounds: Sequence[float], aspect: float) -> None:
    """Move ``camera`` (a ``vtkCamera``) back along its view direction, or widen its parallel
    scale, until the sphere about its focal point holding the box ``bounds`` (x0, x1, y0, y1,
    z0, z1, world µm) fits the frame (width/height ``aspect``): whatever the turn's angle,
    the box then stays inside every frame. A camera already far enough stays where it is."""
    focal = np.array(camera.GetFocalPoint())
    corners = np.array([[x, y, z] for x in bounds[0:2] for y in bounds[2:4]
                        for z in bounds[4:6]], float)
    if not np.all(np.isfinite(corners)) or bounds[0] > bounds[1]:
        return  # nothing visible: nothing to frame
    radius = float(np.linalg.norm(corners - focal, axis=1).max())
    # The narrower of the two fields of view bounds the sphere.
    narrow = min(1.0, aspect)
    if camera.GetParallelProjection():
        camera.SetParallelScale(max(camera.GetParallelScale(), radius / narrow))
        return
    half = math.radians(camera.GetViewAngle()) / 2.0
    half = min(half, math.atan(math.tan(half) * aspect))
    needed = radius / math.sin(half)
    direction = np.array(camera.GetPosition()) - focal
    distance = float(np.linalg.norm(direction))
    if distance < needed:
        camera.SetPosition(*(focal + direction / distance * needed))


def keyframe_frames(
    data: VolumeData,
    animation: Animation,
    *,
    fps: float = 30.0,
    model: SceneModel | None = None,
    size: tuple[int, int] = (800, 600),
    method: str | None = None,
    preset: str | None = None,
    parameters: dict[str, Any] | None = None,
    max_seconds: float | None = 60.0,
    time_points: Callable[[int], VolumeData] | None = None,
    on_error: Callable[[str], None] | None = None,
) -> Iterator[np.ndarray]:
    """Yield the ``animation.frame_count(fps)`` images ``(h, w, 3)`` uint8 of a keyframe
    animation (:class:`vtkvol.model.keyframes.Animation`): frame ``i`` shows the state
    ``i / fps`` seconds in. ``data`` is the time point ``model.volume.time_index`` (0 without a
    model); where the animation shows other time points, ``time_points(index)`` reads them
    (e.g. a :class:`TimePointCache`). Other arguments as :func:`turntable_frames`.

    Raises
    ------
    ValueError
        (before anything renders) a time index the data does not have, or time points to show
        and no ``time_points`` to read them with.
    """
    current = {"index": _time_index(data, model)}
    problem = keyframe_problem(animation, data, current["index"],
                               can_read_time_points=time_points is not None)
    if problem:
        raise ValueError(problem)
    times = animation.frame_times(fps)

    def show(scene: VolumeScene, i: int, has_camera: bool) -> None:
        state = animation.state_at(times[i])
        model_ = scene.model
        if state.time_index is not None and state.time_index != current["index"]:
            assert time_points is not None
            scene.set_data(time_points(state.time_index))
            current["index"] = state.time_index
            model_.volume.time_index = state.time_index
        if state.lights is not None and (
                [light.model_dump() for light in state.lights]
                != [light.model_dump() for light in model_.lights]):
            model_.lights = [light.model_copy(deep=True) for light in state.lights]
        model_.camera.update(state.camera.model_fields())

    yield from _rendered_frames(
        data, len(times), show, model=model, size=size, method=method, preset=preset,
        parameters=parameters, max_seconds=max_seconds, on_error=on_error)


def _rendered_frames(
    data: VolumeData,
    n: int,
    prepare: Callable[[VolumeScene, int, bool], None],
    *,
    max_seconds: float | None,
    **view: Any,
) -> Iterator[np.ndarray]:
    """The frame loop turntables and keyframe animations share: one offscreen view
    (:func:`vtkvol.engine.api.offscreen_view` with ``view``), ``prepare(scene, i, has_camera)``
    sets frame ``i`` up, :func:`~vtkvol.engine.api.settled_frame` renders it as users see it."""
    from vtkvol.engine.api import offscreen_view, settled_frame

    with offscreen_view(data, **view) as (rw, scene, has_camera):
        for i in range(n):
            prepare(scene, i, has_camera)
            # only the first frame can be the failed build's blank one
            yield settled_frame(rw, scene, max_seconds=max_seconds, retry_failed=i == 0)[0]


def _time_index(data: VolumeData, model: SceneModel | None) -> int:
    """The time point ``data`` holds: the model's, else the reader's metadata, else 0."""
    if model is not None:
        return int(model.volume.time_index)
    return int(data.metadata.get("time_index", 0) or 0)


def time_point_count(data: VolumeData) -> int:
    """How many time points the file of ``data`` has (1 when its reader says nothing)."""
    count = data.metadata.get("time_points", 1)
    return int(count) if isinstance(count, int) and count >= 1 else 1


def keyframe_problem(animation: Animation, data: VolumeData, current_index: int = 0, *,
                     can_read_time_points: bool = True) -> str | None:
    """What stops ``animation`` from being shown with ``data`` (one line), or None: a time
    index past the file's time points, or other time points than ``data``'s and no way to
    read them (in-memory data, the built-in sample)."""
    wanted = sorted(set(animation.time_indices()))
    if not wanted:
        return None
    count = time_point_count(data)
    name = Path(data.source).name if data.source else "the data"
    if wanted[-1] >= count:
        return (f"the keyframes show time point {wanted[-1]}, but {name} has "
                f"{'only one time point (0)' if count == 1 else f'{count} (0–{count - 1})'}")
    if not can_read_time_points and wanted != [current_index]:
        return (f"the keyframes show time points {wanted[0]}–{wanted[-1]}, but {name} is not a "
                "file they can be read from")
    return None


class TimePointCache:
    """Time points of one file read on demand through ``read(index)``; the last ``size`` stay
    in memory (least recently used goes first), so an animation that goes back and forth reads
    each time point once. ``cache.reads`` counts the reads done."""

    def __init__(self, read: Callable[[int], VolumeData], *, size: int = 3) -> None:
        if size < 1:
            raise ValueError(f"the cache must hold at least one time point, not {size}")
        self._read = read
        self.size = size
        self._cache: OrderedDict[int, VolumeData] = OrderedDict()
        self.reads = 0

    def put(self, index: int, data: VolumeData) -> None:
        """Keep ``data`` (already read) as time point ``index``."""
        self._cache[index] = data
        self._cache.move_to_end(index)
        while len(self._cache) > self.size:
            self._cache.popitem(last=False)

    def __call__(self, index: int) -> VolumeData:
        if index in self._cache:
            self._cache.move_to_end(index)
            return self._cache[index]
        data = self._read(index)
        self.reads += 1
        self.put(index, data)
        return data

    @classmethod
    def for_file(cls, path: str | os.PathLike[str], *, voxel_size_um: Any = None,
                 fit: str = "auto", size: int = 3) -> TimePointCache:
        """Time points of ``path`` through :func:`vtkvol.io.read_volume` (with the voxel size
        and fit the first one was read with)."""
        from vtkvol.io import read_volume

        return cls(lambda index: read_volume(path, voxel_size_um=voxel_size_um,
                                             time_index=index, fit=fit),  # type: ignore[arg-type]
                   size=size)


def write_movie(
    frames: Iterable[np.ndarray],
    path: str | os.PathLike[str],
    *,
    n_frames: int,
    fps: float = 30.0,
    overwrite: bool = False,
    progress: ProgressCallback | None = None,
    cancel: Callable[[], bool] | None = None,
) -> list[Path]:
    """Write ``n_frames`` RGB frames ``(h, w, 3)`` uint8 to ``path`` (kind by suffix, see the
    module docstring), atomically. Returns the files written.

    Raises
    ------
    FileExistsError
        The output (or a frame file of the sequence) exists and ``overwrite`` is False.
    ValueError
        Unknown suffix, frames of different sizes, odd sizes for a video, fps ≤ 0.
    MovieCancelled
        ``cancel()`` returned True (checked before each frame).
    """
    path = Path(path)
    kind = movie_kind(path)
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    _check_frame_count(n_frames, "n_frames")
    existing = existing_outputs(path, n_frames)
    if existing and not overwrite:
        shown = existing[0] if len(existing) == 1 else f"{existing[0]} and {len(existing) - 1} more"
        raise FileExistsError(f"{shown} exists; pass --overwrite (overwrite=True) to replace it")
    problem = encoder_problem(path)
    if problem:
        raise ValueError(problem)
    folder = path if kind == "folder" else path.parent
    folder.mkdir(parents=True, exist_ok=True)
    writer = {"video": _VideoWriter, "tiff": _TiffWriter}.get(kind, _PngWriter)(path, n_frames, fps)
    shape: tuple[int, ...] | None = None
    done = 0
    try:
        for frame in frames:
            if cancel is not None and cancel():
                raise MovieCancelled("cancelled")
            frame = np.ascontiguousarray(frame, dtype=np.uint8)
            if frame.ndim != 3 or frame.shape[2] != 3:
                raise ValueError(f"frames must be (h, w, 3) RGB, got {frame.shape}")
            if shape is None:
                shape = frame.shape
                if kind == "video" and (shape[0] % 2 or shape[1] % 2):
                    raise ValueError(f"H.264 in yuv420p needs even frame sizes, got "
                                     f"{shape[1]}×{shape[0]}; render at even_size(...)")
            elif frame.shape != shape:
                raise ValueError(f"frame {done} is {frame.shape}, the first was {shape}")
            writer.add(frame)
            done += 1
            if progress is not None:
                progress(done, n_frames)
            if done == n_frames:
                break
        if done != n_frames:
            raise ValueError(f"{n_frames} frames announced, {done} given")
        return writer.finish(overwrite)
    finally:
        writer.discard()


class _VideoWriter:
    """H.264/yuv420p through imageio-ffmpeg into a temporary file, renamed when complete."""

    def __init__(self, path: Path, n: int, fps: float) -> None:
        self.path, self.fps = path, fps
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
        os.close(fd)
        self.tmp: Path | None = Path(tmp)
        self.gen: Any = None

    def add(self, frame: np.ndarray) -> None:
        if self.gen is None:
            import imageio_ffmpeg

            h, w, _ = frame.shape
            self.gen = imageio_ffmpeg.write_frames(
                str(self.tmp), (w, h), fps=self.fps, codec="libx264", pix_fmt_in="rgb24",
                pix_fmt_out="yuv420p", quality=None, macro_block_size=2,
                # crf 18: visually lossless; faststart: playable while downloading.
                output_params=["-crf", "18", "-movflags", "+faststart"],
                ffmpeg_log_level="error",
            )
            self.gen.send(None)
        self.gen.send(frame.tobytes())

    def finish(self, overwrite: bool) -> list[Path]:
        self.gen.close()  # waits for ffmpeg to write the file's index
        self.gen = None
        _publish(self.tmp, self.path)
        self.tmp = None
        return [self.path]

    def discard(self) -> None:
        if self.gen is not None:
            with contextlib.suppress(Exception):
                self.gen.close()
        if self.tmp is not None:
            self.tmp.unlink(missing_ok=True)


class _TiffWriter:
    """A multi-page RGB ImageJ TIFF (a stack for Fiji), written page by page."""

    def __init__(self, path: Path, n: int, fps: float) -> None:
        import tifffile

        self.path, self.fps = path, fps
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
        os.close(fd)
        self.tmp: Path | None = Path(tmp)
        self.tif = tifffile.TiffWriter(tmp, imagej=True)
        self.n = n

    def add(self, frame: np.ndarray) -> None:
        # contiguous: one ImageJ series of n RGB frames; finterval gives Fiji the frame rate.
        self.tif.write(frame, photometric="rgb", contiguous=True,
                       metadata={"finterval": 1.0 / self.fps})

    def finish(self, overwrite: bool) -> list[Path]:
        self.tif.close()
        _publish(self.tmp, self.path)
        self.tmp = None
        return [self.path]

    def discard(self) -> None:
        with contextlib.suppress(Exception):
            self.tif.close()
        if self.tmp is not None:
            self.tmp.unlink(missing_ok=True)


class _PngWriter:
    """PNG frames into a temporary folder beside the sequence, moved into place at the end."""

    def __init__(self, path: Path, n: int, fps: float) -> None:
        self.folder, self.names = _frame_names(path, n)
        self.tmp: Path | None = Path(tempfile.mkdtemp(prefix=".frames.", dir=self.folder))
        self.count = 0

    def add(self, frame: np.ndarray) -> None:
        write_png(frame, self.tmp / self.names[self.count])
        self.count += 1

    def finish(self, overwrite: bool) -> list[Path]:
        written = []
        for name in self.names:
            target = self.folder / name
            _publish(self.tmp / name, target)
            written.append(target)
        return written

    def discard(self) -> None:
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp = None


def _publish(tmp: Path | None, target: Path) -> None:
    """Give ``tmp`` the usual permissions (mkstemp makes 0600) and move it onto ``target``."""
    assert tmp is not None
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, target)
