"""The demo world's vegetation: trunks under broadleaf crowns, crowns porous from above at their stated gap fraction,
conifer whorls with gaps, a forest stand with an edge, hedges; every face labelled tree with its own object, and the
per-tree truth in scene.json matching the built geometry (read back from the scene folder, not from the generator)."""

import json

import numpy as np
import pytest

import sim.worlds.demo as demo
from sim.render.classes import FIELD, GROUND, ROAD, TREE
from sim.render.raycast import intersect
from sim.render.scene import load_scene
from sim.worlds.atlas import PATCH_MARGIN_PX, VEGETATION_PATCH_PX, vegetation_patch_origin
from sim.worlds.layout import VARIANTS
from sim.worlds.vegetation import BROADLEAF_GAP_FRACTION, HEDGE_GAP_FRACTION, SINK_M

#: Spacing (m) of the straight-down sight lines over a crown.
SIGHT_STEP_M = 0.1


@pytest.fixture(scope="module")
def world():
    """(scene folder, loaded scene, scene.json, layout: without the trees the pond and the power line displace) of
    the cached small world, seed 0."""
    folder = demo.demo_scene_dir("small", 0)
    meta = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    layout = demo.generate_world("small", 0)[0]
    return folder, load_scene(folder), meta, layout


def _patch_of_faces(scene, faces):
    """Per face (of the scene's ``faces`` indices), the vegetation patch all its corners' UVs lie in ("leaves",
    "needles", "bark"), or "" when they lie in none (the orthophoto, a facade)."""
    spec = VARIANTS["small"]
    uv = scene.surface.uv[scene.faces[faces]]  # (F, 3, 2)
    col, row = uv[..., 0] * spec.texture_px, (1.0 - uv[..., 1]) * spec.texture_px
    names = np.full(len(faces), "", dtype=object)
    for name in ("leaves", "needles", "bark"):
        col0, row0 = vegetation_patch_origin(spec, name)
        low, high = PATCH_MARGIN_PX - 1e-3, VEGETATION_PATCH_PX - PATCH_MARGIN_PX + 1e-3
        inside = (col >= col0 + low) & (col <= col0 + high) & (row >= row0 + low) & (row <= row0 + high)
        names[np.all(inside, axis=1)] = name
    return names


def _first_hits(scene, origins, directions):
    """(instance, face index; -1 on a miss) of the first hit of each ray."""
    hits = intersect(scene, np.asarray(origins, np.float64), np.asarray(directions, np.float64))
    face = hits.tri.astype(np.int64)
    instance = np.where(face >= 0, scene.labels.face_instance[np.maximum(face, 0)], 0)
    return instance, face


def _sees_object(scene, origins, directions, instance, passes=8):
    """Whether each ray meets object ``instance`` at all (looking through other objects in the way, not through the
    ground)."""
    origins = np.array(origins, np.float64)
    directions = np.asarray(directions, np.float64)
    seen = np.zeros(len(origins), bool)
    going = np.arange(len(origins))
    for _ in range(passes):
        hits = intersect(scene, origins[going], directions[going])
        face = hits.tri.astype(np.int64)
        other = np.where(face >= 0, scene.labels.face_instance[np.maximum(face, 0)], 0)
        seen[going[other == instance]] = True
        onwards = (other > 0) & (other != instance)
        going = going[onwards]
        origins[going] += directions[going] * (hits.t[onwards, None] + 1e-3)
    return seen


def _own_faces(scene, instance):
    return np.flatnonzero(scene.labels.face_instance == instance)


def test_the_small_world_holds_each_kind(world):
    _, _, meta, layout = world
    vegetation, provenance = meta["vegetation"], meta["provenance"]
    kinds = [(t["kind"], t["forest"]) for t in vegetation["trees"]]
    assert {("broadleaf", False), ("conifer", False), ("broadleaf", True)} <= set(kinds)
    assert len(vegetation["forest_stands"]) == 1 and len(vegetation["forest_stands"][0]["tree_instances"]) >= 6
    assert len(vegetation["hedges"]) >= 1
    assert (provenance["trees"], provenance["hedges"]) == (len(layout.trees), len(layout.hedges))
    assert provenance["forest_trees"] == len(vegetation["forest_stands"][0]["tree_instances"])


def test_every_vegetation_face_is_tree_of_its_own_object(world):
    """Trunks, branches, leaves, whorls and hedges are all class tree (as Cityscapes files trunks under
    vegetation); tree j is object B + 1 + j, hedge k object B + T + 1 + k, each within its own reach; and the tree
    faces are exactly those of these objects."""
    _, scene, meta, layout = world
    first = len(layout.buildings) + 1
    trees, hedges = meta["vegetation"]["trees"], meta["vegetation"]["hedges"]
    assert [t["instance"] for t in trees] == list(range(first, first + len(trees)))
    assert [h["instance"] for h in hedges] == list(range(first + len(trees), first + len(trees) + len(hedges)))
    face_class, face_instance = scene.labels.face_class, scene.labels.face_instance
    vegetation = (face_instance >= first) & (face_instance < first + len(trees) + len(hedges))
    np.testing.assert_array_equal(face_class == TREE, vegetation)  # the built objects follow, none a tree
    for truth, tree in zip(trees, layout.trees, strict=True):
        points = scene.vertices[scene.faces[_own_faces(scene, truth["instance"])]].reshape(-1, 3)
        assert len(points)
        assert np.all(np.hypot(*(points[:, :2] - tree.position).T) <= tree.radius_m + 1e-4)
        height = points[:, 2] - tree.ground_z
        assert np.all((height >= -SINK_M - 1e-4) & (height <= tree.height_m + 1e-4))
    for truth, hedge in zip(hedges, layout.hedges, strict=True):
        points = scene.vertices[scene.faces[_own_faces(scene, truth["instance"])]].reshape(-1, 3)
        along = hedge.end - hedge.start
        t = (points[:, :2] - hedge.start) @ along / (along @ along)
        rel = points[:, :2] - hedge.start
        across = np.abs(along[0] * rel[:, 1] - along[1] * rel[:, 0]) / np.linalg.norm(along)
        assert np.all((t >= -0.05) & (t <= 1.05)) and np.all(across <= hedge.width_m / 2 + 0.3)
        ground = layout.terrain.height(points[:, 0], points[:, 1])
        assert np.all((points[:, 2] >= ground - 0.3) & (points[:, 2] <= ground + hedge.height_m + 0.3))


def test_per_tree_truth_matches_the_built_geometry(world):
    """scene.json's top height is the highest point of the object's faces above its stem's ground; conifers reach
    exactly their layout height, broadleaf crowns at most theirs; the crown footprint is the hull of the object's
    faces seen from above."""
    _, scene, meta, layout = world
    for truth, tree in zip(meta["vegetation"]["trees"], layout.trees, strict=True):
        points = scene.vertices[scene.faces[_own_faces(scene, truth["instance"])]].reshape(-1, 3)
        assert truth["kind"] == ("conifer" if tree.conifer else "broadleaf") and truth["forest"] == tree.forest
        np.testing.assert_allclose(truth["position_m"], tree.position, atol=1e-3)
        assert abs(truth["ground_z_m"] - float(layout.terrain.height(*tree.position))) < 1e-3
        assert abs(points[:, 2].max() - truth["ground_z_m"] - truth["top_height_m"]) < 1e-3
        assert truth["top_height_m"] <= tree.height_m + 1e-3
        if tree.conifer:
            assert abs(truth["top_height_m"] - tree.height_m) < 1e-3
        else:
            assert truth["top_height_m"] > 0.85 * tree.height_m
        assert truth["crown_radius_m"] == pytest.approx(tree.radius_m, abs=1e-4)
        hull = np.array(truth["crown_footprint_m"])
        edges = np.roll(hull, -1, axis=0) - hull
        edges /= np.linalg.norm(edges, axis=1, keepdims=True)
        rel = points[:, None, :2] - hull[None]
        inside = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]  # metres left of each ccw edge
        assert np.all(inside >= -0.008)  # the hull of the points rounded to the centimetre
        assert np.hypot(*(hull - tree.position).T).max() > 0.8 * tree.radius_m


def test_a_trunk_stands_under_each_broadleaf_crown(world):
    """A level sight line 0.5 m above the ground, from 1 m beside the stem towards it, meets bark of this very tree
    about a trunk's radius before the stem, from each of four sides."""
    _, scene, meta, layout = world
    sides = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    for truth, tree in zip(meta["vegetation"]["trees"], layout.trees, strict=True):
        if tree.conifer:
            continue
        origins = np.column_stack([tree.position + sides, np.full(4, tree.ground_z + 0.5)])
        instance, face = _first_hits(scene, origins, np.column_stack([-sides, np.zeros(4)]))
        np.testing.assert_array_equal(instance, truth["instance"])
        assert set(_patch_of_faces(scene, face)) == {"bark"}


def _down_sight_lines(truth):
    """Straight-down rays (origins, directions) on a SIGHT_STEP_M grid over a tree's crown disc."""
    radius = truth["crown_radius_m"]
    steps = np.arange(-radius, radius + 1e-9, SIGHT_STEP_M)
    xy = np.stack(np.meshgrid(steps, steps), -1).reshape(-1, 2)
    xy = xy[np.hypot(*xy.T) <= radius] + truth["position_m"]
    origins = np.column_stack([xy, np.full(len(xy), truth["ground_z_m"] + truth["top_height_m"] + 5.0)])
    return origins, np.tile([0.0, 0.0, -1.0], (len(xy), 1))


def test_broadleaf_crowns_are_porous_from_above(world):
    """Over each broadleaf crown's disc, the share of straight-down sight lines that pass the tree (its gap
    fraction; through neighbours' crowns in the forest) is the stated one: the sprays are kept until
    BROADLEAF_GAP_FRACTION of a 2 cm grid is open, and a cell touched by a spray counts as covered there, so the rays
    find up to ~0.03 more. Where no neighbour overhangs, the gaps open onto the ground, and some branches show from
    above."""
    _, scene, meta, _ = world
    gaps, ground_seen, bark_seen = [], [], 0
    for truth in meta["vegetation"]["trees"]:
        if truth["kind"] != "broadleaf":
            continue
        sight_lines = _down_sight_lines(truth)
        gaps.append(1.0 - _sees_object(scene, *sight_lines, truth["instance"]).mean())
        instance, face = _first_hits(scene, *sight_lines)
        own = instance == truth["instance"]
        if not truth["forest"]:
            ground_seen.append(np.isin(scene.labels.face_class[face[~own]], (GROUND, ROAD, FIELD)).mean())
        bark_seen += np.count_nonzero(_patch_of_faces(scene, face[own]) == "bark")
    gaps = np.array(gaps)
    assert BROADLEAF_GAP_FRACTION - 0.01 <= gaps.mean() <= BROADLEAF_GAP_FRACTION + 0.04, gaps.mean()
    assert np.all((gaps > BROADLEAF_GAP_FRACTION - 0.03) & (gaps < BROADLEAF_GAP_FRACTION + 0.07)), gaps
    assert np.median(ground_seen) > 0.8  # the others open onto a neighbour's crown
    assert bark_seen > 0


def test_conifer_whorls_have_gaps_where_the_trunk_shows(world):
    """A conifer's needle faces span whorls separated by open height bands; a level sight line at the middle of
    each band, from just outside the crown towards the stem, meets the trunk (bark of this tree) whenever no other
    object stands in the way; at a whorl's rim height it meets needles."""
    _, scene, meta, layout = world
    directions = np.array([[np.cos(a), np.sin(a)] for a in np.radians(np.arange(0, 360, 45))])
    for truth, tree in zip(meta["vegetation"]["trees"], layout.trees, strict=True):
        if not tree.conifer:
            continue
        faces = _own_faces(scene, truth["instance"])
        needles = faces[_patch_of_faces(scene, faces) == "needles"]
        z = scene.vertices[scene.faces[needles]][..., 2]
        spans = np.array(sorted(zip(z.min(axis=1), z.max(axis=1))))
        reach = np.maximum.accumulate(spans[:, 1])
        gap_low, gap_high = reach[:-1], spans[1:, 0]
        bands = [(low + high) / 2 for low, high in zip(gap_low, gap_high) if high - low > 0.15]
        assert len(bands) >= 3, (truth["instance"], len(bands))
        seen_trunk = 0
        for height in bands:
            origins = np.column_stack([tree.position + (tree.radius_m + 0.05) * directions, np.full(8, height)])
            instance, face = _first_hits(scene, origins, np.column_stack([-directions, np.zeros(8)]))
            mine = instance == truth["instance"]
            assert set(_patch_of_faces(scene, face[mine])) <= {"bark"}
            seen_trunk += np.count_nonzero(mine)
        assert seen_trunk >= len(bands)  # mostly not blocked by neighbours
        rim = spans[np.argmax(spans[:, 1] - spans[:, 0]), 0] + 0.02
        origins = np.column_stack([tree.position + (tree.radius_m + 0.05) * directions, np.full(8, rim)])
        instance, face = _first_hits(scene, origins, np.column_stack([-directions, np.zeros(8)]))
        assert "needles" in set(_patch_of_faces(scene, face[instance == truth["instance"]]))


def test_leaves_needles_and_bark_come_from_their_patches(world):
    """No vegetation face samples the orthophoto: broadleaf trees are leaves and bark, conifers needles and bark,
    hedges leaves only."""
    _, scene, meta, _ = world
    expected = {"broadleaf": {"leaves", "bark"}, "conifer": {"needles", "bark"}}
    for truth in meta["vegetation"]["trees"]:
        assert set(_patch_of_faces(scene, _own_faces(scene, truth["instance"]))) == expected[truth["kind"]]
    for truth in meta["vegetation"]["hedges"]:
        assert set(_patch_of_faces(scene, _own_faces(scene, truth["instance"]))) == {"leaves"}


def test_the_forest_stand_has_a_clear_edge(world):
    """Seen from above, the stand's inside (3 m in from its edge) is mostly canopy of its own trees, and a band 1-4 m
    outside its edge has no tree at all."""
    _, scene, meta, layout = world
    stand = layout.forests[0]
    truth = meta["vegetation"]["forest_stands"][0]
    np.testing.assert_allclose(truth["corners_m"], stand.corners, atol=1e-3)
    low, high = stand.corners.min(axis=0) - 5.0, stand.corners.max(axis=0) + 5.0
    xy = np.stack(np.meshgrid(*[np.arange(a, b, 0.25) for a, b in zip(low, high, strict=True)]), -1).reshape(-1, 2)
    origins = np.column_stack([xy, np.full(len(xy), 60.0)])
    instance, _ = _first_hits(scene, origins, np.tile([0.0, 0.0, -1.0], (len(xy), 1)))
    inner = stand.covers(xy, -3.0)
    band = stand.covers(xy, 4.0) & ~stand.covers(xy, 1.0)
    assert np.isin(instance[inner], truth["tree_instances"]).mean() > 0.6
    first_tree = len(layout.buildings) + 1
    assert not np.any(instance[band] >= first_tree)


def test_hedges_are_dense_but_porous_from_above(world):
    """Over each hedge's footprint, straight-down sight lines pass it at about the stated gap fraction (plus what
    the 2 cm grid's touched cells hide, up to ~0.05 for its small sprays), and they reach the ground there."""
    _, scene, meta, layout = world
    for truth, hedge in zip(meta["vegetation"]["hedges"], layout.hedges, strict=True):
        length = float(np.linalg.norm(hedge.end - hedge.start))
        along, across = (hedge.end - hedge.start) / length, np.array([hedge.start[1] - hedge.end[1],
                                                                       hedge.end[0] - hedge.start[0]]) / length
        s, c = np.meshgrid(np.arange(0.05, length, 0.1), np.arange(-hedge.width_m / 2 + 0.05, hedge.width_m / 2, 0.1))
        xy = hedge.start + s.reshape(-1, 1) * along + c.reshape(-1, 1) * across
        origins = np.column_stack([xy, np.full(len(xy), truth["top_z_m"] + 5.0)])
        directions = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
        gap = 1.0 - _sees_object(scene, origins, directions, truth["instance"]).mean()
        assert HEDGE_GAP_FRACTION <= gap <= HEDGE_GAP_FRACTION + 0.05, gap
        # its sprays reach up to 0.3 m out of its box (sim/worlds/vegetation.py's hedge_part)
        assert truth["top_z_m"] <= float(layout.terrain.height(*xy.T).max()) + hedge.height_m + 0.3


@pytest.mark.slow
def test_default_world_vegetation_budget_and_gaps():
    """The default world: under 1.5 M triangles with its ~500 standalone trees, a forest stand of 60+ trees and
    10 hedges, and its broadleaf crowns at the stated gap fraction (a sample of 40)."""
    folder = demo.demo_scene_dir("default", 0)
    meta = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    assert meta["provenance"]["triangles"] < 1_500_000
    assert meta["provenance"]["forest_trees"] >= 60 and meta["provenance"]["hedges"] == 10
    scene = load_scene(folder)
    broadleaf = [t for t in meta["vegetation"]["trees"] if t["kind"] == "broadleaf"][::5][:40]
    gaps = [1.0 - _sees_object(scene, *_down_sight_lines(t), t["instance"]).mean() for t in broadleaf]
    assert BROADLEAF_GAP_FRACTION - 0.01 <= np.mean(gaps) <= BROADLEAF_GAP_FRACTION + 0.04
