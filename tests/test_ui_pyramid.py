"""The app with a pyramid: the level shown within the GPU-memory budget (and saying so),
"Refine selection" (the crop region at a finer level, in place on screen) and "Back to
overview", the budget setting, and sessions of a refined view. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QSettings

zarr = pytest.importorskip("zarr")
writer = pytest.importorskip("ome_zarr.writer")
ome_format = pytest.importorskip("ome_zarr.format")

from vtkvol.io.pyramid import DEFAULT_GPU_BUDGET_BYTES, parse_bytes  # noqa: E402
from vtkvol.io.volume_data import format_bytes  # noqa: E402
from vtkvol.model.session import load_session_with_data  # noqa: E402
from vtkvol.ui.pyramid_view import (  # noqa: E402
    BUDGET_CHOICES,
    GPU_BUDGET_KEY,
    level_words,
    read_budget,
    restrict_weights,
)

pytestmark = pytest.mark.gui

VOXEL = {"z": 1.0, "y": 0.5, "x": 0.5}  # µm at level 0


def blob_volume() -> np.ndarray:
    """(z, y, x) = (16, 64, 64) uint16: a bright ball off the centre (x 40, y 20, z 8 voxels)
    on a dim background, so a shift of the view would show."""
    z, y, x = np.mgrid[0:16, 0:64, 0:64].astype(np.float32)
    r2 = ((x - 40) * 0.5) ** 2 + ((y - 20) * 0.5) ** 2 + ((z - 8) * 1.0) ** 2
    return (100 + 3000 * np.exp(-r2 / (2 * 3.0 ** 2))).astype(np.uint16)


@pytest.fixture(scope="module")
def pyramid_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("pyr") / "ball.zarr"
    group = zarr.open_group(str(path), mode="w", zarr_format=3)
    writer.write_image(blob_volume()[None], group, axes="czyx", fmt=ome_format.FormatV05(),
                       scale_factors=(2, 4), scale={"c": 1.0, **VOXEL},
                       axes_units={a: "micrometer" for a in "zyx"},
                       storage_options={"chunks": (1, 8, 32, 32)})
    return path


#: Level 0 is 64×64×16×2 bytes = 128 KiB; level 1 32 KiB: a 40 KiB budget shows level 1.
BUDGET = 40 << 10


def open_and_wait(window, qtbot, path):
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_path(path)


def foreground_centroid(image: np.ndarray, window) -> np.ndarray:
    """Centre (x, y) in pixels of the ball's silhouette (anything not background: the shading
    differs between levels, whose gradients differ, the outline does not)."""
    bg = np.array(window.model.render.background) * 255.0
    mask = np.abs(image.astype(float) - bg).max(axis=-1) > 12
    assert mask.mean() > 0.002, "nothing visible"
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()])


def test_level_shown_refine_and_back(main_window, qtbot, pyramid_path, tmp_path):
    window = main_window
    window.budget_override = BUDGET
    open_and_wait(window, qtbot, pyramid_path)
    data = window.data
    assert data.metadata["level"] == 1 and data.array.shape == (1, 16, 32, 32)
    # Level 1 of three is the middle one; "level 1 of 3" read as the first (issue 25).
    assert "level 1 of 0–2 (0 = finest)" in window.data_label.text()
    assert window.data_label.toolTip().startswith(
        "Level 1 of 0–2 (0 = finest), 32×32×16, finest that fits 40 KiB\n")
    assert window.model.volume.level == 1
    assert window.refine_action.isEnabled() and not window.overview_action.isEnabled()
    assert window.ranges_dock.refine_button.isVisible()

    # Crop around the ball: x 14…26 µm, y 4…16 µm (level-1 voxels are 1 µm in x and y).
    window.model.crop.update({"x": (14.0, 26.0), "y": (4.0, 16.0)})
    window.model.illumination.method = "local"
    tf_before = window.model.channels[0].tf.copy_state()
    focal_before = np.array(window.model.camera.focal_point)
    before = window.viewport.screenshot()
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.ranges_dock.refine_button.click()
    refined = window.data
    assert refined.metadata["level"] == 0
    # ome-zarr's writer puts level 1's first voxel centre at 0.25 µm in x and y (half a level-0
    # voxel in), so the view's x 14…26 µm is 14.25…26.25 µm in pyramid space; widened by half
    # a level-1 voxel, 13.75…26.75 µm → level-0 voxels 28…53 (centres at 0.5·i µm); y 4…16 µm
    # → 3.75…16.75 → 8…33; z whole.
    np.testing.assert_array_equal(refined.array[0], blob_volume()[:, 8:34, 28:54])
    assert tuple(refined.voxel_size_um) == pytest.approx((0.5, 0.5, 1.0))
    assert refined.metadata["origin_um"] == pytest.approx([14.0, 4.0, 0.0])
    # The crop is the new whole extent; TF, method and the view are kept, shifted in place.
    assert (window.model.crop.x, window.model.crop.y, window.model.crop.z) == (None, None, None)
    assert window.model.channels[0].tf.copy_state() == tf_before
    assert window.model.illumination.method == "local"
    np.testing.assert_allclose(window.model.camera.focal_point,
                               focal_before - np.array([13.75, 3.75, 0.0]))
    assert window.model.volume.region_um is not None and window.model.volume.level == 0
    assert "refined region" in window.data_label.text()
    assert "region x 14–26.5" in window.statusBar().currentMessage()
    after = window.viewport.screenshot()
    # The ball stays where it was on screen (to a pixel and a half of a 256² view; a view not
    # shifted would move it by (13.75, 3.75) µm, tens of pixels).
    shift = foreground_centroid(after, window) - foreground_centroid(before, window)
    assert np.abs(shift).max() < 1.5, shift
    assert window.overview_action.isEnabled()

    # A session of the refined view reopens the same level and region, whatever the budget.
    saved = window.save_session(tmp_path / "refined.vtkvol.json")
    window.budget_override = 1 << 30
    model, again = load_session_with_data(saved)
    np.testing.assert_array_equal(again.array, refined.array)
    assert model.volume.level == 0 and again.metadata["origin_um"] == pytest.approx(
        [14.0, 4.0, 0.0])
    window.budget_override = BUDGET
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.ranges_dock.overview_button.click()
    assert window.data.metadata["level"] == 1 and window.data.array.shape == (1, 16, 32, 32)
    # No session was involved: the overview says where it came from, not "as saved in the
    # session" (issue 25).
    assert window.data_label.toolTip().startswith(
        "Level 1 of 0–2 (0 = finest), 32×32×16, the overview shown before Refine selection\n")
    assert window.model.crop.x == (14.0, 26.0) and window.model.crop.y == (4.0, 16.0)
    np.testing.assert_allclose(window.model.camera.focal_point, focal_before, atol=1e-9)
    assert window.model.volume.region_um is None
    assert not window.overview_action.isEnabled()

    # A session's level says where it came from.
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(saved)
    assert "finest level (0 of 0–2)" in window.data_label.text()
    assert ", as saved in the session" in window.data_label.toolTip().split("\n")[0]
    window.budget_override = None


def test_refine_at_the_finest_level_says_so(main_window, qtbot, pyramid_path):
    window = main_window
    window.budget_override = 1 << 30  # level 0 fits: nothing finer to load
    open_and_wait(window, qtbot, pyramid_path)
    assert window.data.metadata["level"] == 0
    data = window.data
    window.refine_selection()
    qtbot.waitUntil(lambda: window._task is None, timeout=20_000)
    assert window.data is data
    assert "already the finest level" in window.statusBar().currentMessage()
    window.budget_override = None


def test_budget_setting_is_kept_and_survives_damage(main_window, tmp_path):
    settings = QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat)
    assert read_budget(settings) == DEFAULT_GPU_BUDGET_BYTES
    settings.setValue(GPU_BUDGET_KEY, "a lot")
    assert read_budget(settings) == DEFAULT_GPU_BUDGET_BYTES
    settings.setValue(GPU_BUDGET_KEY, -5)
    assert read_budget(settings) == DEFAULT_GPU_BUDGET_BYTES
    window = main_window
    window.set_gpu_budget(512 << 20)
    assert window.gpu_budget() == 512 << 20
    assert read_budget(window.settings) == 512 << 20
    assert "GPU memory budget 512 MiB:" in window.statusBar().currentMessage()


def test_restricted_slice_weights():
    ramp = [(0.0, 0.0), (1.0, 1.0)]
    part = restrict_weights(ramp, 0.25, 0.75)
    assert part == [(0.0, 0.25), (1.0, 0.75)]
    step = restrict_weights([(0.0, 1.0), (0.5, 0.0), (1.0, 0.0)], 0.0, 1.0)
    assert step == [(0.0, 1.0), (0.5, 0.0), (1.0, 0.0)]


def test_time_points_of_a_pyramid_are_read_at_the_level_and_region_shown(main_window, qtbot,
                                                                         tmp_path):
    """A 3-time-point pyramid shown at level 1 (the budget's): stepping in time reads level 1
    of the other points, not the reader's default level; after Refine selection, the refined
    region at its level. Each time point's ball is brighter, so the voxels shown change."""
    path = tmp_path / "lapse.zarr"
    group = zarr.open_group(str(path), mode="w", zarr_format=3)
    series = np.stack([blob_volume() // 3 * (t + 1) for t in range(3)])[:, None]
    writer.write_image(series, group, axes="tczyx", fmt=ome_format.FormatV05(),
                       scale_factors=(2, 4), scale={"t": 1.0, "c": 1.0, **VOXEL},
                       axes_units={a: "micrometer" for a in "zyx"},
                       storage_options={"chunks": (1, 1, 8, 32, 32)})
    window = main_window
    window.budget_override = BUDGET
    open_and_wait(window, qtbot, path)
    assert window.data.metadata["level"] == 1 and window.time_player.count == 3

    def step_to(index: int) -> None:
        window.time_player.go_to(index)
        qtbot.waitUntil(lambda: window.time_player.shown_index == index, timeout=20_000)

    first = window.data.array.max()
    step_to(2)
    assert window.data.metadata["level"] == 1 and window.data.array.shape == (1, 16, 32, 32)
    assert window.data.array.max() > 2 * first

    window.model.crop.update({"x": (8.0, 24.0), "y": (0.0, 16.0)})
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.refine_selection()
    refined = window.data
    assert refined.metadata["level"] == 0 and refined.metadata["region_um"] is not None
    step_to(0)
    assert window.data.metadata["level"] == 0
    assert window.data.array.shape == refined.array.shape
    assert window.data.metadata["region_um"] == refined.metadata["region_um"]
    assert window.data.array.max() < refined.array.max()


def test_level_words_name_the_finest_and_coarsest():
    """Level 0 is the finest; the words say so rather than "level 1 of 2" for the coarse one."""
    assert level_words(0, 2) == "finest level (0 of 0–1)"
    assert level_words(1, 2) == "coarsest level (1 of 0–1)"
    assert level_words(1, 3) == "level 1 of 0–2 (0 = finest)"
    assert level_words(0, 1) == "the only level"


def test_budget_sizes_read_as_the_choices():
    """The budget dialog lists the current size beside the choices only when it differs: a
    1 GiB budget is written "1 GiB", not "1.0 GiB" next to "1 GiB" (issue 25)."""
    for choice in BUDGET_CHOICES:
        assert format_bytes(parse_bytes(choice)) == choice
    assert format_bytes(1536) == "1.5 KiB" and format_bytes(1000) == "1000 B"
    assert format_bytes(DEFAULT_GPU_BUDGET_BYTES) == "1 GiB"
