"""The demo world's built details and water (sim/worlds/built.py): each object's geometry, found by rays cast into the
loaded scene against the truth scene.json stores, its faces' class and object, and the ids the exports give them."""

import json

import numpy as np
import pytest

import sim.worlds.demo as demo
from sim.dataset.class_maps import CITYSCAPES_ID, VKITTI2_COLOURS, VKITTI2_RGB
from sim.render.classes import (CAR, CHIMNEY, CLASSES, FENCE, GROUPS, POLE, ROOF, TREE, WALL, WATER, WIRE)
from sim.render.raycast import intersect
from sim.render.scene import load_scene
from sim.worlds.built import NEAR_ORIGIN_M, OBJECT_KINDS
from sim.worlds.layout import distance_to_polyline
from sim.worlds.street_furniture import CROSSARM_HALF_M, MIN_POLES, POLE_SIDES, WIRE_RADIUS_M
from sim.worlds.water import FREEBOARD_M

DOWN = np.array([[0.0, 0.0, -1.0]])


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """(loaded scene, scene.json dict, objects by kind, layout) of the small world, seed 0."""
    folder = demo.build_demo_world(tmp_path_factory.mktemp("built") / "small", "small", 0)
    meta = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    by_kind = {kind: [o for o in meta["objects"] if o["kind"] == kind] for kind in OBJECT_KINDS}
    return load_scene(folder), meta, by_kind, demo.generate_world("small", 0)[0]


def _cast(scene, origins, directions):
    """(hit points, class, instance, hit from behind) of rays (origins (N, 3), unit directions (N, 3) or (1, 3))."""
    origins = np.atleast_2d(np.asarray(origins, np.float64))
    hits = intersect(scene, origins, np.broadcast_to(directions, origins.shape))
    assert np.all(hits.hit)
    points = origins + hits.t[:, None].astype(np.float64) * np.broadcast_to(directions, origins.shape)
    return points, scene.labels.face_class[hits.tri], scene.labels.face_instance[hits.tri], hits.back


def test_the_small_world_holds_every_kind_once_at_least_and_counts_them(world):
    _, meta, by_kind, _ = world
    assert all(by_kind[kind] for kind in OBJECT_KINDS), {k: len(v) for k, v in by_kind.items()}
    assert all(meta["provenance"][f"{kind}s"] == len(by_kind[kind]) for kind in OBJECT_KINDS)
    assert len(by_kind["wire"]) == 3 * (len(by_kind["power_pole"]) - 1)
    own = [o["instance"] for o in meta["objects"] if o["kind"] != "dormer"]
    assert len(set(own)) == len(own) and min(own) > meta["provenance"]["buildings"] + meta["provenance"]["trees"]


def test_a_ray_down_a_chimney_meets_its_top_at_its_height_above_the_roof(world):
    scene, _, by_kind, _ = world
    chimneys = by_kind["chimney"]
    origins = [[*c["position_m"], c["top_z_m"] + 10.0] for c in chimneys]
    points, classes, instances, back = _cast(scene, origins, DOWN)
    np.testing.assert_allclose(points[:, 2], [c["top_z_m"] for c in chimneys], atol=1e-3)
    assert np.all(classes == CHIMNEY) and not np.any(back)
    np.testing.assert_array_equal(instances, [c["instance"] for c in chimneys])
    for chimney in chimneys:
        assert 0.6 <= chimney["size_m"] <= 1.0 and 1.0 <= chimney["height_above_roof_m"] <= 2.0 + 1e-9


def test_a_ray_down_just_beside_a_chimney_meets_its_roof_below_its_top(world):
    """0.3 m past a chimney's side, along its building's ridge (where the roof keeps its height), a ray down meets
    the roof of the chimney's building no higher than the roof's top under the chimney."""
    scene, _, by_kind, layout = world
    for chimney in by_kind["chimney"]:
        building = layout.buildings[chimney["building_instance"] - 1]
        along = np.array([np.cos(building.heading_rad), np.sin(building.heading_rad)])
        assert np.degrees(building.heading_rad) == pytest.approx(chimney["heading_deg"], abs=1e-3)
        beside = np.array(chimney["position_m"]) + (chimney["size_m"] / 2 + 0.3) * along
        point, classes, instances, _ = _cast(scene, [[*beside, chimney["top_z_m"] + 10.0]], DOWN)
        assert (classes[0], instances[0]) == (ROOF, chimney["building_instance"])
        assert point[0, 2] <= chimney["roof_z_m"] + 1e-3
        assert chimney["top_z_m"] - point[0, 2] >= chimney["height_above_roof_m"] - 1e-3


@pytest.mark.parametrize("kind", ["lamp_post", "power_pole"])
def test_a_level_ray_at_half_height_hits_the_pole_at_its_radius(world, kind):
    """A ray 0.5 m from the pole's axis towards it meets its surface, an octagon between its inscribed and
    circumscribed circles, facing outwards, as the pole's own object."""
    scene, _, by_kind, _ = world
    poles = by_kind[kind]
    for angle in np.radians([0.0, 100.0, 230.0]):
        direction = np.array([[np.cos(angle), np.sin(angle), 0.0]])
        origins = [[*(np.array(p["position_m"]) - 0.5 * direction[0, :2]), (p["ground_z_m"] + p["top_z_m"]) / 2]
                   for p in poles]
        points, classes, instances, back = _cast(scene, origins, direction)
        from_axis = np.hypot(*(points[:, :2] - [p["position_m"] for p in poles]).T)
        radius = np.array([p["radius_m"] for p in poles])
        assert np.all(from_axis <= radius + 1e-3) and np.all(from_axis >= radius * np.cos(np.pi / POLE_SIDES) - 1e-3)
        assert np.all(classes == POLE) and not np.any(back)
        np.testing.assert_array_equal(instances, [p["instance"] for p in poles])
    heights = np.array([p["top_z_m"] - p["ground_z_m"] for p in poles])
    assert np.all((heights >= 5.0) & (heights <= 9.0)) and np.all((radius >= 0.07) & (radius <= 0.13))


def test_the_pond_is_flat_at_its_level_inside_its_shore_and_banks_rise_above_it(world):
    """Rays down from 1 m above the water inside the shoreline (0.5 m in) meet it at the stored level, upwards; 1.5 m
    outside, the bank stands above the level; the level is the freeboard under the lowest natural ground on the
    shore, and the bed lies under the water."""
    scene, _, by_kind, layout = world
    (pond,) = by_kind["pond"]
    center, shore = np.array(pond["center_m"]), np.array(pond["shoreline_m"])
    outward = (shore - center) / np.linalg.norm(shore - center, axis=1, keepdims=True)
    inside = np.vstack([center[None], center + 0.5 * (shore - center), shore - 0.5 * outward])
    above = np.full(len(inside), pond["level_z_m"] + 1.0)  # under the wires, which may cross the pond
    points, classes, instances, back = _cast(scene, np.column_stack([inside, above]), DOWN)
    np.testing.assert_allclose(points[:, 2], pond["level_z_m"], atol=1e-4)
    assert np.all(classes == WATER) and np.all(instances == pond["instance"]) and not np.any(back)
    outside = shore + 1.5 * outward
    points, classes, _, _ = _cast(scene, np.column_stack([outside, np.full(len(outside), 50.0)]), DOWN)
    banks = ~np.isin(classes, (TREE, POLE, FENCE, CAR, WIRE))
    assert np.all(points[banks, 2] > pond["level_z_m"] + 0.1) and np.count_nonzero(banks) > 0.8 * len(outside)
    natural = layout.terrain.natural.height(shore[:, 0], shore[:, 1])
    assert pond["level_z_m"] == pytest.approx(natural.min() - FREEBOARD_M, abs=1e-4)
    bed = layout.terrain.height(*center)
    assert bed == pytest.approx(pond["level_z_m"] - pond["depth_m"], abs=2e-4)  # both stored to 0.1 mm
    assert np.hypot(*center) <= NEAR_ORIGIN_M


def test_a_car_is_a_car_sized_box_of_its_own(world):
    """Each car's faces, in its own frame, span its stored length and width (4-4.6 m x 1.75-1.9 m) and reach its
    stored top 1.4-1.55 m above the ground; a ray down its middle meets its roof, the car's object."""
    scene, _, by_kind, _ = world
    for car in by_kind["car"]:
        own = scene.labels.face_instance == car["instance"]
        assert np.all(scene.labels.face_class[own] == CAR)
        points = scene.vertices[scene.faces[own]].reshape(-1, 3)
        heading = np.radians(car["heading_deg"])
        relative = points[:, :2] - car["position_m"]
        along = relative @ [np.cos(heading), np.sin(heading)]
        across = relative @ [-np.sin(heading), np.cos(heading)]
        assert np.ptp(along) == pytest.approx(car["length_m"], abs=1e-3)
        assert np.ptp(across) == pytest.approx(car["width_m"], abs=1e-3)
        assert points[:, 2].max() == pytest.approx(car["top_z_m"], abs=1e-3)
        assert 4.0 <= car["length_m"] <= 4.6 and 1.75 <= car["width_m"] <= 1.9
        assert 1.4 <= car["top_z_m"] - car["ground_z_m"] <= 1.55
        hit, classes, instances, _ = _cast(scene, [[*car["position_m"], car["top_z_m"] + 20.0]], DOWN)
        assert (classes[0], instances[0]) == (CAR, car["instance"]) and hit[0, 2] > car["ground_z_m"] + 0.8


def test_wires_sag_between_the_poles_and_are_thin(world):
    """Each wire's faces lie within its radius of the parabola through its ends whose lowest point scene.json
    stores, between two neighbouring poles."""
    scene, _, by_kind, _ = world
    poles = {tuple(p["position_m"]) for p in by_kind["power_pole"]}
    for wire in by_kind["wire"]:
        own = scene.labels.face_instance == wire["instance"]
        assert np.all(scene.labels.face_class[own] == WIRE)
        points = scene.vertices[scene.faces[own]].reshape(-1, 3)
        start, end = np.array(wire["start_m"]), np.array(wire["end_m"])
        span = end[:2] - start[:2]
        t = np.clip((points[:, :2] - start[:2]) @ span / (span @ span), 0, 1)
        sag = wire["sag_per_m"] * np.linalg.norm(span)
        curve = start + t[:, None] * (end - start) - np.outer(4 * sag * t * (1 - t), [0, 0, 1])
        assert np.all(np.linalg.norm(points - curve, axis=1) < WIRE_RADIUS_M + 0.01)
        assert points[:, 2].min() == pytest.approx(wire["lowest_z_m"], abs=0.02)
        assert min(np.hypot(*(np.array(p) - start[:2])) for p in poles) < 1.1  # hangs on a pole's crossarm or top


def test_the_power_line_is_a_row_of_poles_whose_wires_clear_buildings_and_crowns(world):
    """At least four poles in a straight row 30-70 m apart passing the origin at 10-45 m; under no wire (within the
    crossarm's half length + 0.5 m of a span) a building reaches its lowest wire less 1 m or a crown its lowest
    wire less 0.5 m; lamp posts, fences and cars stand off the corridor."""
    _, _, by_kind, layout = world
    poles = np.array([p["position_m"] for p in by_kind["power_pole"]])
    assert len(poles) >= MIN_POLES
    spans = np.diff(poles, axis=0)
    assert np.all((np.linalg.norm(spans, axis=1) > 30.0) & (np.linalg.norm(spans, axis=1) < 70.0))
    direction = spans[0] / np.linalg.norm(spans[0])
    normal = np.array([-direction[1], direction[0]])
    np.testing.assert_allclose((poles - poles[0]) @ normal, 0.0, atol=1e-3)
    assert 10.0 <= abs(poles[0] @ normal) <= NEAR_ORIGIN_M
    reach = CROSSARM_HALF_M + 0.5
    for span, (start, end) in enumerate(zip(poles[:-1], poles[1:])):
        lowest = min(w["lowest_z_m"] for w in by_kind["wire"] if w["span"] == span)
        samples = start + np.linspace(0, 1, 200)[:, None] * (end - start)
        for building in layout.buildings:
            if np.any(building.covers_local(*building.local(samples[:, 0], samples[:, 1]), reach)):
                assert building.ridge_z < lowest - 1.0
        for tree in layout.trees:
            if distance_to_polyline(tree.position[None], np.array([start, end]))[0] - tree.radius_m < reach:
                assert tree.ground_z + tree.height_m <= lowest - 0.5
    others = [o.get("position_m") or o["corners_m"][0] for k in ("lamp_post", "car", "fence") for o in by_kind[k]]
    assert distance_to_polyline(np.array(others), poles).min() > reach


def test_fences_run_along_their_corners_at_their_height(world):
    scene, _, by_kind, layout = world
    for fence in by_kind["fence"]:
        own = scene.labels.face_instance == fence["instance"]
        assert np.all(scene.labels.face_class[own] == FENCE)
        points = scene.vertices[scene.faces[own]].reshape(-1, 3)
        corners = np.array(fence["corners_m"])
        distance = np.min([np.abs((b - a)[0] * (points[:, 1] - a[1]) - (b - a)[1] * (points[:, 0] - a[0]))
                           / np.linalg.norm(b - a) for a, b in zip(corners[:-1], corners[1:])], axis=0)
        assert np.all(distance < 0.08)
        above_ground = points[:, 2] - layout.terrain.height(points[:, 0], points[:, 1])
        assert above_ground.max() == pytest.approx(fence["height_m"], abs=0.05)


def test_a_dormer_belongs_to_its_building_and_rises_from_its_roof(world):
    scene, meta, by_kind, layout = world
    for dormer in by_kind["dormer"]:
        building = layout.buildings[dormer["instance"] - 1]
        assert building.gable and building.eave_z < dormer["front_z_m"] < dormer["top_z_m"] < building.ridge_z
        point, classes, instances, _ = _cast(scene, [[*dormer["position_m"], building.ridge_z + 20]], DOWN)
        # just behind the front wall's middle the dormer's flat roof is the building's roof, at the dormer's top
        assert (classes[0], instances[0]) == (ROOF, dormer["instance"])
        assert point[0, 2] == pytest.approx(dormer["top_z_m"], abs=1e-3)
        own = scene.labels.face_instance == dormer["instance"]
        assert set(np.unique(scene.labels.face_class[own])) == {ROOF, WALL}


def test_every_object_listed_is_its_faces_and_nothing_else(world):
    scene, meta, _, _ = world
    for entry in meta["objects"]:
        if entry["kind"] == "dormer":
            continue
        own = scene.labels.face_instance == entry["instance"]
        assert sorted({CLASSES[c].name for c in np.unique(scene.labels.face_class[own])}) == sorted(entry["classes"])
    listed = {o["instance"] for o in meta["objects"]}
    provenance = meta["provenance"]
    beyond_vegetation = np.unique(scene.labels.face_instance)
    beyond_vegetation = beyond_vegetation[beyond_vegetation > provenance["buildings"] + provenance["trees"]
                                          + provenance["hedges"]]
    assert set(beyond_vegetation.tolist()) == listed - {o["instance"] for o in meta["objects"]
                                                        if o["kind"] == "dormer"}


def test_the_new_classes_export_to_their_cityscapes_and_vkitti2_classes_and_groups():
    vkitti2 = dict(VKITTI2_COLOURS)
    assert [CITYSCAPES_ID[c] for c in (CHIMNEY, POLE, WIRE, FENCE, CAR, WATER)] == [11, 17, 4, 13, 26, 0]
    for ours, theirs in ((CHIMNEY, "Building"), (POLE, "Pole"), (WIRE, "Misc"), (FENCE, "GuardRail"), (CAR, "Car")):
        assert tuple(VKITTI2_RGB[ours]) == vkitti2[theirs]
    assert CHIMNEY in GROUPS["building"] and WATER in GROUPS["ground"]
    assert set(GROUPS["objects"]) == {POLE, WIRE, FENCE, CAR}
    assert [c.id for c in CLASSES[:10]] == list(range(10))  # appended: the earlier ids stay


@pytest.mark.slow
def test_the_default_world_has_many_of_each_near_the_flight():
    """Chimneys on most roofs, dormers on some, lamp posts along both streets, a power line, fences and cars; the
    pond and the power line in sight of the default orbit (50 m around the origin)."""
    folder = demo.demo_scene_dir("default", 0)
    meta = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    count = meta["provenance"]
    assert count["chimneys"] >= 0.6 * count["buildings"] and count["dormers"] >= 3
    assert count["lamp_posts"] >= 12 and count["power_poles"] >= 6 and count["fences"] >= 5 and count["cars"] >= 15
    poles = np.array([o["position_m"] for o in meta["objects"] if o["kind"] == "power_pole"])
    assert np.min(np.hypot(*poles.T)) < 60.0
    (pond,) = [o for o in meta["objects"] if o["kind"] == "pond"]
    assert np.hypot(*pond["center_m"]) <= NEAR_ORIGIN_M and pond["radius_m"] >= 8.0
