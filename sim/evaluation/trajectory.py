"""Trajectory metrics: ATE and RPE computed by evo's library, and the KITTI odometry devkit's drift.

Inputs are matched lists of camera-to-world poses (4x4, metres) of the same frames: the ground truth and the
estimate, in any world frame each (ATE aligns them; RPE and drift use only relative motion).

* **ATE** (evo ``APE``, translation part): after Umeyama alignment of the estimate to the truth -- SE(3), or Sim(3)
  for a monocular estimate known up to scale, or none -- the RMSE, mean and maximum of the position errors (m).
* **RPE** (evo ``RPE``, consecutive frames): RMSE of the relative translation error (m) and of the relative
  rotation angle (deg) between each frame and the next.
* **KITTI drift** (``evaluate_odometry.cpp``): from every 10th frame, for each segment length L (100, 200 ... 800 m
  of ground-truth path), the first frame beyond L along the path closes the segment; its error
  ``E = inv(inv(P_a) P_b) (inv(G_a) G_b)`` gives the translation error ``|t(E)| / L`` (reported in %) and the
  rotation error ``angle(E) / L`` (reported in deg per 100 m). Means over all segments and per length.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: The KITTI devkit's segment lengths (metres of ground-truth path) and first-frame step.
KITTI_LENGTHS_M = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)
KITTI_STEP_FRAMES = 10
ALIGNMENTS = ("se3", "sim3", "none")


def _evo():
    """evo's ``geometry``, ``metrics`` and ``trajectory`` modules: the optional ``evaluate`` extra, imported only
    when a trajectory is scored; a ``ValueError`` saying how to install it when it is missing."""
    try:
        from evo.core import geometry, metrics, trajectory
    except ImportError:
        raise ValueError("scoring a trajectory needs evo: pip install 'aerostereo[evaluate]'") from None
    return geometry, metrics, trajectory


def _evo_trajectory(poses: Sequence[np.ndarray], times_s: Sequence[float]):
    return _evo()[2].PoseTrajectory3D(poses_se3=[np.asarray(pose, dtype=np.float64) for pose in poses],
                                      timestamps=np.asarray(times_s, dtype=np.float64))


def ate_rpe(truth: Sequence[np.ndarray], estimate: Sequence[np.ndarray], times_s: Sequence[float],
            alignment: str = "se3") -> dict[str, float]:
    """ATE after ``alignment`` (:data:`ALIGNMENTS`) and RPE between consecutive frames, by evo; with the Sim(3)
    scale applied (1 unless ``sim3``)."""
    geometry, metrics, _ = _evo()
    if alignment not in ALIGNMENTS:
        raise ValueError(f"alignment {alignment!r}: expected one of {', '.join(ALIGNMENTS)}")
    reference, estimated = _evo_trajectory(truth, times_s), _evo_trajectory(estimate, times_s)
    scale = 1.0
    if alignment != "none":
        try:
            scale = float(estimated.align(reference, correct_scale=alignment == "sim3")[2])
        except geometry.GeometryException:
            raise ValueError(f"the positions (ground truth or estimate) lie in a line, so an {alignment} alignment "
                             "is not unique (any rotation about the line fits); score with --align none") from None
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((reference, estimated))
    statistics = ape.get_all_statistics()
    result = {"ate_rmse_m": statistics["rmse"], "ate_mean_m": statistics["mean"], "ate_max_m": statistics["max"],
              "alignment_scale": scale}
    for key, relation in (("rpe_trans_rmse_m", metrics.PoseRelation.translation_part),
                          ("rpe_rot_rmse_deg", metrics.PoseRelation.rotation_angle_deg)):
        rpe = metrics.RPE(relation, delta=1, delta_unit=metrics.Unit.frames)
        rpe.process_data((reference, estimated))
        result[key] = rpe.get_statistic(metrics.StatisticsType.rmse)
    return {key: float(value) for key, value in result.items()}


def path_distances_m(poses: Sequence[np.ndarray]) -> np.ndarray:
    """Cumulative distance (m) along the camera positions of ``poses``, 0 at the first (``trajectoryDistances``)."""
    positions = np.array([np.asarray(pose)[:3, 3] for pose in poses], dtype=np.float64)
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def rotation_angle_rad(T: np.ndarray) -> float:
    """The rotation angle of a 4x4 pose, from its trace, as the devkit's ``rotationError``."""
    return float(np.arccos(np.clip(0.5 * (np.trace(T[:3, :3]) - 1.0), -1.0, 1.0)))


def kitti_drift(truth: Sequence[np.ndarray], estimate: Sequence[np.ndarray],
                lengths_m: Sequence[float] = KITTI_LENGTHS_M, step: int = KITTI_STEP_FRAMES) -> dict:
    """KITTI's drift: ``{"t_err_percent", "r_err_deg_per_100m", "segments", "per_length": {L: {...}}}``; the
    means are NaN (0 segments) when the path is shorter than every length."""
    truth = [np.asarray(pose, dtype=np.float64) for pose in truth]
    estimate = [np.asarray(pose, dtype=np.float64) for pose in estimate]
    distances = path_distances_m(truth)
    errors: dict[float, list[tuple[float, float]]] = {float(length): [] for length in lengths_m}
    for first in range(0, len(truth), step):
        for length in errors:
            beyond = np.nonzero(distances > distances[first] + length)[0]
            if len(beyond) == 0:
                continue
            last = int(beyond[0])
            delta_truth = np.linalg.inv(truth[first]) @ truth[last]
            delta_estimate = np.linalg.inv(estimate[first]) @ estimate[last]
            error = np.linalg.inv(delta_estimate) @ delta_truth
            errors[length].append((np.linalg.norm(error[:3, 3]) / length, rotation_angle_rad(error) / length))
    per_length = {length: _drift_means(pairs) for length, pairs in errors.items()}
    return {**_drift_means([pair for pairs in errors.values() for pair in pairs]), "per_length": per_length}


def _drift_means(pairs: list[tuple[float, float]]) -> dict:
    """Mean translation error (%) and rotation error (deg / 100 m) of (t_err / L, r_err / L) pairs."""
    if not pairs:
        return {"t_err_percent": float("nan"), "r_err_deg_per_100m": float("nan"), "segments": 0}
    t_err, r_err = np.mean(np.array(pairs), axis=0)
    return {"t_err_percent": float(100.0 * t_err), "r_err_deg_per_100m": float(np.degrees(r_err) * 100.0),
            "segments": len(pairs)}
