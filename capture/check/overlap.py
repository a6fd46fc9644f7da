"""Forward overlap of consecutive photos from their ground footprints.

A photo's footprint is sampled: a grid of its pixels (:data:`GRID`) cast onto the take-off's level (ENU up = 0, a
flat ground) from its geotag's position and camera rotation (``R_world_cam``: ENU <- OpenCV camera); points
beyond :data:`MAX_RANGE_FACTOR` times its height (towards the horizon) or above it are left out. The overlap of
photo A with photo B is the share of A's footprint points B sees (in front of it, inside its image). Cameras are
pinholes: the focal length from EXIF ``FocalLengthIn35mmFilm`` (the 35 mm equivalent over the full-frame
diagonal), else from the aircraft's camera profile at the photo's width.
"""

from __future__ import annotations

import math

import numpy as np

from flightplan.aircraft import FULL_FRAME_DIAGONAL_MM, CameraProfile

#: Pixels sampled across and down each image.
GRID = (16, 12)
#: Ground points further than this many camera heights away are left out (grazing rays near the horizon).
MAX_RANGE_FACTOR = 20.0


def focal_length_px(size_px: tuple[int, int], focal_35mm: float, profile: CameraProfile) -> float:
    """A photo's focal length in pixels: from its 35 mm equivalent focal length (mm) where finite, else
    ``profile``'s at the photo's width."""
    if math.isfinite(focal_35mm) and focal_35mm > 0:
        return focal_35mm / FULL_FRAME_DIAGONAL_MM * math.hypot(*size_px)
    return profile.focal_length_px(size_px[0])


def pixel_rays(size_px: tuple[int, int], focal_px: float) -> np.ndarray:
    """(M,3) camera-frame directions (OpenCV, z = 1) through the :data:`GRID` of pixels."""
    width, height = size_px
    u, v = np.meshgrid(np.linspace(0, width - 1, GRID[0]), np.linspace(0, height - 1, GRID[1]))
    return np.stack([(u.ravel() - (width - 1) / 2) / focal_px, (v.ravel() - (height - 1) / 2) / focal_px,
                     np.ones(u.size)], axis=1)


def footprint(enu_m: np.ndarray, R_world_cam: np.ndarray, size_px: tuple[int, int], focal_px: float) -> np.ndarray:
    """(M,3) ENU points where the photo's sampled pixels meet the ground (up = 0); empty above it."""
    height = float(enu_m[2])
    if height <= 0:
        return np.zeros((0, 3))
    directions = pixel_rays(size_px, focal_px) @ np.asarray(R_world_cam).T
    down = directions[:, 2] < 0
    t = -height / directions[down, 2]
    points = enu_m + t[:, None] * directions[down]
    reach = np.hypot(points[:, 0] - enu_m[0], points[:, 1] - enu_m[1])
    return points[reach <= MAX_RANGE_FACTOR * height]


def seen_share(points: np.ndarray, enu_m: np.ndarray, R_world_cam: np.ndarray, size_px: tuple[int, int],
               focal_px: float) -> float:
    """The share of ``points`` (M,3 ENU) a camera sees in front of it and inside its image (NaN for none)."""
    if len(points) == 0:
        return math.nan
    camera = (points - enu_m) @ np.asarray(R_world_cam)
    z = camera[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = focal_px * camera[:, 0] / z + (size_px[0] - 1) / 2
        v = focal_px * camera[:, 1] / z + (size_px[1] - 1) / 2
    inside = (z > 0) & (u >= -0.5) & (u <= size_px[0] - 0.5) & (v >= -0.5) & (v <= size_px[1] - 0.5)
    return float(np.mean(inside))


def neighbour_overlaps(enu_m: np.ndarray, R_world_cam: list, sizes: list, focal_px: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """For photos in flight order: the share of each one's footprint seen by the previous photo and by the next
    (NaN at the ends, and where a photo has no camera rotation or no footprint)."""
    count = len(enu_m)
    previous, following = np.full(count, math.nan), np.full(count, math.nan)
    for i in range(count):
        if R_world_cam[i] is None:
            continue
        points = footprint(enu_m[i], R_world_cam[i], sizes[i], focal_px[i])
        for j, out in ((i - 1, previous), (i + 1, following)):
            if 0 <= j < count and R_world_cam[j] is not None:
                out[i] = seen_share(points, enu_m[j], R_world_cam[j], sizes[j], focal_px[j])
    return previous, following
