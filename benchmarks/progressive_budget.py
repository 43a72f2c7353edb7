"""How long one frame of hybrid diffusion holds the thread on a large stack, with and without
the app's work budget (issue 25 §1: "the progressive methods run their iterations inside the
frame"). Not part of the installed library; run from a checkout:

    python benchmarks/progressive_budget.py                       # 100×256×256
    python benchmarks/progressive_budget.py --shape 48 96 96      # a quick dry run

Both runs use the same generated stack (the built-in confocal phantom), the same offscreen
window (160² px) and the method's defaults; they alternate frame by frame, side by side in one
process, for ``--seconds`` of each. Halfway through, each run's light moves (a restart on the
same grid). Reported per run: the two restarts — opening (the first frames: extinction,
coefficients, majorants and textures, then the first iterations; its first frame apart, as it
also loads PyOpenGL and compiles the compute program once per process) and the light move — as
the frames they took and their longest work before the render (``Illuminator.last_prepare_ms``);
the longest and median work of the frames that refine (the technique's iterations: samples,
diffusion sweeps); the longest whole frame after the first; how many samples per voxel were
complete after the time given. A technique without ``restarting`` (the code before the restart
was split) restarts inside one frame.

To compare two versions of the code in one run, run this file with ``PYTHONPATH`` set to the
other checkout first (the checkout on ``sys.path`` is the one measured).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import vtkvol
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import simple_volume_scene
from vtkvol.io.sample import confocal_phantom
from vtkvol.model.scene import Light
from vtkvol.ui.refine import WORK_BUDGET_MS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shape", type=int, nargs=3, default=(100, 256, 256),
                        metavar=("Z", "Y", "X"))
    parser.add_argument("--seconds", type=float, default=60.0,
                        help="wall time given to each run (default 60)")
    args = parser.parse_args()
    volume_zyx = confocal_phantom(tuple(args.shape)).array[0].astype(np.float32)
    volume_zyx /= max(float(volume_zyx.max()), 1e-12)
    runs = {}
    for budget in (None, WORK_BUDGET_MS):
        rw, _ren, vol = simple_volume_scene(volume_zyx, size=(160, 160),
                                            opacity=[(0.0, 0.0), (0.2, 0.0), (1.0, 0.5)])
        il = Illuminator(vol, _ren, method="hybrid_diffusion",
                         lights=[Light(direction=(0.3, 0.5, 1.0))])
        il.work_budget_ms = budget
        runs[budget] = {"rw": rw, "il": il, "prepare": [], "frame": [], "phase": [],
                        "spent": 0.0, "moved": False, "restart": "open"}
    while any(r["spent"] < args.seconds for r in runs.values()):
        for run in runs.values():
            if run["spent"] >= args.seconds:
                continue
            if not run["moved"] and run["spent"] >= args.seconds / 2:
                run["il"].set_lights([Light(direction=(-0.3, 0.5, 1.0))])
                run["moved"], run["restart"] = True, "light"
            t0 = time.perf_counter()
            run["rw"].Render()
            dt = time.perf_counter() - t0
            run["spent"] += dt
            run["frame"].append(dt * 1e3)
            run["prepare"].append(run["il"].last_prepare_ms)
            run["phase"].append(run["restart"] or "refine")
            if not getattr(run["il"].technique, "restarting", False):
                run["restart"] = None
    print(f"hybrid diffusion, {'×'.join(map(str, args.shape))} voxels, "
          f"{args.seconds:.0f} s each, alternating frames; code: "
          f"{os.path.dirname(os.path.dirname(os.path.abspath(vtkvol.__file__)))}")
    print("| work budget | frames | opening: frames, first frame's work, longest work after "
          "it (ms) | light move: frames, "
          "longest work (ms) | longest work refining (ms) | median work refining (ms) | "
          "longest frame after the first (ms) | samples complete |")
    print("|---|---|---|---|---|---|---|---|")
    for budget, run in runs.items():
        tech = run["il"].technique
        work = {k: [w for w, p in zip(run["prepare"], run["phase"], strict=True) if p == k]
                or [0.0] for k in ("open", "light", "refine")}
        frames = run["frame"][1:] or [0.0]
        print(f"| {'none' if budget is None else f'{budget:.0f} ms'} | {len(run['frame'])} | "
              f"{run['phase'].count('open')}, {work['open'][0]:.0f}, "
              f"{max(work['open'][1:] or [0.0]):.0f} | "
              f"{run['phase'].count('light')}, {max(work['light']):.0f} | "
              f"{max(work['refine']):.0f} | {float(np.median(work['refine'])):.0f} | "
              f"{max(frames):.0f} | {tech.iteration} |")


if __name__ == "__main__":
    main()
