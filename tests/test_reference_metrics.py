"""Checks of the image/volume error metrics and of the synthetic phantoms."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vtkvol.reference import (
    DirectionalLight,
    PointLight,
    image_metrics,
    phantom_groove,
    phantom_hollow_sphere,
    phantom_slab,
    phantom_sphere_over_slab,
    volume_metrics,
)


def _test_image(shape: tuple[int, ...]) -> np.ndarray:
    rng = np.random.default_rng(9)
    return rng.uniform(0.2, 0.8, shape)


@pytest.mark.parametrize("shape", [(32, 40), (32, 40, 3), (16, 20, 4)])
def test_identical_images(shape: tuple[int, ...]) -> None:
    img = _test_image(shape)
    m = image_metrics(img, img.copy())
    assert m["rmse"] == 0.0 and m["max_abs"] == 0.0
    assert m["psnr"] == math.inf
    assert m["ssim"] == pytest.approx(1.0)


def test_known_offset_float_and_uint8() -> None:
    img = _test_image((32, 32, 3))
    m = image_metrics(img + 0.1, img)
    assert m["rmse"] == pytest.approx(0.1)
    assert m["max_abs"] == pytest.approx(0.1)
    assert m["psnr"] == pytest.approx(20.0)  # 20·log10(1 / 0.1)
    assert m["ssim"] < 1.0

    u8 = (img * 255).astype(np.uint8)
    m = image_metrics(u8 + np.uint8(5), u8)
    assert m["rmse"] == pytest.approx(5.0)
    assert m["psnr"] == pytest.approx(20.0 * math.log10(255.0 / 5.0))
    # A uint8 image against a float reference is compared in [0, 1].
    m = image_metrics(u8, u8 / 255.0)
    assert m["rmse"] == pytest.approx(0.0, abs=1e-12)


def test_image_metrics_rejects_mismatched_shapes() -> None:
    with pytest.raises(ValueError):
        image_metrics(np.zeros((8, 8)), np.zeros((8, 9)))


def test_volume_metrics_with_mask() -> None:
    ref = np.zeros((4, 4, 4))
    val = ref.copy()
    val[0] = 0.5  # 16 voxels too bright
    m = volume_metrics(val, ref)
    assert m["bias"] == pytest.approx(0.5 * 16 / 64)
    assert m["mean_abs"] == pytest.approx(0.125)
    assert m["max_abs"] == pytest.approx(0.5)
    assert m["rmse"] == pytest.approx(math.sqrt(0.25 * 16 / 64))
    mask = np.zeros(ref.shape, dtype=bool)
    mask[1:] = True
    assert volume_metrics(val, ref, mask) == {"rmse": 0, "max_abs": 0, "mean_abs": 0, "bias": 0}
    with pytest.raises(ValueError):
        volume_metrics(val, ref, np.zeros(ref.shape, dtype=bool))


def test_phantoms_shapes_and_geometry() -> None:
    n = 32
    for vol in (
        phantom_sphere_over_slab(n),
        phantom_hollow_sphere(n),
        phantom_groove(n),
        phantom_groove(n, profile="u"),
        phantom_slab(n),
    ):
        assert vol.shape == (n, n, n) and vol.dtype == np.float32
        assert vol.min() >= 0.0 and vol.max() <= 1.0 and vol.max() > 0.0

    sos = phantom_sphere_over_slab(n)
    c = n // 2
    assert sos[int(0.15 * (n - 1)), 2, 2] > 0.5  # slab everywhere in x, y
    assert sos[int(0.6 * (n - 1)), c, c] > 0.8  # sphere centre
    assert sos[int(0.6 * (n - 1)), 1, 1] == 0.0  # beside the sphere
    assert sos[int(0.4 * (n - 1)), c, c] == 0.0  # gap between sphere and slab

    shell = phantom_hollow_sphere(n, thickness=3)
    assert shell[c, c, c] == 0.0 and shell[0, 0, 0] == 0.0
    assert shell[c, c, c + int(0.4 * (n - 1)) - 1] > 0.9

    groove = phantom_groove(n)
    assert groove[2, c, c] > 0.8  # below the groove's floor
    assert groove[int((n - 1) / 2) - 2, c, c] == 0.0  # inside the groove
    assert groove[int((n - 1) / 2) - 2, c, 1] > 0.8  # the block beside the groove
    assert groove[n - 2, c, 1] == 0.0  # above the block

    slab = phantom_slab(n, thickness=2, axis="x", opacity=0.5)
    assert np.count_nonzero(slab.any(axis=(0, 1))) == 2
    assert set(np.unique(slab)) == {0.0, 0.5}


def test_lights_validate() -> None:
    with pytest.raises(ValueError):
        DirectionalLight((0.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        PointLight((0.0, math.nan, 1.0))
    assert DirectionalLight((0, 0, 2)).direction == (0.0, 0.0, 2.0)


def test_reference_imports_neither_vtk_nor_qt() -> None:
    # The references must stay independent of the GPU code: numpy (and scipy/skimage) only.
    code = (
        "import sys, vtkvol.reference; "
        "bad = [m for m in sys.modules if m.split('.')[0] in "
        "('vtk', 'vtkmodules', 'pyvista', 'PySide6', 'PyQt5', 'PyQt6', 'vtkvol.engine')]; "
        "bad += [m for m in sys.modules if m.startswith(('vtkvol.engine', 'vtkvol.plugins'))]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False, env=env
    )
    assert done.returncode == 0, done.stdout + done.stderr
