"""Files vtkvol writes (PNG renders and screenshots, transfer functions, sessions): written
atomically (the old file or the new one, never half of one, never a temporary file left),
a failed write (full disk, file-size limit) reported in one line, and the permissions of any
new file (0o666 less the umask), not mkstemp's 0600; a replaced file keeps its own."""

from __future__ import annotations

import errno
import json
import os
import stat

import numpy as np
import pytest
from tests_support_hostile import run_child, snapshot

from vtkvol.model.scene import SceneModel
from vtkvol.model.session import SessionError, save_session
from vtkvol.model.transfer_function import TransferFunction

IMAGE = np.full((24, 32, 3), 200, np.uint8)


@pytest.fixture
def umask():
    """Set the process umask for one test (restored after)."""
    previous = os.umask(0o022)
    yield lambda value: os.umask(value)
    os.umask(previous)


def mode(path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def full_disk(monkeypatch) -> None:
    """Every write through vtkvol's writer fails as on a full disk."""
    def no_space(_fd, _data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr("vtkvol.io.atomic._write_all", no_space)


def write_cli_png(path):
    from vtkvol.cli import _write_png

    _write_png(IMAGE, path)


def write_screenshot(path):
    pytest.importorskip("PySide6")
    from vtkvol.ui.app import write_png

    write_png(IMAGE, path)


def write_tf(path):
    pytest.importorskip("PySide6")
    from vtkvol.ui.docks.transfer_function import write_tf_file

    write_tf_file(path, TransferFunction())


def write_session(path):
    save_session(path, SceneModel())


WRITERS = {
    "render_png": (write_cli_png, "view.png", OSError),
    "screenshot_png": (write_screenshot, "view.png", OSError),
    "tf": (write_tf, "ramp.tf.json", OSError),
    "session": (write_session, "view.vtkvol.json", SessionError),
}


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_new_files_get_the_umasks_permissions_and_replaced_files_keep_theirs(tmp_path, umask,
                                                                            kind):
    """Before: screenshots and transfer functions were 0600 (mkstemp's mode) whatever the
    umask; a replaced one lost its permissions."""
    write, name, _error = WRITERS[kind]
    target = tmp_path / name
    write(target)
    assert mode(target) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    umask(0o027)
    (tmp_path / "other").mkdir()
    write(tmp_path / "other" / name)
    assert mode(tmp_path / "other" / name) == 0o640
    os.chmod(target, 0o664)  # shared with the group: replacing keeps it so
    write(target)
    assert mode(target) == 0o664


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_a_full_disk_is_reported_and_the_previous_file_kept(tmp_path, monkeypatch, kind):
    write, name, error = WRITERS[kind]
    target = tmp_path / name
    write(target)
    before = snapshot(tmp_path)
    full_disk(monkeypatch)
    with pytest.raises(error, match="No space left on device"):
        write(target)
    assert snapshot(tmp_path) == before  # the old file, and no temporary file beside it


def test_session_save_under_a_file_size_limit_is_refused_cleanly(tmp_path):
    """A real failing write (RLIMIT_FSIZE in a child process): the session says so in one line
    and the previous session is untouched."""
    target = tmp_path / "view.vtkvol.json"
    save_session(target, SceneModel())
    before = snapshot(tmp_path)
    result = run_child(f"""
        import sys
        from vtkvol.model.scene import SceneModel
        from vtkvol.model.session import SessionError, save_session
        model = SceneModel()
        model.render.ambient = 0.25
        try:
            save_session({json.dumps(str(target))}, model)
        except SessionError as exc:
            print("REFUSED", exc)
            sys.exit(3)
    """, file_size_bytes=512)
    assert result.returncode == 3, result.stderr[-2000:]
    assert "view.vtkvol.json: could not be written: File too large" in result.stdout
    assert snapshot(tmp_path) == before


@pytest.mark.gl
def test_vtkvol_render_under_a_file_size_limit_says_so_and_keeps_the_old_png(tmp_path):
    """Before: VTK's PNG writer failed without a word, and the truncated file replaced the old
    one ('wrote view.png', exit status 0)."""
    out = tmp_path / "view.png"
    out.write_bytes(b"the previous picture")
    before = snapshot(tmp_path)
    result = run_child(f"""
        import sys
        from vtkvol.cli import main
        sys.exit(main(["render", "sample", "-o", {json.dumps(str(out))}, "--size", "96", "96",
                       "--overwrite"]))
    """, file_size_bytes=400, timeout=300)
    assert result.died_of is None, result.stderr[-2000:]
    assert result.returncode == 1, (result.stdout, result.stderr[-2000:])
    assert f"vtkvol: could not write {out}: File too large" in result.stderr
    assert "wrote" not in result.stdout
    assert snapshot(tmp_path) == before


@pytest.mark.gl
def test_vtkvol_render_refuses_to_write_over_its_input(tmp_path, capsys):
    from vtkvol.cli import main

    volume = tmp_path / "cells.npy"
    np.save(volume, np.zeros((4, 4, 4), np.uint8))
    before = snapshot(tmp_path)
    assert main(["render", str(volume), "-o", str(volume), "--overwrite"]) == 2
    assert "is the input" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def test_render_where_no_file_can_be_written_is_one_line(tmp_path, capsys):
    from vtkvol.cli import main

    (tmp_path / "notes.txt").write_text("a file, not a folder")
    before = snapshot(tmp_path)
    assert main(["render", "sample", "-o", str(tmp_path / "notes.txt" / "x.png"),
                 "--size", "8", "8"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("vtkvol: could not write") and "notes.txt is not a folder" in err
    assert "Traceback" not in err
    assert snapshot(tmp_path) == before


@pytest.mark.gui
def test_the_app_says_which_file_a_full_disk_stopped(opened_window, tmp_path, monkeypatch,
                                                     dialogs):
    """Screenshot, transfer function and session saved from the app on a full disk: one
    dialog each, naming the file; the previous files are unchanged."""
    window = opened_window
    shot, tf, session = tmp_path / "shot.png", tmp_path / "ramp.tf.json", tmp_path / "v"
    window.save_screenshot(shot)
    window.tf_dock.save_tf(tf)
    written = window.save_session(session)
    assert dialogs == [] and written is not None
    before = snapshot(tmp_path)
    full_disk(monkeypatch)
    assert window.save_screenshot(shot) is None
    window.tf_dock.save_tf(tf)
    assert window.save_session(written) is None
    assert [box.text() for box in dialogs] == [
        "Could not save the screenshot", "Could not save the transfer function",
        "Could not save the session"]
    for box, name in zip(dialogs, ("shot.png", "ramp.tf.json", written.name), strict=True):
        assert name in box.informativeText() and "No space left on device" in \
            box.informativeText()
    assert snapshot(tmp_path) == before
