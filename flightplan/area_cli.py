"""``aerostereo-mission --area FIELD --out DIR``: read the field, plan, check every flight, write, print the tables.

Refused (one line, exit 2, nothing written): options of a single orbit (a centre, rings, per-file previews),
an ``--out`` that is a file or a folder already holding a plan, a field that is not a readable simple polygon,
a plan over :data:`flightplan.area.MAX_ORBITS` orbits, an orbit that does not fit one battery, and any flight
that fails a check of a single mission (:func:`flightplan.checks.check_mission`).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

from flightplan import checks
from flightplan.aircraft import DJI_MINI_SE
from flightplan.area import AreaRequest, orbit_at, plan_area
from flightplan.area_outputs import OVERVIEW_NAMES, SUMMARY_NAME, summary_text, write_area_plan
from cliutil.errors import BadInput
from cliutil.paths import refuse_clobbering
from flightplan.field import read_field
from flightplan.geodesy import validate_latlon
from flightplan.orbit import DEFAULT_HEIGHT_M, DEFAULT_RADIUS_M

#: Single-orbit options that make no sense with --area (the centres come from the field, the previews go in --out).
_SINGLE_ORBIT_ONLY = ("lat", "lon", "demo", "rings", "waypoints", "start_bearing", "kml", "geojson", "plot", "summary_json")


def refuse_single_orbit_options(args: argparse.Namespace) -> None:
    """:class:`BadInput` naming the first single-orbit option given together with ``--area``."""
    for name in _SINGLE_ORBIT_ONLY:
        if getattr(args, name) not in (None, False, 0.0):
            raise BadInput(f"--{name.replace('_', '-')} is for a single orbit; --area places the orbits and writes "
                           f"the overview into --out")


#: A flight CSV's name as :func:`flightplan.area_outputs.flight_csv_name` writes it.
_FLIGHT_CSV = re.compile(r"flight_\d{2,}\.csv")
#: Most plan files a refusal names one by one.
_NAMED_FILES = 8


def is_plan_file(name: str) -> bool:
    """Whether a file called ``name`` is one that a plan writes into its folder."""
    return name in OVERVIEW_NAMES or _FLIGHT_CSV.fullmatch(name) is not None


def refuse_output_folder(folder: Path, field_path: Path) -> None:
    """:class:`BadInput` if ``folder`` is a file or already holds a plan, or part of one (its flights would mix
    with stale ones), or holds the field ``field_path`` under a name the plan writes. A run of this version leaves
    none half-written (:func:`write_area_plan`). The refusal of a half plan names the exact files to delete, which
    never include the field."""
    if folder.exists() and not folder.is_dir():
        raise BadInput(f"--out {folder}: is a file; with --area, --out is the folder for the flights and overview")
    if not folder.is_dir():
        return
    if field_path.parent.resolve() == folder.resolve() and is_plan_file(field_path.name):
        raise BadInput(f"--area {field_path}: lies in --out {folder} under a name the plan writes; move the field "
                       "elsewhere or choose another --out")
    taken = sorted(p.name for p in folder.iterdir() if is_plan_file(p.name))
    if SUMMARY_NAME in taken:
        raise BadInput(f"--out {folder}: already holds a plan ({SUMMARY_NAME}); choose an empty folder")
    if taken:
        more = f" and {len(taken) - _NAMED_FILES} more flight_NN.csv" if len(taken) > _NAMED_FILES else ""
        raise BadInput(f"--out {folder}: holds part of a plan (no {SUMMARY_NAME}: an interrupted run); delete "
                       f"{' '.join(taken[:_NAMED_FILES])}{more} there, or choose an empty folder")


def request_from_args(args: argparse.Namespace, field) -> AreaRequest:
    """The :class:`AreaRequest` of the parsed arguments (take-off in the field's ENU plane)."""
    home = (0.0, 0.0)
    if args.home is not None:
        try:
            validate_latlon(*args.home)
        except ValueError as error:
            raise BadInput(f"--home: {error}") from None
        east, north, _ = field.frame.to_enu(args.home[0], args.home[1], 0.0)
        home = (float(east), float(north))
    orbit = {"speed_m_s": args.speed_kmh / 3.6, "photo_interval_s": args.interval, "direction": args.direction,
             "poi_height_m": args.poi_height, "deviation_tolerance_m": args.tolerance}
    return AreaRequest(
        radius_m=DEFAULT_RADIUS_M if args.radius is None else args.radius,
        height_m=DEFAULT_HEIGHT_M if args.height is None else args.height,
        overlap=args.overlap, transit_speed_m_s=args.transit_speed_kmh / 3.6, orbit=orbit, home_enu_m=home,
    )


def run_area(args: argparse.Namespace) -> int:
    """Plan the field of ``args.area``, check and write every flight; tables on stdout, warnings on stderr."""
    refuse_single_orbit_options(args)
    refuse_clobbering({"--area": args.area}, {"--out": args.out})
    refuse_output_folder(args.out, args.area)
    field = read_field(args.area)
    request = request_from_args(args, field)
    orbit = orbit_at(field, np.zeros(2), request, DJI_MINI_SE)  # an orbit failing the checks fails every flight
    checks.raise_on_errors(checks.check_mission(orbit.mission, DJI_MINI_SE, None, args.legal_height))
    plan = plan_area(field, request, DJI_MINI_SE)
    warnings = check_flights(plan, args.legal_height)
    written = write_area_plan(plan, args.out, warnings)
    print(summary_text(plan))
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"wrote {len(written)} files into {args.out}: {len(plan.flights)} flight CSVs, " + ", ".join(OVERVIEW_NAMES))
    return 0


def check_flights(plan, legal_height_m: float) -> list[str]:
    """Every check of a single mission on every flight: :class:`BadInput` naming the first flight with an error;
    else the warnings, each once with the flights it concerns."""
    flights_of: dict[str, list[int]] = {}
    for number, flight in enumerate(plan.flights, start=1):
        findings = checks.check_mission(flight.mission, DJI_MINI_SE, flight.flight_time_s, legal_height_m)
        try:
            for warning in checks.raise_on_errors(findings):
                flights_of.setdefault(warning, []).append(number)
        except checks.MissionCheckError as error:
            raise BadInput(f"flight {number}: {error}") from None
    every = list(range(1, len(plan.flights) + 1))
    return [f"{'every flight' if numbers == every else 'flight(s) ' + ', '.join(map(str, numbers))}: {warning}"
            for warning, numbers in flights_of.items()]
