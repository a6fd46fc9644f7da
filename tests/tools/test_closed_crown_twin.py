"""tools/bench/closed_crown_twin.py: the two-tree forest of tests/tools/test_bench_trees.py, tree A's crown porous
(three 0.25 m gaps across it), closed into its hull and scored by bench_trees with the identity as its alignment."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sim.render.raycast import from_above
from sim.render.scene import load_scene
from tests.recon.test_oblique import orbit_truth
from tests.recon.test_trees import CROWNS, GROUND_Z
from tests.tools.test_bench_trees import label_forest, write_forest
from tools.bench.bench_trees import main as bench_trees
from tools.bench.closed_crown_twin import main

CAMERA = {"width": 320, "height": 240, "fx": 250.0, "fy": 250.0, "cx": 159.5, "cy": 119.5,
          "distortion": [0.0] * 5}


@pytest.fixture()
def porous_world(tmp_path):
    """(world folder, truth.json): the forest with tree A's crown porous, labelled, and a 12-photo orbit."""
    (tmp_path / "truth.json").write_text(json.dumps({**orbit_truth(), "camera": CAMERA}))
    write_forest(tmp_path / "world", porous=True)
    label_forest(tmp_path / "world")
    return tmp_path / "world", tmp_path / "truth.json"


def test_a_porous_crown_is_closed_into_its_hull_and_scored_as_the_ceiling(porous_world, tmp_path, capsys):
    world, truth = porous_world
    out = tmp_path / "closed"
    assert main(["--world", str(world), "--truth", str(truth), "--out", str(out)]) == 0
    assert json.loads(capsys.readouterr().out) == {"scene": str(out), "trees_closed": 2}
    closed = load_scene(out)
    (x0, x1, y0, y1), (bottom, top) = CROWNS[1]
    gaps = np.array([[-1.125, 0.0], [-0.75, 0.0], [1.125, 0.0]])  # the middle of each gap between A's slabs
    heights, _ = from_above(closed, gaps)
    np.testing.assert_allclose(heights, GROUND_Z + top, atol=1e-4)  # the gaps are roofed at the crown's top
    heights, _ = from_above(closed, np.array([[-5.0, 5.0], [12.0, -8.0], [0.0, 1.45]]))
    np.testing.assert_allclose(heights, [GROUND_Z, GROUND_Z, GROUND_Z + top], atol=1e-4)  # ground; the crown's edge
    assert bench_trees(["--world", str(world), "--truth", str(truth), "--scene", f"closed={out}",
                        "--json", str(tmp_path / "trees.json")]) == 0
    trees = {t["instance"]: t for t in json.loads((tmp_path / "trees.json").read_text())["scenes"]["closed"]["trees"]}
    assert [trees[k]["top_error_m"] for k in (1, 2)] == pytest.approx([0.0, 0.0], abs=1e-3)
    assert trees[1]["iou"] == pytest.approx(13 / 16)  # A's three gap columns (of 16 across) count against it
    # B, a solid box, is its own hull; but A's gap at x 1-1.25 m (12 cells) lies within B's window (its footprint
    # grown by 2 m) over open ground and counts as B's extra: 128 agreeing cells of 140
    assert trees[2]["iou"] == pytest.approx(128 / 140)
    assert trees[1]["outline_iou"] > 0.95  # a forester's outline closes the gaps (all but their ends)


def test_an_existing_output_or_a_world_without_trees_exits_2(porous_world, tmp_path, capsys):
    world, truth = porous_world
    assert main(["--world", str(world), "--truth", str(truth), "--out", str(world)]) == 2
    assert capsys.readouterr().err.splitlines()[-1] == (f"closed_crown_twin: error: argument --out: {world} exists; "
                                                        f"give a new folder")
    bare = tmp_path / "bare"
    write_forest(bare)  # unlabelled, no trees listed
    assert main(["--world", str(bare), "--truth", str(truth), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"closed_crown_twin: error: {bare / 'scene.json'}: expected a labelled world listing its trees "
                   f"(vegetation.trees), like a demo world's")
    assert not (tmp_path / "out").exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    truth.write_text(json.dumps(orbit_truth()))  # no lens
    assert main(["--world", str(world), "--truth", str(truth), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip() == f"closed_crown_twin: error: {truth}: no field 'camera'"
