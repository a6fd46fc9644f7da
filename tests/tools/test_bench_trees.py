"""tools/bench/bench_trees.py end to end: a two-tree forest world (tests/recon/test_trees.py) written as a labelled
scene folder, and twins of it in their own frames (tests/recon/test_oblique.py's moved twin), one with tree A's crown
moved 1 m east."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from PIL import Image

from recon.surface.observed import inside
from sim.render.classes import GROUND, TREE, WATER
from sim.render.labels import FORMAT as LABELS_FORMAT, LABELS_FILE, SceneLabels, write_labels
from sim.render.scene import read_scene_json, read_scene_mesh_enu
from sim.render.sky_file import mesh_sha256
from sim.worlds.synthetic import noise_texture
from tests.recon.test_oblique import orbit_truth, similarity, write_moved_twin
from tests.recon.test_trees import GROUND_Z, forest, tree_records
from tests.sim.render_scene_helpers import ORIGIN, write_scene
from tools.bench.bench_trees import main

OUTSIDE_TREE = {**tree_records()[0], "instance": 3, "position_m": [45.0, 0.0]}
"""A tree listed beyond the 30 m orbit's observed area: never scored."""
POND = {"instance": 9, "kind": "pond", "classes": ["water"], "level_z_m": GROUND_Z,
        "shoreline_m": [[-8.0, -4.0], [-4.0, -4.0], [-4.0, 4.0], [-8.0, 4.0]]}
"""A pond: the ground's faces inside its shoreline, labelled water, at the ground's height (16 x 32 cells seen, 12 x
28 inside the 0.5 m shore band)."""


def write_forest(folder, **tree_a) -> None:
    """The forest (``tree_a``: how tree A is made) as a textured scene folder without labels."""
    scene = forest(**tree_a)
    visual = trimesh.visual.TextureVisuals(uv=scene.vertices[:, :2] / 40.0, image=Image.fromarray(noise_texture(64, 1)))
    folder.mkdir()
    trimesh.Trimesh(scene.vertices, scene.faces, visual=visual, process=False).export(folder / "terrain.obj")
    meta = {"format": "aerostereo-scene/1", "mesh": "terrain.obj", "origin": ORIGIN.to_dict(), "units": "m",
            "up_axis": "z", "frame": "enu", "vertex_offset_m": [0.0, 0.0, 0.0]}
    (folder / "scene.json").write_text(json.dumps(meta))


def label_forest(folder) -> None:
    """Label the forest's faces by where they lie (above the ground: tree A west of x = 2.5 m, B east of it) and list
    its trees (and one outside the flight) in scene.json."""
    meta = read_scene_json(folder)
    vertices, faces, _ = read_scene_mesh_enu(folder, meta)
    centre = vertices[faces].mean(axis=1)
    instance = np.where(centre[:, 2] > GROUND_Z + 1e-6, np.where(centre[:, 0] < 2.5, 1, 2), 0).astype(np.uint32)
    classes = np.where(instance > 0, TREE, GROUND).astype(np.uint8)
    in_pond = (instance == 0) & inside(np.array(POND["shoreline_m"]), centre)
    instance[in_pond], classes[in_pond] = POND["instance"], WATER
    labels = SceneLabels(classes, instance, np.ones(len(faces)))
    write_labels(folder / LABELS_FILE, labels, mesh_sha256(vertices, faces))
    stored = json.loads((folder / "scene.json").read_text())
    stored.update(labels={"file": LABELS_FILE, "format": LABELS_FORMAT, "method": "test geometry"},
                  vegetation={"trees": tree_records() + [OUTSIDE_TREE]}, objects=[POND])
    (folder / "scene.json").write_text(json.dumps(stored))


@pytest.fixture()
def flight(tmp_path):
    """(world folder, truth.json, twin folder, twin with A's crown moved): twins scaled 1.1 and turned 20 deg."""
    truth = orbit_truth()
    (tmp_path / "truth.json").write_text(json.dumps(truth))
    S_twin_world = similarity(1.1, [0.0, 0.0, 20.0], [3.0, 1.0, -2.0])
    write_forest(tmp_path / "world")
    write_forest(tmp_path / "moved", shift_m=(1.0, 0.0))
    write_moved_twin(tmp_path / "world", tmp_path / "twin", S_twin_world, truth)
    write_moved_twin(tmp_path / "moved", tmp_path / "twin_moved", S_twin_world, truth)
    label_forest(tmp_path / "world")
    return tmp_path / "world", tmp_path / "truth.json", tmp_path / "twin", tmp_path / "twin_moved"


def test_each_twins_trees_against_the_truth(flight, tmp_path, capsys):
    world, truth, twin, moved = flight
    out = tmp_path / "trees.json"
    assert main(["--world", str(world), "--truth", str(truth), "--scene", f"copy={twin}",
                 "--scene", f"moved={moved}", "--json", str(out)]) == 0
    out_lines = capsys.readouterr().out.splitlines()
    rows = [line.split(" | ") for line in out_lines if line.startswith("| copy |") and "| 9 |" not in line]
    assert [row[1:6] for row in rows] == [["all", "2", "0.00", "100.0 %", "1.000"],
                                          ["broadleaf", "1", "0.00", "100.0 %", "1.000"],
                                          ["conifer", "1", "0.00", "100.0 %", "1.000"],
                                          ["forest", "1", "0.00", "100.0 %", "1.000"],
                                          ["park", "1", "0.00", "100.0 %", "1.000"]]
    ponds = [line.split(" | ") for line in out_lines if line.startswith("| copy | 9 |")]
    assert [row[2:6] for row in ponds] == [["336", "100.0 %", "100.0 %", "+0.000 |"]]
    report = json.loads(out.read_text())
    moved_trees = {tree["instance"]: tree for tree in report["scenes"]["moved"]["trees"]}
    assert sorted(moved_trees) == [1, 2]  # the tree outside the flight is left out
    assert moved_trees[1]["iou"] == pytest.approx(0.6) and moved_trees[2]["iou"] == pytest.approx(8 / 11)
    assert report["scenes"]["moved"]["summary"]["all"]["median_iou"] == pytest.approx((0.6 + 8 / 11) / 2)
    assert report["scenes"]["moved"]["alignment"]["scale"] == pytest.approx(1 / 1.1)


def test_a_world_without_trees_exits_2_naming_its_scene_json(flight, tmp_path, capsys):
    _, truth, twin, _ = flight
    bare = write_scene(tmp_path / "bare")
    assert main(["--world", str(bare), "--truth", str(truth), "--scene", f"copy={twin}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"bench_trees: error: {bare / 'scene.json'}: no \"vegetation\"")


def test_a_flight_over_another_world_exits_2_naming_both(flight, tmp_path, capsys):
    world, truth, twin, _ = flight
    other = tmp_path / "other_truth.json"
    other.write_text(json.dumps({**json.loads(truth.read_text()), "scene": "/cache/worlds/small-0-v10/world.glb"}))
    assert main(["--world", str(world), "--truth", str(other), "--scene", f"copy={twin}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"bench_trees: error: {other}: the flight flew over /cache/worlds/small-0-v10/world.glb, "
                       f"not over the --world {world}")
    same = tmp_path / "same_truth.json"  # the world's own folder, wherever it was when it was flown
    same.write_text(json.dumps({**json.loads(truth.read_text()), "scene": f"/elsewhere/{world.name}/world.glb"}))
    assert main(["--world", str(world), "--truth", str(same), "--scene", f"copy={twin}"]) == 0


def test_a_truth_that_is_not_json_exits_2_naming_it(flight, tmp_path, capsys):
    world, _, twin, _ = flight
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    assert main(["--world", str(world), "--truth", str(broken), "--scene", f"copy={twin}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"bench_trees: error: {broken}: not UTF-8 JSON")


def test_the_json_may_not_overwrite_an_input(flight, capsys):
    world, truth, twin, _ = flight
    with pytest.raises(SystemExit) as stop:
        main(["--world", str(world), "--truth", str(truth), "--scene", f"copy={twin}", "--json", str(truth)])
    assert stop.value.code == 2 and f"argument --json: {truth} is an input" in capsys.readouterr().err
