"""The whole user-visible state of a view: what a session file stores.

Coordinate conventions (docs/architecture.md):

* **World space** is physical, in **µm**, axes x, y, z, with the volume's first voxel centre at
  the origin: voxel (i, j, k) sits at (i·sx, j·sy, k·sz).
* Arrays are indexed ``[c, z, y, x]``; per-axis tuples in the model are ordered **(x, y, z)**.
* Light directions point **from the scene towards the light**, in world space.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from vtkvol.model.evented import EventedModel
from vtkvol.model.gamma import GAMMA_DEFAULT, GAMMA_MAX, GAMMA_MIN
from vtkvol.model.renderers import RendererName, unsupported_reason
from vtkvol.model.transfer_function import RGB, TransferFunction, TransferFunction2D

BlendMode = Literal["composite", "mip", "minip", "average", "additive", "isosurface"]
BLEND_MODES: tuple[str, ...] = BlendMode.__args__  # type: ignore[attr-defined]
#: PyVista's names for blend modes (``Plotter.add_volume(blending=...)``,
#: ``mapper.blend_mode``), accepted wherever a blend mode is set and stored under our name.
BLEND_ALIASES: dict[str, str] = {"maximum": "mip", "minimum": "minip"}
ChannelMixing = Literal["additive", "composite"]
#: Scalar reconstruction along the ray (docs/reconstruction.md): the GPU's trilinear filter, or
#: Csébfalvi's corrected trilinear filter (seed 001 eq. 2.55), near Catmull-Rom quality; or the
#: nearest voxel, for label images (vtkvol.model.labels): a trilinear sample between labels 3 and
#: 40 is some label in between, which would colour the boundary with labels that are not there.
Interpolation = Literal["trilinear", "corrected", "nearest"]
#: How two to four channels are lit (RenderSettings.multichannel_lighting).
MultichannelLighting = Literal["per_channel", "shared"]
MULTICHANNEL_LIGHTINGS: tuple[str, ...] = MultichannelLighting.__args__  # type: ignore[attr-defined]
Vec3 = tuple[float, float, float]
#: Largest angular radius (°) of a directional light: wider is no longer a "direction".
MAX_ANGULAR_RADIUS = 45.0


def _finite3(v: Vec3, what: str) -> Vec3:
    if not all(math.isfinite(c) for c in v):
        raise ValueError(f"{what} {v} must be finite")
    return v


class VolumeSource(EventedModel):
    """Where the data came from and how it was read (not the voxels themselves)."""

    path: str | None = None  #: file or folder; ``None`` for the built-in sample or in-memory data
    voxel_size_um: Vec3 | None = None  #: user override (x, y, z) in µm; ``None`` = from metadata
    time_index: int = Field(0, ge=0)
    fit: Literal["auto", "crop", "subsample", "average", "none"] = "auto"
    size_bytes: int | None = None  #: recorded on save to detect a changed file
    sha256_head: str | None = None  #: checksum of the first MiB, recorded on save
    shape_zyx: tuple[int, int, int] | None = None  #: shape after reading, recorded on save
    channels: int | None = None
    #: Multiscale files: the pyramid level shown (0 = finest); ``None`` = the finest level that
    #: fits the GPU-memory budget, chosen when the file is opened.
    level: int | None = Field(None, ge=0)
    #: Multiscale files: the region shown ("Refine selection"), ((x0, x1), (y0, y1), (z0, z1))
    #: in µm of pyramid space (the finest level's first voxel centre at 0); ``None`` = all.
    region_um: tuple[tuple[float, float], tuple[float, float], tuple[float, float]] | None = None

    @field_validator("voxel_size_um")
    @classmethod
    def _positive(cls, v: Vec3 | None):
        if v is not None and not all(c > 0 for c in _finite3(v, "voxel size")):
            raise ValueError(f"voxel size {v} µm must be positive")
        return v

    @field_validator("region_um")
    @classmethod
    def _region(cls, v):
        if v is None:
            return v
        for axis, (lo, hi) in zip("xyz", v, strict=True):
            if not (math.isfinite(lo) and math.isfinite(hi)):
                raise ValueError(f"region {axis} = ({lo}, {hi}) µm must be finite")
            if not lo <= hi:
                raise ValueError(f"region {axis} = ({lo}, {hi}) µm must be increasing")
        return v


class LabelDisplay(EventedModel):
    """How a channel that holds a label image (segmentation: an integer id per voxel, 0 =
    background) is shown (vtkvol.model.labels): every id in its own categorical colour, at
    ``opacity`` (per opacity unit distance, 0…1), except the ids in ``hidden``, which are
    transparent and cast no shadow. The channel's ``tf`` holds the resulting step function
    (:func:`vtkvol.model.labels.apply_labels` writes both), so a renderer needs nothing else."""

    opacity: float = Field(1.0, ge=0.0, le=1.0)
    hidden: list[int] = Field(default_factory=list)

    @field_validator("hidden")
    @classmethod
    def _sorted_ids(cls, v: list[int]):
        return sorted(set(v))


class Channel(EventedModel):
    """One fluorescence channel (one component of the rendered volume)."""

    name: str = "channel"
    visible: bool = True
    color: RGB = (1.0, 1.0, 1.0)  #: tint used by presets and the channel list
    tf: TransferFunction = Field(default_factory=TransferFunction)
    tf_linked_to: int | None = None  #: index of a channel whose TF this one follows
    #: Which transfer function classifies the channel: the 1-D ``tf`` over values, or the 2-D
    #: ``tf2d`` over value × gradient magnitude. Switching keeps both, so nothing is lost.
    tf_mode: Literal["1d", "2d"] = "1d"
    tf2d: TransferFunction2D = Field(default_factory=TransferFunction2D)
    #: Gamma on the contrast-limited value (unit-free; vtkvol.model.gamma): 1 = the transfer
    #: function as drawn, < 1 brighter mid-tones, > 1 darker; the limits look the same. It
    #: applies to the 1-D transfer function, not to label channels or 2-D ones.
    gamma: float = Field(GAMMA_DEFAULT, ge=GAMMA_MIN, le=GAMMA_MAX)
    #: Set when the channel is a label image shown with categorical colours; None = values
    #: are intensities.
    labels: LabelDisplay | None = None

    @field_validator("color")
    @classmethod
    def _rgb(cls, v: RGB):
        if not all(0.0 <= c <= 1.0 for c in v):
            raise ValueError(f"channel colour {v} must lie in 0…1")
        return v


class Light(EventedModel):
    """A light in world space.

    ``kind="directional"``: parallel light arriving along ``-direction`` (``direction`` points
    from the scene towards the light). ``kind="point"``: a point light at ``position`` (µm).

    ``size`` is the light's physical extent, which sets how soft its shadows are: the angular
    radius in **degrees** for a directional light (the sun is about 0.27°), the radius in **µm**
    for a point light (a sphere). 0 = an ideal light with hard shadows. Every ``surface``
    technique approximates this same light, and the benchmark's reference averages exact
    transmittance over its extent.

    ``falloff``: ``"none"`` (irradiance independent of distance) or ``"inverse_square"``
    (point lights only): irradiance scales by (d₀/r)², with d₀ the distance from the light to
    the volume's centre, so ``intensity`` is the irradiance at the centre either way.

    :meth:`angular_radius_deg` is the directional size as techniques use it (at most
    :data:`MAX_ANGULAR_RADIUS`; kept as a plain field so switching the kind never fails).
    """

    kind: Literal["directional", "point"] = "directional"
    direction: Vec3 = (0.3, 0.5, 0.8)
    position: Vec3 = (0.0, 0.0, 1000.0)
    color: RGB = (1.0, 1.0, 1.0)
    intensity: float = Field(1.0, ge=0.0, le=100.0)
    enabled: bool = True
    size: float = Field(0.0, ge=0.0, le=1e6)  #: ° (directional; above 45° counts as 45°) or µm
    falloff: Literal["none", "inverse_square"] = "none"

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v: Vec3):
        _finite3(v, "light direction")
        squared = sum(c * c for c in v)
        if not math.isfinite(squared):
            # Every consumer normalises it; with an infinite length the direction becomes
            # (0, 0, 0) or NaN and the light silently vanishes.
            raise ValueError(f"light direction {v} is too long (its squared length overflows); "
                             "give a unit vector")
        if squared < 1e-12:
            raise ValueError("light direction must not be the zero vector")
        return v

    @field_validator("position")
    @classmethod
    def _pos(cls, v: Vec3):
        return _finite3(v, "light position")

    def angular_radius_deg(self) -> float:
        """Angular radius (°) of a directional light, clamped to :data:`MAX_ANGULAR_RADIUS`."""
        return min(self.size, MAX_ANGULAR_RADIUS)

    @field_validator("color")
    @classmethod
    def _rgb(cls, v: RGB):
        if not all(0.0 <= c <= 1.0 for c in v):
            raise ValueError(f"light colour {v} must lie in 0…1")
        return v


class CropBox(EventedModel):
    """Per-axis ranges in µm (world space). ``None`` for an axis means the full extent."""

    x: tuple[float, float] | None = None
    y: tuple[float, float] | None = None
    z: tuple[float, float] | None = None

    @field_validator("x", "y", "z")
    @classmethod
    def _increasing(cls, v: tuple[float, float] | None):
        if v is not None and not v[0] < v[1]:
            raise ValueError(f"range {v} µm must be increasing")
        return v

    def as_bounds(self, full: tuple[float, float, float, float, float, float]):
        """(xmin, xmax, ymin, ymax, zmin, zmax) in µm, clipped to ``full``."""
        out = list(full)
        for i, rng in enumerate((self.x, self.y, self.z)):
            if rng is not None:
                out[2 * i] = max(full[2 * i], rng[0])
                out[2 * i + 1] = min(full[2 * i + 1], rng[1])
        return tuple(out)


WeightPoints = list[tuple[float, float]]


class SliceWeights(EventedModel):
    """Slice-contribution functions (seed 002 §2.11): one weighting function per axis.

    Each is a list of ``(position, weight)`` with position normalised to 0…1 across the
    volume's extent on that axis and weight in 0…1, linearly interpolated. A sample's RGBA is
    multiplied by wX(x)·wY(y)·wZ(z); samples whose weight is below 1e-10 are discarded.
    """

    x: WeightPoints = Field(default_factory=lambda: [(0.0, 1.0), (1.0, 1.0)])
    y: WeightPoints = Field(default_factory=lambda: [(0.0, 1.0), (1.0, 1.0)])
    z: WeightPoints = Field(default_factory=lambda: [(0.0, 1.0), (1.0, 1.0)])

    @field_validator("x", "y", "z")
    @classmethod
    def _points(cls, v: WeightPoints):
        if not v:
            raise ValueError("a weighting function needs at least one point")
        for pos, w in v:
            if not (0.0 <= pos <= 1.0 and 0.0 <= w <= 1.0):
                raise ValueError(f"weight point {(pos, w)}: position and weight must lie in 0…1")
        return sorted(v)

    @property
    def is_identity(self) -> bool:
        return all(all(w == 1.0 for _, w in pts) for pts in (self.x, self.y, self.z))


class Illumination(EventedModel):
    """The illumination technique and the parameter values of every technique used so far.

    Values are validated against the technique's declared ``PARAMETERS`` by the engine (which
    knows the installed techniques); the model only stores them.

    ``auto``: the app picks ``method`` and its parameters itself, as the cheapest setting whose
    predicted image error meets ``auto_budget_ssim`` (predicted SSIM against the reference,
    0…1; :func:`vtkvol.bench.choose`), and picks again when the data, a TF or a light changes.
    ``method`` and ``parameters`` then hold the last pick, so a file saved with Auto renders
    the same where nothing re-chooses (``vtkvol render``).
    """

    method: str = "local"
    parameters: dict[str, dict[str, Any]] = Field(default_factory=dict)
    auto: bool = False
    auto_budget_ssim: float = Field(0.98, gt=0.0, le=1.0)

    def values_for(self, method: str | None = None) -> dict[str, Any]:
        return dict(self.parameters.get(method or self.method, {}))

    def set_value(self, name: str, value: Any, method: str | None = None) -> None:
        method = method or self.method
        params = {k: dict(v) for k, v in self.parameters.items()}
        params.setdefault(method, {})[name] = value
        self.parameters = params


#: Largest magnitude of a camera or light coordinate and of a parallel scale that a session or
#: keyframe file may hold (µm, i.e. 1000 km): far beyond any microscope's field, yet small
#: enough that differences, norms and cross products stay finite, in float32 on the GPU too
#: (1e12² = 1e24 < 3.4e38). 1e308 µm made a blank image or a misleading overflow message.
MAX_COORDINATE_UM = 1e12


class Camera(EventedModel):
    """Camera in world space (µm). ``None`` position means "reset to fit the volume"."""

    position: Vec3 | None = None
    focal_point: Vec3 | None = None
    view_up: Vec3 = (0.0, 1.0, 0.0)
    view_angle: float = Field(30.0, gt=0.0, lt=180.0)  #: degrees
    parallel_projection: bool = False
    parallel_scale: float = Field(1.0, gt=0.0)


class RenderSettings(EventedModel):
    """Ray-casting settings. Distances are in **voxels** of the smallest voxel edge."""

    blend_mode: BlendMode = "composite"
    channel_mixing: ChannelMixing = "additive"
    sample_distance: float = Field(0.5, gt=0.01, le=8.0)  #: voxels, at full quality
    interactive_sample_distance: float = Field(2.0, gt=0.01, le=16.0)  #: voxels, while moving
    interactive_image_factor: float = Field(2.0, ge=1.0, le=8.0)  #: image subsampling while moving
    opacity_unit_distance: float | None = Field(None, gt=0.0)  #: µm; None = smallest voxel edge
    jitter: bool = True
    shade: bool = True
    ambient: float = Field(0.3, ge=0.0, le=1.0)
    diffuse: float = Field(0.7, ge=0.0, le=2.0)
    specular: float = Field(0.2, ge=0.0, le=2.0)
    specular_power: float = Field(20.0, ge=1.0, le=128.0)
    #: Exposure: a linear factor on the shaded colour (1 = as lit; 2 = one stop brighter).
    #: With ``auto_exposure`` it multiplies the automatic factor.
    exposure: float = Field(1.0, ge=0.05, le=16.0)
    #: Automatic exposure (docs/architecture.md, "Lighting models"): shadows, ambient
    #: occlusion and attenuation take light away, so the engine measures the object's mean
    #: brightness with the method's light and with the same lights unobstructed (local
    #: shading's) on a coarse frame, and raises the exposure until the first is 90 % of the
    #: second (never lowers it; at most 4×). Surface methods on the ray caster only.
    auto_exposure: bool = True
    #: Sky fill: light of this strength (× the light colour white, 0…1) reaching every shaded
    #: sample from all around, never shadowed or occluded, so shadowed parts are darker but
    #: not black. 0 = none (shadows may go black).
    fill: float = Field(0.15, ge=0.0, le=1.0)
    isosurface_value: float | None = None  #: data units; None = mid of the first channel's TF
    background: RGB = (0.08, 0.08, 0.1)
    #: Scattering material of ``medium`` techniques (docs/architecture.md, "Lighting models"):
    #: single-scattering albedo (0…1) and Henyey–Greenstein asymmetry g (0 = isotropic,
    #: > 0 forward). Surface techniques ignore both.
    albedo: float = Field(1.0, ge=0.0, le=1.0)
    phase_g: float = Field(0.0, ge=-0.99, le=0.99)
    #: Scalar reconstruction filter of the ray's samples (composite blend; unit-free choice).
    #: ``corrected`` reuses the six fetches of the shading gradient, so shaded it costs almost
    #: nothing; unshaded it adds six texture fetches per sample.
    interpolation: Interpolation = "trilinear"
    #: Empty-space skipping (unit-free switch): rays jump over bricks of 8³ voxels where no
    #: sample can be visible (transfer function, crop, slice weights). Exact (the image does
    #: not change); applies to composite, additive and, with non-decreasing opacity, MIP
    #: blending. docs/empty-space-skipping.md.
    empty_space_skipping: bool = True
    #: Lighting of two to four channels on a composite blend (unit-free choice).
    #: ``per_channel`` (VTK's, the exact reference): every channel is lit with its own normal
    #: (its gradient) and material. ``shared``: every channel is classified unlit (TF colour and
    #: opacity), and the sample is lit ONCE on the mixed colour (the channels' colours weighted
    #: by opacity × visibility, as the channel mixing weights them) with ONE normal — the
    #: weighted sum of the channels' unit normals (each VTK's normalised gradient; turned to the
    #: viewer first with two-sided lighting), from the gradient fetches already shared — and
    #: one material (ambient, diffuse, specular, power: the same weighted mean). All lights and
    #: the technique's shadows, transmittance, ambient occlusion and in-scattering are evaluated
    #: once instead of once per channel. Where one channel is visible at a sample the result is
    #: that channel's own lighting; where channels overlap, their normals are averaged.
    #: ``medium`` techniques (diffusion, path tracing) have no normal: ``shared`` lights the
    #: mixed colour once with the mixed ambient coefficient, which changes nothing visible
    #: unless channels' materials differ. No effect on one channel, on unshaded rendering, on
    #: blends other than composite, with 2-D transfer functions, gradient opacity or VTK's
    #: volumetric scattering (those keep per-channel lighting). docs/benchmarks.md,
    #: "Multi-channel frames", has the cost (lower with several lights, cone tracing and
    #: translucency; about the same with one light and local shading or the shadow volume) and
    #: the measured image difference.
    multichannel_lighting: MultichannelLighting = "per_channel"
    #: Pre-integrated classification (unit-free switch; docs/rendering.md): each sample
    #: classifies the segment from the previous sample instead of the point, from a 2-D table
    #: of the transfer function integrated over the sample distance, so a sharp TF (a narrow
    #: opacity spike) is not stepped over at coarse sample distances. One to four channels
    #: (one table each, mixed as VTK mixes independent components), composite blend, 1-D TF,
    #: surface methods; elsewhere samples are post-classified as before.
    preintegration: bool = False
    #: Adaptive sampling (unit-free switch; docs/rendering.md): in 8³-voxel bricks where the
    #: transfer function's opacity varies by at most 0.02 over the brick's values, one sample
    #: stands for 4 steps (opacity corrected for the longer segment); elsewhere every step is
    #: taken. Faster where the classified volume is smooth, close to the fixed-step image.
    #: One channel, composite blend, 1-D TF; not together with pre-integration.
    adaptive_sampling: bool = False
    #: What draws the volume (vtkvol.model.renderers): VTK's ray caster with the illumination
    #: method (``raycast``), or a renderer beside it — ``path_tracer`` (progressive camera path
    #: tracer of the medium material), ``slicing`` (view-aligned slices, local lighting),
    #: ``half_angle`` (half-angle slicing, one light). docs/architecture.md, "Renderers beside
    #: the ray caster".
    renderer: RendererName = "raycast"

    @field_validator("blend_mode", mode="before")
    @classmethod
    def _blend_alias(cls, v: Any):
        # PyVista users write "maximum"/"minimum" (and any case); store one name per mode.
        if isinstance(v, str):
            name = v.strip().lower()
            return BLEND_ALIASES.get(name, name)
        return v


class ClipPlane(EventedModel):
    """An oblique clipping plane in world µm (the app's draggable plane).

    The volume is kept on the side the ``normal`` points to and cut away on the other (VTK's
    convention for a volume mapper's clipping planes); what is cut away casts no shadow and
    scatters no light either, since the illumination reads the same planes. ``origin`` None is
    the data's centre; ``normal`` is any non-zero vector (stored normalised).
    """

    enabled: bool = False
    origin: Vec3 | None = None
    normal: Vec3 = (0.0, 0.0, 1.0)

    @field_validator("origin")
    @classmethod
    def _origin_finite(cls, v: Vec3 | None):
        return None if v is None else _finite3(v, "clipping plane origin")

    @field_validator("normal")
    @classmethod
    def _normal_unit(cls, v: Vec3):
        x, y, z = _finite3(v, "clipping plane normal")
        length = math.sqrt(x * x + y * y + z * z)
        if length == 0.0:
            raise ValueError("the clipping plane's normal must not be the zero vector")
        return (x / length, y / length, z / length)


class Overlays(EventedModel):
    """Annotations drawn over the volume (in the view and in screenshots). None changes the
    rendered volume or its illumination.

    * ``scale_bar``: a horizontal bar of a round length in µm, measured in the plane of the
      camera's focal point, with its length written above it.
    * ``orientation_axes``: x (red), y (green), z (blue) arrows in a corner, turning with
      the camera.
    * ``bounding_box``: the outline of the data's box (voxel centres, world µm).
    * ``color_legend``: a colour bar per visible channel over its TF's value span (data
      units), titled with the channel's name.
    * ``slice_planes``: the outlines of the three orthogonal slice planes through
      ``SceneModel.cursor`` (x red, y green, z blue: the colour of the plane's normal axis).
    """

    scale_bar: bool = False
    orientation_axes: bool = False
    bounding_box: bool = False
    color_legend: bool = False
    slice_planes: bool = False


class SceneModel(EventedModel):
    """Everything the user set for one view."""

    volume: VolumeSource = Field(default_factory=VolumeSource)
    channels: list[Channel] = Field(default_factory=lambda: [Channel()])
    lights: list[Light] = Field(default_factory=lambda: [Light()])
    illumination: Illumination = Field(default_factory=Illumination)
    crop: CropBox = Field(default_factory=CropBox)
    slice_weights: SliceWeights = Field(default_factory=SliceWeights)
    camera: Camera = Field(default_factory=Camera)
    render: RenderSettings = Field(default_factory=RenderSettings)
    overlays: Overlays = Field(default_factory=Overlays)
    clip_plane: ClipPlane = Field(default_factory=ClipPlane)
    #: The point the orthogonal slice views pass through, world µm (x, y, z); ``None`` = the
    #: data's centre voxel. Views clamp it into the data's box (vtkvol.engine.slices).
    cursor: Vec3 | None = None

    @field_validator("cursor")
    @classmethod
    def _cursor_finite(cls, v: Vec3 | None):
        return None if v is None else _finite3(v, "cursor")

    @model_validator(mode="after")
    def _limits(self):
        if not 1 <= len(self.channels) <= 4:
            raise ValueError(f"1 to 4 channels are supported, not {len(self.channels)}")
        if len(self.lights) > 4:
            raise ValueError(f"at most 4 lights are supported, not {len(self.lights)}")
        return self


def model_unsupported_reason(model: SceneModel, renderer: str | None = None) -> str | None:
    """:func:`unsupported_reason` for a scene model (its ``render.renderer`` unless
    ``renderer`` is given): its method, blend mode, enabled lights and channels."""
    return unsupported_reason(
        model.render.renderer if renderer is None else renderer,
        method=model.illumination.method, blend_mode=model.render.blend_mode,
        lights=sum(1 for light in model.lights if light.enabled and light.intensity > 0),
        channels=max(1, len(model.channels)))
