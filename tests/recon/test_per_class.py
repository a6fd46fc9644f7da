"""recon.measure.per_class against a tiny labelled truth world with known answers.

The world: flat ground (class ground), a 10 m box building (roof on top, walls around: one object), a thin 8 m
vertical cylinder pole (a lamp post) and a 1.5 m box car, each with its class and instance. Cameras nadir straight over
the car or the pole (only their tops are seen, at a known planar depth) or level facing the building's south wall, so
which pixel sees what, and at which depth, is known exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from recon.measure.per_class import (NEAR_M, SEEN_PIXELS, count_objects, object_kinds, objects_in_area, pool_classes,
                                     score_classes)
from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.classes import CAR, GROUND, POLE, ROOF, WALL
from sim.render.labels import SceneLabels
from sim.render.scene import Scene, Surface
from sim.render.renderer import View, render
from sim.render.shade import UNLIT
from sim.worlds.synthetic import grid_mesh

CAMERA = PinholeCamera.from_fov(64, 48, 60.0)
AREA = np.array([[-50.0, -50.0], [50.0, -50.0], [50.0, 50.0], [-50.0, 50.0]])
BUILDING_X, BUILDING_Y, BUILDING_TOP = (-12.0, -2.0), (-6.0, 6.0), 10.0
POLE_XY, POLE_RADIUS, POLE_TOP = (6.0, 0.0), 0.25, 8.0
CAR_X, CAR_Y, CAR_TOP = (16.0, 20.0), (-1.0, 1.0), 1.5
BUILDING, LAMP, AUTO = 1, 2, 3  # instance ids
KINDS = {LAMP: "lamp_post", AUTO: "car"}
CAR_POSE = look_at((18.0, 0.0, 6.0), (18.0, 0.0, 0.0))  # nadir, 4.5 m above the car's roof
POLE_POSE = look_at((*POLE_XY, 10.0), (*POLE_XY, 0.0))  # nadir, 2 m above the pole's top
OBLIQUE_POSE = look_at((-5.0, -40.0, 25.0), (4.0, 0.0, 2.0))  # sees the four of them


def box(x, y, top) -> trimesh.Trimesh:
    return trimesh.creation.box(bounds=[[x[0], y[0], 0.0], [x[1], y[1], top]])


def world(building_top: float = BUILDING_TOP, pole: bool = True, car: bool = True, ground_z: float = 0.0) -> Scene:
    """The labelled world; a twin of it with a lower building, without the pole or the car, or with the ground at
    ``ground_z``."""
    ground_v, ground_f, _ = grid_mesh(50, 50, (-100.0, 100.0, -100.0, 100.0))
    ground_v[:, 2] = ground_z
    parts = [(ground_v, ground_f, np.full(len(ground_f), GROUND), 0, (120, 140, 90))]
    house = box(BUILDING_X, BUILDING_Y, building_top)
    roof = np.isclose(house.face_normals[:, 2], 1.0)
    parts.append((house.vertices, house.faces, np.where(roof, ROOF, WALL), BUILDING, (200, 80, 60)))
    if pole:
        shaft = trimesh.creation.cylinder(POLE_RADIUS, POLE_TOP, sections=16)
        shaft.apply_translation([*POLE_XY, POLE_TOP / 2])
        parts.append((shaft.vertices, shaft.faces, np.full(len(shaft.faces), POLE), LAMP, (90, 90, 90)))
    if car:
        auto = box(CAR_X, CAR_Y, CAR_TOP)
        parts.append((auto.vertices, auto.faces, np.full(len(auto.faces), CAR), AUTO, (30, 30, 160)))
    vertices, faces, colors, face_class, face_instance, offset = [], [], [], [], [], 0
    for part_vertices, part_faces, part_class, instance, rgb in parts:
        vertices.append(np.asarray(part_vertices, float))
        faces.append(np.asarray(part_faces) + offset)
        colors.append(np.tile(rgb, (len(part_vertices), 1)))
        face_class.append(part_class)
        face_instance.append(np.full(len(part_faces), instance))
        offset += len(part_vertices)
    face_class = np.concatenate(face_class).astype(np.uint8)
    labels = SceneLabels(face_class, np.concatenate(face_instance), np.ones(len(face_class)))
    return Scene(np.vstack(vertices), np.vstack(faces), Surface(vertex_colors=np.vstack(colors).astype(np.uint8)),
                 labels=labels)


@pytest.fixture(scope="module")
def truth() -> Scene:
    return world()


def unlit_view(scene: Scene, camera: PinholeCamera, pose: np.ndarray) -> View:
    """The scene's albedo seen from ``pose``: no shadow or shade, so what a twin lost changes only its own pixels."""
    return render(scene, Rig((camera,)), pose, **UNLIT).views[0]


def scored(truth: Scene, twin: Scene, pose: np.ndarray, camera: PinholeCamera = CAMERA):
    return score_classes(unlit_view(truth, camera, pose), unlit_view(twin, camera, pose), truth.labels, AREA,
                         instances=KINDS)


def test_the_truth_against_itself_is_covered_exactly_everywhere_and_every_object_recovered(truth):
    views = [scored(truth, truth, pose) for pose in (CAR_POSE, POLE_POSE, OBLIQUE_POSE)]
    pooled = pool_classes(views)
    assert set(pooled["classes"]) == {"ground", "roof", "wall", "pole", "car"}
    assert views[0].in_area == views[1].in_area == CAMERA.width * CAMERA.height  # the nadir views see only the area
    for row in [*pooled["classes"].values(), *(pooled["groups"][g] for g in ("ground", "building", "objects"))]:
        assert (row["coverage"], row["abs_rel_median"], row["abs_rel_mean"], row["off"], row["off_near"],
                row["error_covered"]) == (1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert pooled["groups"]["vegetation"]["pixels"] == 0 and math.isnan(pooled["groups"]["vegetation"]["coverage"])
    assert sum(row["share"] for row in pooled["classes"].values()) == pytest.approx(1.0)
    assert pooled["groups"]["objects"]["pixels"] == pooled["classes"]["pole"]["pixels"] + \
        pooled["classes"]["car"]["pixels"]
    counted = count_objects(views, KINDS, objects_in_area(truth, KINDS, AREA))
    for kind in ("lamp_post", "car"):
        assert counted["kinds"][kind] == {"in_area": 1, "pixels": counted["kinds"][kind]["pixels"], "coverage": 1.0,
                                          "seen": 1, "recovered": 1, "recovered_near": 1, "share_recovered": 1.0}
        assert counted["kinds"][kind]["pixels"] >= SEEN_PIXELS


def test_a_twin_that_lost_the_pole_and_the_car_shows_the_ground_under_them(truth):
    """Straight above each, the twin shows the ground at the camera's height where the truth has the top 4.5 m (car)
    and 2 m (pole) away: every pixel covered, none within 20 %; the ground's pixels are those of the truth's."""
    twin = world(pole=False, car=False)
    poses = (CAR_POSE, POLE_POSE)
    lost, kept = [scored(truth, twin, pose) for pose in poses], [scored(truth, truth, pose) for pose in poses]
    pooled = pool_classes(lost)
    car, pole = pooled["classes"]["car"], pooled["classes"]["pole"]
    for row in (car, pole):
        assert (row["coverage"], row["off"], row["off_near"]) == (1.0, 1.0, 1.0)
    assert car["abs_rel_median"] == pytest.approx(CAR_TOP / (6.0 - CAR_TOP), rel=1e-5)
    assert pole["abs_rel_mean"] == pytest.approx(POLE_TOP / (10.0 - POLE_TOP), rel=1e-5)
    assert pooled["groups"]["objects"]["off"] == 1.0 and car["error_covered"] > 10.0
    assert pooled["classes"]["ground"] == pool_classes(kept)["classes"]["ground"]
    assert pooled["classes"]["ground"]["off"] == 0.0
    counted = count_objects(lost, KINDS, objects_in_area(truth, KINDS, AREA))["kinds"]
    for kind in ("lamp_post", "car"):
        assert (counted[kind]["seen"], counted[kind]["recovered"], counted[kind]["share_recovered"]) == (1, 0, 0.0)


def test_a_lost_car_seen_from_20_m_passes_the_20_percent_test_but_not_the_metric_one(truth):
    """From 20 m the ground under a 1.5 m car is 1.5 / 18.5 = 8 % farther than its roof: within 20 %."""
    pose = look_at((18.0, 0.0, 20.0), (18.0, 0.0, 0.0))
    view = scored(truth, world(car=False), pose)
    car = pool_classes([view])["classes"]["car"]
    assert car["abs_rel_median"] == pytest.approx(CAR_TOP / (20.0 - CAR_TOP), rel=1e-5)
    assert (car["off"], car["off_near"]) == (0.0, 1.0)
    counted = count_objects([view], KINDS, objects_in_area(truth, KINDS, AREA))["kinds"]["car"]
    assert counted["pixels"] >= SEEN_PIXELS and CAR_TOP > NEAR_M
    assert (counted["recovered"], counted["recovered_near"]) == (1, 0)


def test_a_ground_0_4_m_too_low_is_near_the_truth_even_where_rays_graze_it(truth):
    """From 5 m up, 60 m south, looking at the origin: every true ground pixel's ray meets the twin's ground 0.4 m
    under the true one at 0.4 / 5 = 8 % more depth, so 0.08 x its distance (0.9 m or more beyond the area's edge 11 m
    away) farther along the ray, but 0.4 m from the true plane."""
    view = scored(truth, world(ground_z=-0.4), look_at((0.0, -60.0, 5.0), (0.0, 0.0, 0.0)))
    ground = pool_classes([view])["classes"]["ground"]
    assert ground["pixels"] > 1000 and ground["coverage"] == 1.0
    assert ground["abs_rel_median"] == pytest.approx(0.4 / 5.0, rel=1e-4)
    assert ground["abs_rel_mean"] == pytest.approx(0.4 / 5.0, rel=1e-4)
    assert (ground["off"], ground["off_near"]) == (0.0, 0.0)


def test_a_building_20_percent_too_low_leaves_holes_over_the_top_fifth_of_its_wall(truth):
    """Level, 20 m south of the south wall at 4 m: the rows whose ray meets the wall above 8 m see the sky in the
    twin (holes, off), the rows below see the same wall (exact)."""
    camera = PinholeCamera.from_fov(64, 48, 60.0)
    eye = np.array([-7.0, BUILDING_Y[0] - 20.0, 4.0])
    view = scored(truth, world(building_top=0.8 * BUILDING_TOP), look_at(eye, eye + [0.0, 1.0, 0.0]), camera)
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    x, z = eye[0] + (u - camera.cx) / camera.fx * 20.0, eye[2] - (v - camera.cy) / camera.fy * 20.0
    wall = (x > BUILDING_X[0]) & (x < BUILDING_X[1]) & (z > 0.0) & (z < BUILDING_TOP)
    above = wall & (z > 0.8 * BUILDING_TOP)
    building = pool_classes([view])["groups"]["building"]
    assert building["pixels"] == wall.sum() and above.sum() > 0
    assert building["off"] == building["off_near"] == pytest.approx(above.sum() / wall.sum())
    assert building["coverage"] == pytest.approx(1.0 - above.sum() / wall.sum())
    assert building["abs_rel_mean"] < 1e-6  # what the twin covers is the same wall (float32 depths)
    # pooled with an exact view of the wall, the holes count by pixels, not by views
    both = pool_classes([view, scored(truth, truth, look_at(eye, eye + [0.0, 1.0, 0.0]), camera)])
    assert both["groups"]["building"]["off"] == pytest.approx(above.sum() / (2 * wall.sum()))


def test_objects_in_the_area_are_those_whose_centre_is_in_it(truth):
    west_half = np.array([[-50.0, -50.0], [10.0, -50.0], [10.0, 50.0], [-50.0, 50.0]])
    assert objects_in_area(truth, KINDS, west_half) == {LAMP}
    assert objects_in_area(truth, KINDS, AREA) == {LAMP, AUTO}


def test_object_kinds_keeps_the_small_things_and_names_a_bad_entry():
    objects = [{"instance": 5, "kind": "chimney"}, {"instance": 6, "kind": "dormer"}, {"instance": 7, "kind": "wire"}]
    assert object_kinds(objects, "scene.json") == {5: "chimney", 7: "wire"}
    with pytest.raises(ValueError, match=r"^w/scene.json: objects\[1\]: expected an integer 'instance'"):
        object_kinds([{"instance": 5, "kind": "car"}, {"instance": "6", "kind": "car"}], "w/scene.json")
