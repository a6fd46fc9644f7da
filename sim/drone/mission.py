"""The mission as the virtual drone sees it: Litchi-style waypoints and the home point.

Field names follow the Litchi Mission Hub CSV columns (``altitude(m)`` -> ``altitude_m`` ...), so a parsed
Litchi row maps onto :class:`Waypoint` one field per column. Heights are metres above the take-off point
(Litchi ``altitudemode`` / ``poi_altitudemode`` 0); angles are degrees, headings clockwise from north.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flightplan.geodesy import validate_latlon

#: Litchi ``gimbalmode`` values.
GIMBAL_DISABLED = 0
GIMBAL_FOCUS_POI = 1
GIMBAL_INTERPOLATE = 2


@dataclass(frozen=True)
class Waypoint:
    """One Litchi waypoint; ``speed_mps``, ``photo_timeinterval_s`` apply to the leg that starts here.

    ``speed_mps`` 0 means "the mission's cruising speed"; ``photo_timeinterval_s`` <= 0 (Litchi writes -1)
    means no timed photos on this leg; ``poi_latitude_deg``/``poi_longitude_deg`` both 0 means no POI.
    """

    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    heading_deg: float = 0.0
    curvesize_m: float = 0.0
    gimbalmode: int = GIMBAL_DISABLED
    gimbalpitchangle_deg: float = 0.0
    speed_mps: float = 0.0
    poi_latitude_deg: float = 0.0
    poi_longitude_deg: float = 0.0
    poi_altitude_m: float = 0.0
    photo_timeinterval_s: float = -1.0

    def __post_init__(self) -> None:
        validate_latlon(self.latitude_deg, self.longitude_deg)
        numbers = {
            "altitude_m": self.altitude_m,
            "heading_deg": self.heading_deg,
            "curvesize_m": self.curvesize_m,
            "gimbalpitchangle_deg": self.gimbalpitchangle_deg,
            "speed_mps": self.speed_mps,
            "poi_altitude_m": self.poi_altitude_m,
            "photo_timeinterval_s": self.photo_timeinterval_s,
        }
        for name, value in numbers.items():
            if not math.isfinite(value):
                raise ValueError(f"waypoint {name} must be finite, got {value}")
        if self.curvesize_m < 0:
            raise ValueError(f"waypoint curvesize_m must be >= 0, got {self.curvesize_m}")
        if not 0 <= self.speed_mps <= 15:
            raise ValueError(f"waypoint speed_mps must be within [0, 15] m/s (0 = cruising), got {self.speed_mps}")
        if self.gimbalmode not in (GIMBAL_DISABLED, GIMBAL_FOCUS_POI, GIMBAL_INTERPOLATE):
            raise ValueError(f"waypoint gimbalmode must be 0, 1 or 2, got {self.gimbalmode}")

    @property
    def has_poi(self) -> bool:
        """True when a POI is linked (Litchi writes 0,0 for none)."""
        return not (self.poi_latitude_deg == 0.0 and self.poi_longitude_deg == 0.0)


@dataclass(frozen=True)
class HomePoint:
    """The take-off point: WGS84 degrees and height above the ellipsoid (the ENU origin of the flight)."""

    latitude_deg: float
    longitude_deg: float
    height_ellipsoid_m: float

    def __post_init__(self) -> None:
        validate_latlon(self.latitude_deg, self.longitude_deg)
        if not math.isfinite(self.height_ellipsoid_m):
            raise ValueError(f"home height must be finite, got {self.height_ellipsoid_m}")


def waypoints_from_litchi(mission) -> list[Waypoint]:
    """The rows of a :class:`flightplan.litchi.Mission` (as read from a Litchi CSV) as virtual-drone waypoints.

    Raises ValueError naming the waypoint (1-based) for what the virtual drone does not fly: heights above
    ground (altitude mode 1) instead of above take-off.
    """
    waypoints = []
    for number, row in enumerate(mission.waypoints, start=1):
        if row.altitude_mode != 0 or (row.has_poi and row.poi_altitude_mode != 0):
            raise ValueError(f"waypoint {number}: only heights above take-off (altitudemode 0) are flown")
        try:
            waypoints.append(Waypoint(
                latitude_deg=row.latitude_deg, longitude_deg=row.longitude_deg, altitude_m=row.altitude_m,
                heading_deg=row.heading_deg, curvesize_m=row.curve_size_m, gimbalmode=row.gimbal_mode,
                gimbalpitchangle_deg=row.gimbal_pitch_deg, speed_mps=row.speed_m_s,
                poi_latitude_deg=row.poi_latitude_deg, poi_longitude_deg=row.poi_longitude_deg,
                poi_altitude_m=row.poi_altitude_m, photo_timeinterval_s=row.photo_time_interval_s))
        except ValueError as error:
            raise ValueError(f"waypoint {number}: {error}") from None
    return waypoints


def home_below_first_waypoint(waypoints: list[Waypoint], ground_height_ellipsoid_m: float) -> HomePoint:
    """The take-off point under the first waypoint, on the ground at ``ground_height_ellipsoid_m``."""
    first = waypoints[0]
    return HomePoint(first.latitude_deg, first.longitude_deg, ground_height_ellipsoid_m)
