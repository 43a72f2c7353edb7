"""The plugin API is a Protocol: a technique runs against any object with TechniqueHost's
members, and the engine's technique module does not import the host (no import circle)."""

from __future__ import annotations

import ast
import pathlib
from collections.abc import Generator
from typing import Any

import numpy as np
import pytest
import vtk

from vtkvol.engine.technique import Changes, LightSpec, TechniqueHost, scale_steps

ROOT = pathlib.Path(__file__).resolve().parents[1]


class FakeHost:
    """The smallest TechniqueHost: a 12×10×8 image of 2 µm voxels, one light, no GL."""

    render_window = None
    profiling = False
    work_budget_ms = None

    def __init__(self, opacity: np.ndarray, light: LightSpec) -> None:
        self._opacity = opacity
        self._light = light
        self.bound: dict[str, Any] = {}
        self.image = vtk.vtkImageData()
        nz, ny, nx = opacity.shape
        self.image.SetDimensions(nx, ny, nz)
        self.image.SetSpacing(2.0, 2.0, 2.0)
        self.volume = vtk.vtkVolume()

    dims = property(lambda self: self.image.GetDimensions())
    spacing = property(lambda self: self.image.GetSpacing())
    unit_distance = 2.0
    albedo = 1.0
    phase_g = 0.0
    shaded = True
    precomputing = False

    def light_specs(self) -> list[LightSpec]:
        return [self._light]

    def opacity_volume(self) -> np.ndarray:
        return self._opacity

    def opacity_volume_steps(self) -> Generator[float, None, np.ndarray]:
        yield 1.0
        return self._opacity

    def opacity_texture_steps(self, quantity: str = "alpha") -> Generator[float, None, Any]:
        raise AssertionError("the CPU path must not ask for a GPU texture")
        yield 0.0

    def classify_2d(self, c: int, what: str = "alpha") -> np.ndarray | None:
        return None

    def bind_texture(self, uniform: str, texture: Any, sampler: str = "sampler3D") -> None:
        self.bound[uniform] = texture

    def unbind_texture(self, uniform: str) -> None:
        self.bound.pop(uniform, None)


def test_shadow_volume_runs_against_a_fake_host() -> None:
    """The shadow volume's CPU visibility and its shader defines need nothing but the
    Protocol: a slab of opacity 1 per µm at x = 4…5 shadows what lies behind it (light from
    +x) and nothing in front of it."""
    from vtkvol.plugins.shadow_volume.technique import ShadowVolume

    opacity = np.zeros((8, 10, 12), np.float32)
    opacity[:, :, 4:6] = 1.0
    light = LightSpec("directional", (1.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    host = FakeHost(opacity, light)
    assert isinstance(host, TechniqueHost)
    tech = ShadowVolume(host)  # type: ignore[arg-type]
    assert tech.shader_defines({}) == {"VV_SV_POINT_LIGHTS": "0"}
    vis = tech.light_visibility_cpu(opacity, host.spacing, light,
                                    {"resolution": "full", "backend": "cpu"})
    assert vis.shape == opacity.shape
    lit, shadowed = float(vis[:, :, 8:].mean()), float(vis[:, :, :3].mean())
    assert lit > 0.95, lit
    assert shadowed < 0.05, shadowed


def test_changes_and_steps_live_with_the_technique_contract() -> None:
    merged = Changes(opacity=True).merge(Changes(parameters={"softness"}))
    assert merged.opacity and merged.parameters == {"softness"} and not merged.lights

    def work() -> Generator[float, None, str]:
        yield 0.5
        yield 1.0
        return "done"

    steps = scale_steps(work(), 0.2, 0.4)
    assert [next(steps), next(steps)] == pytest.approx([0.3, 0.4])
    try:
        next(steps)
    except StopIteration as stop:
        assert stop.value == "done"
    else:
        raise AssertionError("scale_steps yielded past its steps")


def test_technique_module_does_not_import_the_host() -> None:
    """engine/technique.py imports no illuminator, not even for typing: the illuminator imports
    the contract, never the other way round."""
    tree = ast.parse((ROOT / "vtkvol/engine/technique.py").read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not any("illuminator" in (m or "") for m in imported), imported
