"""The true flight of a Litchi waypoint mission: take-off, transit, curved legs, return and landing.

Everything is in the local ENU frame of the home point (metres, seconds since the motors started, which is
also the telemetry clock). Angles follow DJI: degrees, NED ZYX, yaw clockwise from north in [-180, 180),
pitch negative nose/camera down, gimbal pitch 0 = horizon, -90 = nadir.

Litchi semantics modelled (see ``research/litchi.md``): the leg speed and photo interval of a waypoint apply
until the next waypoint; a waypoint with a POI gets the heading that faces it (and, in gimbal Focus POI mode,
the pitch that centres it), otherwise its own heading / gimbal pitch; both are interpolated linearly between
the waypoints (heading the short way round).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.attitude import wrap_deg
from capture.messages import MAX_FLY_TIME_S
from flightplan.geodesy import LocalFrame
from sim.drone import path as pathlib
from sim.drone.flight_faults import NO_FAULTS, FlightFaults
from sim.drone.imperfections import Imperfections, PathDeviation, first_order_lag
from sim.drone.mission import GIMBAL_FOCUS_POI, GIMBAL_INTERPOLATE, HomePoint, Waypoint

GRAVITY_MPS2 = 9.80665
#: Leg index of the pieces before the mission (take-off, transit) and after it (return, landing).
BEFORE_MISSION, AFTER_MISSION = -1, -2
#: Phase names, in flight order; ``state_at`` reports them as indices into this tuple.
PHASES = ("on_ground", "takeoff", "transit", "mission", "return", "landing")


@dataclass(frozen=True)
class FlightConfig:
    """How the aircraft flies what the mission does not say (Mini SE P-mode-like values)."""

    cruise_speed_mps: float = 5.0
    climb_rate_mps: float = 2.0
    descent_rate_mps: float = 1.5
    accel_mps2: float = 2.0
    drag_per_s: float = 0.4
    ground_time_s: float = 2.0
    gimbal_pitch_range_deg: tuple[float, float] = (-90.0, 0.0)
    gimbal_grid_s: float = 0.02

    def __post_init__(self) -> None:
        for name in ("cruise_speed_mps", "climb_rate_mps", "descent_rate_mps", "accel_mps2", "gimbal_grid_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"flight config {name} must be > 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class FlightState:
    """True state at N times; ENU metres and m/s, DJI angles in degrees (see module docstring)."""

    t_s: np.ndarray
    position_enu_m: np.ndarray
    velocity_enu_mps: np.ndarray
    aircraft_ypr_deg: np.ndarray
    gimbal_ypr_deg: np.ndarray
    phase: np.ndarray


def bearing_enu_deg(from_enu: np.ndarray, to_enu: np.ndarray) -> np.ndarray:
    """Bearing (degrees clockwise from the frame's north) from points to points, horizontally."""
    d = np.asarray(to_enu, float) - np.asarray(from_enu, float)
    return np.degrees(np.arctan2(d[..., 0], d[..., 1]))


def elevation_enu_deg(from_enu: np.ndarray, to_enu: np.ndarray) -> np.ndarray:
    """Elevation angle (degrees, negative = below) of points seen from points."""
    d = np.asarray(to_enu, float) - np.asarray(from_enu, float)
    return np.degrees(np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])))


def tilt_from_forces(accel_enu, air_velocity_enu, yaw_deg, drag_per_s: float):
    """Pitch and roll (degrees, DJI signs) that point the thrust along ``accel + drag * airspeed + g``.

    A multicopter leans its thrust to accelerate and to push against air drag (linear, ``drag_per_s``):
    nose down (negative pitch) to go forward, right side down (positive roll) to go right.
    """
    force = np.asarray(accel_enu, float).copy()
    force[:, :2] += drag_per_s * np.asarray(air_velocity_enu, float)[:, :2]
    yaw = np.radians(yaw_deg)
    forward = force[:, 0] * np.sin(yaw) + force[:, 1] * np.cos(yaw)
    right = force[:, 0] * np.cos(yaw) - force[:, 1] * np.sin(yaw)
    lift = GRAVITY_MPS2 + force[:, 2]
    pitch = np.degrees(np.arctan2(-forward, lift))
    roll = np.degrees(np.arctan2(right, np.hypot(forward, lift)))
    return pitch, roll


def _ground_taper(up_m: np.ndarray, height_m: float = 5.0):
    """Weight 0 on the ground rising smoothly to 1 at ``height_m`` (gusts cannot move a landed aircraft)."""
    x = np.clip(up_m / height_m, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x), np.where((x > 0) & (x < 1), 6.0 * x * (1.0 - x) / height_m, 0.0)


class Flight:
    """The true flight of ``waypoints`` from ``home``; wind gusts drawn from ``rng`` when imperfect; ``faults``
    asked for (:mod:`sim.drone.flight_faults`: a gust's push and a stuck gimbal act here)."""

    def __init__(self, waypoints: list[Waypoint], home: HomePoint, config: FlightConfig = FlightConfig(),
                 imperfections: Imperfections = Imperfections.none(), rng: np.random.Generator | None = None,
                 faults: FlightFaults = NO_FAULTS):
        if len(waypoints) < 2:
            raise ValueError(f"a mission needs at least 2 waypoints, got {len(waypoints)}")
        self.waypoints = list(waypoints)
        self.home = home
        self.config = config
        self.imperfections = imperfections
        self.frame = LocalFrame(home.latitude_deg, home.longitude_deg, home.height_ellipsoid_m)
        self.waypoints_enu = self._to_enu([(w.latitude_deg, w.longitude_deg, w.altitude_m) for w in waypoints])
        self.pieces, self.waypoint_s_m = self._build_pieces()
        self.profile = pathlib.speed_profile(self.pieces, config.accel_mps2)
        self.duration_s = self.profile.duration_s + 2.0 * config.ground_time_s
        self._refuse_too_long()
        self.waypoint_heading_deg, self.waypoint_gimbal_pitch_deg = self._waypoint_commands()
        self.faults = faults
        faults.check_flight(self.duration_s)
        self._gust_direction_enu = self._right_of_travel(faults.gust.start_s) if faults.gust else None
        if imperfections.gust_offset_std_m > 0 and rng is None:
            raise ValueError("wind gusts need a numpy Generator (rng)")
        self.deviation = PathDeviation(self.duration_s, imperfections.gust_offset_std_m,
                                       imperfections.gust_time_s, rng)
        self._gimbal_grid = self._lagged_gimbal_grid()

    # --- construction -------------------------------------------------------------------------------------
    def _refuse_too_long(self) -> None:
        """``ValueError`` for a flight longer than its telemetry can say (a leg crawling at 1e-300 m/s), before
        its samples fill the memory."""
        if not self.duration_s <= MAX_FLY_TIME_S:
            raise ValueError(f"the mission flies {self.duration_s:.6g} s ({self.duration_s / 3600:.3g} h); a flight "
                             f"lasts at most {MAX_FLY_TIME_S:g} s ({MAX_FLY_TIME_S / 60:.0f} min, the longest fly time "
                             "DJI's OSD telemetry holds): fly it faster, or as several missions")

    def _to_enu(self, lat_lon_alt) -> np.ndarray:
        lat, lon, alt = np.asarray(lat_lon_alt, float).T
        return self.frame.enu_points(lat, lon, self.home.height_ellipsoid_m + alt)

    def _leg_speed(self, index: int) -> float:
        return self.waypoints[index].speed_mps or self.config.cruise_speed_mps

    def _build_pieces(self):
        """Path pieces and the path arc length at which each waypoint is passed (the middle of its curve)."""
        cfg, pts = self.config, self.waypoints_enu
        legs = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        if np.any(legs < 1e-3):
            i = int(np.argmax(legs < 1e-3))
            raise ValueError(f"waypoints {i + 1} and {i + 2} coincide: a leg must be longer than 1 mm")
        first, last = pts[0], pts[-1]
        pieces = []
        self._append(pieces, pathlib.line([0, 0, 0], [0, 0, first[2]], cfg.climb_rate_mps, BEFORE_MISSION, "takeoff"))
        self._append(pieces, pathlib.line([0, 0, first[2]], first, cfg.cruise_speed_mps, BEFORE_MISSION, "transit"))
        tangents = pathlib.corner_tangent_lengths(pts, [w.curvesize_m for w in self.waypoints])
        arcs = [None] + [pathlib.corner_arc(pts[i - 1], pts[i], pts[i + 1], tangents[i], "mission")
                         for i in range(1, len(pts) - 1)] + [None]
        halves = [self._split_corner(arcs[i], i) for i in range(len(pts))]
        waypoint_s = [sum(p.length_m for p in pieces)]
        for i in range(len(pts) - 1):
            direction = (pts[i + 1] - pts[i]) / legs[i]
            start = pts[i] + (tangents[i] if arcs[i] else 0.0) * direction
            end = pts[i + 1] - (tangents[i + 1] if arcs[i + 1] else 0.0) * direction
            self._append(pieces, halves[i][1])
            self._append(pieces, pathlib.line(start, end, self._leg_speed(i), i, "mission"))
            self._append(pieces, halves[i + 1][0])
            waypoint_s.append(sum(p.length_m for p in pieces))
        self._append(pieces, pathlib.line(last, [0, 0, last[2]], cfg.cruise_speed_mps, AFTER_MISSION, "return"))
        self._append(pieces, pathlib.line([0, 0, last[2]], [0, 0, 0], cfg.descent_rate_mps, AFTER_MISSION, "landing"))
        return pieces, np.array(waypoint_s)

    def _split_corner(self, arc, index: int):
        """The halves of waypoint ``index``'s corner arc: the end of leg index-1 and the start of leg index."""
        if arc is None:
            return None, None
        speeds = (self._leg_speed(index - 1), self._leg_speed(index))
        return pathlib.split_arc(arc, arc.length_m / 2.0, (index - 1, index), speeds)

    @staticmethod
    def _append(pieces: list, piece) -> None:
        if piece is not None and piece.length_m > 1e-9:
            pieces.append(piece)

    def _waypoint_commands(self):
        """Heading and gimbal pitch (degrees) that Litchi commands at each waypoint."""
        headings, pitches = [], []
        low, high = self.config.gimbal_pitch_range_deg
        pitch = 0.0
        for i, (w, p) in enumerate(zip(self.waypoints, self.waypoints_enu)):
            poi = self._to_enu([(w.poi_latitude_deg, w.poi_longitude_deg, w.poi_altitude_m)])[0] if w.has_poi else None
            headings.append(float(bearing_enu_deg(p, poi)) if poi is not None else w.heading_deg)
            if w.gimbalmode == GIMBAL_FOCUS_POI:
                if poi is None:
                    raise ValueError(f"waypoint {i + 1}: gimbal mode Focus POI (1) needs a POI, but poi is 0,0")
                pitch = float(elevation_enu_deg(p, poi))
            elif w.gimbalmode == GIMBAL_INTERPOLATE:
                pitch = w.gimbalpitchangle_deg
            pitches.append(float(np.clip(pitch, low, high)))  # gimbal mode 0 keeps the previous pitch
        return np.array(headings), np.array(pitches)

    def _commanded(self, s_m: np.ndarray):
        """Commanded aircraft heading and gimbal pitch at path arc lengths ``s_m`` (interpolated per leg)."""
        ws = self.waypoint_s_m
        i = np.clip(np.searchsorted(ws, s_m, side="right") - 1, 0, len(ws) - 2)
        f = np.clip((s_m - ws[i]) / (ws[i + 1] - ws[i]), 0.0, 1.0)
        h0, h1 = self.waypoint_heading_deg[i], self.waypoint_heading_deg[i + 1]
        p0, p1 = self.waypoint_gimbal_pitch_deg[i], self.waypoint_gimbal_pitch_deg[i + 1]
        return wrap_deg(h0 + f * wrap_deg(h1 - h0)), p0 + f * (p1 - p0)

    def _lagged_gimbal_grid(self):
        """Gimbal yaw (unwrapped) and pitch after the first-order gimbal lag, on a regular time grid."""
        lag = self.imperfections.gimbal_lag_s
        if lag == 0:
            return None
        grid = np.arange(0.0, self.duration_s + self.config.gimbal_grid_s, self.config.gimbal_grid_s)
        heading, pitch = self._commanded(self._arc_length(grid)[0])
        command = np.stack([np.unwrap(heading, period=360.0), pitch], axis=1)
        return grid, first_order_lag(command, self.config.gimbal_grid_s, lag)

    def _right_of_travel(self, t_s: float) -> np.ndarray:
        """The horizontal unit vector (ENU) to the right of the planned path at ``t_s`` (east while the path is
        vertical: the climb, the descent)."""
        s, _, _ = self._arc_length([t_s])
        _, tangent, _, _ = pathlib.evaluate(self.pieces, s)
        east, north = tangent[0, :2]
        length = np.hypot(east, north)
        return np.array([north / length, -east / length, 0.0]) if length > 1e-6 else np.array([1.0, 0.0, 0.0])

    # --- sampling -----------------------------------------------------------------------------------------
    def _arc_length(self, t_s: np.ndarray):
        return self.profile.at(np.asarray(t_s, float) - self.config.ground_time_s)

    def state_at(self, t_s) -> FlightState:
        """The true state at times ``t_s`` (seconds since the motors started; clipped to the flight)."""
        t = np.atleast_1d(np.asarray(t_s, float))
        s, speed, accel_along = self._arc_length(t)
        nominal, tangent, curvature, piece = pathlib.evaluate(self.pieces, s)
        weight, weight_rate = _ground_taper(nominal[:, 2])
        offset, offset_rate, offset_accel = self.deviation.at(t)
        if self._gust_direction_enu is not None:
            push = self.faults.gust.offset_at(t, self._gust_direction_enu)
            offset, offset_rate, offset_accel = offset + push[0], offset_rate + push[1], offset_accel + push[2]
        velocity_nominal = speed[:, None] * tangent
        position = nominal + weight[:, None] * offset
        taper_rate = weight_rate * velocity_nominal[:, 2]
        velocity = velocity_nominal + weight[:, None] * offset_rate + taper_rate[:, None] * offset
        accel = accel_along[:, None] * tangent + (speed**2)[:, None] * curvature + weight[:, None] * offset_accel
        heading, gimbal_pitch = self._commanded(s)
        airspeed = velocity - self.imperfections.wind_velocity_enu() * (nominal[:, 2] > 0)[:, None]
        pitch, roll = tilt_from_forces(accel, airspeed, heading, self.config.drag_per_s)
        gimbal_yaw = heading
        if self._gimbal_grid is not None:
            grid, lagged = self._gimbal_grid
            gimbal_yaw = wrap_deg(np.interp(t, grid, lagged[:, 0]))
            gimbal_pitch = np.interp(t, grid, lagged[:, 1])
        gimbal_pitch = self.faults.gimbal_pitch_deg(t, gimbal_pitch)
        on_ground = (t <= self.config.ground_time_s) | (t >= self.duration_s - self.config.ground_time_s)
        phase = np.where(on_ground, 0, [PHASES.index(self.pieces[k].phase) for k in piece])
        return FlightState(
            t_s=t,
            position_enu_m=position,
            velocity_enu_mps=velocity,
            aircraft_ypr_deg=np.stack([heading, pitch, roll], axis=1),
            gimbal_ypr_deg=np.stack([gimbal_yaw, gimbal_pitch, np.zeros_like(t)], axis=1),
            phase=phase.astype(np.int8),
        )

    def waypoint_times_s(self) -> np.ndarray:
        """When the aircraft passes each waypoint (the middle of its curve), seconds since motors on."""
        return self.profile.time_at(self.waypoint_s_m) + self.config.ground_time_s

    def photo_times_s(self) -> np.ndarray:
        """Times of the timed photos: every ``photo_timeinterval`` from passing a waypoint until the next.

        Consecutive legs with the same interval form one shooting session with an unbroken cadence.
        """
        passes = self.waypoint_times_s()
        intervals = [w.photo_timeinterval_s for w in self.waypoints[:-1]]
        times, i = [], 0
        while i < len(intervals):
            j = i
            while j + 1 < len(intervals) and intervals[j + 1] == intervals[i]:
                j += 1
            if intervals[i] > 0:
                times.append(np.arange(passes[i], passes[j + 1] - 1e-9, intervals[i]))
            i = j + 1
        return np.concatenate(times) if times else np.zeros(0)
