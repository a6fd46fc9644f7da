"""A Litchi mission as the live view measures a flight against it: the path Litchi flies, where along it the
aircraft is, which leg, the planned gimbal pitch and photo interval there, the photos planned and the time left.

Frame: a local ENU frame at the first waypoint (:class:`flightplan.geodesy.LocalFrame`); horizontal positions are
``(east, north)`` metres, heights are metres above take-off (Litchi's altitudes, OSD's barometric height). The
path is :func:`flightplan.flown_path.curved_turns_path` (Litchi's curved turns); along-track distance ``s`` is
metres along it from the first waypoint.

Litchi's gimbal semantics (as the virtual drone flies them, :mod:`sim.drone.flight`): a waypoint in Focus POI mode
(1) plans the pitch that centres its POI, in Interpolate mode (2) its own ``gimbal_pitch_deg``, in Disabled mode
(0) the previous waypoint's; the pitch is interpolated linearly between waypoints. A leg speed of 0 means the
mission's cruising speed, which the CSV does not hold: :data:`CRUISE_SPEED_MPS` is assumed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightplan import litchi
from flightplan.flown_path import curved_turns_path
from flightplan.geodesy import LocalFrame

#: The speed of a leg whose CSV speed is 0 (Litchi: "the cruising speed") and of the return home (m/s).
CRUISE_SPEED_MPS = 5.0
#: The descent rate of the landing after the return home (m/s).
DESCENT_RATE_MPS = 1.5
#: How far behind and ahead of the last known along-track position the aircraft is looked for (m): a closed orbit
#: ends where it starts, so the whole path would put an aircraft at its start at the end too.
SEARCH_BEHIND_M, SEARCH_AHEAD_M = 20.0, 150.0


@dataclass(frozen=True)
class PlannedPath:
    """The path of a mission (module docstring) and what is planned along it, per waypoint ``i`` (``W`` of them) and
    per leg ``i`` (waypoint ``i`` to ``i+1``)."""

    frame: LocalFrame
    points_en: np.ndarray  # (M, 2) the flown path's polyline
    s_m: np.ndarray  # (M,) along-track distance of each polyline point
    waypoint_s_m: np.ndarray  # (W,) along-track distance where each waypoint is passed (nearest path point)
    altitude_m: np.ndarray  # (W,) height above take-off
    gimbal_pitch_deg: np.ndarray  # (W,) planned pitch at each waypoint
    speed_mps: np.ndarray  # (W,) speed of the leg starting there
    photo_interval_s: np.ndarray  # (W,) timed-photo interval of the leg starting there (<= 0: none)

    @property
    def length_m(self) -> float:
        return float(self.s_m[-1])

    @property
    def legs(self) -> int:
        return len(self.waypoint_s_m) - 1

    def locate(self, east_m: float, north_m: float, near_s_m: float) -> tuple[float, float]:
        """``(s, cross-track)`` of a horizontal position: the nearest path point within :data:`SEARCH_BEHIND_M` behind
        and :data:`SEARCH_AHEAD_M` ahead of ``near_s_m`` (its along-track distance, m) and the distance to it (m)."""
        low = max(0, int(np.searchsorted(self.s_m, near_s_m - SEARCH_BEHIND_M)) - 1)
        high = min(len(self.s_m) - 1, int(np.searchsorted(self.s_m, near_s_m + SEARCH_AHEAD_M)) + 1)
        return _nearest_on_polyline(self.points_en[low:high + 1], self.s_m[low:high + 1], np.array([east_m, north_m]))

    def leg_at(self, s_m: float) -> int:
        """0-based index of the leg at along-track distance ``s_m``."""
        return int(np.clip(np.searchsorted(self.waypoint_s_m, s_m, side="right") - 1, 0, self.legs - 1))

    def gimbal_pitch_at(self, s_m: float) -> float:
        """The planned gimbal pitch (degrees) at ``s_m``: interpolated between the waypoints."""
        return float(np.interp(s_m, self.waypoint_s_m, self.gimbal_pitch_deg))

    def altitude_at(self, s_m: float) -> float:
        """The planned height above take-off (m) at ``s_m``."""
        return float(np.interp(s_m, self.waypoint_s_m, self.altitude_m))

    def photo_interval_at(self, s_m: float) -> float:
        """The timed-photo interval (s) of the leg at ``s_m``; <= 0 where it takes none."""
        return float(self.photo_interval_s[self.leg_at(s_m)])

    def leg_times_s(self) -> np.ndarray:
        """(W-1,) seconds each leg takes at its speed."""
        return np.diff(self.waypoint_s_m) / self.speed_mps[:-1]

    def along_after_s(self, seconds: float) -> float:
        """Where along the path (m) the plan is ``seconds`` after the first waypoint, at the legs' speeds."""
        return float(np.interp(seconds, np.concatenate([[0.0], np.cumsum(self.leg_times_s())]), self.waypoint_s_m))

    def time_to_finish_s(self, s_m: float) -> float:
        """Seconds from ``s_m`` to the last waypoint at the legs' speeds."""
        times = self.leg_times_s()
        leg = self.leg_at(s_m)
        into_leg = (s_m - self.waypoint_s_m[leg]) / self.speed_mps[leg]
        return float(max(0.0, times[leg:].sum() - into_leg))

    def planned_photos(self) -> int:
        """How many timed photos the plan takes: one every interval from a waypoint to the next, consecutive legs
        with the same interval shooting one unbroken cadence."""
        times, intervals = self.leg_times_s(), self.photo_interval_s[:-1]
        count, start = 0, 0
        while start < len(intervals):
            end = start
            while end + 1 < len(intervals) and intervals[end + 1] == intervals[start]:
                end += 1
            if intervals[start] > 0:
                count += int(np.ceil(times[start:end + 1].sum() / intervals[start] - 1e-9))
            start = end + 1
        return count

    def position_en(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """A WGS84 position as (east, north) metres in the path's frame."""
        east, north, _ = self.frame.to_enu(lat_deg, lon_deg, 0.0)
        return float(east), float(north)


def _nearest_on_polyline(points: np.ndarray, s_m: np.ndarray, position: np.ndarray) -> tuple[float, float]:
    """``(s, distance)`` of the point of the polyline ``points`` (with along-track distances ``s_m``) nearest to
    ``position``."""
    if len(points) == 1:
        return float(s_m[0]), float(np.linalg.norm(position - points[0]))
    starts, steps = points[:-1], np.diff(points, axis=0)
    lengths2 = np.maximum((steps ** 2).sum(axis=1), 1e-18)
    fraction = np.clip(((position - starts) * steps).sum(axis=1) / lengths2, 0.0, 1.0)
    nearest = starts + fraction[:, None] * steps
    distance = np.linalg.norm(position - nearest, axis=1)
    best = int(np.argmin(distance))
    return float(s_m[best] + fraction[best] * (s_m[best + 1] - s_m[best])), float(distance[best])


def planned_path(mission: litchi.Mission) -> PlannedPath:
    """The :class:`PlannedPath` of a Litchi mission (``ValueError`` for one with fewer than 2 waypoints)."""
    waypoints = mission.waypoints
    if len(waypoints) < 2:
        raise ValueError(f"a mission needs at least 2 waypoints to fly along, got {len(waypoints)}")
    frame = LocalFrame(waypoints[0].latitude_deg, waypoints[0].longitude_deg, 0.0)
    east, north, _ = frame.to_enu(mission.column("latitude_deg"), mission.column("longitude_deg"), 0.0)
    vertices = np.stack([east, north], axis=1)
    points = curved_turns_path(vertices, mission.column("curve_size_m"))
    s_m = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    waypoint_s, near = [], 0.0
    for vertex in vertices:
        near, _ = _located(points, s_m, vertex, near)
        waypoint_s.append(near)
    waypoint_s[-1] = float(s_m[-1])  # Litchi passes the last waypoint exactly
    speeds = mission.column("speed_m_s")
    return PlannedPath(frame, points, s_m, np.maximum.accumulate(np.array(waypoint_s)),
                       mission.column("altitude_m"), _planned_pitches(frame, waypoints),
                       np.where(speeds > 0, speeds, CRUISE_SPEED_MPS), mission.column("photo_time_interval_s"))


def _located(points: np.ndarray, s_m: np.ndarray, vertex: np.ndarray, near_s_m: float) -> tuple[float, float]:
    """Where along the path a waypoint is passed: the nearest point at or after the previous waypoint's."""
    ahead = max(int(np.searchsorted(s_m, near_s_m)) - 1, 0)
    return _nearest_on_polyline(points[ahead:], s_m[ahead:], vertex)


def _planned_pitches(frame: LocalFrame, waypoints) -> np.ndarray:
    """Each waypoint's planned gimbal pitch (degrees, 0 horizon, -90 nadir; module docstring)."""
    pitches, pitch = [], 0.0
    for waypoint in waypoints:
        if waypoint.gimbal_mode == litchi.GIMBAL_FOCUS_POI and waypoint.has_poi:
            east, north, _ = frame.to_enu(waypoint.latitude_deg, waypoint.longitude_deg, 0.0)
            poi_east, poi_north, _ = frame.to_enu(waypoint.poi_latitude_deg, waypoint.poi_longitude_deg, 0.0)
            pitch = float(np.degrees(np.arctan2(waypoint.poi_altitude_m - waypoint.altitude_m,
                                                np.hypot(poi_east - east, poi_north - north))))
        elif waypoint.gimbal_mode == litchi.GIMBAL_INTERPOLATE:
            pitch = waypoint.gimbal_pitch_deg
        pitches.append(float(np.clip(pitch, -90.0, 0.0)))
    return np.array(pitches)
