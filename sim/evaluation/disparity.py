"""Disparity metrics of the KITTI 2015 stereo benchmark: end-point error and the D1 outlier rate.

Over the pixels with a ground-truth disparity ``g > 0`` (pixels; left view of a rectified pair) and the
prediction ``p``, the error is ``e = |p - g|``:

* **EPE**: ``mean(e)`` in pixels;
* **D1**: the share of pixels with ``e > 3 px`` **and** ``e > 5 % of g`` (KITTI's ``ABS_THRESH`` and
  ``REL_THRESH``); D1-all over every ground-truth pixel, D1-noc over those whose point the right camera sees.

Like the KITTI devkit, a prediction with holes (0, negative or not finite: no disparity) is first filled by its
``interpolateBackground``: along each row a gap between two valid pixels takes the smaller (farther) of the two
values, and the ends of a row take their nearest valid value; the same is then done along columns for rows with no
valid pixel. ``density`` reports the share of ground-truth pixels that had a prediction of their own. Counts are
pooled over all frames (KITTI divides the outliers of all images by their pixels), and the mean is reported too.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

D1_ABS_PX = 3.0
D1_REL = 0.05


def _fill_rows(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Fill the invalid entries of each row: min of the nearest valid values on both sides, or the one side's."""
    width = values.shape[1]
    columns = np.arange(width)
    previous = np.maximum.accumulate(np.where(valid, columns, -1), axis=1)
    following = np.fliplr(np.minimum.accumulate(np.fliplr(np.where(valid, columns, width)), axis=1))
    rows = np.arange(values.shape[0])[:, None]
    left = np.where(previous >= 0, values[rows, np.clip(previous, 0, width - 1)], np.inf)
    right = np.where(following < width, values[rows, np.clip(following, 0, width - 1)], np.inf)
    return np.where(valid, values, np.minimum(left, right))


def interpolate_background(disparity_px: np.ndarray) -> np.ndarray:
    """The KITTI devkit's hole filling of an (H, W) disparity map (holes: not finite or <= 0); float64.

    Raises ``ValueError`` when the map has no valid pixel at all.
    """
    disparity = np.asarray(disparity_px, dtype=np.float64)
    valid = np.isfinite(disparity) & (disparity > 0)
    if not valid.any():
        raise ValueError("the predicted disparity has no valid pixel (every value is 0, negative or not finite)")
    rows_filled = _fill_rows(disparity, valid)
    filled_rows = valid.any(axis=1)
    return _fill_rows(rows_filled.T, np.broadcast_to(filled_rows, rows_filled.T.shape)).T


@dataclass(frozen=True)
class DisparityFrameScore:
    """One frame: the sum of end-point errors (px) and the outliers (D1) over ``pixels`` ground-truth pixels, the
    same over the ``noc_pixels`` the right camera sees, and the pixels with a prediction of their own."""

    epe_sum: float
    outliers: int
    pixels: int
    noc_epe_sum: float
    noc_outliers: int
    noc_pixels: int
    predicted_pixels: int

    def as_dict(self) -> dict[str, float]:
        """Per-frame EPE (px), D1-all, D1-noc (shares) and density; NaN where there are no pixels."""
        return {"epe": _share(self.epe_sum, self.pixels), "d1_all": _share(self.outliers, self.pixels),
                "epe_noc": _share(self.noc_epe_sum, self.noc_pixels),
                "d1_noc": _share(self.noc_outliers, self.noc_pixels),
                "density": _share(self.predicted_pixels, self.pixels)}


def _share(count: float, pixels: int) -> float:
    return float(count / pixels) if pixels else float("nan")


def d1_outliers(error_px: np.ndarray, truth_px: np.ndarray) -> np.ndarray:
    """KITTI's D1 test: error above 3 px and above 5 % of the true disparity."""
    return (error_px > D1_ABS_PX) & (error_px > D1_REL * np.abs(truth_px))


def score_disparity(predicted_px: np.ndarray, truth_px: np.ndarray, noc: np.ndarray | None = None
                    ) -> DisparityFrameScore:
    """Score one (H, W) predicted disparity against the truth (0 = no truth); ``noc`` marks the truth pixels
    the right camera sees (all of them when ``None``)."""
    predicted, truth = np.asarray(predicted_px, dtype=np.float64), np.asarray(truth_px, dtype=np.float64)
    if predicted.shape != truth.shape:
        raise ValueError(f"predicted disparity is {predicted.shape} but ground truth is {truth.shape}: sizes must "
                         "match")
    has_truth = np.isfinite(truth) & (truth > 0)
    has_prediction = np.isfinite(predicted) & (predicted > 0)
    error = np.abs(interpolate_background(predicted) - truth)
    outlier = d1_outliers(error, truth)
    visible = has_truth if noc is None else has_truth & noc
    return DisparityFrameScore(
        epe_sum=float(error[has_truth].sum()), outliers=int(outlier[has_truth].sum()), pixels=int(has_truth.sum()),
        noc_epe_sum=float(error[visible].sum()), noc_outliers=int(outlier[visible].sum()),
        noc_pixels=int(visible.sum()), predicted_pixels=int((has_truth & has_prediction).sum()))


def pooled(scores: list[DisparityFrameScore]) -> dict[str, float]:
    """The frames' pixels pooled (KITTI's way): EPE, D1-all, EPE-noc, D1-noc and density over all frames."""
    total = DisparityFrameScore(*(sum(getattr(score, column.name) for score in scores)
                                  for column in fields(DisparityFrameScore)))
    return total.as_dict()
