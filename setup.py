"""The package list, found rather than kept by hand: every folder under vtkvol/, ui/
(installed as vtkvol.ui), plugins/ (vtkvol.plugins) and resources/ (vtkvol.resources) is a
package, the shader and data folders included (as data packages, so setuptools installs
their files without warning that they "would be ignored"). Adding a technique takes its
folder and one entry-point line in pyproject.toml, nothing else. Everything else about the
build is in pyproject.toml."""

from pathlib import Path

from setuptools import find_namespace_packages, setup

ROOT = Path(__file__).resolve().parent
#: Source folder → installed package (pyproject.toml's package-dir says the same).
FOLDERS = {"vtkvol": "vtkvol", "ui": "vtkvol.ui", "plugins": "vtkvol.plugins",
           "resources": "vtkvol.resources"}


def packages() -> list[str]:
    found = []
    for folder, package in FOLDERS.items():
        found.append(package)
        found += [f"{package}.{name}" for name in find_namespace_packages(
            ROOT / folder, exclude=["*__pycache__*"])]
    return sorted(set(found))


setup(packages=packages())
