"""Path-traced illumination (Monte-Carlo, object space): the declaration.

The light arriving at every voxel is estimated by tracing paths from it (delta tracking, next-
event estimation towards each light by ratio tracking, Henyey–Greenstein phase function) — the
same estimator as the benchmark's reference (:func:`vtkvol.reference.inscattered_mc`), run on
the CPU a batch of paths per voxel at a time and averaged as the frames go by. The direct light
is the exact transmittance. Unbiased up to ``max_bounces``, and slow: for final renders and for
checking what another method leaves out, on volumes up to about 128³. Camera moves never restart
it (the result lives on the data grid). The engine part is :mod:`.technique`; this module
imports no VTK.
"""

from __future__ import annotations

from vtkvol.model.params import Invalidates, Param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec

_RESTART = Invalidates.ACCUMULATION
_MULTIPLE = (("scattering", ("multiple",)),)  # what only the in-scattered light uses

PARAMETERS: tuple[Param, ...] = (
    Param(
        "scattering", "multiple", "Scattering",
        "multiple: light scattered any number of times inside the volume; single: the direct "
        "light only (exact transmittance towards each light, scattered once towards the eye).",
        kind="choice", choices=("multiple", "single"), invalidates=_RESTART, uniform=False,
        choice_labels=("Multiple", "Single"),
    ),
    Param(
        "paths_per_iteration", 2, "Paths per iteration",
        "Paths traced from every voxel per iteration (project default).",
        kind="int", range=(1, 64), step=1, invalidates=_RESTART, uniform=False,
        applies_when=_MULTIPLE,
    ),
    Param(
        "max_iterations", 32, "Iterations",
        "Iterations after which the result is final: paths per voxel = iterations × paths per "
        "iteration (noise falls as 1/√paths; project default).",
        kind="int", range=(1, 100000), step=1, uniform=False,
        applies_when=_MULTIPLE,
    ),
    Param(
        "max_bounces", 32, "Bounces",
        "Scattering events a path follows at most (the light of longer paths is left out; with "
        "albedo a it is at most a^bounces of the total).",
        kind="int", range=(1, 256), step=1, invalidates=_RESTART, uniform=False,
        applies_when=_MULTIPLE,
    ),
    Param(
        "frame_budget_ms", 250, "Time per frame", "Tracing time spent before each frame is shown "
        "(the rest continues in the next frames).", kind="int", range=(20, 10000), step=10,
        unit="ms", uniform=False, applies_when=_MULTIPLE,
    ),
    Param(
        "seed", 0, "Seed", "Random seed of the paths.",
        kind="int", range=(0, 2**31 - 1), step=1, invalidates=_RESTART, uniform=False,
        applies_when=_MULTIPLE,
    ),
)

TECHNIQUE = TechniqueSpec(
    name="path_traced",
    label="Path traced (reference quality, slow)",
    engine="vtkvol.plugins.path_traced.technique:PathTraced",
    description=(
        "Light traced along random paths through the specimen from every voxel, all scattering "
        "orders, refining over frames: the physically exact look, for final renders and for "
        "checking faster methods on small volumes."
    ),
    parameters=PARAMETERS,
    lighting="medium",
    capabilities={"progressive", "cpu_path"},
    bench=(BenchSetting({}, "PT", quick=True),),
    stability=(),
)
