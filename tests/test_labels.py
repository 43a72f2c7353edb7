"""Label images: detection, glasbey step transfer functions, nearest-voxel rendering that shows
only the labels present, and illumination driven by the labels' opacity."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("cmap")

from vtkvol.io import VolumeData, confocal_phantom
from vtkvol.model.defaults import scene_for
from vtkvol.model.labels import (
    apply_labels,
    detect_labels,
    label_colors,
    label_transfer_function,
)
from vtkvol.model.scene import Light


def _blobs(shape=(32, 64, 64), n=30, seed=1) -> np.ndarray:
    """``n`` balls of radius 3…7 voxels with random ids in 1…399 (later ones overwrite)."""
    rng = np.random.default_rng(seed)
    z, y, x = np.indices(shape)
    labels = np.zeros(shape, np.uint16)
    for k in rng.choice(np.arange(1, 400), n, replace=False):
        c = rng.uniform([4, 8, 8], [shape[0] - 4, shape[1] - 8, shape[2] - 8])
        r = rng.uniform(3, 7)
        labels[((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) < r * r] = k
    return labels


def test_detection_tells_labels_from_intensities():
    blobs = _blobs()
    found = detect_labels(blobs)
    assert found.is_labels, found.reason
    assert found.labels == tuple(int(v) for v in np.unique(blobs) if v)

    phantom = detect_labels(confocal_phantom().array[:1])   # 12-bit, noisy
    assert not phantom.is_labels and "intensities vary" in phantom.reason
    noise = np.random.default_rng(0).poisson(2, (16, 64, 64)).astype(np.uint8)   # dim 8-bit
    assert not detect_labels(noise).is_labels
    mask = detect_labels((blobs > 0).astype(np.uint8))
    assert not mask.is_labels and mask.reason == "only 1 distinct non-zero value(s)"
    assert not detect_labels(blobs.astype(np.float32)).is_labels
    assert "2 channels" in detect_labels(np.stack([blobs, blobs])).reason


def test_step_transfer_function_gives_each_id_its_colour():
    ids = [3, 4, 17, 250]
    tf = label_transfer_function(ids, opacity=0.8, hidden=[17])
    colours = label_colors(ids)
    assert np.allclose(tf.color_at(np.array(ids, float)), colours, atol=1e-6)
    # Neighbouring ids 3 and 4 keep their own colours up to a quarter of a unit away.
    assert np.allclose(tf.color_at(np.array([3.3, 3.7])), colours[:2], atol=1e-6)
    assert np.allclose(tf.opacity_at(np.array([0, 3, 4, 17, 250])), [0, 0.8, 0.8, 0, 0.8])
    # Glasbey: id k is palette entry k - 1 whatever else is present; distinct colours.
    assert np.array_equal(label_colors([4]), colours[1:2])
    assert len({tuple(c) for c in label_colors(range(1, 257))}) == 256
    with pytest.raises(ValueError, match="relabel_sequential"):
        label_transfer_function([1, 60000])
    with pytest.raises(ValueError, match="no label ids"):
        label_transfer_function([0])


def _foreground(image: np.ndarray, background) -> np.ndarray:
    bg = np.round(np.asarray(background) * 255)
    pixels = image.reshape(-1, 3).astype(int)
    return pixels[np.abs(pixels - bg).max(1) > 2]


def test_nearest_rendering_shows_only_the_labels_present():
    """Unshaded, opaque labels: with apply_labels (nearest voxel) every pixel is the colour of
    a label in the volume; the same transfer function sampled trilinearly paints boundaries
    with ids in between (why labels switch the interpolation)."""
    from vtkvol.engine.api import render_image

    blobs = _blobs()
    data = VolumeData.from_array(blobs[None], (1.0, 1.0, 1.0), ["labels"])
    present = detect_labels(blobs).labels
    palette = np.round(label_colors(present) * 255).astype(int)
    off = {}
    for interpolation in ("nearest", "trilinear"):
        model = scene_for(data)
        apply_labels(model, present)
        assert model.render.interpolation == "nearest"
        model.render.interpolation = interpolation
        model.render.shade = False
        image = render_image(data, model=model, size=(96, 96), method="local")
        fg = _foreground(image, model.render.background)
        assert len(fg) > 1500  # the blobs fill a good part of the view
        distance = np.abs(fg[:, None, :] - palette[None]).max(2).min(1)
        off[interpolation] = float((distance > 2).mean())
    assert off["nearest"] == 0.0
    assert off["trilinear"] > 0.3, off


def test_shadows_follow_the_labels_opacity():
    """A plate (id 5) above a larger plate (id 9), light from +z: with shadow_volume the lower
    plate is darker where the upper one shades it; hiding id 5 (per-label visibility) removes
    its shadow too, because techniques read opacity through the label transfer function."""
    from vtkvol.engine.api import render_image

    labels = np.zeros((40, 48, 48), np.uint8)
    labels[28:32, 12:36, 12:36] = 5
    labels[8:12, 2:46, 2:46] = 9
    data = VolumeData.from_array(labels[None], (1.0, 1.0, 1.0), ["labels"])

    def render(method: str, hidden=(), shade=True) -> np.ndarray:
        model = scene_for(data)
        apply_labels(model, [5, 9], hidden=hidden)
        model.lights = [Light(direction=(0.0, 0.0, 1.0))]
        model.render.shade = shade
        return render_image(data, model=model, size=(96, 96), method=method, elevation=60.0,
                            azimuth=20.0).astype(float)

    # The lower plate's top as seen past the upper plate: its exact colour, unshaded.
    flat = render("local", shade=False)
    plate = np.abs(flat - np.round(label_colors([9])[0] * 255)).max(2) <= 2
    assert plate.sum() > 500
    local = render("local").sum(2)[plate]
    shadowed = render("shadow_volume").sum(2)[plate]
    # Measured: 17 % of the plate's pixels lie in the upper plate's shadow (ambient only).
    assert (shadowed < 0.6 * local).mean() > 0.1
    hidden_local = render("local", hidden=[5]).sum(2)[plate]
    hidden_shadowed = render("shadow_volume", hidden=[5]).sum(2)[plate]
    assert np.array_equal(hidden_local, local)  # local shading has no shadows to lose
    # Without id 5 only the plate's own edges shade themselves (measured: 1.5 % of pixels).
    assert (hidden_shadowed < 0.9 * hidden_local).mean() < 0.03
