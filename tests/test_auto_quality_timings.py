"""Auto quality's cost sources (``default_timings``: ``$VTKVOL_BENCHMARKS`` or the shipped
measurements), ``choose_measured`` over the measured candidates, and the binning of large
volumes for the prediction. CPU only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vtkvol.engine.auto_quality import (
    TIMINGS_ENV,
    Timings,
    binned_for_prediction,
    choose_measured,
    default_timings,
    shipped_timings,
    spec_candidates,
)


def blob(n: int = 32) -> np.ndarray:
    """A soft ball of opacity ≤ 0.8 (a scene local shading serves poorly)."""
    z, y, x = np.mgrid[:n, :n, :n]
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2 - 2) ** 2)
    return (np.clip(1 - r / (0.3 * n), 0, 1) * 0.8).astype(np.float32)


def record(method: str, frame_ms: float, **parameters) -> dict:
    """A benchmark record: like the bench's, with every parameter's value (defaults filled)."""
    from vtkvol.engine.technique import installed_techniques

    cls = installed_techniques().get(method)
    values = {**(cls.defaults() if cls is not None else {}), **parameters}
    return {"method": method, "parameters": values, "size": "32x32x32",
            "frame_ms": frame_ms, "recompute_ms": 0.0, "renderer": "test GL", "ok": True}


def test_shipped_timings_cover_the_main_methods():
    timings = shipped_timings()
    methods = {r["method"] for r in timings.records}
    assert {"local", "shadow_volume", "cone_traced"} <= methods
    assert timings.source.startswith("shipped measurements (llvmpipe")
    assert default_timings({}) == timings


def test_named_results_file_is_used(tmp_path: Path):
    path = tmp_path / "benchmarks.json"
    path.write_text(json.dumps({"records": [record("local", 10.0)]}), encoding="utf-8")
    timings = default_timings({TIMINGS_ENV: str(path)})
    assert timings.source == f"measurements in {path}" and timings.note == ""
    assert [r["method"] for r in timings.records] == ["local"]


@pytest.mark.parametrize(("content", "why"), [
    (None, "cannot read"),
    ("{not json", "is not valid JSON"),
    ('{"runs": []}', 'has no "records" list (not a benchmarks.json)'),
    (json.dumps({"records": [{**record("local", float("nan"))}]}).replace("NaN", "NaN"),
     "has no successful timing records"),
    (json.dumps({"records": [{**record("local", 5.0), "size": "-3x2"}, "junk",
                             {**record("local", 5.0), "ok": False}]}),
     "has no successful timing records"),
])
def test_unusable_results_file_falls_back_to_shipped_and_says_why(tmp_path: Path, content, why):
    path = tmp_path / "benchmarks.json"
    if content is not None:
        path.write_text(content, encoding="utf-8")
    timings = default_timings({TIMINGS_ENV: str(path)})
    assert timings.records == shipped_timings().records
    assert timings.note.startswith(f"{TIMINGS_ENV}: ")
    assert why in timings.note and timings.note.endswith("using the " + timings.source)


def test_choose_measured_ranks_by_the_given_costs_and_names_the_unmeasured():
    # Only two measured settings, the shadow volume at quarter resolution the cheaper: it is
    # tried first and, the ball being smooth, passes; local shading is never evaluated.
    timings = Timings((record("local", 50.0),
                       record("shadow_volume", 10.0, model="transmittance",
                              resolution="quarter")), "test timings")
    choice = choose_measured(blob(), (1.0, 1.0, 1.0), [(0.3, 0.5, 0.8)], budget_ssim=0.9,
                             timings=timings)
    assert choice.label == "shadow_volume (model=transmittance, resolution=quarter)"
    assert [c["label"] for c in choice.considered] == [choice.label]
    assert choice.cost_source == "test timings" and choice.cost_ms == 10.0
    assert set(choice.unmeasured) == {c.label for c in spec_candidates()} - {
        "local", choice.label}
    assert "Costs: test timings." in choice.reason
    assert "Not measured there, so not considered: " in choice.reason


def test_choose_measured_without_any_measured_candidate_says_what_to_do():
    timings = Timings((record("no_such_method", 1.0),), "test timings")
    with pytest.raises(ValueError, match=rf"no.*measured cost in the test timings.*{TIMINGS_ENV}"):
        choose_measured(blob(), (1.0, 1.0, 1.0), [(0.0, 0.0, 1.0)], timings=timings)


def test_choose_measured_refuses_point_lights():
    from vtkvol.model.scene import Light

    with pytest.raises(ValueError, match="directional lights only"):
        choose_measured(blob(16), (1.0, 1.0, 1.0), [Light(kind="point")],
                        timings=shipped_timings())


def test_binning_keeps_small_volumes_and_averages_large_ones():
    small = blob(16)
    same, spacing = binned_for_prediction(small, (0.5, 0.5, 2.0), max_voxels=16**3)
    assert same is small or np.array_equal(same, small)
    assert spacing == (0.5, 0.5, 2.0)
    big = np.random.default_rng(1).random((30, 20, 41)).astype(np.float32)
    out, spacing = binned_for_prediction(big, (1.0, 2.0, 3.0), max_voxels=2000)
    k = 3  # 10 × 7 × 14 = 980 ≤ 2000 < 15 × 10 × 21 (k = 2)
    assert out.shape == (10, 7, 14) and spacing == (3.0, 6.0, 9.0)
    assert out[0, 0, 0] == pytest.approx(big[:k, :k, :k].mean(), rel=1e-5)
    assert out.min() >= big.min() and out.max() <= big.max()
    with pytest.raises(ValueError, match="max_voxels 0 must be at least 1"):
        binned_for_prediction(big, (1.0, 1.0, 1.0), max_voxels=0)
