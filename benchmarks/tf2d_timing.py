"""Development timing of 2-D transfer functions (not part of the installed library): table
rasterisation, the host's opacity volume in 1-D and 2-D mode, and the spatialized classes on
the bead stack of ../shared/data, for docs/transfer-functions-2d.md.

Run from the checkout: ``python benchmarks/tf2d_timing.py`` prints a markdown table (best of
three runs each; an offscreen EGL window for the host).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import vtk

from vtkvol.engine.offscreen import make_render_window
from vtkvol.engine.scene import VolumeScene
from vtkvol.io import read_volume
from vtkvol.io.volume_data import VolumeData
from vtkvol.model.classification import classes_to_tf, feature_sample, spatialized_classes
from vtkvol.model.defaults import scene_for
from vtkvol.model.gradient import gradient_axis_max
from vtkvol.model.tf_paint import TFPaintLayer, apply_stroke, stroke_mask
from vtkvol.model.transfer_function import TFPrimitive, TransferFunction2D

BEADS = Path(__file__).resolve().parents[2] / "shared" / "data" / "Bead_Image1_crop.tif"
TWO_REGIONS = TransferFunction2D(primitives=[
    TFPrimitive(value_range=(40, 157), gradient_range=(0, 700), soft_edge=0.3),
    TFPrimitive(kind="triangle", value_range=(8, 60), gradient_range=(0, 684), soft_edge=0.4),
])


def best_ms(run: Callable[[], object], repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times)


def opacity_volume_ms(n: int, mode: str) -> float:
    """The host's opacity volume of an n³ uint8 volume, recomputed (the TF changed)."""
    arr = (np.random.default_rng(0).random((n, n, n)) * 200).astype(np.uint8)
    data = VolumeData.from_array(arr[None], (1.0, 1.0, 1.0), ["a"])
    model = scene_for(data)
    window = make_render_window((64, 64))
    renderer = vtk.vtkRenderer()
    window.AddRenderer(renderer)
    scene = VolumeScene(renderer, model, data, request_render=lambda: None)
    if mode == "2d":
        model.channels[0].tf2d = TWO_REGIONS
        model.channels[0].tf_mode = "2d"
    host = scene.illuminator
    assert host is not None

    def run() -> None:
        host.opacity._opacity_cache = None
        host.opacity_volume()

    try:
        return best_ms(run)
    finally:
        scene.close()
        window.Finalize()


def main() -> None:
    layer = TFPaintLayer.blank((1, 156), (0, 684))
    layer = layer.with_pixels(apply_stroke(layer.pixels(), stroke_mask(
        layer.shape, [(20.0, 10.0), (100.0, 60.0)], 8.0), (1.0, 0.2, 0.1), 0.6))
    painted = TWO_REGIONS.model_copy(update={"paint": layer})
    stroke_points = [(20.0 + k, 10.0 + 0.5 * k) for k in range(80)]
    rows = [("rasterise a 1024 × 1024 table, 2 primitives",
             best_ms(lambda: TWO_REGIONS.table((1, 156), (0, 684), (1024, 1024)))),
            ("rasterise a 1024 × 1024 table, 2 primitives + 128² painted layer",
             best_ms(lambda: painted.table((1, 156), (0, 684), (1024, 1024)))),
            ("one brush-stroke update (80 points, radius 8 px) + encode",
             best_ms(lambda: layer.with_pixels(apply_stroke(
                 layer.pixels(), stroke_mask(layer.shape, stroke_points, 8.0),
                 (0.0, 1.0, 0.0), 0.5))))]
    for n in (64, 128):
        for mode in ("1d", "2d"):
            rows.append((f"host opacity volume, {n}³, {mode}", opacity_volume_ms(n, mode)))
    if BEADS.exists():
        data = read_volume(BEADS)
        spacing = tuple(data.voxel_size_um)
        values = data.channel_range(0)
        gradients = (0.0, gradient_axis_max(values, spacing))
        rows.append(("feature sample, bead stack",
                     best_ms(lambda: feature_sample(data.array[0], spacing))))
        sample = feature_sample(data.array[0], spacing)
        rows.append(("classes + primitives, bead stack, r = 0.2", best_ms(
            lambda: classes_to_tf(spatialized_classes(sample, values, gradients)))))
    print("| step | ms |\n|---|---|")
    for name, ms in rows:
        print(f"| {name} | {ms:.0f} |")


if __name__ == "__main__":
    main()
