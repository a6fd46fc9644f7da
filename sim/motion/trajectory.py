"""Smooth trajectories of the rig's body (IMU) frame with analytic first and second derivatives.

A trajectory gives, at times ``t`` (seconds, vectorised), the :class:`Kinematics` of the body frame B:
position, velocity and acceleration in the world (ENU metres, m/s, m/s^2), and the attitude of the left
camera through the heading/tilt convention of :func:`sim.sampling.pose.camera_rotation` (heading clockwise from
north, tilt forward from nadir, radians here) with their rates. The camera is rigidly mounted on the body:
``R_world_body = R_world_cam @ R_cam_body`` (:data:`sim.motion.imu.T_BODY_CAM`), so the angular velocity
is closed-form: ``w_world = -heading' * z_up + tilt' * x_cam``.

Every value is an exact derivative of the positions and attitudes the renderer uses (no finite differences):

* :class:`CircleOrbit` -- a circle flown at constant speed facing its centre, in closed form;
* :class:`SplinePath` -- a C2 cubic spline of position in time (scipy ``CubicSpline`` and its
  ``derivative``), heading along the velocity (or a spline of its own), tilt constant or a spline. The
  lawnmower and random loop of :mod:`sim.sampling` (:func:`smooth_path`) and a virtual flight's flown path
  with its gusts (:func:`flight_path`) are fitted this way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from sim.sampling.pose import R_WORLD_NADIR
from sim.sampling.trajectories import Trajectory

#: Distance between the spline knots fitted to a polyline path, metres.
KNOT_SPACING_M = 2.0
#: Time between the spline knots fitted to a virtual flight, seconds.
FLIGHT_KNOT_S = 0.05


@dataclass(frozen=True)
class Kinematics:
    """State of the body frame at N times: ENU position (m), velocity (m/s), acceleration (m/s^2), each (N, 3);
    the left camera's heading and tilt (rad) and their rates (rad/s), each (N,), in the trajectory's own ENU
    frame, which ``frame_rotation`` (world <- own, 3x3; None: the same) turns into the world's."""

    t_s: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    heading: np.ndarray
    heading_rate: np.ndarray
    tilt: np.ndarray
    tilt_rate: np.ndarray
    frame_rotation: np.ndarray | None = None

    def R_world_cam(self) -> np.ndarray:
        """(N, 3, 3) left camera-to-world rotations (OpenCV camera axes), as :func:`sim.sampling.pose.camera_rotation`."""
        turn = Rotation.from_euler("z", -self.heading[:, None]).as_matrix()
        tilt = Rotation.from_euler("x", self.tilt[:, None]).as_matrix()
        return self._to_world(turn @ R_WORLD_NADIR @ tilt)

    def _to_world(self, vectors: np.ndarray) -> np.ndarray:
        """(N, 3) vectors or (N, 3, 3) matrices of the trajectory's own frame in the world frame."""
        if self.frame_rotation is None:
            return vectors
        return self.frame_rotation @ vectors if vectors.ndim == 3 else vectors @ self.frame_rotation.T

    def angular_velocity_world(self) -> np.ndarray:
        """(N, 3) angular velocity of the camera (and body) in the world frame, rad/s."""
        up = self._to_world(np.tile([0.0, 0.0, 1.0], (len(self.t_s), 1)))
        return -self.heading_rate[:, None] * up + self.tilt_rate[:, None] * self.R_world_cam()[:, :, 0]


def heading_along(velocity: np.ndarray, acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Compass heading (rad, clockwise from north) of the horizontal velocity and its exact rate (rad/s)."""
    east, north, a_east, a_north = velocity[:, 0], velocity[:, 1], acceleration[:, 0], acceleration[:, 1]
    return np.arctan2(east, north), (north * a_east - east * a_north) / (east**2 + north**2)


@dataclass(frozen=True)
class CircleOrbit:
    """A horizontal circle of ``radius_m`` around ``centre_xy`` at ENU height ``altitude_m``, flown at
    ``speed_m_s`` from ``start_angle_rad`` (counter-clockwise from east; ``clockwise`` reverses), camera
    heading towards the centre and tilted ``tilt_rad`` from nadir. Closed form; it never ends."""

    centre_xy: tuple[float, float]
    radius_m: float
    altitude_m: float
    speed_m_s: float
    tilt_rad: float
    start_angle_rad: float = 0.0
    clockwise: bool = False

    def at(self, t_s) -> Kinematics:
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        rate = self.speed_m_s / self.radius_m * (-1.0 if self.clockwise else 1.0)
        angle = self.start_angle_rad + rate * t
        radial = np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(t)])
        along = np.column_stack([-np.sin(angle), np.cos(angle), np.zeros_like(t)])
        position = radial * self.radius_m + [*self.centre_xy, self.altitude_m]
        # the centre lies along -radial, whose compass heading is -pi/2 - angle
        return Kinematics(t, position, along * self.radius_m * rate, -radial * self.radius_m * rate**2,
                          -math.pi / 2 - angle, np.full_like(t, -rate), np.full_like(t, self.tilt_rad),
                          np.zeros_like(t))


@dataclass(frozen=True)
class SplinePath:
    """A C2 path: ``position`` a (vector) ``CubicSpline`` of time (periodic for a loop); ``heading`` a spline of
    the unwrapped heading (rad) or None (along the horizontal velocity); ``tilt`` a spline (rad) or a constant.
    ``duration_s``: time of one lap (loop) or of the whole path. ``T_world_own``: 4x4 rigid transform from the
    splines' ENU frame to the world's (None: the same)."""

    position: CubicSpline
    heading: CubicSpline | None
    tilt: CubicSpline | float
    duration_s: float
    T_world_own: np.ndarray | None = None

    def at(self, t_s) -> Kinematics:
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        position, velocity, acceleration = (self.position(t, nu) for nu in range(3))
        if self.heading is None:
            heading, heading_rate = heading_along(velocity, acceleration)
        else:
            heading, heading_rate = self.heading(t), self.heading(t, 1)
        if isinstance(self.tilt, CubicSpline):
            tilt, tilt_rate = self.tilt(t), self.tilt(t, 1)
        else:
            tilt, tilt_rate = np.full_like(t, self.tilt), np.zeros_like(t)
        if self.T_world_own is None:
            return Kinematics(t, position, velocity, acceleration, heading, heading_rate, tilt, tilt_rate)
        R, shift = self.T_world_own[:3, :3], self.T_world_own[:3, 3]
        return Kinematics(t, position @ R.T + shift, velocity @ R.T, acceleration @ R.T, heading, heading_rate,
                          tilt, tilt_rate, R)


def _orbit_circle(path: Trajectory) -> CircleOrbit:
    """The closed-form circle of a :func:`sim.sampling.trajectories.orbit` polyline (its centre, radius, start, direction)."""
    centre = np.asarray(path.look_at_xy, dtype=np.float64)
    offsets = path.points[:2, :2] - centre
    turn = offsets[0, 0] * offsets[1, 1] - offsets[0, 1] * offsets[1, 0]
    return CircleOrbit(tuple(centre), float(np.linalg.norm(offsets[0])), float(path.points[0, 2]), path.speed_m_s,
                       math.radians(path.tilt_deg), math.atan2(offsets[0, 1], offsets[0, 0]), bool(turn < 0))


def _polyline_spline(path: Trajectory) -> SplinePath:
    """A cubic spline of time through the polyline resampled every ~:data:`KNOT_SPACING_M` at the path's speed."""
    length = path.length_m
    knots_s = np.linspace(0.0, length, max(4, math.ceil(length / KNOT_SPACING_M)) + 1)
    points = path.positions_at(knots_s)
    if path.closed:
        points[-1] = points[0]  # s = length is s = 0 again
    spline = CubicSpline(knots_s / path.speed_m_s, points, bc_type="periodic" if path.closed else "not-a-knot")
    return SplinePath(spline, None, math.radians(path.tilt_deg), length / path.speed_m_s)


def smooth_path(path: Trajectory) -> CircleOrbit | SplinePath:
    """The smooth, twice differentiable version of a :mod:`sim.sampling` trajectory: an orbit becomes the exact
    circle, a lawnmower or random loop a cubic spline through its polyline (the turns' curvature jumps smoothed
    over a knot or two)."""
    return _orbit_circle(path) if path.mode == "orbit" else _polyline_spline(path)


def flight_path(flight, start_s: float = 0.0, end_s: float | None = None, T_world_home: np.ndarray | None = None,
                knot_s: float = FLIGHT_KNOT_S) -> SplinePath:
    """The flown path of a :class:`sim.drone.flight.Flight` (gusts included) from ``start_s`` to ``end_s`` (the
    telemetry clock, seconds since the motors started; default the whole flight) as a C2 spline through its true
    state every ``knot_s`` seconds: position, the gimbal camera's heading (gimbal yaw) and tilt from nadir
    (90 deg + gimbal pitch). The path's time 0 is ``start_s``; ``T_world_home`` moves it from the flight's ENU
    frame (at the home point) into the world's."""
    end_s = flight.duration_s if end_s is None else end_s
    grid = np.arange(0.0, end_s - start_s + knot_s / 2, knot_s)
    state = flight.state_at(start_s + grid)
    yaw_deg, pitch_deg = state.gimbal_ypr_deg[:, 0], state.gimbal_ypr_deg[:, 1]
    heading = CubicSpline(grid, np.unwrap(np.radians(yaw_deg)))
    tilt = CubicSpline(grid, np.radians(90.0 + pitch_deg))
    return SplinePath(CubicSpline(grid, state.position_enu_m), heading, tilt, float(grid[-1]), T_world_home)
