"""Smooth trajectories and IMU synthesis against truth: the noise-free IMU integrated from the first true state
reproduces each trajectory (an analytic orbit first, then the splines of the lawnmower, the random loop and a
gusty virtual flight), and the noise measured by Allan deviation is the configured EuRoC ADIS16448's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from capture.attitude import camera_matrix_world
from flightplan.geodesy import LocalFrame
from sim.drone import Flight, Imperfections
from sim.motion.imu import (
    EUROC_ADIS16448,
    R_world_body,
    T_body_cam0,
    T_world_cam0,
    dead_reckon,
    sensor_noise,
    synthesize_imu,
)
from sim.motion.rig_path import RigPath
from sim.motion.trajectory import CircleOrbit, flight_path, smooth_path
from sim.sampling.pose import camera_rotation
from sim.sampling.trajectories import lawnmower, orbit, random_loop
from test_drone_flight import LAT0, LON0, home_point, orbit_waypoints
from test_sampling import GROUND

RATE_HZ = 200.0
SECONDS = 10.0
ALLAN_HOURS = 4.0


def dead_reckoning_error(trajectory, start_s: float = 0.0) -> tuple[float, float]:
    """Position (m) and attitude (deg) error after :data:`SECONDS` of integrating the noise-free IMU."""
    t = start_s + np.arange(int(SECONDS * RATE_HZ) + 1) / RATE_HZ
    samples = synthesize_imu(trajectory, t, RATE_HZ, EUROC_ADIS16448, seed=0)
    truth = samples.kinematics
    R_true = R_world_body(truth)
    R, _, p = dead_reckon(samples.gyro_true, samples.accel_true, RATE_HZ, R_true[0], truth.velocity[0],
                        truth.position[0])
    attitude = Rotation.from_matrix(R_true[-1].T @ R).magnitude()
    return float(np.linalg.norm(p - truth.position[-1])), math.degrees(attitude)


def test_orbit_imu_reads_the_analytic_centripetal_force_and_turn_rate():
    radius, speed, tilt = 50.0, 5.0, math.radians(30.0)
    samples = synthesize_imu(CircleOrbit((10.0, -20.0), radius, 130.0, speed, tilt), np.array([0.0, 7.3]),
                             RATE_HZ, EUROC_ADIS16448, seed=0)
    np.testing.assert_allclose(np.linalg.norm(samples.gyro_true, axis=1), speed / radius, rtol=1e-12)
    world_force = np.einsum("nij,nj->ni", R_world_body(samples.kinematics), samples.accel_true)
    towards_centre = np.array([10.0, -20.0]) - samples.kinematics.position[:, :2]
    expected = towards_centre / radius * speed**2 / radius
    np.testing.assert_allclose(world_force[:, :2], expected, atol=1e-12)
    np.testing.assert_allclose(world_force[:, 2], 9.80665, atol=1e-12)  # gravity included, up
    R = samples.kinematics.R_world_cam()
    heading = math.degrees(samples.kinematics.heading[1]) % 360.0
    np.testing.assert_allclose(R[1], camera_rotation(heading, 30.0), atol=1e-12)
    np.testing.assert_allclose(R[:, :2, 2] / np.linalg.norm(R[:, :2, 2], axis=1)[:, None],
                               towards_centre / radius, atol=1e-12)  # the camera faces the centre


def test_smooth_orbit_is_the_sampled_orbit_circle():
    path = orbit(GROUND, (5.0, -3.0), 40.0, 50.0, 4.0, 10.0, clockwise=True)
    circle = smooth_path(path)
    t = np.arange(50) / 10.0
    polyline = path.positions_at(path.speed_m_s * t)
    assert np.abs(circle.at(t).position - polyline).max() < 2e-3  # chords of the 0.25 m polyline
    headings = [path.pose(GROUND, i).details["heading_deg"] for i in range(50)]
    difference = (np.degrees(circle.at(t).heading) - headings + 180.0) % 360.0 - 180.0
    assert np.abs(difference).max() < 1e-4  # the chords' 1.6e-6 shorter lap: 5e-5 deg after 5 s


def test_body_and_camera_poses_follow_the_extrinsics():
    T_bc = T_body_cam0(0.54)
    kinematics = CircleOrbit((0.0, 0.0), 30.0, 40.0, 3.0, 0.4).at(np.array([1.0]))
    T = T_world_cam0(kinematics, T_bc)[0]
    np.testing.assert_allclose(T[:3, :3], kinematics.R_world_cam()[0], atol=1e-12)
    # the IMU lies half a baseline right of the left camera and 2 cm behind it
    np.testing.assert_allclose(np.linalg.inv(T)[:3, :3] @ kinematics.position[0] + np.linalg.inv(T)[:3, 3],
                               [0.27, 0.0, -0.02], atol=1e-12)


def test_the_rig_pose_at_a_frame_time_is_that_frame_and_moves_between_frames():
    """Rolling shutter and motion blur ask the smooth rig for poses between frames (``pose_at``)."""
    path = orbit(GROUND, (5.0, -3.0), 40.0, 50.0, 4.0, 10.0, clockwise=True)
    rig = RigPath(smooth_path(path), T_body_cam0(0.54), 10.0, True, "orbit")
    for index in (0, 7):
        np.testing.assert_allclose(rig.pose_at(index / 10.0), rig.pose(GROUND, index).T_world_cam, atol=1e-12)
    moved = np.linalg.norm(rig.pose_at(0.75)[:3, 3] - rig.pose_at(0.7)[:3, 3])
    assert moved == pytest.approx(4.0 * 0.05, rel=0.02)  # 4 m/s for 50 ms (the camera sits 27 cm off the path)


@pytest.mark.parametrize("name", ["orbit", "lawnmower", "loop", "flight"])
def test_noise_free_imu_integrates_back_to_the_trajectory(name):
    if name == "orbit":
        trajectory, start = CircleOrbit((0.0, 0.0), 50.0, 30.0, 5.0, math.radians(40.0)), 0.0
    elif name == "lawnmower":  # 10 s across a row's end and into its half-circle turn
        path = lawnmower(GROUND, 40.0, 50.0, 5.0, 10.0)
        trajectory, start = smooth_path(path), (360.0 - 2 * 20.0) / 5.0 - 5.0
    elif name == "loop":
        trajectory, start = smooth_path(random_loop(GROUND, 3, 60.0, 8.0, 10.0)), 4.0
    else:  # the default orbit mission with gusts, 10 s into the orbit, in the ENU frame of an origin 3 km away
        flight = Flight(orbit_waypoints(), home_point(), imperfections=Imperfections.realistic(),
                        rng=np.random.default_rng(5))
        to_scene = flight.frame.transform_to(LocalFrame(LAT0 + 0.02, LON0 - 0.02, 900.0))
        assert Rotation.from_matrix(to_scene[:3, :3]).magnitude() > 1e-4  # the tangent planes differ
        trajectory, start = flight_path(flight, 40.0, T_world_home=to_scene), 20.0
    position_m, attitude_deg = dead_reckoning_error(trajectory, start)
    assert position_m <= 1e-3 and attitude_deg <= 0.01, (position_m, attitude_deg)


def test_spline_paths_move_the_body_along_the_sampled_polyline():
    for path in (lawnmower(GROUND, 40.0, 50.0, 5.0, 10.0), random_loop(GROUND, 3, 60.0, 8.0, 10.0)):
        t = np.arange(0.0, path.length_m / path.speed_m_s, 0.5)
        off = np.linalg.norm(smooth_path(path).at(t).position - path.positions_at(path.speed_m_s * t), axis=1)
        assert np.median(off) < 0.05 and off.max() < 1.0, (path.mode, np.median(off), off.max())


def test_flight_spline_passes_through_the_gusty_flown_states():
    flight = Flight(orbit_waypoints(), home_point(), imperfections=Imperfections.realistic(),
                    rng=np.random.default_rng(5))
    path = flight_path(flight)
    t = np.linspace(0.0, path.duration_s, 997)
    truth = flight.state_at(t)
    kinematics = path.at(t)
    assert np.abs(kinematics.position - truth.position_enu_m).max() < 1e-3
    assert np.abs(kinematics.velocity - truth.velocity_enu_mps).max() < 0.02
    camera = np.transpose(kinematics.R_world_cam(), (0, 2, 1)) @ camera_matrix_world(*truth.gimbal_ypr_deg.T)
    angles = Rotation.from_matrix(camera).magnitude()
    assert math.degrees(angles.max()) < 1e-3


def test_noise_is_reproducible_from_the_seed_and_adds_to_the_truth():
    trajectory = CircleOrbit((0.0, 0.0), 50.0, 30.0, 5.0, 0.5)
    t = np.arange(400) / RATE_HZ
    first, again, other = (synthesize_imu(trajectory, t, RATE_HZ, EUROC_ADIS16448, seed) for seed in (1, 1, 2))
    np.testing.assert_array_equal(first.gyro, again.gyro)
    np.testing.assert_array_equal(first.accel_bias, again.accel_bias)
    assert not np.allclose(first.gyro, other.gyro)
    white = first.accel - first.accel_true - first.accel_bias
    expected = EUROC_ADIS16448.accelerometer_noise_density * math.sqrt(RATE_HZ)
    assert np.std(white) == pytest.approx(expected, rel=0.1)
    np.testing.assert_array_equal(first.gyro_bias[0], 0.0)


def allan_variance(x: np.ndarray, rate_hz: float, taus: np.ndarray) -> np.ndarray:
    """Overlapping Allan variance of a rate signal ``x`` (N,) sampled at ``rate_hz``, at cluster times ``taus``."""
    angle = np.concatenate([[0.0], np.cumsum(x)]) / rate_hz
    result = []
    for tau in taus:
        m = int(round(tau * rate_hz))
        second_difference = angle[2 * m:] - 2 * angle[m:-m] + angle[:-2 * m]
        result.append(np.mean(second_difference**2) / (2 * (m / rate_hz) ** 2))
    return np.array(result)


@pytest.mark.parametrize("sensor", ["gyroscope", "accelerometer"])
def test_allan_deviation_of_a_static_record_gives_the_configured_noise(sensor):
    """Four hours at rest: fit AVAR(tau) = N^2 / tau + K^2 tau / 3 (white noise N, bias random walk K) over
    tau from 0.03 s to 288 s, the three axes pooled; both within 10 % of EuRoC's ADIS16448 figures."""
    density = getattr(EUROC_ADIS16448, f"{sensor}_noise_density")
    walk = getattr(EUROC_ADIS16448, f"{sensor}_random_walk")
    count = int(ALLAN_HOURS * 3600 * RATE_HZ)
    white, bias = sensor_noise(count, RATE_HZ, density, walk, np.random.default_rng([0, 4]))
    taus = np.logspace(-1.5, math.log10(ALLAN_HOURS * 3600 / 50), 30)
    avar = np.mean([allan_variance(white[:, axis] + bias[:, axis], RATE_HZ, taus) for axis in range(3)], axis=0)
    design = np.column_stack([1 / taus, taus / 3]) / avar[:, None]
    n_squared, k_squared = np.linalg.lstsq(design, np.ones_like(avar), rcond=None)[0]
    assert math.sqrt(n_squared) == pytest.approx(density, rel=0.1)
    assert math.sqrt(k_squared) == pytest.approx(walk, rel=0.1)
