"""The scorer's metrics against analytic truth: Eigen depth metrics (and median scaling), EPE and KITTI's D1 (and
the devkit's hole filling), ATE/RPE by evo after a known offset, rotation and scale, KITTI drift per segment."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim.evaluation.depth import score_depth
from sim.evaluation.disparity import interpolate_background, pooled, score_disparity
from sim.evaluation.trajectory import ate_rpe, kitti_drift, rotation_angle_rad

TRUTH_M = np.array([[2.0, 4.0, 8.0], [10.0, 20.0, 40.0]])


# -- depth ------------------------------------------------------------------------------------------------------------

def test_identical_depth_scores_zero_error_and_all_deltas_one():
    score = score_depth(TRUTH_M, TRUTH_M)
    assert score.metrics == {"abs_rel": 0.0, "sq_rel": 0.0, "rmse": 0.0, "rmse_log": 0.0, "a1": 1.0, "a2": 1.0,
                             "a3": 1.0}
    assert (score.scale, score.pixels, score.density) == (1.0, 6, 1.0)


@pytest.mark.parametrize("factor, deltas", [(1.1, (1.0, 1.0, 1.0)), (1.3, (0.0, 1.0, 1.0)), (1.6, (0.0, 0.0, 1.0))])
def test_a_scaled_prediction_gives_the_analytic_metrics(factor, deltas):
    score = score_depth(factor * TRUTH_M, TRUTH_M).metrics
    error = factor - 1.0
    assert score["abs_rel"] == pytest.approx(error)
    assert score["sq_rel"] == pytest.approx(error ** 2 * TRUTH_M.mean())  # (e t)^2 / t = e^2 t
    assert score["rmse"] == pytest.approx(error * math.sqrt(np.mean(TRUTH_M ** 2)))
    assert score["rmse_log"] == pytest.approx(math.log(factor))
    assert (score["a1"], score["a2"], score["a3"]) == deltas


def test_median_scaling_undoes_a_global_scale_and_reports_it():
    score = score_depth(0.25 * TRUTH_M, TRUTH_M, median_scaling=True)
    assert score.scale == pytest.approx(4.0)
    assert score.metrics["abs_rel"] == pytest.approx(0.0, abs=1e-12)
    assert score.metrics["a1"] == 1.0


def test_a_shifted_prediction_gives_the_analytic_metrics():
    score = score_depth(TRUTH_M + 1.0, TRUTH_M).metrics
    assert score["abs_rel"] == pytest.approx(np.mean(1.0 / TRUTH_M))
    assert score["rmse"] == pytest.approx(1.0)
    assert score["sq_rel"] == pytest.approx(np.mean(1.0 / TRUTH_M))
    assert score["a1"] == pytest.approx(4 / 6)  # ratios 3/2 and 5/4 are not below 1.25, the other four are
    assert score["a2"] == 1.0


def test_missing_predictions_and_truth_out_of_range_are_not_scored_and_predictions_are_clipped():
    predicted = TRUTH_M.copy()
    predicted[0, 0] = np.nan  # no prediction: lowers the density
    predicted[1, 1] = 0.0  # no prediction either
    predicted[0, 1] = 100.0  # clipped to max depth 30 m: error 26 m at truth 4 m
    score = score_depth(predicted, TRUTH_M, max_depth_m=30.0)  # truth 40 m is out of range
    assert (score.pixels, score.density) == (3, 3 / 5)
    assert score.metrics["abs_rel"] == pytest.approx((26.0 / 4.0) / 3)
    assert score_depth(np.full_like(TRUTH_M, np.inf), TRUTH_M) is None


# -- disparity --------------------------------------------------------------------------------------------------------

def test_d1_counts_errors_above_3_px_and_5_percent_on_a_crafted_map():
    truth = np.array([[100.0, 100.0, 100.0, 20.0, 20.0, 20.0, 0.0]])
    # errors:          4 (< 5 %), 6 (> both), 2 (< 3 px), 3.5 (> both), 2.9 (< 3 px), 3.0 (not > 3), no truth
    predicted = np.array([[104.0, 94.0, 102.0, 23.5, 17.1, 23.0, 50.0]])
    score = score_disparity(predicted, truth).as_dict()
    assert score["d1_all"] == pytest.approx(2 / 6)
    assert score["epe"] == pytest.approx((4 + 6 + 2 + 3.5 + 2.9 + 3.0) / 6)
    assert score["density"] == 1.0
    identical = score_disparity(truth, truth).as_dict()
    assert (identical["epe"], identical["d1_all"]) == (0.0, 0.0)


def test_noc_scores_only_the_pixels_the_right_camera_sees_and_frames_pool_their_pixels():
    truth = np.full((1, 4), 50.0)
    predicted = np.array([[50.0, 60.0, 60.0, 50.0]])
    seen = np.array([[True, True, False, False]])
    one = score_disparity(predicted, truth, seen)
    assert one.as_dict()["d1_all"] == 0.5 and one.as_dict()["d1_noc"] == 0.5
    other = score_disparity(truth[:, :2], truth[:, :2])
    both = pooled([one, other])
    assert both["d1_all"] == pytest.approx(2 / 6) and both["epe"] == pytest.approx(20 / 6)
    assert both["d1_noc"] == pytest.approx(1 / 4)


def test_holes_are_filled_like_the_kitti_devkit_background_interpolation():
    disparity = np.array([[0.0, 10.0, -1.0, np.nan, 20.0, 0.0],
                          [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                          [7.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    filled = interpolate_background(disparity)
    np.testing.assert_array_equal(filled[0], [10, 10, 10, 10, 20, 20])  # gap: the farther (smaller) neighbour
    np.testing.assert_array_equal(filled[2], [7] * 6)
    np.testing.assert_array_equal(filled[1], np.minimum(filled[0], filled[2]))  # an empty row: from the rows around
    with pytest.raises(ValueError, match="no valid pixel"):
        interpolate_background(np.zeros((2, 2)))


def test_a_hole_counts_against_density_and_is_scored_at_its_filled_value():
    truth = np.array([[30.0, 30.0, 30.0]])
    score = score_disparity(np.array([[30.0, 0.0, 40.0]]), truth).as_dict()
    assert score["density"] == pytest.approx(2 / 3)
    assert score["epe"] == pytest.approx(10 / 3)  # the hole takes 30 (min of 30, 40): no error


# -- trajectory -------------------------------------------------------------------------------------------------------

def pose(rotation: np.ndarray, position) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = position
    return T


def helix(count: int = 40) -> list[np.ndarray]:
    """A climbing, turning path (not planar, so alignment is unique), heading along the track."""
    angles = np.linspace(0.0, 3.0, count)
    return [pose(Rotation.from_euler("zx", [a, 0.3 * a]).as_matrix(), (20 * np.cos(a), 20 * np.sin(a), 2 * a))
            for a in angles]


def test_ate_after_alignment_removes_a_known_offset_and_rotation():
    truth = helix()
    T_other_world = pose(Rotation.from_euler("zyx", [40, -10, 5], degrees=True).as_matrix(), (100.0, -50.0, 7.0))
    estimate = [T_other_world @ T for T in truth]
    times = np.arange(len(truth)) * 0.1
    aligned = ate_rpe(truth, estimate, times, "se3")
    assert aligned["ate_rmse_m"] == pytest.approx(0.0, abs=1e-6)
    assert aligned["rpe_trans_rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert aligned["rpe_rot_rmse_deg"] == pytest.approx(0.0, abs=1e-5)
    shifted = [pose(T[:3, :3], T[:3, 3] + (1.0, 2.0, 2.0)) for T in truth]
    unaligned = ate_rpe(truth, shifted, times, "none")
    assert unaligned["ate_rmse_m"] == pytest.approx(3.0) and unaligned["ate_max_m"] == pytest.approx(3.0)


def test_sim3_alignment_recovers_the_scale_of_a_monocular_estimate():
    truth = helix()
    estimate = [pose(T[:3, :3], 0.5 * T[:3, 3] + 3.0) for T in truth]
    result = ate_rpe(truth, estimate, np.arange(len(truth)) * 0.1, "sim3")
    assert result["alignment_scale"] == pytest.approx(2.0)
    assert result["ate_rmse_m"] == pytest.approx(0.0, abs=1e-6)


def test_rpe_of_a_straight_path_flown_10_percent_too_far_per_step():
    truth = [pose(np.eye(3), (2.0 * i, 0.0, 0.0)) for i in range(20)]
    estimate = [pose(np.eye(3), (2.2 * i, 0.0, 0.0)) for i in range(20)]
    result = ate_rpe(truth, estimate, np.arange(20) * 0.1, "none")
    assert result["rpe_trans_rmse_m"] == pytest.approx(0.2)  # every 2 m step is 0.2 m long
    with pytest.raises(ValueError, match="in a line"):  # Umeyama has no unique rotation about the line
        ate_rpe(truth, estimate, np.arange(20) * 0.1, "se3")


def straight(count: int, scale: float = 1.0, yaw_deg_per_frame: float = 0.0) -> list[np.ndarray]:
    """Frames 1 m apart along x (times ``scale``), turning ``yaw_deg_per_frame`` about z each frame."""
    return [pose(Rotation.from_euler("z", yaw_deg_per_frame * i, degrees=True).as_matrix(), (scale * i, 0.0, 0.0))
            for i in range(count)]


def test_kitti_drift_of_a_path_one_percent_too_long():
    truth, estimate = straight(1000), straight(1000, scale=1.01)
    drift = kitti_drift(truth, estimate)
    for length in (100.0, 400.0, 800.0):
        per_length = drift["per_length"][length]
        # the segment ends at the first frame *beyond* L: L + 1 m of path, 1 % of it in error, divided by L
        assert per_length["t_err_percent"] == pytest.approx(1.0 * (length + 1) / length)
        assert per_length["r_err_deg_per_100m"] == pytest.approx(0.0, abs=1e-9)
        # first frames 0, 10, 20 ... whose segment ends inside the 1000 frames
        assert per_length["segments"] == (999 - (length + 1)) // 10 + 1
    assert drift["segments"] == sum(values["segments"] for values in drift["per_length"].values())


def test_kitti_drift_of_a_heading_that_turns_a_known_rate_too_fast():
    truth, estimate = straight(300), straight(300, yaw_deg_per_frame=0.01)
    drift = kitti_drift(truth, estimate, lengths_m=(50.0, 100.0))
    for length in (50.0, 100.0):  # a segment of L + 1 frames turns 0.01 deg each: (L + 1) * 0.01 deg per L metres
        assert drift["per_length"][length]["r_err_deg_per_100m"] == pytest.approx((length + 1) * 0.01 / length * 100)
    assert math.isnan(kitti_drift(truth, estimate)["per_length"][800.0]["t_err_percent"])  # path too short


def test_rotation_angle_is_the_angle_of_the_rotation():
    assert rotation_angle_rad(pose(Rotation.from_rotvec([0.3, -0.2, 0.1]).as_matrix(), (0, 0, 0))) == \
        pytest.approx(math.sqrt(0.14))


def test_without_evo_a_trajectory_is_refused_saying_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "evo.core", None)  # what an installation without the 'evaluate' extra sees
    with pytest.raises(ValueError, match=r"needs evo: pip install 'aerostereo\[evaluate\]'"):
        ate_rpe(helix(), helix(), np.arange(40) * 0.1)
