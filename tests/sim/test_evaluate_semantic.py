"""``aerostereo-render evaluate --semantic``: predicted class images against the labelled box scene's class images:
the truth scores 1, a known corruption (the roof of frame 0 called wall) the IoUs computed by hand, the truth's
unknown pixels are not scored; predictions that do not fit are refused in one line."""

from __future__ import annotations

import json
import re
import shutil

import cv2
import numpy as np
import pytest

from sim.cli import main as cli_main
from sim.evaluation.semantic import confusion, scores
from sim.render.classes import CLASSES, GROUND, ROOF, SKY, TREE, UNKNOWN, WALL
from tests.sim.label_dataset_helpers import write_labelled_dataset

FRAMES = 2
PROG = "aerostereo-render evaluate: error: "
#: Rows of frame 1's truth made unknown: whatever is predicted there is not scored.
UNKNOWN_ROWS = slice(0, 10)


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    """The labelled dataset, with the top rows of frame 1's left class image made unknown."""
    dataset = write_labelled_dataset(tmp_path_factory.mktemp("semantic"), FRAMES)
    truth = dataset.semantic[1][0]
    truth[UNKNOWN_ROWS] = UNKNOWN
    cv2.imwrite(str(dataset.root / "sequences/00/semantic_2/000001.png"), truth)
    return dataset


def predict(folder, class_images) -> str:
    folder.mkdir()
    for index, classes in enumerate(class_images):
        cv2.imwrite(str(folder / f"{index:06d}.png"), classes)
    return str(folder)


def evaluate(labelled, tmp_path, predictions) -> dict:
    report = tmp_path / "report.json"
    assert cli_main(["evaluate", str(labelled.root), "--semantic", predict(tmp_path / "pred", predictions),
                     "--json", str(report)]) == 0
    return json.loads(report.read_text())["semantic"]


def test_the_truth_scores_one_everywhere_and_the_unknown_pixels_are_not_scored(labelled, tmp_path, capsys):
    predictions = [frame[0].copy() for frame in labelled.semantic]
    predictions[1][UNKNOWN_ROWS] = TREE  # no tree in the scene: scored, it would be wrong
    report = evaluate(labelled, tmp_path, predictions)
    pixels = sum(frame.size for frame in predictions) - predictions[1][UNKNOWN_ROWS].size
    assert (report["miou"], report["pixel_accuracy"], report["pixels"]) == (1.0, 1.0, pixels)
    assert {name for name, values in report["classes"].items() if values["iou"] is not None} == \
        {"ground", "roof", "wall", "sky"}
    assert report["classes"]["tree"] == {"id": TREE, "iou": None, "truth_pixels": 0, "predicted_pixels": 0}
    assert report["groups"]["building"] == {"classes": ["roof", "wall", "chimney"], "iou": 1.0}
    assert report["groups"]["vegetation"]["iou"] is None
    table = capsys.readouterr().out
    assert "mIoU" in table and "building" in table and "\n        tree" not in table


def test_the_roof_of_frame_0_called_wall_scores_the_iou_computed_by_hand(labelled, tmp_path):
    truth = [frame[0] for frame in labelled.semantic]
    predictions = [classes.copy() for classes in truth]
    predictions[0][truth[0] == ROOF] = WALL
    moved = int(np.count_nonzero(truth[0] == ROOF))
    counts = {c: sum(int(np.count_nonzero(classes == c)) for classes in truth) for c in (GROUND, ROOF, WALL, SKY)}
    assert 0 < moved < counts[ROOF]
    report = evaluate(labelled, tmp_path, predictions)
    roof = (counts[ROOF] - moved) / counts[ROOF]  # TP = the roof left, FN = the roof moved, FP = 0
    wall = counts[WALL] / (counts[WALL] + moved)  # TP = every wall, FP = the roof moved, FN = 0
    assert report["classes"]["roof"]["iou"] == pytest.approx(roof)
    assert report["classes"]["wall"]["iou"] == pytest.approx(wall)
    assert report["miou"] == pytest.approx((1.0 + roof + wall + 1.0) / 4)
    assert report["pixel_accuracy"] == pytest.approx(1.0 - moved / report["pixels"])
    assert report["groups"]["building"]["iou"] == 1.0  # roof and wall are one building
    assert report["per_frame"][1]["miou"] == 1.0 and report["per_frame"][0]["miou"] < 1.0


def test_scores_of_a_small_confusion_by_hand():
    """Truth ground, ground, road, unknown; prediction ground, road, road, sky: the unknown pixel is not scored;
    ground IoU 1/2, road 1/2, sky absent from the truth (NaN, not in the mean); ground group (ground + road) 1."""
    matrix = confusion(np.array([GROUND, GROUND, 2, UNKNOWN], np.uint8), np.array([GROUND, 2, 2, SKY], np.uint8))
    result = scores(matrix)
    assert result["pixels"] == 3 and result["pixel_accuracy"] == pytest.approx(2 / 3)
    assert result["classes"]["ground"]["iou"] == result["classes"]["road"]["iou"] == 0.5
    assert np.isnan(result["classes"]["sky"]["iou"]) and result["miou"] == 0.5
    assert result["groups"]["ground"]["iou"] == 1.0


def refused(capsys, arguments) -> str:
    assert cli_main(["evaluate", *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and error.startswith(PROG), error
    return error[len(PROG):]


@pytest.mark.parametrize("case, expected", [
    ("missing", r"--semantic .*pred: (does not exist|not found|no such)"),
    ("colour", r"pred/000001\.png: expected an 8-bit single-channel PNG of class ids .*, got a colour \(mode RGB\) PNG"),
    ("16-bit", r"pred/000001\.png: expected an 8-bit single-channel PNG of class ids .*, got a 16-bit grey \(mode "
               r"I;16\) PNG"),
    ("size", r"pred/000001\.png: 95x72 pixels, but the dataset's frames are 96x72"),
    ("id", rf"pred/000001\.png: class id {len(CLASSES)} at pixel x=3 y=2; expected the ids 0\.\.{len(CLASSES) - 1}"),
    ("no-frame-1", r"--semantic .*pred: no prediction of 1 of the dataset's 2 frames \(000001\); expected one \.png"),
])
def test_predictions_that_do_not_fit_are_refused(labelled, tmp_path, capsys, case, expected):
    folder = tmp_path / "pred"
    if case != "missing":
        predict(folder, [frame[0] for frame in labelled.semantic])
    second = folder / "000001.png"
    bad = {"colour": np.zeros((72, 96, 3), np.uint8), "16-bit": np.zeros((72, 96), np.uint16),
           "size": np.zeros((72, 95), np.uint8)}
    if case in bad:
        cv2.imwrite(str(second), bad[case])
    elif case == "id":
        classes = labelled.semantic[1][0].copy()
        classes[2, 3] = len(CLASSES)  # one past the table
        cv2.imwrite(str(second), classes)
    elif case == "no-frame-1":
        second.unlink()
    error = refused(capsys, [str(labelled.root), "--semantic", str(folder), "--json", str(tmp_path / "r.json")])
    assert re.search(expected, error), error
    assert not (tmp_path / "r.json").exists()


def test_a_dataset_without_class_images_is_refused_naming_the_format(labelled, tmp_path, capsys):
    dataset = tmp_path / "dataset"
    shutil.copytree(labelled.root, dataset)
    description = json.loads((dataset / "dataset.json").read_text())
    description["formats"].remove("semantic_png")
    (dataset / "dataset.json").write_text(json.dumps(description))
    folder = predict(tmp_path / "pred", [frame[0] for frame in labelled.semantic])
    error = refused(capsys, [str(dataset), "--semantic", folder])
    assert "--semantic needs the class images" in error and "--formats including semantic_png" in error
