"""The Litchi mission that re-flies only the arcs of a mission that need it.

Each run of consecutive arcs to re-fly is flown as the original flew it: its waypoints copied whole (height, speed,
heading, curves, gimbal, POI, photo interval, actions), the run's first and last waypoints without a curve (a run
starts and ends at a waypoint). Between runs the aircraft transits at :data:`TRANSIT_SPEED_M_S` with no timed
photos, so photos are taken on the arcs to re-fly only. The result must pass the planner's own checks
(:func:`flightplan.checks.check_mission`) before it is written with the planner's writer.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from flightplan import litchi
from flightplan.aircraft import DJI_MINI_SE, AircraftProfile
from flightplan.checks import MissionCheckError, check_mission, raise_on_errors

#: Speed (m/s) of the transit legs between runs of arcs: flightplan's default transit (18 km/h).
TRANSIT_SPEED_M_S = 5.0


def leg_runs(legs: list[int]) -> list[list[int]]:
    """Sorted leg indices grouped into runs of consecutive legs: ``[1, 2, 5] -> [[1, 2], [5]]``."""
    runs: list[list[int]] = []
    for leg in sorted(set(legs)):
        if runs and leg == runs[-1][-1] + 1:
            runs[-1].append(leg)
        else:
            runs.append([leg])
    return runs


def refly_mission(mission: litchi.Mission, legs: list[int]) -> litchi.Mission:
    """The mission flying only ``legs`` of ``mission`` (0-based start waypoints of its legs), module docstring."""
    rows = []
    for run in leg_runs(legs):
        copied = list(mission.waypoints[run[0]:run[-1] + 2])
        copied[0] = replace(copied[0], curve_size_m=litchi.MIN_CURVE_M)
        copied[-1] = replace(copied[-1], curve_size_m=litchi.MIN_CURVE_M, speed_m_s=TRANSIT_SPEED_M_S,
                             photo_time_interval_s=litchi.DISABLED_INTERVAL,
                             photo_dist_interval_m=litchi.DISABLED_INTERVAL)
        rows += copied
    return litchi.Mission(tuple(rows))


def write_refly(mission: litchi.Mission, legs: list[int], path: Path,
                aircraft: AircraftProfile = DJI_MINI_SE) -> list[str]:
    """Write :func:`refly_mission` to ``path`` (atomically) once it passes the planner's checks for ``aircraft``;
    returns the checks' warnings. ``ValueError`` naming the failed checks (nothing written)."""
    refly = refly_mission(mission, legs)
    try:
        warnings = raise_on_errors(check_mission(refly, aircraft))
    except MissionCheckError as error:
        raise ValueError(f"the re-fly mission fails the planner's checks ({error}); the original mission "
                         "probably does too") from None
    litchi.write_mission_csv(refly, path)
    return warnings
