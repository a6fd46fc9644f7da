"""The virtual drone's flight, imperfections and ground truth against analytic truth.

The reference mission is the project's default orbit (50 m radius, 30 m height, 2.5 km/h, a photo per second,
24 waypoints with half-chord curves, Focus POI on the centre), built with GeographicLib. With half-chord
curves the rounded path between the first and last waypoint is a circle of radius r*cos(pi/N). The home
point is 1000 m above the ellipsoid, so 50 m on the ellipsoid is 50 * (1 + 1000 m / earth radius) = 50.008 m
in the local frame: the expected radius is measured in ENU.
"""

from dataclasses import replace

import numpy as np
import pytest

from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import geodesic_direct
from capture.attitude import camera_matrix_world
from sim.drone import Flight, HomePoint, Imperfections, Waypoint, fly
from sim.drone.flight import PHASES, tilt_from_forces
from sim.drone.imperfections import damage_bytes, first_order_lag, gauss_markov

RADIUS_M, HEIGHT_M, SPEED_MPS, N_WAYPOINTS, PHOTO_S = 50.0, 30.0, 2.5 / 3.6, 24, 1.0
LAT0, LON0 = DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg
HALF_STEP = np.pi / N_WAYPOINTS
MISSION_PHASE = PHASES.index("mission")


def orbit_waypoints(speed_mps=SPEED_MPS):
    """The default orbit: N waypoints clockwise from north plus the first repeated to close the loop."""
    half_chord = RADIUS_M * np.sin(HALF_STEP)
    waypoints = []
    for k in range(N_WAYPOINTS + 1):
        p = geodesic_direct(LAT0, LON0, (k % N_WAYPOINTS) * 360.0 / N_WAYPOINTS, RADIUS_M)
        waypoints.append(Waypoint(p.lat_deg, p.lon_deg, HEIGHT_M, curvesize_m=half_chord, gimbalmode=1,
                                  speed_mps=speed_mps, poi_latitude_deg=LAT0, poi_longitude_deg=LON0,
                                  poi_altitude_m=0.0, photo_timeinterval_s=PHOTO_S))
    return waypoints


def home_point():
    """Take-off 70 m south of the orbit centre, on the ground of the demo location."""
    p = geodesic_direct(LAT0, LON0, 180.0, 70.0)
    return HomePoint(p.lat_deg, p.lon_deg, DEMO_ORIGIN.h0_m)


@pytest.fixture(scope="module")
def perfect():
    return fly(orbit_waypoints(), home_point(), Imperfections.none(), seed=1)


@pytest.fixture(scope="module")
def realistic():
    return fly(orbit_waypoints(), home_point(), replace(Imperfections.realistic(), dropout_rate_per_min=0.0), seed=2)


def centre_enu(flight):
    return flight.frame.enu_points(LAT0, LON0, DEMO_ORIGIN.h0_m)


def enu_radii(flight):
    """The orbit's radius in the flight's ENU frame and the radius of its rounded corners (r cos(pi/N))."""
    offsets = flight.waypoints_enu - centre_enu(flight)
    radius = float(np.hypot(offsets[:, 0], offsets[:, 1]).mean())
    return radius, radius * np.cos(HALF_STEP)


def mission_samples(flight, step_s=0.25):
    """True states on the circle, a little away from the stops at the first and last waypoint."""
    passes = flight.waypoint_times_s()
    t = np.arange(passes[0] + 1.0, passes[-1] - 1.0, step_s)
    return flight.state_at(t)


def analytic_mission_duration_s(flight):
    """Straight half chords at both ends + (N-1) arcs of 2pi/N at r cos(pi/N); ramps at the two stops add v/a."""
    radius, inner = enu_radii(flight)
    length = 2 * radius * np.sin(HALF_STEP) + (N_WAYPOINTS - 1) * 2 * HALF_STEP * inner
    return length / SPEED_MPS + SPEED_MPS / flight.config.accel_mps2


def test_orbit_stays_within_the_curve_model_tolerance_of_the_circle(perfect):
    state = mission_samples(perfect.flight)
    assert np.all(state.phase == MISSION_PHASE)
    offset = state.position_enu_m - centre_enu(perfect.flight)
    radius = np.hypot(offset[:, 0], offset[:, 1])
    outer, inner = enu_radii(perfect.flight)
    tolerance = 0.01  # curvesizes are half chords on the ellipsoid, 1.6e-4 shorter than at 1000 m
    assert inner - tolerance <= radius.min() and radius.max() <= outer + 1e-6
    assert np.median(radius) == pytest.approx(inner, abs=tolerance)  # the curved part is the inner circle
    assert np.abs(state.position_enu_m[:, 2] - HEIGHT_M).max() < 0.01  # earth curvature over 120 m: < 1 mm


def test_speed_on_the_legs_equals_the_waypoint_speed(perfect):
    state = mission_samples(perfect.flight)
    assert np.linalg.norm(state.velocity_enu_mps, axis=1) == pytest.approx(SPEED_MPS, abs=1e-9)
    passes = perfect.flight.waypoint_times_s()
    assert passes[-1] - passes[0] == pytest.approx(analytic_mission_duration_s(perfect.flight), abs=0.02)


def test_heading_and_camera_point_at_the_poi(perfect):
    state = mission_samples(perfect.flight)
    to_poi = centre_enu(perfect.flight) - state.position_enu_m
    bearing = np.degrees(np.arctan2(to_poi[:, 0], to_poi[:, 1]))
    heading_error = (state.aircraft_ypr_deg[:, 0] - bearing + 180.0) % 360.0 - 180.0
    assert np.abs(heading_error).max() < 0.2
    # Litchi computes the Focus POI pitch at the waypoints (radius r), then interpolates.
    assert state.gimbal_ypr_deg[:, 1] == pytest.approx(-np.degrees(np.arctan2(HEIGHT_M, RADIUS_M)), abs=0.01)
    optical_axis = camera_matrix_world(*state.gimbal_ypr_deg.T)[:, :, 2]
    cosine = np.sum(optical_axis * to_poi, axis=1) / np.linalg.norm(to_poi, axis=1)
    # the path runs at r cos(pi/N) < r, so the POI sits slightly below the image centre
    outer, inner = enu_radii(perfect.flight)
    expected = np.degrees(np.arctan2(HEIGHT_M, inner) - np.arctan2(HEIGHT_M, outer))
    assert np.degrees(np.arccos(np.clip(cosine, -1, 1))).max() < expected + 0.2


def test_photos_every_interval_from_the_first_to_the_last_waypoint(perfect):
    photos, passes = perfect.photos, perfect.flight.waypoint_times_s()
    assert np.diff(photos.t_s) == pytest.approx(PHOTO_S, abs=1e-9)
    assert photos.t_s[0] == pytest.approx(passes[0])
    assert len(photos.t_s) == int(np.floor(analytic_mission_duration_s(perfect.flight) / PHOTO_S)) + 1
    assert photos.taken.all()
    assert [r.t_s for r in perfect.telemetry.shutter] == pytest.approx(list(photos.t_s))


@pytest.mark.parametrize("imperfections", [Imperfections.none(), Imperfections.realistic()], ids=["none", "realistic"])
def test_takeoff_and_landing_at_home(imperfections):
    flight = fly(orbit_waypoints(), home_point(), imperfections, seed=3).flight
    ends = flight.state_at([0.0, flight.config.ground_time_s, flight.duration_s])
    assert np.abs(ends.position_enu_m).max() < 1e-9
    assert list(ends.phase) == [0, 0, 0]
    climb = flight.state_at(flight.config.ground_time_s + np.linspace(2.0, 12.0, 6))  # 30 m at 2 m/s + ramps
    assert np.all(climb.phase == PHASES.index("takeoff"))
    perfect = imperfections == Imperfections.none()
    tolerance = 1e-9 if perfect else 0.2  # gusts move the aircraft once it is off the ground
    assert np.abs(climb.velocity_enu_mps[:, 2] - flight.config.climb_rate_mps).max() < tolerance
    assert np.abs(climb.position_enu_m[:, :2]).max() < (1e-9 if perfect else 2.0)


def test_same_seed_same_flight_other_seed_other_noise():
    imperfections = Imperfections.realistic()
    a, b = (fly(orbit_waypoints(), home_point(), imperfections, seed=5) for _ in range(2))
    c = fly(orbit_waypoints(), home_point(), imperfections, seed=6)
    assert a.telemetry.merged() == b.telemetry.merged()
    np.testing.assert_array_equal(a.photos.position_enu_m, b.photos.position_enu_m)
    assert a.damage_link(bytes(10_000)) == b.damage_link(bytes(10_000))
    assert a.telemetry.osd[100] != c.telemetry.osd[100]


def test_no_imperfections_means_measured_equals_truth(perfect):
    flight, telemetry, photos = perfect.flight, perfect.telemetry, perfect.photos
    osd = telemetry.osd
    t = np.array([r.t_s for r in osd])
    assert np.diff(t) == pytest.approx(0.1) and t[-1] == pytest.approx(flight.duration_s, abs=0.1)
    truth = flight.state_at(t)
    lat, lon, _ = flight.frame.to_geodetic(*truth.position_enu_m.T)
    np.testing.assert_array_equal([r.latitude_deg for r in osd], lat)
    np.testing.assert_array_equal([r.longitude_deg for r in osd], lon)
    np.testing.assert_array_equal([r.height_above_takeoff_m for r in osd], truth.position_enu_m[:, 2])
    np.testing.assert_array_equal([r.velocity_north_mps for r in osd], truth.velocity_enu_mps[:, 1])
    np.testing.assert_array_equal([r.velocity_down_mps for r in osd], -truth.velocity_enu_mps[:, 2])
    np.testing.assert_array_equal([(r.yaw_deg, r.pitch_deg, r.roll_deg) for r in osd], truth.aircraft_ypr_deg)
    np.testing.assert_array_equal([(r.yaw_deg, r.pitch_deg, r.roll_deg) for r in telemetry.gimbal],
                                  truth.gimbal_ypr_deg)
    home = telemetry.home[0]
    assert (home.latitude_deg, home.longitude_deg) == pytest.approx((flight.home.latitude_deg,
                                                                      flight.home.longitude_deg), abs=1e-12)
    assert home.height_ellipsoid_m == pytest.approx(flight.home.height_ellipsoid_m, abs=1e-6)
    np.testing.assert_array_equal(photos.measured_latitude_deg, photos.latitude_deg)
    np.testing.assert_array_equal(photos.measured_gimbal_ypr_deg, photos.gimbal_ypr_deg)
    np.testing.assert_array_equal(photos.camera_time_s, photos.t_s)
    assert len(telemetry.dropouts_s) == 0


def test_realistic_gps_errors_have_the_configured_statistics(realistic):
    flight, osd, imp = realistic.flight, realistic.telemetry.osd, realistic.flight.imperfections
    t = np.array([r.t_s for r in osd])
    measured = flight.frame.enu_points([r.latitude_deg for r in osd], [r.longitude_deg for r in osd],
                                       flight.home.height_ellipsoid_m)
    error = measured[:, :2] - flight.state_at(t).position_enu_m[:, :2]
    white = np.diff(error, axis=0).std(axis=0) / np.sqrt(2.0)  # the bias barely moves in 0.1 s
    assert white == pytest.approx([imp.gps_noise_std_m] * 2, rel=0.06)
    assert 0.2 < np.sqrt(np.mean(error**2)) / np.hypot(imp.gps_noise_std_m, imp.gps_bias_std_m) < 2.0
    height_error = np.array([r.height_above_takeoff_m for r in osd]) - flight.state_at(t).position_enu_m[:, 2]
    assert height_error[0] == 0.0  # barometer zeroed at take-off
    assert abs(height_error[1:].std()) < 3 * np.hypot(imp.baro_bias_std_m, imp.baro_noise_std_m)


def test_gauss_markov_bias_has_the_configured_std_and_memory():
    rng = np.random.default_rng(11)
    times = np.arange(0.0, 30.0, 0.5)
    series = np.stack([gauss_markov(times, 1.5, 10.0, rng)[:, 0] for _ in range(3000)])
    assert series.std(axis=0).mean() == pytest.approx(1.5, rel=0.03)
    lag_correlation = np.mean(series[:, 20] * series[:, 40]) / 1.5**2  # 10 s apart
    assert lag_correlation == pytest.approx(np.exp(-1.0), abs=0.04)
    zeroed = gauss_markov(times, 1.5, 10.0, rng, start_at_zero=True)
    assert zeroed[0, 0] == 0.0


def test_gimbal_lag_is_first_order_and_delays_the_yaw_on_the_orbit():
    step = first_order_lag(np.r_[0.0, np.ones(999)], 0.001, 0.3)
    assert np.interp(0.3, np.arange(1000) * 0.001, step) == pytest.approx(1 - np.exp(-1), abs=0.01)
    lagged = fly(orbit_waypoints(), home_point(), Imperfections(gimbal_lag_s=0.3), seed=0).flight
    state = mission_samples(lagged)
    delay = (state.aircraft_ypr_deg[:, 0] - state.gimbal_ypr_deg[:, 0] + 180.0) % 360.0 - 180.0
    yaw_rate_deg_s = np.degrees(SPEED_MPS / enu_radii(lagged)[1])  # clockwise orbit facing the centre
    assert np.median(delay) == pytest.approx(yaw_rate_deg_s * 0.3, rel=0.05)


def test_corrupted_and_dropped_bytes_match_the_rates():
    rng = np.random.default_rng(4)
    corrupted = np.frombuffer(damage_bytes(bytes(1_000_000), 1e-3, 0.0, rng), np.uint8)
    assert len(corrupted) == 1_000_000
    assert abs(np.count_nonzero(corrupted) - 1000) < 4 * np.sqrt(1000)
    shortened = damage_bytes(bytes(range(256)) * 4000, 0.0, 2e-3, rng)
    assert abs((1_024_000 - len(shortened)) - 2048) < 4 * np.sqrt(2048)
    assert damage_bytes(b"\x55\x0d\x04", 0.0, 0.0, rng) == b"\x55\x0d\x04"


def test_dropouts_remove_records_and_dropped_photos_send_no_shutter():
    imperfections = replace(Imperfections.none(), dropout_rate_per_min=6.0, dropout_mean_s=2.0,
                            photo_drop_probability=0.2)
    result = fly(orbit_waypoints(), home_point(), imperfections, seed=8)
    windows = result.telemetry.dropouts_s
    assert len(windows) > 20
    for stream in (result.telemetry.osd, result.telemetry.gimbal, result.telemetry.shutter):
        t = np.array([r.t_s for r in stream])
        assert not ((t[:, None] >= windows[:, 0]) & (t[:, None] < windows[:, 1])).any()
    taken = result.photos.taken
    assert taken.mean() == pytest.approx(0.8, abs=0.06)
    names = result.photos.names
    assert [n for n in names if n] == [f"DJI_{k:04d}.JPG" for k in range(1, taken.sum() + 1)]  # no gaps
    assert all(name == "" for name, kept in zip(names, taken) if not kept)
    assert {r.photo_index for r in result.telemetry.shutter} <= set(np.flatnonzero(taken))


def test_camera_rotation_follows_the_dji_convention():
    north_level, nadir, east_level = camera_matrix_world([0, 0, 90], [0, -90, 0], [0, 0, 0])
    np.testing.assert_allclose(north_level, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-12)  # columns x,y,z
    np.testing.assert_allclose(nadir[:, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(nadir[:, 1], [0, -1, 0], atol=1e-12)  # image down = south when facing north
    np.testing.assert_allclose(east_level[:, 2], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(east_level[:, 0], [0, -1, 0], atol=1e-12)


def test_aircraft_leans_into_acceleration_and_airspeed():
    pitch, roll = tilt_from_forces(np.zeros((2, 3)), np.array([[0, 5.0, 0], [5.0, 0, 0]]), np.array([0.0, 0.0]), 0.4)
    assert pitch[0] == pytest.approx(-np.degrees(np.arctan(2.0 / 9.80665))) and roll[0] == pytest.approx(0.0)
    assert roll[1] == pytest.approx(np.degrees(np.arctan(2.0 / 9.80665))) and pitch[1] == pytest.approx(0.0)


def test_square_with_sharp_and_rounded_corners():
    corners = [geodesic_direct(LAT0, LON0, az, 20.0 * np.sqrt(2)) for az in (45, 135, 225, 315, 45)]
    sharp = [Waypoint(p.lat_deg, p.lon_deg, 20.0, speed_mps=5.0) for p in corners]
    rounded = [replace(w, curvesize_m=5.0) for w in sharp]
    flight = Flight(sharp, home_point())
    pass_states = flight.state_at(flight.waypoint_times_s())
    np.testing.assert_allclose(pass_states.position_enu_m, flight.waypoints_enu, atol=1e-6)
    assert np.abs(pass_states.velocity_enu_mps).max() < 1e-9  # it stops at every sharp corner
    flight = Flight(rounded, home_point())
    inner = flight.state_at(flight.waypoint_times_s()[1:-1])
    miss = np.linalg.norm(inner.position_enu_m - flight.waypoints_enu[1:-1], axis=1)
    assert miss == pytest.approx(5.0 * (np.sqrt(2) - 1), abs=1e-6)  # a 90 deg turn: arc radius = curvesize
    speed = np.linalg.norm(inner.velocity_enu_mps, axis=1)
    assert speed == pytest.approx(np.sqrt(flight.config.accel_mps2 * 5.0), abs=1e-6)  # lateral accel limit


def test_bad_missions_are_rejected_with_a_clear_message():
    w = orbit_waypoints()
    with pytest.raises(ValueError, match="waypoint 1: gimbal mode Focus POI"):
        Flight([replace(w[0], poi_latitude_deg=0.0, poi_longitude_deg=0.0)] + w[1:], home_point())
    with pytest.raises(ValueError, match="waypoints 1 and 2 coincide"):
        Flight([w[0], w[0], w[1]], home_point())
    with pytest.raises(ValueError, match="speed_mps"):
        replace(w[0], speed_mps=20.0)
    with pytest.raises(ValueError, match="gps_noise_std_m"):
        Imperfections(gps_noise_std_m=-1.0)


def test_gusts_push_the_true_path_off_the_plan_by_the_configured_amount(perfect):
    gusty = fly(orbit_waypoints(), home_point(), Imperfections(gust_offset_std_m=0.5), seed=9).flight
    t = mission_samples(perfect.flight).t_s
    deviation = gusty.state_at(t).position_enu_m - perfect.flight.state_at(t).position_enu_m
    assert np.sqrt(np.mean(deviation[:, :2] ** 2)) == pytest.approx(0.5, rel=0.3)
    assert np.sqrt(np.mean(deviation[:, 2] ** 2)) == pytest.approx(0.15, rel=0.4)


def test_truth_files_hold_the_true_poses_and_clock_offset(realistic, tmp_path):
    import csv
    import json

    from scipy.spatial.transform import Rotation

    from sim.drone import write_truth

    photos = realistic.photos
    write_truth(tmp_path, realistic.flight, photos, seed=2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["truth.csv", "truth.json"]  # no temporary left
    assert {p.stat().st_mode & 0o777 for p in tmp_path.iterdir()} == {0o644}  # shareable, not 0600
    document = json.loads((tmp_path / "truth.json").read_text())
    assert document["clock_offset_s"] == Imperfections.realistic().camera_clock_offset_s
    assert document["origin"]["lat0_deg"] == realistic.flight.home.latitude_deg
    with open(tmp_path / "truth.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == len(photos.t_s) and rows[0]["image_name"] == "DJI_0001.JPG"
    quats = np.array([[float(r[k]) for k in ("qx", "qy", "qz", "qw")] for r in rows])
    np.testing.assert_allclose(Rotation.from_quat(quats).as_matrix(), photos.R_world_cam, atol=1e-9)
    east = np.array([float(r["east_m"]) for r in rows])
    np.testing.assert_array_equal(east, photos.position_enu_m[:, 0])
    np.testing.assert_allclose(photos.camera_time_s - photos.t_s, document["clock_offset_s"], atol=1e-12)
