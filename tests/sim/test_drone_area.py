"""The virtual drone flying every flight of an area plan: a GPS fix offset per flight, one folder per flight."""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import replace

import numpy as np
import pytest

from flightplan import litchi
from sim.cli import main
from sim.drone import Imperfections, fly
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.session import BATTERY_SWAP_S
from sim.worlds.demo import build_demo_world
from tests.sim.drone_helpers import short_orbit_csv

HOME_H = 1000.0


@pytest.fixture(scope="module")
def mission_csv(tmp_path_factory):
    return short_orbit_csv(tmp_path_factory.mktemp("mission") / "short.csv")


def flown(mission_csv, imperfections, seed):
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    return fly(waypoints, home_below_first_waypoint(waypoints, HOME_H), imperfections, seed=seed)


def test_the_fix_offset_is_the_whole_gps_error_when_alone(mission_csv):
    """With only the fix offset, every photo's measured position (geotag) is the true one moved by it, and the
    recorded home point's height is off by its vertical part."""
    mission = flown(mission_csv, Imperfections(gps_fix_bias_std_m=1.0), seed=(3, 2))
    bias = mission.sensors.gps_fix_bias_enu_m
    photos, frame = mission.photos, mission.flight.frame
    measured = frame.enu_points(photos.measured_latitude_deg, photos.measured_longitude_deg,
                                frame.h0_m + photos.position_enu_m[:, 2] + bias[2])  # the fix it came from
    np.testing.assert_allclose(measured[:, :2] - photos.position_enu_m[:, :2], np.tile(bias[:2], (len(measured), 1)),
                               atol=1e-6)
    assert mission.sensors.measured_home()[2] == pytest.approx(frame.h0_m + bias[2], abs=1e-6)
    assert np.linalg.norm(bias) > 0.05


def test_each_flight_draws_its_own_offset_from_seed_and_number_and_nothing_else_moves(mission_csv):
    """The offset depends on (seed, flight number) only; adding it leaves every other random draw as it was."""
    area = Imperfections.area()
    biases = [flown(mission_csv, area, seed=(7, k)).sensors.gps_fix_bias_enu_m for k in (1, 2, 3)]
    assert min(np.linalg.norm(a - b) for i, a in enumerate(biases) for b in biases[i + 1:]) > 1e-3
    np.testing.assert_array_equal(flown(mission_csv, area, seed=(7, 2)).sensors.gps_fix_bias_enu_m, biases[1])
    without = flown(mission_csv, replace(area, gps_fix_bias_std_m=0.0), seed=(7, 2)).sensors
    with_offset = flown(mission_csv, area, seed=(7, 2)).sensors
    np.testing.assert_allclose(with_offset.gps_error_enu_m - without.gps_error_enu_m,
                               np.tile(biases[1], (len(without.gps_error_enu_m), 1)), atol=1e-12)
    np.testing.assert_array_equal(with_offset.baro_error_m, without.baro_error_m)
    # horizontal std 1 m, vertical 2 m (the GPS vertical factor), over many flights
    many = np.array([flown(mission_csv, area, seed=(7, k)).sensors.gps_fix_bias_enu_m for k in range(1, 61)])
    assert 0.6 < many[:, :2].std() < 1.4 and 1.2 < many[:, 2].std() < 2.8


# "now" with a fixed sun: the real one may be down when the test runs. The flights stay a time table from the first
# one's start: a clock following this machine's would start each when it is written.
@pytest.mark.parametrize("start", [["--start-utc", "2024-05-01T10:00:00Z"],
                                   ["--start-utc", "now", "--sun", "150,50,10"]], ids=["given", "now"])
def test_cli_flies_every_mission_into_its_own_folder(mission_csv, tmp_path, capsys, start):
    scene_dir = build_demo_world(tmp_path / "world", variant="small", seed=0)
    out = tmp_path / "out"
    argv = ["fly", "--mission", str(mission_csv), "--mission", str(mission_csv), "--scene", str(scene_dir),
            "--out", str(out), "--photo-size", "64", "48", "--photos", "1", "--seed", "5", *start]
    assert main(argv) == 0
    assert capsys.readouterr().out.count("GPS fix offset") == 2
    truths = [json.loads((out / f"flight_0{k}" / "truth.json").read_text(encoding="utf-8")) for k in (1, 2)]
    for number, truth in enumerate(truths, start=1):
        assert truth["seed"] == [5, number]
        assert truth["imperfections"] == Imperfections.area().to_dict()
        assert (out / f"flight_{number:02d}" / "flight.duml").is_file()
        assert sorted(p.name for p in (out / f"flight_{number:02d}" / "photos").iterdir()) == ["DJI_0001.JPG"]
        expected = flown(mission_csv, Imperfections.area(), seed=(5, number)).sensors.gps_fix_bias_enu_m
        np.testing.assert_allclose(truth["gps_fix_bias_enu_m"], expected, atol=1e-12)
    landed = dt.datetime.fromisoformat(truths[0]["start_utc"]) + dt.timedelta(seconds=truths[0]["duration_s"])
    assert dt.datetime.fromisoformat(truths[1]["start_utc"]) == landed + dt.timedelta(seconds=BATTERY_SWAP_S)
    assert truths[0]["gps_fix_bias_enu_m"] != truths[1]["gps_fix_bias_enu_m"]


def test_cli_refuses_an_earlier_flight_and_overwrite_removes_only_its_files(mission_csv, tmp_path, capsys):
    """An --out holding a flight (three area flights of two photos) is refused whole, before anything is written;
    --overwrite replaces it by two flights of one photo (no third flight or second photo of the old one left: a
    mixed flight), then by one flight at the top, and keeps the files that are not a flight's."""
    scene_dir = build_demo_world(tmp_path / "world", variant="small", seed=0)
    out = tmp_path / "out"

    def fly_into_out(missions: int, photos: int, *extra: str) -> int:
        capsys.readouterr()
        return main(["fly", *["--mission", str(mission_csv)] * missions, "--scene", str(scene_dir), "--out", str(out),
                     "--photo-size", "64", "48", "--photos", str(photos), "--start-utc", "2024-05-01T10:00:00Z",
                     *extra])

    assert fly_into_out(3, 2) == 0
    (out / "notes.txt").write_text("mine")
    (out / "flight_01" / "notes.txt").write_text("mine too")
    before = {path: path.read_bytes() for path in out.rglob("*") if path.is_file()}
    assert fly_into_out(2, 1) == 2
    error = capsys.readouterr().err.splitlines()
    assert error == [f"aerostereo-render fly: error: --out {out}: holds an earlier flight (flight_01/photos); pass "
                     "--overwrite to replace it, or choose another folder"]
    assert {path: path.read_bytes() for path in out.rglob("*") if path.is_file()} == before
    assert fly_into_out(2, 1, "--overwrite") == 0
    assert sorted(path.name for path in out.iterdir()) == ["flight_01", "flight_02", "notes.txt"]
    for number in (1, 2):
        assert sorted(path.name for path in (out / f"flight_0{number}" / "photos").iterdir()) == ["DJI_0001.JPG"]
    assert (out / "flight_01" / "notes.txt").read_text() == "mine too"
    assert fly_into_out(1, 1, "--overwrite") == 0
    assert sorted(path.name for path in out.rglob("*")) == sorted([
        "flight.duml", "flight.duml.idx", "truth.json", "truth.csv", "photos", "DJI_0001.JPG", "notes.txt",
        "flight_01", "notes.txt"])


def test_cli_takes_off_from_home_and_refuses_one_off_the_scene(mission_csv, tmp_path, capsys):
    """``--home`` (an area plan's take-off) is the flight's origin on the scene's ground, and the drone transits from
    it to the first waypoint, so the flight lasts longer than one taking off below it; a home with no ground under
    it is one line naming --home, exit 2, and nothing written."""
    scene_dir = build_demo_world(tmp_path / "world", variant="small", seed=0)
    first = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))[0]
    home = (first.latitude_deg - 0.0004, first.longitude_deg + 0.0004)  # ~ 44 m south, 34 m east of waypoint 1
    common = ["fly", "--mission", str(mission_csv), "--scene", str(scene_dir), "--photo-size", "64", "48",
              "--photos", "1", "--start-utc", "2024-05-01T10:00:00Z"]
    assert main([*common, "--out", str(tmp_path / "below")]) == 0
    assert main([*common, "--out", str(tmp_path / "home"), "--home", *map(str, home)]) == 0
    below, from_home = (json.loads((tmp_path / name / "truth.json").read_text(encoding="utf-8"))
                        for name in ("below", "home"))
    assert (from_home["origin"]["lat0_deg"], from_home["origin"]["lon0_deg"]) == pytest.approx(home, abs=1e-12)
    assert from_home["duration_s"] > below["duration_s"] + 2 * 50.0 / 10.0  # there and back at <= 10 m/s
    capsys.readouterr()
    assert main([*common, "--out", str(tmp_path / "off"), "--home", "40.0", "44.0"]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "--home 40.0 44.0" in error[0] and "no ground" in error[0]
    assert not (tmp_path / "off").exists()


def test_an_rtk_flight_measures_centimetres_with_no_offset_and_its_photos_say_so(mission_csv, tmp_path):
    """``--noise rtk``: each photo's measured position is the truth + 1.2 cm white noise per horizontal axis and
    2.4 cm in height (no drift, no fix offset), and its XMP marks an RTK fixed solution that the SfM priors take
    at the receiver's word (floored at 2 cm); a consumer flight's photo keeps the consumer sigma."""
    from recon.inputs.priors import DEFAULT_SIGMA_M, RTK_SIGMA_FLOOR_M, receiver_sigma
    from sim.drone.photos import photo_camera, photo_geotag, write_dji_jpeg

    mission = flown(mission_csv, Imperfections.rtk(), seed=(5, 1))
    photos, frame = mission.photos, mission.flight.frame
    assert not mission.sensors.gps_fix_bias_enu_m.any()
    measured = frame.enu_points(photos.measured_latitude_deg, photos.measured_longitude_deg,
                                np.full(len(photos.t_s), frame.h0_m))
    horizontal = (measured[:, :2] - photos.position_enu_m[:, :2]).ravel()
    height = photos.measured_height_above_takeoff_m - photos.position_enu_m[:, 2]
    assert len(horizontal) > 50 and abs(horizontal.mean()) < 0.005 and 0.008 < horizontal.std() < 0.017
    assert 0.016 < height.std() < 0.034 and np.abs(height).max() < 0.15

    rgb = np.zeros((30, 40, 3), np.uint8)
    for name, rtk_std_m in (("DJI_0001.JPG", mission.flight.imperfections.rtk_std_m), ("DJI_0002.JPG", 0.0)):
        write_dji_jpeg(tmp_path / name, rgb, photo_geotag(photos, 0, HOME_H, name),
                       dt.datetime(2024, 5, 1, 10), photo_camera(40, 30), rtk_std_m=rtk_std_m)
    np.testing.assert_allclose(receiver_sigma(tmp_path / "DJI_0001.JPG"), [RTK_SIGMA_FLOOR_M, RTK_SIGMA_FLOOR_M, 0.024])
    np.testing.assert_allclose(receiver_sigma(tmp_path / "DJI_0002.JPG"), DEFAULT_SIGMA_M)
