"""Score predictions against a finalized dataset folder: depth maps, disparities, class images and/or a trajectory
of the left camera. :func:`evaluate` returns the report (a JSON-ready dict), :func:`report_table` its text table."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cliutil.errors import BadInput
from sim.dataset.images import disparity_from_depth
from sim.dataset.kitti import relative_poses
from sim.dataset.kitti2015 import visible_in_right
from sim.dataset.source import LEFT, RIGHT, DatasetSource
from sim.dataset.writer import DatasetError
from sim.evaluation import depth as depth_metrics
from sim.evaluation import disparity as disparity_metrics
from sim.evaluation import semantic as semantic_metrics
from sim.evaluation import trajectory as trajectory_metrics
from sim.evaluation.predictions import (
    TrajectoryFile,
    map_files,
    match_times,
    read_class_image,
    read_map,
    read_trajectory,
)

#: Fewest matched poses a trajectory is scored with (Umeyama alignment needs three).
MIN_POSES = 3


@dataclass(frozen=True)
class EvaluateOptions:
    """What to score (prediction folders / file; ``None``: not scored) and how."""

    depth: Path | None = None
    disparity: Path | None = None
    trajectory: Path | None = None
    semantic: Path | None = None
    median_scaling: bool = False
    min_depth_m: float = depth_metrics.MIN_DEPTH_M
    max_depth_m: float = float("inf")
    alignment: str = "se3"
    drift_lengths_m: tuple[float, ...] = trajectory_metrics.KITTI_LENGTHS_M


def evaluate(dataset: Path, options: EvaluateOptions) -> dict:
    """The report of every prediction named in ``options`` against the dataset in ``dataset``; every input is
    checked (files present, named and matched) before the first is scored."""
    if all(path is None for path in (options.depth, options.disparity, options.trajectory, options.semantic)):
        raise BadInput("nothing to score: give --depth, --disparity, --semantic and/or --trajectory")
    source = DatasetSource(Path(dataset))
    depth_files = _map_inputs(source, options.depth, "--depth")
    disparity_files = _map_inputs(source, options.disparity, "--disparity")
    semantic_files = _semantic_inputs(source, options.semantic)
    baseline_m = source.baseline_m("--disparity") if disparity_files else None
    trajectory = _trajectory_input(source, options.trajectory) if options.trajectory is not None else None
    report = {"dataset": str(dataset), "frames": len(source.records)}
    if depth_files:
        report["depth"] = evaluate_depth(source, depth_files, options)
    if disparity_files:
        report["disparity"] = evaluate_disparity(source, disparity_files, baseline_m)
    if semantic_files:
        report["semantic"] = evaluate_semantic(source, semantic_files)
    if trajectory is not None:
        report["trajectory"] = evaluate_trajectory(source, *trajectory, options)
    return report


def _map_inputs(source: DatasetSource, folder: Path | None, option: str) -> list[Path]:
    """The per-frame prediction files of ``folder`` (none without it), scored against the depth maps."""
    if folder is None:
        return []
    source.require_depth(option)
    return map_files(folder, len(source.records), option)


def _semantic_inputs(source: DatasetSource, folder: Path | None) -> list[Path]:
    """The predicted class image (PNG) of each frame in ``folder`` (none without it), scored against the dataset's
    left class images, which are checked first."""
    if folder is None:
        return []
    source.require(("semantic",), "--semantic")
    return map_files(folder, len(source.records), "--semantic", (".png",))


def _trajectory_input(source: DatasetSource, path: Path) -> tuple[Path, TrajectoryFile, list[int]]:
    """The trajectory file read and each of its poses' frame."""
    estimate = read_trajectory(path)
    frame_times_s = np.array([float(record["time_s"]) for record in source.records])
    indices = match_times(estimate, path, frame_times_on_clock_of(estimate, source, frame_times_s))
    if len(indices) < MIN_POSES:
        raise BadInput(f"{path}: {len(indices)} poses match the dataset's frames; at least {MIN_POSES} are needed")
    return path, estimate, indices


def frame_times_on_clock_of(estimate: TrajectoryFile, source: DatasetSource, frame_times_s: np.ndarray) -> np.ndarray:
    """The frames' times (s) on the clock of a TUM ``estimate``: the dataset's (``times.txt``, ``frame_times_s``), or
    Unix seconds as the ``tum`` export writes them (frame 0 at the dataset's
    :meth:`~sim.dataset.source.DatasetSource.start_unix_ns`) when the file's first time is nearer that clock."""
    if estimate.times_s is None or not len(estimate.times_s):
        return frame_times_s
    try:
        start_s = source.start_unix_ns("a TUM trajectory") / 1e9
    except DatasetError:  # a dataset whose Unix time cannot be written: the export refused it too
        return frame_times_s
    first = estimate.times_s[0]
    return frame_times_s + start_s if abs(first - start_s - frame_times_s[0]) < abs(first - frame_times_s[0]) \
        else frame_times_s


def evaluate_depth(source: DatasetSource, files: list[Path], options: EvaluateOptions) -> dict:
    """Eigen metrics of each frame's left depth prediction (``files``, one per frame) and their mean."""
    frames = []
    for frame, path in zip(source.frames(), files):
        truth = frame.depth(LEFT)
        score = depth_metrics.score_depth(read_map(path, truth.shape), truth, options.median_scaling,
                                          options.min_depth_m, options.max_depth_m)
        if score is None:
            raise BadInput(f"{path}: no pixel has both a valid prediction and a ground-truth depth in "
                           f"({options.min_depth_m:g}, {options.max_depth_m:g}) m")
        frames.append({"frame": frame.index, **score.metrics, "scale": score.scale, "pixels": score.pixels,
                       "density": score.density})
    scales = np.array([frame["scale"] for frame in frames])
    mean = {key: float(np.mean([frame[key] for frame in frames])) for key in (*depth_metrics.METRICS, "density")}
    return {"predictions": str(options.depth), "median_scaling": options.median_scaling,
            "min_depth_m": options.min_depth_m, "max_depth_m": options.max_depth_m, "mean": mean,
            "scale_median": float(np.median(scales)), "scale_std": float(np.std(scales / np.median(scales))),
            "per_frame": frames}


def evaluate_disparity(source: DatasetSource, files: list[Path], baseline_m: float) -> dict:
    """EPE and D1 (all pixels, and those the right camera sees) of each frame's left disparity prediction, pooled
    over frames; ground truth ``fx * B / z`` from the left depth map."""
    scores, frames = [], []
    for frame, path in zip(source.frames(), files):
        depth_left = frame.depth(LEFT)
        truth = disparity_from_depth(depth_left, frame.camera(LEFT)["fx"], baseline_m)
        noc = visible_in_right(depth_left, frame.depth(RIGHT), truth)
        try:
            score = disparity_metrics.score_disparity(read_map(path, truth.shape), truth, noc)
        except ValueError as error:
            raise BadInput(f"{path}: {error}") from None
        scores.append(score)
        frames.append({"frame": frame.index, **score.as_dict()})
    return {"predictions": str(files[0].parent), "baseline_m": baseline_m,
            "pooled": disparity_metrics.pooled(scores), "per_frame": frames}


def evaluate_semantic(source: DatasetSource, files: list[Path]) -> dict:
    """IoU per class and group, mIoU and pixel accuracy of each frame's left class image prediction (``files``, one
    per frame), pooled over frames (:mod:`sim.evaluation.semantic`), and per frame."""
    pooled = np.zeros((semantic_metrics.CLASS_COUNT,) * 2, dtype=np.int64)
    frames = []
    for frame, path in zip(source.frames(), files):
        truth = frame.semantic(LEFT)
        matrix = semantic_metrics.confusion(truth, read_class_image(path, truth.shape))
        pooled += matrix
        score = semantic_metrics.scores(matrix)
        frames.append({"frame": frame.index, **{key: score[key] for key in ("pixels", "pixel_accuracy", "miou")}})
    if not pooled.any():
        raise BadInput(f"{source.layout.semantic_dir(LEFT)}: every pixel of the truth is unknown; nothing to score")
    return {"predictions": str(files[0].parent), **semantic_metrics.scores(pooled), "per_frame": frames}


def evaluate_trajectory(source: DatasetSource, path: Path, estimate: TrajectoryFile, indices: list[int],
                        options: EvaluateOptions) -> dict:
    """ATE, RPE and KITTI drift of a TUM or KITTI trajectory of the left camera (pose ``i`` of frame
    ``indices[i]``). A KITTI file is compared with the dataset's KITTI poses (relative to frame 0), a TUM file
    with the left camera's ENU poses."""
    truth = [frame.T_world_cam(LEFT) for frame in source.frames()]
    if estimate.kind == "kitti":
        truth = relative_poses(truth)
    truth = [truth[index] for index in indices]
    times = [float(source.records[index]["time_s"]) for index in indices]
    return {"predictions": str(path), "format": estimate.kind, "poses": len(indices),
            "alignment": options.alignment,
            **trajectory_metrics.ate_rpe(truth, estimate.poses, times, options.alignment),
            "kitti_drift": trajectory_metrics.kitti_drift(truth, estimate.poses, options.drift_lengths_m)}


def _row(values, width: int = 10) -> str:
    return " ".join(f"{value:>{width}}" if isinstance(value, str) else f"{value:>{width}.4f}" for value in values)


def report_table(report: dict) -> str:
    """The report as plain text: one block per scored prediction."""
    lines = [f"dataset {report['dataset']}: {report['frames']} frames"]
    if "depth" in report:
        depth = report["depth"]
        scaling = (f"median scaling (ratio median {depth['scale_median']:.3f}, std {depth['scale_std']:.3f})"
                   if depth["median_scaling"] else "no scaling")
        lines += ["", f"depth {depth['predictions']}: mean of {len(depth['per_frame'])} frames, {scaling}, "
                      f"{100 * depth['mean']['density']:.1f} % of ground-truth pixels predicted",
                  _row(depth_metrics.METRICS), _row(depth["mean"][key] for key in depth_metrics.METRICS)]
    if "disparity" in report:
        pooled = report["disparity"]["pooled"]
        lines += ["", f"disparity {report['disparity']['predictions']}: {len(report['disparity']['per_frame'])} "
                      f"frames pooled, {100 * pooled['density']:.1f} % of ground-truth pixels predicted "
                      "(holes filled as the KITTI devkit does)",
                  _row(("EPE px", "D1-all %", "EPE-noc px", "D1-noc %")),
                  _row((pooled["epe"], 100 * pooled["d1_all"], pooled["epe_noc"], 100 * pooled["d1_noc"]))]
    if "semantic" in report:
        lines += ["", *_semantic_lines(report["semantic"])]
    if "trajectory" in report:
        lines += ["", *_trajectory_lines(report["trajectory"])]
    return "\n".join(lines)


def _semantic_lines(semantic: dict) -> list[str]:
    """mIoU and pixel accuracy, then IoU and pixel counts of each class the truth or prediction has, then groups."""
    lines = [f"semantic {semantic['predictions']}: {len(semantic['per_frame'])} frames pooled, "
             f"{semantic['pixels']} pixels scored (the truth's unknown pixels are not)",
             _row(("mIoU", "pixel acc")), _row((semantic["miou"], semantic["pixel_accuracy"])),
             _row(("class", "IoU", "truth px", "predicted px"), 12)]
    for name, values in semantic["classes"].items():
        if values["truth_pixels"] or values["predicted_pixels"]:
            lines.append(_row((name, values["iou"], str(values["truth_pixels"]), str(values["predicted_pixels"])), 12))
    lines.append(_row(("group", "IoU"), 12) + "  classes")
    for name, values in semantic["groups"].items():
        lines.append(_row((name, values["iou"]), 12) + "  " + ", ".join(values["classes"]))
    return lines


def _trajectory_lines(trajectory: dict) -> list[str]:
    lines = [f"trajectory {trajectory['predictions']} ({trajectory['format']}): {trajectory['poses']} poses, "
             f"{trajectory['alignment']} alignment (scale {trajectory['alignment_scale']:.4f})",
             _row(("ATE rmse m", "ATE mean m", "ATE max m", "RPE m", "RPE deg"), 11),
             _row((trajectory[key] for key in ("ate_rmse_m", "ate_mean_m", "ate_max_m", "rpe_trans_rmse_m",
                                               "rpe_rot_rmse_deg")), 11),
             "KITTI drift " + _row(("length m", "segments", "t_err %", "r_err deg/100m"), 14)]
    drift = trajectory["kitti_drift"]
    for length, values in [*drift["per_length"].items(), ("all", drift)]:
        label = length if isinstance(length, str) else f"{length:g}"
        lines.append(" " * 12 + _row((label, str(values["segments"]), values["t_err_percent"],
                                      values["r_err_deg_per_100m"]), 14))
    return lines
