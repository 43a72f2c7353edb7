"""Where the 3-D view's light handle goes: a sphere that the current framing shows whole.

A directional light's handle sits at ``centre + R·direction``. Until issue 25 the centre was
the data box's centre and R just outside the box's bounding sphere; but the view frames the
*visible* content ("Reset view"), which in a time-lapse (a small object moving through a large
box) is a fraction of the box, so the handle lay outside the view for most directions. Now the
centre is the camera's focal point (the centre of what the view frames: "Reset view" puts it
at the visible content's centre and panning moves it with the view) and R is at most what
keeps every point of the sphere inside the view, with a margin.

Coordinates: world µm; the camera's view angle is VTK's vertical one, in degrees.
"""

from __future__ import annotations

import math

import numpy as np
import vtk

#: Share of the view's half-width/half-height the handle's sphere may reach (a margin, so the
#: handle, drawn 14 px wide, stays wholly inside).
VIEW_SHARE = 0.85
#: The handle's sphere lies just outside the data's bounding sphere when the view shows that.
BOUNDS_FACTOR = 1.05


def handle_sphere(renderer: vtk.vtkRenderer,
                  bounds: tuple[float, float, float, float, float, float]
                  ) -> tuple[np.ndarray, float]:
    """(centre in world µm, radius in µm) of the sphere a directional light's handle moves on.

    The centre is the camera's focal point; the radius is ``BOUNDS_FACTOR`` × the bounding
    sphere of ``bounds`` (the data box, world µm) but no larger than the view allows: a point
    of the sphere at lateral offset R and depth ``d − R`` (perspective, ``d`` the distance to
    the focal point) projects within ``VIEW_SHARE`` of the view's half-size when
    ``R / (d − R) ≤ VIEW_SHARE · tan(angle/2)``, i.e. ``R ≤ k·d / (1 + k)`` with
    ``k = VIEW_SHARE · tan(angle/2)`` (the narrower of height and width); with parallel
    projection ``R ≤ VIEW_SHARE · half-size``.
    """
    camera = renderer.GetActiveCamera()
    centre = np.array(camera.GetFocalPoint(), dtype=np.float64)
    extent = np.array([bounds[1] - bounds[0], bounds[3] - bounds[2], bounds[5] - bounds[4]])
    radius = BOUNDS_FACTOR * 0.5 * float(np.linalg.norm(extent))
    width, height = renderer.GetSize()
    aspect = min(1.0, width / height) if width > 0 and height > 0 else 1.0  # narrower side
    if camera.GetParallelProjection():
        limit = VIEW_SHARE * float(camera.GetParallelScale()) * aspect
    else:
        k = VIEW_SHARE * math.tan(math.radians(camera.GetViewAngle()) / 2.0) * aspect
        limit = k * float(camera.GetDistance()) / (1.0 + k)
    if limit > 0.0 and math.isfinite(limit):
        radius = min(radius, limit)
    return centre, max(radius, 1e-6)
