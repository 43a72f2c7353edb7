"""Engine: the VTK scene built from the model, checked through rendered pixels (GL)."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

from vtkvol.engine.offscreen import grab, make_render_window
from vtkvol.engine.scene import VolumeScene
from vtkvol.io.volume_data import VolumeData
from vtkvol.model import BLEND_MODES, SceneModel, TransferFunction
from vtkvol.model.defaults import scene_for

pytestmark = pytest.mark.gl
SIZE = (128, 128)


def gray_tf(hi: float, alpha: float = 1.0) -> TransferFunction:
    return TransferFunction(
        colors=[(0.0, 0.0, 0.0, 0.0), (hi, 1.0, 1.0, 1.0)],
        opacity=[(0.0, 0.0), (hi, alpha)],
        window=(0.0, hi),
        window_range=(0.0, hi),
    )


class Viewer:
    """One offscreen window + VolumeScene; camera looks along +y (x right, z up), parallel."""

    def __init__(self, data: VolumeData, model: SceneModel | None = None) -> None:
        self.model = model or scene_for(data)
        self.model.camera.parallel_projection = True
        self.rw = make_render_window(SIZE)
        self.renderer = vtk.vtkRenderer()
        self.rw.AddRenderer(self.renderer)
        self.scene = VolumeScene(self.renderer, self.model, data, request_render=lambda: None)
        self.scene.reset_camera(azimuth=0.0, elevation=0.0)

    def image(self) -> np.ndarray:
        return grab(self.rw).astype(np.float64)

    def close(self) -> None:
        self.scene.close()
        self.rw.Finalize()


@pytest.fixture
def viewer_factory():
    made: list[Viewer] = []

    def make(data: VolumeData, model: SceneModel | None = None) -> Viewer:
        v = Viewer(data, model)
        made.append(v)
        return v

    yield make
    for v in made:
        v.close()


def blob(shape=(32, 32, 32), center=(16, 16, 16), radius=5.0, value=200) -> np.ndarray:
    z, y, x = np.indices(shape)
    cz, cy, cx = center
    inside = (x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2 <= radius**2
    return np.where(inside, value, 0).astype(np.uint8)


BACKGROUND = np.array([0.08, 0.08, 0.1]) * 255


def foreground(image: np.ndarray) -> np.ndarray:
    """Per-pixel brightness above the background colour."""
    return np.clip(image - BACKGROUND, 0, None).sum(axis=2)


def centroid(image: np.ndarray) -> tuple[float, float]:
    weight = foreground(image)
    rows, cols = np.indices(weight.shape)
    total = weight.sum()
    return float((rows * weight).sum() / total), float((cols * weight).sum() / total)


def test_bright_blob_renders_where_expected(viewer_factory):
    # Blob at +x and +z of the centre: with x to the right and z up it is right and high.
    data = VolumeData.from_array(blob(center=(22, 16, 24)))
    v = viewer_factory(data)
    v.model.channels[0].tf = gray_tf(200.0)
    img = v.image()
    row, col = centroid(img)
    h, w = SIZE
    assert col > w / 2 + 5, "blob should be right of centre (+x)"
    assert row < h / 2 - 5, "blob should be above centre (+z)"
    assert img.max() > 100


def test_mip_of_known_volume_equals_its_maximum(viewer_factory):
    rng = np.random.default_rng(1)
    arr = rng.integers(0, 120, (24, 24, 24)).astype(np.uint8)
    arr[11:13, 11:13, 11:13] = 250
    data = VolumeData.from_array(arr)
    v = viewer_factory(data)
    v.model.render.blend_mode = "mip"
    v.model.render.jitter = False
    v.model.channels[0].tf = gray_tf(255.0)
    img = v.image()
    # Grey ramp 0→255 maps the maximum (a 2-voxel cube, so interpolation keeps the peak) to the
    # brightest pixel.
    assert img.max() >= 245  # (255 is uint8's own bound)
    assert abs(img[..., 0].mean() - img[..., 1].mean()) < 1e-6  # grey


def silhouette_aspect(img: np.ndarray) -> float:
    mask = foreground(img) > 60
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    return (rows[-1] - rows[0] + 1) / (cols[-1] - cols[0] + 1)


def test_anisotropic_spacing_changes_silhouette_aspect(viewer_factory):
    cube = np.zeros((20, 20, 20), np.uint8)
    cube[4:16, 4:16, 4:16] = 200
    aspects = []
    for z_spacing in (1.0, 3.0):
        v = viewer_factory(VolumeData.from_array(cube, voxel_size_um=(1.0, 1.0, z_spacing)))
        v.model.channels[0].tf = gray_tf(200.0)
        aspects.append(silhouette_aspect(v.image()))
    assert aspects[0] == pytest.approx(1.0, abs=0.15)
    assert aspects[1] == pytest.approx(3.0, rel=0.15)


@pytest.mark.parametrize("mode", BLEND_MODES)
def test_every_blend_mode_renders(viewer_factory, mode):
    arr = blob(radius=8.0)
    if mode == "minip":  # a dark blob in a bright block: its minimum shows
        arr = np.full_like(arr, 200)
        arr[:, :, :6] = 0
        arr[:, :, -6:] = 0
        arr[blob(radius=8.0) > 0] = 60
    data = VolumeData.from_array(arr)
    v = viewer_factory(data)
    v.model.channels[0].tf = gray_tf(200.0, alpha=0.5)
    v.model.render.blend_mode = mode
    img = v.image()
    assert foreground(img).max() > 60, f"{mode} rendered nothing"
    # Nothing in the empty left quarter of the view, whatever the blend mode.
    assert foreground(img[:, : SIZE[1] // 8]).max() < 20


def test_two_channels_are_independent_and_hideable(viewer_factory):
    arr = np.zeros((2, 24, 24, 32), np.uint16)
    arr[0, 8:16, 8:16, 2:10] = 3000  # left block: channel 0
    arr[1, 8:16, 8:16, 22:30] = 3000  # right block: channel 1
    data = VolumeData.from_array(arr)
    v = viewer_factory(data)
    assert len(v.model.channels) == 2
    for ch, color in zip(v.model.channels, [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)], strict=True):
        ch.tf = TransferFunction(
            colors=[(0.0, *color), (3000.0, *color)], opacity=[(0.0, 0.0), (3000.0, 1.0)],
            window=(0.0, 3000.0), window_range=(0.0, 3000.0),
        )
    img = v.image()
    w = SIZE[1]
    left, right = img[:, : w // 2], img[:, w // 2 :]
    assert left[..., 0].max() > 100 and left[..., 2].max() < 30
    assert right[..., 2].max() > 100 and right[..., 0].max() < 30
    v.model.channels[1].visible = False
    img = v.image()
    assert img[:, w // 2 :, 2].max() < 30 and img[:, : w // 2, 0].max() > 100


def test_crop_box_hides_what_lies_outside(viewer_factory):
    cube = np.zeros((20, 20, 40), np.uint8)
    cube[5:15, 5:15, 5:35] = 200
    v = viewer_factory(VolumeData.from_array(cube))
    v.model.channels[0].tf = gray_tf(200.0)
    full = v.image()
    v.model.crop.x = (0.0, 19.0)  # keep the left half (µm == voxels here)
    cropped = v.image()
    w = SIZE[1]
    assert full[:, int(w * 0.65) :].max() > 100
    assert cropped[:, int(w * 0.65) :].max() < 30
    assert cropped[:, : int(w * 0.4)].max() > 100
    # What is cropped away casts no shadow: the illumination input is zero there.
    opacity = v.scene.illuminator.opacity_volume()
    assert opacity[:, :, 25:].max() == 0.0 and opacity[:, :, 5:15].max() > 0.5


def test_slice_weights_fade_an_axis(viewer_factory):
    cube = np.zeros((20, 20, 40), np.uint8)
    cube[5:15, 5:15, 5:35] = 200
    v = viewer_factory(VolumeData.from_array(cube))
    v.model.channels[0].tf = gray_tf(200.0, alpha=0.3)
    v.model.slice_weights.x = [(0.0, 1.0), (0.5, 1.0), (0.5001, 0.0), (1.0, 0.0)]
    img = v.image()
    w = SIZE[1]
    assert img[:, int(w * 0.6) :].max() < 30
    assert img[:, : int(w * 0.4)].max() > 60
    v.image()  # the source is captured on the frame after a build
    assert "vv_sliceWeight" in v.scene.illuminator.fragment_source


def test_light_direction_changes_shading(viewer_factory):
    data = VolumeData.from_array(blob(radius=9.0))
    v = viewer_factory(data)
    v.model.channels[0].tf = gray_tf(200.0)
    v.model.lights[0].direction = (1.0, 0.0, 0.0)
    lit_right = v.image()
    v.model.lights[0].direction = (-1.0, 0.0, 0.0)
    lit_left = v.image()
    w = SIZE[1]

    def right_minus_left(img):
        fg = foreground(img)
        return fg[:, w // 2 :].sum() / max(fg.sum(), 1.0) - 0.5

    assert right_minus_left(lit_right) > 0.1
    assert right_minus_left(lit_left) < -0.1


def test_nan_voxels_render_as_empty(viewer_factory):
    """A row of NaN through the blob's centre is classified as empty space (finite opacity,
    zero there) and draws exactly what the same row of zeros draws."""
    arr = blob(radius=8.0).astype(np.float32)
    zeros = arr.copy()
    zeros[16, 16, :] = 0.0
    arr[16, 16, :] = np.nan
    images, opacities = [], []
    for values in (arr, zeros):
        v = viewer_factory(VolumeData.from_array(values))
        v.model.channels[0].tf = gray_tf(200.0)
        v.model.render.jitter = False
        images.append(v.image())
        opacities.append(v.scene.illuminator.opacity_volume())
    assert np.isfinite(opacities[0]).all()
    assert (opacities[0][16, 16, :] == 0).all() and opacities[0].max() > 0.5
    np.testing.assert_array_equal(opacities[0], opacities[1])
    assert foreground(images[1]).max() > 100
    np.testing.assert_array_equal(images[0], images[1])


def test_unshaded_rendering_compiles_and_shows_the_volume(viewer_factory):
    v = viewer_factory(VolumeData.from_array(blob(radius=8.0)))
    v.model.channels[0].tf = gray_tf(200.0)
    v.model.render.shade = False
    img = v.image()
    assert foreground(img).max() > 100
    assert not v.scene.illuminator.shaded


def test_tf_window_change_does_not_touch_vtk(viewer_factory):
    v = viewer_factory(VolumeData.from_array(blob(radius=8.0)))
    v.image()
    mtime = v.scene.property.GetScalarOpacity(0).GetMTime()
    v.model.channels[0].tf.set_window(10.0, 100.0)
    assert v.scene.property.GetScalarOpacity(0).GetMTime() == mtime
