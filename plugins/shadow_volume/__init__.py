"""Precomputed shadow volumes (seed 000 §2.7, made fast and physical): the declaration.

The engine part is :mod:`.technique` (GPU propagation, numpy twin); the shaders are in
``shaders/``. This module imports no VTK: the model, sessions and the lights dock read it.
"""

from __future__ import annotations

from vtkvol.engine.light_grid import RESOLUTIONS
from vtkvol.model.params import Invalidates, Param, backend_param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec

_ILLUM = Invalidates.ILLUMINATION

PARAMETERS: tuple[Param, ...] = (
    Param(
        "model", "transmittance", "Model",
        "transmittance: physically based T = Π(1 − α) with opacity corrected for the "
        "oblique path through each slice. seed000: the thesis's additive, clamped opacity "
        "with a fixed unit Gaussian over 8×8 neighbours (for reproduction).",
        kind="choice", choices=("transmittance", "seed000"), invalidates=_ILLUM,
        choice_labels=("Transmittance (physical)", "Thesis (seed 000)"),
        uniform=False,
    ),
    Param(
        "resolution", "full", "Resolution",
        "Light-volume cells per axis relative to the data: full, half or quarter. Lower "
        "resolution recomputes 8× or 64× faster and blurs the shadow edge accordingly.",
        kind="choice", choices=tuple(RESOLUTIONS), invalidates=_ILLUM, uniform=False,
        choice_labels=tuple(name.capitalize() for name in RESOLUTIONS),
    ),
    Param(
        "softness_from", "light size", "Softness from",
        "light size: each light's penumbra follows its physical size (lights dock), matched to "
        "the geometric penumbra half-way through the volume (docs/shadow-volume.md); custom: "
        "the softness below for every light.",
        kind="choice", choices=("light size", "custom"), invalidates=_ILLUM, uniform=False,
        choice_labels=("Light size", "Custom"),
        applies_when=(("model", ("transmittance",)),),
    ),
    Param(
        "softness", 0.0, "Softness",
        "Standard deviation of the Gaussian blur applied per slice, in light-volume cells "
        "(transmittance model): penumbrae widen with the square root of the distance to "
        "the occluder. 0 = hard shadows (bilinear interpolation only).",
        range=(0.0, 4.0), step=0.1, unit="voxel", invalidates=_ILLUM, uniform=False,
        applies_when=(("model", ("transmittance",)), ("softness_from", ("custom",))),
    ),
    Param(
        "strength", 1.0, "Strength",
        "How much of the shadow is applied: visibility = 1 − strength·(1 − V).",
        range=(0.0, 1.0), step=0.05,
    ),
    Param(
        "offset", 1.25, "Offset h₀",
        "The light volume is read this many cells towards the light, so that a surface "
        "does not shadow itself (the thesis's h₀ = 1.25).",
        range=(0.0, 4.0), step=0.05, unit="voxel",
    ),
    backend_param(_ILLUM),
)



_SHORT = {"transmittance": "T", "seed000": "seed000", "full": "full", "half": "½", "quarter": "¼"}

TECHNIQUE = TechniqueSpec(
    name="shadow_volume",
    label="Precomputed shadow volume",
    engine="vtkvol.plugins.shadow_volume.technique:ShadowVolume",
    description=(
        "Cast shadows from up to four lights, precomputed slice by slice into a light volume "
        "whenever the light, transfer function, crop or data change; one texture fetch per "
        "shaded sample, so frames cost almost the same as local shading."
    ),
    parameters=PARAMETERS,
    lighting="surface",
    capabilities={"cpu_path"},
    # Both models at every resolution; "offset 0" reads the volume without the self-shadowing
    # offset and without blur (what the physical reference computes), to show the offset's share
    # of the error.
    bench=(
        *(
            BenchSetting({"model": m, "resolution": r}, f"{_SHORT[m]} {_SHORT[r]}", quick=True)
            for m in ("transmittance", "seed000")
            for r in ("full", "half", "quarter")
        ),
        *(
            BenchSetting(
                {"model": "transmittance", "resolution": r, "softness": 0.0, "offset": 0.0},
                f"T {_SHORT[r]}, offset 0", quick=r == "full",
            )
            for r in ("full", "half", "quarter")
        ),
    ),
    stability=(
        BenchSetting({"model": "transmittance"}, "T", quick=True),
        BenchSetting({"model": "seed000"}, "seed000", quick=True),
    ),
)
