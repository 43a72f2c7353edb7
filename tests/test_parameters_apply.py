"""Every declared parameter of every technique changes the image exactly when its
``applies_when`` holds (issue 21, "Parameters that do nothing say so").

One small scene per technique (a 24³ sphere over a slab, lit from above and beside, a 48² image):
for each parameter, the image with its default is compared with the image after changing it,

* where it applies (its ``applies_when`` conditions set to an enabling value): some other value
  must change the image (at least :data:`CHANGED` levels somewhere);
* where it does not (one condition set to a value outside its list): the image must stay the
  same (at most :data:`SAME` levels anywhere), and the host warns once naming the enabling
  parameter.

Parameters that legitimately leave this scene unchanged are listed in :data:`NO_CHANGE` with the
reason; for them the test asserts the opposite (the image stays the same), so the list cannot
hide a parameter that silently started or stopped doing something.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.offscreen import grab, simple_volume_scene
from vtkvol.model.params import Param
from vtkvol.model.scene import Light
from vtkvol.model.techniques import technique_specs
from vtkvol.reference.phantoms import phantom_sphere_over_slab

pytestmark = pytest.mark.gl

#: A change of at least this many 8-bit levels in some pixel counts as "changes the image".
CHANGED = 3
#: At most this many levels anywhere counts as "the same image".
SAME = 1

#: (technique, parameter) → why changing it leaves this scene's converged image unchanged.
NO_CHANGE: dict[tuple[str, str], str] = {
    **{(name, "backend"): "the GPU and the numpy path compute the same light (their agreement "
       "is tested per technique); the parameter chooses where, not what"
       for name in ("cone_traced", "convection_diffusion", "hybrid_diffusion", "shadow_volume",
                    "translucency")},
    ("convection_diffusion", "iterations_per_frame"): "the pace of refinement: the image is "
    "taken once converged, which is the same image however many iterations a frame runs",
    ("hybrid_diffusion", "iterations_per_frame"): "the pace of refinement (as for "
    "convection_diffusion); max_iterations fixes the end point",
    ("path_traced", "frame_budget_ms"): "the pace of refinement: the image is taken once "
    "max_iterations are done, whatever the time each frame may take",
    **{(name, "max_iterations"): "an end point, not a restart (it invalidates the frame "
       "only): lowering it keeps the iterations already accumulated, and raising it past "
       "convergence adds none" for name in ("convection_diffusion", "hybrid_diffusion")},
    ("hybrid_diffusion", "light_sampling"): "this scene has one light: sampling one light per "
    "path or all of them is the same estimator",
    ("convection_diffusion", "absorption_mapping"): "it maps the published model's absorption "
    "σ_a = (1 − albedo)·σ_t, which is zero at the default albedo of 1, so both mappings absorb "
    "nothing (its effect at albedo < 1 is in tests/test_convection_diffusion.py); the source "
    "model ray-marches its direct light instead (not applying there is checked here)",
}

#: Values in place of the defaults for every image of a technique, so that its converged image
#: is reached in a few frames at 24³ (progressive techniques end at a fixed, small number of
#: iterations; the path tracer's paths are short). These parameters are tested too, from here.
BASE: dict[str, dict[str, Any]] = {
    # traced_orders 0: the traced orders draw other random numbers on the GPU and in numpy
    # (compared in the mean in their own tests), so "backend" could not leave the image
    # unchanged with them; traced_orders and traced_paths are tested from their own enabling
    # values (traced_orders 1 for traced_paths)
    "convection_diffusion": {"traced_paths": 4, "traced_orders": 0},
    "hybrid_diffusion": {"max_iterations": 4, "traced_orders": 0},
    "path_traced": {"max_iterations": 2, "max_bounces": 4, "paths_per_iteration": 1},
}


#: Values to change to where the range's ends would only cost time (a path tracer with 64
#: paths per iteration or 256 bounces on llvmpipe).
CHEAP: dict[tuple[str, str], tuple[Any, ...]] = {
    ("convection_diffusion", "traced_paths"): (2,),
    ("hybrid_diffusion", "max_iterations"): (2,),
    ("path_traced", "max_iterations"): (1,),
    ("path_traced", "paths_per_iteration"): (2,),
    ("path_traced", "max_bounces"): (1,),
}


def _alternatives(method: str, p: Param, default: Any) -> Iterator[Any]:
    """Other valid values of ``p``, the most different first."""
    if (method, p.name) in CHEAP:
        yield from CHEAP[(method, p.name)]
    elif p.kind == "bool":
        yield not default
    elif p.kind == "choice":
        yield from (c for c in p.choices if c != default)
    else:
        lo, hi = p.range if p.range is not None else (default / 4, default * 4 + 1)
        candidates = [hi, lo, (lo + hi) / 2]
        if p.kind == "int":  # the smallest step last: max_iterations 1 (0 = until converged)
            candidates.append(lo + 1)
        seen = {default}
        for value in candidates:
            value = round(value) if p.kind == "int" else float(value)
            if value not in seen:
                seen.add(value)
                yield value


def _enabling(p: Param) -> dict[str, Any]:
    """Values of the parameters ``p`` depends on under which it applies."""
    return {other: allowed[0] for other, allowed in p.applies_when}


def _disabling(p: Param, spec: Any) -> dict[str, Any] | None:
    """Values under which ``p`` does not apply (its first condition set outside its list),
    or None when ``p`` always applies."""
    if not p.applies_when:
        return None
    other, allowed = p.applies_when[0]
    q = spec.parameter(other)
    choices = q.choices if q.kind == "choice" else (True, False)
    off = next(c for c in choices if c not in allowed)
    return {**_enabling(p), other: off}


class Rig:
    """One technique lighting the phantom in a 48² window."""

    def __init__(self, method: str) -> None:
        vol = phantom_sphere_over_slab(24)
        self.rw, ren, volume = simple_volume_scene(vol, size=(48, 48), elevation=35.0,
                                                   azimuth=20.0)
        # 15° (soft shadows): far from the techniques' custom cone and softness defaults, so that
        # choosing "light size" or "custom" shows.
        light = Light(direction=(0.6, -0.3, 1.0), size=15.0)
        self.il = Illuminator(volume, ren, method=method, lights=[light])
        self._images: dict[tuple, np.ndarray] = {}
        self.renders = 0

    def image(self, values: dict[str, Any]) -> np.ndarray:
        """The converged image with the technique's parameters set to ``values`` (rendered
        once per set of values: the techniques are deterministic, seeds included)."""
        key = tuple(sorted(values.items()))
        if key not in self._images:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # inert values are this test's point
                self.il.set_parameters(**values)
            self.il.converge()
            self._images[key] = grab(self.rw).astype(np.int16)
            self.renders += 1
        return self._images[key]

    def close(self) -> None:
        self.il.release()
        self.rw.Finalize()


def _cases() -> Iterator[Any]:
    for name, spec in technique_specs().items():
        if spec.parameters:
            yield pytest.param(name, id=name)


@pytest.mark.parametrize("method", list(_cases()))
def test_every_parameter_changes_the_image_exactly_when_it_applies(method: str) -> None:
    spec = technique_specs()[method]
    rig = Rig(method)
    defaults = {**spec.defaults(), **BASE.get(method, {})}
    problems: list[str] = []
    try:
        for p in spec.parameters:
            base = {**defaults, **_enabling(p)}
            reference = rig.image(base)
            diffs = []
            for alt in _alternatives(method, p, base[p.name]):
                diff = int(np.abs(rig.image({**base, p.name: alt}) - reference).max())
                diffs.append((alt, diff))
                if diff >= CHANGED:
                    break
            largest = max(d for _, d in diffs)
            if (method, p.name) in NO_CHANGE:
                if largest > SAME:
                    problems.append(f"{p.name} is listed as not changing this scene but "
                                    f"changed it by {largest} levels ({diffs})")
            elif largest < CHANGED:
                problems.append(f"{p.name} applies under {_enabling(p) or 'any values'} but "
                                f"changed no pixel by {CHANGED} levels or more: {diffs}")
            off = _disabling(p, spec)
            if off is None:
                continue
            inert = {**defaults, **off}
            reference = rig.image(inert)
            alt = next(_alternatives(method, p, inert[p.name]))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rig.il.set_parameters(**inert)  # the image may have come from the cache
            rig.il._inert_warned.clear()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                rig.il.set_parameters(**{p.name: alt})
            named = [str(w.message) for w in caught if p.name in str(w.message)]
            if len(named) != 1 or next(iter(off)) not in named[0]:
                problems.append(f"{p.name} set while inert under {off}: warnings {named}")
            diff = int(np.abs(rig.image({**inert, p.name: alt}) - reference).max())
            if diff > SAME:
                problems.append(f"{p.name} does not apply under {off} but changed the image "
                                f"by {diff} levels")
    finally:
        rig.close()
    assert not problems, f"{method}:\n  " + "\n  ".join(problems)
