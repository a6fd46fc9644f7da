"""recon.measure.water against a pond of known shape: flat ground 0.5 m under a square of water (x and y -4..4 m, its
level at z = 0.5 m) with a tree's crown over its east end (x 2..4 m), labelled by object; twins with the water lower,
without it, or moved by a known similarity.

The grid's cells are 0.25 m, their centres a quarter cell off the water's edges: the water seen from above is
x -4..2 by y -4..4, 24 x 32 cells, of which the 0.5 m shore band leaves 20 x 28 = 560.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from recon.measure.oblique import TwinFrame
from recon.measure.water import LEVEL_TOLERANCE_M, read_true_ponds, score_ponds
from sim.render.classes import GROUND, TREE, WATER
from sim.render.labels import SceneLabels
from sim.render.scene import Scene, Surface
from sim.worlds.synthetic import grid_mesh
from tests.recon.test_oblique import similarity

LEVEL_Z = 0.5
POND, CROWN = 7, 8
SHORE = [[-4.0, -4.0], [4.0, -4.0], [4.0, 4.0], [-4.0, 4.0]]
POND_RECORD = {"instance": POND, "kind": "pond", "classes": ["water"], "level_z_m": LEVEL_Z, "shoreline_m": SHORE}
SEEN_CELLS = 20 * 28
FLOAT32_M = 1e-5
"""Heights come from float32 ray hits: their last bits differ between CPUs (5e-7 m seen on one, 0 on another)."""


def pond_world(water_z: float | None = LEVEL_Z, similarity_matrix: np.ndarray | None = None) -> Scene:
    """The ground (z = 0), the water at ``water_z`` (None: none) and the crown (z 3..5 over x 2..4), labelled; moved
    by ``similarity_matrix`` (scene = S @ world) when given."""
    vertices, faces, _ = grid_mesh(20, 20, (-10.0, 10.0, -10.0, 10.0))
    parts = [(vertices, faces, GROUND, 0)]
    if water_z is not None:
        water = np.array([[-4.0, -4.0, water_z], [4.0, -4.0, water_z], [4.0, 4.0, water_z], [-4.0, 4.0, water_z]])
        parts.append((water, np.array([[0, 1, 2], [0, 2, 3]]), WATER, POND))
    crown = trimesh.creation.box(bounds=[[2.0, -4.0, 3.0], [4.0, 4.0, 5.0]])
    parts.append((np.array(crown.vertices), np.array(crown.faces), TREE, CROWN))
    offsets = np.cumsum([0] + [len(v) for v, *_ in parts])
    vertices = np.vstack([v for v, *_ in parts])
    faces = np.vstack([f + offset for (_, f, *_), offset in zip(parts, offsets)])
    classes = np.concatenate([np.full(len(f), c, np.uint8) for _, f, c, _ in parts])
    instance = np.concatenate([np.full(len(f), i, np.uint32) for _, f, _, i in parts])
    if similarity_matrix is not None:
        vertices = vertices @ similarity_matrix[:3, :3].T + similarity_matrix[:3, 3]
    return Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 90, np.uint8)),
                 labels=SceneLabels(classes, instance, np.ones(len(faces))))


def score(twin: Scene, frame: TwinFrame | None = None):
    [result] = score_ponds(pond_world(), twin, frame, read_true_ponds({"objects": [POND_RECORD]}, "scene.json"))
    return result


def test_the_truth_is_at_its_level_over_the_water_seen_from_above():
    result = score(pond_world())
    assert result.cells == SEEN_CELLS  # the crown hides the east end, the shore band is left out
    assert (result.covered, result.at_level) == (1.0, 1.0)
    assert result.median_error_m == pytest.approx(0.0, abs=FLOAT32_M)


@pytest.mark.parametrize("water_z, expected_error", [(LEVEL_Z - 0.3, -0.3), (LEVEL_Z + 0.15, 0.15)])
def test_water_off_its_level_counts_by_the_tolerance(water_z, expected_error):
    result = score(pond_world(water_z))
    assert result.cells == SEEN_CELLS and result.covered == 1.0
    assert result.median_error_m == pytest.approx(expected_error, abs=FLOAT32_M)
    assert result.at_level == float(abs(expected_error) <= LEVEL_TOLERANCE_M)


def test_a_twin_without_the_water_shows_its_bed_off_the_level():
    result = score(pond_world(None))
    assert result.covered == 1.0 and result.at_level == 0.0 and result.median_error_m == pytest.approx(-LEVEL_Z, abs=FLOAT32_M)


def test_a_twin_in_its_own_frame_gives_the_same_answers():
    S_twin_world = similarity(1.3, [2.0, -3.0, 40.0], [5.0, -2.0, 7.0])
    frame = TwinFrame(np.linalg.inv(S_twin_world))
    exact = score(pond_world(similarity_matrix=S_twin_world), frame)
    assert exact.cells == SEEN_CELLS and exact.at_level == 1.0 and abs(exact.median_error_m) < 1e-6
    low = score(pond_world(LEVEL_Z - 0.3, S_twin_world), frame)
    assert low.at_level == 0.0 and low.median_error_m == pytest.approx(-0.3, abs=1e-6)


def test_a_hole_in_the_twin_counts_as_off():
    """A twin of the water alone with no surface over y 1.5..3.5 m: 8 of the 28 rows of seen cells are holes."""
    quads = [[[-4.0, y0, LEVEL_Z], [4.0, y0, LEVEL_Z], [4.0, y1, LEVEL_Z], [-4.0, y1, LEVEL_Z]]
             for y0, y1 in ((-4.0, 1.5), (3.5, 4.0))]
    vertices = np.array(quads).reshape(-1, 3)
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    result = score(Scene(vertices, faces, Surface(vertex_colors=np.full((8, 3), 90, np.uint8))))
    assert result.cells == SEEN_CELLS
    assert result.covered == result.at_level == pytest.approx(20 * 20 / SEEN_CELLS)
    assert result.median_error_m == pytest.approx(0.0, abs=FLOAT32_M)


def test_ponds_are_read_from_the_objects_and_a_broken_entry_is_named():
    meta = {"objects": [{"instance": 3, "kind": "car"}, POND_RECORD]}
    [pond] = read_true_ponds(meta, "w/scene.json")
    assert pond.instance == POND and pond.level_z == LEVEL_Z and pond.shoreline.shape == (4, 2)
    assert read_true_ponds({}, "w/scene.json") == []
    broken = {k: v for k, v in POND_RECORD.items() if k != "level_z_m"}
    with pytest.raises(ValueError, match=r"w/scene\.json: objects: a pond without a usable 'level_z_m'"):
        read_true_ponds({"objects": [broken]}, "w/scene.json")
