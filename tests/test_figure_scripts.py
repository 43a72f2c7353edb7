"""The README's figure scripts refuse a data folder without their stack in one ``vtkvol:`` line
and write nothing (they render for minutes; a wrong folder must not get that far)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(("script", "stack"), [
    ("hero-image.py", "platynereis_nuclei_labels_256x256x103.tif"),
    ("renderer-screenshots.py", "Bead_Image1_crop.tif"),
])
def test_a_folder_without_the_stack_is_refused_in_one_line(tmp_path, script, stack):
    out = tmp_path / "figure.png"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / script), str(tmp_path),
                           "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip() == (f"vtkvol: {tmp_path / stack}: not found; pass the shared "
                                   "data folder (see its SOURCES.md)")
    assert not out.exists()
