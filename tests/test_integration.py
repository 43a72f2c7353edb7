"""The one-call integration with existing pipelines: plain VTK and PyVista (GL)."""

from __future__ import annotations

import numpy as np
import pytest
import vtk

import vtkvol
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model import Light

pytestmark = pytest.mark.gl


def sphere(n: int = 32, radius: float = 9.0) -> np.ndarray:
    z, y, x = np.indices((n, n, n)) - (n - 1) / 2
    return (np.sqrt(x * x + y * y + z * z) <= radius).astype(np.float32)


def right_share(img: np.ndarray) -> float:
    fg = img.astype(float).sum(axis=2)
    return fg[:, img.shape[1] // 2 :].sum() / fg.sum()


def test_plain_vtk_script_gets_vtkvol_lighting():
    rw, ren, volume = simple_volume_scene(sphere(), size=(128, 128))
    before = grab(rw)  # VTK's own headlight shading
    il = vtkvol.illuminate(volume, ren, method="local", lights=[Light(direction=(1, 0, 0))])
    lit_right = grab(rw)
    il.set_lights([Light(direction=(-1, 0, 0))])
    lit_left = grab(rw)
    grab(rw)
    assert "vv_shade" in il.fragment_source
    assert right_share(lit_right) > 0.6 > 0.4 > right_share(lit_left)
    il.release()
    after = grab(rw)
    grab(rw)
    # Released: VTK's own shading again, exactly as before.
    assert np.abs(after.astype(int) - before.astype(int)).max() <= 1
    rw.Finalize()


def test_pyvista_add_volume_gets_vtkvol_lighting():
    pv = pytest.importorskip("pyvista")
    grid = pv.ImageData(dimensions=(32, 32, 32))
    grid.point_data["values"] = sphere().ravel() * 200
    plotter = pv.Plotter(off_screen=True, window_size=(128, 128))
    plotter.set_background("black")
    actor = plotter.add_volume(grid, scalars="values", mapper="gpu", opacity="linear",
                               show_scalar_bar=False)
    plotter.view_xz()
    il = vtkvol.illuminate(actor, plotter, lights=[Light(direction=(1, 0, 0))])
    first = plotter.screenshot(return_img=True)
    il.set_lights([Light(direction=(-1, 0, 0))])
    plotter.render()
    second = plotter.screenshot(return_img=True)
    assert il.method == "local"
    assert right_share(first[..., :3]) - right_share(second[..., :3]) > 0.15
    il.release()
    plotter.close()


def test_illuminate_refuses_cpu_mappers_and_unknown_methods():
    volume = vtk.vtkVolume()
    volume.SetMapper(vtk.vtkFixedPointVolumeRayCastMapper())
    with pytest.raises(TypeError, match="GPU ray-cast mapper"):
        vtkvol.illuminate(volume, vtk.vtkRenderer())
    rw, ren, vol = simple_volume_scene(sphere(8, 3.0), size=(32, 32))
    with pytest.raises(ValueError, match=r"unknown illumination method 'nope'; available: .*local"):
        vtkvol.illuminate(vol, ren, method="nope")
    with pytest.raises(TypeError, match="vtkRenderer or a PyVista Plotter"):
        vtkvol.illuminate(vol, object())
    rw.Finalize()


def test_foreign_tf_edits_are_picked_up():
    """A TF edit made directly on the VTK objects invalidates precomputed light."""
    rw, ren, volume = simple_volume_scene(sphere(16, 5.0), size=(64, 64))
    il = vtkvol.illuminate(volume, ren)
    grab(rw)
    before = il.opacity_volume().copy()
    otf = volume.GetProperty().GetScalarOpacity(0)
    otf.RemoveAllPoints()
    otf.AddPoint(0.0, 0.0)
    otf.AddPoint(1.0, 0.25)
    grab(rw)
    after = il.opacity_volume()
    assert before.max() == pytest.approx(1.0) and after.max() == pytest.approx(0.25)
    il.release()
    rw.Finalize()
