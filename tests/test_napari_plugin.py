"""The napari plugin: the npe2 manifest, the readers through napari's own viewer.open (with
make_napari_viewer, under Xvfb), the napari→vtkvol mapping, the dock widget's render against
`vtkvol render` of the same session, and the camera's direction. Skipped without napari."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

napari = pytest.importorskip("napari")
npe2 = pytest.importorskip("npe2")
h5py = pytest.importorskip("h5py")

from test_io_imaris import add_level, volumes, write_ims  # noqa: E402
from test_io_vendor import _FakeLifImage, _leica_xml, _patch_lif, _write_czi  # noqa: E402

from vtkvol.io import read_volume  # noqa: E402
from vtkvol.io.registry import available_readers  # noqa: E402
from vtkvol.model.defaults import contrast_limits  # noqa: E402
from vtkvol.napari._mapping import (  # noqa: E402
    BLEND_MODES,
    MappingError,
    layers_to_scene,
    transfer_function,
)
from vtkvol.napari._widget import napari_camera  # noqa: E402

pytestmark = pytest.mark.gui


def _manifest():
    pm = npe2.PluginManager.instance()
    pm.discover()
    return pm.get_manifest("vtkvol")


def test_napari_lists_the_plugin_with_readers_for_every_format():
    manifest = _manifest()
    assert manifest.name == "vtkvol"
    reader = manifest.contributions.readers[0]
    patterns = set(reader.filename_patterns)
    wanted = {p for spec in available_readers() for p in spec.filename_patterns}
    assert wanted <= patterns, wanted - patterns
    assert reader.accepts_directories
    assert [w.display_name for w in manifest.contributions.widgets] == ["Illuminated render"]


def _open(viewer, path) -> list:
    return viewer.open(str(path), plugin="vtkvol")


def test_czi_like_file(make_napari_viewer, tmp_path):
    pytest.importorskip("pylibCZIrw.czi")
    path = _write_czi(tmp_path / "cells.czi", n_t=2, n_z=5)
    viewer = make_napari_viewer()
    layers = _open(viewer, path)
    assert [ly.name for ly in layers] == ["DAPI", "GFP"]
    first = read_volume(path)
    for c, ly in enumerate(layers):
        assert ly.data.shape == (2, 5, 6, 7)  # time first
        assert tuple(ly.scale) == pytest.approx((1.0, 0.5, 0.2, 0.2))  # µm
        assert tuple(ly.contrast_limits) == pytest.approx(contrast_limits(first, c))
        np.testing.assert_array_equal(ly.data[0], first.array[c])


def test_lif_like_file(make_napari_viewer, tmp_path, monkeypatch):
    data = np.arange(2 * 4 * 2 * 6 * 5, dtype=np.uint16).reshape(2, 4, 2, 6, 5)  # T Z C Y X
    stack = _FakeLifImage("Series003", data, "TZCYX",
                          _leica_xml({1: (5, 4 * 0.25e-6), 2: (6, 5 * 0.25e-6),
                                      3: (4, 3 * 1.5e-6)}, ["Green", "Red"]))
    _patch_lif(monkeypatch, [stack])
    path = tmp_path / "exp.lif"
    path.write_bytes(b"")
    viewer = make_napari_viewer()
    layers = _open(viewer, path)
    assert [ly.name for ly in layers] == ["Green", "Red"]
    assert tuple(layers[0].scale) == pytest.approx((1.0, 1.5, 0.25, 0.25))
    np.testing.assert_array_equal(layers[1].data, data[:, :, 1])
    # The file's LUT colours: black → green, black → red.
    np.testing.assert_allclose(layers[0].colormap.colors[-1], [0, 1, 0, 1])
    np.testing.assert_allclose(layers[1].colormap.colors[-1], [1, 0, 0, 1])


def test_imaris_pyramid_is_multiscale(make_napari_viewer, tmp_path):
    channels = volumes((8, 12, 16))
    path = write_ims(tmp_path / "cells.ims", channels, extent_max=(16.0, 12.0, 16.0))
    add_level(path, 1, [c[::2, ::2, ::2] for c in channels])
    viewer = make_napari_viewer()
    layers = _open(viewer, path)
    assert [ly.name for ly in layers] == ["DAPI", "GFP"]
    for c, ly in enumerate(layers):
        assert ly.multiscale and len(ly.data) == 2
        assert ly.data[0].shape == (8, 12, 16) and ly.data[1].shape == (4, 6, 8)
        assert tuple(ly.scale) == pytest.approx((2.0, 1.0, 1.0))
        np.testing.assert_array_equal(np.asarray(ly.data[0]), channels[c])


def test_ome_zarr_pyramid_is_multiscale(make_napari_viewer, tmp_path):
    pytest.importorskip("ome_zarr.writer")
    from tests_support_http import VOXEL, phantom, write_served_stores

    root = write_served_stores(tmp_path)
    viewer = make_napari_viewer()
    layers = _open(viewer, root / "cells.ome.zarr")
    assert [ly.name for ly in layers] == ["DAPI", "GFP"]
    for ly in layers:
        assert ly.multiscale and len(ly.data) == 5
        assert [lv.shape for lv in ly.data] == [(64, 64 >> i, 64 >> i) for i in range(5)]
        assert tuple(ly.scale) == pytest.approx((VOXEL["z"], VOXEL["y"], VOXEL["x"]))
    np.testing.assert_array_equal(np.asarray(layers[1].data[0]), phantom()[1])
    np.testing.assert_allclose(layers[0].colormap.colors[-1], [0, 0, 1, 1])  # omero 0000FF


def test_label_image_becomes_a_labels_layer(make_napari_viewer, tmp_path):
    import tifffile

    labels = np.zeros((6, 8, 8), np.uint16)
    labels[1:4, 2:5, 2:5] = 7
    path = tmp_path / "nuclei_labels.tif"
    tifffile.imwrite(path, labels)
    viewer = make_napari_viewer()
    (layer,) = _open(viewer, path)
    assert isinstance(layer, napari.layers.Labels)
    np.testing.assert_array_equal(layer.data, labels)


def test_refused_file_gives_vtkvols_message(make_napari_viewer, tmp_path):
    path = tmp_path / "broken.tif"
    path.write_bytes(b"II*\x00garbage")
    expected = None
    try:
        read_volume(path)
    except ValueError as exc:
        expected = str(exc)
    assert expected and expected.startswith("broken.tif: ")
    viewer = make_napari_viewer()
    with pytest.raises(Exception) as info:
        _open(viewer, path)
    text = str(info.value) + str(info.value.__cause__ or "")
    assert expected in text


# --- the mapping, headless -----------------------------------------------------------------


class FakeLayer:
    """The attributes of a napari Image layer that the mapping reads."""

    def __init__(self, data, name="ch", **kw):
        self.data, self.name, self.visible, self.multiscale = data, name, True, False
        self.scale = kw.get("scale", (1.0, 1.0, 1.0))
        self.contrast_limits = kw.get("contrast_limits", (0.0, 100.0))
        self.colormap = kw.get("colormap", np.array([[0, 0, 0, 1], [0, 1, 0, 1.0]]))
        self.gamma, self.opacity = kw.get("gamma", 1.0), kw.get("opacity", 1.0)
        self.rendering, self.iso_threshold = kw.get("rendering", "translucent"), 40.0
        self.metadata = {}


def test_contrast_limits_colormap_gamma_opacity_become_the_ramp():
    tf = transfer_function((10.0, 110.0), np.array([[0, 0, 0, 1], [1, 0.5, 0, 1.0]]),
                           gamma=2.0, opacity=0.5)
    values = np.array([10.0, 60.0, 110.0])
    np.testing.assert_allclose(tf.opacity_at(values), [0.0, 0.5 * 0.25, 0.5], atol=1e-6)
    np.testing.assert_allclose(tf.color_at(values)[2], [1.0, 0.5, 0.0], atol=1e-6)
    np.testing.assert_allclose(tf.color_at(values)[1], [0.25, 0.125, 0.0], atol=1e-6)


@pytest.mark.parametrize(("rendering", "blend"), [
    ("translucent", "composite"), ("mip", "mip"), ("attenuated_mip", "mip"),
    ("iso", "isosurface"), ("minip", "minip"), ("average", "average"),
])
def test_rendering_modes_map_to_blend_modes(rendering, blend):
    data = np.zeros((4, 5, 6), np.uint8)
    _, model = layers_to_scene([FakeLayer(data, rendering=rendering)])
    assert BLEND_MODES[rendering] == blend and model.render.blend_mode == blend
    if blend == "isosurface":
        assert model.render.isosurface_value == 40.0


def test_scale_becomes_voxel_size_and_layers_channels():
    a, b = np.zeros((4, 5, 6), np.uint16), np.ones((4, 5, 6), np.uint16)
    data, model = layers_to_scene([FakeLayer(a, "A", scale=(2.0, 0.5, 0.25)),
                                   FakeLayer(b, "B", scale=(2.0, 0.5, 0.25))])
    assert data.array.shape == (2, 4, 5, 6) and data.channel_names == ["A", "B"]
    assert data.voxel_size_um == pytest.approx((0.25, 0.5, 2.0))
    assert [c.name for c in model.channels] == ["A", "B"]
    with pytest.raises(MappingError, match="differ in shape"):
        layers_to_scene([FakeLayer(a), FakeLayer(np.zeros((3, 5, 6), np.uint16))])
    with pytest.raises(MappingError, match="up to 4 channels"):
        layers_to_scene([FakeLayer(a) for _ in range(5)])


# --- the dock widget, with GL ---------------------------------------------------------------


def _two_channel_tiff(path: Path) -> Path:
    """(z, c, y, x) = (24, 2, 32, 40) uint16 ImageJ hyperstack, voxel 0.5 × 0.5 × 1 µm: a
    bright ball off the centre (x 28, y 10, z 16) in channel 0, a bar along x in channel 1."""
    import tifffile

    z, y, x = np.mgrid[:24, :32, :40].astype(np.float32)
    ball = 3000 * np.exp(-((x - 28) ** 2 + (y - 10) ** 2 + (z - 16) ** 2) / (2 * 4.0 ** 2))
    bar = 2000 * ((np.abs(y - 22) < 3) & (np.abs(z - 8) < 3) & (x > 6))
    stack = np.stack([ball + 50, bar + 50], axis=1).astype(np.uint16)
    tifffile.imwrite(path, stack, imagej=True, resolution=(2.0, 2.0),
                     metadata={"axes": "ZCYX", "spacing": 1.0, "unit": "um"})
    return path


@pytest.mark.gl
def test_dock_render_equals_vtkvol_render_of_the_session(make_napari_viewer, tmp_path):
    from PIL import Image

    from vtkvol import cli
    from vtkvol.napari._widget import IlluminatedRenderWidget, open_in_vtkvol

    path = _two_channel_tiff(tmp_path / "two.tif")
    viewer = make_napari_viewer()
    layers = _open(viewer, path)
    assert [tuple(ly.scale) for ly in layers] == [pytest.approx((1.0, 0.5, 0.5))] * 2
    viewer.dims.ndisplay = 3
    napari_camera(viewer).angles = (15.0, -25.0, 70.0)
    layers[1].gamma = 0.7
    layers[0].contrast_limits = (100.0, 2500.0)
    widget = IlluminatedRenderWidget(viewer)
    widget.method.setCurrentText("shadow_volume")
    widget.width_px.setValue(96)
    widget.height_px.setValue(96)
    image = widget.render()
    assert image is not None and image.shape == (96, 96, 3) and image.std() > 3
    assert viewer.layers[-1].name == "vtkvol shadow_volume" and viewer.layers[-1].rgb

    session, process = open_in_vtkvol(viewer, tmp_path / "session", start=False, size=(96, 96))
    assert process is None
    out = tmp_path / "cli.png"
    assert cli.main(["render", str(session), "-o", str(out), "--size", "96", "96",
                     "--method", "shadow_volume"]) == 0
    reference = np.asarray(Image.open(out).convert("RGB"))
    diff = np.abs(reference.astype(int) - image.astype(int))
    print(f"dock vs vtkvol render: max diff {diff.max()}, mean {diff.mean():.3f}")
    assert diff.max() <= 1


def _bright_centroid(image: np.ndarray) -> np.ndarray:
    """(x, y) pixel centroid of the brightest 2 % of the image, relative to its centre,
    as fractions of the image size."""
    gray = image[..., :3].astype(float).mean(axis=-1)
    mask = gray >= np.quantile(gray, 0.98)
    mask &= gray > gray.min() + 10
    assert mask.any(), "nothing visible"
    ys, xs = np.nonzero(mask)
    h, w = gray.shape
    return np.array([xs.mean() / w - 0.5, ys.mean() / h - 0.5])


@pytest.mark.gl
@pytest.mark.parametrize(("depth", "angles"), [
    ("away", (0.0, 0.0, 90.0)), ("away", (40.0, -30.0, 120.0)), ("towards", (0.0, 60.0, 90.0)),
])
def test_a_napari_camera_rotation_is_the_same_view_in_the_render(make_napari_viewer, tmp_path,
                                                                 depth, angles):
    from qtpy.QtWidgets import QApplication

    from vtkvol.napari._widget import render_viewer

    path = _two_channel_tiff(tmp_path / "two.tif")
    viewer = make_napari_viewer(show=True)
    layers = _open(viewer, path)
    viewer.layers.remove(layers[1])  # the ball only: an off-centre, asymmetric object
    layers[0].rendering = "mip"
    viewer.window.resize(360, 330)
    viewer.dims.ndisplay = 3
    QApplication.processEvents()  # the canvas takes its size; the view fits the volume to it
    viewer.reset_view()
    # "away": a right-handed view, as vtkvol's; "towards" (napari's default) is left-handed,
    # the mirror image of the sample, so the render is napari's canvas mirrored left-right.
    napari_camera(viewer).orientation = (depth, "down", "right")
    napari_camera(viewer).angles = angles
    shot = viewer.screenshot(canvas_only=True)  # as napari shows it, canvas pixels
    h, w = shot.shape[:2]
    # Half the canvas, same aspect: the world shown is the same, in fewer pixels.
    ours = render_viewer(viewer, size=(w // 2, h // 2), method="local")
    napari_offset, vtkvol_offset = _bright_centroid(shot), _bright_centroid(ours)
    if depth == "towards":
        napari_offset[0] *= -1
    print(f"angles {angles}: napari {napari_offset}, vtkvol {vtkvol_offset}")
    assert np.abs(napari_offset - vtkvol_offset).max() < 0.03  # measured ≤ 0.007
    assert np.abs(napari_offset).max() > 0.05  # the ball is off-centre in the view


@pytest.mark.gl
def test_dock_writes_png_and_turntable_mp4_with_progress(make_napari_viewer, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    from PIL import Image

    from vtkvol.napari._widget import IlluminatedRenderWidget

    viewer = make_napari_viewer()
    _open(viewer, _two_channel_tiff(tmp_path / "two.tif"))
    viewer.dims.ndisplay = 3
    widget = IlluminatedRenderWidget(viewer)
    widget.method.setCurrentText("local")
    widget.width_px.setValue(64)
    widget.height_px.setValue(48)
    widget.output.setCurrentText("PNG")
    widget.path.setText(str(tmp_path / "view.png"))
    image = widget.render()
    saved = np.asarray(Image.open(tmp_path / "view.png").convert("RGB"))
    np.testing.assert_array_equal(saved, image)
    assert len(viewer.layers) == 2  # no layer added for a PNG

    seen: list[int] = []
    widget.progress.valueChanged.connect(seen.append)
    widget.output.setCurrentText("Turntable MP4")
    widget.path.setText(str(tmp_path / "turn.mp4"))
    widget.frames.setValue(6)
    widget.render()
    movie = tmp_path / "turn.mp4"
    assert movie.stat().st_size > 1000 and movie.read_bytes()[4:8] == b"ftyp"
    assert seen[-1] == 6 and len(set(seen)) >= 3  # the bar moved frame by frame
    assert widget.status.text() == f"wrote {movie} (6 frames)"


def test_open_in_vtkvol_writes_the_session_and_starts_the_app_apart(make_napari_viewer,
                                                                   tmp_path, monkeypatch):
    import sys

    from vtkvol.model.session import load_session_with_data
    from vtkvol.napari import _widget
    from vtkvol.napari._widget import open_in_vtkvol

    started: list[list[str]] = []
    monkeypatch.setattr(_widget, "_start_app", started.append)
    path = _two_channel_tiff(tmp_path / "two.tif")
    viewer = make_napari_viewer()
    layers = _open(viewer, path)
    viewer.dims.ndisplay = 3
    napari_camera(viewer).angles = (0.0, 0.0, 90.0)
    layers[0].contrast_limits = (200.0, 1800.0)
    session, _ = open_in_vtkvol(viewer, tmp_path / "s")
    assert started == [[sys.executable, "-m", "vtkvol.cli", "open", str(session)]]
    model, data = load_session_with_data(session)
    assert Path(data.source) == path and data.array.shape == (2, 24, 32, 40)
    assert model.channels[0].tf.opacity[0][0] == pytest.approx(200.0)
    assert model.channels[0].tf.opacity[-1][0] == pytest.approx(1800.0)
    assert model.camera.focal_point is not None
    view = np.subtract(model.camera.focal_point, model.camera.position)
    np.testing.assert_allclose(view / np.linalg.norm(view),
                               np.asarray(napari_camera(viewer).view_direction)[::-1], atol=1e-6)

    # Layers that no vtkvol file holds are saved beside the session, voxel size and all.
    viewer2 = make_napari_viewer()
    viewer2.add_image(np.ones((4, 5, 6), np.float32), scale=(2.0, 1.0, 0.5))
    viewer2.dims.ndisplay = 3
    session2, _ = open_in_vtkvol(viewer2, tmp_path / "s2")
    _, data2 = load_session_with_data(session2)
    assert Path(data2.source).name == "napari_layers.npy"
    assert data2.voxel_size_um == pytest.approx((0.5, 1.0, 2.0))


def test_readers_and_mapping_import_no_qt_and_the_widget_no_pyside6():
    from test_layers import imported_after

    loaded = imported_after(["vtkvol.napari._reader", "vtkvol.napari._mapping"])
    assert sorted(m for m in loaded if m.startswith(("PySide6", "PyQt", "qtpy", "napari"))) == []
    root = Path(__file__).resolve().parents[1] / "vtkvol" / "napari"
    imports = re.compile(r"^\s*(from|import)\s+(PySide6|PyQt5|PyQt6)\b", re.M)
    for source in root.glob("*.py"):
        assert not imports.search(source.read_text(encoding="utf-8")), source


def test_an_ome_zarr_address_opens_in_napari(make_napari_viewer, tmp_path):
    pytest.importorskip("ome_zarr.writer")
    pytest.importorskip("aiohttp")
    from tests_support_http import CountingServer, phantom, write_served_stores

    root = write_served_stores(tmp_path)
    with CountingServer(root) as server:
        viewer = make_napari_viewer()
        layers = _open(viewer, f"{server.url}/cells.ome.zarr")
        assert [ly.name for ly in layers] == ["DAPI", "GFP"]
        assert all(ly.multiscale and len(ly.data) == 5 for ly in layers)
        coarsest = read_volume(root / "cells.ome.zarr", level=4).array[0]
        np.testing.assert_array_equal(np.asarray(layers[0].data[4]), coarsest)
        np.testing.assert_array_equal(np.asarray(layers[1].data[0][:, :8, :8]),
                                      phantom()[1, :, :8, :8])
