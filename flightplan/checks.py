"""Check a mission against Litchi's limits, an aircraft profile and the law.

Errors mean the mission must not be exported (Litchi would reject or misfly it, the aircraft cannot do it, or it
breaks the height limit); warnings are printed and written into the summary. Rows are numbered from 1 as in the
CSV without its header. Limits: see the constants in :mod:`flightplan.litchi` and :mod:`flightplan.aircraft`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flightplan import litchi
from flightplan.aircraft import DJI_MINI_SE, LEGAL_MAX_HEIGHT_M, AircraftProfile
from flightplan.geodesy import geodesic_inverse
from flightplan.orbit import OrbitPlan, OrbitRequest, plan_orbit

ERROR, WARNING = "error", "warning"


@dataclass(frozen=True)
class Finding:
    """One problem: ``severity`` is ``"error"`` or ``"warning"``; ``message`` is one line for a person."""

    severity: str
    message: str


class MissionCheckError(ValueError):
    """Raised when a mission has errors; the message lists them on one line."""

    def __init__(self, findings: list[Finding]):
        self.findings = findings
        super().__init__("mission rejected: " + "; ".join(f.message for f in findings))


def _outside(
    values: np.ndarray, low: float, high: float, severity: str, what: str, only=None, row: str = "row"
) -> list[Finding]:
    """One finding for all rows whose value is outside ``[low, high]``, naming the first of them.

    ``only`` (boolean mask) restricts the check to some rows; ``row`` is how an element is named ("leg from row").
    """
    bad_mask = (values < low) | (values > high)
    bad = np.flatnonzero(bad_mask if only is None else bad_mask & only)
    if bad.size == 0:
        return []
    first = bad[0]
    return [
        Finding(
            severity,
            f"{what} {values[first]:g} on {row} {first + 1} ({bad.size} in all) is outside {low:g}..{high:g}",
        )
    ]


def leg_lengths_m(mission: litchi.Mission) -> np.ndarray:
    """3-D length of each leg (m): geodesic ground distance combined with the altitude change."""
    waypoints = mission.waypoints
    return np.array(
        [
            math.hypot(
                geodesic_inverse(a.latitude_deg, a.longitude_deg, b.latitude_deg, b.longitude_deg).distance_m,
                b.altitude_m - a.altitude_m,
            )
            for a, b in zip(waypoints, waypoints[1:])
        ]
    )


def _curve_findings(mission: litchi.Mission, legs: np.ndarray) -> list[Finding]:
    curves = mission.column("curve_size_m")
    findings = _outside(curves, 0.0, litchi.MAX_CURVE_M, ERROR, "curve size (m)")
    for end, row in (("first", 0), ("last", len(curves) - 1)):
        if curves[row] > litchi.MIN_CURVE_M:
            findings.append(Finding(ERROR, f"the {end} waypoint (row {row + 1}) cannot have a curve, got {curves[row]:g} m"))
    too_big = np.flatnonzero(curves[:-1] + curves[1:] + litchi.CURVE_CLEARANCE_M > legs + 1e-9)
    if too_big.size:
        i = too_big[0]
        findings.append(
            Finding(
                ERROR,
                f"curves {curves[i]:g} m + {curves[i + 1]:g} m on rows {i + 1}-{i + 2} need a leg of at least "
                f"{curves[i] + curves[i + 1] + litchi.CURVE_CLEARANCE_M:g} m, the leg is {legs[i]:.3f} m "
                f"({too_big.size} leg(s))",
            )
        )
    return findings


def _photo_interval_findings(mission: litchi.Mission) -> list[Finding]:
    findings = []
    intervals = (("photo_time_interval_s", "photo time interval (s)"), ("photo_dist_interval_m", "photo distance interval (m)"))
    for column, what in intervals:
        values = mission.column(column)
        enabled = values != litchi.DISABLED_INTERVAL
        findings += _outside(values, litchi.MIN_PHOTO_INTERVAL, litchi.MAX_PHOTO_INTERVAL, ERROR, what, only=enabled)
    both = (mission.column("photo_time_interval_s") > 0) & (mission.column("photo_dist_interval_m") > 0)
    if both.any():
        findings.append(Finding(ERROR, f"row {np.flatnonzero(both)[0] + 1} sets both a time and a distance photo interval"))
    return findings


def check_litchi_limits(mission: litchi.Mission) -> list[Finding]:
    """Waypoint count, leg lengths, total distance, curve rules, speed, altitudes, gimbal pitch, actions, photo intervals."""
    count = len(mission)
    if not 1 <= count <= litchi.MAX_WAYPOINTS:
        return [Finding(ERROR, f"a Litchi mission holds 1..{litchi.MAX_WAYPOINTS} waypoints, this one has {count}")]
    legs = leg_lengths_m(mission)
    findings = _outside(legs, litchi.MIN_LEG_M, litchi.MAX_LEG_M, ERROR, "length (m)", row="the leg from row")
    if legs.sum() > litchi.MAX_MISSION_DISTANCE_M:
        findings.append(
            Finding(
                ERROR,
                f"the mission is {legs.sum() / 1000:.2f} km long; DJI/Litchi missions are limited to "
                f"{litchi.MAX_MISSION_DISTANCE_M / 1000:g} km",
            )
        )
    findings += _curve_findings(mission, legs)
    findings += _outside(mission.column("speed_m_s"), 0.0, litchi.MAX_SPEED_M_S, ERROR, "speed (m/s)")
    if (mission.column("speed_m_s") == 0.0).any():
        findings.append(Finding(WARNING, "a speed of 0 makes Litchi fly at the mission's cruising speed (not in the CSV)"))
    for column, what in (("altitude_m", "altitude (m)"), ("poi_altitude_m", "POI altitude (m)")):
        findings += _outside(mission.column(column), litchi.MIN_ALTITUDE_M, litchi.MAX_ALTITUDE_M, ERROR, what)
    findings += _outside(
        mission.column("gimbal_pitch_deg"), litchi.MIN_GIMBAL_PITCH_DEG, litchi.MAX_GIMBAL_PITCH_DEG, ERROR, "gimbal pitch (deg)"
    )
    findings += _outside(mission.column("heading_deg"), 0.0, 360.0, ERROR, "heading (deg)")
    for prefix in ("", "poi_"):
        findings += _outside(mission.column(f"{prefix}latitude_deg"), -90.0, 90.0, ERROR, f"{prefix}latitude (deg)")
        findings += _outside(mission.column(f"{prefix}longitude_deg"), -180.0, 180.0, ERROR, f"{prefix}longitude (deg)")
    action_counts = np.array([len(w.actions) for w in mission.waypoints], dtype=np.float64)
    findings += _outside(action_counts, 0, litchi.MAX_ACTIONS, ERROR, "number of actions")
    return findings + _photo_interval_findings(mission)


def check_aircraft(mission: litchi.Mission, aircraft: AircraftProfile, flight_time_s: float | None = None) -> list[Finding]:
    """Speed against the aircraft's maximum, photo cadence, gimbal range and (when given) flight time."""
    findings = _outside(mission.column("speed_m_s"), 0.0, aircraft.max_speed_m_s, ERROR, f"{aircraft.name} speed (m/s)")
    intervals = mission.column("photo_time_interval_s")
    too_fast = intervals[(intervals > 0) & (intervals < aircraft.min_timed_shot_interval_s)]
    if too_fast.size:
        findings.append(
            Finding(
                WARNING,
                f"photo interval {too_fast.min():g} s is below the {aircraft.name}'s {aircraft.min_timed_shot_interval_s:g} s "
                "minimum for timed shots (DJI SDK; unverified for Litchi): photos may be skipped",
            )
        )
    low, high = aircraft.gimbal_pitch_range_deg
    findings += _outside(mission.column("gimbal_pitch_deg"), low, high, WARNING, f"{aircraft.name} gimbal pitch (deg)")
    if flight_time_s is not None and flight_time_s > aircraft.usable_flight_time_s:
        batteries = math.ceil(flight_time_s / aircraft.usable_flight_time_s)
        findings.append(
            Finding(
                WARNING,
                f"flight time {flight_time_s / 60:.1f} min exceeds the {aircraft.usable_flight_time_s / 60:.0f} min one "
                f"battery allows (with reserve); plan {batteries} batteries and resume the mission",
            )
        )
    return findings


def check_law(mission: litchi.Mission, legal_max_height_m: float = LEGAL_MAX_HEIGHT_M) -> list[Finding]:
    """Height above take-off against the legal limit (EU open category and US Part 107: 120 m)."""
    heights = mission.column("altitude_m")
    findings = []
    too_high = np.flatnonzero(heights > legal_max_height_m)
    if too_high.size:
        findings.append(
            Finding(
                ERROR,
                f"height {heights[too_high[0]]:g} m above take-off on row {too_high[0] + 1} exceeds the legal "
                f"{legal_max_height_m:g} m (EU open category, US Part 107)",
            )
        )
    low = np.flatnonzero(heights < 5.0)
    if low.size:
        findings.append(Finding(WARNING, f"row {low[0] + 1} flies less than 5 m above take-off: check for obstacles"))
    return findings


def check_mission(
    mission: litchi.Mission,
    aircraft: AircraftProfile = DJI_MINI_SE,
    flight_time_s: float | None = None,
    legal_max_height_m: float = LEGAL_MAX_HEIGHT_M,
) -> list[Finding]:
    """All checks; errors first."""
    findings = check_litchi_limits(mission) + check_aircraft(mission, aircraft, flight_time_s)
    findings += check_law(mission, legal_max_height_m)
    return sorted(findings, key=lambda f: f.severity != ERROR)


def raise_on_errors(findings: list[Finding]) -> list[str]:
    """Raise :class:`MissionCheckError` if any finding is an error; otherwise return the warning messages."""
    errors = [f for f in findings if f.severity == ERROR]
    if errors:
        raise MissionCheckError(errors)
    return [f.message for f in findings if f.severity == WARNING]


def checked_orbit(request: OrbitRequest, aircraft: AircraftProfile = DJI_MINI_SE,
                  legal_max_height_m: float = LEGAL_MAX_HEIGHT_M) -> tuple[OrbitPlan, list[str]]:
    """Plan the orbit of ``request`` for ``aircraft`` and check it (:func:`check_mission`, the legal height in
    metres above take-off): the plan and its warnings; :class:`MissionCheckError` when a check fails."""
    plan = plan_orbit(request, aircraft)
    findings = check_mission(plan.mission, aircraft, plan.flight_time_s, legal_max_height_m)
    return plan, raise_on_errors(findings)
