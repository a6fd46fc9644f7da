"""Area planning: planning time and transit against the lower bound for fields of 1e4..1e6 m² (Markdown table).

Fields around the demo location: squares and an L-shape (a square missing its north-east quarter) of each area,
take-off at the centroid of the vertices, default orbit (50 m at 30 m, 2.5 km/h, 1 s), overlap 0.2 and 18 km/h
transit. Columns: orbits and flights (= batteries), the planning time (``plan_area``: layout, 2-opt tour, flight
split, coverage estimate and every flight's rows; best of ``--repeats``, s), the transit of the plan, of the same
split applied to the lattice's row-by-row order, and the lower bound (max of the spanning tree and the radial
bound, :func:`flightplan.area.transit_lower_bound_m`), and the field coverage of the well-covered discs.

Run: ``python tools/bench/bench_area.py [--repeats 1]``
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from flightplan.area import AreaRequest, plan_area
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.field import field_from_lonlat

AREAS_M2 = (1e4, 1e5, 153_000.0, 1e6)
SHAPES = {
    "square": np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) / 2.0,
    "L": np.array([[-1, -1], [1, -1], [1, 0], [0, 0], [0, 1], [-1, 1]]) / 2.0,
}


def field_of(shape: np.ndarray, area_m2: float):
    """``shape`` (unit coordinates) scaled to ``area_m2``, placed at the demo location."""
    unit_area = 0.5 * abs(np.dot(shape[:, 0], np.roll(shape[:, 1], 1)) - np.dot(shape[:, 1], np.roll(shape[:, 0], 1)))
    enu = shape * math.sqrt(area_m2 / unit_area)
    lat, lon, _ = DEMO_ORIGIN.to_geodetic(enu[:, 0], enu[:, 1], np.zeros(len(enu)))
    return field_from_lonlat(np.stack([lon, lat], -1), "bench")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args(argv)
    print("| field | area (m²) | orbits | flights | plan time (s) | transit (m) | row-order transit (m) | "
          "lower bound (m) | transit / bound | coverage |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for area in AREAS_M2:
        for name, shape in SHAPES.items():
            field = field_of(shape, area)
            best = float("inf")
            for _ in range(args.repeats):
                start = time.perf_counter()
                plan = plan_area(field, AreaRequest())
                best = min(best, time.perf_counter() - start)
            print(f"| {name} | {field.area_m2:,.0f} | {len(plan.centres_enu_m)} | {len(plan.flights)} | {best:.2f} | "
                  f"{plan.transit_m:,.0f} | {plan.naive_transit_m:,.0f} | {plan.transit_lower_bound_m:,.0f} | "
                  f"{plan.transit_m / plan.transit_lower_bound_m:.2f} | {100 * plan.field_coverage:.1f} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
