"""The package list, computed: every technique folder in plugins/ is a package of its own, so
adding a technique takes its package and one entry-point line in pyproject.toml, nothing else.
Everything else about the build is in pyproject.toml."""

from pathlib import Path

from setuptools import setup

ROOT = Path(__file__).resolve().parent
CORE = [
    "vtkvol", "vtkvol.io", "vtkvol.model", "vtkvol.engine", "vtkvol.reference", "vtkvol.bench",
    "vtkvol.ui", "vtkvol.ui.docks", "vtkvol.resources", "vtkvol.plugins", "vtkvol.napari",
]
PLUGINS = sorted(
    f"vtkvol.plugins.{init.parent.name}" for init in (ROOT / "plugins").glob("*/__init__.py")
)

setup(packages=[*CORE, *PLUGINS])
