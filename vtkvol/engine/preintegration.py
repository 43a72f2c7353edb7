"""Pre-integrated classification (seed 000 §4.1, seed 002 §5.2.1; docs/rendering.md).

One service of the technique host. Post-classification looks the transfer function (TF) up at
each sample and treats the segment to the next sample as uniform; a TF feature narrower than
the step between two samples' values is missed. Pre-integration looks up the *segment*: a 2-D
table, indexed by the scalar at the segment's front ``s_f`` and back ``s_b`` (both in VTK's TF
coordinate, 0…1 across the component's data range), holds the opacity and associated colour of
a segment of length ``d`` (the ray caster's sample distance, world µm) along which the scalar
runs linearly from ``s_f`` to ``s_b``:

    κ(s) = −ln(1 − α_TF(s)) / u       extinction per µm (α_TF: TF opacity per unit distance u)
    α    = 1 − exp(−d ∫₀¹ κ(s(ω)) dω)
    C    = ∫₀¹ c(s(ω)) κ(s(ω)) d · exp(−d ∫₀^ω κ) dω       (self-attenuation included)

On the diagonal (s_f = s_b) this is VTK's own opacity correction 1 − (1 − α_TF)^(d/u), so a
constant region renders as before. The table integrates over ``d`` already: the shader must not
correct it again (the seed 000 listing does; gap-spec D19).

The table is computed here with numpy (:func:`preintegration_table`, N sub-steps per segment:
each sub-step crosses at most one table entry, so a one-entry spike is never stepped over);
:func:`preintegrated_segment` is its independent twin (one segment, the model's TF nodes, a
plain loop), used by the tests. GLSL: ``resources/shaders/host_preintegration.glsl``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import vtk

from vtkvol.engine.gl import Texture2D

#: Entries per axis of the table (256² × RGBA float32 = 1 MiB, seed 002's size).
TABLE_SIZE = 256
#: Entries at which the TF is evaluated before the table is integrated (finer than the table,
#: so the piecewise-linear TF is followed between table entries).
FINE_SIZE = 4 * TABLE_SIZE
#: Fewest sub-steps a segment of the table is integrated with.
MIN_STEPS = 256
#: Largest TF opacity used (α = 1 would be an infinite extinction).
_ALPHA_MAX = 1.0 - 1e-6


def extinction(alpha: np.ndarray, unit_distance: float) -> np.ndarray:
    """Extinction per µm from TF opacity ``alpha`` per ``unit_distance`` µm."""
    a = np.clip(np.asarray(alpha, np.float64), 0.0, _ALPHA_MAX)
    return -np.log1p(-a) / float(unit_distance)


def preintegration_table(alpha: np.ndarray, rgb: np.ndarray, sample_distance: float,
                         unit_distance: float, size: int = TABLE_SIZE) -> np.ndarray:
    """The pre-integration table ``[s_f, s_b, RGBA]`` (``size × size × 4`` float32).

    ``alpha`` (``F``) and ``rgb`` (``F × 3``): the TF sampled at ``F`` evenly spaced TF
    coordinates 0…1 (opacity per ``unit_distance`` µm, colour 0…1); ``sample_distance``: the
    segment length in µm. RGB is associated (premultiplied by the segment's opacity)."""
    kappa = extinction(alpha, unit_distance).astype(np.float32)
    rgb = np.asarray(rgb, np.float32).reshape(-1, 3)
    last = len(kappa) - 1
    s = np.linspace(0.0, 1.0, size, dtype=np.float32)
    # Sub-steps per segment: each crosses at most one table entry (and at least 256 of them
    # for small test tables), so a one-entry spike is never stepped over.
    steps = max(size, MIN_STEPS)
    w = ((np.arange(steps) + 0.5) / steps).astype(np.float32)
    out = np.empty((size, size, 4), np.float32)
    dt = np.float32(sample_distance / steps)
    for i, sf in enumerate(s):
        # Linear interpolation of the fine TF at the sub-steps, by hand (np.interp is several
        # times slower on these (size, steps) arrays).
        f = (sf + (s[:, None] - sf) * w[None, :]) * np.float32(last)
        i0 = np.minimum(f.astype(np.int32), last - 1)
        fr = f - i0
        tau = (kappa[i0] * (1 - fr) + kappa[i0 + 1] * fr) * dt  # optical depth per sub-step
        before = np.cumsum(tau, axis=1) - tau                    # optical depth in front
        weight = np.exp(-before) * -np.expm1(-tau)               # light each sub-step adds
        for c in range(3):
            col = rgb[:, c]
            out[i, :, c] = np.sum(weight * (col[i0] * (1 - fr) + col[i0 + 1] * fr), axis=1)
        out[i, :, 3] = -np.expm1(-np.sum(tau, axis=1))
    return out


def preintegrated_segment(nodes_x: np.ndarray, nodes_alpha: np.ndarray,
                          nodes_rgb: np.ndarray, sf: float, sb: float,
                          sample_distance: float, unit_distance: float,
                          steps: int = 4000) -> tuple[float, float, float, float]:
    """One segment's (R, G, B, A), associated, integrated directly from the TF's nodes
    (coordinates 0…1, opacity per ``unit_distance`` µm, colour rows): the twin of
    :func:`preintegration_table`, written as the plain front-to-back loop."""
    dt = sample_distance / steps
    transmittance = 1.0
    colour = [0.0, 0.0, 0.0]
    for m in range(steps):
        s = sf + (sb - sf) * (m + 0.5) / steps
        kappa = float(extinction(np.interp(s, nodes_x, nodes_alpha), unit_distance))
        a = 1.0 - np.exp(-kappa * dt)
        for c in range(3):
            colour[c] += transmittance * a * float(np.interp(s, nodes_x, nodes_rgb[:, c]))
        transmittance *= 1.0 - a
    return colour[0], colour[1], colour[2], 1.0 - transmittance


def tf_samples(prop: vtk.vtkVolumeProperty, value_range: tuple[float, float],
               count: int = FINE_SIZE, component: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(alpha, rgb)`` of ``component``'s TF at ``count`` values evenly across
    ``value_range`` (data units: VTK's table coordinate 0…1 spans it)."""
    lo, hi = (float(v) for v in value_range)
    if hi <= lo:
        hi = lo + 1.0
    alpha = np.empty(count)
    prop.GetScalarOpacity(component).GetTable(lo, hi, count, alpha)
    rgb = np.empty(count * 3)
    prop.GetRGBTransferFunction(component).GetTable(lo, hi, count, rgb)
    return alpha, rgb.reshape(count, 3)


def _lookup(table: np.ndarray, front: np.ndarray, back: np.ndarray) -> np.ndarray:
    """``table`` (``N × N × 4``) at TF coordinates ``front``, ``back`` (0…1, same shape),
    bilinearly between entries, as the shader's texture fetch reads it (texel centres at the
    ends): ``(..., 4)``."""
    last = table.shape[0] - 1
    f = np.clip(np.asarray(front, np.float64), 0.0, 1.0) * last
    b = np.clip(np.asarray(back, np.float64), 0.0, 1.0) * last
    i0 = np.minimum(f.astype(np.int64), last - 1)
    j0 = np.minimum(b.astype(np.int64), last - 1)
    fi = (f - i0)[..., None]
    fj = (b - j0)[..., None]
    t = table.astype(np.float64)
    return ((t[i0, j0] * (1 - fj) + t[i0, j0 + 1] * fj) * (1 - fi)
            + (t[i0 + 1, j0] * (1 - fj) + t[i0 + 1, j0 + 1] * fj) * fi)


def composite_ray(tables: list[np.ndarray], scalars: np.ndarray,
                  weights: np.ndarray | None = None, mixing: str = "additive"
                  ) -> np.ndarray:
    """The CPU twin of the pre-integrated ray (``host_preintegration.glsl`` inside VTK's
    composite loop), unshaded: the premultiplied RGBA that reaches the end of one ray.

    ``tables``: one pre-integration table per channel (:func:`preintegration_table`);
    ``scalars``: ``K × C``, the channels' TF coordinates (0…1) at the ray's ``K`` samples, one
    sample distance apart. Each sample classifies the segment from the previous sample (the
    first one: a segment of its own value, as the shader does at the ray start) per channel
    from that channel's table; the channels' segments are combined exactly as VTK combines
    independent components' samples (``weights``: VTK's component weights, default 1;
    ``mixing``: ``"additive"``, VTK's opacity-weighted mean alpha, or ``"composite"``, the
    channels as independent absorbers, RenderSettings.channel_mixing), then composited front
    to back."""
    scalars = np.asarray(scalars, np.float64).reshape(len(scalars), -1)
    count, channels = scalars.shape
    w = np.ones(channels) if weights is None else np.asarray(weights, np.float64)
    front = np.vstack([scalars[:1], scalars[:-1]])
    rgba = np.stack([_lookup(tables[c], front[:, c], scalars[:, c]) for c in range(channels)],
                    axis=1)                                      # K × C × 4, associated
    alpha = rgba[:, :, 3]
    # The colour VTK's computeColor returns: the segment's colour (associated / opacity).
    with np.errstate(invalid="ignore", divide="ignore"):
        colour = np.where(alpha[..., None] > 0, np.clip(rgba[:, :, :3] / alpha[..., None],
                                                        0.0, 1.0), 0.0)
    out = np.zeros(4)
    for k in range(count):
        total = float(np.sum(alpha[k] * w))
        tmp = np.zeros(4)
        if total > 0.0:
            for c in range(channels):
                if w[c] <= 0:
                    continue
                tmp[:3] += colour[k, c] * alpha[k, c] * w[c]
                if mixing == "composite":
                    tmp[3] = 1.0 - (1.0 - tmp[3]) * (1.0 - alpha[k, c] * w[c])
                else:
                    tmp[3] += alpha[k, c] ** 2 / total
        out = (1.0 - out[3]) * tmp + out
    return out


class PreIntegrator:
    """The pre-integration tables of one illuminated volume's channels, rebuilt when a
    channel's TF, its data range, the sample distance or its opacity unit distance change, and
    bound as ``vv_piTable``: one atlas, an R32F texture of ``N`` columns × ``4CN`` rows for
    ``C`` channels (channel ``c``'s R, G, B and A planes are planes ``4c`` … ``4c + 3``, each
    ``N`` rows; rows = front sample, columns = back sample)."""

    def __init__(self, host: Any) -> None:
        self._host = host
        self._key: tuple | None = None
        self._texture: Texture2D | None = None
        self._tables: dict[tuple, np.ndarray] = {}  # recent tables, by (channel, key)
        #: The channels' last tables (``N × N × 4`` each), for tests and diagnostics.
        self.tables: list[np.ndarray] = []
        #: Whether the last frame drew with the tables, and if not why (a sentence).
        self.stats: dict[str, Any] = {"active": False, "reason": "switched off"}

    @property
    def table(self) -> np.ndarray | None:
        """The first channel's last table (``N × N × 4``), or None."""
        return self.tables[0] if self.tables else None

    def channels(self) -> int:
        """How many components the volume's scalars have (1…4)."""
        scalars = self._host.image.GetPointData().GetScalars()
        return scalars.GetNumberOfComponents() if scalars is not None else 1

    def why_not(self) -> str | None:
        """None when the volume's settings allow pre-integration, else why not."""
        host = self._host
        if not host._preintegrate:
            return "switched off"
        prop = host.volume.GetProperty()
        mapper = host.volume.GetMapper()
        ncomp = self.channels()
        if mapper.GetBlendMode() != vtk.vtkVolumeMapper.COMPOSITE_BLEND:
            return "only composite blending integrates segments"
        if ncomp > 1 and not prop.GetIndependentComponents():
            return "dependent components (colour data) have no transfer function per channel"
        if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_1D:
            return "2-D transfer functions are not supported"
        if prop.GetInterpolationType() == vtk.VTK_NEAREST_INTERPOLATION:
            return "nearest-voxel interpolation (labels) has no linear segment"
        if any(prop.HasGradientOpacity(c) for c in range(ncomp)):
            return "gradient opacity is not supported"
        if host.spec.lighting != "surface":
            return "medium techniques colour samples themselves"
        return None

    @property
    def active(self) -> bool:
        return bool(self.stats.get("active"))

    def update(self) -> None:
        """Rebuild and bind the tables if needed, or unbind them (``stats`` says why)."""
        why = self.why_not()
        if why is not None:
            self.stats = {"active": False, "reason": why}
            self.drop()
            return
        host = self._host
        prop = host.volume.GetProperty()
        mapper = host.volume.GetMapper()
        scalars = host.image.GetPointData().GetScalars()
        ncomp = self.channels()
        distance = float(mapper.GetSampleDistance())
        keys = []
        for c in range(ncomp):
            # VTK's table coordinate of component c spans that component's data range.
            value_range = tuple(scalars.GetRange(c))
            unit = float(prop.GetScalarOpacityUnitDistance(c))
            keys.append((c, prop.GetScalarOpacity(c).GetMTime(),
                         prop.GetRGBTransferFunction(c).GetMTime(), value_range, distance,
                         unit))
        key = tuple(keys)
        if key != self._key or self._texture is None:
            # A table costs about a second on two CPU cores (256 × 256 segments of 256
            # sub-steps); the full-quality and the interactive sample distance alternate with
            # every camera move, so each channel's last two tables are kept (and a channel
            # whose TF did not change is not integrated again).
            for k in keys:
                if k not in self._tables:
                    c, value_range, unit = k[0], k[3], k[5]
                    alpha, rgb = tf_samples(prop, value_range, component=c)
                    self._tables[k] = preintegration_table(alpha, rgb, distance, unit)
            while len(self._tables) > 2 * ncomp:
                self._tables.pop(next(iter(self._tables)))
            self.tables = [self._tables[k] for k in keys]
            planes = np.concatenate([t[:, :, p] for t in self.tables for p in range(4)],
                                    axis=0)
            if self._texture is not None and self._texture.shape != planes.shape:
                self._texture.release()  # the number of channels changed
                self._texture = None
            if self._texture is None:
                self._texture = Texture2D(host.render_window, planes)
            else:
                self._texture.upload(planes)
            self._key = key
        host.bind_texture("vv_piTable", self._texture, "sampler2D")
        self.stats = {"active": True, "reason": "", "channels": ncomp,
                      "sample_distance": distance,
                      "unit_distance": float(prop.GetScalarOpacityUnitDistance(0))}

    def drop(self) -> None:
        self._host.unbind_texture("vv_piTable")
        if self._texture is not None:
            self._texture.release()
            self._texture = None
        self._key = None
