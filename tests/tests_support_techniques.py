"""Techniques registered by the Qt tests (a broken one and a progressive one)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from vtkvol.engine import shaders
from vtkvol.engine.technique import Technique
from vtkvol.model.techniques import TechniqueSpec

BROKEN_SPEC = TechniqueSpec(name="broken_ui", label="Broken", engine=f"{__name__}:Broken")
REFINING_SPEC = TechniqueSpec(name="refining_ui", label="Refining",
                              engine=f"{__name__}:Refining", capabilities={"progressive"})


class Broken(Technique):
    SPEC = BROKEN_SPEC
    SHADER: ClassVar[str] = "broken.glsl"

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        return shaders.parse("//@inject //VTK::ComputeLighting::Dec pre before\n"
                             "float vv_light_visibility(int l, vec3 p, vec3 d) { return x; }\n",
                             "broken.glsl")


class Refining(Technique):
    SPEC = REFINING_SPEC
    SHADER: ClassVar[str] = ""

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        return []

    def prepare(self, changes: Any, values: Mapping[str, Any]) -> None:
        self.iteration = 1 if changes.reset_accumulation else self.iteration + 1
        self.converged = self.iteration >= 5
