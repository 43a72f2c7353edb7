"""Local shading, engine part: no precomputation, no textures; the host's defaults for every
visibility hook (``shaders/local.glsl``)."""

from __future__ import annotations

from typing import ClassVar

from vtkvol.engine.technique import Technique
from vtkvol.plugins.local import TECHNIQUE


class LocalShading(Technique):
    SPEC = TECHNIQUE
    SHADER: ClassVar[str] = "local.glsl"
