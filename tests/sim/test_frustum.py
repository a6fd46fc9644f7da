"""The frustum margin: sampled frames see nothing past the valid area, checked by casting every pixel's ray."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from matplotlib.path import Path as PolygonPath

from sim.camera import PinholeCamera, Rig, camera_rays
from sim.frame_renderer import SceneGround
from sim.frustum import ViewFrustum
from sim.raycast import intersect
from sim.sampling import RandomPoseSettings, camera_rotation, frustum_margin, lawnmower, random_pose
from sim.scene import Scene, SceneError, Surface, read_scene_json

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
