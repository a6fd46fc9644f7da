"""tools/bench/bench_twin_oblique.py end to end on a twin that is the true world moved by a known similarity."""

from __future__ import annotations

import json

import pytest

from tests.recon.test_oblique import orbit_truth, similarity, write_moved_twin
from tests.sim.render_scene_helpers import BOX_INSTANCE, label_box_scene, write_scene
from tools.bench.bench_twin_oblique import main


@pytest.fixture()
def flight(tmp_path):
    """(world folder, truth.json, twin folder)."""
    world = write_scene(tmp_path / "world")
    truth = orbit_truth()
    (tmp_path / "truth.json").write_text(json.dumps(truth))
    write_moved_twin(world, tmp_path / "twin", similarity(1.1, [0.0, 0.0, -20.0], [3.0, 1.0, -2.0]), truth)
    return world, tmp_path / "truth.json", tmp_path / "twin"


def test_a_moved_copy_of_the_world_scores_full_coverage_and_no_error(flight, tmp_path, capsys):
    world, truth, twin = flight
    code = main(["--world", str(world), "--truth", str(truth), "--scene", f"copy={twin}", "--views", "2",
                 "--size", "96", "72", "--json", str(tmp_path / "out.json"), "--pictures", str(tmp_path / "pics"),
                 "--capture-sun", "150,50,10"])
    assert code == 0
    captured = capsys.readouterr()
    assert "the true world has no face labels: no per-class or per-object tables" in captured.err
    row = [line for line in captured.out.splitlines() if line.startswith("| copy |")]
    assert len(row) == 2 and "| 100.0 % |" in row[0]  # the scores, then the light
    report = json.loads((tmp_path / "out.json").read_text())
    summary = report["scenes"]["copy"]["summary"]
    assert summary["views"] == 2 and summary["coverage"] > 0.999
    assert summary["error_in_area"] < 0.1 and summary["depth_abs_rel"] < 1e-5
    assert report["scenes"]["copy"]["alignment"]["scale"] == pytest.approx(1 / 1.1)
    # a copy of the world carries no capture light: where both suns light it, it is the truth
    assert summary["light"]["error_lit"] < 0.1
    assert sorted(p.name for p in (tmp_path / "pics").iterdir()) == ["view000_copy.png", "view001_copy.png"]


def test_a_bad_object_entry_in_the_world_exits_2_naming_it(flight, capsys):
    world, truth, twin = flight
    meta = json.loads((world / "scene.json").read_text())
    meta["objects"] = [{"instance": 3, "kind": "car"}, {"kind": "car"}]
    (world / "scene.json").write_text(json.dumps(meta))
    assert main(["--world", str(world), "--truth", str(truth), "--scene", f"copy={twin}"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"bench_twin_oblique: ValueError: {world / 'scene.json'}: objects[1]: expected an integer "
                   "'instance' and a string 'kind'")


def test_a_missing_scene_folder_exits_2_naming_it(flight, tmp_path, capsys):
    world, truth, _ = flight
    assert main(["--world", str(world), "--truth", str(truth), "--scene", f"x={tmp_path / 'nowhere'}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nowhere" in err


@pytest.mark.parametrize("extra, message", [
    (["--scene", "twin"], "argument --scene: expected LABEL=DIR, got 'twin'"),
    (["--scene", "a=x", "--scene", "a=y"], "argument --scene: labels must differ"),
    (["--scene", "a=x", "--fov", "190"], "argument --fov: horizontal field of view must be in (0, 180) degrees"),
    (["--scene", "a=x", "--views", "0"], "argument --views: must be a positive integer, got 0"),
])
def test_bad_options_exit_2_naming_the_argument(capsys, extra, message):
    with pytest.raises(SystemExit) as stop:
        main(["--truth", "truth.json", *extra])
    assert stop.value.code == 2 and message in capsys.readouterr().err


def test_a_labelled_world_gets_the_per_class_and_per_object_tables(flight, tmp_path, capsys):
    world, truth, twin = flight
    label_box_scene(world)  # ground, roof, walls; the box (instance BOX_INSTANCE) called a car in scene.json
    meta = json.loads((world / "scene.json").read_text())
    meta["objects"] = [{"instance": BOX_INSTANCE, "kind": "car"}, {"instance": 99, "kind": "dormer"}]
    (world / "scene.json").write_text(json.dumps(meta))
    assert main(["--world", str(world), "--truth", str(truth), "--scene", f"copy={twin}", "--views", "2",
                 "--size", "96", "72", "--seed", "3", "--json", str(tmp_path / "out.json"),
                 "--capture-sun", "150,50,10"]) == 0  # seed 3: both views see roof and walls
    out = capsys.readouterr().out.splitlines()
    for name in ("group | ground", "group | building", "class | roof", "class | wall"):
        row = next(line for line in out if line.startswith(f"| copy | {name} |"))
        assert "| 100.0 % | 0.000 | 0.000 | 0.0 % | 0.0 % |" in row  # coverage, abs rel median and mean, off
    assert "| copy | group | vegetation | 0.00 % | - | nan | nan | - | - | nan |" in out
    per_class = json.loads((tmp_path / "out.json").read_text())["scenes"]["copy"]["per_class"]
    car = per_class["objects"]["kinds"]["car"]
    assert [line for line in out if line.startswith("| copy | car |")] == [
        f"| copy | car | 1 | 1 | 1 | 100.0 % | 1 | {car['pixels']} | 100.0 % |"]  # in area, seen, recovered...
    assert car["pixels"] == per_class["groups"]["building"]["pixels"] > 0  # the box is both
    assert per_class["classes"]["ground"]["share"] + per_class["groups"]["building"]["share"] == pytest.approx(1.0)
