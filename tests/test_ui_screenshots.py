"""Screenshots of the app for the documentation: ``docs/screenshots/*.png``.

The whole window twice (the two tabbed dock pairs each in front once) and every dock on its
own; on real data from ``../shared/data``, the window with the slice views, the 3-D view with
every overlay, and the slice views alone. Only the whole-window images and the 3-D view need
a 3-D frame (seconds each on a software GL); the dock images cost nothing.
Deselect with ``-m "not screenshots"``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QSettings, Qt
from PySide6.QtGui import QImage

from vtkvol.ui.app import MainWindow, configure_gl_platform, write_png
from vtkvol.ui.docks.channels import ChannelsDock
from vtkvol.ui.docks.lights import LightsDock
from vtkvol.ui.docks.ranges import RangesDock
from vtkvol.ui.docks.slice_weights import SliceWeightsDock
from vtkvol.ui.docks.transfer_function import TransferFunctionDock

pytestmark = [
    pytest.mark.gui,
    pytest.mark.screenshots,
    # Opt-in: it rewrites the PNGs under docs/, and on this VTK 9.7 / PySide6 / Mesa stack the
    # process can crash in garbage collection after the many-dock window closes (a native
    # fault outside vtkvol's code), which must not take the whole suite down. Run it on its own:
    #   VTKVOL_WRITE_SCREENSHOTS=1 python -m pytest tests/test_ui_screenshots.py
    pytest.mark.skipif(
        os.environ.get("VTKVOL_WRITE_SCREENSHOTS") != "1",
        reason="writes docs/screenshots; set VTKVOL_WRITE_SCREENSHOTS=1 to run",
    ),
]

OUT = Path(__file__).resolve().parents[1] / "docs" / "screenshots"


def _nonblank(path: Path) -> float:
    image = QImage(str(path)).convertToFormat(QImage.Format.Format_Grayscale8)
    width, height = image.width(), image.height()
    bits = np.frombuffer(image.constBits(), np.uint8, image.bytesPerLine() * height)
    return float(bits.reshape(height, -1)[:, :width].std())


def _shown_window(qapp, qtbot, tmp_path) -> MainWindow:
    """The app window the screenshots are taken of: 1240 × 800, its own settings file, a
    sample distance of one voxel (frames that a software GL draws in seconds)."""
    configure_gl_platform(qapp)
    window = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(window)
    window.resize(1240, 800)
    window.show()
    qtbot.waitExposed(window)
    window.model.render.sample_distance = 1.0
    return window


def test_write_docs_screenshots(qapp, qtbot, tmp_path):
    window = _shown_window(qapp, qtbot, tmp_path)
    window.model.illumination.method = "shadow_volume" if "shadow_volume" in (
        window.lights_dock.techniques) else "local"
    with qtbot.waitSignal(window.dataShown, timeout=60_000):
        window.open_sample(shape_zyx=(32, 80, 80), voxel_size_um=(0.3, 0.3, 0.9))
    window.viewport.scene.orbit(-15.0, 5.0)
    # The day-one overlays (issue 15): scale bar, orientation axes, colour legend.
    window.model.overlays.update({"scale_bar": True, "orientation_axes": True,
                                  "color_legend": True})
    qtbot.wait(100)  # layouts settle (the channel rows, the dock sizes)
    OUT.mkdir(parents=True, exist_ok=True)
    written = []

    def save(widget, name: str) -> None:
        path = OUT / f"{name}.png"
        assert widget.grab().save(str(path))
        written.append(path)

    window.tf_dock.raise_()
    window.lights_dock.raise_()
    save(window, "main-window")
    window.slice_dock.raise_()
    window.ranges_dock.raise_()
    window.slice_dock.axis_buttons["z"].click()
    window.model.slice_weights.z = [(0.0, 0.0), (0.15, 1.0), (0.85, 1.0), (1.0, 0.0)]
    window.model.crop.x = (3.0, 21.0)
    window.model.overlays.update({"bounding_box": True, "color_legend": False})
    qtbot.wait(50)
    save(window, "main-window-slices-ranges")
    # Each dock on its own: a second instance bound to the same model and data, at a size
    # that shows all of it. The main window is left alone, so no 3-D frame is rendered.
    sizes = {"transfer-function": (TransferFunctionDock, 940, 300),
             "slice-contribution": (SliceWeightsDock, 940, 300),
             "channels": (ChannelsDock, 380, 270),
             "lights": (LightsDock, 380, 780),
             "ranges": (RangesDock, 380, 330)}
    for name, (cls, width, height) in sizes.items():
        dock = cls(window.model)
        qtbot.addWidget(dock)
        dock.set_data(window.data)
        if cls is SliceWeightsDock:
            dock.axis_buttons["z"].click()
        dock.resize(width, height)
        dock.show()
        qtbot.wait(30)
        save(dock, name)
        dock.release()
        dock.close()
    window.close()
    for path in written:
        assert _nonblank(path) > 10.0, path


DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
NUCLEI = DATA / "platynereis_nuclei_labels_256x256x103.tif"
BEADS = DATA / "Bead_Image1_crop.tif"


@pytest.mark.skipif(not (NUCLEI.exists() and BEADS.exists()), reason="../shared/data not present")
def test_write_slice_view_and_overlay_screenshots(qapp, qtbot, tmp_path):
    """Real data: the platynereis nuclei (labels) with the slice views beside the 3-D view,
    the slice planes and every overlay; the 3-D view alone with the overlays; and the slice
    views alone on the bead stack, whose z-elongated PSF shows the voxels' true aspect."""
    from vtkvol.engine.slices import cursor_index
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.labels import apply_labels, detect_labels
    from vtkvol.ui.docks.slice_views import SliceViewsDock

    window = _shown_window(qapp, qtbot, tmp_path)
    window.model.illumination.method = "shadow_volume" if "shadow_volume" in (
        window.lights_dock.techniques) else "local"
    with qtbot.waitSignal(window.dataShown, timeout=60_000):
        window.open_path(NUCLEI)
    found = detect_labels(window.data.array[0])
    assert found.is_labels, found.reason
    apply_labels(window.model, found.labels)
    # The cursor on a nucleus: the centre of the label nearest the middle of the stack.
    array = window.data.array[0]
    spacing = tuple(window.data.voxel_size_um)
    z, y, x = (np.asarray(v) for v in np.nonzero(array[:, ::2, ::2]))
    middle = np.array(array.shape) / 2
    nearest = np.argmin((z - middle[0]) ** 2 + (2 * y - middle[1]) ** 2
                        + (2 * x - middle[2]) ** 2)
    label = array[z[nearest], 2 * y[nearest], 2 * x[nearest]]
    zz, yy, xx = np.nonzero(array == label)
    centre = (xx.mean() * spacing[0], yy.mean() * spacing[1], zz.mean() * spacing[2])
    window.model.cursor = tuple(
        float(i * s) for i, s in zip(cursor_index(centre, array.shape, spacing), spacing,
                                     strict=True))
    window.model.overlays.update({"scale_bar": True, "orientation_axes": True,
                                  "bounding_box": True, "color_legend": False,
                                  "slice_planes": True})
    window.gizmo_action.setChecked(False)  # the light's handle is no part of the picture
    window.viewport.scene.orbit(-30.0, 15.0)
    dock = window.slice_views_dock
    dock.toggleViewAction().trigger()
    qtbot.waitUntil(dock.isVisible, timeout=5000)
    window.resizeDocks([dock], [400], Qt.Orientation.Horizontal)
    qtbot.wait(100)
    dock.refresh_now()
    OUT.mkdir(parents=True, exist_ok=True)
    written = [OUT / "main-window-slice-views.png"]
    assert window.grab().save(str(written[-1]))

    # The 3-D view alone with all four overlays (the legend of the label colours too).
    dock.toggleViewAction().trigger()
    window.model.overlays.update({"color_legend": True, "slice_planes": False})
    qtbot.wait(100)
    written.append(OUT / "overlays.png")
    write_png(window.viewport.screenshot(), written[-1])
    window.close()

    # The slice views alone on the beads, the cursor on the brightest bead.
    beads = read_volume(BEADS)
    model = scene_for(beads)
    k, j, i = np.unravel_index(int(np.argmax(beads.array[0])), beads.array.shape[1:])
    model.cursor = (i * beads.voxel_size_um[0], j * beads.voxel_size_um[1],
                    k * beads.voxel_size_um[2])
    alone = SliceViewsDock(model)
    qtbot.addWidget(alone)
    alone.set_data(beads)
    alone.resize(620, 560)
    alone.show()
    qtbot.waitExposed(alone)
    alone.refresh_now()
    qtbot.wait(30)
    written.append(OUT / "slice-views-beads.png")
    assert alone.grab().save(str(written[-1]))
    alone.release()
    alone.close()
    for path in written:
        assert _nonblank(path) > 10.0, path
        assert path.stat().st_size < 300_000, path


def test_write_time_slider_screenshot(qapp, qtbot, tmp_path):
    """The time slider of a 20-point time-lapse at time point 7, alone and in the window
    (docs/app.md, README)."""
    from tests_support_time import write_time_lapse

    window = _shown_window(qapp, qtbot, tmp_path)
    path = tmp_path / "lapse.tif"
    write_time_lapse(path)
    with qtbot.waitSignal(window.dataShown, timeout=60_000):
        window.open_path(path)
    window.time_player.go_to(7)
    qtbot.waitUntil(lambda: window.time_player.shown_index == 7, timeout=20_000)
    qtbot.wait(100)
    OUT.mkdir(parents=True, exist_ok=True)
    target = OUT / "time-slider.png"
    assert window.time_toolbar.grab().save(str(target))
    assert _nonblank(target) > 5.0
    whole = OUT / "main-window-time-series.png"
    assert window.grab().save(str(whole))
    assert _nonblank(whole) > 5.0
    window.close()


@pytest.mark.skipif(not BEADS.exists(), reason="../shared/data not present")
def test_write_tf2d_editor_screenshot_on_real_data(qapp, qtbot, tmp_path):
    """``docs/screenshots/tf2d-editor.png``: the confocal bead stack of ../shared/data
    classified in 2-D: the beads' bright cores (a rectangle over every gradient) in orange
    and their steep flanks (a triangle rising from |∇I| = 0) in cyan, over the stack's
    value × gradient histogram; the rectangle is selected. A painted stroke (magenta, the
    Paint tool active) adds the dim flanks of the steepest voxels."""
    from vtkvol.model.tf_paint import TFPaintLayer, apply_stroke, stroke_mask
    from vtkvol.model.transfer_function import TFPrimitive

    configure_gl_platform(qapp)
    window = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(window)
    window.resize(1240, 880)  # room for the editor's three rows of controls
    window.show()
    qtbot.waitExposed(window)
    window.model.render.sample_distance = 1.0
    with qtbot.waitSignal(window.dataShown, timeout=60_000):
        window.open_path(BEADS)
    window.tf_dock.raise_()
    dock = window.tf_dock
    dock.dimension_combo.setCurrentIndex(1)
    (_v0, v1), (_g0, g1) = dock.axes_2d()
    window.model.channels[0].tf2d.primitives = [
        TFPrimitive(value_range=(40.0, v1 + 1.0), gradient_range=(0.0, g1 * 1.01),
                    color=(1.0, 0.55, 0.1), opacity=0.8, soft_edge=0.3),
        TFPrimitive(kind="triangle", value_range=(8.0, 60.0), gradient_range=(0.0, g1),
                    color=(0.2, 0.85, 1.0), opacity=0.25, soft_edge=0.4),
    ]
    dock.editor_2d.select(0)
    layer = TFPaintLayer.blank(*dock.axes_2d())
    stroke = [(float(x), float(y)) for x, y in zip(*layer.pixel_coords(
        np.array([10.0, 25.0, 38.0]), np.array([0.35, 0.55, 0.7]) * g1), strict=True)]
    window.model.channels[0].tf2d.paint = layer.with_pixels(apply_stroke(
        layer.pixels(), stroke_mask(layer.shape, stroke, 5.0), (1.0, 0.2, 0.8), 0.15))
    dock.tool_group.button(1).click()
    window.viewport.scene.orbit(-25.0, 15.0)
    qtbot.wait(100)
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "tf2d-editor.png"
    assert window.grab().save(str(path))
    window.close()
    assert _nonblank(path) > 10.0
