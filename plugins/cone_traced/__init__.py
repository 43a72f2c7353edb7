"""Cone-traced ambient occlusion and soft shadows (seed 000's method 1): the declaration.

The engine part is :mod:`.technique` (filtered opacity pyramid, bake, numpy twins); the shaders
are in ``shaders/``. This module imports no VTK.
"""

from __future__ import annotations

from vtkvol.model.params import Invalidates, Param, backend_param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec

#: AO variants (``ao_mode``) and their ``VV_CT_AO`` value in the fragment shader.
AO_MODES: tuple[str, ...] = ("off", "view_cone", "hemisphere", "baked_hemisphere")
#: What the app shows for each of :data:`AO_MODES`.
AO_MODE_LABELS: tuple[str, ...] = ("Off", "View cone", "Hemisphere (per sample)",
                                   "Hemisphere (baked)")
#: Baked-AO grid: data voxels per grid step (``ao_resolution``).
AO_RESOLUTIONS: dict[str, int] = {"full": 1, "half": 2}

_BAKE = Invalidates.FRAME | Invalidates.ILLUMINATION

PARAMETERS: tuple[Param, ...] = (
    Param(
        "shadows", True, "Soft shadows",
        "Trace one cone towards every light and darken its diffuse and specular light.",
        kind="bool", invalidates=Invalidates.SHADER, uniform=False,
    ),
    Param(
        "shadow_cone", "light size", "Shadow cone",
        "light size: each light's cone is the angle its physical size subtends (the light's "
        "size in the lights dock: angular radius of a directional light, radius / distance of a "
        "point light), so the penumbra is the light's own; custom: the angle below for every "
        "light.",
        kind="choice", choices=("light size", "custom"), invalidates=Invalidates.SHADER,
        choice_labels=("Light size", "Custom"),
        uniform=False, applies_when=(("shadows", (True,)),),
    ),
    Param(
        "shadow_angle", 5.0, "Shadow cone angle",
        "Half-angle of the cone traced towards each light (custom cone); larger = softer "
        "shadows (thesis 5°).",
        range=(0.0, 90.0), step=0.5, unit="°", uniform=False,
        applies_when=(("shadows", (True,)), ("shadow_cone", ("custom",))),
    ),
    Param(
        "shadow_strength", 1.0, "Shadow strength",
        "How much of the light the shadow cone's occlusion removes (diffuse × (1 − s·occlusion)).",
        range=(0.0, 1.0), step=0.05,
        applies_when=(("shadows", (True,)),),
    ),
    Param(
        "ao_mode", "baked_hemisphere", "Ambient occlusion",
        "off; view_cone: one cone towards the viewer (the thesis' directional AO); "
        "hemisphere: N cones about the outward normal, cosine-weighted, traced per sample; "
        "baked_hemisphere: the same cones traced once per voxel of the AO grid when the data or "
        "transfer function change, then one texture fetch per sample (measured within 0.02 RMSE "
        "of per-sample, at about half its frame time on llvmpipe).",
        kind="choice", choices=AO_MODES, choice_labels=AO_MODE_LABELS,
        invalidates=Invalidates.SHADER | Invalidates.ILLUMINATION, uniform=False,
    ),
    Param(
        "ao_cones", "6", "AO cones",
        "Cones of the AO hemisphere (half-angle chosen so they tile it: 90°, 48°, 34°, 24°). "
        "Re-bakes baked AO.",
        kind="choice", choices=("1", "3", "6", "12"),
        invalidates=Invalidates.SHADER | Invalidates.ILLUMINATION, uniform=False,
        applies_when=(("ao_mode", ("hemisphere", "baked_hemisphere")),),
    ),
    Param(
        "ao_resolution", "full", "Baked AO resolution",
        "Grid of the baked AO (baked_hemisphere): full = one value per voxel; half = every "
        "second voxel per axis (8× fewer points, bakes ≈ 3× faster; less accurate near small "
        "features). Both are interpolated trilinearly.",
        kind="choice", choices=tuple(AO_RESOLUTIONS),
        choice_labels=("Full (every voxel)", "Half (every second voxel)"),
        invalidates=Invalidates.ILLUMINATION, uniform=False,
        applies_when=(("ao_mode", ("baked_hemisphere",)),),
    ),
    Param(
        "ao_angle", 30.0, "View-cone AO angle",
        "Half-angle of the single AO cone towards the viewer (view_cone mode; thesis 30°).",
        range=(0.0, 90.0), step=1.0, unit="°", uniform=False,
        applies_when=(("ao_mode", ("view_cone",)),),
    ),
    Param(
        "max_distance", 24.0, "AO distance",
        "Only absorbers within this distance occlude (AO cones), in voxels of the smallest edge. "
        "Re-bakes baked AO.",
        range=(1.0, 1024.0), step=1.0, unit="voxel", scale="log", uniform=False,
        invalidates=_BAKE,
        applies_when=(("ao_mode", ("view_cone", "hemisphere", "baked_hemisphere")),),
    ),
    Param(
        "ao_strength", 1.0, "AO strength",
        "How much of the ambient light the occlusion removes (ambient × (1 − s·AO)).",
        range=(0.0, 1.0), step=0.05,
        applies_when=(("ao_mode", ("view_cone", "hemisphere", "baked_hemisphere")),),
    ),
    Param(
        "sigma", 1.0, "Filter σ",
        "Standard deviation of the Gaussian that filters the opacity, in texels of each mip "
        "level (voxels at level 0). The cone changes level when its half-width exceeds "
        "lod_width·σ·2^L.",
        range=(0.5, 4.0), step=0.25, unit="voxel", invalidates=Invalidates.ILLUMINATION,
    ),
    Param(
        "span", 3.0, "Filter span",
        "Gaussian kernel radius in σ (kernel radius = round(span·σ) texels; thesis 3σ).",
        range=(1.0, 4.0), step=0.5, unit="σ", invalidates=Invalidates.ILLUMINATION,
        uniform=False,
    ),
    Param(
        "lod_width", 4.0, "LOD switch width",
        "The cone moves up one mip level (and doubles its step) when its half-width b·sin α "
        "exceeds lod_width·σ·2^L voxels. The thesis used 2; 4 is closer to the Monte-Carlo "
        "references for shadows and AO (docs/cone-tracing.md). Re-bakes baked AO.",
        range=(1.0, 8.0), step=0.5, unit="σ", invalidates=_BAKE,
    ),
    Param(
        "h", 2.5, "Cone step",
        "Step of the cone march at mip level 0, in voxels; doubles with every level (thesis "
        "2.5σ). Re-bakes baked AO.",
        range=(0.5, 8.0), step=0.25, unit="voxel", invalidates=_BAKE,
    ),
    Param(
        "h0", 3.0, "Start offset",
        "Distance of the first cone segment from the sample, against self-occlusion (thesis 3σ). "
        "Re-bakes baked AO.",
        range=(0.0, 12.0), step=0.25, unit="voxel", invalidates=_BAKE,
    ),
    Param(
        "opacity_threshold", 0.05, "Opacity threshold",
        "Shadows and per-sample AO are computed only for samples whose transfer-function "
        "opacity (per unit distance) exceeds this (thesis 0.05); baked AO applies everywhere.",
        range=(0.0, 1.0), step=0.01,
    ),
    backend_param(_BAKE),
)




TECHNIQUE = TechniqueSpec(
    name="cone_traced",
    label="Cone-traced AO and soft shadows",
    engine="vtkvol.plugins.cone_traced.technique:ConeTraced",
    description=(
        "Soft shadows (one cone per light) and ambient occlusion (view cone or a hemisphere of "
        "cones) traced through a Gaussian-filtered opacity mip chain: shadows per sample, the "
        "hemisphere AO per sample or baked once per voxel (default). Precomputed only when "
        "data, transfer function or AO settings change; light and camera moves are free."
    ),
    parameters=PARAMETERS,
    lighting="surface",
    capabilities={"cpu_path"},
    bench=(
        BenchSetting({"ao_mode": "off"}, "shadows", quick=True),
        BenchSetting({"ao_mode": "view_cone"}, "AO view"),
        BenchSetting({"ao_mode": "baked_hemisphere", "ao_cones": "6"}, "AO baked 6", quick=True),
        BenchSetting(
            {"ao_mode": "baked_hemisphere", "ao_cones": "6", "ao_resolution": "half"},
            "AO baked 6 ½",
        ),
        *(
            BenchSetting({"ao_mode": "hemisphere", "ao_cones": c}, f"AO {c}", quick=c != "3")
            for c in ("1", "3", "6", "12")
        ),
    ),
    # Shadows only in quick runs (every case then needs only a transmittance reference); the
    # default AO as well in full runs.
    stability=(
        BenchSetting({"ao_mode": "off"}, "shadows", quick=True),
        BenchSetting({}, "default"),
    ),
)
