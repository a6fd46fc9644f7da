"""How far a camera rig sees across the ground, and so how far inside the covered area its cameras must stay.

ENU metres (z up), rotations ``R_world_rig`` with OpenCV camera axes (the rig frame is the left camera's). A view
ray leaving a camera ``D`` metres above the scene's lowest surface at angle ``theta`` from nadir crosses the
horizontal plane of that lowest surface at the horizontal distance ``D * tan(theta)``; every surface lies above
that plane, so the ray hits the scene no farther out. The rays along the image borders bound the view (the
frustum is a convex cone: a ray inside it is a positive mix of border rays), so when every border ray goes down,
every pixel's ray meets the scene above the convex hull of the cameras and these plane crossings (the view's
footprint); when that hull lies inside the covered area, the frame sees the scene inside that area only: nothing
beyond its edge, and no sky. The covered area is the valid rectangle and, for a reconstruction, the
``observed_area_m`` polygon of its scene.json: a simple polygon (no holes), in general not convex (the union of an
area's pieces, wavy where their orbits' discs meet). For a convex area the hull is inside when its corners are;
for a non-convex one, a notch can reach between corners that are all inside, so :func:`hull_inside` also checks
that no polygon edge crosses the hull.

The margin this needs in a direction is ``D * tan(theta)`` of the border ray reaching farthest that way; its bound
over all headings is ``D * tan(tilt + half-diagonal field of view)``, and none exists once ``tilt + half-diagonal
field of view`` reaches 90 degrees (the frame sees the horizon). See docs/render-dataset.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path as PolygonPath
from scipy.spatial import ConvexHull, QhullError

from sim.render.camera import Rig

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


#: Cells a side of the grid on which :func:`inner_rectangle` looks for the largest rectangle in a polygon.
INNER_GRID_CELLS = 128


def inner_rectangle(area: Area, polygon: np.ndarray | None, margin_m: float) -> Area | None:
    """The largest axis-aligned rectangle ``(xmin, xmax, ymin, ymax)`` (ENU metres) whose every point lies at least
    ``margin_m`` inside the rectangle ``area`` and, if given, inside the simple ``polygon`` (K, 2), convex or not;
    None when there is none. Without a polygon it is ``area`` less the margin; with one it is found on a grid of
    :data:`INNER_GRID_CELLS` cells a side over the polygon's part of ``area`` less the margin, taking the cells
    whose centre lies inside the polygon at least the margin plus half the cell's diagonal from its edges (so every
    point of the cell is at least the margin inside), then the largest rectangle of such cells."""
    xmin, xmax, ymin, ymax = bounding_area(area, polygon)
    inner = (xmin + margin_m, xmax - margin_m, ymin + margin_m, ymax - margin_m)
    if inner[0] >= inner[1] or inner[2] >= inner[3]:
        return None
    if polygon is None:
        return inner
    xs = np.linspace(inner[0], inner[1], INNER_GRID_CELLS + 1)
    ys = np.linspace(inner[2], inner[3], INNER_GRID_CELLS + 1)
    cx, cy = np.meshgrid((xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2)  # rows: y, columns: x
    centres = np.column_stack([cx.ravel(), cy.ravel()])
    clearance = margin_m + 0.5 * np.hypot(xs[1] - xs[0], ys[1] - ys[0])
    cells = _largest_rectangle(deep_inside(polygon, centres, clearance).reshape(cx.shape))
    if cells is None:
        return None
    row0, row1, col0, col1 = cells
    return float(xs[col0]), float(xs[col1]), float(ys[row0]), float(ys[row1])


def deep_inside(polygon: np.ndarray, points: np.ndarray, margin_m: float) -> np.ndarray:
    """Boolean mask of the ``points`` (N, 2) inside the simple ``polygon`` (K, 2) and at least ``margin_m`` from its
    edges (ENU metres)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return inside_polygon(polygon, points) & (_distance_to_edges(points, np.asarray(polygon, float)) >= margin_m)


def _distance_to_edges(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance (metres) from each of ``points`` (N, 2) to the nearest edge of the closed ``polygon`` (K, 2)."""
    start, end = _edges(polygon)
    edge = end - start
    nearest = np.full(len(points), np.inf)
    for a, d in zip(start, edge):  # one edge at a time: (N,) temporaries only
        t = np.clip(((points - a) @ d) / max(float(d @ d), 1e-300), 0.0, 1.0)
        nearest = np.minimum(nearest, np.hypot(*(points - a - t[:, None] * d).T))
    return nearest


def _largest_rectangle(usable: np.ndarray) -> tuple[int, int, int, int] | None:
    """The largest all-True block of the boolean grid ``usable`` (rows, columns) as ``(row0, row1, col0, col1)``
    (half-open index ranges), None when no cell is True: per row, the largest rectangle under the histogram of
    True runs ending at that row (the classic stack method)."""
    best, heights = None, np.zeros(usable.shape[1], int)
    best_area = 0
    for row, line in enumerate(usable):
        heights = np.where(line, heights + 1, 0)
        stack: list[int] = []  # columns of increasing height
        for col in range(len(heights) + 1):
            height = heights[col] if col < len(heights) else 0
            while stack and heights[stack[-1]] >= height:
                top = heights[stack.pop()]
                left = stack[-1] + 1 if stack else 0
                if top * (col - left) > best_area:
                    best_area, best = top * (col - left), (row + 1 - top, row + 1, left, col)
            stack.append(col)
    return best


def inside_polygon(polygon: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Boolean mask of the points ``xy`` (``(..., 2)`` ENU metres; extra trailing columns such as heights are
    ignored) that lie inside ``polygon`` (``(K, 2)``, any simple polygon, convex or not, either orientation; even-odd
    rule, matplotlib's); points exactly on an edge may go either way."""
    points = np.asarray(xy, dtype=np.float64)
    flat = points.reshape(-1, points.shape[-1])[:, :2]
    return PolygonPath(np.asarray(polygon, dtype=np.float64)).contains_points(flat).reshape(points.shape[:-1])


def _turn(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The z component of ``(b - a) x (c - a)`` (broadcast over leading axes): > 0 where ``a, b, c`` turn left."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _edges(ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points ``(K, 2)`` of the closed ring of vertices ``ring`` (K, 2)."""
    return ring, np.roll(ring, -1, axis=0)


def hull_inside(polygon: np.ndarray, points: np.ndarray) -> bool:
    """Whether the convex hull of ``points`` (N, 2) lies inside the simple ``polygon`` (K, 2) (ENU metres; convex
    or not): every hull vertex inside it, no polygon edge properly crossing a hull edge and no polygon vertex
    strictly inside the hull (which a notch of a non-convex polygon reaching into the hull would need). Contact
    without crossing (a hull vertex on an edge) is allowed."""
    try:
        hull = ConvexHull(points)
    except QhullError:  # all points on one line: joggled, the hull is that segment
        hull = ConvexHull(points, qhull_options="QJ")
    corners = points[hull.vertices]  # counter-clockwise
    if not np.all(inside_polygon(polygon, corners)):
        return False
    polygon = np.asarray(polygon, dtype=np.float64)
    a, b = (end[:, None] for end in _edges(corners))  # hull edges along axis 0
    c, d = (end[None] for end in _edges(polygon))  # polygon edges along axis 1
    crossing = (_turn(a, b, c) * _turn(a, b, d) < 0) & (_turn(c, d, a) * _turn(c, d, b) < 0)
    if crossing.any():
        return False
    # hull facets as n . x + offset <= 0 inside: a polygon vertex is strictly inside when every one is < 0
    side = polygon @ hull.equations[:, :2].T + hull.equations[:, 2]
    return not np.any(np.all(side < -1e-9, axis=1))


def sees_inside(area: Area, xy, reach: np.ndarray | None, polygon: np.ndarray | None = None) -> bool:
    """Whether a rig at ENU ``xy`` with view ``reach`` (None: the horizon) sees only inside ``area`` and, if
    given, the simple ``polygon`` (K, 2), convex or not: the view's footprint is the convex hull of its reach
    points (the frustum is a convex cone), so it must lie inside the polygon (:func:`hull_inside`)."""
    if reach is None:
        return False
    points = np.asarray(xy, float)[:2] + reach
    xmin, xmax, ymin, ymax = area
    in_area = np.all((points[:, 0] >= xmin) & (points[:, 0] <= xmax) & (points[:, 1] >= ymin) & (points[:, 1] <= ymax))
    return bool(in_area and (polygon is None or hull_inside(polygon, points)))
