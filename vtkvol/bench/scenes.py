"""Benchmark scenes: procedural phantoms with known structure, the user's files, stability cases.

A :class:`Scene` is what the benchmark renders: a scalar volume ``[z, y, x]``, its voxel size
(x, y, z) in µm, a linear opacity transfer function (``(value, alpha)`` points; alpha is the
opacity of a slab one smallest voxel edge thick, the ray caster's opacity unit distance), the
lights (world space, here equal to dataset space because the volume's matrix is the identity)
and the camera orbit. :meth:`Scene.opacity` evaluates the transfer function on the CPU with
numpy, so the references see exactly the opacity the techniques are given, without going
through any GPU code.

Scene families:

* phantoms (``vtkvol.reference.phantoms`` + :func:`cell_phantom` here): sphere over slab,
  hollow sphere, a confocal-like cell cluster with nuclei and membranes on anisotropic voxels;
* the user's files (``vtkvol bench --data FILE``), resampled to the benchmark size;
* :func:`stability_cases`: the sweeps of the stability suite (light direction, structure
  thickness, opacity scale, anisotropy, illumination-volume resolution, noise, 16-bit outliers).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vtkvol.reference import phantom_hollow_sphere, phantom_sphere_over_slab

Vec3 = tuple[float, float, float]

#: Light used by every benchmark scene unless a sweep changes it: from above, 30° off +z, so
#: shadows fall visibly onto the receivers below (world direction towards the light).
DEFAULT_LIGHT: Vec3 = (0.35, -0.25, 0.866)

#: Physical size of the benchmark's lights: angular radius (°), a small lamp's softness.
DEFAULT_LIGHT_SIZE_DEG = 2.0
#: AO distance of the scenes' reference (voxels of the smallest edge).
DEFAULT_AO_DISTANCE_VOXELS = 24.0

#: Single-scattering albedo of the scenes' medium: below 1 so that light is absorbed as well as
#: scattered (tissue), and the Monte-Carlo reference's paths end (0.9^48 < 1 %).
DEFAULT_ALBEDO = 0.9

#: Camera orbit of the comparison images (degrees): looking down onto the scene a little, so
#: cast shadows on horizontal receivers are visible.
DEFAULT_AZIMUTH = 30.0
DEFAULT_ELEVATION = 25.0

@dataclass
class Scene:
    """One volume to render and measure.

    Attributes
    ----------
    name
        Short identifier used in records, file names and tables.
    data
        Scalar volume ``[z, y, x]`` (uint8, uint16 or float32).
    spacing
        Voxel edge (x, y, z) in µm.
    opacity_points
        Linear opacity transfer function ``(value, alpha)``, alpha per smallest voxel edge.
    description
        One line for the tables.
    kind
        ``"phantom"``, ``"real"`` or ``"stability"``.
    lights
        World-space directions towards directional lights (unit or not).
    azimuth, elevation
        Camera orbit in degrees from the default view (looking along +y, z up).
    """

    name: str
    data: np.ndarray
    spacing: Vec3
    opacity_points: list[tuple[float, float]]
    description: str = ""
    kind: str = "phantom"
    lights: list[Vec3] = field(default_factory=lambda: [DEFAULT_LIGHT])
    #: The lights' physical size: angular radius (°) of every directional light. Every surface
    #: technique approximates this light, and the scene's one reference averages the exact
    #: transmittance over it.
    light_size_deg: float = DEFAULT_LIGHT_SIZE_DEG
    #: Ambient occlusion of the reference counts absorbers within this many voxels of the
    #: smallest edge (the cone tracer's default AO distance).
    ao_distance_voxels: float = DEFAULT_AO_DISTANCE_VOXELS
    azimuth: float = DEFAULT_AZIMUTH
    elevation: float = DEFAULT_ELEVATION
    #: Scattering material of the ``medium`` lighting model (techniques and reference alike):
    #: single-scattering albedo and Henyey–Greenstein asymmetry g.
    albedo: float = DEFAULT_ALBEDO
    phase_g: float = 0.0
    #: Intensity of each light (the convergence study's three-light scenes give each 1/3, so
    #: that the images do not saturate and compare with the one-light ones).
    light_intensity: float = 1.0
    #: Parallel (orthographic) instead of perspective projection of the comparison view, and
    #: the perspective camera's view angle (°).
    parallel: bool = False
    view_angle: float = 30.0
    #: Scenes whose image must be flat: the side (fraction of the image's shorter side) of the
    #: centred square in which every pixel sees the same surface under the same light (the
    #: stability suite records the spread there, ``flat_spread``); None for the others.
    flat_region: float | None = None

    @property
    def unit_distance(self) -> float:
        """Opacity unit distance in µm: the smallest voxel edge (what the ray caster uses)."""
        return float(min(self.spacing))

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(int(s) for s in self.data.shape[:3])  # type: ignore[return-value]

    @property
    def size_label(self) -> str:
        """``"nx×ny×nz"`` voxels."""
        nz, ny, nx = self.shape
        return f"{nx}x{ny}x{nz}"

    def opacity(self) -> np.ndarray:
        """Per-voxel opacity α ∈ [0, 1] (float32 ``[z, y, x]``) through the linear transfer
        function, as the ray caster and the techniques see it (non-finite values → 0)."""
        xs = np.array([p[0] for p in self.opacity_points], dtype=np.float64)
        ys = np.array([p[1] for p in self.opacity_points], dtype=np.float64)
        values = np.asarray(self.data)
        if values.dtype.kind == "f":
            values = np.where(np.isfinite(values), values, xs[0])
        return np.clip(np.interp(values, xs, ys), 0.0, 1.0).astype(np.float32)


# ------------------------------------------------------------------------------------------
# Phantoms
# ------------------------------------------------------------------------------------------
def _alpha_scene(
    name: str,
    alpha: np.ndarray,
    description: str,
    *,
    spacing: Vec3 = (1.0, 1.0, 1.0),
    lights: list[Vec3] | None = None,
    kind: str = "phantom",
) -> Scene:
    """A scene whose data *is* the opacity: identity transfer function 0 → 0, 1 → 1."""
    return Scene(name, np.ascontiguousarray(alpha, np.float32), spacing,
                 [(0.0, 0.0), (1.0, 1.0)], description, kind,
                 list(lights) if lights is not None else [DEFAULT_LIGHT])


def _smooth_noise(shape: Sequence[int], cell: int, rng: np.random.Generator) -> np.ndarray:
    """A smooth random field in [0, 1]: coarse uniform noise, trilinearly upsampled."""
    from scipy.ndimage import zoom

    coarse = rng.random(tuple(max(2, math.ceil(s / cell) + 1) for s in shape))
    factors = [s / c for s, c in zip(shape, coarse.shape, strict=True)]
    return np.clip(zoom(coarse, factors, order=1)[tuple(slice(0, s) for s in shape)], 0, 1)


def cell_phantom(n: int = 64, *, z_factor: int = 2, seed: int = 1) -> tuple[np.ndarray, Vec3]:
    """A confocal-like cell cluster: packed cells with membranes and textured nuclei.

    ``n`` voxels in x and y and ``n // z_factor`` slices in z, voxel size (1, 1, ``z_factor``)
    µm, so the stack is anisotropic like a confocal stack. Cells are the Voronoi regions of
    jittered seeds inside a sphere of radius 0.45·n µm; membranes are their boundaries (about
    1.5 µm wide), nuclei ellipsoids of half the cell size with a smooth texture. The image is
    blurred along z (σ 1 µm, the axial PSF), gets Gaussian noise (σ 4 of 255) and is returned
    as uint8 with the voxel size (x, y, z) µm. Deterministic for a given ``seed``.
    """
    from scipy.ndimage import gaussian_filter1d
    from scipy.spatial import cKDTree

    if n < 16 or z_factor < 1:
        raise ValueError(f"cell phantom needs n >= 16 and z_factor >= 1, got {n}, {z_factor}")
    rng = np.random.default_rng(seed)
    nz = max(4, n // z_factor)
    spacing: Vec3 = (1.0, 1.0, float(z_factor))
    z, y, x = np.meshgrid(np.arange(nz) * spacing[2], np.arange(n), np.arange(n), indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    centre = np.array([(n - 1) / 2, (n - 1) / 2, (nz - 1) * spacing[2] / 2])
    radius = 0.45 * n
    cell = n / 4.0  # about 16 cells across the cluster's diameter at any n
    grid = np.arange(-radius, radius + cell, cell)
    seeds = np.stack(np.meshgrid(grid, grid, grid, indexing="ij"), -1).reshape(-1, 3)
    seeds = seeds + rng.uniform(-0.3, 0.3, seeds.shape) * cell
    seeds = seeds[np.linalg.norm(seeds, axis=1) < radius - 0.3 * cell] + centre
    dist, idx = cKDTree(seeds).query(pts, k=2)
    inside = np.linalg.norm(pts - centre, axis=1) < radius
    # Membrane: near the bisector of the two nearest seeds (d2 − d1 small) or the outer surface.
    gap = (dist[:, 1] - dist[:, 0]) / 2.0
    outer = np.abs(np.linalg.norm(pts - centre, axis=1) - radius)
    membrane = np.clip(1.0 - np.minimum(gap, outer) / 1.5, 0.0, 1.0) * (inside | (outer < 1.5))
    # Nucleus: an ellipsoid around the nearest seed, half the cell size, flattened in z.
    rel = pts - seeds[idx[:, 0]]
    r_n = 0.28 * cell
    ell = np.sqrt((rel[:, 0] / r_n) ** 2 + (rel[:, 1] / r_n) ** 2 + (rel[:, 2] / (0.75 * r_n)) ** 2)
    nucleus = np.clip((1.0 - ell) * r_n, 0.0, 1.0) * inside
    texture = _smooth_noise((nz, n, n), 4, rng).ravel()
    image = 0.85 * membrane + nucleus * (0.35 + 0.35 * texture)
    image = image.reshape(nz, n, n)
    image = gaussian_filter1d(image, sigma=1.0 / spacing[2], axis=0, mode="nearest")
    image = image * 255.0 + rng.normal(0.0, 4.0, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8), spacing


def phantom_scenes(n: int = 64) -> list[Scene]:
    """The procedural scenes: sphere over slab, hollow sphere (3-voxel shell, cut open so the
    inside is visible), and the confocal-like cell cluster (uint8, z voxel 2× x)."""
    hollow = phantom_hollow_sphere(n, 3, opacity=0.9)
    hollow[:, : n // 3, :] = 0.0  # cut away the front third: light enters, shadow inside shows
    cells, cell_spacing = cell_phantom(n, z_factor=2)
    return [
        _alpha_scene("sphere_over_slab", phantom_sphere_over_slab(n),
                     "sphere (α 0.9) over a slab (α 0.6): hard and soft cast shadows"),
        _alpha_scene("hollow_sphere", hollow,
                     "spherical shell 3 voxels thick (α 0.9), front cut open: self-shadowing"),
        Scene("cells", cells, cell_spacing, [(25.0, 0.0), (255.0, 0.9)],
              "confocal-like cell cluster: membranes, textured nuclei, z voxel 2×, noise"),
    ]


def _resample(data: np.ndarray, spacing: Vec3, max_size: int) -> tuple[np.ndarray, Vec3]:
    """Linear resampling so no axis exceeds ``max_size`` voxels; spacing scales to match.

    Isotropic stacks are scaled uniformly (they stay isotropic); anisotropic ones only lose
    voxels along the axes that are too long, so a thin z stack keeps its slices.
    """
    from scipy.ndimage import zoom

    shape = np.array(data.shape, dtype=np.float64)
    if len(set(spacing)) == 1:
        new = np.round(shape * min(1.0, max_size / shape.max()))
    else:
        new = np.minimum(shape, max_size)
    if np.all(new == shape):
        return data, spacing
    factors = new / shape
    out = zoom(data.astype(np.float32), factors, order=1)
    z_f, y_f, x_f = (float(f) for f in np.array(out.shape) / shape)
    sx, sy, sz = spacing
    return out, (sx / x_f, sy / y_f, sz / z_f)


def file_scenes(paths: Sequence[str | Path], max_size: int = 64) -> list[Scene]:
    """The user's volumes (any file vtkvol reads, first channel) resampled to at most
    ``max_size`` voxels per axis, each with a transfer function derived from its values:

    * label images (integer values, mostly 0, more than two distinct labels) become a mask
      (label > 0) smoothed by σ = 0.7 voxel, so the ray caster has gradients;
    * anything else ramps from the median (background) to half-way to the 99.9th percentile.

    Raises :class:`~vtkvol.io.VolumeReadError` for a file that cannot be read.
    """
    from scipy.ndimage import gaussian_filter

    from vtkvol.io import read_volume

    scenes: list[Scene] = []
    used: set[str] = set()
    for path in paths:
        data = read_volume(path, channels=[0], fit="none", max_texture_size=None)
        raw = np.asarray(data.array[0])
        spacing = tuple(data.voxel_size_um)
        name = "".join(c if c.isalnum() else "_" for c in Path(path).stem.lower())[:40] or "data"
        while name in used:
            name += "_"
        used.add(name)
        label = f"{Path(path).name} ({' × '.join(str(n) for n in raw.shape[::-1])})"
        zeros = float(np.mean(raw == 0))
        if raw.dtype.kind in "iu" and zeros > 0.5 and len(np.unique(raw[::4, ::4, ::4])) > 2:
            mask = gaussian_filter((raw > 0).astype(np.float32), 0.7)
            values, sp = _resample(mask, spacing, max_size)
            tf = [(0.2, 0.0), (0.6, 0.85), (1.0, 0.85)]
        else:
            values, sp = _resample(raw.astype(np.float32), spacing, max_size)
            lo = float(np.percentile(values, 50.0))
            hi = float(max(lo + 1e-6, np.percentile(values, 99.9)))
            tf = [(lo, 0.0), (lo + 0.5 * (hi - lo), 0.8), (hi, 0.8)]
        scenes.append(Scene(name, values.astype(np.float32), sp, tf, label, "real"))
    return scenes


def bench_scenes(n: int, *, quick: bool, data: Sequence[str | Path] = ()) -> list[Scene]:
    """The scenes of a benchmark run: every phantom at ``n`` voxels and the user's files
    (``vtkvol bench --data FILE``); quick runs keep the first file only, to stay within
    their budget."""
    files = list(data)[:1] if quick else list(data)
    return phantom_scenes(n) + file_scenes(files, n)


# ------------------------------------------------------------------------------------------
# Stability sweeps
# ------------------------------------------------------------------------------------------
@dataclass
class StabilityCase:
    """One point of a stability sweep.

    ``sweep`` names the swept variable, ``value`` is its numeric value (for the chart's x axis),
    ``value_label`` how it is printed, ``unit`` its unit. ``parameter_sweep`` (name, choice)
    asks the runner to set that technique parameter instead of changing the scene (the
    illumination-volume resolution sweep); techniques without that parameter skip the case.
    """

    sweep: str
    value: float
    value_label: str
    unit: str
    scene: Scene
    parameter_sweep: tuple[str, str] | None = None


def _direction(theta_deg: float) -> Vec3:
    """Towards the light at ``theta_deg`` from +z, tilted towards the (+x, +y) diagonal."""
    t = math.radians(theta_deg)
    s = math.sin(t) / math.sqrt(2.0)
    return (s, s, math.cos(t))


def thin_occluder(n: int, thickness: int, *, opacity: float = 0.8) -> np.ndarray:
    """A plate ``thickness`` voxel layers thick (exactly voxelised, like seed 000's 1-voxel slab
    test) over a receiving floor: plate at z ≈ 0.6·n over x < 0.6·n, floor (α 0.6) at
    z ∈ [0.1, 0.2)·n. α is ``opacity`` inside the plate."""
    out = np.zeros((n, n, n), np.float32)
    out[int(0.1 * n): int(0.2 * n)] = 0.6
    z0 = int(0.6 * n)
    out[z0: z0 + int(thickness), :, : int(0.6 * n)] = opacity
    return out


def sphere_over_slab_aniso(n: int, z_factor: float) -> tuple[np.ndarray, Vec3]:
    """:func:`~vtkvol.reference.phantom_sphere_over_slab`'s geometry (same µm) sampled with
    voxels ``z_factor`` times longer in z: (n, n, ≈n/z_factor) voxels of (1, 1, z_factor) µm."""
    m = n - 1
    nz = max(4, round(m / z_factor) + 1)
    sz = m / (nz - 1)
    z = (np.arange(nz) * sz)[:, None, None]
    y = np.arange(n, dtype=np.float64)[None, :, None]
    x = np.arange(n, dtype=np.float64)[None, None, :]
    slab = np.abs(z - 0.15 * m) - 0.05 * m + 0.0 * (x + y)
    sphere = np.sqrt((x - m / 2) ** 2 + (y - m / 2) ** 2 + (z - 0.6 * m) ** 2) - 0.15 * n
    # Anti-alias over one voxel of the axis the distance runs along (z voxels are longer).
    out = np.maximum(0.6 * np.clip(0.5 - slab / sz, 0, 1), 0.9 * np.clip(0.5 - sphere, 0, 1))
    return out.astype(np.float32), (1.0, 1.0, float(sz))


def lit_slab(n: int = 48, thickness: int = 5) -> np.ndarray:
    """An opaque slab filling the x–y extent: ``thickness`` voxel layers of α = 1 in the middle
    of an ``(n, n, ≈ 5/6 n)`` volume ``[z, y, x]`` (48 → 48 × 48 × 40 voxels), empty elsewhere.

    Seen from above, every pixel over the slab shows the same horizontal surface under the
    same (directional) light, so the correct image is flat: any trend across the image is an
    error of the rendering, not of the scene. With a perspective camera each ray meets the
    surface at its own angle and at its own phase of the ray's sample lattice (the rays start
    on the bounding box, one sample distance apart along the ray), which a parallel camera does
    not vary; issue 26 found the shadow volume's surface darkening towards the image edges
    here (docs/shadow-volume.md, "Sample phase at opaque surfaces")."""
    nz = max(thickness + 4, round(n * 5 / 6))
    out = np.zeros((nz, n, n), np.float32)
    z0 = (nz - thickness) // 2
    out[z0: z0 + thickness] = 1.0
    return out


#: Camera elevation (°) of the slab views: straight down onto the slab (90° itself leaves the
#: orbit's view-up parallel to the view direction).
SLAB_VIEW_ELEVATION = 89.0


#: View angle (°) of the perspective slab views (VTK's default is 30°).
SLAB_VIEW_ANGLE = 60.0


def slab_view_scene(n: int, theta_deg: float, *, parallel: bool,
                    azimuth: float = 0.0) -> Scene:
    """:func:`lit_slab` seen from above (``azimuth`` turns the view about the vertical), lit by
    a directional light ``theta_deg`` from +z towards the (+x, +y) diagonal."""
    proj = "parallel" if parallel else "perspective"
    scene = _alpha_scene(
        f"slab_{proj}_{theta_deg:g}" + (f"_az{azimuth:g}" if azimuth else ""), lit_slab(n),
        f"opaque 5-voxel slab from above, {proj} camera", lights=[_direction(theta_deg)],
        kind="stability")
    scene.azimuth, scene.elevation = azimuth, SLAB_VIEW_ELEVATION
    scene.parallel = parallel
    # A wide lens: rays at the image's edges meet the slab up to about 25° off the view axis.
    scene.view_angle = SLAB_VIEW_ANGLE
    # The slab fills the middle of the framed box; its inner 40 % is away from its borders
    # (where oblique light enters through the side faces) in either projection.
    scene.flat_region = 0.4
    return scene


def sixteen_bit_cells(n: int, outlier_fraction: float, seed: int = 3) -> Scene:
    """The cell phantom as 12-bit values in uint16 (offset 100, up to ≈4000) with a fraction of
    voxels set to 65535 (hot pixels / saturated outliers); the transfer function covers the
    12-bit range, so outliers saturate it instead of rescaling it."""
    cells, spacing = cell_phantom(n, z_factor=2)
    data = cells.astype(np.float64) * 15.0 + 100.0
    rng = np.random.default_rng(seed)
    count = round(outlier_fraction * data.size)
    if count:
        flat = data.reshape(-1)
        flat[rng.choice(flat.size, count, replace=False)] = 65535.0
    return Scene(f"cells16_{outlier_fraction:g}", data.astype(np.uint16), spacing,
                 [(100.0 + 25 * 15.0, 0.0), (100.0 + 255 * 15.0, 0.9)],
                 f"12-bit cells in uint16, {outlier_fraction:.2%} voxels at 65535", "stability")


def stability_cases(n: int = 48, *, quick: bool = True) -> list[StabilityCase]:
    """Every sweep of the stability suite at ``n`` voxels (see ``docs/stability.md``).

    light_angle (° from +z: axis-aligned → 45° diagonal → grazing), thickness (1, 2, 4 voxel
    plate), opacity_scale (extinction × s: α' = 1 − (1 − α)^s, transparent → opaque),
    anisotropy (z voxel 1× → 10× the x voxel), resolution (a technique parameter, on the
    1-voxel plate), noise (Gaussian σ added to α) and outliers (16-bit data, hot voxels).
    ``quick`` drops the intermediate values of the longer sweeps.
    """
    cases: list[StabilityCase] = []
    base = phantom_sphere_over_slab(n)

    def scene(name: str, alpha: np.ndarray, desc: str, *, spacing: Vec3 = (1.0, 1.0, 1.0),
              lights: list[Vec3] | None = None) -> Scene:
        return _alpha_scene(name, alpha, desc, spacing=spacing, lights=lights, kind="stability")

    angles = (0.0, 45.0, 70.0, 85.0) if quick else (0.0, 22.5, 45.0, 60.0, 70.0, 80.0, 85.0)
    for theta in angles:
        cases.append(StabilityCase(
            "light_angle", theta, f"{theta:g}°", "°",
            scene(f"light_{theta:g}", base, "sphere over slab", lights=[_direction(theta)])))
    for t in (1, 2, 4):
        cases.append(StabilityCase(
            "thickness", t, f"{t} voxel", "voxel",
            scene(f"plate_{t}", thin_occluder(n, t), f"{t}-voxel plate over a floor",
                  lights=[_direction(20.0)])))
    scales = (0.1, 1.0, 10.0, 100.0) if quick else (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0)
    for s in scales:
        alpha = 1.0 - np.power(1.0 - np.clip(base, 0, 1 - 1e-6), s)
        cases.append(StabilityCase(
            "opacity_scale", s, f"×{s:g}", "× extinction",
            scene(f"opacity_{s:g}", alpha.astype(np.float32), "sphere over slab, scaled σ")))
    factors = (1.0, 3.0, 10.0) if quick else (1.0, 2.0, 3.0, 5.0, 10.0)
    for f in factors:
        alpha, spacing = sphere_over_slab_aniso(n, f)
        cases.append(StabilityCase(
            "anisotropy", f, f"z {f:g}×", "× (z/x voxel)",
            scene(f"aniso_{f:g}", alpha, "sphere over slab, long z voxels", spacing=spacing)))
    plate = thin_occluder(n, 1)
    for i, res in enumerate(("full", "half", "quarter")):
        cases.append(StabilityCase(
            "resolution", float(2 ** i), res, "÷ grid",
            scene(f"plate_1_{res}", plate, "1-voxel plate over a floor",
                  lights=[_direction(20.0)]), parameter_sweep=("resolution", res)))
    rng = np.random.default_rng(7)
    noises = (0.0, 0.1, 0.3) if quick else (0.0, 0.05, 0.1, 0.2, 0.3)
    for sigma in noises:
        noisy = np.clip(base + rng.normal(0.0, sigma, base.shape), 0.0, 1.0) if sigma else base
        cases.append(StabilityCase(
            "noise", sigma, f"σ {sigma:g}", "α σ",
            scene(f"noise_{sigma:g}", noisy.astype(np.float32), "sphere over slab + noise")))
    for frac in ((0.0, 1e-3) if quick else (0.0, 1e-4, 1e-3, 1e-2)):
        s16 = sixteen_bit_cells(n, frac)
        cases.append(StabilityCase("outliers", frac * 100, f"{frac:.2%}", "% voxels", s16))
    # value: the case's index (0, 1: light from above; 2, 3: at 45°; parallel camera first).
    for theta in (0.0, 45.0):
        for parallel in (True, False):
            proj = "parallel" if parallel else "perspective"
            cases.append(StabilityCase(
                "slab_view", float(len([c for c in cases if c.sweep == "slab_view"])),
                f"{proj} {theta:g}°", "case", slab_view_scene(n, theta, parallel=parallel)))
    return cases

