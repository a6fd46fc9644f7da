"""Trajectories: polyline paths flown at constant speed over the ground (orbit, lawnmower, random loop); frame ``i``
is taken at ``t = i / frame_rate``. The smooth, twice-differentiable versions are in :mod:`sim.motion`."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from sim.render.camera import pose_from_position
from sim.sampling.pose import GroundModel, PoseSample, camera_rotation, covered_polygon, height_above_ground, inner_area
from sim.sampling.seeds import PATH_STREAM


PATH_STEP_M = 0.25
#: The random loop's forward camera tilt from nadir (degrees).
RANDOM_LOOP_TILT_DEG = 20.0


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A flight path flown at constant speed; frame ``i`` is taken at ``t = i / frame_rate_hz``.

    ``points``: a dense (M, 3) ENU polyline; ``closed``: the path loops (frames beyond one lap go
    round again); the camera heading follows the path, or points at ``look_at_xy`` if given;
    ``tilt_deg`` tilts it forward from nadir.
    """

    points: np.ndarray
    closed: bool
    speed_m_s: float
    frame_rate_hz: float
    tilt_deg: float
    look_at_xy: tuple[float, float] | None = None
    mode: str = "trajectory"

    @functools.cached_property
    def _arc(self) -> tuple[np.ndarray, np.ndarray]:
        """The polyline (closed loops repeat their first point) and the arc length at each vertex."""
        path = np.vstack([self.points, self.points[:1]]) if self.closed else self.points
        return path, np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])

    @property
    def length_m(self) -> float:
        return float(self._arc[1][-1])

    def frames_available(self) -> int | None:
        """How many frames fit on an open path (None for a loop)."""
        if self.closed:
            return None
        return int(math.floor(self.length_m / self.speed_m_s * self.frame_rate_hz + 1e-9)) + 1

    def positions_at(self, s: np.ndarray) -> np.ndarray:
        """ENU positions (M, 3) at arc lengths ``s`` (metres; a loop wraps, an open path is clamped at its ends)."""
        path, arc = self._arc
        s = np.mod(s, arc[-1]) if self.closed else np.clip(s, 0.0, arc[-1])
        return np.stack([np.interp(s, arc, path[:, axis]) for axis in range(3)], axis=-1)

    def pose(self, ground: GroundModel, index: int) -> PoseSample:
        """The pose at frame ``index``."""
        available = self.frames_available()
        if available is not None and index >= available:
            raise ValueError(f"the {self.mode} path is {self.length_m:.0f} m long: {available} frames at "
                             f"{self.speed_m_s} m/s and {self.frame_rate_hz} Hz, frame {index} is beyond it")
        time_s = index / self.frame_rate_hz
        T, heading = self._pose_heading(time_s)
        details = {"mode": self.mode, "heading_deg": heading, "tilt_x_deg": self.tilt_deg, "tilt_y_deg": 0.0}
        return PoseSample(index, T, time_s, height_above_ground(ground, T[:3, 3]), 0, details)

    def pose_at(self, time_s: float) -> np.ndarray:
        """``T_world_cam`` at ``time_s`` seconds from the start (frame ``i`` at ``i / frame_rate_hz``; an open
        path holds its end pose beyond its ends)."""
        return self._pose_heading(time_s)[0]

    def _pose_heading(self, time_s: float) -> tuple[np.ndarray, float]:
        """The pose at ``time_s`` and its heading (degrees clockwise from north)."""
        s = self.speed_m_s * time_s
        if not self.closed:
            s = min(max(s, 0.0), self.length_m)
        position = self.positions_at(np.array(s))
        if self.look_at_xy is not None:
            east, north = np.subtract(self.look_at_xy, position[:2])
        else:
            ahead, behind = self.positions_at(np.array(s + PATH_STEP_M)), self.positions_at(np.array(s - PATH_STEP_M))
            east, north = (ahead - behind)[:2]
        heading = math.degrees(math.atan2(east, north)) % 360.0
        return pose_from_position(position, camera_rotation(heading, self.tilt_deg)), heading


def _terrain_following(ground: GroundModel, xy: np.ndarray, height_m: float) -> np.ndarray:
    z = np.asarray(ground.ground_height(xy[:, 0], xy[:, 1]), dtype=float) + height_m
    return np.column_stack([xy, z])


def orbit(ground: GroundModel, center_xy, radius_m: float, height_m: float, speed_m_s: float,
          frame_rate_hz: float, tilt_deg: float | None = None, clockwise: bool = False) -> Trajectory:
    """A circle at constant altitude (``height_m`` above the ground at the centre), camera facing the centre.

    ``tilt_deg`` None aims the optical axis at the ground below the centre.
    """
    steps = max(64, int(math.ceil(2 * math.pi * radius_m / PATH_STEP_M)))
    angles = np.linspace(0.0, 2 * math.pi, steps, endpoint=False) * (-1 if clockwise else 1)
    altitude = float(np.asarray(ground.ground_height(*center_xy))) + height_m
    points = np.column_stack([center_xy[0] + radius_m * np.cos(angles), center_xy[1] + radius_m * np.sin(angles),
                              np.full(steps, altitude)])
    tilt = math.degrees(math.atan2(radius_m, height_m)) if tilt_deg is None else tilt_deg
    return Trajectory(points, True, speed_m_s, frame_rate_hz, tilt, tuple(center_xy), "orbit")


def lawnmower(ground: GroundModel, spacing_m: float, height_m: float, speed_m_s: float, frame_rate_hz: float,
              margin_m: float = 20.0, tilt_deg: float = 0.0) -> Trajectory:
    """East-west rows ``spacing_m`` apart over the valid area (its largest rectangle inside the covered polygon when
    the ground has one) less ``margin_m``, joined by half-circle turns; terrain following."""
    xmin, xmax, ymin, ymax = inner_area(ground, margin_m, covered_polygon(ground))
    radius = spacing_m / 2
    rows = np.arange(ymin, ymax + 1e-9, spacing_m)
    if len(rows) < 2 or xmax - xmin <= spacing_m:
        inside = "" if covered_polygon(ground) is None else " (its largest rectangle inside the covered polygon)"
        raise ValueError(f"the valid area {ground.valid_area}{inside} with margin {margin_m} m is too small for "
                         f"{spacing_m} m row spacing")
    west, east = xmin + radius, xmax - radius
    row_x = np.arange(west, east, PATH_STEP_M)
    turn = np.linspace(-math.pi / 2, math.pi / 2, max(8, int(math.pi * radius / PATH_STEP_M)))
    pieces = []
    for row, y in enumerate(rows):
        eastbound = row % 2 == 0
        pieces.append(np.column_stack([row_x if eastbound else row_x[::-1], np.full(row_x.size, y)]))
        if row + 1 < len(rows):
            side = 1.0 if eastbound else -1.0
            end_x = east if eastbound else west
            pieces.append(np.column_stack([end_x + side * radius * np.cos(turn), y + radius + radius * np.sin(turn)]))
    return Trajectory(_terrain_following(ground, np.vstack(pieces), height_m), False, speed_m_s, frame_rate_hz,
                      tilt_deg, None, "lawnmower")


def random_loop(ground: GroundModel, seed: int, height_m: float, speed_m_s: float, frame_rate_hz: float,
                control_points: int = 8, margin_m: float = 20.0, tilt_deg: float = RANDOM_LOOP_TILT_DEG) -> Trajectory:
    """A smooth random closed loop (periodic cubic spline through random points around the centre of the valid
    area, or of its largest rectangle inside the covered polygon when the ground has one, less ``margin_m``)."""
    rng = np.random.default_rng([seed, PATH_STREAM])
    xmin, xmax, ymin, ymax = inner_area(ground, margin_m, covered_polygon(ground))
    centre, half = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2]), np.array([(xmax - xmin) / 2, (ymax - ymin) / 2])
    # One point per sector, not too close to the centre: a star-shaped loop without tight kinks.
    angles = (np.arange(control_points) + rng.uniform(0.2, 0.8, control_points)) * 2 * math.pi / control_points
    radii = rng.uniform(0.55, 1.0, control_points)
    knots = np.column_stack([np.cos(angles), np.sin(angles)]) * radii[:, None]
    spline = CubicSpline(np.arange(control_points + 1), np.vstack([knots, knots[:1]]), bc_type="periodic")
    unit_loop = spline(np.linspace(0.0, control_points, 400 * control_points, endpoint=False))
    unit_loop /= np.abs(unit_loop).max()  # keep the overshooting spline inside the area
    xy = centre + unit_loop * half
    return Trajectory(_terrain_following(ground, xy, height_m), True, speed_m_s, frame_rate_hz, tilt_deg,
                      None, "random_loop")
