"""``aerostereo-render evaluate`` end to end on a small analytic dataset: predictions in the formats users write
(and the formats our own exports write) score 0 / 1 when they are the truth and the analytic values when scaled or
moved; everything it cannot score is refused with one line, exit code 2 and no JSON."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dataset_helpers import BASELINE_M, CAMERA, ORIGIN, looking_down_pose, render_plane_view, rig_transforms, spec
from sim.cli import main as cli_main
from sim.dataset import DatasetSpec, FrameRecord, KittiDatasetWriter, finalize_dataset
from sim.dataset import images
from sim.dataset.export import export_dataset
from sim.render.shade import Sun

FRAMES = 4
PROG = "aerostereo-render evaluate: error: "


def turning_pose(index: int) -> np.ndarray:
    """The helpers' downward-looking pose, moved around a circle so the positions span a plane (ATE aligns)."""
    T = looking_down_pose(index)
    T[:3, 3] += (10.0 * np.cos(index), 10.0 * np.sin(index), 0.0)
    return T


def record(index: int) -> FrameRecord:
    T_world_left = turning_pose(index)
    views = [render_plane_view(CAMERA, T_world_left @ T) for T in rig_transforms()]
    return FrameRecord(index=index, views=views, T_world_cam=T_world_left, time_s=0.1 * index, seed=7,
                       sun=Sun(120.0, 45.0, 7.5))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("evaluate") / "dataset"
    writer = KittiDatasetWriter(root, spec(FRAMES))
    for index in range(FRAMES):
        writer.write_frame(record(index))
    finalize_dataset(root)
    return root


def truth_depth(index: int) -> np.ndarray:
    return record(index).views[0].depth


def truth_disparity(index: int) -> np.ndarray:
    return images.disparity_from_depth(truth_depth(index), CAMERA.fx, BASELINE_M)


def write_maps(folder: Path, maps, suffix: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for index, values in enumerate(maps):
        path = folder / f"{index:06d}{suffix}"
        if suffix == ".npy":
            np.save(path, values)
        elif suffix == ".exr":
            images.write_exr(path, values)
        else:
            cv2.imwrite(str(path), values)
    return folder


def evaluate(dataset: Path, tmp_path: Path, *arguments: str) -> dict:
    report = tmp_path / "report.json"
    assert cli_main(["evaluate", str(dataset), *arguments, "--json", str(report)]) == 0
    return json.loads(report.read_text())  # strict JSON: NaN and infinity are written as null


def refused(capsys, arguments: list[str]) -> str:
    assert cli_main(["evaluate", *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and error.startswith(PROG), error
    return error[len(PROG):]


def test_the_truth_as_npy_and_exr_scores_zero_error(dataset, tmp_path, capsys):
    depth = write_maps(tmp_path / "depth", [truth_depth(i) for i in range(FRAMES)], ".npy")
    disparity = write_maps(tmp_path / "disp", [truth_disparity(i) for i in range(FRAMES)], ".exr")
    report = evaluate(dataset, tmp_path, "--depth", str(depth), "--disparity", str(disparity))
    assert report["depth"]["mean"] == {"abs_rel": 0.0, "sq_rel": 0.0, "rmse": 0.0, "rmse_log": 0.0, "a1": 1.0,
                                       "a2": 1.0, "a3": 1.0, "density": 1.0}
    assert len(report["depth"]["per_frame"]) == FRAMES and report["depth"]["max_depth_m"] is None
    pooled = report["disparity"]["pooled"]
    assert (pooled["epe"], pooled["d1_all"], pooled["density"]) == (0.0, 0.0, 1.0)
    table = capsys.readouterr().out
    assert "abs_rel" in table and "D1-all %" in table


def test_kitti_png_predictions_from_our_kitti2015_export_score_within_the_format_resolution(dataset, tmp_path):
    export_dataset(dataset, tmp_path / "export", ["kitti2015"])  # disp_occ_0/000000_10.png: KITTI's disparity PNG
    depth_png = [images.kitti_depth_png(truth_depth(i)) for i in range(FRAMES)]
    depth = write_maps(tmp_path / "depth", depth_png, ".png")
    report = evaluate(dataset, tmp_path, "--disparity", str(tmp_path / "export/training/disp_occ_0"),
                      "--depth", str(depth))
    assert report["disparity"]["pooled"]["epe"] <= 0.5 / 256 and report["disparity"]["pooled"]["d1_all"] == 0.0
    assert report["depth"]["mean"]["rmse"] <= 0.5 / 256 and report["depth"]["mean"]["a1"] == 1.0


def test_a_scaled_depth_prediction_scores_its_error_and_median_scaling_removes_it(dataset, tmp_path):
    depth = write_maps(tmp_path / "depth", [2.0 * truth_depth(i) for i in range(FRAMES)], ".exr")
    assert evaluate(dataset, tmp_path, "--depth", str(depth))["depth"]["mean"]["abs_rel"] == pytest.approx(1.0)
    scaled = evaluate(dataset, tmp_path, "--depth", str(depth), "--median-scaling")["depth"]
    assert scaled["scale_median"] == pytest.approx(0.5) and scaled["mean"]["abs_rel"] == pytest.approx(0, abs=1e-6)


def test_our_kitti_poses_and_tum_export_score_zero_and_a_moved_trajectory_its_offset(dataset, tmp_path):
    export_dataset(dataset, tmp_path / "export", ["tum"])
    for path in (dataset / "poses/00.txt", tmp_path / "export/tum/00.txt"):
        trajectory = evaluate(dataset, tmp_path, "--trajectory", str(path))["trajectory"]
        assert trajectory["poses"] == FRAMES and trajectory["ate_rmse_m"] == pytest.approx(0.0, abs=1e-6)
    rotation = Rotation.from_euler("z", 30, degrees=True)
    moved = tmp_path / "moved.txt"  # the TUM export in another world frame: turned 30 deg and shifted 3 m
    lines = []
    for line in (tmp_path / "export/tum/00.txt").read_text().splitlines()[1:]:
        t, *values = map(float, line.split())
        position = rotation.apply(values[:3]) + (0.0, 0.0, 3.0)
        quaternion = (rotation * Rotation.from_quat(values[3:])).as_quat()
        lines.append(" ".join(map(str, [t, *position, *quaternion])))
    moved.write_text("\n".join(lines) + "\n")
    assert evaluate(dataset, tmp_path, "--trajectory", str(moved))["trajectory"]["ate_rmse_m"] == \
        pytest.approx(0.0, abs=1e-6)
    offset = tmp_path / "offset.txt"
    offset.write_text("\n".join(f"{0.1 * i} {3 * np.cos(i)} {4 + 3 * np.sin(i)} {i} 0 0 0 1" for i in range(FRAMES)))
    result = evaluate(dataset, tmp_path, "--trajectory", str(offset), "--align", "none")["trajectory"]
    positions = np.array([turning_pose(i)[:3, 3] for i in range(FRAMES)])
    expected = np.array([[3 * np.cos(i), 4 + 3 * np.sin(i), i] for i in range(FRAMES)]) - positions
    assert result["ate_rmse_m"] == pytest.approx(np.sqrt(np.mean(np.sum(expected ** 2, axis=1))))


@pytest.mark.parametrize("case, expected", [
    ("missing", "no prediction of 1 of the dataset's 4 frames (000003)"),
    ("extra", "the dataset has no frame 7"),
    ("badname", "not named like a frame"),
    ("twice", "a second prediction of frame 0"),
    ("size", "32x48 pixels, but the dataset's frames are 64x48"),
    ("8bit", "expected a 16-bit single-channel PNG"),
    ("garbage", "not a readable .npy prediction"),
])
def test_prediction_folders_that_do_not_fit_are_refused(dataset, tmp_path, capsys, case, expected):
    folder = write_maps(tmp_path / "pred", [truth_depth(i) for i in range(FRAMES)], ".npy")
    if case == "missing":
        (folder / "000003.npy").unlink()
    elif case == "extra":
        np.save(folder / "000007.npy", truth_depth(0))
    elif case == "badname":
        np.save(folder / "depth_0.npy", truth_depth(0))
    elif case == "twice":
        images.write_exr(folder / "000000.exr", truth_depth(0))
    elif case == "size":
        np.save(folder / "000002.npy", truth_depth(2)[:, :32])
    elif case == "8bit":
        (folder / "000001.npy").unlink()
        cv2.imwrite(str(folder / "000001.png"), np.zeros((48, 64), np.uint8))
    elif case == "garbage":
        (folder / "000001.npy").write_bytes(b"not numpy")
    report = tmp_path / "report.json"
    assert expected in refused(capsys, [str(dataset), "--depth", str(folder), "--json", str(report)])
    assert not report.exists()


@pytest.mark.parametrize("text, expected", [
    ("0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0\n", "line 2 has 7 numbers"),
    ("# header\n0 0 0 0 0 0 0 2\n", "line 2: quaternion of norm 2"),
    ("0 0 0 0 0 0 0 1\n0.25 0 0 0 0 0 0 1\n", "line 2: time 0.25 s is no frame's time"),
    ("0.1 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n", "line 2: time 0 s does not follow 0.1 s"),
    ("1 0 0 0 0 1 0 0 0 0 1 0\n" * 3, "3 KITTI poses, but the dataset has 4 frames"),
    ("2 0 0 0 0 1 0 0 0 0 1 0\n" * 4, "line 1: the 3x3 block is not a rotation matrix"),
    ("0 0 0 0 0 0 0 1\n0.1 0 0 x 0 0 0 1\n", "line 2 is not a row of numbers"),
    ("0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n", "2 poses match the dataset's frames; at least 3"),
])
def test_trajectory_files_that_do_not_fit_are_refused_naming_the_line(dataset, tmp_path, capsys, text, expected):
    path = tmp_path / "trajectory.txt"
    path.write_text(text)
    assert expected in refused(capsys, [str(dataset), "--trajectory", str(path)])


def test_nothing_to_score_a_json_that_names_an_input_and_a_dataset_without_depth_are_refused(dataset, tmp_path,
                                                                                           capsys):
    assert "nothing to score" in refused(capsys, [str(dataset)])
    poses = dataset / "poses/00.txt"
    before = poses.read_bytes()
    assert "--json" in refused(capsys, [str(dataset), "--trajectory", str(poses), "--json", str(poses)])
    assert poses.read_bytes() == before
    no_depth = tmp_path / "no_depth"
    writer = KittiDatasetWriter(no_depth, spec(1, formats=("disparity_png",)))
    writer.write_frame(record(0))
    finalize_dataset(no_depth)
    folder = write_maps(tmp_path / "pred", [truth_disparity(0)], ".npy")
    assert "depth_exr" in refused(capsys, [str(no_depth), "--disparity", str(folder)])


def test_disparity_of_a_pair_that_is_not_rectified_is_refused_before_any_frame_is_read(tmp_path, capsys):
    T_right = rig_transforms()[1].copy()
    T_right[1, 3] = 0.2  # the right camera also 0.2 m below the left: epipolar lines are no longer rows
    root = tmp_path / "dataset"
    writer = KittiDatasetWriter(root, DatasetSpec(cameras=[CAMERA] * 2, T_rig_cams=[np.eye(4), T_right],
                                                  origin=ORIGIN, frame_count=1, formats=("depth_exr",),
                                                  command_line=["test"]))
    writer.write_frame(record(0))
    finalize_dataset(root)
    folder = write_maps(tmp_path / "pred", [truth_disparity(0)], ".npy")
    assert "--disparity needs a rectified stereo pair" in refused(capsys, [str(root), "--disparity", str(folder)])
    report = evaluate(root, tmp_path, "--depth", str(write_maps(tmp_path / "depth", [truth_depth(0)], ".npy")))
    assert report["depth"]["mean"]["abs_rel"] == 0.0  # depth needs no rectified pair


def test_a_json_report_over_a_dataset_file_is_refused(dataset, tmp_path, capsys):
    times = dataset / "sequences/00/times.txt"
    before = times.read_bytes()
    message = refused(capsys, [str(dataset), "--trajectory", str(dataset / "poses/00.txt"), "--json", str(times)])
    assert "is also DATASET" in message and times.read_bytes() == before
