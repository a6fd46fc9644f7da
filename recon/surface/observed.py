"""The observed area of a flight: where its registered cameras stood, as a ground polygon (ENU metres).

A flight observes well what lies under the ring or block of its camera positions; outside it the ground is seen
only at grazing angles. :func:`observed_area` is the convex hull of the cameras' horizontal positions (for a
50 m orbit: the 50 m disc), :func:`viewed_area` adds the ground points the cameras' optical axes meet (a short
arc of an orbit looks at its centre), :func:`inside` (:func:`sim.sampling.frustum.inside_polygon`, the one point-in-polygon
test of the project) tests ground points against such a polygon. Both work in one ENU frame (x east, y north,
metres); heights are ignored.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from sim.sampling.frustum import inside_polygon as inside  # noqa: F401  (re-exported: recon's name for it)


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


def viewed_area(T_world_cams: np.ndarray, ground_z: float) -> np.ndarray:
    """``(K, 2)`` polygon (ENU metres) of what a flight stands over and looks at: the convex hull of the cameras'
    horizontal positions and of the points where their optical axes meet the plane ``z = ground_z`` (cameras
    looking at or above the horizon add their position only). For a whole orbit or a nadir block this is
    :func:`observed_area`; for a short arc of an orbit it also takes in the centre the cameras look at.
    ``T_world_cams``: ``(N, 4, 4)`` camera-to-world poses (OpenCV axes: the optical axis is the third column)."""
    poses = np.asarray(T_world_cams, dtype=np.float64)
    centres, axes = poses[:, :3, 3], poses[:, :3, 2]
    looking_down = axes[:, 2] < -1e-6
    reach = (ground_z - centres[looking_down, 2]) / axes[looking_down, 2]
    ground = centres[looking_down] + reach[:, None] * axes[looking_down]
    return observed_area(np.concatenate([centres[:, :2], ground[reach > 0, :2]]))
