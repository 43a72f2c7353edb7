"""Screenshots of the app for the documentation: ``docs/screenshots/*.png``.

The whole window twice (the two tabbed dock pairs each in front once) and every dock on its
own. Only the two whole-window images need a 3-D frame (a few seconds each on a software GL);
the dock images cost nothing. Deselect with ``-m "not screenshots"``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QSettings
from PySide6.QtGui import QImage

from vtkvol.ui.app import MainWindow, configure_gl_platform
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


def test_write_docs_screenshots(qapp, qtbot, tmp_path):
    configure_gl_platform(qapp)
    window = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(window)
    window.resize(1240, 800)
    window.show()
    qtbot.waitExposed(window)
    window.model.render.sample_distance = 1.0
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


BEADS = Path(__file__).resolve().parents[2] / "shared" / "data" / "Bead_Image1_crop.tif"


@pytest.mark.skipif(not BEADS.exists(), reason="../shared/data not present")
def test_write_tf2d_editor_screenshot_on_real_data(qapp, qtbot, tmp_path):
    """``docs/screenshots/tf2d-editor.png``: the confocal bead stack of ../shared/data
    classified in 2-D: the beads' bright cores (a rectangle over every gradient) in orange
    and their steep flanks (a triangle rising from |∇I| = 0) in cyan, over the stack's
    value × gradient histogram; the rectangle is selected."""
    from vtkvol.model.transfer_function import TFPrimitive

    configure_gl_platform(qapp)
    window = MainWindow(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(window)
    window.resize(1240, 800)
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
    window.viewport.scene.orbit(-25.0, 15.0)
    qtbot.wait(100)
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "tf2d-editor.png"
    assert window.grab().save(str(path))
    window.close()
    assert _nonblank(path) > 10.0
