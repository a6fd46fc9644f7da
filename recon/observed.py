"""The observed area of a flight: where its registered cameras stood, as a ground polygon (ENU metres).

A flight observes well what lies under the ring or block of its camera positions; outside it the ground is seen
only at grazing angles. :func:`observed_area` is the convex hull of the cameras' horizontal positions (for a
50 m orbit: the 50 m disc), :func:`inside` tests ground points against such a polygon. Both work in one ENU
frame (x east, y north, metres); heights are ignored.
"""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path as PolygonPath
from scipy.spatial import ConvexHull, QhullError


def observed_area(centres_enu: np.ndarray) -> np.ndarray:
    """``(K, 2)`` counter-clockwise polygon (ENU x, y metres): the convex hull of the camera centres' (x, y)
    (``centres_enu`` ``(N, 2)`` or ``(N, 3)``). Raises ValueError when they span no area (fewer than three
    cameras, or all on one line)."""
    xy = np.asarray(centres_enu, dtype=np.float64).reshape(len(centres_enu), -1)[:, :2]
    try:
        hull = ConvexHull(xy)
    except (QhullError, ValueError) as error:
        raise ValueError(f"{len(xy)} camera positions span no area (need three not on one line)") from error
    return xy[hull.vertices]  # scipy orders 2-D hull vertices counter-clockwise


def inside(polygon: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Boolean mask of the points ``xy`` (``(..., 2)`` ENU metres; extra trailing columns such as heights are
    ignored) that lie inside ``polygon`` (``(K, 2)``, any simple polygon); points exactly on an edge may go
    either way."""
    points = np.asarray(xy, dtype=np.float64)
    flat = points.reshape(-1, points.shape[-1])[:, :2]
    return PolygonPath(np.asarray(polygon, dtype=np.float64)).contains_points(flat).reshape(points.shape[:-1])
