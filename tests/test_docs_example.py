"""docs/writing-a-technique.md builds a working technique: this test builds it from the page."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model.scene import Light
from vtkvol.model.techniques import get_spec, register

PAGE = Path(__file__).resolve().parents[1] / "docs" / "writing-a-technique.md"
BLOCK = re.compile(r"```\w+ file=(\S+)\n(.*?)```", re.S)


@pytest.fixture
def haze(tmp_path, monkeypatch):
    files = dict(BLOCK.findall(PAGE.read_text(encoding="utf-8")))
    assert sorted(files) == ["vtkvol_haze/__init__.py", "vtkvol_haze/shaders/haze.glsl",
                             "vtkvol_haze/technique.py"]
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    package = importlib.import_module("vtkvol_haze")
    with register(package.TECHNIQUE):
        yield package.TECHNIQUE
    for module in [m for m in sys.modules if m.startswith("vtkvol_haze")]:
        del sys.modules[module]


def test_declaration_is_read_without_the_engine_part(haze):
    assert get_spec("haze") is haze
    assert "vtkvol_haze.technique" not in sys.modules
    assert haze.defaults() == {"density": 0.02}


@pytest.mark.gl
def test_the_example_renders_and_its_haze_darkens_the_far_side(haze):
    arr = np.zeros((24, 24, 24), np.float32)
    arr[2:22, 2:22, 2:22] = 1.0
    rw, ren, volume = simple_volume_scene(arr, size=(96, 96), opacity=[(0.0, 0.0), (1.0, 0.05)])
    light = [Light(direction=(1.0, 0.0, 0.0))]  # from +x: the image's right side faces it
    il = Illuminator(volume, ren, method="haze", lights=light, parameters={"density": 0.0})
    errors: list[str] = []
    il.on_error = errors.append
    grab(rw)
    clear = grab(rw).astype(float)
    il.set_parameters(density=0.2)
    hazy = grab(rw).astype(float)
    assert errors == [] and il.method == "haze"
    rows = slice(30, 66)
    near, far = (slice(58, 70), 0), (slice(26, 38), 0)  # image columns: right = +x
    assert hazy[rows][:, near[0], 0].mean() > 1.5 * hazy[rows][:, far[0], 0].mean()
    assert clear[rows][:, far[0], 0].mean() > 1.3 * hazy[rows][:, far[0], 0].mean()
    il.release()
    rw.Finalize()
