"""Every command and code example of README.md and docs/library.md runs as written.

Each fenced block is taken from the page. A shell line is either run (the ``vtkvol`` command
of the environment under test, in a folder holding small stand-ins for the files the page
names, with images made 64 pixels wide and movies a few frames long) or skipped for a reason
listed in :data:`SKIPPED`. A Python block runs in a subprocess after a short prelude that makes
what the page assumes exists (a PyVista ``grid``, an off-screen ``pv.Plotter``), with the
replacements of :data:`PYTHON_EDITS` (tiny sizes); a replacement that no longer matches fails.
A block or a line that this file has no plan for fails too, so a new example is run or skipped
by decision, never by omission.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tifffile

ROOT = Path(__file__).resolve().parents[1]
DOCS = ("README.md", "docs/library.md")
BLOCK = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)
VTKVOL = str(Path(sys.executable).parent / "vtkvol")

pytestmark = pytest.mark.gl

#: Shell lines not run here, by the start of the line, with the reason.
SKIPPED = {
    "./scripts/run-app.sh": "installs the app's environment and starts the GUI "
                            "(CI runs it: .ci/check-run-app)",
    "./scripts/test.sh": "installs the test environment and runs the whole suite (CI runs it)",
    "vtkvol open": "starts the GUI (tests/test_ui_*.py open files, sessions and --time)",
    "vtkvol bench": "runs for many minutes (tests/test_bench.py runs it at test size)",
    "vtkvol info experiment.lif": "no Leica writer here (tests/test_io_vendor.py reads LIF)",
    "vtkvol info https://": "needs the network (tests/test_io_remote.py serves HTTP locally)",
    "vtkvol render s3://": "needs the network and S3 credentials",
    "vtkvol batch views/*.vtkvol.json -o renders --scheduler": "needs a running Dask "
                                                                "scheduler at that address",
}

#: Files the pages name that are made here as something else, with the reason.
STAND_INS = {
    "embryo.czi": ("embryo_lapse.tif", "no CZI writer here: a time-lapse TIFF instead"),
}

#: Python blocks: (page, first line) -> (prelude, [(text in the block, replacement)]).
PRELUDE_GRID = (
    "import numpy as np\nimport pyvista as pv\n"
    "grid = pv.ImageData(dimensions=(24, 24, 24))\n"
    "z, y, x = np.mgrid[0:24, 0:24, 0:24]\n"
    "grid.point_data['values'] = (255 * np.exp(-((x - 12.0) ** 2 + (y - 12.0) ** 2"
    " + (z - 12.0) ** 2) / 40)).astype(np.uint8).ravel()\n"
)
OFFSCREEN = ("pv.Plotter()", "pv.Plotter(off_screen=True, window_size=(64, 64))")
SHOW = ("plotter.show()", "plotter.show(auto_close=False)")
PYTHON_EDITS: dict[tuple[str, str], tuple[str, list[tuple[str, str]]]] = {
    ("README.md", "import pyvista as pv"): (PRELUDE_GRID, [
        OFFSCREEN, SHOW, ("size=(800, 600)", "size=(64, 48)")]),
    ("README.md", "import vtkvol"): ("", [
        ('method="shadow_volume")', 'method="shadow_volume", size=(64, 48))')]),
    ("docs/library.md", "import pyvista as pv"): (PRELUDE_GRID, [OFFSCREEN, SHOW]),
    # The second block continues the first (same plotter, grid and imports).
    ("docs/library.md", "actor, il = plotter.vtkvol.add_volume(grid, method=\"hybrid_diffusion\")"
     "  # mapper=\"gpu\" for you"): (
        PRELUDE_GRID + "import vtkvol\n"
        "plotter = pv.Plotter(off_screen=True, window_size=(64, 64))\n", []),
    ("docs/library.md", "from vtkvol.io import read_volume"): ("", [
        ("size=(640, 480)", "size=(64, 48)")]),
}


def blocks() -> list[tuple[str, int, str, str]]:
    """(page, line, language, text) of every fenced block of the pages."""
    found = []
    for page in DOCS:
        text = (ROOT / page).read_text(encoding="utf-8")
        for match in BLOCK.finditer(text):
            line = text.count("\n", 0, match.start()) + 1
            found.append((page, line, match.group(1), match.group(2)))
    return found


def shell_lines() -> list[tuple[str, int, tuple[str, ...]]]:
    """(page, line, words) of every shell line (``shlex`` words, comments dropped)."""
    out = []
    for page, line, language, text in blocks():
        if language in ("bash", "sh", "shell", "console"):
            for i, row in enumerate(text.splitlines()):
                words = shlex.split(row, comments=True)  # a trailing "# …" is a comment
                if words:
                    out.append((page, line + 1 + i, tuple(words)))
    return out


def python_blocks() -> list[tuple[str, int, str]]:
    return [(page, line, text) for page, line, language, text in blocks()
            if language == "python"]


def skip_reason(words: tuple[str, ...]) -> str | None:
    command = " ".join(words)
    for start, reason in SKIPPED.items():
        if command.startswith(start):
            return reason
    return None


def small(argv: list[str]) -> list[str]:
    """The command with 64-pixel images and at most three turntable frames."""
    argv = list(argv)
    if argv[1] in ("render", "batch"):
        if "--size" in argv:
            i = argv.index("--size")
            argv[i + 1:i + 3] = ["64", "48"]
        else:
            argv += ["--size", "64", "48"]
    if "--frames" in argv:
        i = argv.index("--frames")
        argv[i + 1] = str(min(int(argv[i + 1]), 3))
    return [STAND_INS.get(a, (a,))[0] for a in argv]


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """The files the pages name, small (a 2-channel 24³ stack, a session of it, keyframes,
    a label image, time-lapses; the OME-Zarr pyramid is made by ``vtkvol convert`` when needed)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from tests_support_time import write_time_lapse

    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.keyframes import Animation, CameraState, Keyframe, save_keyframes
    from vtkvol.model.session import save_session

    here = tmp_path_factory.mktemp("docs")
    z, y, x = np.mgrid[0:24, 0:24, 0:24]
    ball = np.exp(-((x - 12.0) ** 2 + (y - 12.0) ** 2 + (z - 12.0) ** 2) / 30.0)
    cells = np.stack([3000 * ball, 3000 * np.roll(ball, 5, axis=2)]).astype(np.uint16)
    for name in ("cells.tif", "embryo.tif", "big_stack.tif"):
        tifffile.imwrite(here / name, cells.transpose(1, 0, 2, 3), imagej=True,
                         metadata={"axes": "ZCYX"})
    labels = np.zeros((24, 24, 24), np.uint16)
    labels[4:10, 4:10, 4:10] = 3
    labels[12:20, 12:20, 12:20] = 17
    labels[4:10, 14:20, 12:18] = 40
    tifffile.imwrite(here / "nuclei_labels.tif", labels)
    write_time_lapse(here / "embryo_lapse.tif")
    write_time_lapse(here / "series.tif")
    data = read_volume(here / "cells.tif")
    save_session(here / "view.vtkvol.json", scene_for(data), data=data)
    start = CameraState(position=(12, -60, 12), focal_point=(12, 12, 12), view_up=(0, 0, 1))
    end = CameraState(position=(80, 12, 12), focal_point=(12, 12, 12), view_up=(0, 0, 1))
    save_keyframes(here / "fly.keyframes.json",
                   Animation((Keyframe(0.0, start), Keyframe(0.1, end))))
    (here / "tests").symlink_to(ROOT / "tests")  # the README's time-lapse line imports from it
    # The stand-in inputs, which each Python example gets linked into a folder of its own.
    (here / ".inputs").write_text("\n".join(sorted(p.name for p in here.iterdir())))
    return here


def run(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": ""}
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def test_every_block_has_a_plan():
    """New examples are run (a shell line starting ``vtkvol``/``python``, or a Python block
    with its edits) or skipped with a reason here; nothing is left out silently."""
    for page, line, words in shell_lines():
        assert skip_reason(words) or words[0] in ("vtkvol", "python"), (
            f"{page}:{line}: {' '.join(words)!r} is neither run nor skipped with a reason")
    for page, line, text in python_blocks():
        assert (page, text.splitlines()[0]) in PYTHON_EDITS, (
            f"{page}:{line}: a Python block with no entry in PYTHON_EDITS")
    languages = {language for *_, language, _ in blocks()}
    assert languages <= {"bash", "python"}, languages


@pytest.mark.parametrize("page,line,words", shell_lines(),
                         ids=lambda v: str(v) if isinstance(v, int) else None)
def test_shell_example_runs(folder, page, line, words):
    reason = skip_reason(words)
    if reason:
        pytest.skip(f"{page}:{line}: {reason}")
    argv = list(words)
    if argv[0] == "python":
        argv[0] = sys.executable
    else:
        argv = small(argv)
        argv[0] = VTKVOL
    if "brain.ome.zarr" in argv and not (folder / "brain.ome.zarr").exists():
        made = run([VTKVOL, "convert", "cells.tif", "brain.ome.zarr"], folder)
        assert made.returncode == 0, made.stderr
    done = run(argv, folder)
    assert done.returncode == 0, f"{page}:{line}: {' '.join(argv)}\n{done.stderr}"
    assert "Traceback" not in done.stderr, done.stderr
    if "-o" in argv and argv[1] == "render":
        out = folder / argv[argv.index("-o") + 1]
        stem = out.with_name(out.stem + "_0000" + out.suffix)
        assert out.is_file() or stem.is_file(), f"{page}:{line}: no {out.name}"


@pytest.mark.parametrize("page,line,text", python_blocks(),
                         ids=lambda v: str(v) if isinstance(v, int) else None)
def test_python_example_runs(folder, page, line, text):
    prelude, edits = PYTHON_EDITS[(page, text.splitlines()[0])]
    for old, new in edits:
        assert old in text, f"{page}:{line}: the example no longer contains {old!r}"
        text = text.replace(old, new)
    # Each block in a folder of its own that links the stand-in inputs: what another example
    # wrote (fly.mp4, say) is not there for this one, which would refuse to overwrite it.
    work = folder / f"python_{Path(page).stem}_{line}"
    work.mkdir(exist_ok=True)
    for name in (folder / ".inputs").read_text().split():  # not what shell lines wrote
        if not (work / name).exists():
            (work / name).symlink_to(folder / name)
    script = work / f"example_{Path(page).stem}_{line}.py"
    script.write_text(prelude + text, encoding="utf-8")
    done = run([sys.executable, str(script)], work)
    assert done.returncode == 0, f"{page}:{line}:\n{done.stderr}"


def test_the_readme_time_lapse_line_makes_a_time_lapse(folder):
    """The README's own recipe for a time-lapse writes one the reader sees as 20 time points."""
    (words,) = [w for _, _, w in shell_lines() if "write_time_lapse" in " ".join(w)]
    done = run([sys.executable, *words[1:]], folder)
    assert done.returncode == 0, done.stderr
    from vtkvol.io import read_volume

    assert read_volume(folder / "lapse.tif").metadata["time_points"] == 20

