"""Mission checks: Litchi's limits, the aircraft and the law, each tripped by a hand-made mission."""

import dataclasses

import pytest

from flightplan import checks, litchi
from flightplan.aircraft import DJI_MINI_SE
from flightplan.orbit import OrbitRequest, plan_orbit


@pytest.fixture(scope="module")
def good():
    return plan_orbit(OrbitRequest(47.0, 8.0, photo_interval_s=2.0)).mission


def with_row(mission, row, **changes):
    rows = list(mission.waypoints)
    rows[row] = dataclasses.replace(rows[row], **changes)
    return litchi.Mission(tuple(rows))


def messages(findings, severity=checks.ERROR):
    return [f.message for f in findings if f.severity == severity]


def test_default_plan_at_two_seconds_is_clean(good):
    assert checks.check_mission(good, DJI_MINI_SE, flight_time_s=450.0) == []
    assert checks.raise_on_errors([]) == []


@pytest.mark.parametrize(
    "row, changes, text",
    [
        (3, {"speed_m_s": 16.0}, "speed (m/s) 16 on row 4"),
        (2, {"altitude_m": -250.0}, "altitude (m) -250 on row 3"),
        (5, {"poi_altitude_m": 600.0}, "POI altitude (m) 600"),
        (1, {"gimbal_pitch_deg": 45.0}, "gimbal pitch (deg) 45"),
        (0, {"curve_size_m": 3.0}, "first waypoint (row 1) cannot have a curve"),
        (4, {"curve_size_m": 9.0}, "need a leg of at least"),
        (4, {"actions": ((litchi.ACTION_TAKE_PHOTO, 0.0),) * 16}, "number of actions 16"),
        (4, {"photo_time_interval_s": 0.05}, "photo time interval (s) 0.05"),
        (4, {"photo_dist_interval_m": 5.0}, "sets both a time and a distance"),
        (2, {"heading_deg": 361.0}, "heading (deg) 361"),
        (2, {"poi_longitude_deg": 200.0}, "poi_longitude (deg) 200"),
    ],
)
def test_litchi_limit_errors(good, row, changes, text):
    errors = messages(checks.check_litchi_limits(with_row(good, row, **changes)))
    assert any(text in e for e in errors), errors


def test_leg_length_limits(good):
    first = good.waypoints[0]
    too_close = litchi.Mission((first, dataclasses.replace(first, latitude_deg=first.latitude_deg + 0.3 / 111_000)))
    assert any("the leg from row 1" in e and "0.6..1999" in e for e in messages(checks.check_litchi_limits(too_close)))
    too_far = litchi.Mission((first, dataclasses.replace(first, latitude_deg=first.latitude_deg + 0.02)))
    assert any("length (m) 2223.4" in e for e in messages(checks.check_litchi_limits(too_far)))
    assert "holds 1..99 waypoints" in messages(checks.check_litchi_limits(litchi.Mission()))[0]


def test_aircraft_speed_interval_and_battery(good):
    fast = litchi.Mission(tuple(dataclasses.replace(w, speed_m_s=14.0, photo_time_interval_s=1.0) for w in good.waypoints))
    findings = checks.check_aircraft(fast, DJI_MINI_SE, flight_time_s=40 * 60.0)
    assert any("DJI Mini SE speed (m/s) 14 on row 1" in e for e in messages(findings))
    warnings = messages(findings, checks.WARNING)
    assert any("below the DJI Mini SE's 2 s minimum" in w for w in warnings)
    assert any("40.0 min exceeds the 24 min" in w and "2 batteries" in w for w in warnings)


def test_law_and_raise(good):
    high = with_row(good, 7, altitude_m=121.0)
    with pytest.raises(checks.MissionCheckError, match="121 m above take-off on row 8 exceeds the legal 120 m"):
        checks.raise_on_errors(checks.check_mission(high))
    assert checks.check_law(high, legal_max_height_m=150.0) == []
