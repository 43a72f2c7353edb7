"""The session suffix is recognised in one place (``vtkvol.model.session.is_session_path``),
case-insensitively, by every reader: the CLI's ``render`` and ``batch`` and the app (review 2,
§7: ``vtkvol render VIEW.VTKVOL.JSON`` failed with "unknown file type '.JSON'")."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from vtkvol.model.session import is_session_path, session_target


@pytest.mark.parametrize("name", ["view.vtkvol.json", "VIEW.VTKVOL.JSON", "View.VtkVol.Json"])
def test_is_session_path_ignores_case(name: str) -> None:
    assert is_session_path(name) and is_session_path(Path("/tmp") / name)


@pytest.mark.parametrize("name", ["view.json", "view.vtkvol", "view.tif", "vtkvol.json"])
def test_other_names_are_not_sessions(name: str) -> None:
    assert not is_session_path(name)


@pytest.mark.parametrize(("given", "written"), [
    ("view", "view.vtkvol.json"), ("view.vtkvol", "view.vtkvol.json"),
    ("VIEW.VTKVOL.JSON", "VIEW.VTKVOL.JSON"), ("a.b", "a.b.vtkvol.json")])
def test_session_target_appends_the_suffix_once(given: str, written: str) -> None:
    assert session_target(Path("/d") / given) == Path("/d") / written


@pytest.mark.gl
def test_render_reads_an_upper_case_session(tmp_path, capsys) -> None:
    from tests_support_time import write_time_lapse

    from vtkvol.cli import main
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.session import save_session

    lapse = tmp_path / "lapse.tif"
    write_time_lapse(lapse, 2)
    data = read_volume(lapse, time_index=0)
    saved = save_session(tmp_path / "view", scene_for(data), data=data)
    upper = tmp_path / "VIEW.VTKVOL.JSON"
    shutil.copy(saved, upper)
    out = tmp_path / "out.png"
    assert main(["render", str(upper), "-o", str(out), "--size", "48", "48"]) == 0, (
        capsys.readouterr().err)
    assert out.exists() and out.stat().st_size > 0
    # The same file under its lower-case name renders the same picture.
    lower = tmp_path / "lower.png"
    assert main(["render", str(saved), "-o", str(lower), "--size", "48", "48"]) == 0
    assert out.read_bytes() == lower.read_bytes()


def test_batch_names_outputs_after_an_upper_case_session() -> None:
    from vtkvol.batch import _stem

    assert _stem("/data/VIEW.VTKVOL.JSON") == "VIEW"
