"""Benchmark the IMU: cost per rendered frame of synthesizing and writing it, against the dead-reckoning error
its samples leave at each rate.

    .venv/bin/python tools/bench/bench_imu.py [--seconds 10] [--frame-rate 10]

For each trajectory the renderer follows (the closed-form orbit, the spline lawnmower and random loop of an
analytic sloped ground, the gusty flown path of the default orbit mission) and each IMU rate, the table prints:
milliseconds per rendered frame (``--frame-rate``) to synthesize the samples (trajectory evaluation, noise) and to
write them (``imu/NN.csv``), and the position (mm) and attitude (deg) error after ``--seconds`` of integrating the
noise-free samples from the first true state with RK4 (two samples a step) -- what the sampling rate leaves to
a consumer's integrator. A rendered frame itself costs ~0.1-1 s (tools/bench/bench_render.py).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from flightplan.demo_location import DEMO_ORIGIN  # noqa: E402
from flightplan.orbit import OrbitRequest, plan_orbit  # noqa: E402
from sim.dataset.imu_file import write_imu_csv  # noqa: E402
from sim.drone import Imperfections, fly  # noqa: E402
from sim.drone.mission import HomePoint, waypoints_from_litchi  # noqa: E402
from sim.motion.imu import EUROC_ADIS16448, R_world_body, dead_reckon, synthesize_imu  # noqa: E402
from sim.motion.trajectory import CircleOrbit, flight_path, smooth_path  # noqa: E402
from sim.sampling.trajectories import lawnmower, random_loop  # noqa: E402

RATES_HZ = (100.0, 200.0, 400.0, 1000.0)


class SlopedGround:
    """A slope east plus a wave north over 400 m x 300 m (the sampling tests' analytic ground)."""

    valid_area = (-200.0, 200.0, -150.0, 150.0)

    def ground_height(self, x, y):
        return 0.02 * np.asarray(x) + 3.0 * np.sin(np.asarray(y) / 40.0)


def trajectories() -> dict:
    """Name -> (trajectory, start time s) of each kind the renderer follows."""
    ground = SlopedGround()
    plan = plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg))
    home = HomePoint(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg, DEMO_ORIGIN.h0_m)
    flight = fly(waypoints_from_litchi(plan.mission), home, Imperfections.realistic(), seed=5).flight
    return {
        "orbit (closed form)": (CircleOrbit((0.0, 0.0), 50.0, 30.0, 5.0, math.radians(40.0)), 0.0),
        "lawnmower (spline)": (smooth_path(lawnmower(ground, 40.0, 50.0, 5.0, 10.0)), 59.0),
        "random loop (spline)": (smooth_path(random_loop(ground, 3, 60.0, 8.0, 10.0)), 4.0),
        "flight + gusts (spline)": (flight_path(flight, float(flight.waypoint_times_s()[0])), 0.0),
    }


def row(name: str, trajectory, start_s: float, rate_hz: float, seconds: float, frame_rate_hz: float,
        scratch: Path) -> str:
    t = start_s + np.arange(int(seconds * rate_hz) + 1) / rate_hz
    begin = time.perf_counter()
    samples = synthesize_imu(trajectory, t, rate_hz, EUROC_ADIS16448, seed=0)
    synthesize_s = time.perf_counter() - begin
    begin = time.perf_counter()
    write_imu_csv(scratch / "imu.csv", samples)
    write_s = time.perf_counter() - begin
    truth = samples.kinematics
    R_true = R_world_body(truth)
    R, _, p = dead_reckon(samples.gyro_true, samples.accel_true, rate_hz, R_true[0], truth.velocity[0],
                          truth.position[0])
    frames = seconds * frame_rate_hz
    position_mm = 1000 * np.linalg.norm(p - truth.position[-1])
    attitude_deg = math.degrees(Rotation.from_matrix(R_true[-1].T @ R).magnitude())
    return (f"{name:<24} {rate_hz:7.0f} {1000 * synthesize_s / frames:12.3f} {1000 * write_s / frames:10.3f} "
            f"{position_mm:12.2e} {attitude_deg:12.2e}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each record, s")
    parser.add_argument("--frame-rate", type=float, default=10.0, help="rendered frames per second")
    args = parser.parse_args(argv)
    print(f"{'trajectory':<24} {'IMU Hz':>7} {'synth ms/fr':>12} {'write ms/fr':>10} "
          f"{'pos err mm':>12} {'att err deg':>12}   (after {args.seconds:g} s, {args.frame_rate:g} frames/s)")
    with tempfile.TemporaryDirectory() as folder:
        for name, (trajectory, start_s) in trajectories().items():
            for rate_hz in RATES_HZ:
                print(row(name, trajectory, start_s, rate_hz, args.seconds, args.frame_rate, Path(folder)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
