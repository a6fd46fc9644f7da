"""Round three of the hostile re-run (issue 40), ``aerostereo-render``'s part: each case was taken as valid, leaked
RuntimeWarnings or blamed the wrong input; each must now be one line naming the argument or file, exit code 2,
nothing written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.bad_input.harness import Case, assert_refused, run_case, small_disk
from tests.bad_input.test_limits import write_mission
from tests.sim.label_dataset_helpers import write_labelled_dataset
from tests.sim.render_scene_helpers import write_scene

RENDER = "aerostereo-render"
FLY = ["fly", "--mission", "{tmp}/m.csv", "--scene", "demo:small", "--out", "{tmp}/f", "--photos", "1",
       "--photo-size", "16", "12", "--start-utc", "2024-05-01T08:00:00Z"]
DATASET = ["--scene", "demo:small", "--out", "{tmp}/d", "--frames", "1", "--width", "16", "--height", "12"]


def write_scene_with_broken_labels(tmp: Path) -> None:
    """The test box scene whose scene.json names a labels file that is not there."""
    write_scene(tmp / "scene", ground_half_size_m=60.0)
    meta = json.loads((tmp / "scene/scene.json").read_text())
    meta["labels"] = {"file": "labels.npz", "format": "aerostereo-labels/1"}
    (tmp / "scene/scene.json").write_text(json.dumps(meta))


CASES = [
    # fly: dates EXIF's DateTimeOriginal cannot hold ("1:01:01 08:00:18"), sizes beyond the render's limit
    Case("fly-start-year-1", RENDER, [*FLY[:-1], "0001-01-01T08:00:00Z"],
         r"--start-utc 0001-01-01T08:00:00\+00:00: .*years 1000 to 9999", write_mission),
    Case("fly-start-year-999", RENDER, [*FLY[:-1], "0999-12-31T23:00:00Z"],
         r"--start-utc 0999-12-31T23:00:00\+00:00: .*years 1000 to 9999", write_mission),
    Case("fly-photo-size-65535", RENDER, [*FLY[:10], "65535", "16", *FLY[12:]],
         r"argument --photo-size: expected 1\.\.16384 pixels a side .*got '65535'", write_mission),
    # the sun's strength: 1e308 rendered saturated images with RuntimeWarnings
    Case("fly-sun-strength-1e308", RENDER, [*FLY, "--sun", "45,60,1e308"],
         r"argument --sun: '45,60,1e308': strength must be a finite number >= 0 and at most 100", write_mission),
    Case("render-sun-strength-1e308", RENDER, [*DATASET, "--sun", "45,60,1e308"],
         r"argument --sun: '45,60,1e308': strength must be a finite number >= 0 and at most 100"),
    Case("render-variant-strength-1e308", RENDER, [*DATASET, "--lighting-variants", "a=45,60,1e308"],
         r"argument --lighting-variants: a=45,60,1e308: .*strength must be a finite number >= 0 and at most 100"),
    # a negative-leading --sun was "expected one argument"; a bad one must say what --sun takes
    Case("fly-sun-negative-two-numbers", RENDER, [*FLY, "--sun", "-45,60"],
         r"argument --sun: expected random, AZ,EL,STRENGTH", write_mission),
    # --heights 20,1e308 leaked 4 RuntimeWarnings before refusing
    Case("render-heights-1e308", RENDER, [*DATASET, "--heights", "20,1e308"],
         r"argument --heights: expected MIN,MAX metres above the ground with 0 < MIN <= MAX <= 10000 .*got 20,1e\+308"),
    # each refusal names its argument: --distortion nan was blamed on the scene, --seed -1 on the mission
    Case("render-distortion-nan", RENDER, [*DATASET, "--formats", "depth_exr", "--distortion", "nan,0,0,0,0"],
         r"argument --distortion: expected five finite numbers"),
    Case("render-seed-negative", RENDER, [*DATASET, "--seed", "-1"], r"argument --seed: expected an integer >= 0"),
    Case("fly-seed-negative", RENDER, [*FLY, "--seed", "-1"], r"argument --seed: expected an integer >= 0",
         write_mission),
    # a render that needs the labels names scene.json and its labels entry
    Case("render-semantic-broken-labels", RENDER,
         ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--frames", "1", "--width", "16", "--height", "12",
          "--formats", "semantic_png"], r"scene\.json: \"labels\": its file .labels\.npz. is not found",
         write_scene_with_broken_labels),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_many_lighting_variants_are_sized_in_all_before_the_first(tmp_path):
    """300 variants of one 64x48 frame need 300 datasets on disk: refused up front on a 2 MiB disk, where each one
    alone fits."""
    variants = ",".join(f"v{index}=45,60,8" for index in range(300))
    with small_disk(tmp_path / "disk", "2m") as disk:
        case = Case("render-300-lighting-variants-small-disk", RENDER,
                    ["--scene", "demo:small", "--out", f"{disk}/d", "--frames", "1", "--width", "64", "--height",
                     "48", "--lighting-variants", variants],
                    r"300 lighting variants x 1 frames of 64x48 pixels x 2 cameras needs about .* on disk; .* has .* free")
        assert_refused(run_case(case, tmp_path), case, tmp_path)


# -- evaluate --semantic and the class table of exports ------------------------------------------------------------

@pytest.fixture(scope="module")
def labelled(tmp_path_factory) -> Path:
    """A 2-frame labelled dataset (96x72, class, object and normal images)."""
    return write_labelled_dataset(tmp_path_factory.mktemp("labels"), 2).root


def _class_predictions(mode: str, file_format: str = "PNG"):
    """A --semantic folder whose frame 1 is a class image of Pillow ``mode`` saved as ``file_format`` (under the
    .png name)."""
    def setup(tmp: Path) -> None:
        (tmp / "pred").mkdir()
        Image.fromarray(np.ones((72, 96), np.uint8)).save(tmp / "pred/000000.png")
        Image.fromarray(np.ones((72, 96), np.uint8)).convert(mode).save(tmp / "pred/000001.png", format=file_format)
    return setup


@pytest.mark.parametrize("mode, file_format, message", [
    ("P", "PNG", r"pred/000001\.png: expected .* \(8-bit grey, mode L\), got a palette \(mode P\) PNG; save its "
                 r"palette indices as grey"),
    ("LA", "PNG", r"pred/000001\.png: expected .* \(8-bit grey, mode L\), got a grey PNG with an alpha channel "
                  r"\(mode LA\)"),
    ("L", "JPEG", r"pred/000001\.png: expected .* \(8-bit grey, mode L\), got a JPEG image \(lossy"),
], ids=["palette", "grey-alpha", "jpeg"])
def test_a_class_prediction_of_another_kind_is_named_for_what_it_is(labelled, tmp_path, mode, file_format, message):
    shutil.copytree(labelled, tmp_path / "d")
    case = Case(f"evaluate-semantic-{mode}-{file_format}", RENDER, ["evaluate", "{tmp}/d", "--semantic", "{tmp}/pred"],
                message, _class_predictions(mode, file_format))
    assert_refused(run_case(case, tmp_path), case, tmp_path)


@pytest.mark.parametrize("name, classes, message", [
    ("300-bogus", [{"id": i, "name": f"bogus{i}"} for i in range(300)],
     r"dataset\.json: \"classes\" lists 300 classes; an 8-bit class image holds at most 255"),
    ("renamed", [{"id": 0, "name": "unknown"}, {"id": 1, "name": "lava"}],
     r"dataset\.json: \"classes\" entry 1 \{'id': 1, 'name': 'lava'\}: not the renderer's class table .*class 1 is "
     r"'ground'"),
    ("not-a-list", {"ground": 1}, r"dataset\.json: \"classes\" must be a list"),
], ids=["300-bogus", "renamed", "not-a-list"])
def test_an_export_of_a_bogus_class_table_is_refused(labelled, tmp_path, name, classes, message):
    def setup(tmp: Path) -> None:
        shutil.copytree(labelled, tmp / "d")
        description = json.loads((tmp / "d/dataset.json").read_text())
        description["classes"] = classes
        (tmp / "d/dataset.json").write_text(json.dumps(description))
    case = Case(f"export-classes-{name}", RENDER, ["export", "{tmp}/d", "--layout", "kitti2015", "--out", "{tmp}/x"],
                message, setup)
    assert_refused(run_case(case, tmp_path), case, tmp_path)
