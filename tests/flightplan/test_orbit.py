"""The orbit planner against GeographicLib: radius, height, headings, closure, hard places and predictions."""

import csv
import math
import re

import numpy as np
import pytest
from geographiclib.geodesic import Geodesic
from hypothesis import given, settings
from hypothesis import strategies as st

from flightplan import checks, flown_path, litchi
from flightplan.aircraft import MINI_SE_CAMERA
from flightplan.geodesy import LocalFrame
from flightplan.orbit import OrbitRequest, Ring, consecutive_overlap, plan_orbit

WGS84 = Geodesic.WGS84


def assert_orbit_geometry(plan, ring_index=0):
    """Every waypoint of the ring at the radius (1 mm) and height, heading at the centre in whole degrees (the
    Hub's), loop closed."""
    request, ring = plan.request, plan.request.rings[ring_index]
    start = sum(r.waypoints + 1 for r in plan.rings[:ring_index])
    rows = plan.mission.waypoints[start : start + plan.rings[ring_index].waypoints + 1]
    assert rows[-1] == rows[0], "the loop must close on its first waypoint"
    for w in rows:
        back = WGS84.Inverse(w.latitude_deg, w.longitude_deg, request.center_lat_deg, request.center_lon_deg)
        assert back["s12"] == pytest.approx(ring.radius_m, abs=1e-3)
        assert w.altitude_m == ring.height_m
        heading_error = (w.heading_deg - back["azi1"] + 180.0) % 360.0 - 180.0
        assert abs(heading_error) <= 0.5 + 1e-6  # a half-degree tie rounds either way, to float noise
        assert 0.0 <= w.heading_deg < 360.0 and w.heading_deg == int(w.heading_deg)
        assert w.speed_m_s == request.speed_m_s > 0.0
        assert w.photo_time_interval_s == request.photo_interval_s
    return rows


HARD_CENTRES = [
    (0.0, 0.0),  # equator and prime meridian (POI must not be written as 0,0 = "no POI")
    (90.0, 0.0),  # on the pole itself: every heading is north (0 deg)
    (89.99, 10.0),
    (-89.99, -120.0),
    (10.0, 179.9999),  # the circle crosses the antimeridian
    (-33.9, -179.9999),
    (40.1792, 44.4991),
]


@pytest.mark.parametrize("centre", HARD_CENTRES)
@pytest.mark.parametrize("direction", ["cw", "ccw"])
def test_waypoints_on_the_circle_facing_the_centre(centre, direction):
    plan = plan_orbit(OrbitRequest(*centre, direction=direction, start_bearing_deg=30.0))
    rows = assert_orbit_geometry(plan)
    bearings = [WGS84.Inverse(*centre, w.latitude_deg, w.longitude_deg)["azi1"] % 360.0 for w in rows]
    assert bearings[0] == pytest.approx(30.0, abs=1e-6)
    steps = (np.diff(bearings) + 180.0) % 360.0 - 180.0
    expected_step = 360.0 / plan.rings[0].waypoints * (1 if direction == "cw" else -1)
    np.testing.assert_allclose(steps, expected_step, atol=1e-6)
    assert all(w.rotation_dir == (litchi.ROTATION_CW if direction == "cw" else litchi.ROTATION_CCW) for w in rows)
    assert all(w.has_poi and w.gimbal_mode == litchi.GIMBAL_FOCUS_POI for w in rows)
    assert abs(rows[0].poi_latitude_deg - centre[0]) <= 1e-8 and rows[0].poi_longitude_deg == centre[1]
    assert [f for f in checks.check_litchi_limits(plan.mission)] == []


def test_defaults_match_the_paper_and_the_tolerance():
    plan = plan_orbit(OrbitRequest(40.1792, 44.4991))
    ring = plan.rings[0]
    assert (ring.radius_m, ring.height_m) == (50.0, 30.0)
    assert plan.request.speed_m_s == pytest.approx(0.694, abs=5e-4)
    n = ring.waypoints
    sagitta = lambda count: 50.0 * (1.0 - math.cos(math.pi / count))  # noqa: E731
    assert sagitta(n) <= 0.25 < sagitta(n - 1), "the fewest waypoints within 0.25 m"
    assert plan.max_deviation_m == pytest.approx(sagitta(n), abs=1e-3)
    assert ring.gimbal_pitch_deg == -31.0  # -atan(30 / 50) = -30.96 deg in the Hub's whole degrees
    assert all(w.gimbal_pitch_deg == ring.gimbal_pitch_deg for w in plan.mission.waypoints)
    # The flown path lies between the inscribed circle and the waypoint polygon.
    assert 2 * math.pi * 50.0 * math.cos(math.pi / n) - 1e-3 <= plan.path_length_m <= 2 * n * 50.0 * math.sin(math.pi / n)
    assert plan.flight_time_s == pytest.approx(plan.path_length_m / plan.request.speed_m_s)
    assert plan.photo_count == math.floor(plan.flight_time_s / 1.0) + 1
    assert ring.gsd_at_center_cm_px == pytest.approx(100 * math.hypot(50, 30) / MINI_SE_CAMERA.focal_length_px())
    assert ring.max_heading_error_deg < 0.5 + 0.01  # the whole degrees' rounding + the interpolation's 0.01


def test_centre_longitude_beyond_180_is_wrapped():
    plan = plan_orbit(OrbitRequest(10.0, 200.0))
    assert {w.poi_longitude_deg for w in plan.mission.waypoints} == {-160.0}
    assert checks.check_litchi_limits(plan.mission) == []
    assert_orbit_geometry(plan)


def test_explicit_waypoint_count_and_poi_height():
    plan = plan_orbit(OrbitRequest(47.0, 8.0, (Ring(80.0, 40.0),), waypoints_per_ring=12, poi_height_m=10.0))
    assert len(plan.mission) == 13
    assert plan.rings[0].gimbal_pitch_deg == -21.0  # -atan(30 / 80) = -20.56 deg in whole degrees
    assert plan.max_deviation_m == pytest.approx(80.0 * (1 - math.cos(math.pi / 12)), abs=1e-3)
    assert all(w.poi_altitude_m == 10.0 for w in plan.mission.waypoints)
    assert_orbit_geometry(plan)


def test_several_rings():
    rings = (Ring(40.0, 20.0), Ring(60.0, 45.0, -60.0))
    plan = plan_orbit(OrbitRequest(-12.0, 130.0, rings))
    assert len(plan.mission) == sum(r.waypoints + 1 for r in plan.rings) <= litchi.MAX_WAYPOINTS
    for i in range(2):
        assert_orbit_geometry(plan, i)
    fixed = plan.mission.waypoints[-1]
    assert fixed.gimbal_mode == litchi.GIMBAL_INTERPOLATE and fixed.gimbal_pitch_deg == -60.0
    transition = math.hypot(20.0, 25.0)
    assert plan.path_length_m == pytest.approx(sum(r.path_length_m for r in plan.rings) + transition)
    assert checks.check_litchi_limits(plan.mission) == []


def test_radius_one_metre_keeps_legs_above_the_minimum():
    plan = plan_orbit(OrbitRequest(45.0, 7.0, (Ring(1.0, 10.0),)))
    legs = checks.leg_lengths_m(plan.mission)
    assert legs.min() >= litchi.MIN_LEG_M
    assert plan.rings[0].waypoints == 3  # a 4th would make legs too short for the curve rule (1.41 m < 1.42 m)
    assert plan.max_deviation_m == pytest.approx(0.5, abs=1e-3)  # 1 - cos(60 deg)
    assert "out of reach" in plan.notes[0]
    assert checks.check_litchi_limits(plan.mission) == []
    assert_orbit_geometry(plan)


def test_radius_below_the_leg_rules_is_refused():
    with pytest.raises(ValueError, match="no feasible waypoint count for radius 0.6 m"):
        plan_orbit(OrbitRequest(45.0, 7.0, (Ring(0.6, 10.0),)))


def test_the_largest_radius_fills_the_waypoints_and_fits_the_mission_distance_and_5_km_is_refused():
    """One ring: the 30 km mission bounds its circle (4774.6 m); 98 legs of 1999 m would reach 31 km."""
    from flightplan.orbit import largest_radius_m

    largest = largest_radius_m()
    assert largest == pytest.approx(litchi.MAX_MISSION_DISTANCE_M / (2.0 * math.pi))
    plan = plan_orbit(OrbitRequest(45.0, 7.0, (Ring(largest, 100.0),)))
    assert len(plan.mission) == litchi.MAX_WAYPOINTS
    assert checks.leg_lengths_m(plan.mission).max() <= litchi.MAX_LEG_M
    assert plan.max_deviation_m == pytest.approx(largest * (1 - math.cos(math.pi / 98)), abs=1e-2)
    assert_orbit_geometry(plan)
    assert checks.check_litchi_limits(plan.mission) == []  # 29.99 km
    with pytest.raises(ValueError, match=r"^radius 5000 m: expected at most 4775 m: no Litchi mission flies a "
                                         r"larger orbit \(30 km in all, a ring of at most 98 legs of at most 1999 m\)"):
        OrbitRequest(45.0, 7.0, (Ring(5000.0, 100.0),))


def test_with_many_rings_the_leg_length_bounds_the_radius():
    """24 rings share 99 rows: 3 legs a ring, each at most 1999 m, close a circle of at most 1154 m."""
    from flightplan.orbit import largest_radius_m

    largest = largest_radius_m(24)
    assert largest == pytest.approx(litchi.MAX_LEG_M / math.sqrt(3.0))
    rings = tuple(Ring(1150.0 if k == 0 else 10.0, 10.0 + k) for k in range(24))
    plan = plan_orbit(OrbitRequest(45.0, 7.0, rings))
    assert plan.rings[0].waypoints == 3 and 1990.0 < checks.leg_lengths_m(plan.mission)[:3].max() <= litchi.MAX_LEG_M
    with pytest.raises(ValueError, match=r"radius 1200 m: expected at most 1154 m: .* at most 3 legs"):
        OrbitRequest(45.0, 7.0, (Ring(1200.0, 10.0), *rings[1:]))


@pytest.mark.parametrize("height, severity, text", [(0.0, checks.WARNING, "less than 5 m"), (500.0, checks.ERROR, "legal 120 m")])
def test_heights_zero_and_five_hundred(height, severity, text):
    plan = plan_orbit(OrbitRequest(52.0, 5.0, (Ring(50.0, height),)))
    assert_orbit_geometry(plan)
    assert plan.rings[0].gimbal_pitch_deg == round(-math.degrees(math.atan2(height, 50.0)))  # 0 and -84
    assert checks.check_litchi_limits(plan.mission) == []  # 500 m is Litchi's own maximum
    assert any(f.severity == severity and text in f.message for f in checks.check_law(plan.mission))


@pytest.mark.parametrize(
    "field, value",
    [("center_lat_deg", 91.0), ("center_lat_deg", math.nan), ("speed_m_s", 0.0), ("photo_interval_s", -1.0), ("direction", "up")],
)
def test_bad_requests_name_the_problem(field, value):
    arguments = {"center_lat_deg": 10.0, "center_lon_deg": 10.0} | {field: value}
    with pytest.raises(ValueError):
        OrbitRequest(**arguments)


@pytest.mark.parametrize("ring", [Ring(-5.0, 30.0), Ring(0.0, 30.0), Ring(math.inf, 30.0), Ring(50.0, math.nan)])
def test_bad_rings_are_refused(ring):
    with pytest.raises(ValueError, match="radius|height"):
        OrbitRequest(10.0, 10.0, (ring,))


def test_overlap_model_limits():
    hfov = math.radians(MINI_SE_CAMERA.horizontal_fov_deg)
    assert consecutive_overlap(MINI_SE_CAMERA, 50.0, 30.0, 0.0) == 1.0
    # Height 0: only the background term; moving the slant range times the FOV shifts a whole image.
    assert consecutive_overlap(MINI_SE_CAMERA, 50.0, 0.0, 50.0 * hfov * 0.5) == pytest.approx(0.5)
    assert consecutive_overlap(MINI_SE_CAMERA, 50.0, 0.0, 50.0 * hfov * 2) == 0.0
    assert consecutive_overlap(MINI_SE_CAMERA, 50.0, 30.0, 2.0) < consecutive_overlap(MINI_SE_CAMERA, 50.0, 30.0, 1.0)


@settings(max_examples=40, deadline=None)
@given(
    lat=st.floats(-89.999, 89.999),
    lon=st.floats(-180.0, 179.999999),
    radius=st.floats(2.0, 1500.0),
    direction=st.sampled_from(["cw", "ccw"]),
    start=st.floats(0.0, 360.0),
)
def test_property_random_orbits(lat, lon, radius, direction, start):
    plan = plan_orbit(OrbitRequest(lat, lon, (Ring(radius, 40.0),), direction=direction, start_bearing_deg=start))
    assert_orbit_geometry(plan)
    assert checks.check_litchi_limits(plan.mission) == []
    if not plan.notes:
        assert plan.max_deviation_m <= plan.request.deviation_tolerance_m + 1e-3


@pytest.mark.parametrize("turns", [1e17, 1e308 / 360.0])
def test_a_start_bearing_of_many_turns_is_the_same_orbit(turns, recwarn):
    """A start bearing of many turns flies the orbit of that bearing reduced to 0..360 deg: 1e308 deg once
    swallowed the 360 / N steps between waypoints (every waypoint on one spot, a refusal with RuntimeWarnings)."""
    bearing = math.floor(turns) * 360.0 + 30.0
    far, near = (plan_orbit(OrbitRequest(40.1792, 44.4991, start_bearing_deg=b)) for b in (bearing, bearing % 360.0))
    assert [(w.latitude_deg, w.longitude_deg) for w in far.mission.waypoints] == \
        [(w.latitude_deg, w.longitude_deg) for w in near.mission.waypoints]
    assert_orbit_geometry(far)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_a_tolerance_below_rounding_gives_the_most_waypoints_not_a_crash():
    from flightplan.orbit import choose_waypoint_count, feasible_waypoint_range

    for tolerance in (1e-15, 5e-324):
        assert choose_waypoint_count(50.0, tolerance, 98) == feasible_waypoint_range(50.0, 98)[1] == 98


@pytest.mark.parametrize("radius", [999.0, 999.6, 1000.0, 5000.0, 31_000.0, 1e6, 1e12, 1e300, 1.7976931348623157e308])
def test_fewest_waypoints_for_leg_is_the_smallest_count_whose_chord_fits(radius):
    """Up to the largest float (1e308 m used to divide by zero: 2 R overflowed); beyond 2**53 legs a count is exact
    only to the float's precision."""
    from flightplan.orbit import chord_m, fewest_waypoints_for_leg

    count = fewest_waypoints_for_leg(radius, litchi.MAX_LEG_M)
    if count < 2**53:
        assert chord_m(radius, count) <= litchi.MAX_LEG_M
        assert count == 1 or chord_m(radius, count - 1) > litchi.MAX_LEG_M
    else:
        assert count == pytest.approx(math.pi / (litchi.MAX_LEG_M / radius / 2.0), rel=1e-9)  # sin x = x, tiny x


@pytest.mark.parametrize("radius", [math.inf, math.nan, 0.0, -1.0])
def test_fewest_waypoints_for_leg_refuses_what_is_no_radius(radius):
    from flightplan.orbit import fewest_waypoints_for_leg

    with pytest.raises(ValueError, match="radius and leg must be positive finite numbers of metres"):
        fewest_waypoints_for_leg(radius, litchi.MAX_LEG_M)


def test_a_radius_beyond_litchi_limits_is_refused_at_once():
    # 1e12 m needs ~3e9 legs of 1999 m; the planner used to count them one by one. 1e308 m divided by zero.
    from flightplan.orbit import choose_waypoint_count

    for radius in (1e12, 1e308):
        with pytest.raises(ValueError, match=rf"^radius {re.escape(f'{radius:g}')} m: expected at most 4775 m"):
            OrbitRequest(45.0, 7.0, (Ring(radius, 30.0),))
        with pytest.raises(ValueError, match=f"no feasible waypoint count for radius {re.escape(f'{radius:g}')} m"):
            choose_waypoint_count(radius, 0.25, 98)


@pytest.mark.parametrize("rings, most", [((Ring(),), 98), ((Ring(), Ring(80.0, 40.0)), 48)])
def test_waypoints_per_ring_beyond_litchi_mission_limit_are_refused(rings, most):
    assert len(plan_orbit(OrbitRequest(45.0, 7.0, rings, waypoints_per_ring=most)).mission) <= litchi.MAX_WAYPOINTS
    with pytest.raises(ValueError, match=f"waypoints per ring must be 3..{most}"):
        OrbitRequest(45.0, 7.0, rings, waypoints_per_ring=most + 1)
    with pytest.raises(ValueError, match="waypoints per ring"):
        OrbitRequest(45.0, 7.0, rings, waypoints_per_ring=10**9)


def test_heading_and_pitch_are_whole_degrees_and_the_heading_check_uses_them(tmp_path):
    """Litchi Mission Hub writes heading and gimbal pitch as integers (a real export's rows: 92, 178, 358 and 2, 0,
    -55; research/litchi.md [REAL]): the CSV holds them so, and the predicted heading error along the legs is the one
    of the headings written, read back from the file."""
    plan = plan_orbit(OrbitRequest(40.1792, 44.4991, start_bearing_deg=12.345))
    path = litchi.write_mission_csv(plan.mission, tmp_path / "m.csv")
    rows = list(csv.DictReader(path.open()))
    assert all(re.fullmatch(r"-?\d+", row[column]) for row in rows for column in ("heading(deg)", "gimbalpitchangle"))
    assert {row["gimbalpitchangle"] for row in rows} == {"-31"}
    written = litchi.read_mission_csv(path)
    frame = LocalFrame(40.1792, 44.4991, 0.0)
    east, north, _ = frame.to_enu(written.column("latitude_deg"), written.column("longitude_deg"), np.zeros(len(rows)))
    error = flown_path.heading_error_along_legs_deg(np.stack([east, north], -1), written.column("heading_deg"))
    assert plan.rings[0].max_heading_error_deg == pytest.approx(error, abs=1e-9)
    assert 0.1 < error < 0.5 + 0.01  # rounding to whole degrees shows; the unrounded headings were within 0.01
