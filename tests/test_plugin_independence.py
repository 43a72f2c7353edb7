"""A plugin imports the engine, never another plugin (docs/architecture.md, layers): one
broken plugin cannot break another, and a third-party technique never needs a sibling's
private modules. Checked by reading every plugin file's imports (in-function and
``TYPE_CHECKING`` ones included), so nothing has to be imported to find them."""

from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
PLUGINS = ROOT / "plugins"


def imported_plugins(path: pathlib.Path, own: str) -> set[str]:
    """The sibling plugins ``path`` (in plugin ``own``) imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: ".." leaves the plugin
                if node.level >= 2 and node.module:
                    names.append(f"vtkvol.plugins.{node.module}")
                continue
            names += [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
    out = set()
    for name in names:
        parts = name.split(".")
        if (parts[:2] == ["vtkvol", "plugins"] and len(parts) > 2 and parts[2] != own
                and (PLUGINS / parts[2]).is_dir()):
            out.add(parts[2])
    return out


def cross_imports() -> set[tuple[str, str, str]]:
    found = set()
    for plugin in sorted(p for p in PLUGINS.iterdir() if (p / "__init__.py").exists()):
        for path in plugin.rglob("*.py"):
            for other in imported_plugins(path, plugin.name):
                found.add((plugin.name, other, str(path.relative_to(ROOT))))
    return found


def test_no_plugin_imports_another() -> None:
    offending = sorted(f"{path}: imports plugin {other!r}"
                       for own, other, path in cross_imports())
    assert not offending, "\n".join(offending)


def test_the_scan_sees_an_import_of_a_sibling(tmp_path) -> None:
    """The scan is not blind: every form of a sibling import is found."""
    sample = tmp_path / "x.py"
    sample.write_text(
        "from vtkvol.plugins.shadow_volume.cpu import LightGrid\n"
        "import vtkvol.plugins.translucency\n"
        "def f():\n    from vtkvol.plugins import path_traced\n"
        "from ..cone_traced import gpu\n"
        "from vtkvol.engine import gl\nfrom . import cpu\n")
    assert imported_plugins(sample, "local") == {
        "shadow_volume", "translucency", "path_traced", "cone_traced"}
    assert imported_plugins(sample, "shadow_volume") == {
        "translucency", "path_traced", "cone_traced"}
