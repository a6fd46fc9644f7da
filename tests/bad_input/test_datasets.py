"""A rendered dataset damaged after the fact: the commands that read it (export, evaluate, compare) name the
damaged file in one line and exit 2."""

from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim.cli import main as render_main
from sim.dataset.images import write_exr
from tests.bad_input.harness import Case, assert_refused, run_case
from tests.sim.render_scene_helpers import write_scene


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """A 2-frame random-mode dataset of the analytic scene, with depth EXRs and a replay-like frames.jsonl."""
    root = tmp_path_factory.mktemp("dataset")
    scene = write_scene(root / "scene")
    out = root / "d"
    assert render_main(["--scene", str(scene), "--out", str(out), "--frames", "2", "--width", "32", "--height", "16",
                        "--formats", "depth_exr", "--quiet"]) == 0
    return out


def _copy(dataset: Path, tmp: Path) -> Path:
    copy = tmp / "d"
    for path in dataset.rglob("*"):
        if path.is_file():
            (copy / path.relative_to(dataset)).parent.mkdir(parents=True, exist_ok=True)
            (copy / path.relative_to(dataset)).write_bytes(path.read_bytes())
    return copy


def test_a_truncated_depth_exr_is_named_by_export(dataset, tmp_path):
    exr = _copy(dataset, tmp_path) / "sequences/00/depth_2/000001.exr"
    exr.write_bytes(exr.read_bytes()[:100])
    case = Case("export-truncated-depth-exr", "aerostereo-render",
                ["export", "{tmp}/d", "--layout", "kitti_depth", "--out", "{tmp}/e"],
                r"depth_2/000001\.exr: not a readable EXR")
    assert_refused(run_case(case, tmp_path), case, tmp_path)


@pytest.mark.parametrize("layout", ["kitti_flow", "kitti_depth", "flo"])
def test_a_depth_exr_of_another_size_is_named_by_export(dataset, tmp_path, layout):
    """A depth map of the wrong size (here the right camera's, frame 1) is refused from its header before any
    frame is exported (into an --out folder that was there, which a failed export keeps): the layouts that read it
    once indexed past its end (IndexError) or wrote garbage flow."""
    write_exr(_copy(dataset, tmp_path) / "sequences/00/depth_3/000001.exr", np.ones((8, 16), np.float32))
    case = Case(f"export-{layout}-depth-exr-of-another-size", "aerostereo-render",
                ["export", "{tmp}/d", "--layout", layout, "--out", "{tmp}/e"],
                r"depth_3/000001\.exr: a 16x8 depth map, expected 32x16 \(camera 1's image size\)",
                lambda tmp: (tmp / "e").mkdir())
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def _predictions(tmp: Path, first: bytes) -> None:
    """A --depth folder whose frame 0 holds the bytes ``first`` and frame 1 a valid 32x16 prediction."""
    folder = tmp / "pred"
    folder.mkdir()
    (folder / "000000.npy").write_bytes(first)
    (folder / "000001.npy").write_bytes(_npy(np.ones((16, 32))))


def _npy(array: np.ndarray) -> bytes:
    """The bytes ``numpy.save`` writes for ``array``."""
    file = io.BytesIO()
    np.save(file, array)
    return file.getvalue()


def _npz(**arrays: np.ndarray) -> bytes:
    """The bytes ``numpy.savez`` writes for the named ``arrays``."""
    file = io.BytesIO()
    np.savez(file, **arrays)
    return file.getvalue()


@pytest.mark.parametrize("name, first, message", [
    ("empty-npy", b"", r"pred/000000\.npy: not a readable \.npy prediction \(No data left in file\)"),
    ("npz-named-npy", _npz(depth=np.ones((16, 32))),
     r"pred/000000\.npy: an \.npz archive, expected one array saved by numpy\.save"),
], ids=["empty-npy", "npz-named-npy"])
def test_a_damaged_npy_prediction_is_named_by_evaluate(dataset, tmp_path, name, first, message):
    _copy(dataset, tmp_path)
    case = Case(f"evaluate-{name}", "aerostereo-render", ["evaluate", "{tmp}/d", "--depth", "{tmp}/pred"], message,
                lambda tmp: _predictions(tmp, first))
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_truth_depth_of_another_size_is_named_by_evaluate(dataset, tmp_path):
    write_exr(_copy(dataset, tmp_path) / "sequences/00/depth_2/000000.exr", np.ones((16, 33), np.float32))
    case = Case("evaluate-truth-depth-of-another-size", "aerostereo-render",
                ["evaluate", "{tmp}/d", "--depth", "{tmp}/pred"],
                r"depth_2/000000\.exr: a 33x16 depth map, expected 32x16",
                lambda tmp: _predictions(tmp, _npy(np.ones((16, 32)))))
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_damaged_frames_record_is_named_by_compare(dataset, tmp_path):
    copy = _copy(dataset, tmp_path)
    replay, photos = copy / "sequences/00/replay_2", tmp_path / "photos"
    for folder in (replay, photos):
        folder.mkdir()
        cv2.imwrite(str(folder / "DJI_0001.png"), np.zeros((8, 8, 3), np.uint8))
    (copy / "sequences/00/frames.jsonl").write_text("garbage\n")
    case = Case("compare-damaged-frames-jsonl", "aerostereo-render",
                ["compare", "{tmp}/photos", "{tmp}/d/sequences/00/replay_2"],
                r"frames\.jsonl: line 1 is not JSON")
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_failed_decode_keeps_the_output_that_was_there(tmp_path):
    """A capture with no DUML frame is refused, and the --out the user already had is left as it was."""
    (tmp_path / "junk.duml").write_bytes(bytes(range(256)) * 20)
    (tmp_path / "telemetry.csv").write_text("the user's\n")
    case = Case("decode-junk-keeps-output", "aerostereo-ingest",
                ["decode", "{tmp}/junk.duml", "--out", "{tmp}/telemetry.csv"], r"junk\.duml: no DUML frame found")
    assert_refused(run_case(case, tmp_path), case, tmp_path)
    assert (tmp_path / "telemetry.csv").read_text() == "the user's\n"


def test_an_export_folder_in_the_scene_is_refused(tmp_path):
    scene = write_scene(tmp_path / "scene")
    case = Case("render-export-out-is-the-scene", "aerostereo-render",
                ["--scene", str(scene), "--out", "{tmp}/d", "--export", "tum", "--export-out", str(scene)],
                r"--export-out .*scene: is also --scene")
    assert_refused(run_case(case, tmp_path), case, tmp_path)


@pytest.mark.parametrize("layout, options, message", [
    ("euroc", [], r"--export euroc needs an IMU; render the dataset with --mode trajectory --imu"),
    ("kitti2015", ["--formats", "disparity_png"], r"--export kitti2015 needs the depth maps"),
    ("kitti_flow", ["--formats", "depth_cm_png"], r"--export kitti_flow needs the depth maps"),
])
def test_a_layout_the_render_cannot_feed_is_refused_before_the_first_frame(tmp_path, layout, options, message):
    """render --export checks what each layout needs against the dataset it is about to make: refused before any
    frame is rendered (not after the last), and nothing is left behind."""
    scene = write_scene(tmp_path / "scene")
    case = Case(f"render-export-{layout}-unfed", "aerostereo-render",
                ["--scene", str(scene), "--out", "{tmp}/d", "--frames", "2", "--width", "32", "--height", "16",
                 *options, "--export", layout, "--export-out", "{tmp}/e", "--quiet"], message)
    assert_refused(run_case(case, tmp_path), case, tmp_path)
    assert not (tmp_path / "d").exists() and not (tmp_path / "e").exists()


@pytest.fixture(scope="module")
def imu_dataset(tmp_path_factory) -> Path:
    """A 2-frame trajectory of the demo world rendered with --imu at 100 Hz: an IMU record of 11 samples."""
    out = tmp_path_factory.mktemp("imu") / "d"
    assert render_main(["--scene", "demo:small", "--out", str(out), "--mode", "trajectory", "--imu", "--imu-rate",
                        "100", "--frames", "2", "--width", "32", "--height", "16", "--formats", "depth_exr",
                        "--quiet"]) == 0
    return out


@pytest.mark.parametrize("name, line, column, value, message", [
    ("gyro-nan", 3, "w_x", "nan", r"imu/00\.csv:3: w_x nan is not a finite number within \+-100 rad/s"),
    ("accel-inf", 5, "a_true_z", "inf", r"imu/00\.csv:5: a_true_z inf is not a finite number within \+-1000 m/s\^2"),
    ("accel-1e308", 4, "a_y", "1e308", r"imu/00\.csv:4: a_y 1e\+308 is not a finite number within \+-1000"),
    ("position-far", 2, "p_x", "-2e6", r"imu/00\.csv:2: p_x -2e\+06 is not a finite number within \+-1e\+06 m"),
    ("quaternion-component-3", 6, "q_w", "3", r"imu/00\.csv:6: q_w 3 is not a finite number within \+-1"),
    ("quaternion-not-unit", 9, "q_w", "0.5",
     r"imu/00\.csv:9: q_w,q_x,q_y,q_z is not a unit quaternion \(norm [\d.]+\)"),
    ("time-backwards", 7, "timestamp_ns", "0", r"imu/00\.csv:7: timestamp_ns 0 is not after the previous line's"),
    ("time-fraction", 8, "timestamp_ns", "60000000.5", r"imu/00\.csv:8: timestamp_ns 60000000.5 is not whole"),
])
def test_an_implausible_imu_sample_is_named_by_the_euroc_export(imu_dataset, tmp_path, name, line, column, value,
                                                                message):
    """An IMU record whose sample is not finite or beyond what a flying rig can measure is refused with its file,
    line and column before anything is written, never copied into EuRoC's imu0/data.csv."""
    record = _copy(imu_dataset, tmp_path) / "imu" / "00.csv"
    lines = record.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[line - 1].split(",")
    cells[header.index(column)] = value
    lines[line - 1] = ",".join(cells)
    record.write_text("\n".join(lines) + "\n")
    case = Case(f"export-euroc-imu-{name}", "aerostereo-render",
                ["export", "{tmp}/d", "--layout", "euroc", "--out", "{tmp}/e"], message)
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_the_untouched_imu_record_exports(imu_dataset, tmp_path):
    """The bounds refuse only what no rig measures: the record as rendered exports, sample for sample."""
    _copy(imu_dataset, tmp_path)
    case = Case("export-euroc-imu", "aerostereo-render", ["export", "{tmp}/d", "--layout", "euroc", "--out",
                                                          "{tmp}/e"], "")
    assert run_case(case, tmp_path).code == 0
    assert len((tmp_path / "e/mav0/imu0/data.csv").read_text().splitlines()) == 1 + 11
