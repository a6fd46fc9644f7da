"""Plan circular orbits around a point of interest and predict what flying them yields.

Frames and units: centre and waypoints are WGS84 degrees; every height here is metres **above the take-off
point** (Litchi altitude mode 0); the POI height likewise (0 = the ground at take-off). Bearings and headings
are degrees clockwise from north in [0, 360).

A ring of ``N`` waypoints is placed on the ellipsoid with GeographicLib's direct problem at equal bearing steps
of ``360 / N`` from the centre, starting at ``start_bearing_deg``; the first waypoint is repeated at the end to
close the loop. Each waypoint's heading is the bearing back to the centre, the gimbal is in Focus POI mode with
the pitch towards the POI written too (or Interpolate with a fixed pitch when the ring asks for one), and the
speed and photo interval are written on every row. Heading and pitch are whole degrees, as Litchi Mission Hub
writes them (:func:`flightplan.litchi.hub_degrees`), and the predictions (the heading error along the legs, the
ring's pitch) are made from those rounded values: what the aircraft is told, not what was computed.

``N`` is by default the fewest waypoints whose flown path (see :mod:`flightplan.flown_path`: the path is inside
the circle by at most the sagitta ``R (1 - cos(pi / N))``) keeps within ``deviation_tolerance_m``. Litchi's
limits cap it: at most 99 rows in all, and legs long enough for the curve rule (two minimum curves plus 1 m,
i.e. 1.42 m with our margin). When the tolerance cannot be met inside those limits (a tiny or a huge circle)
the planner uses the nearest feasible ``N`` and records a note; when no ``N >= 3`` is feasible (radius below
~0.82 m) it raises ``ValueError``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from flightplan import flown_path, litchi
from flightplan.aircraft import DJI_MINI_SE, AircraftProfile, CameraProfile
from flightplan.geodesy import LocalFrame, geodesic_direct, validate_latlon

DEFAULT_RADIUS_M = 50.0
DEFAULT_HEIGHT_M = 30.0
DEFAULT_SPEED_M_S = 2.5 / 3.6
DEFAULT_PHOTO_INTERVAL_S = 1.0
DEFAULT_DEVIATION_TOLERANCE_M = 0.25
MIN_WAYPOINTS_PER_RING = 3
# Small margin that keeps written curve sizes strictly inside the curve rule after rounding.
_CURVE_MARGIN_M = 0.01
POI_NUDGE_DEG = 1e-8
#: Shortest leg for which every curve size we write satisfies the curve rule (see module docstring).
MIN_PLANNED_LEG_M = 2.0 * (litchi.MIN_CURVE_M + _CURVE_MARGIN_M) + litchi.CURVE_CLEARANCE_M


@dataclass(frozen=True)
class Ring:
    """One circle: radius (m, horizontal, on the ellipsoid), height above take-off (m), optional fixed pitch.

    ``gimbal_pitch_deg=None`` points the gimbal at the POI (Focus POI); a number fixes the pitch (Interpolate).
    """

    radius_m: float = DEFAULT_RADIUS_M
    height_m: float = DEFAULT_HEIGHT_M
    gimbal_pitch_deg: float | None = None


@dataclass(frozen=True)
class OrbitRequest:
    """Everything the planner needs; invalid values raise ``ValueError`` naming the field."""

    center_lat_deg: float
    center_lon_deg: float
    rings: tuple[Ring, ...] = (Ring(),)
    speed_m_s: float = DEFAULT_SPEED_M_S
    photo_interval_s: float = DEFAULT_PHOTO_INTERVAL_S
    direction: str = "cw"
    start_bearing_deg: float = 0.0
    poi_height_m: float = 0.0
    waypoints_per_ring: int | None = None
    deviation_tolerance_m: float = DEFAULT_DEVIATION_TOLERANCE_M

    def __post_init__(self) -> None:
        validate_latlon(self.center_lat_deg, self.center_lon_deg)
        if not self.rings:
            raise ValueError("at least one ring is needed")
        for ring in self.rings:
            _require(ring.radius_m > 0.0, "radius must be a positive number of metres", ring.radius_m)
            if problem := oversized_radius(ring.radius_m, len(self.rings)):
                raise ValueError(f"radius {ring.radius_m:g} m: {problem}")
            _require(math.isfinite(ring.height_m), "height must be a finite number of metres", ring.height_m)
            if ring.gimbal_pitch_deg is not None:
                _require(math.isfinite(ring.gimbal_pitch_deg), "gimbal pitch must be finite", ring.gimbal_pitch_deg)
        _require(self.speed_m_s > 0.0, "speed must be positive", self.speed_m_s)
        _require(self.photo_interval_s > 0.0, "photo interval must be a positive number of seconds", self.photo_interval_s)
        _require(self.direction in ("cw", "ccw"), "direction must be 'cw' or 'ccw'", self.direction)
        _require(math.isfinite(self.start_bearing_deg), "start bearing must be finite", self.start_bearing_deg)
        _require(math.isfinite(self.poi_height_m), "POI height must be finite", self.poi_height_m)
        _require(self.deviation_tolerance_m > 0.0, "deviation tolerance must be positive", self.deviation_tolerance_m)
        if self.waypoints_per_ring is not None:
            most = max_waypoints_per_ring(len(self.rings))
            _require(
                MIN_WAYPOINTS_PER_RING <= self.waypoints_per_ring <= most,
                f"waypoints per ring must be {MIN_WAYPOINTS_PER_RING}..{most} (Litchi holds at most "
                f"{litchi.MAX_WAYPOINTS} waypoints per mission, each ring adds one to close its loop)",
                self.waypoints_per_ring,
            )


def max_waypoints_per_ring(ring_count: int) -> int:
    """Most waypoints a ring may have when ``ring_count`` closed rings share one Litchi mission."""
    return litchi.MAX_WAYPOINTS // ring_count - 1


def largest_radius_m(ring_count: int = 1) -> float:
    """The largest ring radius (m) a Litchi mission of ``ring_count`` rings can fly: a ring closes with at most
    :func:`max_waypoints_per_ring` legs (at least :data:`MIN_WAYPOINTS_PER_RING`) of at most ``litchi.MAX_LEG_M``
    each, and its circle (2 pi r, which the ring's legs approach) fits the mission's
    ``litchi.MAX_MISSION_DISTANCE_M``."""
    legs = max(MIN_WAYPOINTS_PER_RING, max_waypoints_per_ring(ring_count))
    return min(litchi.MAX_LEG_M / (2.0 * math.sin(math.pi / legs)), litchi.MAX_MISSION_DISTANCE_M / (2.0 * math.pi))


def oversized_radius(radius_m: float, ring_count: int = 1) -> str | None:
    """Why no Litchi mission of ``ring_count`` rings flies a ring of ``radius_m`` metres (:func:`largest_radius_m`),
    or ``None`` when one may."""
    largest = largest_radius_m(ring_count)
    if radius_m <= largest:
        return None
    legs = max(MIN_WAYPOINTS_PER_RING, max_waypoints_per_ring(ring_count))
    return (f"expected at most {largest:.0f} m: no Litchi mission flies a larger orbit "
            f"({litchi.MAX_MISSION_DISTANCE_M / 1000:g} km in all, a ring of at most {legs} legs of at most "
            f"{litchi.MAX_LEG_M:g} m)")


def _require(condition: bool, message: str, value) -> None:
    """Raise ``ValueError(message, value)``; NaN fails every comparison and infinities are rejected here too."""
    if not condition or (isinstance(value, float) and not math.isfinite(value)):
        raise ValueError(f"{message}, got {value}")


@dataclass(frozen=True)
class RingPrediction:
    """What one ring yields. Lengths m, angles deg, GSD cm/pixel at the POI, overlap as a fraction 0..1."""

    radius_m: float
    height_m: float
    waypoints: int
    leg_m: float
    curve_size_m: float
    gimbal_pitch_deg: float
    path_length_m: float
    max_deviation_m: float
    max_heading_error_deg: float
    gsd_at_center_cm_px: float
    overlap_consecutive: float


@dataclass(frozen=True)
class OrbitPlan:
    """The mission (rows of the Litchi CSV) and the predictions for flying it at the requested speed."""

    request: OrbitRequest
    mission: litchi.Mission
    rings: tuple[RingPrediction, ...]
    path_length_m: float
    flight_time_s: float
    photo_count: int
    max_deviation_m: float
    notes: tuple[str, ...] = field(default_factory=tuple)

    def summary_dict(self) -> dict:
        """JSON-ready parameters and predictions (``mission.json``'s content without checks)."""
        request = asdict(self.request)
        request["speed_kmh"] = self.request.speed_m_s * 3.6
        return {
            "parameters": request,
            "heights": "metres above take-off (Litchi altitude mode 0)",
            "waypoints": len(self.mission),
            "path_length_m": self.path_length_m,
            "flight_time_s": self.flight_time_s,
            "photo_count": self.photo_count,
            "max_deviation_m": self.max_deviation_m,
            "rings": [asdict(r) for r in self.rings],
            "notes": list(self.notes),
        }


def sagitta_m(radius_m: float, waypoints: int) -> float:
    """How far the middle of a chord between neighbouring waypoints lies inside the circle (metres)."""
    return radius_m * (1.0 - math.cos(math.pi / waypoints))


def chord_m(radius_m: float, waypoints: int) -> float:
    """Straight distance between neighbouring waypoints on a circle of ``waypoints`` equal steps (metres)."""
    return radius_m * (2.0 * math.sin(math.pi / waypoints))  # 2 R would overflow for R above 9e307 m


def feasible_waypoint_range(radius_m: float, max_waypoints: int) -> tuple[int, int]:
    """``(fewest, most)`` waypoints per ring whose legs stay within Litchi's leg and curve rules."""
    fewest = max(MIN_WAYPOINTS_PER_RING, fewest_waypoints_for_leg(radius_m, litchi.MAX_LEG_M))
    if fewest > max_waypoints:  # a circle this large cannot keep its legs short enough
        return fewest, fewest - 1
    most = fewest - 1
    while most < max_waypoints and chord_m(radius_m, most + 1) >= MIN_PLANNED_LEG_M:
        most += 1
    return fewest, most


def fewest_waypoints_for_leg(radius_m: float, max_leg_m: float) -> int:
    """The fewest equal steps around a circle of ``radius_m`` whose chords are at most ``max_leg_m`` (metres).

    Closed form (``chord = 2 R sin(pi / N)``), so a huge radius costs no time; at least 1. ``ValueError`` for a
    radius or leg that is not a positive finite number, or a count beyond any float (``1e308`` m with legs of 1e-10 m).
    """
    if not (0.0 < radius_m < math.inf and 0.0 < max_leg_m < math.inf):
        raise ValueError(f"radius and leg must be positive finite numbers of metres, got {radius_m}, {max_leg_m}")
    if radius_m <= max_leg_m / 2.0:
        return 1
    try:  # max_leg / R / 2, not max_leg / (2 R): 2 R overflows to inf from R = 9e307 m
        count = math.ceil(math.pi / math.asin(max_leg_m / radius_m / 2.0))
    except (ZeroDivisionError, OverflowError):
        raise ValueError(f"a circle of radius {radius_m:g} m needs more than 1e308 legs of {max_leg_m:g} m") from None
    return count + (chord_m(radius_m, count) > max_leg_m)  # one more where rounding left the chord a hair long


def choose_waypoint_count(radius_m: float, tolerance_m: float, max_waypoints: int) -> int:
    """The fewest feasible waypoints whose sagitta is within ``tolerance_m``, else the most feasible.

    Raises ``ValueError`` when no count is feasible (a circle too small for the leg rules or too large).
    """
    fewest, most = feasible_waypoint_range(radius_m, max_waypoints)
    if most < fewest:
        raise ValueError(
            f"no feasible waypoint count for radius {radius_m:g} m: legs must be {MIN_PLANNED_LEG_M:.2f}-"
            f"{litchi.MAX_LEG_M:.0f} m and a ring holds at most {max_waypoints} waypoints"
        )
    within_tolerance = (count for count in range(fewest, most + 1) if sagitta_m(radius_m, count) <= tolerance_m)
    return next(within_tolerance, most)


def gsd_at_center_m(camera: CameraProfile, radius_m: float, height_above_poi_m: float) -> float:
    """Ground sampling distance (m per pixel) at the POI, across the line of sight, for a camera aimed at it."""
    return math.hypot(radius_m, height_above_poi_m) / camera.focal_length_px()


def consecutive_overlap(camera: CameraProfile, radius_m: float, height_above_poi_m: float, step_m: float) -> float:
    """Fraction of the image width shared by two consecutive photos taken ``step_m`` apart on the orbit.

    Model: between shots the camera moves ``step_m`` sideways and yaws so the POI (at slant range ``D``) stays
    centred. A point at range ``d`` on the image's centre column then shifts by ``step_m * |1/d - 1/D|``
    radians; the background (``d`` infinite) by ``step_m / D``; the nearest ground point in view (flat ground
    at the POI height, bottom image edge) by the most when it is closer than ``D / 2``. The overlap is
    ``1 - worst shift / horizontal FOV``, clipped at 0.
    """
    slant = math.hypot(radius_m, height_above_poi_m)
    worst_shift = step_m / slant
    if height_above_poi_m > 0.0:
        depression = math.atan2(height_above_poi_m, radius_m)
        bottom_ray = min(math.pi / 2.0, depression + math.radians(camera.vertical_fov_deg) / 2.0)
        nearest_ground = height_above_poi_m / math.sin(bottom_ray)
        worst_shift = max(worst_shift, step_m * (1.0 / nearest_ground - 1.0 / slant))
    return max(0.0, 1.0 - worst_shift / math.radians(camera.horizontal_fov_deg))


def poi_coordinates(lat_deg: float, lon_deg: float) -> tuple[float, float]:
    """POI latitude/longitude to write: longitude wrapped into [-180, 180); Litchi reads ``0,0`` as "no POI", so a
    centre written as 0,0 (:func:`flightplan.litchi.written_value`: within 1e-10 deg of it) moves 1e-8 deg north.

    1e-8 deg of latitude is 1.1 mm, far below GPS accuracy; the headings still point at the true centre.
    """
    if lon_deg >= 180.0:  # validate_latlon allows up to 360; subtracting keeps in-range values bit-exact
        lon_deg -= 360.0
    if litchi.written_value(lat_deg) == 0.0 and litchi.written_value(lon_deg) == 0.0:
        return POI_NUDGE_DEG, 0.0
    return lat_deg, lon_deg


def _ring_waypoints(request: OrbitRequest, ring: Ring, count: int) -> tuple[list[litchi.Waypoint], float]:
    """The closed ring's ``count + 1`` rows, and the curve size used on its interior rows."""
    sign = 1.0 if request.direction == "cw" else -1.0
    focus_poi = ring.gimbal_pitch_deg is None
    pitch = litchi.hub_degrees(
        -math.degrees(math.atan2(ring.height_m - request.poi_height_m, ring.radius_m))
        if focus_poi
        else ring.gimbal_pitch_deg
    )
    longest_allowed = (chord_m(ring.radius_m, count) - litchi.CURVE_CLEARANCE_M) / 2.0 - _CURVE_MARGIN_M
    curve = min(litchi.MAX_CURVE_M, max(litchi.MIN_CURVE_M, longest_allowed))
    poi_lat, poi_lon = poi_coordinates(request.center_lat_deg, request.center_lon_deg)
    rows = []
    for k in range(count):
        point = geodesic_direct(
            request.center_lat_deg, request.center_lon_deg,
            request.start_bearing_deg % 360.0 + sign * 360.0 * k / count,  # a huge bearing would swallow the steps
            ring.radius_m,
        )
        rows.append(
            litchi.Waypoint(
                latitude_deg=point.lat_deg,
                longitude_deg=point.lon_deg,
                altitude_m=ring.height_m,
                # the geodesic continued back to the centre, in whole degrees (360 is north again: 0)
                heading_deg=litchi.hub_degrees((point.azimuth_deg + 180.0) % 360.0) % 360.0,
                curve_size_m=curve if k > 0 else litchi.MIN_CURVE_M,
                rotation_dir=litchi.ROTATION_CW if sign > 0 else litchi.ROTATION_CCW,
                gimbal_mode=litchi.GIMBAL_FOCUS_POI if focus_poi else litchi.GIMBAL_INTERPOLATE,
                gimbal_pitch_deg=pitch,
                speed_m_s=request.speed_m_s,
                poi_latitude_deg=poi_lat,
                poi_longitude_deg=poi_lon,
                poi_altitude_m=request.poi_height_m,
                photo_time_interval_s=request.photo_interval_s,
            )
        )
    rows.append(rows[0])  # close the loop: fly back to the first waypoint
    return rows, curve


def _predict_ring(
    request: OrbitRequest, ring: Ring, rows: list[litchi.Waypoint], curve: float, camera: CameraProfile
) -> RingPrediction:
    frame = LocalFrame(request.center_lat_deg, request.center_lon_deg, 0.0)
    lat = np.array([w.latitude_deg for w in rows])
    lon = np.array([w.longitude_deg for w in rows])
    east, north, _ = frame.to_enu(lat, lon, np.zeros_like(lat))
    vertices = np.stack([east, north], axis=-1)
    curves = np.array([w.curve_size_m for w in rows])
    path = flown_path.curved_turns_path(vertices, curves)
    height_above_poi = ring.height_m - request.poi_height_m
    count = len(rows) - 1
    return RingPrediction(
        radius_m=ring.radius_m,
        height_m=ring.height_m,
        waypoints=count,
        leg_m=chord_m(ring.radius_m, count),
        curve_size_m=curve,
        gimbal_pitch_deg=rows[0].gimbal_pitch_deg,
        path_length_m=flown_path.path_length_m(path),
        max_deviation_m=flown_path.max_radial_deviation_m(path, ring.radius_m),
        max_heading_error_deg=flown_path.heading_error_along_legs_deg(vertices, np.array([w.heading_deg for w in rows])),
        gsd_at_center_cm_px=100.0 * gsd_at_center_m(camera, ring.radius_m, height_above_poi),
        overlap_consecutive=consecutive_overlap(
            camera, ring.radius_m, height_above_poi, request.speed_m_s * request.photo_interval_s
        ),
    )


def _transition_length_m(previous: RingPrediction, following: RingPrediction) -> float:
    """Straight 3-D leg from one ring's start/end waypoint to the next ring's first (same bearing)."""
    return math.hypot(following.radius_m - previous.radius_m, following.height_m - previous.height_m)


def plan_orbit(request: OrbitRequest, aircraft: AircraftProfile = DJI_MINI_SE) -> OrbitPlan:
    """Plan ``request`` (see the module docstring) and predict path length, time, photos, GSD and overlap."""
    max_per_ring = max_waypoints_per_ring(len(request.rings))
    rows: list[litchi.Waypoint] = []
    predictions: list[RingPrediction] = []
    notes: list[str] = []
    for ring in request.rings:
        count = request.waypoints_per_ring or choose_waypoint_count(
            ring.radius_m, request.deviation_tolerance_m, max_per_ring
        )
        ring_rows, curve = _ring_waypoints(request, ring, count)
        prediction = _predict_ring(request, ring, ring_rows, curve, aircraft.camera)
        if request.waypoints_per_ring is None and prediction.max_deviation_m > request.deviation_tolerance_m:
            notes.append(
                f"ring r={ring.radius_m:g} m: deviation tolerance {request.deviation_tolerance_m:g} m is out of reach "
                f"within Litchi's limits; {count} waypoints give {prediction.max_deviation_m:.3f} m"
            )
        rows += ring_rows
        predictions.append(prediction)
    length = sum(p.path_length_m for p in predictions)
    length += sum(_transition_length_m(a, b) for a, b in zip(predictions, predictions[1:]))
    flight_time = length / request.speed_m_s
    return OrbitPlan(
        request=request,
        mission=litchi.Mission(tuple(rows)),
        rings=tuple(predictions),
        path_length_m=length,
        flight_time_s=flight_time,
        photo_count=int(flight_time // request.photo_interval_s) + 1,
        max_deviation_m=max(p.max_deviation_m for p in predictions),
        notes=tuple(notes),
    )
