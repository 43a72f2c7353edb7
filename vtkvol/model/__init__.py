"""Plain, serialisable state: no VTK, no Qt. See docs/architecture.md."""

from vtkvol.model.evented import EventedModel, Signal
from vtkvol.model.params import Invalidates, Param
from vtkvol.model.scene import (
    BLEND_MODES,
    Camera,
    Channel,
    CropBox,
    Illumination,
    Light,
    RenderSettings,
    SceneModel,
    SliceWeights,
    VolumeSource,
)
from vtkvol.model.transfer_function import TransferFunction

__all__ = [
    "BLEND_MODES",
    "Camera",
    "Channel",
    "CropBox",
    "EventedModel",
    "Illumination",
    "Invalidates",
    "Light",
    "Param",
    "RenderSettings",
    "SceneModel",
    "Signal",
    "SliceWeights",
    "TransferFunction",
    "VolumeSource",
]
