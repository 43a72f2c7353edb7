"""Issue 25 §3: the colour legend's title overlapped its top value, and after reopening a
session its numbers were drawn over the bars. Checked on geometry: the boxes VTK draws the
title and the labels in (``vtkTextActor.GetBoundingBox`` after a frame) and the bar's box
(its polygon's points) do not intersect, for one to three channels, small and large frames
and short and long numbers; and in the app after a session is saved and reopened (needs GL;
the app part needs X through pytest-xvfb)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import vtk

from vtkvol.engine.offscreen import grab, make_render_window
from vtkvol.engine.overlays import SceneOverlays
from vtkvol.model.scene import Overlays

Box = tuple[float, float, float, float]  # xmin, xmax, ymin, ymax (display pixels)


def text_box(actor: vtk.vtkTextActor, renderer: vtk.vtkRenderer) -> Box:
    """Where VTK draws the text: its bounding box (relative to the actor's anchor, as
    ``GetBoundingBox`` gives it) moved to the anchor's display position."""
    bbox = [0.0, 0.0, 0.0, 0.0]
    actor.GetBoundingBox(renderer, bbox)
    x, y = actor.GetPositionCoordinate().GetComputedDisplayValue(renderer)
    return (bbox[0] + x, bbox[1] + x, bbox[2] + y, bbox[3] + y)


def bar_box(legend, width: int, height: int) -> Box:
    """The bar's drawn box from its polygon's points (normalised viewport → pixels)."""
    points = legend.bar.GetMapper().GetInput().GetPoints()
    xy = np.array([points.GetPoint(i)[:2] for i in range(points.GetNumberOfPoints())])
    return (xy[:, 0].min() * width, xy[:, 0].max() * width,
            xy[:, 1].min() * height, xy[:, 1].max() * height)


def overlap(a: Box, b: Box) -> bool:
    """Whether two boxes share more than their edges."""
    return min(a[1], b[1]) > max(a[0], b[0]) and min(a[3], b[3]) > max(a[2], b[2])


def legend_parts(overlays: SceneOverlays, renderer: vtk.vtkRenderer, width: int,
                 height: int) -> list[tuple[str, Box]]:
    parts = []
    for k, legend in enumerate(overlays.legends):
        parts.append((f"{k}:title", text_box(legend.title, renderer)))
        for j, label in enumerate(legend.labels):
            parts.append((f"{k}:label{j}", text_box(label, renderer)))
        parts.append((f"{k}:bar", bar_box(legend, width, height)))
    return parts


def assert_apart(parts: list[tuple[str, Box]], width: int, height: int) -> None:
    for (name_a, a), (name_b, b) in itertools.combinations(parts, 2):
        assert not overlap(a, b), f"{name_a} {a} overlaps {name_b} {b}"
    for name, (x0, x1, y0, y1) in parts:
        assert x0 >= 0 and y0 >= 0 and x1 <= width and y1 <= height, f"{name} leaves the frame"
        assert x1 > x0 and y1 > y0, f"{name} is empty"


def lut(lo: float, hi: float) -> vtk.vtkColorTransferFunction:
    f = vtk.vtkColorTransferFunction()
    f.AddRGBPoint(lo, 0.0, 0.0, 0.0)
    f.AddRGBPoint(hi, 0.2, 1.0, 0.4)
    return f


@pytest.mark.parametrize(("size", "channels"), [
    ((256, 256), [("DAPI", (0.0, 4095.0))]),
    ((256, 160), [("nuclei (DAPI)", (0.0, 65535.0)), ("membrane", (-1.5e-05, 0.25))]),
    ((200, 256), [("a", (100.0, 900.0)), ("b", (0.0, 1.0)), ("cells", (0.0, 65535.0))]),
    ((256, 120), [("GFP", (12.0, 3.2e4))]),
])
def test_legend_title_labels_and_bars_do_not_overlap(size, channels):
    width, height = size
    window = make_render_window(size)
    renderer = vtk.vtkRenderer()
    window.AddRenderer(renderer)
    overlays = SceneOverlays(renderer)
    try:
        overlays.set_legend_channels([(name, lut(*span)) for name, span in channels])
        overlays.apply(Overlays(color_legend=True, scale_bar=True))
        window.Render()
        assert len(overlays.legends) == len(channels)
        parts = legend_parts(overlays, renderer, width, height)
        assert_apart(parts, width, height)
        # The labels say the colour function's span; the top one sits above the bottom one.
        for legend, (_, (lo, hi)) in zip(overlays.legends, channels, strict=True):
            assert [a.GetInput() for a in legend.labels] == [
                f"{lo:.4g}", f"{(lo + hi) / 2:.4g}", f"{hi:.4g}"]
            low, top = (text_box(legend.labels[i], renderer) for i in (0, 2))
            assert top[2] > low[3]
            title = text_box(legend.title, renderer)
            assert title[2] >= top[3]  # the title above the top value, not on it
    finally:
        overlays.close()
        window.Finalize()


def test_the_parts_drawn_alone_share_no_pixel():
    """The same on the pixels: each part rendered alone; no pixel is lit by two parts."""
    window = make_render_window((256, 200))
    renderer = vtk.vtkRenderer()
    window.AddRenderer(renderer)
    overlays = SceneOverlays(renderer)
    try:
        overlays.set_legend_channels([("nuclei (DAPI)", lut(0.0, 65535.0)),
                                      ("membrane", lut(-1.5e-05, 0.25))])
        overlays.apply(Overlays(color_legend=True))
        props = [p for legend in overlays.legends for p in legend.props]
        masks = []
        for prop in props:
            for other in props:
                other.SetVisibility(int(other is prop))
            masks.append(grab(window).max(axis=-1) > 30)
        assert all(m.sum() > 3 for m in masks)
        for (i, a), (j, b) in itertools.combinations(enumerate(masks), 2):
            assert not np.any(a & b), f"parts {i} and {j} share pixels"
    finally:
        overlays.close()
        window.Finalize()


def test_the_bar_shows_the_colour_function():
    window = make_render_window((256, 256))
    renderer = vtk.vtkRenderer()
    window.AddRenderer(renderer)
    overlays = SceneOverlays(renderer)
    f = lut(0.0, 100.0)
    try:
        overlays.set_legend_channels([("ch", f)])
        overlays.apply(Overlays(color_legend=True))
        window.Render()
        [legend] = overlays.legends
        colors = legend.bar.GetMapper().GetInput().GetCellData().GetScalars()
        first, last = colors.GetTuple3(0), colors.GetTuple3(colors.GetNumberOfTuples() - 1)
        assert first[1] < 10 and last[1] > 240  # dark at the low end, green at the top
        f.AddRGBPoint(100.0, 1.0, 0.0, 0.0)  # edited in place: the next frame shows it
        window.Render()
        last = colors.GetTuple3(colors.GetNumberOfTuples() - 1)
        assert last[0] > 240 and last[1] < 10
    finally:
        overlays.close()
        window.Finalize()


@pytest.mark.gui
def test_legend_apart_after_reopening_a_session(opened_window, qtbot, tmp_path, dialogs):
    window = opened_window
    model = window.model
    model.overlays.update({"color_legend": True, "scale_bar": True})
    model.channels[0].name = "nuclei (DAPI)"
    path = tmp_path / "legend.vtkvol.json"
    assert window.save_session(path) == path
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_session(path)
    assert dialogs == []
    viewport = window.viewport
    viewport.render_now()
    overlays = viewport.scene.overlays
    renderer = viewport.renderer
    width, height = renderer.GetSize()
    assert [legend.name for legend in overlays.legends] == ["nuclei (DAPI)"]
    assert_apart(legend_parts(overlays, renderer, width, height), width, height)
    model.overlays.update({"color_legend": False, "scale_bar": False})
