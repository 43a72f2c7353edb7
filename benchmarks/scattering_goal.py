"""Issue goal check: how close HD (and KD) get to the multiple-scattering reference at 128³ on
llvmpipe, and after how long (seed 003's accuracy claim, measured).

One scene (the sphere over the slab, 128³ voxels, one light), each technique refining for at
most five minutes, against the path-traced reference (8 paths per voxel × 2 seeds). The results
merge into ``docs/benchmarks.json`` as the study mode ``goal-128`` and appear in
``docs/benchmarks.md`` beside the other convergence studies.

Run: ``python benchmarks/scattering_goal.py [OUT_DIR]`` (about half an hour on two cores).
"""

from __future__ import annotations

import sys
from pathlib import Path

from vtkvol.bench.convergence import StudyConfig, run
from vtkvol.bench.references import QUICK_BUDGET
from vtkvol.bench.scenes import phantom_scenes


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "docs")
    config = StudyConfig(mode="goal-128", size=128, image_size=192, light_counts=(1,),
                         max_seconds=300.0)
    result = run(config, out, phantom_scenes(128)[:1],
                 ["convection_diffusion", "hybrid_diffusion"], budget=QUICK_BUDGET,
                 command="python benchmarks/scattering_goal.py")
    print(f"{len(result['records'])} checkpoints in {result['duration_s'] / 60:.1f} min")


if __name__ == "__main__":
    main()
