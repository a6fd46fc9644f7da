"""Dense SGBM depth on a synthetic textured plane seen by two known cameras (truth: ray-plane depth)."""

import cv2
import numpy as np
import pytest

from recon.dense import View, fuse_pair_depths, normals_from_depth, pair_depth

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


@pytest.fixture(scope="module")
def texture():
    rng = np.random.default_rng(7)
    noise = rng.uniform(0, 255, (TEXTURE_SIZE // 4, TEXTURE_SIZE // 4)).astype(np.float32)
    big = cv2.resize(noise, (TEXTURE_SIZE, TEXTURE_SIZE), interpolation=cv2.INTER_CUBIC)
    fine = rng.uniform(-40, 40, (TEXTURE_SIZE, TEXTURE_SIZE)).astype(np.float32)
    return np.clip(big + cv2.GaussianBlur(fine, (0, 0), 1.5), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("src_offset, yaw_deg", [((4.0, 0.0), 0.0), ((-4.0, 0.0), 0.0), ((0.0, 4.0), 30.0), ((0.0, -6.0), 0.0), ((0.0, 6.0), 0.0)])
def test_sgbm_recovers_plane_depth(texture, src_offset, yaw_deg):
    """Right, left and diagonal/vertical baselines all give the plane's depth to within 1 % (median)."""
    ref = look_down_view((0.0, 0.0, 30.0), yaw_deg, tilt_deg=5.0)
    src = look_down_view((src_offset[0], src_offset[1], 30.0), yaw_deg + 3.0, tilt_deg=-3.0)
    depth = pair_depth(render_plane(texture, ref), render_plane(texture, src), ref, src, (20.0, 45.0))
    truth = true_plane_depth(ref)
    valid = np.isfinite(depth)
    relative = np.abs(depth[valid] - truth[valid]) / truth[valid]
    assert valid.mean() > 0.5
    assert np.median(relative) < 0.01
    assert np.percentile(relative, 90) < 0.03


def test_consistency_keeps_agreeing_or_single_estimates():
    a = np.array([[10.0, 10.0, np.nan, np.nan]])
    b = np.array([[10.1, 14.0, 10.0, np.nan]])
    c = np.array([[np.nan, 14.2, np.nan, np.nan]])
    fused = fuse_pair_depths([a, b, c], tolerance=0.02)
    assert fused[0, 0] == pytest.approx(10.05)  # two agree
    assert fused[0, 1] == pytest.approx(14.1)  # the two that agree win over the outlier
    assert fused[0, 2] == pytest.approx(10.0)  # only one neighbour sees it
    assert np.isnan(fused[0, 3])
    disagree = fuse_pair_depths([np.array([[10.0]]), np.array([[12.0]])], tolerance=0.02)
    assert np.isnan(disagree[0, 0])


def test_normals_of_a_fronto_parallel_plane_face_the_camera():
    K = np.array([[100.0, 0, 50], [0, 100.0, 40], [0, 0, 1]])
    normals = normals_from_depth(np.full((80, 100), 7.0), K)
    assert np.allclose(normals[5:-5, 5:-5], [0, 0, -1], atol=1e-9)
