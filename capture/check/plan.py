"""The planned path of a Litchi mission in the geotags' ENU frame (metres, origin the take-off point): its arcs,
where a photo or a shutter event lies along it, and the gimbal pitch it plans there.

An arc is one leg of the mission on which it takes timed photos (waypoint k to k + 1, where waypoint k's
``photo_time_interval_s`` > 0): the piece a re-fly can repeat on its own. Points are placed on the path by their
horizontal position (the nearest point of the polyline through the waypoints; Litchi's curves cut the corners by
less than their ``curvesize``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flightplan import litchi
from flightplan.geodesy import LocalFrame


@dataclass(frozen=True)
class Arc:
    """One photo leg: its 1-based ``number`` in flight order, its start waypoint (0-based; it ends at the next),
    its along-path span (m from the first waypoint) and the photos it plans (length / (speed x interval); NaN where
    the leg flies at the mission's unstated cruise speed)."""

    number: int
    first_waypoint: int
    start_m: float
    end_m: float
    expected_photos: float

    def to_dict(self) -> dict:
        expected = round(self.expected_photos, 1) if math.isfinite(self.expected_photos) else None
        return {"arc": self.number, "waypoints": [self.first_waypoint + 1, self.first_waypoint + 2],
                "length_m": round(self.end_m - self.start_m, 2), "expected_photos": expected}


class PlannedPath:
    """``mission``'s waypoints in ``frame`` (heights: the frame's h0 + their altitude above take-off) and its arcs."""

    def __init__(self, mission: litchi.Mission, frame: LocalFrame):
        self.mission = mission
        self.frame = frame
        rows = mission.waypoints
        self.enu_m = frame.enu_points(mission.column("latitude_deg"), mission.column("longitude_deg"),
                                      frame.h0_m + mission.column("altitude_m"))
        lengths = np.linalg.norm(np.diff(self.enu_m[:, :2], axis=0), axis=1)
        self.waypoint_m = np.concatenate([[0.0], np.cumsum(lengths)])
        photo_legs = [leg for leg in range(len(rows) - 1) if rows[leg].photo_time_interval_s > 0]
        self.arcs = [Arc(number, leg, float(self.waypoint_m[leg]), float(self.waypoint_m[leg + 1]),
                         planned_photos(lengths[leg], rows[leg]))
                     for number, leg in enumerate(photo_legs, start=1)]

    @property
    def photo_interval_s(self) -> float:
        """The shortest timed-photo interval the mission asks for (s; NaN with none)."""
        intervals = [row.photo_time_interval_s for row in self.mission.waypoints if row.photo_time_interval_s > 0]
        return min(intervals) if intervals else math.nan

    def locate(self, east_north: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For points (N,2 ENU metres): the leg each lies nearest (0-based), the fraction along it (0..1) and the
        horizontal distance to it (m)."""
        points = np.asarray(east_north, float).reshape(-1, 2)
        start, end = self.enu_m[:-1, :2], self.enu_m[1:, :2]
        span = end - start
        fraction = np.einsum("nlk,lk->nl", points[:, None, :] - start, span) / np.maximum(
            np.einsum("lk,lk->l", span, span), 1e-12)
        fraction = np.clip(fraction, 0.0, 1.0)
        nearest = start + fraction[..., None] * span
        distance = np.linalg.norm(points[:, None, :] - nearest, axis=-1)
        leg = np.argmin(distance, axis=1) if len(points) else np.zeros(0, int)
        rows = np.arange(len(points))
        return leg, fraction[rows, leg], distance[rows, leg]

    def arc_numbers(self, east_north: np.ndarray) -> np.ndarray:
        """The arc (1-based number) each point lies on; 0 for a point nearest a leg without timed photos."""
        leg, _, _ = self.locate(east_north)
        by_leg = {arc.first_waypoint: arc.number for arc in self.arcs}
        return np.array([by_leg.get(int(k), 0) for k in leg], int)

    def planned_pitch_deg(self, enu_m: np.ndarray) -> np.ndarray:
        """The gimbal pitch (degrees, 0 horizon, -90 nadir) the mission plans at camera positions (N,3 ENU m):
        aimed at the leg's POI in gimbal mode Focus POI, interpolated between the leg's ends in Interpolate mode,
        NaN where the gimbal is not under the mission's control (mode Disabled)."""
        enu_m = np.asarray(enu_m, float).reshape(-1, 3)
        leg, fraction, _ = self.locate(enu_m[:, :2])
        pitch = np.full(len(enu_m), math.nan)
        for i, (k, f) in enumerate(zip(leg, fraction)):
            start, end = self.mission.waypoints[k], self.mission.waypoints[k + 1]
            if start.gimbal_mode == litchi.GIMBAL_FOCUS_POI and start.has_poi:
                pitch[i] = self.pitch_towards_poi(enu_m[i], start)
            elif start.gimbal_mode == litchi.GIMBAL_INTERPOLATE:
                pitch[i] = (1.0 - f) * start.gimbal_pitch_deg + f * end.gimbal_pitch_deg
        return pitch

    def pitch_towards_poi(self, camera_enu_m: np.ndarray, waypoint: litchi.Waypoint) -> float:
        """Pitch (degrees) from a camera position to ``waypoint``'s POI (its height above take-off)."""
        poi = self.frame.enu_points(waypoint.poi_latitude_deg, waypoint.poi_longitude_deg,
                                    self.frame.h0_m + waypoint.poi_altitude_m).reshape(3)
        d = poi - camera_enu_m
        return math.degrees(math.atan2(d[2], math.hypot(d[0], d[1])))


def planned_photos(length_m: float, waypoint: litchi.Waypoint) -> float:
    """Photos a leg of ``length_m`` plans at its start waypoint's speed and interval (NaN at the cruise speed)."""
    if waypoint.speed_m_s <= 0:
        return math.nan
    return float(length_m / (waypoint.speed_m_s * waypoint.photo_time_interval_s))
