"""The technique registry and declarations (no VTK, no GL)."""

from __future__ import annotations

import importlib.metadata
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import tomllib

from vtkvol.model import techniques
from vtkvol.model.params import Invalidates, Param
from vtkvol.model.techniques import BenchSetting, TechniqueSpec, get_spec, register

ROOT = Path(__file__).resolve().parents[1]


def spec(**overrides) -> TechniqueSpec:
    fields = {"name": "demo", "label": "Demo", "engine": "somewhere.demo:Demo"}
    return TechniqueSpec(**{**fields, **overrides})


def test_entry_points_name_every_plugin_package_and_nothing_else():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    entry_points = declared["project"]["entry-points"]["vtkvol.techniques"]
    packages = sorted(p.parent.name for p in (ROOT / "plugins").glob("*/__init__.py"))
    assert sorted(entry_points) == packages
    for name, target in entry_points.items():
        assert target == f"vtkvol.plugins.{name}:TECHNIQUE"
    installed = {ep.name: ep.value for ep in importlib.metadata.entry_points(
        group=techniques.ENTRY_POINT_GROUP)}
    assert installed == entry_points, "reinstall: pip install -e ."
    assert sorted(techniques.technique_specs()) == packages


def test_every_declaration_is_sane():
    for name, s in techniques.technique_specs().items():
        assert s.name == name and s.label and s.description
        assert s.engine.startswith(f"vtkvol.plugins.{name}.")
        for p in s.parameters:
            assert p.doc and p.label
            assert p.validate(p.default) == p.default
            if p.kind in ("float", "int"):
                assert p.range is not None and p.range[0] <= p.default <= p.range[1]
            assert p.applies(s.defaults()) in (True, False)
        for setting in (*s.bench, *s.stability):
            s.validate(setting.values)  # raises on a typo


def test_reading_declarations_and_sessions_loads_no_vtk():
    code = (
        "import sys\n"
        "from vtkvol.model.techniques import technique_specs\n"
        "from vtkvol.model.session_checks import technique_parameters\n"
        "assert technique_specs()\n"
        "assert technique_parameters('shadow_volume')[0]\n"
        "print(any(m == 'vtk' or m.startswith('vtkmodules') for m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def test_register_is_scoped_and_restores_what_it_replaced():
    demo = spec()
    with register(demo) as registered:
        assert registered is demo and get_spec("demo") is demo
        other = spec(label="Other")
        handle = register(other)
        assert get_spec("demo") is other
        handle.unregister()
        assert get_spec("demo") is demo
    with pytest.raises(ValueError, match="unknown illumination method 'demo'; available: "):
        get_spec("demo")


def test_broken_plugin_is_reported_not_dropped(monkeypatch):
    bad = importlib.metadata.EntryPoint("ghost", "no_such_module_xyz:TECHNIQUE",
                                        techniques.ENTRY_POINT_GROUP)
    wrong = importlib.metadata.EntryPoint("wrong", "vtkvol.model.params:Param",
                                          techniques.ENTRY_POINT_GROUP)
    monkeypatch.setattr(techniques, "_entry_points", lambda: [bad, wrong])
    techniques.reload_techniques()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert techniques.technique_specs() == {}
        messages = [str(w.message) for w in caught if w.category is RuntimeWarning]
        assert any("'ghost'" in m and "no_such_module_xyz" in m for m in messages)
        assert any("'wrong'" in m and "not a TechniqueSpec" in m for m in messages)
        with pytest.raises(ValueError, match="'ghost' is installed but broken"):
            get_spec("ghost")
    finally:
        monkeypatch.undo()
        techniques.reload_techniques()


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"name": "two words"}, "must be a Python identifier"),
        ({"lighting": "glow"}, "lighting must be one of surface, medium"),
        ({"capabilities": {"teleport"}}, "unknown capabilities teleport"),
        ({"engine": "no_colon"}, "engine must be 'module:Class'"),
        ({"parameters": (Param("a", 1.0, "A", "a"), Param("a", 2.0, "A", "a"))},
         "declares a parameter twice"),
        ({"parameters": (Param("a", 1.0, "A", "a", applies_when=(("mode", ("x",)),)),)},
         "a applies when 'mode'"),
        ({"parameters": (Param("a", 1.0, "A", "a", range=(0, 2)),),
          "bench": (BenchSetting({"a": 5.0}),)}, "outside its range"),
    ],
)
def test_bad_declarations_are_refused_with_the_reason(overrides, message):
    with pytest.raises(ValueError, match=message):
        spec(**overrides)


def test_applies_when_and_merged_invalidations():
    mode = Param("mode", "a", "Mode", "", kind="choice", choices=("a", "b"),
                 invalidates=Invalidates.SHADER)
    angle = Param("angle", 1.0, "Angle", "", range=(0, 2), applies_when=(("mode", ("b",)),),
                  invalidates=Invalidates.ILLUMINATION)
    s = spec(parameters=(mode, angle))
    assert not angle.applies(s.defaults())
    assert angle.applies({**s.defaults(), "mode": "b"})
    assert s.invalidations({"mode", "angle"}) == Invalidates.SHADER | Invalidates.ILLUMINATION
    assert s.invalidations({"unknown"}) == Invalidates(0)


def test_cpu_path_values_are_validated_like_parameters():
    p = Param("samples", 4, "Samples", "", kind="int", range=(1, 64), step=1)
    assert spec(parameters=(p,), cpu_path_values={"samples": 2}).cpu_path_values == {"samples": 2}
    with pytest.raises(ValueError, match="samples"):
        spec(parameters=(p,), cpu_path_values={"samples": 1000})
    with pytest.raises(ValueError, match="unknown"):
        spec(parameters=(p,), cpu_path_values={"iterations": 2})
