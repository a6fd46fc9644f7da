"""Synthetic views of a textured ground plane (z = 0, ENU): cameras, images by plane homography, truth."""

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from recon.surface.dense import View
from tools.geotag_csv import geotag_row

WIDTH, HEIGHT, FOCAL = 640, 480, 600.0
TEXTURE_M_PER_PX = 0.02
TEXTURE_SIZE = 4000


def look_down_view(centre, yaw_deg: float, tilt_deg: float = 0.0) -> View:
    """Camera at ``centre`` (ENU m) looking down at the z = 0 plane, image x along ``yaw``; tilted about x."""
    yaw, tilt = np.radians(yaw_deg), np.radians(tilt_deg)
    x_axis = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    z_axis = np.array([0.0, 0.0, -1.0])
    y_axis = np.cross(z_axis, x_axis)
    r_world_cam = np.stack([x_axis, y_axis, z_axis], axis=1)
    tilt_rot = cv2.Rodrigues(np.array([tilt, 0.0, 0.0]))[0]
    r_world_cam = r_world_cam @ tilt_rot
    R = r_world_cam.T
    K = np.array([[FOCAL, 0, WIDTH / 2], [0, FOCAL, HEIGHT / 2], [0, 0, 1.0]])
    return View(K, R, -R @ np.asarray(centre, dtype=float))


def render_plane(texture: np.ndarray, view: View) -> np.ndarray:
    """Image of the textured z = 0 plane (texture pixel (a, b) at world (a, b) * scale - half size)."""
    half = TEXTURE_SIZE * TEXTURE_M_PER_PX / 2
    texture_to_world = np.array([[TEXTURE_M_PER_PX, 0, -half], [0, TEXTURE_M_PER_PX, -half], [0, 0, 1]])
    plane_to_image = view.K @ np.column_stack([view.R[:, 0], view.R[:, 1], view.t])
    homography = plane_to_image @ texture_to_world
    return cv2.warpPerspective(texture, homography, (WIDTH, HEIGHT), flags=cv2.INTER_AREA)


def true_plane_depth(view: View) -> np.ndarray:
    u, v = np.meshgrid(np.arange(WIDTH, dtype=float), np.arange(HEIGHT, dtype=float))
    rays_cam = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(view.K).T
    rays_world = rays_cam @ view.R  # R^T applied to each ray
    return -view.centre[2] / rays_world[..., 2]


def make_texture(seed: int = 7) -> np.ndarray:
    """Grey multi-scale noise texture (uint8, TEXTURE_SIZE square), distinctive at several image scales."""
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, (TEXTURE_SIZE // 4, TEXTURE_SIZE // 4)).astype(np.float32)
    big = cv2.resize(noise, (TEXTURE_SIZE, TEXTURE_SIZE), interpolation=cv2.INTER_CUBIC)
    fine = rng.uniform(-40, 40, (TEXTURE_SIZE, TEXTURE_SIZE)).astype(np.float32)
    return np.clip(big + cv2.GaussianBlur(fine, (0, 0), 1.5), 0, 255).astype(np.uint8)


def write_nadir_photos(photos, centres, texture: np.ndarray) -> list[str]:
    """Nadir photos ``view_<i>.png`` of the textured plane from ``centres`` (ENU m, yaw 0) into the folder
    ``photos``; returns their geotags.csv rows (exact positions and attitudes)."""
    photos.mkdir(parents=True, exist_ok=True)
    rows = []
    for i, centre in enumerate(centres):
        view = look_down_view(centre, yaw_deg=0.0)
        cv2.imwrite(str(photos / f"view_{i}.png"), render_plane(texture, view))
        rows.append(geotag_row(f"view_{i}.png", centre, Rotation.from_matrix(view.R.T).as_quat(scalar_first=True)))
    return rows
