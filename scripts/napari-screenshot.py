"""Write docs/screenshots/napari-dock.png: napari with vtkvol's "Illuminated render" dock and
its result (the built-in sample opened through the plugin, rendered with shadow_volume).

Run under an X server (napari needs one), from the checkout with the [napari] extra:

    xvfb-run -s "-screen 0 1400x900x24" .venv/bin/python scripts/napari-screenshot.py

The PNG is reduced to 256 colours so that it stays well under 300 KB.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import napari
import tifffile
from PIL import Image
from qtpy.QtWidgets import QApplication

from vtkvol.io import confocal_phantom
from vtkvol.napari._widget import IlluminatedRenderWidget, napari_camera

OUT = Path(__file__).resolve().parents[1] / "docs" / "screenshots" / "napari-dock.png"


def main() -> int:
    sample = confocal_phantom()
    folder = Path(tempfile.mkdtemp(prefix="vtkvol-napari-shot-"))
    path = folder / "sample.tif"
    sx, sy, sz = sample.voxel_size_um
    # ImageJ hyperstack (z, c, y, x) with the sample's voxel size, opened through the plugin.
    tifffile.imwrite(path, sample.array.transpose(1, 0, 2, 3), imagej=True,
                     resolution=(1 / sx, 1 / sy), metadata={"axes": "ZCYX", "spacing": sz,
                                                           "unit": "um"})
    viewer = napari.Viewer(show=True)
    viewer.window.resize(1300, 760)
    viewer.open(str(path), plugin="vtkvol")
    viewer.dims.ndisplay = 3
    QApplication.processEvents()  # the canvas takes its size: the view fits the volume to it
    viewer.reset_view()
    napari_camera(viewer).angles = (10.0, -30.0, 60.0)
    widget = IlluminatedRenderWidget(viewer)
    viewer.window.add_dock_widget(widget, name="Illuminated render", area="right")
    widget.method.setCurrentText("shadow_volume")
    widget.width_px.setValue(384)
    widget.height_px.setValue(384)
    widget.render()  # adds the render as an RGB layer, shown on top of the channels
    for layer in list(viewer.layers)[:-1]:
        layer.visible = False
    viewer.dims.ndisplay = 2
    viewer.reset_view()
    QApplication.processEvents()
    shot = viewer.screenshot(canvas_only=False, flash=False)
    image = Image.fromarray(shot).convert("RGB")
    image.thumbnail((1100, 1100))
    image.quantize(256).save(OUT, optimize=True)
    print(f"wrote {OUT} ({OUT.stat().st_size // 1024} KB)")
    viewer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
