"""Local shading: Blinn–Phong with the scene's lights, no shadows, no occlusion.

The baseline: every other technique's frame time is reported as a ratio to this one, and its
image differs from this one only by the visibility terms (see resources/shaders/host_lighting.glsl).
"""

from __future__ import annotations

from typing import ClassVar

from vtkvol.engine.technique import Technique


class LocalShading(Technique):
    NAME: ClassVar[str] = "local"
    LABEL: ClassVar[str] = "Local shading"
    DESCRIPTION: ClassVar[str] = (
        "Gradient-based Blinn–Phong shading with up to four lights; no shadows or occlusion."
    )
    PARAMETERS = ()
    SHADER: ClassVar[str] = "local_shading.glsl"
