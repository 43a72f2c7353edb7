"""Translucency (seed 001 §2.3.1, eqs. 2.42–2.44, after Kniss et al.): the declaration.

Per light, a light volume holding the direct transmittance (the shadow volume's transmittance
model, unchanged) and an RGB *indirect* transmittance with its own chromatic extinction, blurred
within a cone towards the light as it propagates. Built on the shadow volume's slice-by-slice
propagation (:mod:`vtkvol.plugins.shadow_volume`), so camera moves never recompute and up to four
lights work. The engine part is :mod:`.technique`, the numpy path :mod:`.cpu`, the shaders are in
``shaders/``; docs/translucency.md has the model and the choices made where the text is
ambiguous. This module imports no VTK.
"""

from __future__ import annotations

from vtkvol.engine.light_grid import RESOLUTIONS
from vtkvol.model.params import Invalidates, Param, backend_param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec

_ILLUM = Invalidates.ILLUMINATION

#: Surface-shading factor choices and their ``VV_TL_SURFACE`` value in the fragment shader.
SURFACE_FACTORS: dict[str, int] = {"gradient": 1, "binary": 0}

PARAMETERS: tuple[Param, ...] = (
    Param(
        "indirect_angle", 15.0, "Indirect cone θ",
        "Half-angle of the cone, opening towards the light, within which the indirect light is "
        "averaged as it propagates (eq. 2.44's Blur(θ)): a Gaussian per slice whose 2σ reach is "
        "the cone's radius over one slice, d·tan θ (docs/translucency.md). The document gives no "
        "value; project default 15°.",
        range=(0.0, 60.0), step=1.0, unit="°", invalidates=_ILLUM, uniform=False,
    ),
    Param(
        "indirect_extinction", 0.5, "Indirect extinction k",
        "Extinction of the indirect light relative to the direct one: τ_i = k·τ·(1 − tint·colour) "
        "per RGB channel, colour = the transfer function's colour. The document gives no value; "
        "project default 0.5 (indirect light travels twice as far as direct light in grey "
        "material).",
        range=(0.0, 2.0), step=0.05, invalidates=_ILLUM, uniform=False,
    ),
    Param(
        "tint", 0.75, "Chromatic tint",
        "How much the transfer function's colour lowers the indirect extinction of its own "
        "channel (0: grey indirect light; 1: white material never attenuates indirect light). "
        "Project default 0.75.",
        range=(0.0, 1.0), step=0.05, invalidates=_ILLUM, uniform=False,
    ),
    Param(
        "indirect_strength", 1.0, "Indirect strength",
        "Weight of the indirect term in the light reaching a sample, I_l = T + w·T_i (eq. 2.44 "
        "has w = 1), divided by 1 + w when normalised. 0 = direct light only, i.e. the shadow "
        "volume's transmittance.",
        range=(0.0, 2.0), step=0.05,
    ),
    Param(
        "indirect_normalised", True, "Normalise to the irradiance",
        "Divide the light by 1 + w, so that an unoccluded sample receives the light's "
        "irradiance once, as with every other technique, and the indirect term redistributes "
        "light into shadows instead of adding it everywhere. Off: eq. 2.44's sum T + w·T_i "
        "(twice the irradiance in empty space at w = 1). Project default: on.",
        kind="bool",
    ),
    Param(
        "surface_factor", "gradient", "Surface shading",
        "gradient: Kniss's surface-shading factor S = smoothstep(g₀, g₁, |∇f|) blends unoriented "
        "lighting (S = 0) and Blinn–Phong (S = 1) by the gradient magnitude; binary: the host's "
        "rule (Blinn–Phong wherever the gradient is not zero).",
        kind="choice", choices=tuple(SURFACE_FACTORS), invalidates=Invalidates.SHADER,
        uniform=False,
    ),
    Param(
        "gradient_low", 0.05, "Gradient g₀",
        "Gradient magnitude below which a sample is lit as an unoriented medium (S = 0): change "
        "of the value per voxel, as a fraction of the transfer function's range. Project default "
        "0.05.",
        range=(0.0, 1.0), step=0.01, unit="range/voxel",
        applies_when=(("surface_factor", ("gradient",)),),
    ),
    Param(
        "gradient_high", 0.2, "Gradient g₁",
        "Gradient magnitude above which a sample is fully surface-shaded (S = 1); same unit as "
        "g₀ (a value below g₀ acts as g₀). Project default 0.2.",
        range=(0.0, 1.0), step=0.01, unit="range/voxel",
        applies_when=(("surface_factor", ("gradient",)),),
    ),
    Param(
        "resolution", "full", "Resolution",
        "Light-volume cells per axis relative to the data: full, half or quarter (the shadow "
        "volume's grids).",
        kind="choice", choices=tuple(RESOLUTIONS), invalidates=_ILLUM, uniform=False,
    ),
    Param(
        "offset", 1.25, "Offset h₀",
        "The light volume is read this many cells towards the light, so that a surface does not "
        "shadow itself (as the shadow volume; seed 000's h₀ = 1.25).",
        range=(0.0, 4.0), step=0.05, unit="voxel",
    ),
    backend_param(_ILLUM),
)

TECHNIQUE = TechniqueSpec(
    name="translucency",
    label="Translucency (direct + coloured indirect light)",
    engine="vtkvol.plugins.translucency.technique:Translucency",
    description=(
        "Light passing through tissue (seed 001 after Kniss et al.): per light a sharp direct "
        "transmittance plus a blurred, colour-shifted indirect term with its own extinction, "
        "precomputed slice by slice into an RGBA light volume whenever the light, transfer "
        "function, crop or data change; up to four lights, camera moves are free. Surfaces are "
        "shaded by a gradient-magnitude factor (Kniss)."
    ),
    parameters=PARAMETERS,
    lighting="surface",
    capabilities={"cpu_path", "rgb", "adds_light"},
    # The default look, the same light volume at half resolution, and the direct term alone
    # under the host's shading rule (which must measure like shadow_volume "T full").
    bench=(
        BenchSetting({}, "T + indirect", quick=True),
        BenchSetting({"resolution": "half"}, "T + indirect ½"),
        BenchSetting({"indirect_strength": 0.0, "surface_factor": "binary"}, "direct only",
                     quick=True),
    ),
    stability=(BenchSetting({}, "T + indirect", quick=True),),
)
