"""Shared pieces of the virtual-drone tests: a short orbit mission written as a Litchi CSV."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from flightplan import litchi
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.orbit import OrbitRequest, plan_orbit


def short_orbit_csv(path: Path, waypoints: int = 3, photo_interval_s: float = 1.0) -> Path:
    """The default orbit (50 m radius, 30 m, 2.5 km/h) around the demo origin, cut to its first ``waypoints``
    rows (a short arc, about 13 m per leg), written as a Litchi CSV."""
    plan = plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg, photo_interval_s=photo_interval_s))
    rows = plan.mission.waypoints[:waypoints]
    rows = rows[:-1] + (replace(rows[-1], curve_size_m=litchi.MIN_CURVE_M),)
    litchi.write_mission_csv(litchi.Mission(rows), path)
    return path
