"""How far a camera rig sees across the ground, and so how far inside the covered area its cameras must stay.

ENU metres (z up), rotations ``R_world_rig`` with OpenCV camera axes (the rig frame is the left camera's). A view
ray leaving a camera ``D`` metres above the scene's lowest surface at angle ``theta`` from nadir crosses the
horizontal plane of that lowest surface at the horizontal distance ``D * tan(theta)``; every surface lies above
that plane, so the ray hits the scene no farther out. The rays along the image borders bound the view (the
frustum is a convex cone: a ray inside it is a positive mix of border rays), so when every border ray goes down
and the cameras and these plane crossings all lie inside a convex covered area (a rectangle), every pixel of the
frame sees the scene inside that area: nothing beyond its edge, and no sky. A reconstruction's covered area is the
convex ``observed_area_m`` polygon of its scene.json within its valid rectangle.

The margin this needs in a direction is ``D * tan(theta)`` of the border ray reaching farthest that way; its bound
over all headings is ``D * tan(tilt + half-diagonal field of view)``, and none exists once ``tilt + half-diagonal
field of view`` reaches 90 degrees (the frame sees the horizon). See docs/render-dataset.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.camera import Rig

#: Points sampled along each image border (corners included): lens distortion bends the borders.
BORDER_SAMPLES = 9
#: A border ray must descend at least this steeply (sine of its angle below the horizon) to count as seeing the
#: ground: shallower rays would cross the plane kilometres away.
MIN_DESCENT = 1e-6


def border_pixels(width: int, height: int) -> np.ndarray:
    """``(4 * BORDER_SAMPLES, 2)`` continuous pixel coordinates (u, v) along the outer edge of a ``width`` x
    ``height`` image (pixel centres at integers, so the image spans ``[-0.5, width - 0.5]``)."""
    u = np.linspace(-0.5, width - 0.5, BORDER_SAMPLES)
    v = np.linspace(-0.5, height - 0.5, BORDER_SAMPLES)
    top, bottom = np.column_stack([u, np.full_like(u, v[0])]), np.column_stack([u, np.full_like(u, v[-1])])
    left, right = np.column_stack([np.full_like(v, u[0]), v]), np.column_stack([np.full_like(v, u[-1]), v])
    return np.vstack([top, bottom, left, right])


@dataclass(frozen=True)
class ViewFrustum:
    """The border rays of every camera of a rig, in the rig frame: ``origins`` (N, 3) metres and unit
    ``directions`` (N, 3); ``cameras`` (C, 3) the cameras' centres."""

    origins: np.ndarray
    directions: np.ndarray
    cameras: np.ndarray

    @classmethod
    def of_rig(cls, rig: Rig) -> "ViewFrustum":
        """The border rays of every camera of ``rig`` (through its lens, distortion included)."""
        origins, directions = [], []
        for camera, T_rig_cam in zip(rig.cameras, rig.T_rig_cam):
            rays = camera.ray_directions(border_pixels(camera.width, camera.height)) @ T_rig_cam[:3, :3].T
            directions.append(rays)
            origins.append(np.tile(T_rig_cam[:3, 3], (len(rays), 1)))
        return cls(np.vstack(origins), np.vstack(directions), np.array([T[:3, 3] for T in rig.T_rig_cam]))

    def reach(self, R_world_rig: np.ndarray, drop_m: float) -> np.ndarray | None:
        """Horizontal ENU offsets (M, 2) metres from the rig origin of the cameras and of where the border rays
        cross the plane ``drop_m`` below the rig origin; None when a border ray does not go down to it (the view
        reaches the horizon, or a camera lies below the plane)."""
        origins, directions = self.origins @ R_world_rig.T, self.directions @ R_world_rig.T
        if np.any(directions[:, 2] > -MIN_DESCENT):
            return None
        along = (-drop_m - origins[:, 2]) / directions[:, 2]
        if np.any(along < 0):
            return None
        crossings = origins[:, :2] + along[:, None] * directions[:, :2]
        return np.vstack([crossings, (self.cameras @ R_world_rig.T)[:, :2]])

    def radius(self, R_world_rig: np.ndarray, drop_m: float) -> float | None:
        """The farthest horizontal reach (metres) of :meth:`reach`; the same for every heading of the rig (a
        turn about the vertical keeps distances); None when the view reaches the horizon."""
        reach = self.reach(R_world_rig, drop_m)
        return None if reach is None else float(np.linalg.norm(reach, axis=1).max())


Area = tuple[float, float, float, float]
"""An ENU rectangle ``(xmin, xmax, ymin, ymax)``, metres."""


def placement_area(area: Area, reach: np.ndarray) -> Area | None:
    """The rectangle ``(xmin, xmax, ymin, ymax)`` of rig positions (ENU x, y) from which every point of ``reach``
    (offsets from the rig, :meth:`ViewFrustum.reach`) lies inside ``area``; None when there is none."""
    xmin, xmax, ymin, ymax = area
    low, high = reach.min(axis=0), reach.max(axis=0)
    placed = (xmin - low[0], xmax - high[0], ymin - low[1], ymax - high[1])
    return placed if placed[0] < placed[1] and placed[2] < placed[3] else None


def bounding_area(area: Area, polygon: np.ndarray | None) -> Area:
    """The part of the rectangle ``area`` inside the bounding box of ``polygon`` ((K, 2) ENU metres; None: all)."""
    if polygon is None:
        return area
    (pxmin, pymin), (pxmax, pymax) = polygon.min(axis=0), polygon.max(axis=0)
    return max(area[0], pxmin), min(area[1], pxmax), max(area[2], pymin), min(area[3], pymax)


def inside_convex(polygon: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which ``points`` (N, 2) lie inside (or on) the convex ``polygon`` (K, 2), either orientation (ENU metres)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    rel = points[:, None, :] - polygon[None]
    cross = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]
    doubled_area = np.sum(polygon[:, 0] * np.roll(polygon[:, 1], -1) - np.roll(polygon[:, 0], -1) * polygon[:, 1])
    return np.all(np.sign(doubled_area) * cross >= -1e-9, axis=1)


def sees_inside(area: Area, xy, reach: np.ndarray | None, polygon: np.ndarray | None = None) -> bool:
    """Whether a rig at ENU ``xy`` with view ``reach`` (None: the horizon) sees only inside ``area`` and, if
    given, the convex ``polygon`` (K, 2)."""
    if reach is None:
        return False
    points = np.asarray(xy, float)[:2] + reach
    xmin, xmax, ymin, ymax = area
    in_area = np.all((points[:, 0] >= xmin) & (points[:, 0] <= xmax) & (points[:, 1] >= ymin) & (points[:, 1] <= ymax))
    return bool(in_area and (polygon is None or np.all(inside_convex(polygon, points))))
