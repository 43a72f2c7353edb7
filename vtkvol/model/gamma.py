"""Per-channel gamma: a power curve on the contrast-limited value, as napari's and Fiji's.

No VTK, no Qt. A channel's transfer function spans its contrast limits ``lo…hi`` (data units:
its first to its last control point, :attr:`TransferFunction.value_span`). With gamma ``g``
the channel shows at value ``v`` what the transfer function gives at

    lo + (hi − lo) · t^g,   t = (v − lo) / (hi − lo)   (clamped to 0…1)

so ``t = 0`` and ``t = 1`` (the limits themselves, and everything outside them) look the same
for every gamma; g < 1 brightens the mid-tones (and makes them more opaque), g > 1 darkens
them, as napari's ``gamma`` does for the normalised intensity before its colour map. The
curve is baked into the colour and opacity functions the engine hands to VTK
(:func:`with_gamma`), so every illumination technique, the slice views, the colour legend and
``vtkvol render`` of a session see the same classification; the stored transfer function is
the user's, untouched.
"""

from __future__ import annotations

import numpy as np

from vtkvol.model.transfer_function import TransferFunction

__all__ = ["GAMMA_DEFAULT", "GAMMA_MAX", "GAMMA_MIN", "GAMMA_SAMPLES", "with_gamma"]

#: Smallest and largest gamma a channel may have (unit-free). napari's slider spans
#: 0.2…2; the wider range lets a dim mid-tone be lifted further.
GAMMA_MIN = 0.1
GAMMA_MAX = 10.0
GAMMA_DEFAULT = 1.0
#: Evenly spaced samples of the curve over the contrast limits (besides the transfer
#: function's own control points, which are kept at their new positions): VTK's lookup table
#: has 1024 entries over the span, so 256 samples leave no visible facets.
GAMMA_SAMPLES = 256


def with_gamma(tf: TransferFunction, gamma: float) -> TransferFunction:
    """``tf`` as channel gamma ``gamma`` shows it: a new transfer function whose colour and
    opacity at value ``v`` (data units) are ``tf``'s at ``lo + (hi − lo)·t^gamma`` (see the
    module docstring). ``tf`` itself is returned for gamma 1 or a function with no span."""
    if not GAMMA_MIN <= gamma <= GAMMA_MAX:
        raise ValueError(f"gamma must lie in {GAMMA_MIN:g}…{GAMMA_MAX:g}, not {gamma}")
    lo, hi = tf.value_span
    if gamma == 1.0 or not hi > lo:
        return tf
    span = hi - lo
    # The user's control points land where the curve maps them (a step stays a step), the
    # even samples follow the curve in between.
    own = [p[0] for p in tf.colors] + [p[0] for p in tf.opacity]
    t_own = np.clip((np.asarray(own, np.float64) - lo) / span, 0.0, 1.0) ** (1.0 / gamma)
    t = np.unique(np.concatenate([np.linspace(0.0, 1.0, GAMMA_SAMPLES), t_own]))
    x = lo + span * t
    source = lo + span * t**gamma
    rgb = np.clip(tf.color_at(source).astype(np.float64), 0.0, 1.0)
    alpha = np.clip(tf.opacity_at(source).astype(np.float64), 0.0, 1.0)
    return TransferFunction(
        colors=[(float(v), *map(float, c)) for v, c in zip(x, rgb, strict=True)],
        opacity=[(float(v), float(a)) for v, a in zip(x, alpha, strict=True)],
        window=tf.window, window_range=tf.window_range)
