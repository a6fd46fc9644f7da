"""Depth metrics of Eigen et al. (NeurIPS 2014) exactly as monodepth2's ``compute_errors`` computes them.

Over the pixels ``i`` of one frame where the truth ``t`` is finite and inside ``(min_depth, max_depth)`` and the
prediction ``p`` is finite and positive (depths in metres, planar z):

* abs rel ``mean(|t - p| / t)``, sq rel ``mean((t - p)^2 / t)`` (metres), RMSE ``sqrt(mean((t - p)^2))`` (metres),
  RMSE log ``sqrt(mean((ln t - ln p)^2))``;
* ``a1, a2, a3``: the share of pixels with ``max(t / p, p / t) < 1.25^k`` for k = 1, 2, 3.

As in monodepth2, a monocular prediction (known only up to scale) may be **median scaled** first: multiplied by
``median(t) / median(p)`` of its frame; then the prediction is clipped to ``[min_depth, max_depth]``. Metrics are
computed per frame and averaged over frames (monodepth2's mean of per-image errors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: monodepth2's MIN_DEPTH (metres); its MAX_DEPTH of 80 m is KITTI's range: aerial views see farther.
MIN_DEPTH_M = 1e-3
DELTA_BASE = 1.25
METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")


def eigen_errors(predicted: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """The metrics of :data:`METRICS` of matching 1-D arrays of positive depths (metres)."""
    predicted, truth = np.asarray(predicted, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    ratio = np.maximum(truth / predicted, predicted / truth)
    difference = truth - predicted
    errors = {"abs_rel": np.mean(np.abs(difference) / truth), "sq_rel": np.mean(difference ** 2 / truth),
              "rmse": np.sqrt(np.mean(difference ** 2)),
              "rmse_log": np.sqrt(np.mean((np.log(truth) - np.log(predicted)) ** 2))}
    errors.update({f"a{k}": np.mean(ratio < DELTA_BASE ** k) for k in (1, 2, 3)})
    return {key: float(value) for key, value in errors.items()}


@dataclass(frozen=True)
class DepthFrameScore:
    """One frame's metrics (:data:`METRICS`), the median-scaling ratio applied (1 without scaling), the pixels
    scored and ``density``: the share of ground-truth pixels that had a valid prediction."""

    metrics: dict[str, float]
    scale: float
    pixels: int
    density: float


def score_depth(predicted_m: np.ndarray, truth_m: np.ndarray, median_scaling: bool = False,
                min_depth_m: float = MIN_DEPTH_M, max_depth_m: float = np.inf) -> DepthFrameScore | None:
    """Score one (H, W) predicted depth map against the truth (metres; +inf/NaN/<= 0 in the prediction = no
    prediction); ``None`` when no pixel has both a valid truth and a valid prediction."""
    predicted, truth = np.asarray(predicted_m, dtype=np.float64), np.asarray(truth_m, dtype=np.float64)
    if predicted.shape != truth.shape:
        raise ValueError(f"predicted depth is {predicted.shape} but ground truth is {truth.shape}: sizes must match")
    in_range = np.isfinite(truth) & (truth > min_depth_m) & (truth < max_depth_m)
    scored = in_range & np.isfinite(predicted) & (predicted > 0)
    if not scored.any():
        return None
    predicted, truth_scored = predicted[scored], truth[scored]
    scale = float(np.median(truth_scored) / np.median(predicted)) if median_scaling else 1.0
    predicted = np.clip(predicted * scale, min_depth_m, max_depth_m)
    return DepthFrameScore(eigen_errors(predicted, truth_scored), scale, int(scored.sum()),
                           float(scored.sum() / in_range.sum()))
