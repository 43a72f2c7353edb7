"""Precomputation in chunks outside a frame (``Illuminator.precompute``,
``Technique.prepare_steps``) and deferred precomputation (``defer_precompute``): the chunked
result equals the one a frame computes, Cancel leaves local shading with nothing of the
technique bound, and deferred changes are caught up exactly once."""

from __future__ import annotations

import numpy as np
import pytest
from test_shadow_volume import _agreement_scene, _light_volume, _require_compute

from vtkvol.engine import light_grid as sv
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab
from vtkvol.model import Light

pytestmark = pytest.mark.gl


def _cpu_reference(il: Illuminator) -> np.ndarray:
    values = il.parameters
    grid = sv.LightGrid.for_data(il.dims, il.spacing, values["resolution"])
    spec = il.light_specs()[0]
    return sv.light_volume_cpu(il.opacity_volume(), il.spacing, spec,
                               unit_distance=il.unit_distance, model=values["model"],
                               resolution=values["resolution"],
                               softness=sv.light_softness(spec, grid, values))


def test_chunked_shadow_volume_equals_the_reference_and_the_frame_adds_nothing():
    rw, ren, volume = _agreement_scene()
    il = Illuminator(volume, ren, method="shadow_volume", lights=[Light(direction=(0.2, 0.3, 1))])
    try:
        rw.Render()
        _require_compute(rw)
        before = il.technique.stats()["recomputes"]
        il.set_lights([Light(direction=(1.0, 0.2, 0.3))])  # sweeps along x: 26 slices
        fractions: list[float] = []
        assert il.precompute(lambda f: fractions.append(f) or True)
        assert len(fractions) >= 3, fractions  # several chunks, the event loop between them
        assert fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)
        assert il.technique.stats()["recomputes"] == before + 1
        np.testing.assert_allclose(_light_volume(il)[..., 0], _cpu_reference(il), atol=1e-4)
        rw.Render()  # the frame finds nothing left to compute
        assert il.technique.stats()["recomputes"] == before + 1
        assert il.precompute(lambda f: pytest.fail("nothing changed: no chunk"))
    finally:
        il.release()


def test_cancel_shows_local_shading_with_nothing_of_the_technique_left():
    rw, ren, volume = _agreement_scene()
    lights = [Light(direction=(1.0, 0.2, 0.3))]
    local = Illuminator(volume, ren, method="local", lights=lights)
    rw.Render()
    local_image = grab(rw)
    assert local_image.max() > 30  # something is drawn: the comparison below can fail
    local.release()
    il = Illuminator(volume, ren, method="local", lights=lights)
    try:
        rw.Render()
        _require_compute(rw)
        il.set_method("shadow_volume")
        calls: list[float] = []
        assert not il.precompute(lambda f: calls.append(f) or len(calls) < 2)
        assert len(calls) == 2 and calls[-1] < 1.0
        assert il.method == "local" and il.cancelled_method == "shadow_volume"
        assert il.failed_method is None  # not a failure: choosing it again just computes it
        assert il.bound_textures() == {}
        rw.Render()
        assert np.abs(grab(rw).astype(float) - local_image.astype(float)).max() <= 2.0
        il.set_method("shadow_volume")
        assert il.precompute(lambda f: True)
        assert il.cancelled_method is None and il.technique.stats()["recomputes"] == 1
    finally:
        il.release()


def test_deferred_changes_keep_the_previous_light_and_are_caught_up_once():
    rw, ren, volume = _agreement_scene()
    il = Illuminator(volume, ren, method="shadow_volume", lights=[Light(direction=(0.2, 0.3, 1))])
    try:
        rw.Render()
        first = _light_volume(il).copy()
        recomputes = il.technique.stats()["recomputes"]
        il.defer_precompute = True
        il.set_lights([Light(direction=(1.0, 0.2, 0.3))])
        rw.Render()
        rw.Render()
        assert il.technique.stats()["recomputes"] == recomputes
        np.testing.assert_array_equal(_light_volume(il), first)  # the previous light stays
        assert il.has_pending_changes
        assert il.precompute(lambda f: pytest.fail("deferred: no chunk"))
        il.defer_precompute = False
        rw.Render()
        assert il.technique.stats()["recomputes"] == recomputes + 1
        assert not il.has_pending_changes
        np.testing.assert_allclose(_light_volume(il)[..., 0], _cpu_reference(il), atol=1e-4)
        # A change of the shader is never deferred (the old textures would not fit it).
        il.defer_precompute = True
        il.set_method("cone_traced")
        rw.Render()
        assert il.technique.NAME == "cone_traced" and il.technique.stats()["recomputes"] == 1
    finally:
        il.release()


def test_chunked_cone_traced_bake_equals_the_one_dispatch_bake():
    def baked(chunked: bool) -> np.ndarray:
        rw, ren, volume = _agreement_scene()
        il = Illuminator(volume, ren, method="local",
                         parameters=None, lights=[Light(direction=(0.2, 0.3, 1))])
        try:
            rw.Render()
            _require_compute(rw)
            il.set_method("cone_traced", {"ao_mode": "baked_hemisphere"})
            if chunked:
                fractions: list[float] = []
                assert il.precompute(lambda f: fractions.append(f) or True)
                assert len(fractions) >= 3 and fractions[-1] == pytest.approx(1.0)
            else:
                rw.Render()
            rw.MakeCurrent()
            assert il.technique.stats()["bake_backend"] == "gpu"
            return il.technique.ao.download().copy()
        finally:
            il.release()

    whole, chunks = baked(False), baked(True)
    assert whole.std() > 0.01  # the AO varies: the comparison can fail
    np.testing.assert_allclose(chunks, whole, atol=1e-6)
