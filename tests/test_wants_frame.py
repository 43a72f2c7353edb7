"""``Illuminator.wants_frame`` after a parameter change of a converged progressive technique."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.gl


def test_a_parameter_change_after_convergence_wants_frames_until_it_converges_again():
    """The bench rig refines while ``wants_frame`` (``Rig.refine``); a parameter set on a
    converged technique used to leave its ``converged`` flag stale until the next frame, so
    the rig measured the new setting after one frame of iterations (found by issue 24's
    traced-orders test: 2 of 256 samples)."""
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import simple_volume_scene
    from vtkvol.model.scene import Light

    arr = np.zeros((12, 12, 12), np.float32)
    arr[3:9, 3:9, 3:9] = 1.0
    rw, ren, volume = simple_volume_scene(arr, size=(32, 32), opacity=[(0.0, 0.0), (1.0, 0.3)])
    il = Illuminator(volume, ren, method="hybrid_diffusion", lights=[Light()],
                     parameters={"max_iterations": 4, "iterations_per_frame": 2})
    try:
        il.converge(max_seconds=60.0)
        assert il.technique.converged and not il.wants_frame
        il.set_parameters(seed=5)
        assert il.wants_frame  # the accumulation will restart: not final
        il.converge(max_seconds=60.0)
        assert il.technique.converged and il.technique.iteration == 4
        assert not il.wants_frame
    finally:
        il.release()
        rw.Finalize()
