"""The live view's state (capture.live_state, capture.live_plan) on synthetic messages with known answers: a straight
100 m leg north at 2 m/s, 30 m up, a photo every 2 s, the gimbal planned at -60 degrees, home under its start."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from capture.live_plan import CRUISE_SPEED_MPS, DESCENT_RATE_MPS, planned_path
from capture.live_state import SHUTTER_JITTER_S, LiveLimits, LiveState
from capture.messages import CameraState, GimbalParams, HomePoint, OsdGeneral
from flightplan import litchi
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import LocalFrame
from flightplan.orbit import OrbitRequest, plan_orbit

LAT0, LON0 = DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg
FRAME = LocalFrame(LAT0, LON0, 0.0)
LEG_M, SPEED, INTERVAL, PITCH, HEIGHT = 100.0, 2.0, 2.0, -60.0, 30.0
OSD = OsdGeneral(0.0, 0.0, HEIGHT, 0.0, SPEED, 0.0, 0.0, 0.0, 0.0, ctrl_info=14, latest_app_command=0,
                 controller_state=5 << 18, gps_satellites=14, gohome_reason=0, motor_start_fail=0, ctrl_state_ext=0,
                 battery_percent=100, ultrasonic_height_m=0.0, fly_time_s=0.0, motor_start_count=1, battery_alarm1=0,
                 battery_alarm2=0, version_match=1, product_type=0, imu_init_fail_reason=0)
CAMERA = CameraState(status_flags=1 << 9, camera_mode=0, sd_total_mb=30000, sd_free_mb=20000, remaining_shots=999,
                     remaining_time_s=0, file_index_mode=0)
SHOOTING = dataclasses.replace(CAMERA, status_flags=CAMERA.status_flags | 1 << 3)  # photo_state 1: a shot
PUSH_S = 0.2  # camera pushes at 5 Hz


def mission() -> litchi.Mission:
    lat, lon, _ = FRAME.to_geodetic(0.0, LEG_M, 0.0)
    start = litchi.Waypoint(LAT0, LON0, HEIGHT, gimbal_mode=litchi.GIMBAL_INTERPOLATE, gimbal_pitch_deg=PITCH,
                            speed_m_s=SPEED, photo_time_interval_s=INTERVAL)
    return litchi.Mission((start, dataclasses.replace(start, latitude_deg=float(lat), longitude_deg=float(lon))))


def osd_at(east_m: float, north_m: float, **fields) -> OsdGeneral:
    lat, lon, _ = FRAME.to_geodetic(east_m, north_m, 0.0)
    return dataclasses.replace(OSD, latitude_deg=float(lat), longitude_deg=float(lon), **fields)


def gimbal(pitch_deg: float) -> GimbalParams:
    return GimbalParams(pitch_deg, 0.0, 0.0, mode_flags=2 << 6, roll_adjust_deg=0.0, joystick_yaw_deg=0.0,
                        limit_flags=0, version_flags=1)


def started_state(limits: LiveLimits = LiveLimits()) -> LiveState:
    """A state that has seen the home point under the first waypoint and the aircraft there, 30 m up, at t = 0."""
    state = LiveState(planned_path(mission()), limits)
    state.on_packet(0.0, HomePoint(LON0, LAT0, 100.0, 1, 30, 0, 0, 0, 0, 0))
    state.on_packet(0.0, osd_at(0.0, 0.0))
    assert state.progress.on_mission
    return state


def fly_straight(state: LiveState, until_s: float, east_m=lambda t: 0.0, shots=(), step_s: float = 0.1,
                 start_s: float = 0.0, battery=lambda t: 100, pitch=lambda t: PITCH) -> None:
    """OSD and gimbal every ``step_s`` at the leg's speed, ``east_m(t)`` off it; camera pushes every 0.2 s with a
    shot at the first push at or after each of ``shots``; a tick after each."""
    times = np.round(np.arange(start_s, until_s + 1e-9, step_s), 6)
    pushes = set(np.round(np.arange(start_s, until_s + 1e-9, PUSH_S), 6).tolist())
    shot_pushes = {min(p for p in pushes if p >= shot - 1e-9) for shot in shots}
    for t in times.tolist():
        state.on_packet(t, osd_at(east_m(t), SPEED * t, battery_percent=battery(t)))
        state.on_packet(t, gimbal(pitch(t)))
        if t in pushes:
            state.on_packet(t, SHOOTING if t in shot_pushes else CAMERA)
        state.tick(t)


def kinds(state: LiveState) -> list[str]:
    return [alert.kind for alert in state.warnings]


def test_the_plan_of_a_straight_leg_has_its_length_time_photos_and_pitch():
    plan = planned_path(mission())
    assert plan.length_m == pytest.approx(LEG_M, abs=1e-6)
    assert plan.time_to_finish_s(0.0) == pytest.approx(LEG_M / SPEED)
    assert plan.time_to_finish_s(40.0) == pytest.approx((LEG_M - 40.0) / SPEED)
    assert plan.planned_photos() == LEG_M / SPEED / INTERVAL
    assert plan.gimbal_pitch_at(50.0) == PITCH
    assert plan.along_after_s(10.0) == pytest.approx(10.0 * SPEED) and plan.along_after_s(1e3) == plan.length_m
    assert plan.locate(3.0, 40.0, 0.0) == pytest.approx((40.0, 3.0), abs=1e-6)


def test_the_plan_of_the_default_orbit_is_what_the_virtual_drone_flies():
    """Photos planned and the gimbal pitch against the virtual drone's own schedule of the same CSV (its truth)."""
    from sim.drone import Flight
    from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
    orbit = plan_orbit(OrbitRequest(LAT0, LON0)).mission
    waypoints = waypoints_from_litchi(orbit)
    flight = Flight(waypoints, home_below_first_waypoint(waypoints, 100.0))
    plan = planned_path(orbit)
    assert plan.planned_photos() == len(flight.photo_times_s())
    np.testing.assert_allclose(plan.gimbal_pitch_deg, flight.waypoint_gimbal_pitch_deg, atol=0.01)
    assert plan.time_to_finish_s(0.0) == pytest.approx(np.ptp(flight.waypoint_times_s()), rel=0.02)


def test_a_clean_straight_flight_raises_nothing_and_counts_its_photos():
    state = started_state()
    fly_straight(state, 40.0, shots=np.arange(1.0, 40.0, INTERVAL))
    assert state.warnings == []
    assert state.photos == 20
    assert state.longest_gap_s == pytest.approx(INTERVAL, abs=PUSH_S + 1e-9)
    assert state.progress.along_m == pytest.approx(80.0, abs=1e-3) and state.progress.cross_m < 1e-3
    assert state.progress.along_error_m == pytest.approx(0.0, abs=1e-3)


def test_an_aircraft_slower_than_the_plan_is_behind_it_along_the_track():
    state = started_state()
    for t in np.arange(0.0, 20.01, 0.5):
        state.on_packet(t, osd_at(0.0, 0.75 * SPEED * t))
    assert state.progress.along_error_m == pytest.approx(-0.25 * SPEED * 20.0, abs=1e-3)


def test_off_the_path_is_warned_from_the_first_position_beyond_the_limit_until_it_is_back():
    state = started_state(LiveLimits(off_path_m=5.0))
    fly_straight(state, 20.0, east_m=lambda t: 8.0 if 10.0 <= t < 14.0 else 3.0, shots=np.arange(1.0, 20.0, 2.0))
    assert kinds(state) == ["off_path"]
    alert = state.warnings[0]
    assert (alert.start_t, alert.end_t) == (10.0, 14.0)
    assert "8.0 m off the path on leg 1" in alert.message


def test_a_gimbal_off_its_planned_pitch_is_warned_and_a_small_error_is_not():
    state = started_state(LiveLimits(gimbal_tolerance_deg=5.0))
    fly_straight(state, 20.0, pitch=lambda t: PITCH + (20.0 if 5.0 <= t < 8.0 else 4.0),
                 shots=np.arange(1.0, 20.0, 2.0))
    assert kinds(state) == ["gimbal"]
    assert (state.warnings[0].start_t, state.warnings[0].end_t) == (5.0, 8.0)


def test_a_shutter_gap_beyond_one_skipped_shot_is_warned_when_it_grows_past_the_limit():
    state = started_state()
    shots = [1.0, 3.0, 5.0, 9.0, 17.0, 19.0]  # one skipped shot at 7 (allowed), then three at 11, 13, 15
    fly_straight(state, 20.0, shots=shots)
    assert kinds(state) == ["shutter_gap"]
    allowed = 2 * INTERVAL + SHUTTER_JITTER_S
    alert = state.warnings[0]
    assert 9.0 + allowed < alert.start_t <= 9.0 + allowed + 0.1 + 1e-9 and alert.end_t == 17.0
    assert state.longest_gap_s == pytest.approx(8.0)
    assert state.photos == len(shots)


def test_a_gap_with_lost_camera_pushes_is_not_the_cameras():
    state = started_state()
    for t in np.round(np.arange(0.0, 10.0, 0.1), 6).tolist():  # pushes lost from 4.1 s to 9.9 s
        state.on_packet(t, osd_at(0.0, SPEED * t))
        if t <= 4.0 and round(t / PUSH_S, 6).is_integer():
            state.on_packet(t, SHOOTING if t in (2.0, 4.0) else CAMERA)
        state.tick(t)
    state.on_packet(9.8, CAMERA)
    state.on_packet(10.0, SHOOTING)
    state.tick(10.0)
    assert state.warnings == [] and state.photos == 3
    assert state.longest_gap_s == pytest.approx(2.0)  # the 6 s across the hole is not counted


def test_a_silent_link_is_warned_after_the_limit_and_cleared_by_the_next_packet():
    state = started_state(LiveLimits(silent_after_s=1.0))
    fly_straight(state, 10.0, shots=np.arange(1.0, 10.0, 2.0))
    state.tick(10.9)
    assert state.warnings == []
    state.tick(11.05)
    assert kinds(state) == ["link_silent"] and state.warnings[0].start_t == 11.05
    state.on_packet(13.0, osd_at(0.0, 26.0))
    assert state.warnings[0].end_t == 13.0 and state.active == {}


def test_time_left_is_the_rest_of_the_path_and_the_way_home():
    state = started_state()
    fly_straight(state, 10.0, shots=np.arange(1.0, 10.0, 2.0))
    home_s = LEG_M / CRUISE_SPEED_MPS + HEIGHT / DESCENT_RATE_MPS  # from the leg's end back over the start and down
    assert state.time_left_s() == pytest.approx((LEG_M - 20.0) / SPEED + home_s, abs=1e-3)


def test_the_battery_rate_is_read_from_its_changes_and_a_fast_drain_is_warned():
    """At 1 % per 15 s (a 25 min battery) one change in 10 s gives no rate and nothing is warned; at 3 %/s from 10 s the
    rate read is the drain's and the warning comes as soon as the rest would need more than is left."""
    state = started_state()
    fly_straight(state, 10.0, shots=np.arange(1.0, 10.0, 2.0), battery=lambda t: round(100 - t / 15))
    assert state.battery_rate_percent_per_s() <= 1 / 15 and state.warnings == []

    def draining(t):
        return round(100 - t / 15 - (3.0 * (t - 10.0) if t > 10.0 else 0.0))

    fly_straight(state, 20.0, start_s=10.1, shots=np.arange(11.0, 20.0, 2.0), battery=draining)
    assert state.battery_rate_percent_per_s() == pytest.approx(3.0 + 1 / 15, rel=0.1)
    assert kinds(state) == ["battery"]
    alert = state.warnings[0]
    assert 10.0 < alert.start_t <= 12.0
    assert f"battery {draining(alert.start_t)} %" in alert.message


def test_a_burst_of_readings_with_one_receive_time_gives_no_battery_rate():
    """A link's backlog arrives in one chunk, every packet with its time: a battery drop inside it cannot be timed
    (it divided by zero, stopping the view at the link's fastest rate)."""
    state = started_state()
    for percent in (99, 98, 97, 96):
        state.on_packet(5.0, osd_at(0.0, 10.0, battery_percent=percent))
    assert state.battery_rate_percent_per_s() == 0.0 and state.warnings == []
