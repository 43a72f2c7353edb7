"""``vtkvol render``'s movies (``-o NAME.mp4|.gif``): option checks, a turntable or a
keyframe animation rendered frame by frame, and the writer. Part of the command line
(:mod:`vtkvol.cli`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vtkvol.cli_signals import _signals


def _movie_problem(args: argparse.Namespace, out: Path) -> str | None:
    """What is wrong with the movie options, before anything is read or rendered."""
    from vtkvol.model.keyframes import MAX_FRAMES
    from vtkvol.movie import encoder_problem, existing_outputs

    # Before anything that lists the frames (the names of 10⁹ PNGs filled 2 GB of memory).
    if args.frames < 1:
        return f"--frames must be at least 1, got {args.frames}"
    if args.frames > MAX_FRAMES:
        return (f"--frames must be at most {MAX_FRAMES} (about 55 min at 30 fps), got "
                f"{args.frames}")
    if args.turntable is not None and abs(args.turntable) > MAX_TURNTABLE_DEGREES:
        return (f"--turntable must be at most {MAX_TURNTABLE_DEGREES:g} degrees (100 turns) "
                f"either way, got {args.turntable:g}")
    if not (args.fps > 0 and args.fps < 1000):
        return f"--fps must be between 0 and 1000, got {args.fps}"
    try:
        problem = encoder_problem(out)  # checks the suffix too
    except ValueError as exc:
        return str(exc)
    if problem:
        return problem
    existing = existing_outputs(out, args.frames)
    if existing and not args.overwrite:
        more = f" (and {len(existing) - 1} more frame files)" if len(existing) > 1 else ""
        return f"{existing[0]} exists{more}; pass --overwrite to replace it"
    return None


#: Largest turn of ``--turntable`` (degrees, either way): 100 full turns.
MAX_TURNTABLE_DEGREES = 36000.0


def _keyframe_option_problem(args: argparse.Namespace, out: Path) -> str | None:
    """Options that make no sense with ``--keyframes`` (the keyframes fix the view)."""
    if args.turntable is not None:
        return ("--turntable and --keyframes are two kinds of movie; choose one (a turn can "
                "be made of keyframes too)")
    for name, flag in (("frames", "--frames"), ("azimuth", "--azimuth"),
                       ("elevation", "--elevation")):
        if getattr(args, name) is not None:
            why = ("the frame count follows from the last keyframe's time and --fps"
                   if name == "frames" else "the keyframes place the camera")
            return f"{flag} does not apply to --keyframes: {why}"
    if Path(args.keyframes).resolve() == out.resolve():
        return f"{out} is the keyframe file; choose another name for the movie"
    return None


def _movie_size(args: argparse.Namespace, out: Path) -> tuple[int, int]:
    """``--size``, rounded up to even numbers for H.264 (said on stderr)."""
    from vtkvol.movie import even_size, movie_kind

    size = tuple(args.size)
    if movie_kind(out) == "video" and even_size(size) != size:
        size = even_size(size)
        print(f"vtkvol: H.264 needs even sizes: rendering {size[0]}×{size[1]}", file=sys.stderr)
    return size  # type: ignore[return-value]


def _render_turntable(args: argparse.Namespace, out: Path, data, model, params) -> int:
    """``--turntable``: render the frames and write them; progress on stderr."""
    from vtkvol.movie import turntable_frames

    size = _movie_size(args, out)
    frames = turntable_frames(
        data, frames=args.frames, degrees=args.turntable, model=model, size=size,
        method=args.method, preset=args.preset, azimuth=args.azimuth, elevation=args.elevation,
        parameters=params or None,
        on_error=lambda message: print(f"vtkvol: {message}", file=sys.stderr),
    )
    return _write_movie(args, out, frames, size)


def _render_keyframes(args: argparse.Namespace, out: Path, data, model, params,
                      animation) -> int:
    """``--keyframes``: check the time points, render the frames and write them. Time points
    other than the one read are read per frame (a few kept in memory)."""
    from vtkvol.movie import TimePointCache, keyframe_frames, keyframe_problem

    source = data.source if args.file != "sample" else None
    current = int(model.volume.time_index) if model is not None else (args.time or 0)
    problem = keyframe_problem(animation, data, current, can_read_time_points=bool(source))
    if problem:
        print(f"vtkvol: {problem}", file=sys.stderr)
        return 2
    time_points = None
    if source:
        voxel = model.volume.voxel_size_um if model is not None else args.voxel_size
        fit = model.volume.fit if model is not None else "auto"
        time_points = TimePointCache.for_file(source, voxel_size_um=voxel, fit=fit)
        time_points.put(current, data)
    size = _movie_size(args, out)
    frames = keyframe_frames(
        data, animation, fps=args.fps, model=model, size=size, method=args.method,
        preset=args.preset, parameters=params or None, time_points=time_points,
        on_error=lambda message: print(f"vtkvol: {message}", file=sys.stderr),
    )
    return _write_movie(args, out, frames, size)


def _write_movie(args: argparse.Namespace, out: Path, frames, size: tuple[int, int]) -> int:
    """Write the movie's frames (turntable or keyframes) to ``out``; progress on stderr."""
    from vtkvol.movie import write_movie

    end = "\r" if sys.stderr.isatty() else "\n"

    def progress(done: int, total: int) -> None:
        print(f"frame {done}/{total}", end=end if done < total else "\n", file=sys.stderr,
              flush=True)

    try:
        with _signals.deferred():
            written = write_movie(frames, out, n_frames=args.frames, fps=args.fps,
                                  overwrite=args.overwrite, progress=progress,
                                  cancel=lambda: _signals.received is not None)
    except Exception:
        # MovieCancelled, or ffmpeg killed by the same Ctrl-C: the signal is the reason
        _signals.check()
        raise
    where = out if len(written) == 1 else f"{written[0]} … {written[-1].name}"
    print(f"wrote {where} ({args.frames} frames, {size[0]}×{size[1]}, "
          f"{args.frames / args.fps:.2f} s at {args.fps:g} fps)")
    return 0
