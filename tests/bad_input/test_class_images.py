"""Class images that do not fit: evaluate --semantic and the label exports name the file (or the dataset.json
that lacks the format) in one line and exit 2, leaving nothing behind."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.bad_input.harness import Case, assert_refused, run_case
from tests.sim.label_dataset_helpers import write_labelled_dataset

RENDER = "aerostereo-render"
SEMANTIC = ["evaluate", "{tmp}/d", "--semantic", "{tmp}/pred"]


@pytest.fixture(scope="module")
def labelled(tmp_path_factory) -> Path:
    """A 2-frame labelled dataset (96x72, class, object and normal images)."""
    return write_labelled_dataset(tmp_path_factory.mktemp("labels"), 2).root


def _copy(dataset: Path, tmp: Path, without_format: str | None = None) -> Path:
    copy = tmp / "d"
    shutil.copytree(dataset, copy)
    if without_format:
        description = json.loads((copy / "dataset.json").read_text())
        description["formats"].remove(without_format)
        (copy / "dataset.json").write_text(json.dumps(description))
    return copy


def _predictions(second: np.ndarray):
    """A setup writing a --semantic folder whose frame 0 is all ground and frame 1 the array ``second``."""
    def setup(tmp: Path) -> None:
        (tmp / "pred").mkdir()
        cv2.imwrite(str(tmp / "pred/000000.png"), np.ones((72, 96), np.uint8))
        cv2.imwrite(str(tmp / "pred/000001.png"), second)
    return setup


@pytest.mark.parametrize("name, second, message", [
    ("wrong-size", np.ones((70, 96), np.uint8), r"pred/000001\.png: 96x70 pixels, but the dataset's frames are 96x72"),
    ("16-bit", np.ones((72, 96), np.uint16), r"pred/000001\.png: expected an 8-bit single-channel PNG of class ids"),
    ("id-outside-table", np.full((72, 96), 200, np.uint8), r"pred/000001\.png: class id 200 at pixel x=0 y=0"),
], ids=["wrong-size", "16-bit", "id-outside-table"])
def test_a_class_prediction_that_does_not_fit_is_named(labelled, tmp_path, name, second, message):
    _copy(labelled, tmp_path)
    case = Case(f"evaluate-semantic-{name}", RENDER, SEMANTIC, message, _predictions(second))
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_missing_class_prediction_folder_is_named(labelled, tmp_path):
    _copy(labelled, tmp_path)
    case = Case("evaluate-semantic-missing-folder", RENDER, SEMANTIC, r"--semantic .*pred: .*expected a folder")
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_dataset_without_class_images_is_refused_by_evaluate(labelled, tmp_path):
    _copy(labelled, tmp_path, without_format="semantic_png")
    case = Case("evaluate-semantic-no-class-images", RENDER, SEMANTIC,
                r"dataset\.json: --semantic needs the class images, .*render it with --formats including semantic_png",
                _predictions(np.ones((72, 96), np.uint8)))
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_truth_class_image_of_another_size_is_named_by_the_export(labelled, tmp_path):
    cv2.imwrite(str(_copy(labelled, tmp_path) / "sequences/00/semantic_3/000001.png"), np.ones((72, 95), np.uint8))
    case = Case("export-vkitti2-class-image-of-another-size", RENDER,
                ["export", "{tmp}/d", "--layout", "vkitti2", "--out", "{tmp}/e"],
                r"semantic_3/000001\.png: a 95x72 class image, expected 96x72 \(camera 1's image size\)")
    assert_refused(run_case(case, tmp_path), case, tmp_path)
