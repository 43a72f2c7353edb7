"""Convection–diffusion multiple scattering (seed 003 §3.2, "KD"): the declaration.

Light from each source is convected into the volume with absorption, then diffused where the
medium scatters; the result refines over frames and is never reset by camera moves. The engine
part is :mod:`.technique` (GPU compute, ping-pong textures), the numpy twin :mod:`.cpu`, the
decisions the paper leaves open are in docs/multiple-scattering.md. This module imports no VTK.
"""

from __future__ import annotations

from vtkvol.model.diffusion import (
    DIFFUSING_STEPS,
    MAX_TRACED_ORDERS,
    diffusion_model_params,
    traced_orders_param,
)
from vtkvol.model.params import Invalidates, Param, backend_param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec

_RESTART = Invalidates.ACCUMULATION

PARAMETERS: tuple[Param, ...] = (
    Param(
        "iterations_per_frame", 4, "Iterations per frame",
        "Transport iterations run before each frame: more refine faster, each frame costs more.",
        kind="int", range=(1, 256), step=1, uniform=False,
    ),
    Param(
        "max_iterations", 0, "Iterations",
        "Iterations after which the result is final. 0 = automatic: source model, until the "
        "residual is below the tolerance (and, with traced orders, traced_paths paths are "
        "drawn); published model, four times what the light front "
        "needs to cross the volume's diagonal (it moves half a voxel per iteration).",
        kind="int", range=(0, 100000), step=1, uniform=False,
    ),
    Param(
        "diffusion_steps", 1, "Diffusion steps",
        "Diffusion steps per iteration: explicit steps (published) or Jacobi sweeps (source); "
        "0 = direct light only, no multiple scattering (no traced orders either).",
        kind="int", range=(0, 16), step=1, invalidates=_RESTART, uniform=False,
    ),
    Param(
        "absorption_mapping", "matched", "Absorption",
        "matched: the per-iteration absorption is set so an axis-aligned light decays exactly as "
        "exp(−σ·distance) (tanh(σh)); vpt: half the opacity of a voxel, as the authors' code "
        "does (for reproduction). Published model only: the source model ray-marches its "
        "direct light, with no convection to absorb in.",
        kind="choice", choices=("matched", "vpt"), invalidates=_RESTART, uniform=False,
        choice_labels=("Matched to exp(−σ·distance)", "As the authors' code (VPT)"),
        applies_when=(("diffusion_model", ("published",)),),
    ),
    traced_orders_param(_RESTART),
    Param(
        "traced_paths", 256, "Traced paths",
        "Source model with traced orders: paths per voxel (one per iteration) after which the "
        "traced light is final; the result is final once they are drawn and the residual is "
        "below the tolerance (the noise falls as 1/√paths).",
        kind="int", range=(1, 100000), step=1, invalidates=_RESTART, uniform=False,
        applies_when=(("diffusion_model", ("source",)),
                      ("traced_orders", tuple(range(1, MAX_TRACED_ORDERS + 1))),
                      ("diffusion_steps", DIFFUSING_STEPS)),
    ),
    *diffusion_model_params(_RESTART),
    backend_param(_RESTART),
)

TECHNIQUE = TechniqueSpec(
    name="convection_diffusion",
    label="Multiple scattering (convection–diffusion)",
    engine="vtkvol.plugins.convection_diffusion.technique:ConvectionDiffusion",
    description=(
        "Soft, glowing light that scatters inside the specimen (seed 003's convection–diffusion): "
        "each light is carried into the volume with absorption and diffused where the medium "
        "scatters, refining over frames; camera moves never restart it."
    ),
    parameters=PARAMETERS,
    lighting="medium",
    capabilities={"progressive", "cpu_path"},
    bench=(
        BenchSetting({}, "KD", quick=True),
        BenchSetting({"diffusion_steps": 0}, "KD direct only"),
        BenchSetting({"traced_orders": 0}, "KD no traced orders"),
        BenchSetting({"diffusion_model": "published"}, "KD published"),
        BenchSetting({"diffusion_model": "published", "absorption_mapping": "vpt"},
                     "KD as published (VPT absorption)"),
    ),
    stability=(BenchSetting({}, "KD", quick=True),
               BenchSetting({"diffusion_model": "published"}, "KD published", quick=True)),
    # The numpy path traces its orders through the Monte-Carlo reference, seconds per path
    # and voxel grid at 64³ on two cores: eight paths keep the benchmark's per-voxel check
    # under a minute; their noise (1/√8) is part of the reported error.
    cpu_path_values={"traced_paths": 8},
)
