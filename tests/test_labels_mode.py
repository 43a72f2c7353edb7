"""Labels mode: the one check behind ``--labels`` and the app (``label_ids``), detection of
label channels beside raw data, the recorded display (``Channel.labels``), hidden labels
absent from the image, label channels over raw data sampled at the nearest voxel, and the
probe's read-out of a label id."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cmap")

from vtkvol.engine.probe import ProbeResult
from vtkvol.io import VolumeData, confocal_phantom
from vtkvol.model.defaults import scene_for
from vtkvol.model.labels import (
    LabelImageError,
    apply_labels,
    detect_labels,
    label_colors,
    label_ids,
    show_detected_labels,
    show_intensities,
)
from vtkvol.model.scene import LabelDisplay


def blobs(shape=(32, 48, 48), ids=(3, 9, 17, 40, 41, 250), seed=2) -> np.ndarray:
    """Balls of radius 4…6 voxels with the given ids (uint16)."""
    rng = np.random.default_rng(seed)
    z, y, x = np.indices(shape)
    out = np.zeros(shape, np.uint16)
    for k in ids:
        c = rng.uniform([7, 7, 7], [shape[0] - 7, shape[1] - 7, shape[2] - 7])
        r = rng.uniform(4, 6)
        out[((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) < r * r] = k
    return out


def test_label_ids_refuses_floats_and_absurd_id_counts():
    # A million distinct ids (each voxel its own): refused by their span, before np.unique.
    million = np.arange(1, 1_000_001, dtype=np.int32).reshape(16, 250, 250)
    start = time.perf_counter()
    with pytest.raises(LabelImageError) as info:
        label_ids(million, "cells.tif")
    assert str(info.value) == (
        "cells.tif: ids span 1…1000000, more than 4000: renumber them first "
        "(e.g. skimage.segmentation.relabel_sequential)")
    assert time.perf_counter() - start < 2.0
    # Read from a file, int32 ids that do not fit 16 bits become float32: refused as floats.
    read = VolumeData.from_array(million[None], (1.0, 1.0, 1.0), ["cells"])
    with pytest.raises(LabelImageError, match=r"^cells holds float32 values; label ids are "
                                              r"integers$"):
        label_ids(read.array[0], "cells")
    with pytest.raises(LabelImageError, match="with the background 0 they span more than 4000"):
        label_ids(np.array([[[0, 3000, 7000]]], np.int32), "far.tif")
    with pytest.raises(LabelImageError, match="has no label other than 0"):
        label_ids(np.zeros((2, 2, 2), np.uint8), "empty.tif")
    assert label_ids(blobs(), "seg") == [3, 9, 17, 40, 41, 250]


def test_absurd_label_images_open_as_intensities():
    """Detection on open leaves a million-id image and float labels as intensities (no
    exception, no nearest sampling)."""
    million = np.arange(1, 1_000_001, dtype=np.int32).reshape(16, 250, 250)
    for array in (million, blobs().astype(np.float32)):
        data = VolumeData.from_array(array[None], (1.0, 1.0, 1.0), ["x"])
        model = scene_for(data)
        assert show_detected_labels(model, data) == []
        assert model.channels[0].labels is None
        assert model.render.interpolation == "trilinear"


def test_a_label_channel_beside_raw_data_is_detected_alone():
    raw = confocal_phantom((32, 48, 48)).array[0]
    data = VolumeData.from_array(np.stack([raw, blobs()]), (1.0, 1.0, 1.0), ["raw", "seg"])
    model = scene_for(data)
    shown = show_detected_labels(model, data)
    assert [c for c, _ in shown] == [1] and "6 integer ids over regions" in shown[0][1]
    assert model.channels[0].labels is None and model.channels[1].labels == LabelDisplay()
    assert model.render.interpolation == "nearest"
    colours = label_colors([3, 9, 17, 40, 41, 250])
    assert np.allclose(model.channels[1].tf.color_at(np.array([3.0, 9, 17, 40, 41, 250])),
                       colours, atol=1e-6)


def test_categorical_colours_are_distinct():
    """Ids get clearly different colours (glasbey): the closest pair of the first 64 ids
    differs by more than 0.1 in some RGB component (measured: 0.106)."""
    rgb = label_colors(range(1, 65))
    distance = np.abs(rgb[:, None] - rgb[None]).max(2)
    distance[np.diag_indices(64)] = 1.0
    assert distance.min() > 0.1


def test_apply_and_undo_labels_on_one_channel():
    raw = confocal_phantom((32, 48, 48)).array[0]
    data = VolumeData.from_array(np.stack([raw, blobs()]), (1.0, 1.0, 1.0), ["raw", "seg"])
    model = scene_for(data)
    model.channels[1].tf_linked_to = 0
    events = []
    model.changed.connect(events.append)
    apply_labels(model, [3, 9, 17], channel=1, opacity=0.5, hidden=[9, 9])
    assert len(events) == 1  # one edit: one undo step, one frame
    seg = model.channels[1]
    assert seg.labels == LabelDisplay(opacity=0.5, hidden=[9]) and seg.tf_linked_to is None
    assert seg.tf.opacity_at(np.array([3.0, 9.0, 17.0])) == pytest.approx([0.5, 0.0, 0.5])
    from vtkvol.model.defaults import default_transfer_function

    show_intensities(model, 1, default_transfer_function(data, 1, seg.color))
    assert seg.labels is None and model.render.interpolation == "trilinear"


def test_probe_reads_label_ids():
    result = ProbeResult((1.0, 2.0, 3.0), (1, 2, 3), (812.0, 17.0, 0.0),
                         ("raw", "nuclei", "cells"), (False, True, True))
    assert result.text() == ("x 1 y 2 z 3 µm · voxel (1, 2, 3) · raw 812 · nuclei label 17 · "
                             "cells background")
    plain = ProbeResult((1.0, 2.0, 3.0), (1, 2, 3), (17.0,), ("nuclei",))
    assert plain.text().endswith("nuclei 17")


def _foreground(image: np.ndarray, background) -> np.ndarray:
    bg = np.round(np.asarray(background) * 255)
    pixels = image.reshape(-1, 3).astype(int)
    return pixels[np.abs(pixels - bg).max(1) > 2]


@pytest.mark.gl
def test_labels_over_raw_data_show_only_label_colours_and_hidden_ones_vanish():
    """Raw intensities and a segmentation in one volume, the raw channel hidden: every pixel
    has the colour of a label present (nearest sampling: no blended ids at boundaries, also
    with two components); hiding id 17 removes its colour from the image."""
    from vtkvol.engine.api import render_image

    raw = confocal_phantom((32, 48, 48)).array[0]
    seg = blobs()
    ids = [3, 9, 17, 40, 41, 250]
    data = VolumeData.from_array(np.stack([raw, seg]), (1.0, 1.0, 1.0), ["raw", "seg"])
    palette = np.round(label_colors(ids) * 255).astype(int)

    def render(hidden=(), interpolation="nearest") -> np.ndarray:
        model = scene_for(data)
        show_detected_labels(model, data)
        apply_labels(model, ids, channel=1, hidden=hidden)
        model.render.interpolation = interpolation
        model.channels[0].visible = False
        model.render.shade = False
        fg = _foreground(render_image(data, model=model, size=(96, 96), method="local"),
                         model.render.background)
        assert len(fg) > 400  # measured: 586 of 9216 pixels
        return np.abs(fg[:, None, :] - palette[None]).max(2)  # [pixel, id] distance

    near = render()
    assert float((near.min(1) > 2).mean()) == 0.0
    assert (near[:, 2] <= 2).sum() > 30  # id 17 is in view
    blended = render(interpolation="trilinear")
    assert float((blended.min(1) > 2).mean()) > 0.2
    hidden = render(hidden=[17])
    assert (hidden[:, 2] <= 2).sum() == 0
    assert float((hidden.min(1) > 2).mean()) == 0.0


DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data not present")
def test_real_stacks_are_told_apart():
    """What the app opens in labels mode among the shared stacks: the nuclei labels, not the
    8-bit bead image (its neighbours are equal in 71 % of pairs, as labels' are, but 28 % of
    them change by 1 or 2 along x, 29 % between slices: intensities) nor the deconvolution
    crop."""
    import vtkvol

    found = {name: detect_labels(vtkvol.read_volume(DATA / name).array[0])
             for name in ("platynereis_nuclei_labels_256x256x103.tif", "Bead_Image1_crop.tif",
                          "DeconvolutionSampleVerticalGrid1AU-crop.tif")}
    assert found["platynereis_nuclei_labels_256x256x103.tif"].is_labels
    beads = found["Bead_Image1_crop.tif"]
    assert not beads.is_labels
    assert beads.reason == ("neighbouring voxels differ by 1 or 2 in 29% of pairs: intensities "
                            "change in small steps, ids do not")
    assert not found["DeconvolutionSampleVerticalGrid1AU-crop.tif"].is_labels


@pytest.mark.gl
def test_labels_over_visible_raw_data_have_their_own_opacity():
    """Raw intensities and labels both shown: the labels change the image where they are;
    at label opacity 0 the image is the raw channel's alone."""
    from vtkvol.engine.api import render_image

    raw = confocal_phantom((32, 48, 48)).array[0]
    data = VolumeData.from_array(np.stack([raw, blobs()]), (1.0, 1.0, 1.0), ["raw", "seg"])
    ids = [3, 9, 17, 40, 41, 250]

    def render(opacity: float | None) -> np.ndarray:
        model = scene_for(data)
        apply_labels(model, ids, channel=1, opacity=opacity or 0.0)
        model.channels[1].visible = opacity is not None
        return render_image(data, model=model, size=(64, 64), method="local").astype(float)

    alone, faint, opaque = render(None), render(0.0), render(1.0)
    assert np.abs(faint - alone).max() <= 2  # opacity 0: only the raw channel shows
    changed = np.abs(opaque - alone).max(2) > 10
    assert changed.mean() > 0.05, changed.mean()


def test_a_label_image_with_too_many_ids_says_why_it_is_not_coloured():
    """5120 ids, each a run of 8 voxels along x: detected as labels, but their span is more
    than the colour table resolves; the channel stays as intensities and the reason is
    given (the app shows it in the status bar)."""
    ids = np.arange(1, 10 * 64 * 8 + 1, dtype=np.uint16).reshape(10, 64, 8)
    array = np.repeat(ids, 8, axis=2)  # (10, 64, 64)
    assert detect_labels(array).is_labels
    data = VolumeData.from_array(array[None], (1.0, 1.0, 1.0), ["cells"])
    model = scene_for(data)
    refused: list[tuple[int, str]] = []
    assert show_detected_labels(model, data, refused) == []
    assert refused == [(0, "channel 'cells': ids span 1…5120, more than 4000: renumber them "
                           "first (e.g. skimage.segmentation.relabel_sequential)")]
    assert model.channels[0].labels is None and model.render.interpolation == "trilinear"


@pytest.mark.gl
def test_many_labels_keep_exact_colours_in_the_renderer():
    """600 ids (1202 colour points, more than a TF is otherwise reduced to): VTK's colour
    function gives every id exactly its glasbey colour, and opacity 0 to a hidden one."""
    import vtk

    from vtkvol.engine.scene import VolumeScene

    ids = np.arange(1, 601, dtype=np.uint16)
    array = np.zeros((4, 16, 600), np.uint16)
    array[1:3, 4:12] = ids  # each id a 2 × 8 × 1 column
    data = VolumeData.from_array(array[None], (1.0, 1.0, 1.0), ["seg"])
    model = scene_for(data)
    apply_labels(model, ids.tolist(), hidden=[300])
    renderer = vtk.vtkRenderer()
    scene = VolumeScene(renderer, model, data, request_render=lambda: None)
    ctf = scene.property.GetRGBTransferFunction(0)
    otf = scene.property.GetScalarOpacity(0)
    got = np.array([ctf.GetColor(float(k)) for k in ids])
    assert np.abs(got - label_colors(ids)).max() < 1e-6
    assert otf.GetValue(300.0) == 0.0 and otf.GetValue(299.0) == 1.0


def test_the_napari_reader_shares_the_detection():
    """A label image named like anything else becomes a napari Labels layer, as the app
    opens it in labels mode; intensities stay an image layer."""
    from vtkvol.napari._reader import layer_data

    seg = VolumeData.from_array(blobs()[None], (1.0, 1.0, 1.0), ["stack"])
    raw = VolumeData.from_array(confocal_phantom((32, 48, 48)).array[:1], (1.0, 1.0, 1.0),
                                ["stack"])
    assert layer_data(seg, 0, seg.array[0], (1.0, 1.0, 1.0))[2] == "labels"
    assert layer_data(raw, 0, raw.array[0], (1.0, 1.0, 1.0))[2] == "image"


def test_a_segmentation_file_beside_its_raw_stack_opens_over_it(tmp_path):
    """A facility's segmentation is a file of its own: a folder holding the raw stack and its
    label image opens as two channels (File → Open folder → "Open all as channels", or
    ``vtkvol open --as-channels``), and only the label file's channel is shown as labels."""
    import tifffile

    from vtkvol.io.folder_channels import read_folder_as_channels

    raw = confocal_phantom((32, 48, 48)).array[0]
    tifffile.imwrite(tmp_path / "embryo.tif", raw, imagej=True, metadata={"axes": "ZYX"})
    tifffile.imwrite(tmp_path / "embryo_labels.tif", blobs(), imagej=True,
                     metadata={"axes": "ZYX"})
    data = read_folder_as_channels(tmp_path)
    assert data.n_channels == 2
    model = scene_for(data)
    shown = show_detected_labels(model, data)
    labelled = [data.channel_names[c] for c, _ in shown]
    assert labelled == [n for n in data.channel_names if "labels" in n]
    raw_channel = 1 - shown[0][0]
    assert model.channels[raw_channel].labels is None
