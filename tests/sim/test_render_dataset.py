"""The dataset-render pipeline and CLI against known truth: a box of known corners on a flat textured ground.

pykitti (a real KITTI client) reads what we write; the box top projected with pykitti's P2 and poses lands
on the pixels the renderer drew it on; depth, disparity and the two views agree; the output does not depend
on worker count, shards or a kill in the middle of a frame; bad input exits with code 2.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pykitti
import pytest

from flightplan.geodesy import LocalFrame
from sim.render.camera import PinholeCamera
from sim.dataset.images import read_exr, read_png
from sim.run.frame_renderer import FrameRenderer
from cliutil.errors import BadInput
from sim.dataset.imu_file import DISK_BYTES_PER_SAMPLE
from sim.run.options import PoseOptions, RenderInputError, RenderOptions, RigOptions, RunOptions
from sim.cli import main as cli_main
from sim.cli.render import build_parser, options_from_args
from sim.run import render_dataset as render_dataset_module
from sim.run.render_dataset import render_dataset
from sim.sampling.pose import R_WORLD_NADIR, camera_rotation

from dataset_helpers import dataset_bytes
from render_scene_helpers import BOX_TOP_M, BOX_X_M, BOX_Y_M, ORIGIN, box_top_corners, write_geotags, write_scene

REPO_ROOT = Path(__file__).resolve().parents[2]
SMALL = dict(width=160, height=100, frames=8, seed=3)


def small_options(**run) -> RenderOptions:
    """:data:`SMALL` as render options (what the command line renders from ``_argv(**SMALL)``), run as ``run`` says."""
    return RenderOptions(seed=SMALL["seed"], rig=RigOptions(width=SMALL["width"], height=SMALL["height"]),
                         poses=PoseOptions(frames=SMALL["frames"]), run=RunOptions(**run))


def _argv(scene: Path, out: Path, **options) -> list[str]:
    argv = ["--scene", str(scene), "--out", str(out), "--quiet"]
    return argv + [f"--{key}={value}" for key, value in options.items()]


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory) -> Path:
    return write_scene(tmp_path_factory.mktemp("scene"))


@pytest.fixture(scope="module")
def reference(scene_dir, tmp_path_factory):
    """A small random-mode dataset rendered in this process (1 worker); (folder, summary)."""
    out = tmp_path_factory.mktemp("reference") / "dataset"
    summary = render_dataset(scene_dir, out, small_options(), command_line=["test"], progress=False)
    return out, summary


def frame_records(dataset: Path) -> list[dict]:
    return [json.loads(line) for line in (dataset / "sequences/00/frames.jsonl").read_text().splitlines()]


def pixel_rays(P: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W, 3) camera-frame rays K^-1 [u, v, 1] (z = 1, so a ray parameter is planar depth)."""
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    return np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(P[:, :3]).T


def test_pykitti_reads_the_sequence_and_the_box_top_lands_where_rendered(reference):
    """Box-top corners projected with pykitti's P2 and poses bound exactly the pixels whose depth is the box top."""
    out, _ = reference
    kitti = pykitti.odometry(str(out), "00")
    records = frame_records(out)
    assert len(kitti.poses) == len(records) == SMALL["frames"] and len(kitti.timestamps) == SMALL["frames"]
    assert kitti.get_cam2(0).size == (SMALL["width"], SMALL["height"]) and kitti.get_cam0(0).mode == "L"
    assert kitti.calib.b_rgb == pytest.approx(0.54, abs=1e-9)
    T_world_first = np.array(records[0]["T_world_cam"])
    P2 = kitti.calib.P_rect_20
    frames_with_box, checked = 0, 0
    for index, T_first_cam in enumerate(kitti.poses):
        T_world_cam = T_world_first @ T_first_cam
        corners_cam = (np.linalg.inv(T_world_cam) @ np.c_[box_top_corners(), np.ones(4)].T)
        if np.any(corners_cam[2] <= 0):
            continue
        projected = P2 @ corners_cam
        polygon = (projected[:2] / projected[2]).T.astype(np.float32)
        depth = read_exr(out / f"sequences/00/depth_2/{index:06d}.exr")
        rays_world = pixel_rays(P2, SMALL["width"], SMALL["height"]) @ T_world_cam[:3, :3].T
        with np.errstate(divide="ignore", invalid="ignore"):
            top_depth = (BOX_TOP_M - T_world_cam[2, 3]) / rays_world[..., 2]
        rendered_top = np.abs(depth - top_depth) < 1e-4 * top_depth
        signed = np.array([[cv2.pointPolygonTest(polygon, (float(u), float(v)), True)
                            for u in range(SMALL["width"])] for v in range(SMALL["height"])])
        clear = np.abs(signed) > 0.5  # pixel centres more than half a pixel from the projected outline
        np.testing.assert_array_equal(rendered_top[clear], signed[clear] > 0, err_msg=f"frame {index}")
        frames_with_box += int(np.sum(signed > 0.5) >= 30)
        checked += int(clear.sum())
    assert frames_with_box >= 1 and checked > 0


def test_depth_disparity_and_the_two_views_agree(reference):
    out, _ = reference
    calib = pykitti.odometry(str(out), "00").calib
    fx, baseline = calib.P_rect_20[0, 0], calib.b_rgb
    seq = out / "sequences/00"
    agreeing = []
    for index in range(SMALL["frames"]):
        name = f"{index:06d}"
        depth_left, depth_right = read_exr(seq / f"depth_2/{name}.exr"), read_exr(seq / f"depth_3/{name}.exr")
        disparity = read_exr(seq / f"disp_2/{name}.exr")
        finite = np.isfinite(depth_left)
        np.testing.assert_allclose(disparity[finite], fx * baseline / depth_left[finite], rtol=1e-6)
        assert np.all(disparity[~finite] == 0)
        png = read_png(seq / f"disp_2/{name}.png").astype(float) / 256
        np.testing.assert_allclose(png[finite], np.clip(disparity[finite], 1 / 256, None), atol=1 / 512 + 1e-9)
        assert np.all(png[~finite] == 0)
        # The left pixel (u, v) sees the point the right camera sees at (u - d, v), at the same planar depth.
        v, u = np.mgrid[0:SMALL["height"], 0:SMALL["width"]].astype(np.float32)
        right_at_match = cv2.remap(np.nan_to_num(depth_right, posinf=0.0), u - disparity, v, cv2.INTER_LINEAR,
                                   borderValue=-1.0)
        inside = finite & (right_at_match > 0)
        relative = np.abs(right_at_match[inside] - depth_left[inside]) / depth_left[inside]
        agreeing.append(np.mean(relative < 1e-3))
    assert np.mean(agreeing) > 0.97  # the rest: occlusion edges of the box and the horizon


def test_poses_times_and_sampler_records_agree(reference):
    out, summary = reference
    records = frame_records(out)
    poses = np.loadtxt(out / "poses/00.txt").reshape(-1, 3, 4)
    T_first_world = np.linalg.inv(np.array(records[0]["T_world_cam"]))
    for record, pose in zip(records, poses):
        np.testing.assert_allclose(pose, (T_first_world @ np.array(record["T_world_cam"]))[:3], atol=1e-9)
        assert record["sampler"]["mode"] == "random"
        assert 20.0 <= record["sampler"]["height_above_ground_m"] <= 100.0
        assert all(-45.0 <= record["sampler"][key] <= 45.0 for key in ("tilt_x_deg", "tilt_y_deg"))
        assert 30.0 <= record["sun"]["elevation_deg"] <= 90.0 and 5.0 <= record["sun"]["intensity"] <= 10.0
    np.testing.assert_allclose(np.loadtxt(out / "sequences/00/times.txt"), [r["time_s"] for r in records])
    # The sky probe rejects tilted views of the horizon, and the summary counts exactly the recorded redraws.
    assert summary.rejected_poses == sum(r["sampler"]["rejected"] for r in records) > 0
    assert summary.rendered == SMALL["frames"] and summary.finalized
    description = json.loads((out / "dataset.json").read_text())
    assert description["command_line"] == ["test"] and description["sampling"]["seed"] == SMALL["seed"]


def test_a_rerun_skips_complete_frames_and_redoes_a_damaged_one(reference, scene_dir, tmp_path):
    out = tmp_path / "dataset"
    shutil.copytree(reference[0], out)
    (out / "sequences/00/frame_meta/000002.json").unlink()  # as if killed before frame 2's record was written
    (out / "sequences/00/image_3/000002.png").write_bytes(b"half a png")
    summary = render_dataset(scene_dir, out, small_options(), command_line=["test"], progress=False)
    assert (summary.rendered, summary.skipped) == (1, SMALL["frames"] - 1)
    assert dataset_bytes(out) == dataset_bytes(reference[0])


@pytest.mark.slow
def test_same_bytes_with_two_workers_and_from_merged_shards(reference, scene_dir, tmp_path):
    expected = dataset_bytes(reference[0])
    two_workers = render_dataset(scene_dir, tmp_path / "two", small_options(workers=2), progress=False)
    assert two_workers.rendered == SMALL["frames"]
    assert dataset_bytes(tmp_path / "two") == expected
    for shard in (0, 1):
        summary = render_dataset(scene_dir, tmp_path / f"shard{shard}", small_options(shard=(shard, 2)),
                                 progress=False)
        assert not summary.finalized and summary.remaining == SMALL["frames"] // 2
        shutil.copytree(tmp_path / f"shard{shard}", tmp_path / "merged", dirs_exist_ok=True)
    merged = render_dataset(scene_dir, tmp_path / "merged", small_options(), progress=False)
    assert merged.rendered == 0 and merged.finalized
    assert dataset_bytes(tmp_path / "merged") == expected


def test_workers_beyond_the_frames_start_one_process_per_frame_and_are_sized_so(scene_dir, tmp_path, monkeypatch):
    """--workers 100000 for 2 frames starts 2 processes: its memory is sized for those 2 (not refused for 100000)."""
    started = []
    monkeypatch.setattr(render_dataset_module, "render_in_processes",
                        lambda job, pending, processes, frame_done: started.append((list(pending), processes)))
    options = RenderOptions(rig=RigOptions(width=SMALL["width"], height=SMALL["height"]), poses=PoseOptions(frames=2),
                            run=RunOptions(workers=100_000))
    render_dataset(scene_dir, tmp_path / "out", options, progress=False)
    assert started == [([0, 1], 2)]


def test_the_imu_record_is_in_the_disk_estimate(tmp_path, monkeypatch):
    """With --imu the disk check counts the record (0.7 kB a sample) beside the frames, before anything is written."""
    asked = []

    def require_disk(folder, bytes_needed, what):
        asked.append((bytes_needed, what))
        raise BadInput("stopped after the disk check")

    monkeypatch.setattr(render_dataset_module, "require_disk", require_disk)
    for rate in (None, 100.0):
        options = RenderOptions(rig=RigOptions(width=32, height=16),
                                poses=PoseOptions(frames=2, mode="trajectory", imu_rate_hz=rate))
        with pytest.raises(RenderInputError, match="stopped after the disk check"):
            render_dataset("demo:small", tmp_path / "out", options, progress=False)
    (frames_only, plain), (with_imu, described) = asked
    assert with_imu - frames_only == 11 * DISK_BYTES_PER_SAMPLE  # 2 frames at 10 Hz, sampled at 100 Hz
    assert described == plain + " and the IMU record of 11 samples (--imu-rate 100.0)"
    assert not (tmp_path / "out").exists()


KILL_OPTIONS = dict(width=640, height=400, frames=6, seed=5)


def _first_partial_frame(dataset: Path) -> int | None:
    """A frame with some files on disk but no record yet (a kill now lands in the middle of writing it)."""
    seq = dataset / "sequences/00"
    for index in range(KILL_OPTIONS["frames"] - 1):
        if (seq / f"image_2/{index:06d}.png").exists() and not (seq / f"frame_meta/{index:06d}.json").exists():
            return index
    return None


@pytest.mark.slow
def test_a_run_killed_in_the_middle_of_a_frame_resumes_to_the_same_bytes(scene_dir, tmp_path):
    killed = tmp_path / "killed"
    argv = _argv(scene_dir, killed, **KILL_OPTIONS)
    code = f"import sys; from sim.cli import main; sys.exit(main({argv!r}))"
    process = subprocess.Popen([sys.executable, "-c", code], cwd=REPO_ROOT,
                               env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})
    deadline, partial = time.monotonic() + 60, None
    while partial is None and process.poll() is None and time.monotonic() < deadline:
        partial = _first_partial_frame(killed) if (killed / "sequences/00/image_2").exists() else None
        time.sleep(0.001)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert partial is not None, "the run ended before a frame was caught half-written"
    # One writer thread writes frames in order, so the frame after the half-written one is certainly unfinished.
    assert not (killed / f"sequences/00/frame_meta/{partial + 1:06d}.json").exists()
    assert cli_main(argv) == 0
    uninterrupted = tmp_path / "uninterrupted"
    assert cli_main(_argv(scene_dir, uninterrupted, **KILL_OPTIONS)) == 0
    assert dataset_bytes(killed) == dataset_bytes(uninterrupted)
    assert not [p for p in killed.rglob(".*.tmp*")]


def test_two_runs_of_one_command_give_identical_files_and_timings_go_to_the_run_log(scene_dir, tmp_path):
    out = tmp_path / "dataset"
    argv = _argv(scene_dir, out, frames=3, width=48, height=32, seed=4)
    assert cli_main(argv) == 0
    first = out.rename(tmp_path / "first")
    assert cli_main(argv) == 0
    assert dataset_bytes(out, command_line=True) == dataset_bytes(first, command_line=True)  # byte for byte
    assert all("render_time_s" not in record for record in frame_records(out))
    logs = list((out / "logs").glob("render-*.jsonl"))
    assert len(logs) == 1
    run, *frames = [json.loads(line) for line in logs[0].read_text().splitlines()]
    assert run["run"]["command_line"] == ["aerostereo-render", *argv] and run["run"]["rendered"] == 3
    assert [frame["frame"] for frame in frames] == [0, 1, 2]
    assert all(0 < frame["render_s"] <= frame["done_s"] <= run["run"]["elapsed_s"] for frame in frames)


def _files_and_sizes(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``folder`` (temporaries included): size and modification time."""
    return {str(p): (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*") if p.is_file()}


@pytest.mark.slow
def test_killing_the_parent_of_two_workers_stops_every_write_and_a_rerun_resumes(scene_dir, tmp_path):
    options = dict(width=480, height=300, frames=24, seed=5)
    killed = tmp_path / "killed"
    argv = _argv(scene_dir, killed, workers=2, **options)
    code = f"import sys; from sim.cli import main; sys.exit(main({argv!r}))"
    process = subprocess.Popen([sys.executable, "-c", code], cwd=REPO_ROOT, start_new_session=True,
                               env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})
    try:
        deadline = time.monotonic() + 120
        while not list(killed.glob("sequences/00/frame_meta/*.json")) and time.monotonic() < deadline:
            time.sleep(0.01)
        process.send_signal(signal.SIGKILL)  # the parent only: its workers are left to the kernel
        process.wait()
        time.sleep(1.0)
        settled = _files_and_sizes(killed)
        time.sleep(1.5)
        assert _files_and_sizes(killed) == settled, "a worker kept writing after its parent was killed"
    finally:
        with contextlib.suppress(ProcessLookupError):  # no process left of the run: what the test expects
            os.killpg(process.pid, signal.SIGKILL)
    complete = len(list(killed.glob("sequences/00/frame_meta/*.json")))
    assert 1 <= complete < options["frames"]
    assert cli_main(argv) == 0
    uninterrupted = tmp_path / "uninterrupted"
    assert cli_main(_argv(scene_dir, uninterrupted, **options)) == 0
    assert dataset_bytes(killed) == dataset_bytes(uninterrupted)


def test_trajectory_mode_flies_the_orbit_at_the_set_speed(scene_dir, tmp_path):
    out = tmp_path / "orbit"
    argv = _argv(scene_dir, out, mode="trajectory", frames=5, width=48, height=32, speed=4.0, rate=2.0, altitude=30)
    assert cli_main(argv) == 0
    records = frame_records(out)
    positions = np.array([r["position_enu_m"] for r in records])
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    np.testing.assert_allclose(steps, 2.0, rtol=1e-3)  # 4 m/s at 2 Hz (chords of a 27 m circle)
    np.testing.assert_allclose(np.loadtxt(out / "sequences/00/times.txt"), np.arange(5) / 2.0)
    np.testing.assert_allclose(positions[:, 2], BOX_TOP_M + 30.0)  # 30 m over the ground at the centre: the box top


def test_frustum_margin_refuses_a_path_whose_views_reach_past_the_scene(scene_dir, tmp_path, capsys):
    assert cli_main(_argv(scene_dir, tmp_path / "out", mode="trajectory", trajectory="lawnmower", frames=4, width=32,
                          height=24, altitude=40)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "lawnmower path's views reach" in err and "lower --altitude" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("path", ["lawnmower", "loop"])
def test_terrain_following_trajectories_keep_speed_and_height(scene_dir, tmp_path, path):
    out = tmp_path / path
    # a fixed margin: at 40 m the views of this 90 m scene reach past it, which the frustum margin refuses
    assert cli_main(_argv(scene_dir, out, mode="trajectory", trajectory=path, frames=4, width=32, height=24,
                             speed=6.0, rate=3.0, altitude=40, margin=20)) == 0
    records = frame_records(out)
    steps = np.linalg.norm(np.diff([r["position_enu_m"] for r in records], axis=0)[:, :2], axis=1)
    np.testing.assert_allclose(steps, 2.0, rtol=0.02)  # 6 m/s at 3 Hz, along the (possibly curved) path
    np.testing.assert_allclose([r["sampler"]["height_above_ground_m"] for r in records], 40.0, atol=1e-6)


def test_replay_renders_exactly_where_the_photos_were_taken(scene_dir, tmp_path):
    positions = [(0.0, -5.0, 60.0), (3.0, -5.0, 61.0), (6.0, -4.0, 62.0)]
    geotags = write_geotags(tmp_path, ORIGIN, positions)
    out = tmp_path / "replay"
    assert cli_main(_argv(scene_dir, out, mode="replay", geotags=geotags, width=48, height=32)) == 0
    records = frame_records(out)
    np.testing.assert_allclose([r["position_enu_m"] for r in records], positions, atol=1e-6)
    np.testing.assert_allclose(np.array(records[1]["T_world_cam"])[:3, :3], R_WORLD_NADIR, atol=1e-9)
    np.testing.assert_allclose(np.loadtxt(out / "sequences/00/times.txt"), [0.0, 2.0, 4.0])
    depth = read_exr(out / "sequences/00/depth_2/000000.exr")
    assert depth[0, 0] == pytest.approx(60.0, rel=1e-5)  # nadir view of flat ground 60 m below


@pytest.mark.slow
def test_without_a_scene_it_renders_the_demo_world(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # the demo world is built into this cache
    out = tmp_path / "demo"
    assert cli_main(["--scene", "demo:small", "--out", str(out), "--frames", "2", "--width", "64", "--height", "36",
                        "--quiet"]) == 0
    description = json.loads((out / "dataset.json").read_text())
    assert description["scene"]["provenance"]["variant"] == "small"
    assert description["origin"] == ORIGIN.to_dict()  # the demo world sits at the demo location
    assert np.isfinite(read_exr(out / "sequences/00/depth_2/000001.exr")).mean() > 0.98


def test_cli_writes_a_contact_sheet(reference, scene_dir, tmp_path):
    sheet = tmp_path / "sheet.png"
    out = tmp_path / "dataset"
    shutil.copytree(reference[0], out)
    assert cli_main(_argv(scene_dir, out, **SMALL) + ["--contact-sheet", str(sheet)]) == 0
    image = read_png(sheet)
    assert image.ndim == 3 and image.shape[1] > image.shape[0] > 100 and image.std() > 10


def _error_of(capsys, argv: list[str]) -> str:
    assert cli_main(argv) == 2
    message = capsys.readouterr().err.strip()
    assert message.count("\n") == 0 and "Traceback" not in message
    return message


def test_cli_bad_input_is_one_line_and_exit_code_2(scene_dir, tmp_path, capsys):
    missing = tmp_path / "no-such-scene"
    assert str(missing) in _error_of(capsys, _argv(missing, tmp_path / "a"))
    untextured = write_scene(tmp_path / "untextured", textured=False)
    assert "texture" in _error_of(capsys, _argv(untextured, tmp_path / "b"))
    far_away = write_geotags(tmp_path, LocalFrame(47.0, 8.0, 400.0), [(0.0, 0.0, 50.0)])
    assert "another area" in _error_of(capsys, _argv(scene_dir, tmp_path / "c", mode="replay", geotags=far_away))
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    assert str(blocker / "out") in _error_of(capsys, _argv(scene_dir, blocker / "out", frames=1, width=16, height=8))
    assert "replay needs --geotags FILE, or a reconstructed scene" in _error_of(
        capsys, _argv(scene_dir, tmp_path / "d", mode="replay"))  # a scene without cameras.json
    assert cli_main(_argv(scene_dir, tmp_path / "f", frames=1, width=16, height=8)) == 0
    assert "differs in sampling" in _error_of(capsys, _argv(scene_dir, tmp_path / "f", frames=1, width=16, height=8,
                                                           seed=9))
    islet = write_scene(tmp_path / "islet", valid_half_size_m=25.0, ground_half_size_m=15.0)  # every view sees sky
    assert "sky/miss pixels" in _error_of(capsys, _argv(islet, tmp_path / "g", frames=2, width=16, height=8,
                                                        workers=2, heights="20,100"))  # given: not lowered
    assert "--shard must look like I/N" in _error_of(capsys, _argv(scene_dir, tmp_path / "e", shard="2/2"))


def test_cli_defaults_are_the_render_options_defaults():
    assert options_from_args(build_parser().parse_args(["--out", "x"])) == RenderOptions()


def test_cli_refuses_settings_that_cannot_render_before_rendering(scene_dir, tmp_path, capsys):
    for option, value in (("rate", 0), ("speed", -2), ("altitude", 0), ("margin", -1), ("baseline", math.inf),
                          ("margin", math.inf)):
        message = _error_of(capsys, _argv(scene_dir, tmp_path / option, mode="trajectory", **{option: value}))
        expected = "a finite number >= 0" if option == "margin" else "a positive finite number"
        assert message.endswith(f"{option} must be {expected}, got {value:.1f}")
    out = tmp_path / "no-depth"
    argv = _argv(scene_dir, out, frames=1, width=16, height=8, formats="disparity_png") + ["--contact-sheet",
                                                                                             str(tmp_path / "s.png")]
    assert "a contact sheet shows depth, but the dataset has no depth_exr" in _error_of(capsys, argv)
    assert not out.exists()  # refused before anything was rendered


def test_ctrl_c_is_one_line_exit_130_and_a_rerun_resumes(scene_dir, tmp_path, capsys, monkeypatch):
    out = tmp_path / "interrupted"
    argv = _argv(scene_dir, out, frames=3, width=16, height=8)
    record = FrameRenderer.record

    def interrupted_at_frame_1(renderer, index):
        if index == 1:
            raise KeyboardInterrupt
        return record(renderer, index)

    monkeypatch.setattr(FrameRenderer, "record", interrupted_at_frame_1)
    assert cli_main(argv) == 130
    assert capsys.readouterr().err.strip() == "aerostereo-render: interrupted: rerun the same command to resume"
    monkeypatch.setattr(FrameRenderer, "record", record)
    assert cli_main(argv) == 0
    assert "rendered 2 frames" in capsys.readouterr().out  # frame 0 was kept


def test_compare_prints_the_photorealism_table(reference, tmp_path, capsys):
    seq = reference[0] / "sequences/00"
    assert cli_main(["compare", str(seq / "image_2"), str(seq / "image_2")]) == 0
    table = capsys.readouterr().out
    assert f"mean of {SMALL['frames']}" in table and "0.00" in table.splitlines()[-1]
    assert cli_main(["compare", str(seq / "image_2"), str(seq / "image_3")]) == 0
    mean_error = float(capsys.readouterr().out.splitlines()[-1].split()[3])
    assert 0.0 < mean_error < 30.0  # a stereo partner differs, but far less than unrelated images
    assert cli_main(["compare", str(tmp_path / "missing"), str(seq / "image_2")]) == 2


def test_a_three_camera_rig_writes_a_third_colour_camera(scene_dir, tmp_path):
    out = tmp_path / "three"
    assert cli_main(_argv(scene_dir, out, cameras=3, frames=2, width=40, height=24, baseline=0.3)) == 0
    calib = {line.split(":")[0]: np.array(line.split()[1:], float).reshape(3, 4)
             for line in (out / "sequences/00/calib.txt").read_text().splitlines()}
    assert calib["P4"][0, 3] == pytest.approx(-calib["P4"][0, 0] * 0.6)  # third camera 2 x 0.3 m to the right
    assert read_png(out / "sequences/00/image_4/000001.png").shape == (24, 40, 3)
    assert read_exr(out / "sequences/00/depth_4/000001.exr").shape == (24, 40)


def test_lens_distortion_renders_through_the_distorted_lens(scene_dir, tmp_path, capsys):
    """Back-projected through the stated (k1, k2, p1, p2, k3), every ground pixel's depth lands on the ground."""
    R_world_cam = camera_rotation(0.0, tilt_x_deg=30.0)  # looking north, 30 deg from nadir
    geotags = write_geotags(tmp_path, ORIGIN, [(30.0, -30.0, 60.0)], R_world_cam)
    out = tmp_path / "distorted"
    distortion = "-0.25,0.05,0.001,-0.002,0"
    argv = _argv(scene_dir, out, mode="replay", geotags=geotags, width=64, height=48, distortion=distortion)
    assert "disparity needs rectified" in _error_of(capsys, argv)
    assert cli_main(argv + ["--formats", "depth_exr"]) == 0
    camera = json.loads((out / "dataset.json").read_text())["cameras"][0]
    assert camera["dist"] == [float(k) for k in distortion.split(",")]  # dataset.json states the lens
    lens = PinholeCamera(camera["fx"], camera["fy"], camera["cx"], camera["cy"], 64, 48, dist=tuple(camera["dist"]))
    depth = read_exr(out / "sequences/00/depth_2/000000.exr").ravel()

    def hit_points(camera_model) -> np.ndarray:
        rays = camera_model.ray_directions(camera_model.pixel_centres())
        return (rays / rays[:, 2:3] * depth[:, None]) @ R_world_cam.T + [30.0, -30.0, 60.0]

    points = hit_points(lens)
    (x0, x1), (y0, y1) = BOX_X_M, BOX_Y_M
    ground = ~((points[:, 0] > x0 - 1) & (points[:, 0] < x1 + 1) & (points[:, 1] > y0 - 1) & (points[:, 1] < y1 + 1))
    assert ground.mean() > 0.7
    np.testing.assert_allclose(points[ground, 2], 0.0, atol=2e-3)
    pinhole = PinholeCamera(camera["fx"], camera["fy"], camera["cx"], camera["cy"], 64, 48)
    assert np.abs(hit_points(pinhole)[ground, 2]).max() > 1.0  # the distortion is really in the images


def test_the_disk_estimate_per_frame_is_within_a_factor_two_of_the_frames_written(reference, scene_dir):
    from sim.dataset.writer import KittiDatasetWriter, frame_disk_bytes
    from sim.run.render_dataset import dataset_spec

    dataset, summary = reference
    renderer = FrameRenderer(scene_dir, small_options())
    spec = dataset_spec(renderer, scene_dir, renderer.options, ["test"])
    renderer.close()
    files = KittiDatasetWriter(dataset, spec).frame_files(0)
    on_disk = sum(path.stat().st_blocks * 512 for path in files)  # what the files take, block-rounded
    assert 0.5 <= frame_disk_bytes(spec) / on_disk <= 2.0


def test_the_memory_estimate_counts_every_array_a_view_keeps(scene_dir):
    from sim.render.renderer import VIEW_BYTES_PER_PIXEL, render, render_memory_bytes
    from sim.run.rig import build_rig
    from sim.render.shade import Sun

    options = RenderOptions(rig=RigOptions(width=40, height=30))
    rig = build_rig(options.rig)
    renderer = FrameRenderer(scene_dir, options, threads=1)
    T = renderer.poses.pose(0).T_world_cam
    views = render(renderer.scene, rig, T, Sun(0.0, 45.0, 1.0), pool=renderer.pool).views
    renderer.close()
    kept = sum(view.rgb.nbytes + view.depth.nbytes + view.distance.nbytes + view.normal.nbytes + view.triangle.nbytes
               + view.valid.nbytes for view in views)
    assert kept == render_memory_bytes([40 * 30] * len(views), 1, 1) == VIEW_BYTES_PER_PIXEL * 40 * 30 * len(views)
    # Supersampling adds each thread's sample pattern: 2 bytes per sample and pixel, twice while permuted.
    assert render_memory_bytes([40 * 30] * 2, 16, 3) - kept == 3 * 4 * 16 * 40 * 30


def test_overwrite_replaces_a_dataset_of_other_settings_and_keeps_other_files(scene_dir, tmp_path, capsys):
    """Other settings on an existing dataset are refused (one line naming --overwrite); with --overwrite the old
    dataset's files go, files it did not write stay, and the result equals a fresh render byte for byte."""
    out, fresh = tmp_path / "d", tmp_path / "fresh"
    kept = [out / "notes.txt", out / "sequences" / "00" / "notes.txt"]
    for path in kept:
        path.parent.mkdir(parents=True)
        path.write_text("the user's")
    tiny = dict(width=16, height=8)
    assert cli_main(_argv(scene_dir, out, frames=3, seed=1, **tiny)) == 0
    before = dataset_bytes(out)
    message = _error_of(capsys, _argv(scene_dir, out, frames=2, seed=2, **tiny))
    assert "differs in frame_count, sampling" in message and "pass --overwrite" in message
    assert dataset_bytes(out) == before
    assert cli_main(_argv(scene_dir, out, frames=2, seed=2, **tiny) + ["--overwrite"]) == 0
    assert cli_main(_argv(scene_dir, fresh, frames=2, seed=2, **tiny)) == 0
    assert all(path.read_text() == "the user's" for path in kept)
    for path in kept:
        path.unlink()
    assert dataset_bytes(out) == dataset_bytes(fresh)  # no frame 2 left over, nothing of seed 1
    capsys.readouterr()
    assert cli_main(_argv(scene_dir, out, frames=2, seed=2, **tiny) + ["--overwrite"]) == 0
    printed = capsys.readouterr().out
    assert "rendered 0 frames in" in printed  # the same settings resume, even with --overwrite
    assert "nan" not in printed  # no rate for a run that rendered nothing


def test_a_trajectory_is_one_flight_under_one_sun_and_random_poses_draw_their_own(scene_dir, tmp_path):
    """Consecutive trajectory frames differ only by motion (flow and VO assume it): one sun for the sequence,
    recorded in dataset.json; random frames keep a sun each."""
    def suns(mode: str) -> list:
        out = tmp_path / mode
        assert cli_main(_argv(scene_dir, out, frames=3, width=16, height=8, mode=mode)) == 0
        sampling = json.loads((out / "dataset.json").read_text())["sampling"]
        return [json.loads(line)["sun"] for line in (out / "sequences/00/frames.jsonl").read_text().splitlines()], \
            sampling

    trajectory, sampling = suns("trajectory")
    assert trajectory[0] == trajectory[1] == trajectory[2] and "one per sequence" in sampling["sun"]
    random, sampling = suns("random")
    assert len({json.dumps(sun) for sun in random}) == 3 and "sun" not in sampling
