"""recon.measure.trees against a tiny forest of known shape: two trees on flat ground, each a cylinder trunk under a
box crown, labelled by object; twins made from it with a crown moved, flattened, or the whole twin moved by a known
similarity.

Tree A (object 1): crown x -2..2, y -1.5..1.5, 3..8 m above the ground (12 m2); tree B (object 2): crown x 3..7,
y -1..1, 2..6 m up (8 m2), so A's window (its crown grown by 2 m) holds part of B's crown. The crowns' edges lie on
whole metres and the cells' centres a quarter cell off them, so every area below is a whole number of cells.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from recon.measure.oblique import TwinFrame
from recon.measure.trees import (CELL_M, TreeScore, TrueTree, read_true_trees, score_trees, summarise_trees,
                                 tree_grid, trees_inside)
from recon.surface.observed import inside
from sim.render.classes import GROUND, TREE
from sim.render.labels import SceneLabels
from sim.render.raycast import from_above
from sim.render.scene import Scene, Surface
from sim.worlds.synthetic import grid_mesh

GROUND_Z = 5.0
CROWNS = {1: ((-2.0, 2.0, -1.5, 1.5), (3.0, 8.0)), 2: ((3.0, 7.0, -1.0, 1.0), (2.0, 6.0))}
"""Object -> crown box ((xmin, xmax, ymin, ymax), (bottom, top) above the ground), metres."""


POROUS_SLABS_X = ((-2.0, -1.25), (-1.0, -0.5), (-0.25, 1.0), (1.25, 2.0))
"""A porous crown A: its box cut into slabs across x, three 0.25 m gaps (one cell) the ground shows through."""


def tree_parts(instance: int, shift_m=(0.0, 0.0), flatten: bool = False,
               porous: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A tree's trunk (a cylinder from the ground to the crown's base at the crown's centre) and crown box, the crown
    moved by ``shift_m`` (east, north); ``flatten``: every height squashed onto the ground (its walls vanish);
    ``porous``: the crown made of :data:`POROUS_SLABS_X`."""
    (x0, x1, y0, y1), (bottom, top) = CROWNS[instance]
    trunk = trimesh.creation.cylinder(radius=0.2, height=bottom, sections=8)
    trunk.apply_translation([(x0 + x1) / 2, (y0 + y1) / 2, GROUND_Z + bottom / 2])
    dx, dy = shift_m
    slabs = POROUS_SLABS_X if porous else ((x0, x1),)
    crown = [trimesh.creation.box(bounds=[[a + dx, y0 + dy, GROUND_Z + bottom], [b + dx, y1 + dy, GROUND_Z + top]])
             for a, b in slabs]
    mesh = trimesh.util.concatenate([trunk, *crown])
    vertices = np.array(mesh.vertices)
    if flatten:
        vertices[:, 2] = GROUND_Z
    return vertices, np.array(mesh.faces)


def forest(similarity: np.ndarray | None = None, porous: bool = False, **tree_a) -> Scene:
    """Flat ground at GROUND_Z (x -10..15, y -10..10) with trees A (made with ``tree_a``) and B, labelled; moved by
    ``similarity`` (4x4, scene = S @ world) when given; ``porous``: A's crown porous (:data:`POROUS_SLABS_X`)."""
    vertices, faces, _ = grid_mesh(25, 20, (-10.0, 15.0, -10.0, 10.0))
    vertices[:, 2] = GROUND_Z
    parts, instance = [(vertices, faces)], [np.zeros(len(faces), np.uint32)]
    for tree in CROWNS:
        parts.append(tree_parts(tree, **({**tree_a, "porous": porous} if tree == 1 else {})))
        instance.append(np.full(len(parts[-1][1]), tree, np.uint32))
    offsets = np.cumsum([0] + [len(v) for v, _ in parts])
    vertices = np.vstack([v for v, _ in parts])
    faces = np.vstack([f + offset for (_, f), offset in zip(parts, offsets)])
    instance = np.concatenate(instance)
    if similarity is not None:
        vertices = vertices @ similarity[:3, :3].T + similarity[:3, 3]
    labels = SceneLabels(np.where(instance > 0, TREE, GROUND).astype(np.uint8), instance, np.ones(len(faces)))
    colours = np.full((len(vertices), 3), 120, np.uint8)
    return Scene(vertices, faces, Surface(vertex_colors=colours), labels=labels)


def tree_records() -> list[dict]:
    """The two trees as scene.json's vegetation lists them (footprints: the crown boxes)."""
    records = []
    for instance, ((x0, x1, y0, y1), (_, top)) in CROWNS.items():
        records.append({"instance": instance, "kind": "broadleaf" if instance == 1 else "conifer",
                        "forest": instance == 2, "position_m": [(x0 + x1) / 2, (y0 + y1) / 2],
                        "ground_z_m": GROUND_Z, "top_height_m": top, "crown_radius_m": 2.0,
                        "crown_footprint_m": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]})
    return records


def true_trees() -> list[TrueTree]:
    return read_true_trees({"vegetation": {"trees": tree_records()}}, "scene.json")


def scores_by_tree(twin: Scene, frame: TwinFrame | None = None, world: Scene | None = None) -> dict[int, TreeScore]:
    return {s.instance: s for s in score_trees(world or forest(), twin, frame, true_trees())}


def cells(area_m2: float) -> int:
    return round(area_m2 / CELL_M ** 2)


def test_a_twin_that_is_the_truth_has_every_crown_right():
    scores = scores_by_tree(forest())
    assert scores[1].iou == 1.0 and scores[2].iou == 1.0
    assert scores[1].outline_iou == 1.0 and scores[2].outline_iou == 1.0
    assert scores[1].top_error_m == pytest.approx(0.0, abs=1e-5) and scores[2].top_error_m == pytest.approx(0.0, abs=1e-5)
    assert scores[1].true_top_m == pytest.approx(8.0) and scores[2].true_top_m == pytest.approx(6.0)
    # B's crown in A's window is B's, not A's: A's crown is its own 12 m2 only
    assert (scores[1].true_cells, scores[1].twin_cells) == (cells(12.0), cells(12.0))
    assert (scores[2].true_cells, scores[2].twin_cells) == (cells(8.0), cells(8.0))


def test_the_true_crown_is_the_footprint_seen_from_above():
    """Cross-check: the cells whose first surface is the tree are those inside its footprint polygon."""
    world = forest()
    for tree in true_trees():
        window = tree_grid(tree)
        assert (window.rows, window.cols) == (int((np.ptp(tree.footprint[:, 1]) + 4) / CELL_M),
                                              int((np.ptp(tree.footprint[:, 0]) + 4) / CELL_M))
        _, hits = from_above(world, window.centres())
        seen = world.labels.face_instance[hits.tri] == tree.instance
        np.testing.assert_array_equal(seen, inside(tree.footprint, window.centres()))


def test_a_crown_moved_1_m_east_overlaps_as_the_rectangles_do():
    scores = scores_by_tree(forest(shift_m=(1.0, 0.0)))
    # A: crown x -1..3 against -2..2 (3 m high): overlap 9 m2, union 15 m2
    assert scores[1].iou == pytest.approx(9.0 / 15.0)
    assert scores[1].agreeing_cells == cells(9.0)
    assert scores[1].outline_iou == pytest.approx(9.0 / 15.0)  # a box's outline is the box
    assert scores[1].top_error_m == pytest.approx(0.0, abs=1e-5)
    # B: A's crown now stands over 1 m x 3 m of B's window where the truth shows ground
    assert scores[2].iou == pytest.approx(8.0 / 11.0)
    assert scores[2].top_error_m == pytest.approx(0.0, abs=1e-5)
    pooled = summarise_trees([scores[1], scores[2]])["all"]
    assert (pooled["agreeing_cells"], pooled["extra_cells"], pooled["missed_cells"]) == (cells(17.0), cells(6.0), cells(3.0))
    assert pooled["pooled_iou"] == pytest.approx(17.0 / 26.0)


def test_a_crown_flattened_to_the_ground_is_lost():
    scores = scores_by_tree(forest(flatten=True))
    assert scores[1].iou == 0.0 and scores[1].twin_cells == 0 and scores[1].outline_iou == 0.0
    assert scores[1].top_error_m == pytest.approx(-8.0, abs=1e-5) and scores[1].twin_top_m == pytest.approx(0.0, abs=1e-5)
    assert scores[2].iou == 1.0 and scores[2].top_error_m == pytest.approx(0.0, abs=1e-5)  # float32 ray hits


@pytest.mark.parametrize("scale, rotvec_deg", [(1.3, (0.0, 0.0, 30.0)), (0.7, (3.0, -2.0, 200.0))])
def test_a_twin_in_its_own_frame_scores_as_in_the_worlds(scale, rotvec_deg):
    S_twin_world = np.eye(4)
    S_twin_world[:3, :3] = scale * Rotation.from_rotvec(rotvec_deg, degrees=True).as_matrix()
    S_twin_world[:3, 3] = [120.0, -40.0, 7.0]
    frame = TwinFrame(np.linalg.inv(S_twin_world))
    for twin_args, expected in [({}, {1: 1.0, 2: 1.0}), ({"shift_m": (1.0, 0.0)}, {1: 0.6, 2: 8.0 / 11.0})]:
        scores = scores_by_tree(forest(S_twin_world, **twin_args), frame)
        for instance, iou in expected.items():
            assert scores[instance].iou == pytest.approx(iou)
            assert scores[instance].top_error_m == pytest.approx(0.0, abs=1e-4)
    flat = scores_by_tree(forest(S_twin_world, flatten=True), frame)
    assert flat[1].iou == 0.0 and flat[1].top_error_m == pytest.approx(-8.0, abs=1e-4)


def test_a_closed_twin_of_a_porous_crown_misses_its_gaps_but_not_its_outline():
    porous_world = forest(porous=True)
    scores = scores_by_tree(forest(), world=porous_world)
    assert scores[1].true_cells == cells(12.0 - 3 * 0.25 * 3.0) and scores[1].twin_cells == cells(12.0)
    assert scores[1].iou == pytest.approx(9.75 / 12.0)
    # the outline closes the gaps but for a notch of one cell where each meets the crown's rim (a closing's corners)
    assert scores[1].outline_iou == (cells(12.0) - 3 * 2) / cells(12.0)
    assert scores_by_tree(porous_world, world=porous_world)[1].iou == 1.0


def score(kind: str, forest_tree: bool, error: float, iou: float, true_cells: int = 10) -> TreeScore:
    return TreeScore(0, kind, forest_tree, 5.0, 5.0 + error, error, 5.0, true_cells, 10, round(iou * 10), iou, iou / 2)


def test_summaries_per_group():
    scores = [score("broadleaf", False, 0.1, 1.0), score("broadleaf", True, -0.6, 0.6),
              score("conifer", False, math.nan, 0.2), score("conifer", True, 0.4, 0.5, true_cells=0)]
    summary = summarise_trees(scores)
    assert summary["all"] == {"trees": 3, "hidden": 1, "median_abs_top_error_m": 0.6, "within_share": 1 / 3,
                              "median_iou": 0.6, "p10_iou": pytest.approx(0.28), "median_outline_iou": 0.3,
                              "p10_outline_iou": pytest.approx(0.14), "agreeing_cells": 18, "extra_cells": 12,
                              "missed_cells": 12, "pooled_iou": 18 / 42}
    assert summary["broadleaf"]["median_abs_top_error_m"] == pytest.approx(0.35)
    assert summary["broadleaf"]["within_share"] == 0.5
    assert summary["conifer"]["median_abs_top_error_m"] == math.inf  # no twin surface over its crown
    assert (summary["forest"]["trees"], summary["forest"]["hidden"]) == (1, 1)
    assert summary["park"]["median_iou"] == 0.6
    assert summarise_trees([]) == {}


def test_only_trees_standing_in_the_polygon_are_kept():
    trees = true_trees()
    assert [t.instance for t in trees_inside(trees, np.array([[3.0, -5.0], [9.0, -5.0], [9.0, 5.0], [3.0, 5.0]]))] == [2]
    assert trees_inside(trees, None) == trees


@pytest.mark.parametrize("meta, message", [
    ({}, 'scene.json: no "vegetation"'),
    ({"vegetation": {"trees": [{"instance": 1}]}}, "scene.json: vegetation.trees: an entry without a usable 'kind'"),
])
def test_a_world_without_usable_trees_is_refused(meta, message):
    with pytest.raises(ValueError, match=message):
        read_true_trees(meta, "scene.json")


def test_a_world_without_labels_is_refused():
    world = forest()
    world.labels = None
    with pytest.raises(ValueError, match="no face labels"):
        score_trees(world, forest(), None, true_trees())
