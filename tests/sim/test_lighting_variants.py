"""``--lighting-variants``: one pose set under several lights, each a complete dataset in OUT/NAME/ with identical poses,
times and depth and its own images; listed in OUT/lighting_variants.json; resumed variant by variant; the same bytes
with two workers; other variants, a dataset folder and a variants folder refused."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from sim.cli import main as cli_main
from sim.cli.light import lighting_variants_value
from sim.run.variants import VARIANTS_JSON

from dataset_helpers import dataset_bytes
from render_scene_helpers import write_scene

VARIANTS = "noon=45,60,8,morning=time:2026-06-21T04:00:00Z,flat=overcast,raw=unlit,paper=random"
NAMES = ("noon", "morning", "flat", "raw", "paper")


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory) -> Path:
    return write_scene(tmp_path_factory.mktemp("scene"))


def argv(scene_dir: Path, out: Path, *options: str) -> list[str]:
    return ["--scene", str(scene_dir), "--out", str(out), "--quiet", "--frames", "3", "--width", "40", "--height",
            "30", *options]


@pytest.fixture(scope="module")
def variants(scene_dir, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("variants") / "out"
    assert cli_main(argv(scene_dir, out, "--lighting-variants", VARIANTS)) == 0
    return out


def test_a_comma_followed_by_a_name_and_equals_starts_the_next_variant():
    parsed = lighting_variants_value("morning=time:2026-06-01T06:30:00Z,noon=45,60,8,flat=overcast")
    assert [(v.name, v.sun.text) for v in parsed] == [("morning", "time:2026-06-01T06:30:00Z"), ("noon", "45,60,8"),
                                                      ("flat", "overcast")]
    for bad, message in (("noon=45,60", "expected random, AZ,EL,STRENGTH"), ("noon", "expected NAME=SUN"),
                         ("a=random,A=unlit", "must differ .*A, a repeat"), ("../up=random", "variant name '../up'"),
                         (".hidden=random", "variant name"), ("a=random,,b=unlit", "got 'random,'")):
        with pytest.raises(argparse.ArgumentTypeError, match=message):
            lighting_variants_value(bad)


def test_every_variant_is_a_dataset_with_the_same_poses_times_and_depth_and_its_own_images(variants):
    listing = json.loads((variants / VARIANTS_JSON).read_text())
    assert [(v["name"], v["dataset"]) for v in listing["variants"]] == [(name, name) for name in NAMES]
    assert listing["variants"][1]["sun"] == "time:2026-06-21T04:00:00Z"
    files = {name: dataset_bytes(variants / name) for name in NAMES}
    reference = files["noon"]
    shared = [f for f in reference if f.endswith(("poses/00.txt", "times.txt")) or "/depth_" in f]
    images = [f for f in reference if "/image_" in f]
    assert len(shared) == 2 + 2 * 3 and len(images) == 4 * 3  # 2 files, 2 depth views; 2 colour + 2 grey views
    for name in NAMES[1:]:
        assert all(files[name][f] == reference[f] for f in shared), name
        assert all(files[name][f] != reference[f] for f in images if "image_2" in f), name
    suns = {name: json.loads((variants / name / "sequences/00/frames.jsonl").read_text().splitlines()[0])["sun"]
            for name in NAMES}
    assert suns["noon"]["form"] == "fixed" and suns["morning"]["form"] == "time" and suns["raw"] is None
    assert suns["flat"]["form"] == "overcast" and "sweep_angle_deg" in suns["paper"]


def test_a_rerun_resumes_each_variant_and_two_workers_give_the_same_bytes(variants, scene_dir, tmp_path, capsys):
    capsys.readouterr()
    assert cli_main(argv(scene_dir, variants, "--lighting-variants", VARIANTS)) == 0
    assert capsys.readouterr().out.count("rendered 0 frames") == len(NAMES)
    assert cli_main(argv(scene_dir, tmp_path / "two", "--workers", "2", "--lighting-variants",
                         "noon=45,60,8,paper=random")) == 0
    for name in ("noon", "paper"):
        assert dataset_bytes(tmp_path / "two" / name) == dataset_bytes(variants / name), name


def test_other_variants_are_refused_unless_overwrite_which_removes_the_datasets_dropped(scene_dir, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli_main(argv(scene_dir, out, "--lighting-variants", "a=45,60,8,b=overcast")) == 0
    (out / "notes.txt").write_text("kept")
    capsys.readouterr()
    assert cli_main(argv(scene_dir, out, "--lighting-variants", "a=45,60,8,c=unlit")) == 2
    assert "holds other lighting variants; pass --overwrite" in capsys.readouterr().err
    assert cli_main(argv(scene_dir, out, "--lighting-variants", "a=45,60,8,c=unlit", "--overwrite")) == 0
    assert [v["name"] for v in json.loads((out / VARIANTS_JSON).read_text())["variants"]] == ["a", "c"]
    assert sorted(path.name for path in (out / "b").iterdir()) == ["logs"]  # b's dataset gone, its run logs kept
    assert (out / "notes.txt").read_text() == "kept" and (out / "c" / "dataset.json").is_file()


def test_variants_and_a_single_dataset_never_share_a_folder(scene_dir, tmp_path, capsys):
    assert cli_main(argv(scene_dir, tmp_path / "one")) == 0
    assert cli_main(argv(scene_dir, tmp_path / "one", "--lighting-variants", "a=unlit")) == 2
    assert "holds a dataset; lighting variants are written into OUT/NAME/" in capsys.readouterr().err
    assert cli_main(argv(scene_dir, tmp_path / "many", "--lighting-variants", "a=unlit")) == 0
    assert cli_main(argv(scene_dir, tmp_path / "many")) == 2
    assert "holds lighting variants" in capsys.readouterr().err
    assert not (tmp_path / "many" / "dataset.json").exists()
