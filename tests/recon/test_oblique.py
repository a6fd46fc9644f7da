"""recon.measure.oblique against analytic scenes: the in-area mask, the wall/flat split, the similarity removal,
coverage.

Scenes: flat ground (sim.worlds.synthetic.grid_mesh), ground with a hole, and tests/sim/render_scene_helpers' ground
with a box of known corners; cameras nadir or level, so which pixel sees which ground point is known exactly.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from PIL import Image
from scipy.spatial.transform import Rotation

from recon.measure.oblique import (TwinFrame, render_view, sample_views, score_view, summarise, surface_points,
                                   true_camera_area, twin_frame, wall_mask)
from sim.render.camera import PinholeCamera, look_at
from sim.render.scene import Scene, Surface, load_scene, read_scene_json, read_scene_mesh_enu
from sim.render.scene_cameras import SceneCamera, write_cameras
from sim.render.shade import Sun
from sim.worlds.synthetic import grid_mesh
from tests.sim.render_scene_helpers import BOX_TOP_M, BOX_X_M, BOX_Y_M, ORIGIN, write_scene

SUN = Sun(135.0, 50.0, 0.8)
GREY, DARK = (150, 150, 150), (60, 60, 60)


def coloured(vertices, faces, rgb) -> Scene:
    """A scene of one vertex colour per vertex (``rgb``: one colour or (V, 3))."""
    colors = np.broadcast_to(np.asarray(rgb, np.uint8), (len(vertices), 3)).copy()
    return Scene(vertices, faces, Surface(vertex_colors=colors))


def flat_ground(hole_half_m: float = 0.0) -> Scene:
    """z = 0 over +-100 m in 1 m cells, without the cells inside +-``hole_half_m`` (a square hole)."""
    vertices, faces, _ = grid_mesh(200, 200, (-100.0, 100.0, -100.0, 100.0))
    centre = vertices[faces].mean(axis=1)
    keep = np.maximum(np.abs(centre[:, 0]), np.abs(centre[:, 1])) > hole_half_m
    return coloured(vertices, faces[keep], GREY)


def square(x0, x1, y0, y1) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


NADIR_CAMERA = PinholeCamera.from_fov(200, 150, 80.0)
NADIR_HEIGHT_M = 60.0
NADIR_POSE = look_at((0.0, 0.0, NADIR_HEIGHT_M), (0.0, 0.0, 0.0))


def nadir_ground_xy() -> np.ndarray:
    """(H, W, 2) ground point of every pixel centre of the nadir camera (image top = north, x = east)."""
    c = NADIR_CAMERA
    u, v = np.meshgrid(np.arange(c.width), np.arange(c.height))
    return np.stack([(u - c.cx) / c.fx, -(v - c.cy) / c.fy], axis=-1) * NADIR_HEIGHT_M


def in_rect(xy, x0, x1, y0, y1) -> np.ndarray:
    return (xy[..., 0] > x0) & (xy[..., 0] < x1) & (xy[..., 1] > y0) & (xy[..., 1] < y1)


def test_in_area_pixels_are_those_whose_true_ground_point_is_in_the_polygon():
    ground = flat_ground()
    view = render_view(ground, NADIR_CAMERA, NADIR_POSE, SUN)
    expected_xy = nadir_ground_xy()
    np.testing.assert_allclose(surface_points(view)[..., :2], expected_xy, atol=1e-3)
    area = square(5.0, 25.0, -10.0, 0.0)  # off centre: a mirrored image would count other pixels
    scores = score_view(view, view, area)
    assert scores.in_area == in_rect(expected_xy, 5.0, 25.0, -10.0, 0.0).sum() > 500
    assert (scores.coverage, scores.error_in_area, scores.depth_abs_rel, scores.wall_fraction) == (1.0, 0.0, 0.0, 0.0)
    assert math.isnan(scores.error_walls)  # no wall pixel at all


def test_coverage_of_a_twin_with_a_hole():
    view = render_view(flat_ground(), NADIR_CAMERA, NADIR_POSE, SUN)
    holed = render_view(flat_ground(hole_half_m=5.0), NADIR_CAMERA, NADIR_POSE, SUN)
    scores = score_view(view, holed, square(-20.0, 20.0, -20.0, 20.0))
    xy = nadir_ground_xy()
    in_area, in_hole = in_rect(xy, -20, 20, -20, 20), in_rect(xy, -5, 5, -5, 5)
    assert scores.coverage == pytest.approx(1.0 - in_hole.sum() / in_area.sum())  # ~1 - 100/1600
    assert scores.coverage == pytest.approx(1.0 - 100 / 1600, abs=0.01)
    assert scores.error_in_area == 0.0 and scores.depth_abs_rel == 0.0  # what the twin covers is the truth
    assert scores.error_whole > 0.0  # the hole shows the sky


def box_scene(box_rgb) -> Scene:
    """render_scene_helpers' box on flat ground; the box (walls and top) coloured ``box_rgb``."""
    ground_v, ground_f, _ = grid_mesh(8, 8, (-400.0, 400.0, -400.0, 400.0))
    box = trimesh.creation.box(bounds=[[BOX_X_M[0], BOX_Y_M[0], 0.0], [BOX_X_M[1], BOX_Y_M[1], BOX_TOP_M]])
    vertices = np.vstack([ground_v, box.vertices])
    colors = np.vstack([np.tile(GREY, (len(ground_v), 1)), np.tile(box_rgb, (len(box.vertices), 1))])
    return coloured(vertices, np.vstack([ground_f, box.faces + len(ground_v)]), colors)


def test_walls_and_flat_pixels_of_a_box_seen_level_from_the_south():
    camera = PinholeCamera.from_fov(320, 240, 60.0)
    eye_x, eye_y, eye_z = -2.0, BOX_Y_M[0] - 30.0, BOX_TOP_M / 2  # 30 m south of the south wall, mid-height
    pose = look_at((eye_x, eye_y, eye_z), (eye_x, 0.0, eye_z))
    truth = render_view(box_scene(GREY), camera, pose, SUN)
    # only the south wall is seen: pixel centres within its projection (20 m x 10 m at 30 m)
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    x, z = eye_x + (u - camera.cx) / camera.fx * 30.0, eye_z - (v - camera.cy) / camera.fy * 30.0
    expected = (x > BOX_X_M[0]) & (x < BOX_X_M[1]) & (z > 0.0) & (z < BOX_TOP_M)
    np.testing.assert_array_equal(wall_mask(truth), expected)

    twin = render_view(box_scene(DARK), camera, pose, SUN)  # the same shape, darker walls
    scores = score_view(truth, twin, square(-50.0, 50.0, -50.0, 50.0))
    seen = truth.valid & in_rect(surface_points(truth), -50, 50, -50, 50)
    assert scores.wall_fraction == pytest.approx(expected.sum() / seen.sum())
    assert scores.error_flat == 0.0 and scores.error_walls > 5.0
    assert scores.error_in_area == pytest.approx(scores.error_walls * scores.wall_fraction)
    summary = summarise([scores, scores])
    assert summary["walls_to_flat"] != summary["walls_to_flat"]  # NaN: the flat pixels have no error
    assert summary["error_walls"] == pytest.approx(scores.error_walls) and summary["views"] == 2


def similarity(scale: float, rotvec_deg, translation) -> np.ndarray:
    S = np.eye(4)
    S[:3, :3] = scale * Rotation.from_rotvec(rotvec_deg, degrees=True).as_matrix()
    S[:3, 3] = translation
    return S


def orbit_truth(radius_m: float = 30.0, count: int = 12) -> dict:
    """A truth.json of ``count`` photos on a circle 30 m up, looking at the centre, home = the scene origin."""
    photos = []
    for k, angle in enumerate(np.linspace(0.0, 2 * math.pi, count, endpoint=False)):
        T = look_at((radius_m * math.cos(angle), radius_m * math.sin(angle), 30.0), (0.0, 0.0, 0.0))
        qw, qx, qy, qz = Rotation.from_matrix(T[:3, :3]).as_quat(scalar_first=True)
        photos.append({"image_name": f"P{k:02d}.JPG", "taken": True, "east_m": T[0, 3], "north_m": T[1, 3],
                       "up_m": T[2, 3], "qw": qw, "qx": qx, "qy": qy, "qz": qz})
    return {"origin": ORIGIN.to_dict(), "photos": photos}


def write_moved_twin(world_dir, twin_dir, S_twin_world: np.ndarray, truth: dict) -> None:
    """The true world moved by the similarity ``S_twin_world``, with its cameras (moved too) in cameras.json."""
    vertices, faces, surface = read_scene_mesh_enu(world_dir, read_scene_json(world_dir))
    visual = trimesh.visual.TextureVisuals(uv=surface.uv, image=Image.fromarray(surface.texture))
    twin_dir.mkdir()
    trimesh.Trimesh(vertices @ S_twin_world[:3, :3].T + S_twin_world[:3, 3], faces, visual=visual,
                    process=False).export(twin_dir / "terrain.obj")
    scale = np.cbrt(np.linalg.det(S_twin_world[:3, :3]))
    cameras = []
    for row in truth["photos"]:
        T = S_twin_world @ look_at((row["east_m"], row["north_m"], row["up_m"]), (0.0, 0.0, 0.0))
        T[:3, :3] /= scale
        cameras.append(SceneCamera(row["image_name"], PinholeCamera.from_fov(800, 600, 80.0), T))
    write_cameras(twin_dir / "cameras.json", cameras)
    meta = json.loads((world_dir / "scene.json").read_text())
    meta.update(cameras="cameras.json", valid_area_m=None)
    (twin_dir / "scene.json").write_text(json.dumps(meta))


def test_a_twin_moved_by_a_known_similarity_scores_like_the_truth(tmp_path):
    world_dir = write_scene(tmp_path / "world")
    truth = orbit_truth()
    S_twin_world = similarity(0.8, [2.0, -1.0, 30.0], [5.0, -3.0, 2.0])
    write_moved_twin(world_dir, tmp_path / "twin", S_twin_world, truth)

    frame = twin_frame(tmp_path / "twin", truth, ORIGIN)
    np.testing.assert_allclose(frame.T_world_twin, np.linalg.inv(S_twin_world), atol=1e-6)
    assert frame.scale == pytest.approx(1.25)
    assert frame.rotation_deg == pytest.approx(np.linalg.norm([2.0, -1.0, 30.0]))
    area = true_camera_area(truth, [row["image_name"] for row in truth["photos"]], ORIGIN)
    assert len(area) == 12 and np.hypot(*area.T) == pytest.approx(np.full(12, 30.0))

    world, twin = load_scene(world_dir), load_scene(tmp_path / "twin")
    camera = PinholeCamera.from_fov(160, 120, 80.0)
    views = sample_views(world, camera, area, 3, seed=4)
    for sample in views:
        T = sample.T_world_cam
        assert np.hypot(*T[:2, 3]) < 30.0 and 20.0 <= sample.height_above_ground_m <= 100.0
        assert max(abs(sample.details["tilt_x_deg"]), abs(sample.details["tilt_y_deg"])) <= 45.0
        assert math.degrees(math.acos(-T[2, 2])) <= 60.0 + 1e-9  # optical axis from nadir: 45 deg about each axis
        scores = score_view(render_view(world, camera, T, SUN),
                            render_view(twin, camera, frame.camera_pose(T), frame.sun(SUN)), area, frame.scale)
        assert scores.in_area > 1000
        assert scores.coverage > 0.999 and scores.error_in_area < 0.05 and scores.depth_abs_rel < 1e-5
    # without the similarity's scale the depths are off by it
    unscaled = score_view(render_view(world, camera, views[0].T_world_cam, SUN),
                          render_view(twin, camera, frame.camera_pose(views[0].T_world_cam), frame.sun(SUN)), area)
    assert unscaled.depth_abs_rel == pytest.approx(0.2, abs=1e-3)


def test_twin_frame_maps_poses_and_sun_consistently():
    frame = TwinFrame(similarity(2.0, [0.0, 0.0, 90.0], [10.0, 0.0, 0.0]))  # twin x = world north
    T_world_cam = look_at((10.0, 20.0, 30.0), (10.0, 20.0, 0.0))
    T_twin_cam = frame.camera_pose(T_world_cam)
    np.testing.assert_allclose(frame.T_world_twin[:3, :3] @ T_twin_cam[:3, 3] + frame.T_world_twin[:3, 3],
                               T_world_cam[:3, 3])
    np.testing.assert_allclose(T_twin_cam[:3, 3], [10.0, 0.0, 15.0], atol=1e-12)
    sun = frame.sun(Sun(90.0, 30.0, 0.7))  # from the east in the world: from twin -y (south)
    assert (sun.azimuth_deg, sun.elevation_deg, sun.intensity) == pytest.approx((180.0, 30.0, 0.7))
