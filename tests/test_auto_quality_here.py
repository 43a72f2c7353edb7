"""Auto quality as product code (issues 21 and 25): it lives outside the benchmark, quotes this
machine's measured frames, and says its choice in the words of the app."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from vtkvol.engine.auto_quality import (
    Candidate,
    Choice,
    FrameTimes,
    Timings,
    choose_measured,
    duration_words,
    setting_words,
    shipped_timings,
)


def test_the_app_and_the_product_module_do_not_import_the_benchmark():
    code = ("import sys; import vtkvol.engine.auto_quality, vtkvol.ui.auto_quality; "
            "print(sorted(m for m in sys.modules if m.startswith('vtkvol.bench')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


@pytest.mark.parametrize(("ms", "words"), [
    (4.0, "about 10 ms"), (445.0, "about 450 ms"), (4200.0, "about 4.2 s"),
    (4000.0, "about 4 s"), (20_400.0, "about 20 s"), (150_000.0, "about 2 min"),
    (math.nan, "an unknown time")])
def test_durations_in_words(ms, words):
    assert duration_words(ms) == words


def test_settings_in_the_apps_words():
    assert setting_words("local", {}) == "Local shading"
    words = setting_words("cone_traced", {"ao_mode": "hemisphere", "ao_cones": "12",
                                          "shadows": True})
    assert words == ("Cone-traced AO and soft shadows (ambient occlusion: Hemisphere (per "
                     "sample), AO cones: 12)")


def _timings(local: float, shadow: float) -> Timings:
    def record(method: str, ms: float, **parameters) -> dict:
        return {"method": method, "parameters": parameters, "size": "32x32x32",
                "frame_ms": ms, "recompute_ms": 0.0, "renderer": "test", "ok": True}

    return Timings((record("local", local), record("shadow_volume", shadow)), "test figures")


def test_frame_times_measured_here_scale_the_settings_not_shown_yet():
    frames = FrameTimes()
    for ms in (3900.0, 4100.0, 4000.0):
        frames.record("local", {}, ms)
    frames.record("local", {}, -1.0)  # ignored
    local, shadow = Candidate("local"), Candidate("shadow_volume")
    costs, here = frames.costs([local, shadow], {local: 100.0, shadow: 300.0},
                               {"local": {}, "shadow_volume": {}}, _timings(100, 300),
                               32**3)
    assert here == {local}
    assert costs[local] == pytest.approx(4000.0)
    assert costs[shadow] == pytest.approx(12_000.0)  # 3× local, as the shipped figures say
    assert FrameTimes().costs([local], {local: 100.0}, {"local": {}}, _timings(100, 300),
                              32**3) == ({}, set())


def _ball() -> np.ndarray:
    z, y, x = np.indices((24, 24, 24)) - 11.5
    return (np.sqrt(x * x + y * y + z * z) < 8).astype(np.float32) * 0.6


def test_a_choice_quotes_this_machines_frames_not_the_shipped_ones():
    frames = FrameTimes()
    from vtkvol.model.techniques import get_spec

    frames.record("local", get_spec("local").defaults(), 4000.0)
    shipped = shipped_timings()
    without = choose_measured(_ball(), (1.0, 1.0, 1.0), [(0.3, 0.5, 0.8)], budget_ssim=0.3,
                              timings=shipped)
    with_frames = choose_measured(_ball(), (1.0, 1.0, 1.0), [(0.3, 0.5, 0.8)],
                                  budget_ssim=0.3, timings=shipped, frames=frames)
    assert without.method == with_frames.method == "local"  # 0.3: the cheapest passes
    assert not without.cost_here and with_frames.cost_here
    assert with_frames.cost_ms == pytest.approx(4000.0)
    assert with_frames.measured_here == ("local",)
    assert with_frames.cost_source.startswith("frames measured on this machine (local; the "
                                              "others scaled by the shipped measurements")


def test_the_app_says_a_frame_here_in_seconds_with_the_methods_title():
    from vtkvol.ui.auto_quality import describe

    choice = Choice("cone_traced", {"ao_mode": "hemisphere", "ao_cones": "12"}, 0.985,
                    4200.0, "reason", ({"label": "local", "method": "local", "parameters": {},
                                        "predicted_ssim": 0.9, "cost_ms": 1500.0},),
                    cost_source="frames measured on this machine", cost_here=True)
    outcome = describe(choice, 0.98)
    assert outcome.summary == (
        "Auto picked Cone-traced AO and soft shadows (ambient occlusion: Hemisphere (per "
        "sample), AO cones: 12): predicted similarity to the reference 0.985 (goal 0.98); "
        "about 4.2 s a frame here.")
    assert "  Local shading: similarity 0.900, about 1.5 s a frame here" in outcome.details
    shipped = describe(Choice("local", {}, 0.99, 445.0, "reason"), 0.98)
    assert "445" not in shipped.summary and "450 ms" not in shipped.summary
    assert shipped.summary.endswith("ranked by another machine's measurements (no frame "
                                    "measured here yet).")


def _ball_over_slab() -> np.ndarray:
    """20³: a ball resting on a slab, so that the ambient light is occluded where they meet."""
    z, y, x = np.indices((20, 20, 20)).astype(float)
    ball = (x - 9.5) ** 2 + (y - 9.5) ** 2 + (z - 10.0) ** 2 < 5.0**2
    slab = z < 5
    return ((ball | slab) * 0.7).astype(np.float32)


def test_each_ambient_occlusion_variant_gets_a_prediction_of_its_own():
    from vtkvol.engine.auto_quality import choose

    variants = [Candidate("cone_traced", {"ao_mode": "off"}),
                Candidate("cone_traced", {"ao_mode": "view_cone"}),
                Candidate("cone_traced", {"ao_mode": "hemisphere", "ao_cones": "1"}),
                Candidate("cone_traced", {"ao_mode": "hemisphere", "ao_cones": "6"}),
                Candidate("cone_traced", {"ao_mode": "baked_hemisphere", "ao_cones": "6"})]
    choice = choose(_ball_over_slab(), (1.0, 1.0, 1.0), [(0.3, 0.5, 0.8)], budget_ssim=1.0,
                    candidates=variants)
    scores = [c["predicted_ssim"] for c in choice.considered]
    assert len(scores) == 5
    assert len({round(s, 4) for s in scores}) == 5, scores  # all different
    # Six cones about the normal come closer to the Monte-Carlo AO than one (measured here:
    # 0.335 against 0.326; AO off 0.513, view cone 0.280, baked 6 cones 0.286 — cone tracing
    # is coarse on a 20³ scene).
    assert scores[3] > scores[2]
