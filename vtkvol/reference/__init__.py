"""Independent CPU references (numpy only: no VTK, no Qt) for measuring the GPU illumination.

Every GPU technique (precomputed shadow volumes, cone-traced AO and soft shadows, multiple
scattering) is measured against these. They are deliberately simple and brute-force: dense ray
marching and Monte Carlo through the medium the renderers draw, vectorised with numpy.

Conventions (``docs/architecture.md``):

* volumes are numpy arrays ``[z, y, x]``; ``spacing`` and all vectors are (x, y, z), in µm;
* world space: voxel (i, j, k) at (i·sx, j·sy, k·sz); the volume is the box spanned by the voxel
  centres, with zero extinction outside;
* the input is the transfer-function opacity α of a slab ``unit_distance`` µm thick (default the
  smallest voxel edge); α is interpolated trilinearly (as VTK's ray caster and the camera path
  tracer sample it) and σ(x) = −ln(1 − α(x))/unit_distance per µm;
* a :class:`DirectionalLight` ``direction`` points from the scene towards the light; a
  :class:`PointLight` ``position`` is in world µm and may be inside the box;
* per-voxel results are float32 ``[z, y, x]``; with ``points=`` (world (N, 3)) they are (N,).

Modules: :mod:`~vtkvol.reference.raymarch` (extinction field, ray march),
:mod:`~vtkvol.reference.transmittance`, :mod:`~vtkvol.reference.ambient_occlusion`,
:mod:`~vtkvol.reference.scattering`, :mod:`~vtkvol.reference.metrics`,
:mod:`~vtkvol.reference.phantoms`, :mod:`~vtkvol.reference.sampling` (seeded random directions),
:mod:`~vtkvol.reference.reconstruction` (trilinear, corrected trilinear and tricubic filters,
the Marschner–Lobb signal).
"""

from vtkvol.reference.ambient_occlusion import ambient_occlusion_mc
from vtkvol.reference.lights import DirectionalLight, PointLight
from vtkvol.reference.metrics import image_metrics, volume_metrics
from vtkvol.reference.phantoms import (
    phantom_groove,
    phantom_hollow_sphere,
    phantom_slab,
    phantom_sphere_over_slab,
)
from vtkvol.reference.raymarch import ExtinctionField, extinction, voxel_centres
from vtkvol.reference.reconstruction import (
    corrected_trilinear,
    marschner_lobb,
    marschner_lobb_rmse,
    phantom_marschner_lobb,
    reconstruct,
)
from vtkvol.reference.scattering import inscattered_mc
from vtkvol.reference.transmittance import (
    cone_transmittance_mc,
    extended_transmittance,
    transmittance,
)

__all__ = [
    "DirectionalLight",
    "ExtinctionField",
    "PointLight",
    "ambient_occlusion_mc",
    "cone_transmittance_mc",
    "corrected_trilinear",
    "extended_transmittance",
    "extinction",
    "image_metrics",
    "inscattered_mc",
    "marschner_lobb",
    "marschner_lobb_rmse",
    "phantom_groove",
    "phantom_hollow_sphere",
    "phantom_marschner_lobb",
    "phantom_slab",
    "phantom_sphere_over_slab",
    "reconstruct",
    "transmittance",
    "volume_metrics",
    "voxel_centres",
]
