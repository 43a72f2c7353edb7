"""Local shading: Blinn–Phong with the scene's lights, no shadows, no occlusion (the declaration).

The baseline: every other technique's frame time is reported as a ratio to this one, and its
image differs from this one only by the visibility terms (docs/architecture.md, "Lighting
models"). This module imports no VTK.
"""

from __future__ import annotations

from vtkvol.model.techniques import TechniqueSpec

TECHNIQUE = TechniqueSpec(
    name="local",
    label="Local shading",
    engine="vtkvol.plugins.local.technique:LocalShading",
    description=(
        "Gradient-based Blinn–Phong shading with up to four lights; no shadows or occlusion."
    ),
    lighting="surface",
)
