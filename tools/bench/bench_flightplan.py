"""Waypoints per circle against path error, heading error and planning time (prints Markdown tables).

For the default orbit (50 m radius, 30 m above take-off, around the demo location) and each N: the largest
deviation of the modelled flown path from the true circle (m), the largest heading error between waypoints
(Litchi interpolates the heading linearly, deg), the time to plan (best of ``--repeats``, ms: geodesic placement,
flown-path model and predictions) and that time as a ratio of the planner's own choice for the default 0.25 m
tolerance (the baseline, measured in the same run). A second table gives the chosen N for other radii.

Run: ``python tools/bench/bench_flightplan.py [--repeats 5]``
"""

from __future__ import annotations

import argparse
import time

from flightplan.demo_location import DEMO_ORIGIN
from flightplan.orbit import DEFAULT_DEVIATION_TOLERANCE_M, OrbitRequest, Ring, plan_orbit

COUNTS = (8, 12, 16, 24, 32, 36, 48, 72, 98)
RADII_M = (2.0, 10.0, 50.0, 200.0, 1000.0, 4000.0)


def timed_plan(request: OrbitRequest, repeats: int):
    """The plan and the best wall-clock time of ``repeats`` runs (seconds)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        plan = plan_orbit(request)
        best = min(best, time.perf_counter() - start)
    return plan, best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    centre = (DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg)
    baseline_plan, baseline_s = timed_plan(OrbitRequest(*centre), args.repeats)
    chosen = baseline_plan.rings[0].waypoints
    print(f"Default orbit r=50 m, h=30 m; planner's choice for {DEFAULT_DEVIATION_TOLERANCE_M} m tolerance: N = {chosen}\n")
    print("| N per circle | leg (m) | max deviation (m) | max heading error (deg) | plan time (ms) | time / chosen N |")
    print("|---:|---:|---:|---:|---:|---:|")
    for count in sorted(set(COUNTS) | {chosen}):
        plan, seconds = timed_plan(OrbitRequest(*centre, waypoints_per_ring=count), args.repeats)
        ring = plan.rings[0]
        mark = " (chosen)" if count == chosen else ""
        print(
            f"| {count}{mark} | {ring.leg_m:.2f} | {ring.max_deviation_m:.3f} | {ring.max_heading_error_deg:.4f} | "
            f"{1000 * seconds:.2f} | {seconds / baseline_s:.2f} |"
        )
    print("\nChosen N for other radii (same tolerance, Litchi limits):\n")
    print("| radius (m) | chosen N | leg (m) | max deviation (m) | note |")
    print("|---:|---:|---:|---:|---|")
    for radius in RADII_M:
        plan = plan_orbit(OrbitRequest(*centre, rings=(Ring(radius, 30.0),)))
        ring = plan.rings[0]
        note = "tolerance out of reach" if plan.notes else ""
        print(f"| {radius:g} | {ring.waypoints} | {ring.leg_m:.2f} | {ring.max_deviation_m:.3f} | {note} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
