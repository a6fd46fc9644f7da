"""tools/bench/bench_labels.py: group IoU from a class confusion, and the recon log's stage times."""

import numpy as np
import pytest

from sim.render.classes import CLASSES, GROUND, OTHER, ROAD, ROOF, TREE, UNKNOWN, WALL
from tools.bench.bench_labels import group_scores, stage_seconds


def test_group_iou_pools_classes_into_groups_and_counts_unknown_against_the_truth():
    matrix = np.zeros((len(CLASSES), len(CLASSES)), np.int64)
    matrix[GROUND, ROAD] = 60  # ground taken for road: right group
    matrix[ROAD, GROUND] = 20
    matrix[GROUND, TREE] = 10
    matrix[ROOF, WALL] = 30
    matrix[ROOF, UNKNOWN] = 10
    matrix[TREE, TREE] = 40
    matrix[OTHER, GROUND] = 99  # truth in no group: left out
    scores = group_scores(matrix)
    assert scores["iou"] == pytest.approx({"ground": 80 / 90, "building": 30 / 40, "vegetation": 40 / 50})
    assert scores["miou"] == pytest.approx(np.mean([80 / 90, 30 / 40, 40 / 50]))
    assert scores["pixels"] == 170 and scores["unknown_share"] == pytest.approx(10 / 170)
    assert scores["group_confusion"] == [[80, 0, 10, 0], [0, 30, 0, 10], [0, 0, 40, 0]]


def test_stage_seconds_are_read_from_the_done_lines_of_a_recon_log(tmp_path):
    log = tmp_path / "recon.log"
    log.write_text("[sfm] running (stage 1/8)\n[sfm] done (221.7 s)\n[mesh] 3-D surface\n[mesh] done (41.72 s)\n")
    assert stage_seconds(log) == {"sfm": 221.7, "mesh": 41.72}
