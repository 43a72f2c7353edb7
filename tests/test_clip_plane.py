"""The oblique clipping plane: the model's plane cuts the volume, and what it cuts away casts
no shadow; the app's View → Clipping plane and its draggable widget edit the model."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

from vtkvol.engine.offscreen import grab, make_render_window
from vtkvol.engine.scene import VolumeScene
from vtkvol.io import VolumeData
from vtkvol.model.defaults import scene_for
from vtkvol.model.scene import ClipPlane, Light


def block_over_floor() -> VolumeData:
    """A 12×12×4-voxel block floating over a floor slab, 24³ voxels of 1 µm."""
    arr = np.zeros((1, 24, 24, 24), np.float32)
    arr[0, 1:4, 2:22, 2:22] = 1.0  # floor, z 1..3
    arr[0, 14:18, 6:18, 6:18] = 1.0  # block, z 14..17
    return VolumeData.from_array(arr, (1.0, 1.0, 1.0), ["density"])


def make_scene(method: str = "local"):
    data = block_over_floor()
    model = scene_for(data)
    model.channels[0].tf.opacity = [(0.0, 0.0), (1.0, 0.8)]
    model.lights = [Light(direction=(0.0, 0.0, 1.0))]
    model.illumination.method = method
    rw = make_render_window((96, 96))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    scene = VolumeScene(ren, model, data, request_render=lambda: None)
    return rw, ren, scene, model


def material(image: np.ndarray) -> np.ndarray:
    """Pixels that show the volume, not the dark background (per image row)."""
    return (image.astype(float).sum(axis=2) > 150).sum(axis=1)


@pytest.mark.gl
def test_the_plane_keeps_the_side_its_normal_points_to():
    rw, _, scene, model = make_scene()
    scene.reset_camera(azimuth=0.0, elevation=0.0)  # looking along +y, z up
    rows = material(grab(rw))
    top, bottom = rows[:48].sum(), rows[48:].sum()  # image rows: top = the block (high z)
    assert top > 50 and bottom > 50
    model.clip_plane = ClipPlane(enabled=True, origin=(11.5, 11.5, 9.0), normal=(0.0, 0.0, 1.0))
    cut = material(grab(rw))
    assert scene.mapper.GetClippingPlanes().GetNumberOfItems() == 1
    assert cut[48:].sum() == 0  # the floor (below the plane) is gone
    assert cut[:48].sum() > 0.8 * top  # the block (above it) stays
    model.clip_plane.enabled = False
    planes = scene.mapper.GetClippingPlanes()
    assert planes is None or planes.GetNumberOfItems() == 0
    assert abs(int(material(grab(rw)).sum()) - int(rows.sum())) <= 0.02 * rows.sum()
    scene.close()
    rw.Finalize()


@pytest.mark.gl
def test_what_the_plane_cuts_away_casts_no_shadow():
    rw, _, scene, model = make_scene("shadow_volume")
    grab(rw)
    il = scene.illuminator

    def floor_light() -> tuple[float, float]:
        """Light reaching the floor's top layer under the block, and away from it."""
        vis = il.technique.light_visibility_cpu(il.opacity_volume(), il.spacing,
                                                il.light_specs()[0], il.parameters)
        return float(vis[3, 9:15, 9:15].mean()), float(vis[3, 3:5, 3:5].mean())

    under, open_floor = floor_light()
    assert under < 0.5 * open_floor  # the block shadows the floor
    # cut the block away (keep what lies below z = 10 µm)
    model.clip_plane = ClipPlane(enabled=True, origin=(11.5, 11.5, 10.0),
                                 normal=(0.0, 0.0, -1.0))
    grab(rw)
    alpha = il.opacity_volume()
    assert alpha[14:18].max() == 0.0 and alpha[1:4].max() > 0.5  # what techniques read
    under, open_floor = floor_light()
    assert under == pytest.approx(open_floor, abs=0.02)  # no shadow left
    scene.close()
    rw.Finalize()


def test_the_model_normalises_the_normal_and_refuses_a_zero_or_nan_one():
    assert ClipPlane(normal=(0.0, 3.0, 4.0)).normal == pytest.approx((0.0, 0.6, 0.8))
    for bad in ((0.0, 0.0, 0.0), (float("nan"), 0.0, 1.0)):
        with pytest.raises(ValueError, match="normal"):
            ClipPlane(normal=bad)
    with pytest.raises(ValueError, match="origin"):
        ClipPlane(origin=(0.0, float("inf"), 0.0))


@pytest.mark.gui
def test_view_menu_and_plane_widget_edit_the_model_both_ways(opened_window, qtbot):
    window = opened_window
    viewport = window.viewport
    action = window.view_actions.clip_action
    model = window.model
    try:
        viewport.render_now()
        before = viewport.screenshot().astype(float)
        # widget → model → pixels: ticking the action turns the plane on, the widget shows
        action.trigger()
        assert model.clip_plane.enabled and viewport.clip_widget.visible
        assert viewport.scene.mapper.GetClippingPlanes().GetNumberOfItems() == 1
        # a drag of the widget ends: its plane goes into the model in one edit
        b = viewport.bounds
        centre = ((b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2)
        rep = viewport.clip_widget.representation
        rep.SetNormal(1.0, 0.0, 0.0)
        rep.SetOrigin(*centre)
        viewport.clip_widget.widget.InvokeEvent(vtk.vtkCommand.EndInteractionEvent)
        assert model.clip_plane.normal == pytest.approx((1.0, 0.0, 0.0))
        assert model.clip_plane.origin == pytest.approx(centre)
        viewport.render_now()
        cut = viewport.screenshot().astype(float)
        assert np.abs(cut - before).max(axis=-1).mean() > 2.0  # half the data is gone
        window.undo_action.trigger()
        assert model.clip_plane.origin is None  # one undo step restores the plane before
        # model → widget and action: a session or undo switches it off
        model.clip_plane.enabled = False
        assert not action.isChecked() and not viewport.clip_widget.visible
        model.clip_plane.enabled = True
        assert action.isChecked() and viewport.clip_widget.visible
        plane = viewport.scene.mapper.GetClippingPlanes().GetItem(0)
        assert plane.GetNormal() == pytest.approx(model.clip_plane.normal)
    finally:
        model.clip_plane = ClipPlane()
        window.recorder.reset()
