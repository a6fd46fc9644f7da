"""The frustum margin: sampled frames see nothing past the valid area, checked by casting every pixel's ray."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from matplotlib.path import Path as PolygonPath

from sim.sampling import random_poses
from sim.render.camera import PinholeCamera, Rig, camera_rays, pose_from_position
from sim.run.poses import SceneGround
from sim.sampling.frustum import INNER_GRID_CELLS, ViewFrustum, inner_rectangle, sees_inside
from sim.render.raycast import intersect
from sim.sampling.trajectories import RANDOM_LOOP_TILT_DEG, lawnmower, random_loop
from sim.sampling.random_poses import RandomPoseSettings, frustum_margin, random_pose
from sim.sampling.pose import camera_rotation
from sim.render.scene import Scene, SceneError, Surface, read_scene_json
from sim.worlds.synthetic import grid_mesh

AREA = (-170.0, 170.0, -130.0, 130.0)
CAMERA = PinholeCamera.from_fov(48, 27, 80.0)
RIG = Rig.stereo(CAMERA, 0.54)


#: A reconstruction's covered area: a convex hexagon (ENU metres, clockwise) inside AREA.
HEXAGON = [[-150.0, 0.0], [-80.0, 120.0], [90.0, 125.0], [165.0, 0.0], [90.0, -125.0], [-80.0, -120.0]]


def analytic_scene(**kwargs) -> Scene:
    """A 4 km ground plane at z = 0 with a 25 m tower and a 6 m deep pit inside a 340 m x 260 m valid area:
    content lies far beyond the area, so a view reaching past its edge shows up as hits outside it."""
    plane = trimesh.creation.box(extents=(4000.0, 4000.0, 1.0))
    plane.apply_translation((0.0, 0.0, -0.5))
    tower = trimesh.creation.box(extents=(30.0, 20.0, 25.0))
    tower.apply_translation((60.0, -40.0, 12.5))
    pit = trimesh.creation.box(extents=(40.0, 40.0, 6.0))  # its floor at z = -6: the scene's lowest surface
    pit.apply_translation((-80.0, 50.0, -4.0))
    mesh = trimesh.util.concatenate([plane, tower, pit])
    colors = np.full((len(mesh.vertices), 3), 150, np.uint8)
    return Scene(mesh.vertices, mesh.faces, Surface(vertex_colors=colors), source="<frustum test>",
                 valid_area_m=dict(zip(("xmin", "xmax", "ymin", "ymax"), AREA)), **kwargs)


@pytest.fixture(scope="module")
def world() -> SceneGround:
    return SceneGround(analytic_scene())


def hits_outside(world: SceneGround, T_world_cam: np.ndarray, polygon=None) -> int:
    """How many pixel rays (every pixel of both cameras) miss or hit the scene outside the valid area (or
    ``polygon``, checked with matplotlib's point-in-polygon)."""
    xmin, xmax, ymin, ymax = AREA
    outside = 0
    for T in RIG.camera_poses(T_world_cam):
        rays = camera_rays(CAMERA, T)
        hits = intersect(world.scene, rays.origin, rays.directions)
        points = rays.origin + hits.t[:, None] * rays.directions
        inside = hits.hit & (points[:, 0] >= xmin - 1e-3) & (points[:, 0] <= xmax + 1e-3)
        inside &= (points[:, 1] >= ymin - 1e-3) & (points[:, 1] <= ymax + 1e-3)
        if polygon is not None:
            inside &= PolygonPath(polygon).contains_points(points[:, :2], radius=-1e-3)
        outside += int((~inside).sum())
    return outside


def test_nadir_reach_is_the_half_diagonal_field_of_view():
    """Straight down, a single camera's farthest view reaches D * tan(half-diagonal field of view)."""
    height = 73.0
    half_w = math.tan(math.radians(40.0))
    half_diagonal = math.hypot(half_w, half_w * CAMERA.height / CAMERA.width)
    single = ViewFrustum.of_rig(Rig((CAMERA,)))
    assert single.radius(camera_rotation(0.0), height) == pytest.approx(height * half_diagonal, rel=1e-9)
    # tilted, the reach stays under the bound D * tan(tilt + half-diagonal angle) and grows with the tilt
    for tilt in (10.0, 25.0, 40.0):
        bound = height * math.tan(math.radians(tilt) + math.atan(half_diagonal))
        assert height * half_diagonal < single.radius(camera_rotation(0.0, tilt), height) <= bound * (1 + 1e-9)
    # tilted forward, the image top's rays reach the horizon at 90 deg - half the vertical field of view
    horizon_tilt = 90.0 - math.degrees(math.atan(half_w * CAMERA.height / CAMERA.width))
    assert single.radius(camera_rotation(0.0, horizon_tilt - 0.5), height) > 50 * height
    assert single.radius(camera_rotation(0.0, horizon_tilt + 0.5), height) is None


def test_random_frames_see_only_the_valid_area(world):
    """Every ray of every sampled stereo frame hits the scene inside the valid area; the paper's fixed 20 m
    margin, on the same draws, lets frames see past it (so the check can fail)."""
    frustum = ViewFrustum.of_rig(RIG)
    settings = RandomPoseSettings(margin_m=0.0, max_attempts=500)
    samples = [random_pose(world, 2, index, settings, frustum=frustum) for index in range(40)]
    assert [hits_outside(world, s.T_world_cam) for s in samples] == [0] * len(samples)
    heights = [s.height_above_ground_m for s in samples]
    assert min(heights) < 40.0 and max(heights) > 70.0  # the paper's 20-100 m range is still sampled
    fixed = [random_pose(world, 2, index, RandomPoseSettings(margin_m=20.0)) for index in range(40)]
    assert sum(hits_outside(world, s.T_world_cam) > 0 for s in fixed) > 10


def test_lawnmower_with_the_frustum_margin_stays_inside(world):
    frustum = ViewFrustum.of_rig(RIG)
    margin = frustum_margin(world, frustum, 0.0, 40.0)
    path = lawnmower(world, 30.0, 40.0, 5.0, 0.5, margin_m=margin)
    frames = path.frames_available()
    assert frames > 20
    assert [hits_outside(world, path.pose(world, i).T_world_cam) for i in range(frames)] == [0] * frames
    with pytest.raises(ValueError, match="sees the horizon"):
        frustum_margin(world, frustum, 70.0, 40.0)  # the image top passes the horizon beyond 64.7 deg


def test_random_frames_stay_inside_a_reconstructions_observed_polygon(tmp_path):
    """With scene.json's observed_area_m, the views stay inside that (convex) polygon too."""
    world = SceneGround(analytic_scene(observed_area_m=HEXAGON))
    settings = RandomPoseSettings(margin_m=0.0, max_attempts=500)
    samples = [random_pose(world, 9, index, settings, frustum=ViewFrustum.of_rig(RIG)) for index in range(30)]
    assert [hits_outside(world, s.T_world_cam, np.array(HEXAGON)) for s in samples] == [0] * len(samples)
    plain = [random_pose(SceneGround(analytic_scene()), 9, i, settings, frustum=ViewFrustum.of_rig(RIG))
             for i in range(30)]
    assert sum(hits_outside(world, s.T_world_cam, np.array(HEXAGON)) > 0 for s in plain) > 3  # the rectangle's


def test_scene_json_observed_area_must_be_a_polygon(tmp_path):
    meta = {"format": "aerostereo-scene/1", "mesh": "world.glb",
            "origin": {"lat0_deg": 40.0, "lon0_deg": 44.0, "h0_ellipsoid_m": 1000.0}}
    (tmp_path / "scene.json").write_text(json.dumps({**meta, "observed_area_m": HEXAGON}), encoding="utf-8")
    assert read_scene_json(tmp_path)["observed_area_m"] == HEXAGON
    (tmp_path / "scene.json").write_text(json.dumps({**meta, "observed_area_m": [[0, 0], [1, "a"], [2, 2]]}),
                                         encoding="utf-8")
    with pytest.raises(SceneError, match="observed_area_m. must be a list of at least 3"):
        read_scene_json(tmp_path)


#: A non-convex covered area: an L (ENU metres, counter-clockwise) whose notch is the north-east quadrant
#: x > 0, y > 0 of AREA, its reflex corner at the origin.
L_SHAPE = [[-150.0, -110.0], [150.0, -110.0], [150.0, 0.0], [0.0, 0.0], [0.0, 110.0], [-150.0, 110.0]]


@pytest.fixture(scope="module")
def flat_l_world() -> SceneGround:
    """A flat ground z = 0 reaching 2 km beyond AREA, covered (scene.json's observed_area_m) by :data:`L_SHAPE`."""
    vertices, faces, _ = grid_mesh(4, 4, (-2000.0, 2000.0, -2000.0, 2000.0))
    return SceneGround(Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 150, np.uint8)),
                             source="<flat L>", valid_area_m=dict(zip(("xmin", "xmax", "ymin", "ymax"), AREA)),
                             observed_area_m=L_SHAPE))


def reach_points_inside(area, xy, reach, polygon) -> bool:
    """The test before non-convex areas: every reach point inside the rectangle and the polygon (matplotlib)."""
    points = np.asarray(xy, float)[:2] + reach
    xmin, xmax, ymin, ymax = area
    in_area = np.all((points[:, 0] >= xmin) & (points[:, 0] <= xmax) & (points[:, 1] >= ymin) & (points[:, 1] <= ymax))
    return bool(in_area and PolygonPath(polygon).contains_points(points).all())


def test_a_view_whose_reach_points_avoid_the_notch_but_whose_footprint_covers_it_is_refused(flat_l_world):
    """Nadir from 40 m, turned 45 deg, south-west of the L's reflex corner: the corner pokes into the footprint
    between two border samples; every reach point is inside the L, yet pixels see into the notch (ray cast)."""
    rotation, xy = camera_rotation(45.0), (-14.0, -8.0)
    reach = ViewFrustum.of_rig(RIG).reach(rotation, 40.0)
    assert reach_points_inside(AREA, xy, reach, np.array(L_SHAPE))
    assert hits_outside(flat_l_world, pose_from_position((*xy, 40.0), rotation), np.array(L_SHAPE)) > 0
    assert not sees_inside(AREA, xy, reach, np.array(L_SHAPE))
    assert sees_inside(AREA, (-40.0, -30.0), reach, np.array(L_SHAPE))  # farther from the corner: all inside


def test_random_frames_never_see_into_the_notch_of_a_non_convex_area(flat_l_world, monkeypatch):
    """Every pixel ray of 200 sampled stereo frames hits the ground inside the L; the same draws tested on their
    reach points only (right for convex areas) let frames see into the notch (so the check can fail)."""
    frustum = ViewFrustum.of_rig(RIG)
    settings = RandomPoseSettings(margin_m=0.0, max_attempts=500)
    polygon = np.array(L_SHAPE)
    samples = [random_pose(flat_l_world, 5, index, settings, frustum=frustum) for index in range(200)]
    assert [hits_outside(flat_l_world, s.T_world_cam, polygon) for s in samples] == [0] * len(samples)
    monkeypatch.setattr(random_poses, "sees_inside", reach_points_inside)
    points_only = [random_pose(flat_l_world, 5, index, settings, frustum=frustum) for index in range(200)]
    assert sum(hits_outside(flat_l_world, s.T_world_cam, polygon) > 0 for s in points_only) >= 2


def inside_convex(polygon: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The convex test the samplers used before: inside (or on) every edge of a convex polygon, either orientation."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    rel = points[:, None, :] - polygon[None]
    cross = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]
    doubled_area = np.sum(polygon[:, 0] * np.roll(polygon[:, 1], -1) - np.roll(polygon[:, 0], -1) * polygon[:, 1])
    return np.all(np.sign(doubled_area) * cross >= -1e-9, axis=1)


def test_a_convex_area_gets_the_same_decisions_as_the_convex_test():
    """400 random views (paper ranges of height and tilt, any heading) over the convex HEXAGON: the exact test
    decides as the convex one did (every reach point inside), both ways, many times each."""
    rng = np.random.default_rng(11)
    frustum, hexagon = ViewFrustum.of_rig(RIG), np.array(HEXAGON)
    decisions = []
    for _ in range(400):
        rotation = camera_rotation(rng.uniform(0.0, 360.0), *rng.uniform(-45.0, 45.0, 2))
        reach = frustum.reach(rotation, rng.uniform(20.0, 100.0))
        xy = rng.uniform((-100.0, -80.0), (120.0, 80.0))
        convex = reach is not None and bool(np.all(inside_convex(hexagon, xy + reach)))
        decisions.append((sees_inside(AREA, xy, reach, hexagon), convex))
    assert all(new == old for new, old in decisions)
    assert sum(new for new, _ in decisions) >= 40 and sum(not new for new, _ in decisions) >= 40


@pytest.mark.parametrize("path", ["lawnmower", "loop"])
def test_paths_with_the_frustum_margin_stay_inside_a_non_convex_area(flat_l_world, path):
    """The lawnmower and the random loop are flown in the largest rectangle inside the L less the frustum margin:
    every pixel ray of every frame hits the ground inside the L. Flown over the valid rectangle alone (the same
    ground without the polygon), they see into the notch."""
    frustum, polygon = ViewFrustum.of_rig(RIG), np.array(L_SHAPE)
    tilt = 0.0 if path == "lawnmower" else RANDOM_LOOP_TILT_DEG
    margin = frustum_margin(flat_l_world, frustum, tilt, 30.0)
    rectangle = SceneGround(Scene(flat_l_world.scene.vertices, flat_l_world.scene.faces, flat_l_world.scene.surface,
                                  valid_area_m=flat_l_world.scene.valid_area_m))
    for world, expect_inside in ((flat_l_world, True), (rectangle, False)):
        if path == "lawnmower":
            flown = lawnmower(world, 20.0, 30.0, 5.0, 0.5, margin_m=margin)
        else:
            flown = random_loop(world, 3, 30.0, 5.0, 0.5, margin_m=margin)
        frames = flown.frames_available() or int(flown.length_m / 5.0 * 0.5)
        outside = [hits_outside(world, flown.pose(world, i).T_world_cam, polygon) for i in range(frames)]
        assert frames > 15
        assert (outside == [0] * frames) == expect_inside


def test_inner_rectangle_is_the_largest_one_inside_the_polygon_less_the_margin():
    """In the L less 30 m: the west arm (90 m x 160 m beats the south arm's 240 m x 50 m), to within a grid cell;
    without a polygon, the valid area less the margin exactly; nothing when the margin eats the polygon."""
    polygon = np.array(L_SHAPE)
    xmin, xmax, ymin, ymax = inner_rectangle(AREA, polygon, 30.0)
    cell = max(150.0 - -150.0, 110.0 - -110.0) / INNER_GRID_CELLS
    assert xmin >= -120.0 and ymin >= -80.0 and xmax <= -30.0 and ymax <= 80.0  # every point 30 m inside
    assert xmin == pytest.approx(-120.0, abs=2 * cell) and xmax == pytest.approx(-30.0, abs=2 * cell)
    assert ymin == pytest.approx(-80.0, abs=2 * cell) and ymax == pytest.approx(80.0, abs=2 * cell)
    assert inner_rectangle(AREA, None, 30.0) == (-140.0, 140.0, -100.0, 100.0)
    assert inner_rectangle(AREA, polygon, 80.0) is None  # both arms are 150 m and 110 m wide: nothing is 80 m in


def test_random_cameras_with_a_fixed_margin_stand_that_far_inside_the_covered_polygon(flat_l_world):
    """The paper-era fixed margin keeps the camera positions, not the views, inside: 20 m inside the L as well as
    the valid area; the same draws on the rectangle alone put cameras in the notch or near its edges."""
    settings = RandomPoseSettings(margin_m=20.0)
    polygon = np.array(L_SHAPE)
    rectangle = SceneGround(Scene(flat_l_world.scene.vertices, flat_l_world.scene.faces, flat_l_world.scene.surface,
                                  valid_area_m=flat_l_world.scene.valid_area_m))
    for world, expect_inside in ((flat_l_world, True), (rectangle, False)):
        positions = np.array([random_pose(world, 4, index, settings).T_world_cam[:2, 3] for index in range(100)])
        inside = PolygonPath(polygon).contains_points(positions)
        edge_distance = np.min([np.abs(positions[:, 0] - x) for x in (-150.0, 150.0)]
                               + [np.abs(positions[:, 1] - y) for y in (-110.0, 110.0)], axis=0)
        notch_distance = np.hypot(np.maximum(-positions[:, 0], 0.0), np.maximum(-positions[:, 1], 0.0))
        deep = inside & (edge_distance >= 20.0) & (notch_distance >= 20.0)
        assert deep.all() == expect_inside
