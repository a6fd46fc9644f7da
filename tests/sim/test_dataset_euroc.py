"""The EuRoC layout of a rendered stereo-inertial orbit, read back the way EuRoC's consumers read it: evo reads
the ground truth, the sensor.yaml files parse as YAML, image names are 19-digit Unix nanoseconds that sort in time
order and parse as Kalibr's bag creator parses them, timestamps agree between cameras, IMU and ground truth, and
the IMU integrated from the first ground-truth state lands on the rendered camera poses."""

from __future__ import annotations

import datetime as dt
import json
import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from evo.tools.file_interface import read_euroc_csv_trajectory

from sim.dataset.export import check_layouts, export_dataset
from sim.dataset.imu_file import read_imu_csv
from sim.dataset.writer import DatasetError, dataset_description
from drone_helpers import short_orbit_csv
from sim.drone import Imperfections
from sim.drone.session import fly_litchi_mission
from sim.sampling.light import SunSetting
from sim.run.options import (LightOptions, OutputOptions, PoseOptions, RenderInputError, RenderOptions,
                             RigOptions)
from sim.motion.imu import EUROC_ADIS16448, dead_reckon
from sim.run.render_dataset import render_dataset, resolve_scene_dir
from sim.render.scene import load_scene

FRAMES, FRAME_RATE_HZ, IMU_RATE_HZ = 21, 10.0, 200.0
#: Frame 0's Unix time when the dataset records none: 2001-09-09T01:46:40Z (docs/dataset-format.md, "euroc").
FIXED_START_NS = 10**18


def render(out: Path, overwrite: bool = False, seed: int = 0, sun=None, **changes) -> Path:
    options = render_options(seed, sun, **changes)
    render_dataset("demo:small", out, options, command_line=["test"], progress=False, overwrite=overwrite)
    return out


def render_options(seed: int = 0, sun=None, **changes) -> RenderOptions:
    poses = PoseOptions(**{"frames": FRAMES, "mode": "trajectory", "trajectory": "orbit",
                           "frame_rate_hz": FRAME_RATE_HZ, "imu_rate_hz": IMU_RATE_HZ, **changes})
    return RenderOptions(seed=seed, rig=RigOptions(width=96, height=64), poses=poses, light=LightOptions(sun),
                         outputs=OutputOptions(("depth_exr",)))


@pytest.fixture(scope="module")
def euroc(tmp_path_factory):
    """(rendered dataset, its EuRoC export's mav0 folder)."""
    source = render(tmp_path_factory.mktemp("render") / "dataset")
    out = tmp_path_factory.mktemp("euroc")
    export_dataset(source, out, ["euroc"])
    return source, out / "mav0"


def frame_records(source: Path) -> list[dict]:
    return [json.loads(line) for line in (source / "sequences/00/frames.jsonl").read_text().splitlines()]


def sensor(mav0: Path, name: str) -> dict:
    return yaml.safe_load((mav0 / name / "sensor.yaml").read_text())


def matrix(entry: dict) -> np.ndarray:
    return np.array(entry["data"], dtype=np.float64).reshape(entry["rows"], entry["cols"])


def test_evo_reads_the_ground_truth_and_it_carries_the_rendered_cameras(euroc):
    source, mav0 = euroc
    truth = read_euroc_csv_trajectory(str(mav0 / "state_groundtruth_estimate0/data.csv"))
    T_body_cam0 = matrix(sensor(mav0, "cam0")["T_BS"])
    by_time = dict(zip(first_column_ns(mav0 / "state_groundtruth_estimate0/data.csv"), truth.poses_se3))
    for record in frame_records(source):
        T_world_body = by_time[FIXED_START_NS + round(record["time_s"] * 1e9)]
        np.testing.assert_allclose(T_world_body @ T_body_cam0, record["T_world_cam"], atol=1e-9)
    T_body_cam1 = matrix(sensor(mav0, "cam1")["T_BS"])
    baseline = np.linalg.inv(T_body_cam0) @ T_body_cam1
    np.testing.assert_allclose(baseline[:3, 3], [0.54, 0.0, 0.0], atol=1e-12)  # the rig's right camera


def first_column_ns(path: Path) -> np.ndarray:
    """The timestamps (first column, integer nanoseconds) of a EuRoC ``data.csv``."""
    return np.loadtxt(path, delimiter=",", comments="#", dtype=np.int64, usecols=0)


def kalibr_time_ns(stem: str) -> int:
    """An image name's time as Kalibr's bag creator (kalibr_bagcreater) reads it: seconds = all but the last nine
    digits, nanoseconds = the last nine."""
    secs, nsecs = int(stem[0:-9]), int(stem[-9:])
    return secs * 10**9 + nsecs


def test_image_names_are_19_digit_unix_nanoseconds_in_time_order(euroc):
    """What DROID-SLAM's EuRoC script (sorted folder listing) and Kalibr's bag creator (name split after the
    seconds) read: sorting the names sorts the frames by time, and each name gives back its frame's time on the
    Unix clock, from 2001-09-09T01:46:40Z for a dataset that records no real time."""
    source, mav0 = euroc
    frame_ns = [FIXED_START_NS + round(record["time_s"] * 1e9) for record in frame_records(source)]
    for view in (0, 1):
        names = sorted(os.listdir(mav0 / f"cam{view}/data"))
        stems = [Path(name).stem for name in names]
        assert all(len(stem) == 19 and stem.isdigit() for stem in stems)
        assert [kalibr_time_ns(stem) for stem in stems] == frame_ns  # the sorted names are the frames in order
    assert frame_ns[10] - frame_ns[0] == 10**9 and kalibr_time_ns("1000000001000000000") == frame_ns[10]


def test_timestamps_agree_between_cameras_imu_and_ground_truth(euroc):
    source, mav0 = euroc
    cam0, cam1 = (np.array([line.split(",") for line in (mav0 / f"cam{v}/data.csv").read_text().splitlines()[1:]])
                  for v in (0, 1))
    np.testing.assert_array_equal(cam0, cam1)
    stamps = cam0[:, 0].astype(np.int64)
    np.testing.assert_array_equal(stamps, FIXED_START_NS + np.arange(FRAMES) * 100_000_000)
    assert [f"{stamp}.png" for stamp in cam0[:, 0]] == list(cam0[:, 1])
    assert all((mav0 / f"cam{v}/data" / name).is_file() for v in (0, 1) for name in cam0[:, 1])
    grey = source / "sequences/00/image_1/000004.png"
    assert (mav0 / "cam1/data" / cam0[4, 1]).read_bytes() == grey.read_bytes()
    imu = first_column_ns(mav0 / "imu0/data.csv")
    truth = first_column_ns(mav0 / "state_groundtruth_estimate0/data.csv")
    np.testing.assert_array_equal(imu, truth)
    np.testing.assert_array_equal(imu, FIXED_START_NS + np.arange(len(imu)) * 5_000_000)
    assert set(stamps) <= set(imu) and imu[0] == stamps[0] and imu[-1] == stamps[-1]  # one clock for all sensors


def test_a_dataset_rendered_at_a_utc_time_starts_at_it(tmp_path):
    """``--sun time:UTC``: frame 0 is at that UTC on the Unix clock, for cameras, IMU and ground truth alike; a time
    before 2001-09-09 has 18 digits of nanoseconds and is zero-padded to EuRoC's 19."""
    utc = dt.datetime(2000, 6, 1, 8, 0, 0, 250000, tzinfo=dt.timezone.utc)
    source = render(tmp_path / "dataset", frames=2, sun=SunSetting("time", utc=utc))
    export_dataset(source, tmp_path / "out", ["euroc"])
    mav0 = tmp_path / "out" / "mav0"
    start_ns = 959_846_400_250_000_000  # 2000-06-01T08:00:00.25Z
    names = sorted(os.listdir(mav0 / "cam0/data"))
    assert names == ["0959846400250000000.png", "0959846400350000000.png"]
    assert [kalibr_time_ns(Path(name).stem) for name in names] == [start_ns, start_ns + 100_000_000]
    for sensor_csv in ("imu0/data.csv", "state_groundtruth_estimate0/data.csv"):
        stamps = first_column_ns(mav0 / sensor_csv)
        np.testing.assert_array_equal(stamps, start_ns + np.arange(len(stamps)) * 5_000_000)
    assert (mav0 / "imu0/data.csv").read_text().splitlines()[1].startswith("0959846400250000000,")


@pytest.mark.parametrize("utc", ["1969-12-31T10:00:00Z", "2300-06-01T10:00:00Z"])
def test_a_utc_the_unix_nanosecond_clock_cannot_hold_is_refused(tmp_path, utc):
    """Before 1970 Unix time is negative, after 2255 an int64 of nanoseconds runs out within a few years: refused
    when the render is planned, naming dataset.json and the UTC."""
    out = tmp_path / "dataset"
    with pytest.raises(DatasetError, match=rf"dataset.json: --export euroc times frames in Unix nanoseconds from the "
                                           rf"sun's UTC {utc}, which must lie between 1970 and 2255"):
        render_dataset("demo:small", out, render_options(sun=SunSetting("time", utc=dt.datetime.fromisoformat(utc))),
                       command_line=["test"], progress=False,
                       check_spec=lambda spec: check_layouts(["euroc"], out, dataset_description(spec)))
    assert not out.exists()


def test_sensor_yaml_files_say_what_was_rendered(euroc):
    source, mav0 = euroc
    camera, imu = sensor(mav0, "cam0"), sensor(mav0, "imu0")
    description = json.loads((source / "dataset.json").read_text())["cameras"][0]
    assert camera["resolution"] == [96, 64] and camera["rate_hz"] == FRAME_RATE_HZ
    assert camera["intrinsics"] == [description[key] for key in ("fx", "fy", "cx", "cy")]
    assert camera["distortion_coefficients"] == [0, 0, 0, 0]
    assert imu["rate_hz"] == IMU_RATE_HZ and np.array_equal(matrix(imu["T_BS"]), np.eye(4))
    for name, value in EUROC_ADIS16448.to_dict().items():
        assert imu[name] == value


def test_imu_integrated_from_the_first_ground_truth_state_reaches_the_last(euroc):
    """The noise-free samples of the dataset's IMU record integrated from the first EuRoC ground-truth state end on
    its last state (2 s of orbit); the EuRoC samples minus the ground-truth biases differ from them by white noise
    of the configured density."""
    source, mav0 = euroc
    truth = np.loadtxt(mav0 / "state_groundtruth_estimate0/data.csv", delimiter=",", comments="#")
    poses = read_euroc_csv_trajectory(str(mav0 / "state_groundtruth_estimate0/data.csv")).poses_se3
    record = read_imu_csv(source / "imu/00.csv")
    gyro = np.column_stack([record[f"w_true_{axis}"] for axis in "xyz"])
    accel = np.column_stack([record[f"a_true_{axis}"] for axis in "xyz"])
    R, _, p = dead_reckon(gyro, accel, IMU_RATE_HZ, poses[0][:3, :3], truth[0, 8:11], poses[0][:3, 3])
    assert np.linalg.norm(p - poses[-1][:3, 3]) < 1e-4
    assert np.abs(R - poses[-1][:3, :3]).max() < 1e-6
    measured = np.loadtxt(mav0 / "imu0/data.csv", delimiter=",", comments="#")
    white = measured[:, 4:7] - truth[:, 14:17] - accel
    expected = EUROC_ADIS16448.accelerometer_noise_density * np.sqrt(IMU_RATE_HZ)
    assert np.std(white) == pytest.approx(expected, rel=0.1)


def test_euroc_needs_a_dataset_rendered_with_an_imu(tmp_path):
    source = render(tmp_path / "plain", frames=2, imu_rate_hz=None)
    with pytest.raises(DatasetError, match=r"dataset.json: the euroc layout needs an IMU.*--imu"):
        export_dataset(source, tmp_path / "out", ["euroc"])
    assert not (tmp_path / "out").exists()


def test_overwrite_removes_the_imu_record_with_its_dataset(tmp_path):
    source = render(tmp_path / "dataset", frames=2)
    assert (source / "imu/00.csv").is_file()
    render(source, overwrite=True, frames=2, imu_rate_hz=None)
    assert not (source / "imu").exists() and (source / "sequences/00/frames.jsonl").is_file()


@pytest.mark.parametrize("changes, message", [
    ({"mode": "random"}, "--imu needs --mode trajectory"),
    ({"imu_rate_hz": 15.0}, r"IMU rate \(15.0 Hz\) must be a whole multiple of the frame rate \(10.0 Hz\)"),
])
def test_render_refuses_an_imu_it_cannot_synthesize(tmp_path, changes, message):
    with pytest.raises(RenderInputError, match=message):
        render(tmp_path / "dataset", **changes)
    assert not (tmp_path / "dataset").exists()


def test_a_virtual_flight_renders_along_the_drones_gusty_flown_path(tmp_path):
    """``--trajectory flight``: the body follows the virtual drone's true flown path (gusts from the seed) from the
    first waypoint on, moved into the scene's frame; the frames' cameras sit on it at ``T_BS``."""
    mission = short_orbit_csv(tmp_path / "mission.csv")
    source = render(tmp_path / "dataset", trajectory="flight", mission=mission, frames=8, seed=3)
    scene = load_scene(resolve_scene_dir("demo:small"))
    flight = fly_litchi_mission(mission, scene, 3, Imperfections.realistic()).flight
    assert flight.imperfections.gust_offset_std_m > 0
    record = read_imu_csv(source / "imu/00.csv")
    t = record["timestamp_ns"] / 1e9
    truth = flight.state_at(flight.waypoint_times_s()[0] + t)
    T = flight.frame.transform_to(scene.origin)
    expected = truth.position_enu_m @ T[:3, :3].T + T[:3, 3]
    body = np.column_stack([record[f"p_{axis}"] for axis in "xyz"])
    assert np.abs(body - expected).max() < 1e-3
    T_body_cam0 = np.array(json.loads((source / "dataset.json").read_text())["sampling"]["imu"]["T_body_cam"][0])
    T_world_body = np.array(frame_records(source)[0]["T_world_cam"]) @ np.linalg.inv(T_body_cam0)
    np.testing.assert_allclose(T_world_body[:3, 3], body[0], atol=1e-9)  # frame 0 is the first IMU sample


def test_one_command_renders_a_virtual_flight_as_euroc_with_flow_and_effects(tmp_path, capsys):
    """The issue's one command: a virtual flight rendered with an IMU, rolling shutter and vignetting, written as
    EuRoC and KITTI flow in the same run (``--export``); an export folder inside ``--out`` is refused first."""
    from sim.cli import main

    mission = short_orbit_csv(tmp_path / "mission.csv")
    argv = ["--scene", "demo:small", "--out", str(tmp_path / "flight"), "--mode", "trajectory", "--trajectory",
            "flight", "--mission", str(mission), "--imu", "--frames", "3", "--width", "64", "--height", "48",
            "--line-delay", "2e-4", "--vignetting", "cos4", "--quiet", "--export", "euroc,kitti_flow"]
    assert main([*argv, "--export-out", str(tmp_path / "flight" / "export")]) == 2
    assert "--export-out" in capsys.readouterr().err and not (tmp_path / "flight").exists()
    assert main([*argv, "--export-out", str(tmp_path / "export")]) == 0
    out = capsys.readouterr().out
    assert "euroc:" in out and "kitti_flow: 2 frame pairs" in out
    mav0 = tmp_path / "export" / "mav0"
    assert len(list((mav0 / "cam0" / "data").glob("*.png"))) == 3
    assert len(read_euroc_csv_trajectory(str(mav0 / "state_groundtruth_estimate0" / "data.csv")).timestamps) == 41
    assert len(list((tmp_path / "export" / "training" / "flow_noc").glob("*_10.png"))) == 2
    effects = json.loads((tmp_path / "flight" / "dataset.json").read_text())["sampling"]["effects"]
    assert effects["rolling_shutter"]["line_delay_s"] == 2e-4 and "vignetting" in effects
