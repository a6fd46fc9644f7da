"""Optical flow of a static scene between two views, from the first view's depth and the two camera poses.

A pixel centre ``(u, v)`` of view A with planar depth ``z`` (metres) is the camera-frame point ``z * (x, y, 1)``
(``x, y`` its undistorted normalised coordinates); moved to the world by ``T_world_camA`` and projected into view B
(lens distortion included) it lands at ``(u', v')``; the flow is ``(u' - u, v' - v)`` in pixels (OpenCV pixel
convention, sim/render/camera.py). A pixel has flow (``valid``) when it hit something and its point lies in front of B;
it is ``visible`` in B when it also lands inside B's image and nothing in B's depth map lies in front of it
(:func:`visible_at`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.render.camera import PinholeCamera, project_world_points


@dataclass(frozen=True)
class Flow:
    """Flow from view A to view B: ``uv`` (H, W, 2) float32 pixels (0 where not ``valid``), ``valid`` (H, W) bool
    (A's pixel hit a point in front of B), ``visible`` (H, W) bool (valid, inside B's image and not occluded)."""

    uv: np.ndarray
    valid: np.ndarray
    visible: np.ndarray


def visible_at(depth_target: np.ndarray, u: np.ndarray, v: np.ndarray, z: np.ndarray, tolerance: float) -> np.ndarray:
    """True where a point of planar depth ``z`` (metres) seen at pixel ``(u, v)`` of a target view is not hidden
    there: ``(u, v)`` lies between the target's pixel centres (``0 <= u <= W-1``, ``0 <= v <= H-1``) and
    ``z <= (1 + tolerance) * max`` of the target depth at the (up to four) pixel centres around ``(u, v)``.
    The largest neighbour is taken, so on a surface whose depth is monotone across a pixel the point's own
    depth is never judged hidden; ``tolerance`` absorbs float32 depth and creases (kitti2015's
    ``NOC_RELATIVE_TOLERANCE``). Non-finite ``u``, ``v`` or ``z`` are not visible."""
    height, width = depth_target.shape
    u, v, z = (np.asarray(a, dtype=np.float64) for a in np.broadcast_arrays(u, v, z))
    inside = np.isfinite(z) & (u >= 0) & (u <= width - 1) & (v >= 0) & (v <= height - 1)
    u, v = np.where(inside, u, 0.0), np.where(inside, v, 0.0)
    u0, v0 = np.floor(u).astype(np.intp), np.floor(v).astype(np.intp)
    u1 = np.where(u > u0, np.minimum(u0 + 1, width - 1), u0)
    v1 = np.where(v > v0, np.minimum(v0 + 1, height - 1), v0)
    seen = np.maximum(np.maximum(depth_target[v0, u0], depth_target[v0, u1]),
                      np.maximum(depth_target[v1, u0], depth_target[v1, u1])).astype(np.float64)
    return inside & (z <= seen * (1.0 + tolerance))


def flow_between(depth: np.ndarray, camera: PinholeCamera, T_world_cam: np.ndarray, camera_to: PinholeCamera,
                 T_world_cam_to: np.ndarray, depth_to: np.ndarray, tolerance: float) -> Flow:
    """Flow of every pixel of view A (``depth`` (H, W) planar metres, +inf on miss, ``camera`` at ``T_world_cam``)
    into view B (``camera_to`` at ``T_world_cam_to``, its depth map ``depth_to`` for the occlusion test with
    relative ``tolerance``; module docstring)."""
    z = np.asarray(depth, dtype=np.float64).ravel()
    pixels = camera.pixel_centres()
    hit = np.isfinite(z)
    points_cam = np.concatenate([camera.pixels_to_normalized(pixels[hit]) * z[hit, None], z[hit, None]], axis=1)
    points_world = points_cam @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]
    landed, z_to = project_world_points(camera_to, T_world_cam_to, points_world)
    target = np.full((len(z), 2), np.nan)
    target[hit] = landed
    depth_in_b = np.full(len(z), np.nan)
    depth_in_b[hit] = z_to
    valid = np.isfinite(target).all(axis=1)
    uv = np.where(valid[:, None], target - pixels, 0.0).astype(np.float32)
    visible = valid & visible_at(depth_to, target[:, 0], target[:, 1], depth_in_b, tolerance)
    shape = camera.shape
    return Flow(uv.reshape(*shape, 2), valid.reshape(shape), visible.reshape(shape))
