"""Issue 23: the refined object-space reference, which removes the reference's discretisation
bias against the camera path tracer (docs/benchmarks.md, "The two truths: noise or bias?" and
"The two truths with a refined reference").

The bench's reference stores each light's transmittance at the data's voxel centres and the
ray caster interpolates it trilinearly (too high near a cut box face: the exact transmittance
is convex between centres), is ray cast at 0.5 unit distances and sampled at pixel centres;
the path tracer integrates the continuous medium over each pixel. The refined reference
(:class:`Refinement`, :class:`RefinedReferences`) changes the three:

* the light's transmittance is computed on a grid refined ``factor``× per axis
  (:func:`refined_scene`: the same medium, see there);
* the ray caster's step is ``step`` unit distances (0.125 instead of 0.5);
* the image is rendered ``supersample``× larger and box-filtered (:func:`box_filter`), the
  pixel average a jittered camera pixel estimates.

The in-scattered light (multiple scattering) is resampled from the coarse reference's
Monte-Carlo volume onto the fine grid trilinearly (:func:`upsample`: exactly the field the
coarse reference's ray caster reads) except within ``face_voxels`` coarse voxels of a box face,
where it is recomputed at the fine grid's points with the same estimator, paths and seeds:
there the in-scattered light falls towards the face (light leaves through it) and its
interpolant between voxel centres is too low (sphere over slab, 24³: −0.066 within half a
voxel of a face, −0.040 from ½ to 1 voxel, ≈ 0 deeper in; docs/benchmarks.md). The noise per
point is the bench's, so the refined ``ms`` image keeps the bench reference's noise floor.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from vtkvol.bench.reference_technique import ReferenceVolumes
from vtkvol.bench.references import MediumReference, ReferenceCache
from vtkvol.bench.scenes import Scene

#: The refined reference's ray-caster step, in unit distances (the bench's default is 0.5).
REFINED_STEP = 0.125
#: The refined reference's supersampling factor per image axis.
REFINED_SUPERSAMPLE = 4
#: The refined reference's grid factor per axis.
REFINED_FACTOR = 2


@dataclass(frozen=True)
class Refinement:
    """How the refined reference differs from the bench's: light grid ``factor``× per axis,
    ray-cast ``step`` in unit distances, image ``supersample``× per axis then box-filtered,
    in-scattered light recomputed on the fine grid within ``face_voxels`` coarse voxels of a
    box face (0: upsampled everywhere)."""

    factor: int = REFINED_FACTOR
    step: float = REFINED_STEP
    supersample: int = REFINED_SUPERSAMPLE
    face_voxels: float = 1.0

    def __post_init__(self) -> None:
        if (self.factor < 1 or self.supersample < 1 or not self.step > 0
                or not self.face_voxels >= 0):
            raise ValueError(f"a refinement needs factor ≥ 1, supersample ≥ 1, step > 0 and "
                             f"face_voxels ≥ 0; got {self.factor}, {self.supersample}, "
                             f"{self.step}, {self.face_voxels}")

    @property
    def label(self) -> str:
        """Short text for tables: ``grid 2×, step 0.125, 4× pixel box, S at faces 1``."""
        faces = f", S at faces {self.face_voxels:g}" if self.face_voxels > 0 else ""
        return (f"grid {self.factor}×, step {self.step:g}, "
                f"{self.supersample}× pixel box{faces}")


def upsample(volume: np.ndarray, factor: int) -> np.ndarray:
    """A ``[z, y, x]`` (or ``[z, y, x, c]``) voxel-centre volume resampled trilinearly onto the
    grid refined ``factor``× per axis: f·(n − 1) + 1 points over the same box, the old points
    kept. Exact for the trilinear interpolant (restricted to a sub-cell it is trilinear), so
    the refined grid's trilinear field is the coarse one's."""
    v = np.asarray(volume, np.float64)
    if factor == 1:
        return v.astype(np.float32)
    out = v
    for axis in range(3):
        n = out.shape[axis]
        pos = np.arange(factor * (n - 1) + 1) / factor
        i0 = np.minimum(np.floor(pos).astype(np.int64), max(n - 2, 0))
        i1 = np.minimum(i0 + 1, n - 1)
        f = pos - i0
        shape = [1] * out.ndim
        shape[axis] = len(pos)
        f = f.reshape(shape)
        out = (np.take(out, i0, axis=axis) * (1.0 - f) + np.take(out, i1, axis=axis) * f)
    return out.astype(np.float32)


def refined_scene(scene: Scene, factor: int = REFINED_FACTOR) -> Scene:
    """The same medium on a grid refined ``factor``× per axis: f·(n − 1) + 1 points over the
    same box (world coordinates unchanged, spacing divided by f), the **data** resampled
    trilinearly (:func:`upsample`) and the transfer function and the original unit distance
    kept, so the opacity per world length is unchanged.

    Why the data and not the classified α: VTK's ray caster and the camera path tracer (one
    channel, 1-D TF: :meth:`BesideRenderer.post_classification_reason` is None on the bench
    scenes) both interpolate the scalar trilinearly and then look the TF up, so the medium is
    α(TF(trilinear data)); the trilinear data interpolant is unchanged by the refinement, so
    both renderers see exactly the same medium on the fine grid. For the identity TF (the
    α phantoms) this is α resampled. Only the reference's light grid, which classifies at
    grid points (:meth:`Scene.opacity`), changes: its points are f× denser, which is the
    refinement. Float32 data (a uint8 stack's values interpolated)."""
    if factor < 1:
        raise ValueError(f"the refinement factor must be ≥ 1, not {factor}")
    unit = scene.unit_distance

    class Fine(Scene):
        @property
        def unit_distance(self) -> float:
            return unit

    fields = {f.name: getattr(scene, f.name) for f in dataclasses.fields(scene)}
    fields.update(data=upsample(scene.data, factor),
                  spacing=tuple(s / factor for s in scene.spacing))
    return Fine(**fields)


def box_filter(image: np.ndarray, factor: int) -> np.ndarray:
    """An (n·factor, m·factor, c) image averaged over factor × factor blocks to (n, m, c): the
    pixel average a jittered camera pixel estimates, from a supersampled render."""
    h, w, c = image.shape
    if h % factor or w % factor:
        raise ValueError(f"image {h}x{w} is not a multiple of the factor {factor}")
    return image.reshape(h // factor, factor, w // factor, factor, c).mean(axis=(1, 3))


class RefinedReferences:
    """The refined reference volumes of one (lit) scene: each light's transmittance on the
    refined grid (computed once, shared by every :class:`MediumReference`), the in-scattered
    light of the bench's reference upsampled. ``seconds``: CPU time spent here (the fine
    transmittance and the upsampling; the coarse in-scattered light is charged to
    ``cache.seconds`` as in the bench)."""

    def __init__(self, cache: ReferenceCache, scene: Scene,
                 refinement: Refinement = Refinement()) -> None:
        self.cache = cache
        self.scene = scene
        self.refinement = refinement
        self.fine = refined_scene(scene, refinement.factor)
        self.seconds = 0.0
        self._visibility: tuple[np.ndarray, ...] | None = None
        self._scattered: dict[tuple, np.ndarray] = {}

    def visibility(self) -> tuple[np.ndarray, ...]:
        """Every light's transmittance over the light's size on the fine grid, in [0, 1]."""
        if self._visibility is None:
            t0 = time.perf_counter()
            before = self.cache.seconds
            alpha = self.fine.opacity()
            self._visibility = tuple(
                np.clip(self.cache.light_visibility(self.fine, light, self.fine.light_size_deg,
                                                    alpha), 0, 1)
                for light in self.fine.lights)
            self.cache.seconds = before  # charged here, not to the bench's reference
            self.seconds += time.perf_counter() - t0
        return self._visibility

    def face_mask(self) -> np.ndarray:
        """Fine-grid points within ``face_voxels`` coarse voxels of a box face, ``[z, y, x]``."""
        f = self.refinement.factor
        reach = self.refinement.face_voxels * f
        axes = []
        for n in self.fine.shape:
            i = np.arange(n)
            axes.append(np.minimum(i, n - 1 - i) <= reach + 1e-9)
        z, y, x = np.meshgrid(*axes, indexing="ij")
        return z | y | x

    def scattered(self, albedo: float, phase_g: float, seed: int) -> np.ndarray:
        """The in-scattered light of one seed on the fine grid (see the module docstring)."""
        from vtkvol.bench.references import relevant_mask
        from vtkvol.reference import DirectionalLight, inscattered_mc

        key = (float(albedo), float(phase_g), int(seed))
        if key not in self._scattered:
            coarse = self.cache.scattered(self.scene, albedo, phase_g, seed)
            t0 = time.perf_counter()
            out = upsample(coarse, self.refinement.factor)
            if self.refinement.face_voxels > 0:
                alpha = self.fine.opacity()
                mask = relevant_mask(alpha) & self.face_mask()
                if mask.any():
                    budget = self.cache.budget
                    pts = np.argwhere(mask)[:, ::-1] * np.asarray(self.fine.spacing)
                    lights = [DirectionalLight(tuple(float(c) for c in d))  # type: ignore[arg-type]
                              for d in self.fine.lights]
                    out[mask] = inscattered_mc(
                        alpha, self.fine.spacing, lights, albedo=albedo, phase_g=phase_g,
                        n_paths=budget.scatter_paths, seed=seed,
                        unit_distance=self.fine.unit_distance,
                        max_bounces=budget.scatter_bounces, points=pts)
            self._scattered[key] = np.maximum(out, 0.0)
            self.seconds += time.perf_counter() - t0
        return self._scattered[key]

    def volumes(self, reference: MediumReference) -> ReferenceVolumes:
        """The refined :class:`ReferenceVolumes` of ``reference`` (on the fine grid)."""
        spec = reference.spec(self.scene, self.cache.budget)
        vis = self.visibility()
        irradiance = None
        if spec.orders == "multiple":
            # unit-irradiance lights, scaled here as the bench's reference does
            irradiance = (self.scene.light_intensity * np.mean(
                [self.scattered(spec.albedo, spec.phase_g, seed) for seed in spec.seeds],
                axis=0)).astype(np.float32)
        return ReferenceVolumes(vis, None, irradiance)

    def release(self) -> None:
        """Forget the fine scene's cached volumes (memory bounded across scenes)."""
        self.cache.clear_scene(self.fine)
        self._visibility = None
        self._scattered.clear()


def render_refined(refs: RefinedReferences, image_size: int,
                   references: dict[str, MediumReference],
                   errors: Callable[[], Any] | None = None) -> dict[str, np.ndarray]:
    """Render each of ``references`` (name → reference) refined: a :class:`Rig` of
    ``image_size × supersample`` pixels showing the fine scene at the refined step, the
    reference technique shading each refined volume set, box-filtered back to
    ``image_size``² and rounded to uint8 (as the camera mean is). ``errors()`` (optional):
    VTK errors since the last call, raised as RuntimeError when non-empty."""
    from vtkvol.bench.measure import Rig
    from vtkvol.bench.reference_technique import MEDIUM_NAME, ReferenceVolume

    r = refs.refinement
    rig = Rig(image_size * r.supersample)
    out: dict[str, np.ndarray] = {}
    try:
        rig.rw.Render()
        rig.load(refs.fine)
        rig.volume.GetMapper().SetSampleDistance(r.step * refs.fine.unit_distance)
        for name, reference in references.items():
            ReferenceVolume.use(refs.volumes(reference))
            rig.set_method(MEDIUM_NAME, {})
            image = rig.image().astype(np.float64)
            problem = errors() if errors is not None else None
            if problem:
                raise RuntimeError(f"the refined reference shader failed: {problem}")
            out[name] = np.clip(np.rint(box_filter(image, r.supersample)), 0,
                                255).astype(np.uint8)
    finally:
        rig.close()
    return out
