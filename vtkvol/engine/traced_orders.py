"""Per-voxel tracking towards the lights, shared by the grid-diffusion techniques (issue 24):
hybrid diffusion's direct light and both techniques' traced scattering orders.

``traced_orders`` k > 0 (the source model): per iteration one Monte-Carlo path per voxel traces
the first k scattering orders — delta tracking to each collision, next-event estimation to every
light (the tracker), the albedo per collision, Henyey–Greenstein phase — and keeps running means
of E_1 + … + E_k (shown: "traced") and of E_k ("last": the diffusion's source becomes σ_s·E_k
instead of σ_s·E_0). Light traced this way crosses empty space (a cavity, the gap between two
objects), which a local diffusion cannot.

The GPU path is ``resources/shaders/tracker.comp.glsl`` driven by :class:`GpuTracker`; its numpy
counterpart for the orders is :func:`traced_orders_sample` (the Monte-Carlo reference
:func:`vtkvol.reference.inscattered_mc`: the same estimator with other random numbers, so the
two agree in the mean, not sample by sample). Lengths are µm (dataset space), arrays
``[z, y, x(, c)]`` on the data's voxel centres.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
import vtk

from vtkvol.engine.diffusion import GROUP, Grid, LightSource, dispatch_groups, light_quadrature
from vtkvol.engine.gl import ComputeProgram, Texture3D, unbind_images
from vtkvol.engine.shaders import compute_source

#: Tentative collisions after which a path counts as absorbed.
MAX_STEPS = 512
#: Ratio tracking stops once the throughput is this small (its remaining contribution).
MIN_THROUGHPUT = 1e-6
#: Edge (voxels) of the bricks of the per-brick majorant grid.
BRICK = 8
#: Offset of the traced orders' Monte-Carlo seeds (iteration k of seed s uses
#: ORDERS_SEED_BASE + s·1000003 + k): the bench's references use seeds 0 and 1, and a technique
#: measured against them must not share their paths.
ORDERS_SEED_BASE = 1 << 21
#: The diffusion reads an RGB light (the traced orders' E_k, HD's ρ_d) as three "lights" with
#: these colours: its r, g, b.
RGB_AS_LIGHTS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
#: The three "lights" of :data:`RGB_AS_LIGHTS` for the source diffusion's fall-off: directional,
#: so none (the fall-off is in the traced light already).
RGB_LIGHTS = (LightSource("directional", (0.0, 0.0, 1.0)),) * 3


class TracedSetup(Protocol):
    """What the tracker needs of a technique's accumulation setup (dataset µm)."""

    grid: Grid
    sigma_t: Any  # np.ndarray [z, y, x], extinction per µm
    lights: Sequence[LightSource]
    colors: Sequence[tuple[float, float, float]]
    unit_distance: float | None  # µm; None: σ_t interpolated linearly
    bricks: Any  # np.ndarray [bz, by, bx] (brick_majorants) or None for the global majorant
    orders: int  # traced scattering orders k (0: none)
    albedo: float
    phase_g: float


def brick_majorants(sigma_t: np.ndarray) -> np.ndarray:
    """The per-brick majorant grid ``[bz, by, bx]`` (float32, per µm): the largest σ_t any
    trilinear sample inside each brick of :data:`BRICK`³ voxels can take — the maximum over the
    brick's voxels and the next voxel along each axis (a sample between the brick's last voxel
    centre and the next one interpolates both)."""
    out = sigma_t.astype(np.float32)
    for axis in range(3):
        n = out.shape[axis]
        bricks = -(-n // BRICK)
        pad = bricks * BRICK + 1 - n  # room for the next voxel of the last brick
        padded = np.concatenate([out, np.take(out, [n - 1] * pad, axis=axis)], axis=axis)
        # Brick b covers voxels [B·b, B·b + B]: a sliding maximum over B + 1 voxels, every B.
        windows = np.lib.stride_tricks.sliding_window_view(padded, BRICK + 1, axis=axis)
        out = np.take(windows.max(axis=-1), np.arange(bricks) * BRICK, axis=axis)
    return np.ascontiguousarray(out, np.float32)


def traced_orders_sample(setup: TracedSetup, region: tuple[int, int, int, int], iteration: int,
                         seed: int) -> tuple[np.ndarray, np.ndarray]:
    """One path per voxel of ``region`` (z0, z1, y0, y1; all x) for the traced orders 1 … k
    (``setup.orders``): (E_1 + … + E_k, E_k), each ``[z1 − z0, y1 − y0, x, 3]`` float32 in the
    lights' colours. The numpy path of ``tracker.comp.glsl``'s ``VV_ORDERS``: the same estimator
    (the Monte-Carlo reference, :func:`vtkvol.reference.inscattered_mc`: delta tracking to each
    collision, next-event estimation, albedo and Henyey–Greenstein g) with other random
    numbers — the two agree in the mean (tested), not sample by sample. A sized light is the
    engine's quadrature of its extent (:func:`~vtkvol.engine.diffusion.light_quadrature`).
    Voxels no visible sample reads (:func:`readable_voxels`) stay 0 and cost nothing."""
    from vtkvol.reference import DirectionalLight, PointLight, inscattered_mc

    grid = setup.grid
    z0, z1, y0, y1 = region
    nx = grid.shape_zyx[2]
    origin = np.asarray(grid.origin, np.float64)
    lights: list[DirectionalLight | PointLight] = []
    colors: list[tuple[float, float, float]] = []
    for light, color in zip(setup.lights, setup.colors, strict=True):
        for part, weight in light_quadrature(light):
            if part.kind == "point":
                lights.append(PointLight(tuple(np.asarray(part.vector) - origin),
                                         falloff_distance=part.falloff_distance))
            else:
                lights.append(DirectionalLight(part.vector))
            colors.append(tuple(float(c) * weight for c in color))
    readable = readable_voxels(setup)[z0:z1, y0:y1]
    zz, yy, xx = np.nonzero(readable)
    points = np.stack([xx, yy + y0, zz + z0], axis=-1) * np.asarray(grid.spacing)
    unit = setup.unit_distance if setup.unit_distance else 1.0
    alpha = -np.expm1(-np.asarray(setup.sigma_t, np.float64) * unit)
    run_seed = ORDERS_SEED_BASE + seed * 1000003 + iteration
    out = []
    for lowest in (1, setup.orders):
        field = np.zeros((z1 - z0, y1 - y0, nx, 3), np.float32)
        if len(points):
            field[readable] = inscattered_mc(
                alpha, grid.spacing, lights, albedo=setup.albedo, phase_g=setup.phase_g,
                n_paths=1, seed=run_seed, unit_distance=unit, max_bounces=setup.orders,
                min_bounces=lowest, points=points, light_colors=colors)
        out.append(field)
    return out[0], out[1]


def global_majorant(setup: TracedSetup) -> float:
    """The largest σ_t (per µm) of ``setup``, cached on it: a sample is drawn in many regions
    per accumulation, and the grid does not change within one."""
    majorant = getattr(setup, "max_sigma_t", None)
    if majorant is None:
        majorant = float(np.asarray(setup.sigma_t).max())
        setup.max_sigma_t = majorant
    return majorant


def readable_voxels(setup: TracedSetup) -> np.ndarray:
    """Voxels a visible sample can read (``[z, y, x]`` bool, cached on ``setup``): σ_t > 0 in
    the 26-neighbourhood. The others are a corner of no cell with opacity, so their traced
    light is never shown (nor a source: the diffusion has no unknown there); the traced orders
    leave them 0 and spend no path on them, as ``tracker.comp.glsl`` does."""
    readable = getattr(setup, "readable", None)
    if readable is None:
        from scipy.ndimage import binary_dilation

        readable = binary_dilation(np.asarray(setup.sigma_t) > 0.0,
                                   structure=np.ones((3, 3, 3), bool))
        setup.readable = readable
    return readable


class GpuTracker:
    """``tracker.comp.glsl``'s programs (one per variant, compiled once) and their dispatch:
    the uniforms of a setup's grid, lights and medium, and the images the variant declares."""

    def __init__(self, render_window: vtk.vtkRenderWindow, label: str) -> None:
        self.render_window = render_window
        self.label = label
        self.programs: dict[tuple[bool, str, str, bool, int], ComputeProgram] = {}

    def program(self, *, direct: bool, orders: int, estimator: str = "ratio",
                light_sampling: str = "one", bricks: bool = False) -> ComputeProgram:
        """The variant: with ``direct`` the direct light's running mean (``VV_DIRECT``),
        ``orders`` traced orders (``VV_ORDERS``; > 0 without ``direct``), the ``estimator``
        ("ratio" / "delta") and ``light_sampling`` ("one" / "all") of the direct light's and
        the next events' tracking, and the per-brick majorant grid (``bricks``)."""
        if not direct and orders <= 0:
            raise ValueError("the tracker without the direct light needs traced orders")
        key = (direct, estimator, light_sampling, bricks, orders)
        prog = self.programs.get(key)
        if prog is None:
            defines = {
                "VV_DIRECT": "1" if direct else "0",
                "VV_RATIO": "1" if estimator == "ratio" else "0",
                "VV_ALL_LIGHTS": "1" if light_sampling == "all" else "0",
                "VV_MAX_STEPS": str(MAX_STEPS),
                "VV_MIN_THROUGHPUT": repr(MIN_THROUGHPUT),
                "VV_BRICKS": "1" if bricks else "0",
                "VV_BRICK": str(BRICK),
                "VV_ORDERS": str(orders),
            }
            source = compute_source("tracker.comp.glsl", defines)
            prog = ComputeProgram(self.render_window, source, f"{self.label} tracker {key}")
            self.programs[key] = prog
        return prog

    def sample(self, setup: TracedSetup, iteration: int, seed: int,
               region: tuple[int, int, int, int], sigma: Texture3D, *,
               bricks: Texture3D | None = None, direct: Texture3D | None = None,
               traced: Texture3D | None = None, last: Texture3D | None = None,
               estimator: str = "ratio", light_sampling: str = "one") -> None:
        """Sample ``iteration`` (the running means' index) of ``region`` (z0, z1, y0, y1) into
        the RGBA running means on the data grid: ``direct`` (the direct light, None: not
        sampled), ``traced`` and ``last`` (E_1 + … + E_k and E_k; needed when
        ``setup.orders``). ``sigma``: σ_t (r32f, per µm) on the data grid; ``bricks``: the
        per-brick majorants (``setup.bricks`` uploaded), None for the global majorant."""
        grid = setup.grid
        nz, ny, nx = grid.shape_zyx
        orders = int(setup.orders)
        prog = self.program(direct=direct is not None, orders=orders, estimator=estimator,
                            light_sampling=light_sampling, bricks=bricks is not None)
        prog.use()
        vecs: list[float] = []
        for light in setup.lights:
            vecs += [*light.vector, 1.0 if light.kind == "point" else 0.0]
        vecs += [0.0] * (16 - len(vecs))
        colors = [c for color in setup.colors for c in color]
        colors += [0.0] * (12 - len(colors))
        falloffs: list[float] = []
        for light in setup.lights:
            d0 = light.falloff_distance if light.kind == "point" else 0.0
            falloffs += [*light.vector, d0]
        falloffs += [0.0] * (16 - len(falloffs))
        prog.set_uniform("vv_sigma", 0)
        prog.set_uniform("vv_dims", nx, ny, nz)
        prog.set_uniform("vv_first", region[0], region[2])
        prog.set_uniform("vv_end", region[1], region[3])
        prog.set_uniform("vv_origin", *grid.origin, kind="f")
        prog.set_uniform("vv_spacing", *grid.spacing, kind="f")
        prog.set_uniform("vv_majorant", global_majorant(setup), kind="f")
        prog.set_uniform("vv_unitDistance", float(setup.unit_distance or 0.0), kind="f")
        prog.set_uniform("vv_iteration", iteration, kind="ui")
        prog.set_uniform("vv_seed", int(seed), kind="ui")
        prog.set_uniform("vv_numLights", len(setup.lights))
        prog.set_uniform_array("vv_lightVec", vecs, size=4)
        prog.set_uniform_array("vv_color", colors, size=3)
        prog.set_uniform_array("vv_falloff", falloffs, size=4)
        sizes = [float(light.size) for light in setup.lights]
        prog.set_uniform_array("vv_lightSize", sizes + [0.0] * (4 - len(sizes)), size=1)
        sigma.bind_image(0, "read")
        if direct is not None:
            prog.set_uniform("vv_direct", 1)
            direct.bind_image(1, "readwrite")
        if bricks is not None:
            assert setup.bricks is not None
            prog.set_uniform("vv_bricks", 2)
            nbz, nby, nbx = setup.bricks.shape
            prog.set_uniform("vv_brickDims", nbx, nby, nbz)
            bricks.bind_image(2, "read")
        if orders:
            assert traced is not None and last is not None
            prog.set_uniform("vv_traced", 3)
            prog.set_uniform("vv_last", 4)
            prog.set_uniform("vv_albedo", float(setup.albedo), kind="f")
            prog.set_uniform("vv_phaseG", float(setup.phase_g), kind="f")
            traced.bind_image(3, "readwrite")
            last.bind_image(4, "readwrite")
        groups = dispatch_groups(grid)
        prog.dispatch((groups[0], -(-(region[3] - region[2]) // GROUP[1]),
                       -(-(region[1] - region[0]) // GROUP[2])))
        unbind_images(self.render_window, 5 if orders else 3)
        prog.done()

    def release(self) -> None:
        for prog in self.programs.values():
            prog.release()
        self.programs.clear()
