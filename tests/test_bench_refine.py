"""Issue 23: the reference refinements moved from benchmarks/two_truths_bias.py into
vtkvol.bench.refine (2× grid of the same trilinear medium, pixel box filter)."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.bench.refine import box_filter, refined_scene
from vtkvol.bench.scenes import phantom_scenes


def _scene(name: str):
    return next(s for s in phantom_scenes(16) if s.name == name)


def test_refined_scene_is_the_same_trilinear_medium_on_a_2x_grid() -> None:
    base = _scene("sphere_over_slab")
    fine = refined_scene(base)
    n = base.data.shape
    assert fine.data.shape == tuple(2 * k - 1 for k in n)
    assert fine.spacing == tuple(s / 2 for s in base.spacing)
    # Same box in world coordinates, same optical depth per world length.
    assert np.allclose(np.subtract(fine.data.shape, 1) * np.array(fine.spacing[::-1]),
                       np.subtract(n, 1) * np.array(base.spacing[::-1]))
    assert fine.unit_distance == base.unit_distance
    # Original points kept; new points on an edge are the midpoints (trilinear interpolant).
    assert np.allclose(fine.data[::2, ::2, ::2], base.data, atol=1e-6)
    mid = (base.data[:-1].astype(np.float64) + base.data[1:]) / 2
    assert np.allclose(fine.data[1::2, ::2, ::2], mid, atol=1e-6)


def test_refined_scene_refines_the_data_of_a_non_identity_transfer_function() -> None:
    """cells: the TF is kept and the data refined (post-classified renderers interpolate the
    data, then classify); before issue 23's refined reference this was refused."""
    base = _scene("cells")
    fine = refined_scene(base)
    assert fine.opacity_points == base.opacity_points
    assert np.allclose(fine.data[::2, ::2, ::2], base.data, atol=1e-4)
    mid = (base.data[:, :, :-1].astype(np.float64) + base.data[:, :, 1:]) / 2
    assert np.allclose(fine.data[::2, ::2, 1::2], mid, atol=1e-4)


def test_box_filter_averages_blocks() -> None:
    img = np.arange(4 * 6 * 3, dtype=np.float64).reshape(4, 6, 3)
    out = box_filter(img, 2)
    assert out.shape == (2, 3, 3)
    assert np.allclose(out[1, 2], img[2:4, 4:6].mean(axis=(0, 1)))
    with pytest.raises(ValueError, match="not a multiple of the factor 4"):
        box_filter(img, 4)
