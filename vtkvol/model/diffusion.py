"""The declared parameters both grid-diffusion techniques (convection–diffusion and hybrid
diffusion) share: which diffusion model runs, when the source model stops and how many of its
first scattering orders are traced. No VTK here;
the models themselves are in :mod:`vtkvol.engine.diffusion` and docs/multiple-scattering.md."""

from __future__ import annotations

from vtkvol.model.params import Invalidates, Param

#: The models, the default first.
DIFFUSION_MODELS = ("source", "published")
#: The source model's stopping tolerance: relative residual ‖b − Aφ‖/‖b‖.
DEFAULT_TOLERANCE = 1e-4
#: The grids the source model's scattered light can be solved on, the default first: the data
#: grid, or ⌈n/2⌉ / ⌈n/4⌉ cells per axis tiling the same extent (issue 24).
SCATTER_GRIDS = ("full", "half", "quarter")


def diffusion_model_params(invalidates: Invalidates) -> tuple[Param, ...]:
    """``diffusion_model``, ``tolerance`` and ``scatter_grid``, restarting the accumulation
    (``invalidates``)."""
    return (
        Param(
            "diffusion_model", "source", "Diffusion model",
            "source: the scattered light solves a diffusion equation with the single-scattering "
            "source σ_s·E_direct and absorption σ_a, positive and stopped by the residual "
            "tolerance; published: seed 003 as written (eq. 7 split into convection with "
            "absorption and explicit diffusion), for comparison.",
            kind="choice", choices=DIFFUSION_MODELS, invalidates=invalidates, uniform=False,
            choice_labels=("Single-scattering source", "As published (seed 003)"),
        ),
        Param(
            "tolerance", DEFAULT_TOLERANCE, "Tolerance",
            "Source model: the scattered light is final once the relative residual of its "
            "equation is below this.",
            kind="float", range=(1e-8, 0.1), invalidates=invalidates, uniform=False,
        ),
        Param(
            "scatter_grid", SCATTER_GRIDS[0], "Scattered-light grid",
            "Source model: the grid the scattered light is solved on — full: the data grid; "
            "half / quarter: ½ or ¼ of the cells per axis over the same extent (8× or 64× "
            "fewer unknowns and texels, fewer and cheaper sweeps; the light is smoother, the "
            "error measured in docs/benchmarks.md). The direct light stays on the data grid.",
            kind="choice", choices=SCATTER_GRIDS, invalidates=invalidates, uniform=False,
            choice_labels=("Data grid", "½ per axis", "¼ per axis"),
            applies_when=(("diffusion_model", ("source",)),),
        ),
    )


#: Scattering orders traced per voxel by default (``traced_orders``) and the most allowed.
DEFAULT_TRACED_ORDERS = 3
MAX_TRACED_ORDERS = 4


#: The ``diffusion_steps`` values with scattered light (0 is the direct light alone, which
#: traces no orders either); the techniques' range is 0…16.
DIFFUSING_STEPS = tuple(range(1, 17))


def traced_orders_param(invalidates: Invalidates) -> Param:
    """``traced_orders`` (source model): the first scattering orders traced per voxel before the
    diffusion takes over (:mod:`vtkvol.engine.traced_orders`), restarting the accumulation
    (``invalidates``)."""
    return Param(
        "traced_orders", DEFAULT_TRACED_ORDERS, "Traced orders",
        "Source model: the first scattering orders traced per voxel (one path per iteration, "
        "next-event estimation at each collision) before the diffusion takes over from the last "
        "of them. Traced light crosses empty space (a cavity, the gap between two objects), "
        "which a diffusion cannot; 0 = the diffusion from the direct light alone. Each order "
        "costs about one more tracking per voxel and iteration.",
        kind="int", range=(0, MAX_TRACED_ORDERS), step=1, invalidates=invalidates,
        uniform=False, applies_when=(("diffusion_model", ("source",)),
                                     ("diffusion_steps", DIFFUSING_STEPS)),
    )
