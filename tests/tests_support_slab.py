"""The lit-slab scene of issue 26 for the GL tests: an opaque 5-voxel slab filling the x–y
extent of a 48 × 48 × 40 volume, seen from above (:func:`vtkvol.bench.scenes.lit_slab`, the
bench's ``slab_view`` stability sweep), rendered by several techniques in one window, and the
flatness measure the tests apply to it.

Every pixel over the slab shows the same horizontal surface, so with a directional light the
correct image is flat, and with a point light it is local shading's image times a flat shadow
factor: the tests measure the shadowed image divided by local shading's, which is flat in both
cases whatever the camera."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vtkvol.bench.measure import set_view
from vtkvol.bench.scenes import slab_view_scene
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model import Light

N = 48  #: voxels along x and y (40 along z)
SIZE = (96, 96)  #: image pixels
#: Side of the centred square measured (fraction of the image): inside the slab's top face
#: in every view below, away from its borders, where oblique light enters through the sides.
REGION = 0.4


def render_slab(methods: Sequence[str], light: Light, *, parallel: bool,
                view_angle: float = 60.0, azimuth: float = 0.0,
                sample_distance: float = 1.0) -> dict[str, np.ndarray]:
    """Images ``(h, w, 3)`` uint8 of the slab by each of ``methods`` (defaults), in one window:
    camera above (orbit ``azimuth``° about the vertical), parallel or perspective with
    ``view_angle``°, ray step ``sample_distance`` voxels (1: PyVista's default, 0.5: vtkvol's),
    no specular term (its highlight is not flat under a perspective camera)."""
    scene = slab_view_scene(N, 0.0, parallel=parallel, azimuth=azimuth)
    scene.view_angle = view_angle
    rw, ren, volume = simple_volume_scene(scene.data, size=SIZE,
                                          opacity=list(scene.opacity_points),
                                          sample_distance=sample_distance)
    volume.GetProperty().SetSpecular(0.0)
    set_view(ren, scene)
    il = Illuminator(volume, ren, method="local", lights=[light])
    images = {}
    try:
        for method in methods:
            il.set_method(method)
            grab(rw)  # build frame (shader, light volume)
            images[method] = grab(rw)
    finally:
        il.release()
        rw.Finalize()
    return images


def centre(image: np.ndarray, region: float = REGION) -> np.ndarray:
    """Mean of R, G, B over the centred square of side ``region`` (fraction of the image)."""
    h, w = image.shape[:2]
    half = max(1, round(region * min(h, w) / 2))
    cy, cx = h // 2, w // 2
    return image[cy - half: cy + half, cx - half: cx + half, :3].astype(np.float64).mean(axis=2)


def shadow_factor_spread(image: np.ndarray, local: np.ndarray) -> float:
    """Spread of ``image / local`` over the centred square: (95th − 5th percentile) / median;
    0 when the shadowing is the same over the whole slab."""
    ratio = centre(image) / np.maximum(centre(local), 1.0)
    lo, mid, hi = np.percentile(ratio, [5, 50, 95])
    return float((hi - lo) / mid)
