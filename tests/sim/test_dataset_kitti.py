"""The KITTI-layout writer against a real client (pykitti) and against first-principles projections."""

from __future__ import annotations

import errno
import json
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import OpenEXR
import pykitti
import pytest

from dataset_helpers import BASELINE_M, CAMERA, ORIGIN, frame_record, looking_down_pose, spec
from tests.bad_input.harness import small_disk
from sim.dataset import FORMATS as ALL_FORMATS
from sim.dataset import AsyncFrameWriter, DatasetError, DatasetSpec, KittiDatasetWriter, finalize_dataset, shard_frames
from sim.dataset.images import read_exr, read_png, write_exr
from sim.dataset.writer import dataset_description

FRAMES = 4


def write_dataset(root: Path, frames=range(FRAMES), frame_count=FRAMES, camera_count=2, finalize=True, **kwargs):
    writer = KittiDatasetWriter(root, spec(frame_count, camera_count, **kwargs))
    for index in frames:
        writer.write_frame(frame_record(index, camera_count))
    if finalize:
        finalize_dataset(root)
    return writer


def tree_bytes(root: Path) -> dict[str, bytes]:
    return {str(path.relative_to(root)): path.read_bytes() for path in sorted(root.rglob("*")) if path.is_file()}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("kitti")
    write_dataset(root, formats=ALL_FORMATS)
    return root


def pinhole_pixel(T_world_cam: np.ndarray, point_world: np.ndarray) -> np.ndarray:
    """u = fx x / z + cx, v = fy y / z + cy with x = R^T (X - t): the definition, nothing borrowed."""
    x, y, z = T_world_cam[:3, :3].T @ (point_world - T_world_cam[:3, 3])
    return np.array([CAMERA.fx * x / z + CAMERA.cx, CAMERA.fy * y / z + CAMERA.cy])


def test_pykitti_loads_images_calibration_and_poses(dataset):
    odometry = pykitti.odometry(str(dataset), "00")
    assert len(odometry) == FRAMES and len(odometry.poses) == FRAMES
    assert odometry.calib.b_rgb == pytest.approx(BASELINE_M, abs=1e-12)
    assert odometry.calib.b_gray == pytest.approx(BASELINE_M, abs=1e-12)
    np.testing.assert_allclose(odometry.calib.K_cam2, [[50.0, 0, 31.5], [0, 52.0, 23.25], [0, 0, 1]])
    expected = frame_record(2)
    np.testing.assert_array_equal(np.asarray(odometry.get_cam2(2)), expected.views[0].rgb)
    np.testing.assert_array_equal(np.asarray(odometry.get_cam3(2)), expected.views[1].rgb)
    assert np.asarray(odometry.get_cam0(2)).shape == (CAMERA.height, CAMERA.width)
    np.testing.assert_allclose(odometry.poses[0], np.eye(4), atol=1e-12)


@pytest.mark.parametrize("index", range(FRAMES))
def test_world_point_projects_through_pykitti_where_the_pinhole_puts_it(dataset, index):
    odometry = pykitti.odometry(str(dataset), "00")
    T_world_left = looking_down_pose(index)
    T_world_right = T_world_left.copy()
    T_world_right[:3, 3] += T_world_left[:3, :3] @ [BASELINE_M, 0.0, 0.0]
    point_world = T_world_left[:3, 3] + 25.0 * T_world_left[:3, :3] @ [0.1, -0.05, 1.0]
    point_first_camera = np.linalg.inv(looking_down_pose(0)) @ np.append(point_world, 1.0)
    point_camera = np.linalg.inv(odometry.poses[index]) @ point_first_camera
    for P, T_world_cam in ((odometry.calib.P_rect_20, T_world_left), (odometry.calib.P_rect_30, T_world_right),
                           (odometry.calib.P_rect_00, T_world_left)):
        projected = P @ point_camera
        assert np.abs(projected[:2] / projected[2] - pinhole_pixel(T_world_cam, point_world)).max() < 0.5e-3


def test_depth_exr_is_lossless_float32_channel_y_zip(dataset):
    path = dataset / "sequences/00/depth_2/000001.exr"
    with OpenEXR.File(str(path)) as exr:
        header = exr.header()
        assert [channel.name for channel in header["channels"]] == ["Y"]
        assert header["compression"] == OpenEXR.ZIP_COMPRESSION
        pixels = exr.channels()["Y"].pixels
    assert pixels.dtype == np.float32
    expected = frame_record(1).views[0].depth
    assert np.isinf(expected).any() and np.isfinite(expected).any()
    np.testing.assert_array_equal(pixels, expected)


def test_disparity_is_fx_baseline_over_depth_and_links_left_and_right_depth(dataset):
    sequence = dataset / "sequences/00"
    depth_left = read_exr(sequence / "depth_2/000001.exr")
    depth_right = read_exr(sequence / "depth_3/000001.exr")
    disparity = read_exr(sequence / "disp_2/000001.exr")
    disparity_png = read_png(sequence / "disp_2/000001.png")
    valid = np.isfinite(depth_left)
    np.testing.assert_allclose(disparity[valid], CAMERA.fx * BASELINE_M / depth_left[valid], rtol=1e-6)
    assert np.all(disparity[~valid] == 0) and np.all(disparity_png[~valid] == 0)
    assert disparity_png.dtype == np.uint16
    scaled = np.rint(disparity[valid].astype(np.float64) * 256)
    assert (scaled == 0).any(), "the far ground should include disparities below 1/512 px"
    np.testing.assert_array_equal(disparity_png[valid], np.maximum(scaled, 1))  # valid never reads as invalid
    # The ground point seen at left pixel (u, v) is seen at (u - d, v) in the right image, at the same planar depth.
    rows, cols = np.nonzero(valid)
    right_u = cols - disparity[rows, cols]
    inside = (right_u >= 0) & (right_u <= CAMERA.width - 2)
    rows, right_u, depth = rows[inside], right_u[inside], depth_left[rows[inside], cols[inside]]
    left_col = np.floor(right_u).astype(int)
    weight = right_u - left_col
    right_depth = (1 - weight) * depth_right[rows, left_col] + weight * depth_right[rows, left_col + 1]
    finite = np.isfinite(right_depth) & (depth < 1000.0)  # near the horizon z is too curved to interpolate
    assert finite.sum() > 500
    np.testing.assert_allclose(right_depth[finite], depth[finite], rtol=2e-3)


def test_vkitti_depth_png_is_centimetres(dataset):
    depth_cm = read_png(dataset / "sequences/00/depth_cm_2/000000.png")
    depth = frame_record(0).views[0].depth
    finite = np.isfinite(depth)
    centimetres = np.rint(depth[finite].astype(np.float64) * 100)
    assert (centimetres > 65535).any() and (centimetres < 65535).any()
    np.testing.assert_array_equal(depth_cm[finite], np.minimum(centimetres, 65535))
    assert np.all(depth_cm[~finite] == 65535)


def test_calib_txt_has_kitti_form(dataset):
    lines = (dataset / "sequences/00/calib.txt").read_text().split("\n")
    assert lines[-1] == "" and "" not in lines[:-1]
    keys = [line.split(":")[0] for line in lines[:-1]]
    assert keys == ["P0", "P1", "P2", "P3", "Tr"]
    matrices = {key: np.array(line.split(":")[1].split(), dtype=float) for key, line in zip(keys, lines)}
    assert all(len(values) == 12 for values in matrices.values())
    np.testing.assert_array_equal(matrices["P0"], matrices["P2"])
    np.testing.assert_array_equal(matrices["P1"], matrices["P3"])
    assert matrices["P3"][3] == pytest.approx(-CAMERA.fx * BASELINE_M)
    np.testing.assert_array_equal(matrices["Tr"], np.eye(4)[:3].ravel())
    assert lines[0].split()[1] == "5.000000000000e+01"


def test_frames_jsonl_and_poses_describe_the_same_cameras(dataset):
    records = [json.loads(line) for line in (dataset / "sequences/00/frames.jsonl").read_text().splitlines()]
    poses = np.loadtxt(dataset / "poses/00.txt").reshape(-1, 3, 4)
    assert [record["frame"] for record in records] == list(range(FRAMES)) and len(poses) == FRAMES
    T_first = np.array(records[0]["T_world_cam"])
    for record, pose in zip(records, poses):
        T_world_cam = np.array(record["T_world_cam"])
        np.testing.assert_allclose(T_world_cam, looking_down_pose(record["frame"]), atol=1e-12)
        np.testing.assert_allclose(T_first[:3, :3] @ pose[:, :3], T_world_cam[:3, :3], atol=1e-9)
        np.testing.assert_allclose(T_first[:3, :3] @ pose[:, 3] + T_first[:3, 3], T_world_cam[:3, 3], atol=1e-9)
        geodetic = record["geodetic"]
        enu = ORIGIN.to_enu(geodetic["lat_deg"], geodetic["lon_deg"], geodetic["h_ellipsoid_m"])
        np.testing.assert_allclose(np.ravel(enu), T_world_cam[:3, 3], atol=1e-6)
        assert record["sun"] == {"azimuth_deg": 120.0 + record["frame"], "elevation_deg": 45.0, "intensity": 7.5}
    times = np.loadtxt(dataset / "sequences/00/times.txt")
    np.testing.assert_allclose(times, [0.1 * i for i in range(FRAMES)], rtol=1e-9)
    description = json.loads((dataset / "dataset.json").read_text())
    assert description["baseline_m"] == BASELINE_M and description["depth"]["kind"] == "planar_z"


def test_rerun_after_interrupted_frame_completes_to_identical_bytes(dataset, tmp_path):
    write_dataset(tmp_path, formats=ALL_FORMATS)
    sequence = tmp_path / "sequences/00"
    # What a kill during frame 2 leaves: record not yet written, one file absent, temp files half written.
    (sequence / "frame_meta/000002.json").unlink()
    (sequence / "disp_3/000002.exr").unlink()
    (sequence / "disp_3/.000002.exr.999-1.tmp.exr").write_bytes(b"half an EXR")
    (sequence / "image_2/.000002.png.999-2.tmp.png").write_bytes(b"\x89PNG half")
    (sequence / "frames.jsonl").unlink()
    with pytest.raises(DatasetError, match="1 of 4 frames are incomplete \\(first: 2\\)"):
        finalize_dataset(tmp_path)
    writer = KittiDatasetWriter(tmp_path, spec(FRAMES, formats=ALL_FORMATS))
    assert writer.pending(range(FRAMES)) == [2]
    writer.write_frame(frame_record(2))
    finalize_dataset(tmp_path)
    assert tree_bytes(tmp_path) == tree_bytes(dataset)
    assert not list(tmp_path.rglob(".*.tmp*"))


KILLED_WRITER = """
import os, signal, sys
sys.path[:0] = sys.argv[1:3]
import cliutil.atomic as atomic
from dataset_helpers import frame_record, spec
from sim.dataset import FORMATS, KittiDatasetWriter

renames = 0
rename = atomic.os.replace


def rename_or_die(source, target):
    global renames
    renames += 1
    if renames == int(sys.argv[4]):  # the temporary file is written, the rename never happens
        os.kill(os.getpid(), signal.SIGKILL)
    rename(source, target)


atomic.os.replace = rename_or_die
writer = KittiDatasetWriter(sys.argv[3], spec(4, formats=FORMATS))
for index in range(4):
    writer.write_frame(frame_record(index))
"""


def test_rerun_after_a_writer_killed_mid_frame_completes_to_identical_bytes(dataset, tmp_path):
    files_per_frame = 2 * len(ALL_FORMATS) + 2 * 2 + 1  # per view: formats, colour, grey; then the record
    kill_at = 2 + 2 * files_per_frame + 5  # dataset.json, calib.txt, two frames, five files into frame 2
    helpers = Path(__file__).parent
    killed = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(helpers.parents[1]), str(helpers),
                             str(tmp_path), str(kill_at)], capture_output=True, text=True, timeout=60)
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    assert len(list(tmp_path.rglob(".*.tmp*"))) == 1
    writer = KittiDatasetWriter(tmp_path, spec(FRAMES, formats=ALL_FORMATS))
    assert writer.pending(range(FRAMES)) == [2, 3]
    for index in writer.pending(range(FRAMES)):
        writer.write_frame(frame_record(index))
    finalize_dataset(tmp_path)
    assert tree_bytes(tmp_path) == tree_bytes(dataset)
    assert not list(tmp_path.rglob(".*.tmp*"))


def test_shards_written_apart_merge_into_the_same_sequence(tmp_path):
    whole, merged = tmp_path / "whole", tmp_path / "merged"
    write_dataset(whole, frames=range(5), frame_count=5)
    for shard in range(3):
        part = tmp_path / f"shard{shard}"
        write_dataset(part, frames=shard_frames(5, shard, 3), frame_count=5, finalize=False)
        shutil.copytree(part, merged, dirs_exist_ok=True)
    finalize_dataset(merged)
    assert tree_bytes(merged) == tree_bytes(whole)
    assert list(shard_frames(5, 1, 3)) == [1, 4]


def test_async_writer_matches_the_synchronous_writer(dataset, tmp_path):
    writer = KittiDatasetWriter(tmp_path, spec(FRAMES, formats=ALL_FORMATS))
    with AsyncFrameWriter(writer, max_pending=2, threads=2) as frames:
        for index in reversed(range(FRAMES)):
            frames.submit(frame_record(index))
    assert frames.written == FRAMES
    finalize_dataset(tmp_path)
    assert tree_bytes(tmp_path) == tree_bytes(dataset)


def test_async_writer_reports_a_failed_frame(tmp_path):
    writer = KittiDatasetWriter(tmp_path, spec(FRAMES))
    bad = frame_record(1)
    bad.views[1].depth = bad.views[1].depth[:, :10]
    frames = AsyncFrameWriter(writer)
    frames.submit(frame_record(0))
    frames.submit(bad)
    with pytest.raises(RuntimeError, match="frame 1 view 1: depth must be float \\(48, 64\\)"):
        frames.close()
    assert writer.is_complete(0) and not writer.is_complete(1)


def test_an_exr_that_does_not_fit_is_an_os_error_naming_it_and_leaves_nothing(tmp_path):
    """OpenEXR reports a full disk as a RuntimeError with a message: it becomes ENOSPC naming the file."""
    noise = np.random.default_rng(2).random((256, 256), dtype=np.float32)  # 256 KiB that ZIP cannot shrink much
    with small_disk(tmp_path / "disk", "64k") as disk:
        with pytest.raises(OSError) as raised:
            write_exr(disk / "depth.exr", noise)
        assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(disk / "depth.exr")
        assert not list(disk.iterdir())


def test_a_frame_that_does_not_fit_leaves_no_file_and_the_error_names_the_file(tmp_path):
    with small_disk(tmp_path / "disk", "160k") as disk:
        writer = KittiDatasetWriter(disk, spec(FRAMES, formats=ALL_FORMATS))
        with pytest.raises(OSError) as raised, AsyncFrameWriter(writer) as frames:
            for index in range(FRAMES):
                frames.submit(frame_record(index))
        assert raised.value.errno == errno.ENOSPC and Path(raised.value.filename).is_relative_to(disk)
        complete = [index for index in range(FRAMES) if writer.is_complete(index)]
        assert complete == list(range(len(complete))) and len(complete) < FRAMES
        partial = [path for index in range(len(complete), FRAMES) for path in writer.frame_files(index)
                   if path.exists()]
        assert not partial and not list(disk.rglob(".*.tmp*"))


def test_extra_rig_cameras_get_their_own_folders_and_calib_lines(tmp_path):
    write_dataset(tmp_path, frames=range(2), frame_count=2, camera_count=3)
    calib = pykitti.utils.read_calib_file(str(tmp_path / "sequences/00/calib.txt"))
    assert calib["P4"][3] == pytest.approx(-CAMERA.fx * 2 * BASELINE_M)
    image = read_png(tmp_path / "sequences/00/image_4/000001.png")
    np.testing.assert_array_equal(image, frame_record(1, camera_count=3).views[2].rgb)
    assert (tmp_path / "sequences/00/depth_4/000001.exr").exists()
    assert not (tmp_path / "sequences/00/disp_4").exists()
    assert len(pykitti.odometry(str(tmp_path), "00")) == 2


def test_reopening_with_other_settings_is_refused(tmp_path):
    write_dataset(tmp_path, frames=[0], finalize=False)
    with pytest.raises(DatasetError, match="dataset.json: the folder holds a different dataset .*frame_count"):
        KittiDatasetWriter(tmp_path, spec(FRAMES + 1))


def test_finalize_names_a_folder_that_is_no_dataset(tmp_path):
    with pytest.raises(DatasetError, match="dataset.json: not found"):
        finalize_dataset(tmp_path)
    (tmp_path / "dataset.json").write_text("[1, 2]", encoding="utf-8")
    with pytest.raises(DatasetError, match="dataset.json: expected a JSON object, got a list"):
        finalize_dataset(tmp_path)
    (tmp_path / "dataset.json").write_bytes(b'{"format": "\xff"}')
    with pytest.raises(DatasetError, match="dataset.json: not UTF-8 text \\(byte 12"):
        finalize_dataset(tmp_path)


def test_spec_from_a_rig_object_matches_the_explicit_spec():
    rig = SimpleNamespace(cameras=[CAMERA, CAMERA], T_rig_cam=[np.eye(4), np.array(spec(1).T_rig_cams[1])])
    from_rig = DatasetSpec.from_rig(rig, ORIGIN, FRAMES, command_line=["test"])
    assert dataset_description(from_rig) == dataset_description(spec(FRAMES))


def test_an_unwritable_output_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(DatasetError, match="file/sub: cannot write the dataset there"):
        KittiDatasetWriter(blocker / "sub", spec(FRAMES))
