"""tools/bench/bench_labels.py: group IoU from a class confusion, and the recon log's stage times."""

import numpy as np
import pytest

from sim.render.classes import (CAR, CHIMNEY, CLASSES, GROUND, OTHER, POLE, ROAD, ROOF, SKY, TREE, UNKNOWN, WALL,
                                WATER)
from tools.bench.bench_labels import class_scores, group_scores, stage_seconds


def test_group_iou_pools_classes_into_groups_and_counts_unknown_against_the_truth():
    matrix = np.zeros((len(CLASSES), len(CLASSES)), np.int64)
    matrix[GROUND, ROAD] = 60  # ground taken for road: right group
    matrix[ROAD, GROUND] = 20
    matrix[GROUND, TREE] = 10
    matrix[ROOF, WALL] = 30
    matrix[ROOF, UNKNOWN] = 10
    matrix[CHIMNEY, ROOF] = 5  # a chimney taken for roof: right group (building)
    matrix[TREE, TREE] = 40
    matrix[CAR, CAR] = 5
    matrix[POLE, GROUND] = 5  # a pole lost into the ground
    matrix[OTHER, GROUND] = 99  # truth in no group: left out
    scores = group_scores(matrix)
    expected = {"ground": 80 / 95, "building": 35 / 45, "vegetation": 40 / 50, "objects": 5 / 10}
    assert scores["iou"] == pytest.approx(expected)
    assert scores["miou"] == pytest.approx(np.mean(list(expected.values())))
    assert scores["pixels"] == 185 and scores["unknown_share"] == pytest.approx(10 / 185)
    assert scores["group_confusion"] == [[80, 0, 10, 0, 0], [0, 35, 0, 0, 10], [0, 0, 40, 0, 0], [5, 0, 0, 5, 0]]


def test_a_group_the_truth_does_not_show_has_no_iou_and_stays_out_of_the_mean():
    matrix = np.zeros((len(CLASSES), len(CLASSES)), np.int64)
    matrix[GROUND, GROUND], matrix[ROOF, ROOF], matrix[TREE, GROUND] = 50, 30, 10
    scores = group_scores(matrix)
    assert np.isnan(scores["iou"]["objects"]) and scores["iou"]["vegetation"] == 0.0
    assert scores["miou"] == pytest.approx(np.mean([50 / 60, 1.0, 0.0]))


def test_a_class_scores_the_share_of_its_truth_found_and_of_its_labels_right():
    matrix = np.zeros((len(CLASSES), len(CLASSES)), np.int64)
    matrix[WATER, WATER], matrix[WATER, GROUND], matrix[WATER, UNKNOWN] = 70, 20, 10
    matrix[GROUND, WATER], matrix[ROAD, WATER], matrix[SKY, WATER] = 20, 10, 50  # sky: truth in no group, left out
    assert class_scores(matrix, WATER) == pytest.approx({"pixels": 100, "recall": 0.7, "precision": 0.7})
    matrix[:, WATER] = 0
    scores = class_scores(matrix, WATER)
    assert scores["recall"] == 0.0 and np.isnan(scores["precision"])
    assert np.isnan(class_scores(np.zeros_like(matrix), WATER)["recall"])


def test_stage_seconds_are_read_from_the_done_lines_of_a_recon_log(tmp_path):
    log = tmp_path / "recon.log"
    log.write_text("[sfm] running (stage 1/8)\n[sfm] done (221.7 s)\n[mesh] 3-D surface\n[mesh] done (41.72 s)\n")
    assert stage_seconds(log) == {"sfm": 221.7, "mesh": 41.72}
