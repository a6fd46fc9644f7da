"""Scores of predicted class images against a dataset's (ids of :mod:`sim.render.classes`), from one confusion
matrix pooled over the frames, as Cityscapes' and KITTI's segmentation benchmarks pool theirs.

Truth pixels of class ``unknown`` are left out (nobody knows their class); every other truth class counts, ``sky``
too. A prediction of ``unknown`` on a known pixel is wrong like any other class. Per class, IoU = TP / (TP + FP +
FN); mIoU is their mean over the classes present in the truth; pixel accuracy is the share of scored pixels
predicted right; a group of :data:`sim.render.classes.GROUPS` is scored as one class made of its members.
"""

from __future__ import annotations

import numpy as np

from sim.render.classes import CLASSES, GROUPS, UNKNOWN

CLASS_COUNT = len(CLASSES)


def confusion(truth: np.ndarray, prediction: np.ndarray) -> np.ndarray:
    """(classes, classes) int64 pixel counts, row the truth's class and column the prediction's, of two class id
    images of one size; truth pixels of class ``unknown`` are not counted."""
    scored = truth != UNKNOWN
    pairs = truth[scored].astype(np.int64) * CLASS_COUNT + prediction[scored]
    return np.bincount(pairs, minlength=CLASS_COUNT ** 2).reshape(CLASS_COUNT, CLASS_COUNT)


def iou(matrix: np.ndarray, ids) -> float:
    """IoU of the classes ``ids`` taken as one class (NaN when the truth has none of them)."""
    ids = list(ids)
    truth = matrix[ids, :].sum()
    if truth == 0:
        return float("nan")
    hits = matrix[np.ix_(ids, ids)].sum()
    return float(hits / (truth + matrix[:, ids].sum() - hits))


def scores(matrix: np.ndarray) -> dict:
    """The scores of a confusion matrix: ``pixels`` scored, ``pixel_accuracy``, ``miou`` (over the classes present in
    the truth), per class (by name) its ``id``, ``iou`` (NaN where the truth has none) and pixel counts in truth and
    prediction, and per group its ``iou``. NaN throughout when no pixel was scored."""
    pixels = int(matrix.sum())
    present = [c.id for c in CLASSES if matrix[c.id].sum() > 0]
    classes = {c.name: {"id": c.id, "iou": iou(matrix, [c.id]), "truth_pixels": int(matrix[c.id].sum()),
                        "predicted_pixels": int(matrix[:, c.id].sum())} for c in CLASSES if c.id != UNKNOWN}
    return {"pixels": pixels,
            "pixel_accuracy": float(np.trace(matrix) / pixels) if pixels else float("nan"),
            "miou": float(np.mean([iou(matrix, [i]) for i in present])) if present else float("nan"),
            "classes": classes,
            "groups": {name: {"classes": [CLASSES[i].name for i in ids], "iou": iou(matrix, ids)}
                       for name, ids in GROUPS.items()}}
