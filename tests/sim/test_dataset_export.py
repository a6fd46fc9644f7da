"""``aerostereo-render export``: each layout read the way its consumer reads it (KITTI 2015 stereo loaders, the
KITTI depth devkit, Virtual KITTI 2 loaders, evo), against analytic truth; the source is never touched."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pykitti
import pytest
from evo.tools.file_interface import read_tum_trajectory_file
from PIL import Image

from dataset_helpers import BASELINE_M, CAMERA, ORIGIN, frame_record, looking_down_pose, spec
from render_scene_helpers import BOX_TOP_M, BOX_X_M, write_scene
from sim.render.camera import PinholeCamera, Rig
from sim.cli import main as cli_main
from sim.dataset import DatasetSpec, FrameRecord, KittiDatasetWriter, finalize_dataset
from sim.dataset.export import LAYOUTS, export_dataset
from sim.dataset.kitti2015 import visible_in_right
from sim.render.renderer import render
from sim.render.scene import load_scene
from sim.render.shade import Sun

FRAMES = 3
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def write_dataset(root: Path, frame_records, dataset_spec: DatasetSpec) -> Path:
    writer = KittiDatasetWriter(root, dataset_spec)
    for record in frame_records:
        writer.write_frame(record)
    finalize_dataset(root)
    return root


def tree_bytes(root: Path) -> dict[str, bytes]:
    return {str(path.relative_to(root)): path.read_bytes() for path in sorted(root.rglob("*")) if path.is_file()}


@pytest.fixture(scope="module")
def plane(tmp_path_factory):
    """The analytic ground-plane dataset and its export in every layout: (source, out, source bytes before)."""
    source = write_dataset(tmp_path_factory.mktemp("plane") / "dataset", [frame_record(i) for i in range(FRAMES)],
                           spec(FRAMES))
    before = tree_bytes(source)
    out = tmp_path_factory.mktemp("export")
    export_dataset(source, out, [name for name in LAYOUTS if name != "euroc"])  # euroc needs an IMU: its own test
    return source, out, before


def png_header(path: Path) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from the PNG's IHDR chunk, read from the bytes."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR"
    return (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big"), data[24], data[25])


# -- KITTI 2015 stereo -----------------------------------------------------------------------------------------------

def test_kitti2015_names_and_byte_level_encodings(plane):
    source, out, _ = plane
    training = out / "training"
    names = [f"{i:06d}_10.png" for i in range(FRAMES)]
    for folder in ("image_2", "image_3", "disp_occ_0", "disp_noc_0"):
        # (kitti_flow, exported beside it, adds the second frames of its pairs, NNNNNN_11.png, to image_2)
        assert sorted(path.name for path in (training / folder).glob("*_10.png")) == names
    assert png_header(training / "image_2/000001_10.png") == (CAMERA.width, CAMERA.height, 8, 2)  # 8-bit RGB
    source_png = source / "sequences/00/image_3/000001.png"
    assert (training / "image_3/000001_10.png").read_bytes() == source_png.read_bytes()
    for folder in ("disp_occ_0", "disp_noc_0"):
        assert png_header(training / folder / "000001_10.png") == (CAMERA.width, CAMERA.height, 16, 0)  # 16-bit grey
    occ = np.asarray(Image.open(training / "disp_occ_0/000001_10.png")).astype(np.int64)
    depth = frame_record(1).views[0].depth.astype(np.float64)
    hit = np.isfinite(depth)
    np.testing.assert_array_equal(occ[hit], np.maximum(np.rint(CAMERA.fx * BASELINE_M / depth[hit] * 256), 1))
    assert np.all(occ[~hit] == 0) and (~hit).any()
    noc = np.asarray(Image.open(training / "disp_noc_0/000001_10.png")).astype(np.int64)
    assert np.all((noc == occ) | (noc == 0))
    # A plane occludes nothing: only pixels whose right-view column (u - d) falls off the image are not visible.
    u = np.arange(CAMERA.width)[None, :].repeat(CAMERA.height, axis=0)
    right_column = u - CAMERA.fx * BASELINE_M / np.where(hit, depth, np.inf)
    clearly = hit & (np.abs(right_column) > 1e-3)
    np.testing.assert_array_equal((noc > 0)[clearly], (right_column >= 0)[clearly])


def test_kitti2015_calibration_gives_focal_length_and_baseline(plane):
    _, out, _ = plane
    lines = dict(line.split(": ") for line in (out / "training/calib_cam_to_cam/000002.txt").read_text().splitlines())
    P2 = np.array(lines["P_rect_02"].split(), dtype=float).reshape(3, 4)
    P3 = np.array(lines["P_rect_03"].split(), dtype=float).reshape(3, 4)
    np.testing.assert_allclose(P2[:, :3], [[CAMERA.fx, 0, CAMERA.cx], [0, CAMERA.fy, CAMERA.cy], [0, 0, 1]])
    assert P3[0, 3] / -P3[0, 0] - P2[0, 3] / -P2[0, 0] == pytest.approx(BASELINE_M)  # how KITTI tools take B
    assert np.array(lines["S_rect_02"].split(), dtype=float).tolist() == [CAMERA.width, CAMERA.height]


# A box in front of the ground, seen straight down by a rectified pair along east: left camera over the box,
# H above the ground, 2 m west of its west wall (x0); the right camera B further east. A ground point just west of the
# wall is hidden from a camera at east e when the ray to it crosses the box top: x_ground in
# [x0 - (e - x0) h / (H - h), x0]. Visible from the left but hidden from the right: x in [-16, -14] m.
BOX_H, BOX_B = 20.0, 2.0
BOX_CAMERA = PinholeCamera(fx=80.0, fy=80.0, cx=79.5, cy=49.5, width=160, height=100)
BOX_LEFT_EAST_M, BOX_NORTH_M = BOX_X_M[0] + 2.0, 2.0


def box_pose() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # camera x east, y south, z down
    T[:3, 3] = (BOX_LEFT_EAST_M, BOX_NORTH_M, BOX_H)
    return T


def left_pixel_of_ground(east_m: float) -> float:
    return BOX_CAMERA.cx + BOX_CAMERA.fx * (east_m - BOX_LEFT_EAST_M) / BOX_H


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    """The box scene rendered by the real renderer, written as a 1-frame dataset and exported as KITTI 2015."""
    root = tmp_path_factory.mktemp("box")
    scene = load_scene(write_scene(root / "scene"))
    rig = Rig.stereo(BOX_CAMERA, BOX_B)
    frame = render(scene, rig, box_pose(), Sun(0.0, 60.0, 5.0))
    record = FrameRecord(index=0, views=frame.views, T_world_cam=frame.views[0].T_world_cam, time_s=0.0, seed=0)
    dataset_spec = DatasetSpec(cameras=list(rig.cameras), T_rig_cams=list(rig.T_rig_cam), origin=ORIGIN,
                               frame_count=1, command_line=["test"])
    source = write_dataset(root / "dataset", [record], dataset_spec)
    export_dataset(source, root / "out", ["kitti2015"])
    occ, noc = (np.asarray(Image.open(root / "out/training" / folder / "000000_10.png")).astype(np.int64)
                for folder in ("disp_occ_0", "disp_noc_0"))
    return frame, occ, noc


def test_ground_hidden_behind_the_box_is_valid_in_occ_and_zero_in_noc(box):
    frame, occ, noc = box
    x0, h = BOX_X_M[0], BOX_TOP_M
    hidden_east = [x0 - (east - x0) * h / (BOX_H - h) for east in (BOX_LEFT_EAST_M + BOX_B, BOX_LEFT_EAST_M)]
    first, last = (left_pixel_of_ground(east) for east in hidden_east)  # 55.5 and 63.5
    row = int(round(BOX_CAMERA.cy))
    ground_disparity_png = round(BOX_CAMERA.fx * BOX_B / BOX_H * 256)
    occluded = np.arange(int(np.ceil(first)) + 1, int(np.floor(last)))  # a pixel clear of both edges
    assert len(occluded) >= 5
    np.testing.assert_allclose(frame.views[0].depth[row, occluded], BOX_H, rtol=1e-5)  # ground, seen by the left
    assert np.all(occ[row, occluded] == ground_disparity_png)
    assert np.all(noc[row, occluded] == 0)
    off_image = int(BOX_CAMERA.fx * BOX_B / BOX_H)  # columns u < d have no right-view partner
    open_ground = np.arange(off_image + 2, int(first) - 1)
    box_top = np.arange(int(last) + 2, BOX_CAMERA.width)
    assert np.all(noc[row, open_ground] == ground_disparity_png)
    assert np.all(noc[row, box_top] == round(BOX_CAMERA.fx * BOX_B / (BOX_H - h) * 256))
    assert np.all(noc[row, : off_image - 1] == 0) and np.all(occ[row, : off_image - 1] > 0)


def test_visible_in_right_needs_the_point_in_the_image_and_nothing_closer():
    depth_left = np.full((1, 6), 10.0)
    disparity = np.full((1, 6), 2.0)
    depth_right = np.full((1, 6), 10.0)
    np.testing.assert_array_equal(visible_in_right(depth_left, depth_right, disparity), [[0, 0, 1, 1, 1, 1]])
    depth_right[0, 1:3] = 5.0  # something closer covers right columns 1 and 2: left columns 3 and 4 see it
    np.testing.assert_array_equal(visible_in_right(depth_left, depth_right, disparity), [[0, 0, 1, 0, 0, 1]])
    depth_right[0, 1:3] = 10.0 * (1 - 0.001)  # the same surface within the tolerance (float32, creases)
    np.testing.assert_array_equal(visible_in_right(depth_left, depth_right, disparity), [[0, 0, 1, 1, 1, 1]])
    depth_left[0, 4] = np.inf  # a miss is never valid
    assert not visible_in_right(depth_left, depth_right, np.where(np.isfinite(depth_left), disparity, 0))[0, 4]


# -- KITTI depth ------------------------------------------------------------------------------------------------------

def test_kitti_depth_reads_back_by_the_devkit_convention(plane):
    source, out, _ = plane
    drive = out / "aerostereo/aerostereo_drive_0000_sync"
    for camera, view in (("image_02", 0), ("image_03", 1)):
        names = sorted(path.name for path in (drive / "proj_depth/groundtruth" / camera).iterdir())
        assert names == [f"{i:010d}.png" for i in range(FRAMES)]
        path = drive / "proj_depth/groundtruth" / camera / "0000000002.png"
        assert png_header(path)[2:] == (16, 0)
        png = np.asarray(Image.open(path)).astype(np.float64)
        depth_m = png / 256.0  # the devkit: depth = png / 256, and 0 means no data
        truth = frame_record(2).views[view].depth.astype(np.float64)
        storable = np.isfinite(truth) & (truth * 256 <= 65535)
        assert np.abs(depth_m[storable] - truth[storable]).max() <= 1 / 512 + 1e-9
        assert np.all(png[~storable] == 0)
        assert (np.isfinite(truth) & ~storable).any(), "the oblique view reaches beyond 256 m"
        image = drive / camera / "data/0000000002.png"
        assert image.read_bytes() == (source / f"sequences/00/image_{view + 2}/000002.png").read_bytes()
    lines = (out / "aerostereo/calib_cam_to_cam.txt").read_text().splitlines()
    assert [line.split(":")[0] for line in lines] == ["S_rect_02", "P_rect_02", "S_rect_03", "P_rect_03"]


# -- the source -------------------------------------------------------------------------------------------------------

def test_export_leaves_the_source_unchanged_and_pykitti_still_loads_it(plane):
    source, _, before = plane
    assert tree_bytes(source) == before
    odometry = pykitti.odometry(str(source), "00")
    assert len(odometry) == FRAMES
    np.testing.assert_array_equal(np.asarray(odometry.get_cam2(1)), frame_record(1).views[0].rgb)


# -- TUM / evo --------------------------------------------------------------------------------------------------------

def test_evo_loads_the_tum_trajectory_with_unix_times_and_our_poses(plane):
    _, out, _ = plane
    # no real time in the dataset: frame 0 at the EuRoC export's fixed start, 10**9 Unix seconds
    lines = (out / "tum/00.txt").read_text().splitlines()[1:]
    assert [line.split()[0] for line in lines] == [f"1000000000.{i * 100_000_000:09d}" for i in range(FRAMES)]
    trajectory = read_tum_trajectory_file(str(out / "tum/00.txt"))
    np.testing.assert_allclose(trajectory.timestamps, [1e9 + 0.1 * i for i in range(FRAMES)], rtol=0, atol=1e-6)
    for index, pose in enumerate(trajectory.poses_se3):
        np.testing.assert_allclose(pose, looking_down_pose(index), atol=1e-9)


# -- Virtual KITTI 2 --------------------------------------------------------------------------------------------------

def test_vkitti2_names_depth_and_camera_files(plane):
    _, out, _ = plane
    clone = out / "Scene01/clone"  # the default scene: the first of the folders VKITTI2's loaders list
    for view in (0, 1):
        assert sorted(p.name for p in (clone / f"frames/rgb/Camera_{view}").iterdir()) == \
            [f"rgb_{i:05d}.jpg" for i in range(FRAMES)]
        assert sorted(p.name for p in (clone / f"frames/depth/Camera_{view}").iterdir()) == \
            [f"depth_{i:05d}.png" for i in range(FRAMES)]
    truth = frame_record(1)
    rgb = cv2.cvtColor(cv2.imread(str(clone / "frames/rgb/Camera_1/rgb_00001.jpg")), cv2.COLOR_BGR2RGB)
    # JPEG, as VKITTI2 ships its images; full-resolution colour keeps this tiny sharp checkerboard at a mean error of
    # 3.1 levels (4:2:0 chroma subsampling: 21)
    assert np.abs(rgb.astype(float) - truth.views[1].rgb).mean() < 4.0
    depth_png = cv2.imread(str(clone / "frames/depth/Camera_1/depth_00001.png"),
                           cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH)
    assert depth_png.dtype == np.uint16
    depth = truth.views[1].depth.astype(np.float64)
    near = np.isfinite(depth) & (depth < 600.0)
    assert np.abs(depth_png[near] / 100.0 - depth[near]).max() <= 0.005 + 1e-9  # loaders: png / 100 -> metres
    assert np.all(depth_png[~np.isfinite(depth)] == 65535)
    intrinsic = np.loadtxt(clone / "intrinsic.txt", skiprows=1)
    assert (clone / "intrinsic.txt").read_text().splitlines()[0] == "frame cameraID K[0,0] K[1,1] K[0,2] K[1,2]"
    np.testing.assert_allclose(intrinsic[3], [1, 1, CAMERA.fx, CAMERA.fy, CAMERA.cx, CAMERA.cy])
    extrinsic = np.loadtxt(clone / "extrinsic.txt", skiprows=1)
    T_world_right = looking_down_pose(1) @ np.array([[1, 0, 0, BASELINE_M], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    assert extrinsic[3, :2].tolist() == [1, 1]
    np.testing.assert_allclose(extrinsic[3, 2:].reshape(4, 4), np.linalg.inv(T_world_right), atol=1e-9)


def test_vkitti2_scene_is_one_vkitti2_loaders_list(plane, tmp_path, capsys):
    """``--vkitti2-scene``: the layout is written as that scene folder; a name VKITTI2 does not have (the sequence's
    ``Scene00``) is refused with one line naming the option and the five it has, and nothing is written."""
    source, _, _ = plane
    assert cli_main(["export", str(source), "--layout", "vkitti2", "--vkitti2-scene", "Scene18",
                     "--out", str(tmp_path / "out")]) == 0
    assert [path.relative_to(tmp_path / "out").as_posix() for path in (tmp_path / "out").iterdir()] == ["Scene18"]
    assert (tmp_path / "out/Scene18/clone/frames/rgb/Camera_0/rgb_00002.jpg").is_file()
    assert "Scene18/clone" in capsys.readouterr().out
    assert cli_main(["export", str(source), "--layout", "vkitti2", "--vkitti2-scene", "Scene00",
                     "--out", str(tmp_path / "bad")]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "--vkitti2-scene" in error and "'Scene00'" in error
    assert "'Scene01', 'Scene02', 'Scene06', 'Scene18', 'Scene20'" in error
    assert not (tmp_path / "bad").exists()
    with pytest.raises(ValueError, match=r"VKITTI2 scene 'Scene00': expected one of Scene01, Scene02, Scene06, "
                                         r"Scene18, Scene20"):
        export_dataset(source, tmp_path / "bad", ["vkitti2"], vkitti2_scene="Scene00")
    assert not (tmp_path / "bad").exists()


def test_render_export_writes_the_vkitti2_scene_asked_for(tmp_path, capsys):
    """``render --export vkitti2 --vkitti2-scene S``: the one-command render and export names the scene folder too."""
    assert cli_main(["--scene", "demo:small", "--out", str(tmp_path / "dataset"), "--frames", "2", "--width", "32",
                     "--height", "16", "--quiet", "--export", "vkitti2", "--export-out", str(tmp_path / "out"),
                     "--vkitti2-scene", "Scene06"]) == 0
    assert "Scene06/clone" in capsys.readouterr().out
    assert sorted(p.name for p in (tmp_path / "out/Scene06/clone/frames/depth/Camera_1").iterdir()) == \
        ["depth_00000.png", "depth_00001.png"]


# -- the command line -------------------------------------------------------------------------------------------------

def test_cli_exports_and_prints_one_line_per_layout(plane, tmp_path, capsys):
    source, _, _ = plane
    assert cli_main(["export", str(source), "--layout", "tum,kitti2015", "--out", str(tmp_path / "out")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["tum", "kitti2015"]
    assert (tmp_path / "out/tum/00.txt").is_file() and (tmp_path / "out/training/disp_noc_0").is_dir()


@pytest.mark.parametrize("case", ["inside_source", "no_depth", "not_finalized"])
def test_cli_refuses_with_one_line_and_writes_nothing(tmp_path, capsys, case):
    formats = ("disparity_png",) if case == "no_depth" else ("depth_exr",)
    source = tmp_path / "dataset"
    writer = KittiDatasetWriter(source, spec(1, formats=formats))
    writer.write_frame(frame_record(0))
    if case != "not_finalized":
        finalize_dataset(source)
    out = source / "export" if case == "inside_source" else tmp_path / "out"
    assert cli_main(["export", str(source), "--layout", "tum,kitti2015", "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and error.startswith("aerostereo-render export: error: ")
    assert {"inside_source": "overlaps the source", "no_depth": "depth_exr", "not_finalized": "not finalized"}[case] \
        in error
    assert not out.exists()


def test_layouts_that_need_pinhole_images_refuse_a_distorted_lens_and_tum_does_not(tmp_path):
    distorted = PinholeCamera(CAMERA.fx, CAMERA.fy, CAMERA.cx, CAMERA.cy, CAMERA.width, CAMERA.height,
                              dist=(-0.1, 0.01, 0.0, 0.0, 0.0))
    dataset_spec = DatasetSpec(cameras=[distorted] * 2, T_rig_cams=spec(1).T_rig_cams, origin=ORIGIN, frame_count=1,
                               formats=("depth_exr",), command_line=["test"])
    source = write_dataset(tmp_path / "dataset", [frame_record(0)], dataset_spec)
    for layout in ("kitti2015", "kitti_depth", "vkitti2"):
        with pytest.raises(ValueError, match=f"the {layout} layout needs undistorted pinhole images"):
            export_dataset(source, tmp_path / "out", [layout])
    assert not (tmp_path / "out").exists()
    assert export_dataset(source, tmp_path / "out", ["tum"])[0].startswith("tum: 1 poses")


def test_kitti2015_refuses_a_pair_that_is_not_rectified_and_the_depth_layouts_do_not(tmp_path):
    T_right = spec(1).T_rig_cams[1].copy()
    T_right[1, 3] = 0.2  # the right camera also 0.2 m below the left: epipolar lines are no longer rows
    dataset_spec = DatasetSpec(cameras=[CAMERA] * 2, T_rig_cams=[np.eye(4), T_right], origin=ORIGIN, frame_count=1,
                               formats=("depth_exr",), command_line=["test"])
    source = write_dataset(tmp_path / "dataset", [frame_record(0)], dataset_spec)
    with pytest.raises(ValueError, match="the kitti2015 layout needs a rectified stereo pair"):
        export_dataset(source, tmp_path / "out", ["kitti_depth", "kitti2015"])
    assert not (tmp_path / "out").exists()
    assert len(export_dataset(source, tmp_path / "out", ["kitti_depth", "vkitti2"])) == 2


def test_a_damaged_frames_jsonl_is_named_with_its_line(plane, tmp_path):
    source = tmp_path / "dataset"
    source.mkdir()
    for name in ("dataset.json", "sequences/00/frames.jsonl"):
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        (source / name).write_bytes((plane[0] / name).read_bytes())
    frames_jsonl = source / "sequences/00/frames.jsonl"
    lines = frames_jsonl.read_text().splitlines()
    frames_jsonl.write_text("\n".join([lines[0], lines[1][:20], *lines[2:]]) + "\n")
    with pytest.raises(ValueError, match=r"frames.jsonl: line 2 is not JSON"):
        export_dataset(source, tmp_path / "out", ["tum"])


def test_unknown_layout_is_refused_naming_the_known_ones(plane, tmp_path):
    source, _, _ = plane
    known = "kitti2015, kitti_depth, vkitti2, tum"
    with pytest.raises(ValueError, match=f"unknown layouts \\['vkitti'\\]; choose from {known}"):
        export_dataset(source, tmp_path / "out", ["vkitti"])
    assert not (tmp_path / "out").exists()
