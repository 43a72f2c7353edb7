"""Per-channel gamma: the curve (mid-tones change, the contrast limits do not), its range, and
that it reaches the renderer (VTK's functions, the image) and ``vtkvol render`` of a session."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from vtkvol.io import VolumeData
from vtkvol.model.defaults import scene_for
from vtkvol.model.gamma import with_gamma
from vtkvol.model.scene import Channel
from vtkvol.model.transfer_function import TransferFunction


def ramp() -> TransferFunction:
    """Black and transparent at 100, white and opaque at 200 (data units)."""
    return TransferFunction(colors=[(100.0, 0.0, 0.0, 0.0), (200.0, 1.0, 1.0, 1.0)],
                            opacity=[(100.0, 0.0), (200.0, 1.0)],
                            window=(0.0, 300.0), window_range=(0.0, 300.0))


def test_gamma_changes_the_mid_tones_but_not_the_limits():
    tf = ramp()
    values = np.array([50.0, 100.0, 150.0, 175.0, 200.0, 250.0])
    for gamma, mid in ((0.5, 0.5 ** 0.5), (2.0, 0.25), (1.0, 0.5)):
        shown = with_gamma(tf, gamma)
        alpha = shown.opacity_at(values)
        grey = shown.color_at(values)[:, 0]
        # Below, at and above the limits: as without gamma (0 and 1).
        assert alpha[[0, 1, 4, 5]] == pytest.approx([0, 0, 1, 1], abs=1e-6)
        assert grey[[0, 1, 4, 5]] == pytest.approx([0, 0, 1, 1], abs=1e-6)
        # The middle of the span: t ** gamma.
        assert alpha[2] == pytest.approx(mid, abs=2e-3)
        assert grey[2] == pytest.approx(mid, abs=2e-3)
        assert alpha[3] == pytest.approx(0.75 ** gamma, abs=2e-3)
    assert with_gamma(tf, 1.0) is tf
    assert tf.opacity == [(100.0, 0.0), (200.0, 1.0)]  # the stored function is untouched


def test_gamma_keeps_a_step_where_it_was_drawn_mapped():
    """A TF's own control points land where the curve maps them: a hard step stays hard."""
    tf = TransferFunction(colors=[(0.0, 1.0, 1.0, 1.0), (100.0, 1.0, 1.0, 1.0)],
                          opacity=[(0.0, 0.0), (25.0, 0.0), (25.001, 1.0), (100.0, 1.0)],
                          window=(0.0, 100.0), window_range=(0.0, 100.0))
    shown = with_gamma(tf, 2.0)
    # t = 0.25 maps to 0.25 ** 0.5 = 0.5: the step is now at 50.
    assert shown.opacity_at(np.array([49.9, 50.1])) == pytest.approx([0.0, 1.0], abs=1e-3)


@pytest.mark.parametrize("gamma", [0.0, 0.05, 10.5, float("nan")])
def test_gamma_outside_its_range_is_refused(gamma):
    with pytest.raises(ValidationError, match="gamma"):
        Channel(gamma=gamma)
    with pytest.raises(ValueError, match=r"gamma must lie in 0\.1…10"):
        with_gamma(ramp(), gamma)


def _volume() -> VolumeData:
    """A linear ramp of values 0…255 along x (uint8), 16 × 32 × 32."""
    x = np.linspace(0, 255, 32).round().astype(np.uint8)
    return VolumeData.from_array(np.broadcast_to(x, (1, 16, 32, 32)).copy(), (1.0, 1.0, 1.0),
                                 ["ramp"])


@pytest.mark.gl
def test_gamma_reaches_the_renderer_and_brightens_the_image():
    import vtk

    from vtkvol.engine.api import render_image
    from vtkvol.engine.scene import VolumeScene

    data = _volume()
    model = scene_for(data)
    model.channels[0].tf = ramp()
    renderer = vtk.vtkRenderer()
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.AddRenderer(renderer)
    scene = VolumeScene(renderer, model, data, request_render=lambda: None)
    otf = scene.property.GetScalarOpacity(0)
    assert otf.GetValue(150.0) == pytest.approx(0.5, abs=1e-3)
    model.channels[0].gamma = 0.5
    assert otf.GetValue(150.0) == pytest.approx(0.5 ** 0.5, abs=2e-3)
    assert otf.GetValue(100.0) == pytest.approx(0.0, abs=1e-6)
    assert otf.GetValue(200.0) == pytest.approx(1.0, abs=1e-6)

    means = {}
    for gamma in (0.5, 1.0, 2.0):
        model = scene_for(data)
        model.channels[0].tf = ramp()
        model.channels[0].gamma = gamma
        model.render.shade = False
        image = render_image(data, model=model, size=(64, 64), method="local")
        means[gamma] = float(image.mean())
    # Measured 2026-11-28 (llvmpipe): 80.2, 74.6, 69.4 (whole image, background included):
    # the brighter mid-tones show.
    assert means[0.5] > means[1.0] * 1.04 and means[1.0] > means[2.0] * 1.04, means


@pytest.mark.gl
def test_vtkvol_render_applies_a_sessions_gamma(tmp_path):
    import imageio.v3 as iio

    from vtkvol.cli import main
    from vtkvol.model.session import save_session

    data = _volume()
    np.save(tmp_path / "ramp.npy", data.array[0])
    images = {}
    for gamma in (1.0, 0.4):
        model = scene_for(data)
        model.volume.path = str(tmp_path / "ramp.npy")
        model.channels[0].tf = ramp()
        model.channels[0].gamma = gamma
        session = save_session(tmp_path / f"g{gamma}.vtkvol.json", model)
        out = tmp_path / f"g{gamma}.png"
        assert main(["render", str(session), "-o", str(out), "--size", "64", "64"]) == 0
        images[gamma] = iio.imread(out)[..., :3].astype(float)
    # Measured: 59.5 against 54.8 (the whole image, background included).
    assert images[0.4].mean() > images[1.0].mean() * 1.05
