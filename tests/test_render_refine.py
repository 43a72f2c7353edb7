"""`vtkvol render` and `render_image` refine progressive methods to a stated iteration count or
time budget, and say where they stopped."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.cli import main
from vtkvol.engine.api import render_image
from vtkvol.io import VolumeData


def _cube() -> VolumeData:
    arr = np.zeros((1, 24, 24, 24), np.float32)
    arr[0, 6:18, 6:18, 6:18] = 1.0
    return VolumeData.from_array(arr, (1.0, 1.0, 1.0))


def test_render_image_stops_at_the_stated_iteration_count_even_past_the_default_end():
    seen: list[tuple[int, bool]] = []
    render_image(_cube(), size=(48, 48), method="hybrid_diffusion",
                 parameters={"iterations_per_frame": 1, "max_iterations": 4}, iterations=6,
                 on_refined=lambda it, done, s: seen.append((it, done)))
    # max_iterations 4 would have ended at 4: the stated count wins and is reached exactly
    assert seen == [(6, True)]


def test_a_zero_time_budget_stops_refining_at_once():
    seen: list[tuple[int, bool]] = []
    render_image(_cube(), size=(48, 48), method="convection_diffusion",
                 parameters={"iterations_per_frame": 1}, max_seconds=0.0,
                 on_refined=lambda it, done, s: seen.append((it, done)))
    (iterations, converged), = seen
    assert not converged and 1 <= iterations <= 3


@pytest.mark.parametrize("bad", [0, -3, True])
def test_render_image_rejects_a_bad_iteration_count(bad):
    with pytest.raises(ValueError, match="iterations must be a whole number"):
        render_image(_cube(), size=(32, 32), iterations=bad)


def test_cli_reports_the_refinement_and_rejects_bad_budgets(tmp_path, capsys):
    out = tmp_path / "ms.png"
    rc = main(["render", "sample", "-o", str(out), "--size", "48", "48", "--method",
               "hybrid_diffusion", "--iterations", "3", "--param", "iterations_per_frame=1"])
    assert rc == 0 and out.stat().st_size > 0
    assert "refined to 3 iterations" in capsys.readouterr().out
    for args, message in ((["--iterations", "0"], "--iterations must be at least 1"),
                          (["--time-budget", "-1"], "--time-budget must be"),
                          (["--time-budget", "nan"], "--time-budget must be")):
        target = tmp_path / "never.png"
        rc = main(["render", "sample", "-o", str(target), "--size", "32", "32", *args])
        err = capsys.readouterr().err
        assert rc == 2 and message in err and not target.exists()
