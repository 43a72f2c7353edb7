"""The intensity probe: what voxel lies under a point of the view, and its values.

``probe(renderer, volume, data, x, y)`` casts the view ray through display pixel (x, y) (VTK's
display coordinates: pixels from the bottom-left corner) with :class:`vtkVolumePicker`, which
stops at the first sample whose transfer-function opacity exceeds a threshold: the first thing
the user sees there, not the first voxel of the box. The answer gives the world position (µm),
the voxel's index (i, j, k = x, y, z) and every channel's raw value there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import vtk

from vtkvol.io import VolumeData

#: Transfer-function opacity at which the probe's ray stops (the first visible material).
VISIBLE_OPACITY = 0.05


@dataclass(frozen=True)
class ProbeResult:
    """One probed voxel: ``position_um`` (x, y, z) world µm where the ray met the material,
    ``index`` (i, j, k) of the nearest voxel, ``values`` per channel (raw data values), the
    channel ``names`` and, per channel, whether it is a label image (``labels``; its value
    is then a label id, 0 the background)."""

    position_um: tuple[float, float, float]
    index: tuple[int, int, int]
    values: tuple[float, ...]
    names: tuple[str, ...]
    labels: tuple[bool, ...] = ()

    def text(self) -> str:
        """One line for a status bar: ``x 12.3 y 4.5 z 6 µm · voxel (12, 4, 6) · DAPI 1234``;
        a label channel's value reads ``nuclei label 17`` (``nuclei background`` for 0)."""
        x, y, z = self.position_um
        flags = self.labels or (False,) * len(self.values)
        values = " · ".join(
            f"{name} {_label(v) if is_label else _number(v)}"
            for name, v, is_label in zip(self.names, self.values, flags, strict=True))
        return f"x {x:.4g} y {y:.4g} z {z:.4g} µm · voxel {self.index} · {values}"


def _label(value: float) -> str:
    return "background" if value == 0 else f"label {int(value)}"


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else f"{value:.4g}"


def probe(renderer: vtk.vtkRenderer, volume: vtk.vtkVolume, data: VolumeData, x: float,
          y: float, labels: tuple[bool, ...] = ()) -> ProbeResult | None:
    """The first visible voxel of ``volume`` under display pixel (x, y), or None (nothing
    visible there). ``data`` is what the volume shows (its array ``[c, z, y, x]``);
    ``labels`` marks the channels that are label images (their values read as ids)."""
    picker = vtk.vtkVolumePicker()
    picker.SetVolumeOpacityIsovalue(VISIBLE_OPACITY)
    picker.PickFromListOn()
    picker.AddPickList(volume)
    if not picker.Pick(x, y, 0.0, renderer) or picker.GetProp3D() is not volume:
        return None
    pos = np.array(picker.GetPickPosition(), dtype=np.float64)
    image = volume.GetMapper().GetInput()
    origin = np.array(image.GetOrigin(), dtype=np.float64)
    spacing = np.array(image.GetSpacing(), dtype=np.float64)
    # The ray stops where the interpolated opacity first crosses the threshold, in front of
    # the voxel that causes it: of the voxels nearest to the next two voxel lengths of the ray,
    # report the most opaque (the first of equals), i.e. the material the user is looking at.
    camera = np.array(renderer.GetActiveCamera().GetPosition(), dtype=np.float64)
    ray = pos - camera
    ray /= max(float(np.linalg.norm(ray)), 1e-30)
    array = data.array
    _, nz, ny, nx = array.shape
    prop = volume.GetProperty()
    best: tuple[float, tuple[int, int, int]] | None = None
    for t in np.linspace(0.0, 2.0, 9) * float(spacing.min()):
        ijk = np.clip(np.rint((pos + t * ray - origin) / spacing), 0, [nx - 1, ny - 1, nz - 1])
        i, j, k = (int(v) for v in ijk)
        alpha = max(prop.GetScalarOpacity(min(c, 3)).GetValue(float(array[c, k, j, i]))
                    for c in range(min(array.shape[0], 4)))
        if best is None or alpha > best[0]:
            best = (alpha, (i, j, k))
    assert best is not None
    i, j, k = best[1]
    values = tuple(float(array[c, k, j, i]) for c in range(array.shape[0]))
    flags = tuple(bool(f) for f in labels[:len(values)])
    flags += (False,) * (len(values) - len(flags))
    return ProbeResult(tuple(float(v) for v in pos), (i, j, k), values,  # type: ignore[arg-type]
                       tuple(data.channel_names), flags)
