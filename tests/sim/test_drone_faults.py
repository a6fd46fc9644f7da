"""The virtual drone's flight and link faults (sim.drone.flight_faults): each does what it says to the true flight, the
photos and the telemetry, leaves everything else as the same seed flies it without faults, and is in truth.json."""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from flightplan import litchi
from sim.cli import main
from sim.drone import FlightFaults, Imperfections, fly
from sim.drone.flight_faults import GUST_RISE_S, BatteryDrain, FaultAfterLanding, GimbalStuck, Gust, LinkSilence
from sim.drone.link import duml_frames
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.schedule import BATTERY_ENDURANCE_S
from tests.sim.drone_helpers import short_orbit_csv

START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)


@pytest.fixture(scope="module")
def mission_csv(tmp_path_factory):
    return short_orbit_csv(tmp_path_factory.mktemp("faults") / "arc.csv")


def flown(mission_csv, faults=FlightFaults(), imperfections=None):
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    return fly(waypoints, home_below_first_waypoint(waypoints, 100.0), imperfections or Imperfections.none(), seed=3,
               faults=faults)


def test_a_gust_pushes_the_aircraft_to_the_right_of_its_path_by_its_offset(mission_csv):
    gust = Gust(start_s=30.0, duration_s=6.0, offset_m=12.0)
    clean, pushed = flown(mission_csv), flown(mission_csv, FlightFaults(gust=gust))
    times = np.array([29.9, 30.5, 31.0, 33.0, 35.0, 35.5, 36.1])
    before, after = clean.flight.state_at(times), pushed.flight.state_at(times)
    push = after.position_enu_m - before.position_enu_m
    np.testing.assert_allclose(np.linalg.norm(push, axis=1), [0.0, 6.0, 12.0, 12.0, 12.0, 6.0, 0.0], atol=1e-9)
    assert GUST_RISE_S == 1.0  # the smoothstep is half way at 0.5 s
    travel = before.velocity_enu_mps[2, :2] / np.linalg.norm(before.velocity_enu_mps[2, :2])
    right = np.array([travel[1], -travel[0]])
    assert push[3, :2] / 12.0 == pytest.approx(right, abs=0.02) and push[3, 2] == 0.0
    inside = (pushed.photos.t_s > 31.0) & (pushed.photos.t_s < 35.0)
    assert inside.any()
    moved = pushed.photos.position_enu_m[inside] - clean.photos.position_enu_m[inside]
    np.testing.assert_allclose(np.linalg.norm(moved, axis=1), 12.0, atol=1e-9)


def test_a_link_silence_sends_nothing_in_its_window_and_the_photos_are_still_taken(mission_csv):
    silence = LinkSilence(start_s=25.0, duration_s=5.0)
    clean, silent = flown(mission_csv), flown(mission_csv, FlightFaults(link_silence=silence))
    times = np.array([frame.t_s for frame in duml_frames(silent)])
    assert not np.any((times >= 25.0) & (times < 30.0))
    assert np.any((times >= 24.8) & (times < 25.0)) and np.any((times >= 30.0) & (times < 30.2))
    np.testing.assert_array_equal(silent.photos.taken, clean.photos.taken)
    shutter = np.array([record.t_s for record in silent.telemetry.shutter])
    assert len(shutter) == len(clean.telemetry.shutter) - np.count_nonzero((clean.photos.t_s >= 25.0) &
                                                                          (clean.photos.t_s < 30.0))


def test_a_stuck_gimbal_holds_its_pitch_in_the_photos_and_the_telemetry(mission_csv):
    stuck = GimbalStuck(start_s=25.0, duration_s=5.0, pitch_deg=-80.0)
    faulty = flown(mission_csv, FlightFaults(gimbal_stuck=stuck))
    sent = {round(record.t_s, 3): record.pitch_deg for record in faulty.telemetry.gimbal}
    assert sent[25.0] == sent[29.9] == -80.0 and sent[24.9] != -80.0 and sent[30.0] != -80.0
    inside = (faulty.photos.t_s >= 25.0) & (faulty.photos.t_s < 30.0)
    assert inside.any() and np.all(faulty.photos.gimbal_ypr_deg[inside, 1] == -80.0)
    assert not np.any(faulty.photos.gimbal_ypr_deg[~inside, 1] == -80.0)


def test_a_battery_drain_runs_the_battery_down_factor_times_faster_from_its_start(mission_csv):
    drain = BatteryDrain(start_s=20.0, factor=30.0)
    faulty = flown(mission_csv, FlightFaults(battery_drain=drain))
    times = np.array([record.t_s for record in faulty.telemetry.osd])
    battery = np.array([record.battery_percent for record in faulty.telemetry.osd])
    used_s = np.where(times > 20.0, 20.0 + 30.0 * (times - 20.0), times)
    np.testing.assert_array_equal(battery, np.clip(np.round(100 * (1 - used_s / BATTERY_ENDURANCE_S)), 0, 100))
    assert battery[times <= 20.0].min() == 99 and battery[-1] < 70


def test_faults_keep_every_other_draw_of_the_seed(mission_csv):
    """The same seed with a late fault: everything before it is sent byte for byte as without it."""
    clean = flown(mission_csv, imperfections=Imperfections.realistic())
    faulty = flown(mission_csv, FlightFaults(gimbal_stuck=GimbalStuck(40.0, 2.0, -10.0)), Imperfections.realistic())
    before = [frame for frame in duml_frames(clean) if frame.t_s < 40.0]
    assert [frame for frame in duml_frames(faulty) if frame.t_s < 40.0] == before


def test_a_fault_after_the_landing_is_refused_naming_its_option(mission_csv):
    with pytest.raises(FaultAfterLanding, match=r"^--link-silence: START 5000 s: the flight lasts \d+\.\d s"):
        flown(mission_csv, FlightFaults(link_silence=LinkSilence(5000.0, 1.0)))


@pytest.mark.parametrize("make, message", [
    (lambda: Gust(10.0, 1.0, 5.0), r"--gust: DURATION 1 s: .* at least 2 s"),
    (lambda: Gust(10.0, 5.0, 0.0), r"--gust: METRES 0: expected a push in \(0, 100\] m"),
    (lambda: LinkSilence(-1.0, 5.0), r"--link-silence: START -1 s"),
    (lambda: GimbalStuck(1.0, 5.0, 10.0), r"--gimbal-stuck: PITCH 10: expected degrees in \[-90, 0\]"),
    (lambda: BatteryDrain(1.0, 1.0), r"--battery-drain: FACTOR 1: expected how many times faster"),
])
def test_faults_out_of_their_bounds_are_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_fly_records_its_faults_in_truth_json(mission_csv, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["fly", "--mission", str(mission_csv), "--scene", "demo:small", "--out", str(out), "--photo-size", "16",
            "12", "--photos", "0", "--start-utc", "2024-05-01T10:00:00Z", "--gust", "20", "4", "9",
            "--link-silence", "30", "3", "--gimbal-stuck", "35", "2", "-85", "--battery-drain", "40", "20"]
    assert main(argv) == 0
    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    duration = truth["duration_s"]
    assert truth["faults"] == [
        {"kind": "gust", "start_s": 20.0, "end_s": 24.0, "start_utc": "2024-05-01T10:00:20+00:00",
         "end_utc": "2024-05-01T10:00:24+00:00", "offset_m": 9.0},
        {"kind": "link_silence", "start_s": 30.0, "end_s": 33.0, "start_utc": "2024-05-01T10:00:30+00:00",
         "end_utc": "2024-05-01T10:00:33+00:00"},
        {"kind": "gimbal_stuck", "start_s": 35.0, "end_s": 37.0, "start_utc": "2024-05-01T10:00:35+00:00",
         "end_utc": "2024-05-01T10:00:37+00:00", "pitch_deg": -85.0},
        {"kind": "battery_drain", "start_s": 40.0, "end_s": duration, "start_utc": "2024-05-01T10:00:40+00:00",
         "end_utc": (START + dt.timedelta(seconds=duration)).isoformat(), "factor": 20.0}]
    assert [30.0, 33.0] in truth["link_dropouts_s"]
    capsys.readouterr()


def test_fly_without_faults_records_none(mission_csv, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fly", "--mission", str(mission_csv), "--scene", "demo:small", "--out", str(out), "--photo-size",
                 "16", "12", "--photos", "0", "--start-utc", "2024-05-01T10:00:00Z"]) == 0
    assert json.loads((out / "truth.json").read_text(encoding="utf-8"))["faults"] == []
    capsys.readouterr()
