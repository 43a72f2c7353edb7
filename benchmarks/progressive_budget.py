"""How long one frame of hybrid diffusion holds the thread on a large stack, with and without
the app's work budget (issue 25 §1: "the progressive methods run their iterations inside the
frame"). Not part of the installed library; run from a checkout:

    python benchmarks/progressive_budget.py                       # 100×256×256
    python benchmarks/progressive_budget.py --shape 48 96 96      # a quick dry run

Both runs use the same generated stack (the built-in confocal phantom), the same offscreen
window (160² px) and the method's defaults; they alternate frame by frame, side by side in one
process, for ``--seconds`` of each. Reported per run: the first frame's work (the restart:
extinction, coefficients, majorants and textures, then the first iterations), the longest and
median work before the render after it (``Illuminator.last_prepare_ms``: the technique's
iterations), the longest whole frame after the first, and how many samples per voxel were
complete after the time given.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

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
        runs[budget] = {"rw": rw, "il": il, "prepare": [], "frame": [], "spent": 0.0}
    while any(r["spent"] < args.seconds for r in runs.values()):
        for run in runs.values():
            if run["spent"] >= args.seconds:
                continue
            t0 = time.perf_counter()
            run["rw"].Render()
            dt = time.perf_counter() - t0
            run["spent"] += dt
            run["frame"].append(dt * 1e3)
            run["prepare"].append(run["il"].last_prepare_ms)
    print(f"hybrid diffusion, {'×'.join(map(str, args.shape))} voxels, "
          f"{args.seconds:.0f} s each, alternating frames")
    print("| work budget | frames | first frame: restart + work (ms) | longest work after it "
          "(ms) | median work (ms) | longest frame after the first (ms) | samples complete |")
    print("|---|---|---|---|---|---|---|")
    for budget, run in runs.items():
        tech = run["il"].technique
        later, frames = run["prepare"][1:] or [0.0], run["frame"][1:] or [0.0]
        print(f"| {'none' if budget is None else f'{budget:.0f} ms'} | {len(run['frame'])} | "
              f"{run['prepare'][0]:.0f} | {max(later):.0f} | {float(np.median(later)):.0f} | "
              f"{max(frames):.0f} | {tech.iteration} |")


if __name__ == "__main__":
    main()
