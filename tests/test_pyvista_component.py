"""``plotter.vtkvol``: the PyVista plotter component, found through its entry point."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.model.scene import Light

pv = pytest.importorskip("pyvista")
pytestmark = pytest.mark.gl


def sphere_grid() -> object:
    z, y, x = np.mgrid[:32, :32, :32]
    inside = ((x - 15.5) ** 2 + (y - 15.5) ** 2 + (z - 15.5) ** 2 < 100).astype(np.float32)
    grid = pv.ImageData(dimensions=(32, 32, 32))
    grid.point_data["values"] = inside.ravel() * 200
    return grid


def right_share(img: np.ndarray) -> float:
    lum = img[..., :3].astype(float).sum(axis=2)
    half = lum.shape[1] // 2
    return float(lum[:, half:].sum() / max(lum.sum(), 1e-9))


def test_plotter_component_is_found_without_importing_vtkvol_and_lights_the_last_volume():
    # a fresh interpreter: PyVista finds the component through the entry point alone
    import subprocess
    import sys

    code = ("import pyvista as pv; p = pv.Plotter(off_screen=True); "
            "print(type(p.vtkvol).__name__, 'vtkvol.engine' in __import__('sys').modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[-2:] == ["VtkvolComponent", "True"]

    plotter = pv.Plotter(off_screen=True, window_size=(128, 128))
    plotter.set_background("black")
    plotter.add_volume(sphere_grid(), scalars="values", mapper="gpu", opacity="linear",
                       show_scalar_bar=False)
    plotter.view_xz()
    il = plotter.vtkvol.illuminate(lights=[Light(direction=(1, 0, 0))])
    first = plotter.screenshot(return_img=True)
    again = plotter.vtkvol.illuminate(lights=[Light(direction=(-1, 0, 0))])
    assert again is il and plotter.vtkvol.illuminators == [il]  # the same volume: one host
    plotter.render()
    second = plotter.screenshot(return_img=True)
    assert right_share(first) - right_share(second) > 0.15
    plotter.close()
    assert il.closed  # released with the plotter


def test_add_volume_illuminates_and_refuses_other_mappers():
    plotter = pv.Plotter(off_screen=True, window_size=(96, 96))
    actor, il = plotter.vtkvol.add_volume(sphere_grid(), scalars="values", opacity="linear",
                                          method="shadow_volume", show_scalar_bar=False,
                                          parameters={"resolution": "half"})
    assert il.volume is actor and il.method == "shadow_volume"
    assert il.parameters["resolution"] == "half"
    with pytest.raises(ValueError, match="GPU ray caster only"):
        plotter.vtkvol.add_volume(sphere_grid(), mapper="smart")
    plotter.vtkvol.release()
    assert il.closed and plotter.vtkvol.illuminators == []
    plotter.close()


def test_no_volume_is_a_clear_error():
    plotter = pv.Plotter(off_screen=True, window_size=(64, 64))
    with pytest.raises(ValueError, match="no volume to illuminate"):
        plotter.vtkvol.illuminate()
    plotter.close()
