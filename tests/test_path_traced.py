"""Path-traced illumination: the engine shows exactly the reference's Monte-Carlo light."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model.scene import Light
from vtkvol.plugins.path_traced import technique
from vtkvol.plugins.path_traced.technique import DIRECT_UNIFORM, SCATTERED_UNIFORM
from vtkvol.reference import DirectionalLight, inscattered_mc, transmittance

pytestmark = pytest.mark.gl


def cube() -> np.ndarray:
    arr = np.zeros((14, 14, 14), np.float32)
    arr[4:10, 4:10, 4:10] = 1.0
    return arr


def scene(**params):
    rw, ren, volume = simple_volume_scene(cube(), size=(48, 48),
                                          opacity=[(0.0, 0.0), (1.0, 0.4)])
    il = Illuminator(volume, ren, method="path_traced",
                     lights=[Light(direction=(0.0, 0.0, 1.0), color=(1.0, 0.5, 0.25))],
                     parameters={"max_iterations": 2, "paths_per_iteration": 3, **params})
    il.set_material(albedo=0.8, phase_g=0.3)
    return rw, ren, il


def textures(il: Illuminator) -> dict[str, np.ndarray]:
    il.renderer.GetRenderWindow().MakeCurrent()
    return {name: tex.download(0) for name, tex in il.bound_textures().items()}


def test_direct_and_scattered_light_are_the_references_own():
    rw, _, il = scene()
    il.converge(max_frames=50)
    assert il.technique.converged and il.technique.iteration == 2
    got = textures(il)
    alpha = il.opacity_volume()
    up = DirectionalLight((0.0, 0.0, 1.0))
    exact = transmittance(alpha, (1, 1, 1), up, unit_distance=1.0, step=0.5)
    np.testing.assert_allclose(got[DIRECT_UNIFORM], exact, atol=1e-5)
    # the running mean of two iterations of three paths each, seeded per iteration
    zyx = np.array([[7, 7, 7], [5, 8, 6], [9, 4, 4]])
    pts = zyx[:, ::-1].astype(float)
    runs = [inscattered_mc(alpha, (1, 1, 1), up, albedo=0.8, phase_g=0.3, n_paths=3,
                           seed=technique.SEED_BASE + k,
                           unit_distance=1.0, max_bounces=32, points=pts,
                           light_colors=[(1.0, 0.5, 0.25)]) for k in (0, 1)]
    expected = (runs[0] + runs[1]) / 2
    scattered = got[SCATTERED_UNIFORM][tuple(zyx.T)][:, :3]
    np.testing.assert_allclose(scattered, expected, rtol=1e-4, atol=1e-6)
    assert scattered[0, 0] > 0.05 and np.allclose(scattered[:, 1], scattered[:, 0] / 2, rtol=1e-4)
    il.release()
    rw.Finalize()


def test_camera_moves_keep_it_light_moves_restart_it_and_it_brightens_the_image(monkeypatch):
    # The frame budget, made independent of this machine's speed: a clock that advances 15 ms
    # a reading and 128 voxels a call, so each frame traces exactly one call within its 20 ms
    # and the 512 voxels' two iterations take 8 frames.
    readings = iter(np.arange(0.0, 1e6, 0.015))
    monkeypatch.setattr(technique, "time", SimpleNamespace(perf_counter=lambda: next(readings)))
    monkeypatch.setattr(technique, "CHUNK", 128)
    rw, ren, il = scene(frame_budget_ms=20)
    single_rw, _, single = scene(scattering="single")
    single.converge(max_frames=5)
    assert single.technique.converged and single.technique.iteration == 0
    dark = grab(single_rw).astype(float)
    frames = il.converge(max_frames=100)
    assert frames == 8 and il.technique.iteration == 2  # progressive within the budget
    bright = grab(rw).astype(float)
    assert bright.mean() > dark.mean() + 1.0  # in-scattered light adds to the direct light
    ren.GetActiveCamera().Azimuth(35)
    grab(rw)
    assert il.technique.stats()["recomputes"] == 1 and il.technique.iteration == 2
    il.set_lights([Light(direction=(1.0, 0.0, 0.0))])
    grab(rw)
    assert il.technique.stats()["recomputes"] == 2
    for ill, window in ((il, rw), (single, single_rw)):
        ill.release()
        window.Finalize()


def test_a_volume_too_large_falls_back_to_local_shading_with_a_message(monkeypatch):
    monkeypatch.setattr(technique, "MAX_VOXELS", 1000)
    rw, _, il = scene()
    errors: list[str] = []
    il.on_error = errors.append
    grab(rw)
    assert il.method == "local" and il.failed_method == "path_traced"
    assert len(errors) == 1 and "at most 1,000 voxels" in errors[0] and "14×14×14" in errors[0]
    il.release()
    rw.Finalize()
