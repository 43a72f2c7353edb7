"""Hybrid diffusion multiple scattering (seed 003 §3.3, "HD"): the declaration.

The direct light is estimated per voxel by tracking towards a randomly chosen light (unbiased,
averaged over iterations), the multiple scattering by the engine's grid diffusion (the source
model by default, or seed 003's published step);
memory does not grow with the number of lights. Engine part :mod:`.technique`, numpy twin
:mod:`.cpu`, decisions in docs/multiple-scattering.md ("Hybrid diffusion"). No VTK here.
"""

from __future__ import annotations

from vtkvol.model.diffusion import diffusion_model_params, traced_orders_param
from vtkvol.model.params import Invalidates, Param, backend_param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec

_RESTART = Invalidates.ACCUMULATION

PARAMETERS: tuple[Param, ...] = (
    Param(
        "iterations_per_frame", 2, "Iterations per frame",
        "Samples of the direct light (and diffusion steps) per voxel before each frame.",
        kind="int", range=(1, 256), step=1, uniform=False,
    ),
    Param(
        "max_iterations", 256, "Iterations",
        "Samples of the direct light per voxel (the noise falls as 1/√iterations); the source "
        "model's scattered light then refines until its residual tolerance.",
        kind="int", range=(1, 100000), step=1, uniform=False,
    ),
    Param(
        "diffusion_steps", 1, "Diffusion steps",
        "Diffusion steps per iteration: Jacobi sweeps (source) or explicit steps (published); "
        "0 = direct light only, no multiple scattering.",
        kind="int", range=(0, 16), step=1, invalidates=_RESTART, uniform=False,
    ),
    Param(
        "estimator", "ratio", "Estimator",
        "ratio: ratio tracking, unbiased with less noise (project default); delta: the paper's "
        "Woodcock tracking, where a path either reaches the light or is absorbed.",
        kind="choice", choices=("ratio", "delta"), invalidates=_RESTART, uniform=False,
        choice_labels=("Ratio tracking", "Delta tracking (paper)"),
    ),
    Param(
        "light_sampling", "one", "Lights per sample",
        "one: each sample tracks towards one light chosen at random (cost independent of the "
        "number of lights, as in the paper); all: towards every light.",
        kind="choice", choices=("one", "all"), invalidates=_RESTART, uniform=False,
        choice_labels=("One, chosen at random", "All"),
    ),
    Param(
        "majorant", "bricks", "Majorant",
        "bricks: each 8³-voxel brick tracks against its own largest extinction, so paths cross "
        "empty and thin regions in few steps (unbiased: the same mean); global: one majorant, "
        "the densest voxel's, as in the paper.",
        kind="choice", choices=("bricks", "global"), invalidates=_RESTART, uniform=False,
        choice_labels=("Per brick", "Global (paper)"),
    ),
    Param(
        "seed", 0, "Seed", "Random seed of the sample streams.",
        kind="int", range=(0, 2**31 - 1), step=1, invalidates=_RESTART, uniform=False,
    ),
    traced_orders_param(_RESTART),
    *diffusion_model_params(_RESTART),
    backend_param(_RESTART),
)

TECHNIQUE = TechniqueSpec(
    name="hybrid_diffusion",
    label="Multiple scattering (hybrid diffusion)",
    engine="vtkvol.plugins.hybrid_diffusion.technique:HybridDiffusion",
    description=(
        "Light that scatters inside the specimen (seed 003's hybrid method): direct light traced "
        "from every voxel towards the lights, unbiased and refining over frames, plus diffused "
        "multiple scattering; memory independent of the number of lights."
    ),
    parameters=PARAMETERS,
    lighting="medium",
    capabilities={"progressive", "cpu_path"},
    bench=(
        BenchSetting({}, "HD", quick=True),
        BenchSetting({"estimator": "delta"}, "HD delta tracking"),
        BenchSetting({"majorant": "global"}, "HD global majorant"),
        BenchSetting({"diffusion_model": "published"}, "HD published"),
        BenchSetting({"traced_orders": 0}, "HD no traced orders"),
    ),
    stability=(BenchSetting({"max_iterations": 16}, "HD 16 samples", quick=True),
               BenchSetting({"max_iterations": 16, "diffusion_model": "published"},
                            "HD published 16 samples", quick=True)),
    # The numpy tracker takes 3-6 s per sample at 64^3 on two cores: 256 samples per voxel
    # would hold the benchmark for tens of minutes per scene. Eight samples keep the per-voxel
    # check under a minute; its noise (ratio tracking, 1/sqrt(8)) is part of the reported error.
    cpu_path_values={"max_iterations": 8},
)
