"""``vtkvol bench --empty-space``: frame time with and without empty-space skipping.

For every bench scene (the phantoms at ``size`` voxels) and every ``--data`` file (read at its
own resolution, with the transfer function the app opens it with: ``scene_for(data)``), and for
each measured technique, the same view is rendered with skipping off and on in alternating
blocks (warm-up frame, then timed frames with a 2° camera orbit each; ``rounds`` blocks of
each), so both sides see the same machine load. Recorded per pair: median wall and process-CPU
frame times, their ratios (off ÷ on: above 1 is faster with skipping), the largest pixel
difference between the two images (exactness: must be ≤ 1 level), the share of empty bricks
and the occupancy's own cost. Results merge into ``benchmarks.json`` (lists
``empty_space_runs`` and ``empty_space``) and appear in ``benchmarks.md`` under "Empty-space
skipping". Method: docs/empty-space-skipping.md.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from vtkvol.bench import report
from vtkvol.bench.scenes import Scene, phantom_scenes


@dataclass(frozen=True)
class SkipConfig:
    """``size``: phantom voxels per axis; ``image_size``: square image (pixels); ``frames``:
    timed frames per block; ``rounds``: off/on block pairs; ``methods``: techniques (None: the
    installed ones that render in one frame, local shading first, at most ``max_methods``)."""

    mode: str
    size: int
    image_size: int
    frames: int
    rounds: int
    methods: tuple[str, ...] | None = None
    max_methods: int | None = None


QUICK = SkipConfig("quick", 64, 256, 3, 2, max_methods=2)
FULL = SkipConfig("full", 128, 256, 4, 3)


def default_methods(config: SkipConfig) -> tuple[str, ...]:
    """The techniques a run measures: the configuration's, or every installed technique that
    is not progressive (those refine over many frames), local shading first."""
    if config.methods is not None:
        return tuple(config.methods)
    from vtkvol.bench.reference_technique import MEDIUM_NAME, NAME
    from vtkvol.engine.technique import installed_techniques

    names = sorted((n for n, c in installed_techniques().items()
                    if n not in (NAME, MEDIUM_NAME) and not c.SPEC.has("progressive")),
                   key=lambda n: (n != "local", n))
    return tuple(names[: config.max_methods])


def app_scenes(paths: Sequence[str | Path]) -> list[Scene]:
    """The user's files at their own resolution (first channel), each with the opacity
    transfer function the app gives it on opening (what users see first)."""
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for

    scenes = []
    for path in paths:
        data = read_volume(path, channels=[0])
        model = scene_for(data)
        array = np.ascontiguousarray(data.array[0])
        name = "".join(c if c.isalnum() else "_" for c in Path(path).stem.lower())[:40]
        label = f"{Path(path).name} ({' × '.join(str(n) for n in array.shape[::-1])})"
        scenes.append(Scene(name or "data", array, tuple(data.voxel_size_um),
                            [tuple(p) for p in model.channels[0].tf.opacity],
                            f"{label}, the app's default transfer function", "real"))
    return scenes


def measure_pair(rig: Any, scene: Scene, method: str, config: SkipConfig) -> dict[str, Any]:
    """Skipping off vs on for one technique on the loaded scene, side by side."""
    from vtkvol.bench.measure import FrameTiming

    il = rig.illuminator
    record: dict[str, Any] = {"scene": scene.name, "method": method,
                              "size": scene.size_label, "spacing": list(scene.spacing),
                              "kind": scene.kind, "ok": False, "error": None}
    try:
        rig.set_method(method, {})
        il.set_empty_space_skipping(True)
        rig.refine(30.0)
        images = {}
        for on in (False, True):
            il.set_empty_space_skipping(on)
            rig.image()  # the switch rebuilds the shader: settle before grabbing
            images[on] = rig.image().astype(np.int16)
        stats = il.empty_space_stats()
        timings = {False: FrameTiming(), True: FrameTiming()}
        for _ in range(config.rounds):
            for on in (False, True):
                il.set_empty_space_skipping(on)
                block = rig.time_frames(1, config.frames)
                timings[on].samples += block.samples
                timings[on].cpu_samples += block.cpu_samples
        il.set_empty_space_skipping(True)
        off, on = timings[False], timings[True]
        record.update(
            ok=True, frame_off_ms=off.median, frame_on_ms=on.median,
            cpu_off_ms=off.cpu_median, cpu_on_ms=on.cpu_median,
            ratio=off.median / on.median, cpu_ratio=off.cpu_median / on.cpu_median,
            max_abs=int(np.abs(images[True] - images[False]).max()),
            active=bool(stats.get("active")), reason=stats.get("reason", ""),
            empty_fraction=stats.get("empty_fraction"),
            bricks=list(stats.get("bricks", ())),
            brick_voxels=list(stats.get("brick_voxels", ())),
            ranges_ms=stats.get("ranges_ms"), occupancy_ms=stats.get("occupancy_ms"),
            n_frames=len(on.samples))
    except Exception as exc:  # one failing pair must not end the run: record it
        record["error"] = f"{type(exc).__name__}: {exc}"[:500]
    return record


def run(config: SkipConfig, out_dir: Path, scenes: Sequence[Scene], *,
        command: str = "vtkvol bench --empty-space", stream: TextIO | None = None,
        progress: bool = True) -> dict[str, Any]:
    """Measure every scene × technique and merge the results into ``out_dir``."""
    from vtkvol.bench.measure import Rig, VtkErrors, machine_info
    from vtkvol.bench.runner import Progress, _load_average

    t0 = time.perf_counter()
    cpu0 = time.process_time()
    load_start = _load_average()
    date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    methods = default_methods(config)
    bar = Progress(len(scenes) * len(methods), stream=stream, enabled=progress)
    records: list[dict[str, Any]] = []
    with VtkErrors():
        rig = Rig(config.image_size)
        try:
            rig.rw.Render()
            info = machine_info(rig.rw)
            for scene in scenes:
                rig.load(scene)
                for method in methods:
                    bar.step(f"{scene.name}: {method}")
                    rec = measure_pair(rig, scene, method, config)
                    rec.update(renderer=info["renderer"], mode=config.mode, date=date)
                    records.append(rec)
                    bar.advance()
        finally:
            rig.close()
    bar.finish()
    run_info = {
        "mode": config.mode, "date": date, "command": command,
        "duration_s": time.perf_counter() - t0, "cpu_seconds": time.process_time() - cpu0,
        "size": config.size, "image_size": config.image_size, "frames": config.frames,
        "rounds": config.rounds, "methods": list(methods),
        "load_average_start": load_start, "load_average_end": _load_average(), **info,
    }
    paths = report.write_empty_space(out_dir, run_info, records)
    return {**run_info, "records": records, "paths": paths}


def main(quick: bool = False, out: str = "vtkvol-bench", size: int | None = None,
         data: Sequence[str] = ()) -> int:
    """``vtkvol bench --empty-space -o DIR [--quick] [--size N] [--data FILE]…``. Returns 1
    when a pair failed or skipping changed an image by more than one level."""
    import sys
    from dataclasses import replace

    from vtkvol.bench.runner import bench_command, check_size
    from vtkvol.io import VolumeReadError

    config = QUICK if quick else FULL
    check_size(size)
    if size is not None:
        config = replace(config, size=int(size))
    command = bench_command(" --empty-space", quick, size, out, data)
    try:
        scenes = phantom_scenes(config.size) + app_scenes(data)
    except VolumeReadError as exc:
        print(f"vtkvol: {exc}", file=sys.stderr)
        return 1
    Path(out).mkdir(parents=True, exist_ok=True)
    result = run(config, Path(out), scenes, command=command)
    bad = [r for r in result["records"] if not r["ok"] or r.get("max_abs", 0) > 1]
    print(f"vtkvol bench --empty-space ({config.mode}): {len(result['records'])} pairs in "
          f"{result['duration_s'] / 60:.1f} min on {result['renderer']}", file=sys.stderr)
    print(f"  md: {result['paths']['md']}", file=sys.stderr)
    if bad:
        print(f"  {len(bad)} failed or not exact (see the table)", file=sys.stderr)
    return 1 if bad else 0
