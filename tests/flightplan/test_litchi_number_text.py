"""The Litchi CSV's numbers: a normal plan's text is every value's shortest round-trip decimal (so its bytes are
those of the writer before numbers were bounded), and a value nearer zero than 1e-10 is written ``0``."""

from __future__ import annotations

import numpy as np
import pytest

from flightplan import litchi
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.orbit import OrbitRequest, Ring, plan_orbit

NORMAL_REQUESTS = {
    "demo default": OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg),
    "two rings, fixed pitch": OrbitRequest(-12.0, 130.0, (Ring(40.0, 20.0), Ring(60.0, 45.0, -60.0)),
                                           photo_interval_s=2.0, direction="ccw"),
    "near 0,0": OrbitRequest(1e-6, -3e-7, (Ring(600.0, 100.0),)),  # coordinates of 17 digits after 2-5 zeros
}


def shortest_text(value) -> str:
    """A cell as the unbounded writer wrote it: integers as such, floats as their shortest round-trip decimal."""
    if isinstance(value, int):
        return str(value)
    return np.format_float_positional(value, unique=True, trim="-")


@pytest.mark.parametrize("name", NORMAL_REQUESTS)
def test_a_normal_plan_is_written_as_its_shortest_round_trip_text(name):
    mission = plan_orbit(NORMAL_REQUESTS[name]).mission
    text = litchi.mission_to_csv_text(mission)
    for line, waypoint in zip(text.splitlines()[1:], mission.waypoints):
        values = [getattr(waypoint, c.attribute) for c in litchi._BEFORE_ACTIONS]
        values += [-1, 0] * litchi.MAX_ACTIONS
        values += [getattr(waypoint, c.attribute) for c in litchi._AFTER_ACTIONS]
        assert line.split(",") == [shortest_text(v) for v in values]
    assert litchi.parse_mission_csv(text) == mission  # every value back bit for bit


@pytest.mark.parametrize("value", [1e-300, -1e-300, 5e-324, -0.0, 9.99e-11, -9.99e-11])
def test_a_value_nearer_zero_than_the_bound_is_written_as_zero(value):
    assert litchi.format_number(value) == "0"
    assert litchi.written_value(value) == 0.0


def test_the_bound_itself_and_the_poi_nudge_keep_their_digits():
    assert litchi.format_number(litchi.WRITTEN_AS_ZERO_BELOW) == "0.0000000001"
    longest = litchi.format_number(-1.2345678901234567e-10)  # a sign, "0.", 9 zeros and 17 digits
    assert float(longest) == -1.2345678901234567e-10 and len(longest) == 29
    assert litchi.format_number(1e-8) == "0.00000001"


@pytest.mark.parametrize("lat, lon", [(0.0, 0.0), (1e-300, 0.0), (-5e-11, 5e-11)])
def test_a_centre_written_as_0_0_keeps_its_poi(lat, lon):
    waypoint = plan_orbit(OrbitRequest(lat, lon, (Ring(20.0, 30.0),))).mission.waypoints[0]
    assert (waypoint.poi_latitude_deg, waypoint.poi_longitude_deg) == (1e-8, 0.0)
    assert waypoint.has_poi


def test_a_centre_just_beyond_the_bound_is_written_as_it_is():
    waypoint = plan_orbit(OrbitRequest(2e-10, 0.0, (Ring(20.0, 30.0),))).mission.waypoints[0]
    assert (waypoint.poi_latitude_deg, waypoint.poi_longitude_deg) == (2e-10, 0.0)


@pytest.mark.parametrize("column, meaning", [("speed_m_s", "the cruise speed"),
                                             ("photo_time_interval_s", "no timed photos"),
                                             ("photo_dist_interval_m", "no distance photos")])
def test_a_tiny_speed_or_interval_is_refused_not_written_as_litchis_zero(column, meaning):
    """0 is Litchi's cruise speed or "no photos" there: 1e-300 written as 0 would change what the aircraft does."""
    waypoint = litchi.Waypoint(47.0, 8.0, **{column: 1e-300})
    with pytest.raises(ValueError, match=f"{column} 1e-300 would be written as 0, which Litchi reads as {meaning}"):
        litchi.mission_to_csv_text(litchi.Mission((waypoint,)))
