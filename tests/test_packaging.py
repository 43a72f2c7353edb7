"""``import vtkvol`` finds the whole package wherever Python runs, editable install or not.

Issue 21's defect: after ``git clone … vtkvol`` and the README's editable install, Python run
from the folder that *contains* the clone found the clone's root (a folder named ``vtkvol``
without ``__init__.py``, first on ``sys.path`` as ``''``) as an empty namespace package, because
the remapped layout was installed through a meta-path finder that runs after the path search:
``vtkvol.__file__`` was None and ``from vtkvol import __version__`` failed. The project's
install (``scripts/project-env.sh``) is now the checkout's root on ``sys.path``
(``editable_mode=compat``), and ``vtkvol/__init__.py`` finds ``ui/``, ``plugins/`` and
``resources/`` beside itself. These tests copy the checkout into a folder named ``vtkvol``,
install it into throwaway virtual environments (one editable as the project's scripts do, one
from a wheel built with ``pip wheel --no-deps``) and import it from the clone's parent, from
inside the clone and from an unrelated folder.

The environments see the project's dependencies through a folder of links to the test
environment's site-packages without vtkvol itself, so nothing is downloaded but setuptools
for the build (build isolation, from pip's cache or index).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.packaging

#: What each import run prints: where vtkvol came from and that its parts are there. The
#: technique list comes through the entry points, so the installed metadata is checked too.
PROBE = """
import importlib, importlib.resources, json
import vtkvol
from vtkvol import __version__, read_volume
from vtkvol.model.techniques import technique_specs
importlib.import_module("vtkvol.ui")
importlib.import_module("vtkvol.plugins.shadow_volume.technique")
glsl = importlib.resources.files("vtkvol.plugins.shadow_volume") / "shaders" / "shadow_volume.glsl"
print(json.dumps({"file": vtkvol.__file__, "version": __version__,
                  "techniques": sorted(technique_specs()),
                  "shader": glsl.is_file()}))
"""


def _tracked_files() -> list[str]:
    """The checkout's files as a clone would have them (tracked plus new, not ignored)."""
    out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return [name for name in out.split("\0") if name and (ROOT / name).is_file()]


#: Left out of the dependency folder: vtkvol's own install, and the build tools (the builds
#: get their own, isolated, setuptools; an old one seen through the folder would shadow it).
NOT_DEPENDENCIES = ("vtkvol", "__editable__", "setuptools", "pkg_resources", "_distutils_hack",
                    "distutils-precedence", "pip", "wheel")


def _dependencies_folder(tmp: Path) -> Path:
    """A folder of links to this environment's site-packages, without any vtkvol install."""
    site = Path(sysconfig.get_paths()["purelib"])
    deps = tmp / "deps"
    deps.mkdir()
    for entry in site.iterdir():
        if entry.name.lower().startswith(NOT_DEPENDENCIES):
            continue
        (deps / entry.name).symlink_to(entry)
    return deps


def _venv(path: Path, deps: Path) -> Path:
    """A virtual environment that sees ``deps`` as a site folder (its .pth files run too)."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(path)], check=True)
    python = path / "bin" / "python"
    purelib = subprocess.run([str(python), "-c",
                              "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    Path(purelib, "zz_test_dependencies.pth").write_text(
        f"import site; site.addsitedir({str(deps)!r})\n")
    return python


def _pip(python: Path, *args: str) -> None:
    done = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), *args,
                           "--no-deps", "-q"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr


def _probe(python: Path, cwd: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    done = subprocess.run([str(python), "-c", PROBE], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, f"from {cwd}:\n{done.stderr}"
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def installs(tmp_path_factory):
    """The checkout copied to ``<tmp>/vtkvol``; an editable and a wheel install of it."""
    tmp = tmp_path_factory.mktemp("packaging")
    clone = tmp / "vtkvol"
    for name in _tracked_files():
        (clone / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, clone / name)
    deps = _dependencies_folder(tmp)
    dist = tmp / "dist"
    # The wheel builds while the editable install runs (each in its own isolated build).
    build = subprocess.Popen([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                              str(dist), str(clone)], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    editable = _venv(tmp / "venv-editable", deps)
    _pip(editable, "install", "-e", str(clone), "--config-settings", "editable_mode=compat")
    output, _ = build.communicate(timeout=300)
    assert build.returncode == 0, output
    wheel = _venv(tmp / "venv-wheel", deps)
    _pip(wheel, "install", str(next(dist.glob("vtkvol-*.whl"))))
    elsewhere = tmp / "elsewhere"
    elsewhere.mkdir()
    return {"tmp": tmp, "clone": clone, "editable": editable, "wheel": wheel,
            "elsewhere": elsewhere}


WHERE = ["parent of the clone", "inside the clone", "elsewhere"]


def _folder(installs: dict, where: str) -> Path:
    return {"parent of the clone": installs["tmp"], "inside the clone": installs["clone"],
            "elsewhere": installs["elsewhere"]}[where]


@pytest.mark.parametrize("where", WHERE)
def test_editable_install_imports_the_clone_from(installs, where):
    found = _probe(installs["editable"], _folder(installs, where))
    assert found["file"] == str(installs["clone"] / "vtkvol" / "__init__.py")
    assert found["version"] == "0.1.0" and found["shader"] is True
    assert {"local", "shadow_volume", "path_traced"} <= set(found["techniques"])


@pytest.mark.parametrize("where", WHERE)
def test_wheel_install_imports_the_whole_package_from(installs, where):
    found = _probe(installs["wheel"], _folder(installs, where))
    if where == "inside the clone":  # Python puts the working folder first: the source wins
        assert found["file"] == str(installs["clone"] / "vtkvol" / "__init__.py")
    else:
        assert found["file"].startswith(str(installs["tmp"] / "venv-wheel"))
    assert found["version"] == "0.1.0" and found["shader"] is True
    assert {"local", "shadow_volume", "path_traced"} <= set(found["techniques"])
