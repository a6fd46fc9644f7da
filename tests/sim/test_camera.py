"""Cameras, rigs, poses, ray generation and projection against closed-form truth."""

import math
import warnings

import cv2
import numpy as np
import pytest

from sim.render.camera import (
    PinholeCamera,
    Rig,
    camera_rays,
    look_at,
    pose_from_position,
    project_world_points,
    row_dots,
    stratified_offsets,
)

DISTORTED = {
    "pinhole": (-0.28, 0.09, 0.0012, -0.0008, -0.015),
    "fisheye": (0.08, -0.02, 0.004, -0.001),
}


def test_from_fov_gives_the_focal_length_and_centred_principal_point():
    camera = PinholeCamera.from_fov(1280, 720, 90.0)
    assert camera.fx == pytest.approx(640.0) and camera.fy == pytest.approx(640.0)
    assert (camera.cx, camera.cy) == (639.5, 359.5)
    np.testing.assert_allclose(camera.K, [[640, 0, 639.5], [0, 640, 359.5], [0, 0, 1]])
    # the outer edge of the outermost pixel (u = -0.5) lies at 45 degrees
    direction = camera.ray_directions(np.array([[-0.5, 359.5]]))[0]
    assert math.degrees(math.atan2(-direction[0], direction[2])) == pytest.approx(45.0)


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_distorted_ray_directions_project_back_onto_their_pixels(model):
    camera = PinholeCamera(520.0, 515.0, 321.3, 238.7, 640, 480, dist=DISTORTED[model], model=model)
    pixels = camera.pixel_centres()[:: 7]
    directions = camera.ray_directions(pixels)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, atol=1e-12)
    # independent forward model: OpenCV's own projection of the ray direction
    project = cv2.fisheye.projectPoints if model == "fisheye" else cv2.projectPoints
    back, _ = project(directions.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, np.array(DISTORTED[model]))
    assert np.abs(back.reshape(-1, 2) - pixels).max() < 1e-6
    # and the distortion really bends rays: the corner ray differs from the undistorted model's
    plain = PinholeCamera(520.0, 515.0, 321.3, 238.7, 640, 480, model=model)
    assert np.degrees(np.arccos(directions[0] @ plain.ray_directions(pixels[:1])[0])) > 1.0


@pytest.mark.parametrize("dist", [None, DISTORTED["pinhole"]])
def test_projection_of_world_points_inverts_ray_generation(dist):
    camera = PinholeCamera(700.0, 690.0, 300.2, 200.9, 600, 400, dist=dist)
    T_world_cam = look_at([10.0, -20.0, 80.0], [30.0, 15.0, 0.0])
    rays = camera_rays(camera, T_world_cam)
    depth = np.linspace(5.0, 900.0, len(rays.depth_scale))
    points = rays.origin + rays.directions.astype(np.float64) * (depth / rays.depth_scale)[:, None]
    pixels, z = project_world_points(camera, T_world_cam, points)
    assert np.abs(pixels - camera.pixel_centres()).max() < 1e-3
    np.testing.assert_allclose(z, depth, rtol=1e-5)


@pytest.mark.parametrize("dist", [None, DISTORTED["pinhole"]])
def test_points_behind_the_camera_project_to_nan(dist):
    camera = PinholeCamera(56.0, 56.0, 31.5, 23.5, 64, 48, dist=dist)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a point in the camera's plane divides by zero, silently
        pixels, z = camera.project(np.array([[0.0, 0.0, -1.0], [0.1, 0.0, 2.0], [0.3, 0.2, 0.0]]))
    assert np.isnan(pixels[[0, 2]]).all() and np.isfinite(pixels[1]).all() and z[0] == -1.0


def test_stereo_rig_puts_camera_1_baseline_metres_to_the_right():
    camera = PinholeCamera.from_fov(64, 48, 60.0)
    rig = Rig.stereo(camera, 0.54)
    T_world_rig = look_at([0.0, 0.0, 50.0], [0.0, 40.0, 0.0])
    left, right = rig.camera_poses(T_world_rig)
    np.testing.assert_allclose(right[:3, 3] - left[:3, 3], 0.54 * left[:3, 0])
    np.testing.assert_allclose(right[:3, :3], left[:3, :3])
    with pytest.raises(ValueError, match="baseline"):
        Rig.stereo(camera, 0.0)


def test_look_at_points_z_at_target_with_image_up_towards_up():
    T = look_at([0.0, 0.0, 100.0], [100.0, 0.0, 0.0])
    np.testing.assert_allclose(T[:3, 2], [math.sqrt(0.5), 0.0, -math.sqrt(0.5)], atol=1e-12)
    assert T[2, 1] < 0  # camera y (image down) points down in the world
    nadir = look_at([5.0, 5.0, 100.0], [5.0, 5.0, 0.0])
    # nadir: image top towards north (x east, y south), the pose samplers' heading-0 convention
    np.testing.assert_allclose(nadir[:3, :3], [[1, 0, 0], [0, -1, 0], [0, 0, -1]], atol=1e-12)
    np.testing.assert_allclose(nadir[:3, :3].T @ nadir[:3, :3], np.eye(3), atol=1e-12)
    assert np.linalg.det(nadir[:3, :3]) == pytest.approx(1.0)


def test_pose_from_position_rejects_a_non_rotation():
    with pytest.raises(ValueError, match="rigid"):
        pose_from_position([0, 0, 0], np.diag([1.0, 1.0, -1.0]))


def test_pose_check_accepts_float32_rounding_and_rejects_a_skewed_rotation():
    T = look_at([3.0, -40.0, 25.0], [0.0, 0.0, 0.0])
    T[:3, :3] = T[:3, :3].astype(np.float32)
    pose_from_position(T[:3, 3], T[:3, :3])
    T[0, 1] += 1e-4
    with pytest.raises(ValueError, match="rigid"):
        pose_from_position(T[:3, 3], T[:3, :3])


def test_rays_of_a_pixel_range_are_those_rows_of_the_whole_image():
    camera = PinholeCamera(90.0, 92.0, 63.7, 47.2, 128, 96, dist=DISTORTED["pinhole"])
    T = look_at([1.0, -30.0, 20.0], [0.0, 0.0, 0.0])
    pixels = slice(1000, 4321)
    offsets = np.random.default_rng(0).random((camera.width * camera.height, 2)) - 0.5
    np.testing.assert_array_equal(camera.pixel_centres(pixels), camera.pixel_centres()[pixels])
    np.testing.assert_array_equal(camera_rays(camera, T, pixels=pixels).directions, camera_rays(camera, T).directions[pixels])
    part = camera_rays(camera, T, offsets[pixels], pixels=pixels)
    np.testing.assert_allclose(part.directions, camera_rays(camera, T, offsets).directions[pixels], atol=1e-7)
    np.testing.assert_allclose(part.depth_scale, camera_rays(camera, T, offsets).depth_scale[pixels], atol=1e-7)


def test_row_dots_match_the_dot_product_of_each_row():
    a, b = np.random.default_rng(1).standard_normal((2, 50, 3)).astype(np.float32)
    np.testing.assert_allclose(row_dots(a, b), np.einsum("ij,ij->i", a, b), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(row_dots(a, b[0]), a @ b[0], rtol=1e-6, atol=1e-6)


def test_stratified_offsets_put_one_sample_in_every_row_and_column_stratum():
    n, pixels = 8, 500
    samples = np.stack(list(stratified_offsets(n, pixels, np.random.default_rng(3))))  # (n, pixels, 2)
    assert samples.min() >= -0.5 and samples.max() < 0.5
    for axis in (0, 1):
        strata = np.floor((samples[..., axis] + 0.5) * n).astype(int)
        assert (np.sort(strata, axis=0) == np.arange(n)[:, None]).all()
    again = np.stack(list(stratified_offsets(n, pixels, np.random.default_rng(3))))
    np.testing.assert_array_equal(samples, again)
    (centre,) = stratified_offsets(1, pixels, np.random.default_rng(3))
    assert not centre.any()


def test_scaled_camera_keeps_the_field_of_view():
    camera = PinholeCamera(1000.0, 1000.0, 639.5, 359.5, 1280, 720, dist=DISTORTED["pinhole"])
    small = camera.scaled(64)
    assert (small.width, small.height) == (64, 36)
    corner = camera.ray_directions(np.array([[-0.5, -0.5]]))[0]
    np.testing.assert_allclose(small.ray_directions(np.array([[-0.5, -0.5]]))[0], corner, atol=1e-9)


def test_bad_intrinsics_are_rejected_clearly():
    with pytest.raises(ValueError, match="5 coefficients"):
        PinholeCamera(1, 1, 0, 0, 4, 4, dist=(0.1, 0.2))
    with pytest.raises(ValueError, match="model"):
        PinholeCamera(1, 1, 0, 0, 4, 4, model="orthographic")
