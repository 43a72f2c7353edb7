"""The set-up scripts' choice of Python environment (scripts/project-env.sh, sourced by
scripts/test.sh and scripts/run-app.sh): an active venv or conda environment is used as it is,
otherwise ``.venv`` in the checkout; Python >= 3.10 is checked with a clear message; a second run
installs nothing. Each test copies the file into a temporary checkout and puts fake interpreters
(small shell scripts that log how they were called) first on the PATH, so nothing is installed."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "project-env.sh"

pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="the scripts are bash")


def fake_python(folder: Path, name: str, version: tuple[int, int], log: Path) -> Path:
    """A fake interpreter: answers the version probe, makes a venv folder for ``-m venv DIR``
    (with itself as DIR/bin/python), and logs every other call to ``log``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(f"""#!/usr/bin/env bash
if [ "$1" = "-c" ]; then
  case "$2" in
    *'print(f"'*) echo "{version[0]}.{version[1]}"; exit 0;;
    *version_info*) echo "{version[0]} {version[1]}"; exit 0;;
  esac
fi
echo "$0 $*" >> "{log}"
if [ "$1" = "-m" ] && [ "$2" = "venv" ]; then
  mkdir -p "$3/bin" && cp "$0" "$3/bin/python"
fi
exit 0
""")
    path.chmod(path.stat().st_mode | stat.S_IEXEC)
    return path


def source_and_run(checkout: Path, call: str, path: str, **env: str) -> subprocess.CompletedProcess:
    scripts = checkout / "scripts"
    scripts.mkdir(parents=True, exist_ok=True)
    shutil.copy(SCRIPT, scripts / "project-env.sh")
    for name in ("pyproject.toml", "setup.py"):
        (checkout / name).write_text(f"# {name}\n")
    environment = {"HOME": str(checkout), "PATH": f"{path}:{_bash_only(checkout.parent)}", **env}
    return subprocess.run(
        ["bash", "-c", f'set -euo pipefail; . scripts/project-env.sh; {call}; '
                       'echo "PY=${VTKVOL_PY:-}"'],
        cwd=checkout, env=environment, capture_output=True, text=True, timeout=60)


def test_a_venv_is_made_in_the_checkout_with_the_first_python_3_10_or_newer(tmp_path):
    log = tmp_path / "calls.log"
    bin_dir = tmp_path / "bin"
    fake_python(bin_dir, "python3", (3, 9), log)
    newer = fake_python(bin_dir, "python3.12", (3, 12), log)
    checkout = tmp_path / "checkout"
    done = source_and_run(checkout, "vtkvol_env_install test", str(bin_dir))
    assert done.returncode == 0, done.stderr
    assert "skipping" in done.stderr and "Python 3.9 (vtkvol needs Python >= 3.10)" in done.stderr
    calls = log.read_text().splitlines()
    assert calls[0] == f"{newer} -m venv {checkout}/.venv"
    venv_python = checkout / ".venv" / "bin" / "python"
    assert calls[1] == (f"{venv_python} -m pip install -q -e {checkout}[test]"
                        " --config-settings editable_mode=compat")
    assert f"PY={venv_python}" in done.stdout


def test_a_second_run_reuses_the_venv_and_installs_nothing(tmp_path):
    log = tmp_path / "calls.log"
    bin_dir = tmp_path / "bin"
    fake_python(bin_dir, "python3", (3, 11), log)
    checkout = tmp_path / "checkout"
    assert source_and_run(checkout, "vtkvol_env_install app", str(bin_dir)).returncode == 0
    first = log.read_text().splitlines()
    done = source_and_run(checkout, "vtkvol_env_install app", str(bin_dir))
    assert done.returncode == 0, done.stderr
    again = log.read_text().splitlines()[len(first):]
    assert [c for c in again if " -m pip install " in c or " -m venv " in c] == []
    # another extra, or a changed pyproject.toml, installs again
    assert source_and_run(checkout, "vtkvol_env_install test", str(bin_dir)).returncode == 0
    assert "pip install -q -e" in log.read_text().splitlines()[-1]


def test_without_python_3_10_the_message_says_so_and_nothing_is_made(tmp_path):
    log = tmp_path / "calls.log"
    bin_dir = tmp_path / "bin"
    fake_python(bin_dir, "python3", (3, 8), log)
    checkout = tmp_path / "checkout"
    # the empty folder first on the PATH hides any real python3.1x from the test's machine
    done = subprocess.run(
        ["bash", "-c", ". scripts/project-env.sh; vtkvol_env_install test"],
        cwd=_prepared(checkout), capture_output=True, text=True, timeout=60,
        env={"HOME": str(tmp_path), "PATH": f"{bin_dir}:{_bash_only(tmp_path)}"})
    assert done.returncode == 1
    assert done.stderr.strip().splitlines()[-1] == (
        "vtkvol setup: no Python >= 3.10 found on the PATH "
        "(set PYTHON=/path/to/python3.10+ to name one)")
    assert not (checkout / ".venv").exists()
    assert not log.exists() or "pip" not in log.read_text()


def test_an_active_virtual_environment_is_used_as_it_is(tmp_path):
    log = tmp_path / "calls.log"
    active = tmp_path / "active-env"
    fake_python(active / "bin", "python", (3, 12), log)
    checkout = tmp_path / "checkout"
    done = source_and_run(checkout, "vtkvol_env_install test", str(tmp_path / "nothing"),
                          VIRTUAL_ENV=str(active))
    assert done.returncode == 0, done.stderr
    assert f"PY={active}/bin/python" in done.stdout
    assert not (checkout / ".venv").exists()
    assert log.read_text().splitlines() == [
        f"{active}/bin/python -m pip install -q -e {checkout}[test]"
        " --config-settings editable_mode=compat"]


def test_an_active_environment_older_than_3_10_is_refused(tmp_path):
    log = tmp_path / "calls.log"
    conda = tmp_path / "conda-env"
    fake_python(conda / "bin", "python", (3, 9), log)
    done = source_and_run(tmp_path / "checkout", "vtkvol_env_install test",
                          str(tmp_path / "nothing"), CONDA_PREFIX=str(conda))
    assert done.returncode == 1
    assert done.stderr.strip() == (
        f"vtkvol setup: the active environment's Python ({conda}/bin/python) is 3.9; "
        "vtkvol needs >= 3.10")
    assert not log.exists()


def _prepared(checkout: Path) -> Path:
    source_and_run(checkout, "true", "/nonexistent")
    return checkout


def _bash_only(tmp_path: Path) -> str:
    """A PATH folder with only the tools the script needs, so no python3 of the test's
    machine is found."""
    tools = tmp_path / "tools"
    tools.mkdir(exist_ok=True)
    for tool in ("bash", "cat", "cksum", "cut", "dirname", "mkdir", "rm", "cp", "env", "echo"):
        found = shutil.which(tool)
        if found and not (tools / tool).exists():
            os.symlink(found, tools / tool)
    return str(tools)


@pytest.mark.parametrize("args", [["open"], ["open", "cells.tif"]])
def test_open_without_a_display_says_so_in_one_line(args, monkeypatch, capsys):
    from vtkvol import cli

    for name in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(cli.sys, "platform", "linux")
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    shown = args[1] if len(args) > 1 else "sample"
    assert err == ("vtkvol: no display found (neither DISPLAY nor WAYLAND_DISPLAY is set); the "
                   "app needs a desktop session. Headless, render images instead: vtkvol render "
                   f"{shown} -o view.png\n")


def test_open_with_an_offscreen_qt_platform_is_not_refused(monkeypatch):
    from vtkvol import cli

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    assert cli.no_display_reason() is None
    monkeypatch.delenv("QT_QPA_PLATFORM")
    assert cli.no_display_reason() is not None
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    assert cli.no_display_reason() is None
