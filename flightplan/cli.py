"""``aerostereo-mission``: plan a circular orbit and export it as a Litchi Mission Hub CSV; with ``--area``, cover
a field with orbits and write one CSV per flight plus an overview (see :mod:`flightplan.area`).

Heights are metres above the take-off point; the centre is WGS84 degrees. Prints a summary (waypoints, path
length, flight time, photos, GSD, overlap, deviation from the circle) on stdout and the plan's warnings on stderr.
Bad input, a plan that fails the checks or an output that names another output: one line on stderr, exit code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from flightplan import checks, litchi, preview
from flightplan.aircraft import DJI_MINI_SE, LEGAL_MAX_HEIGHT_M
from flightplan.area import DEFAULT_OVERLAP, DEFAULT_TRANSIT_SPEED_M_S
from cliutil.argtypes import finite_number, number_within
from cliutil.atomic import atomic_paths, write_text_atomic
from cliutil.errors import BadInput
from cliutil.program import Parser, add_version, run_cli
from cliutil.paths import refuse_clobbering, refuse_folders
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.litchi import write_mission_csv
from flightplan.orbit import (
    DEFAULT_DEVIATION_TOLERANCE_M,
    DEFAULT_HEIGHT_M,
    DEFAULT_PHOTO_INTERVAL_S,
    DEFAULT_RADIUS_M,
    DEFAULT_SPEED_M_S,
    OrbitPlan,
    OrbitRequest,
    Ring,
    oversized_radius,
)

PROGRAM = "aerostereo-mission"

#: Ranges of the options, from Litchi's limits (:mod:`flightplan.litchi`): a waypoint's speed 0.1..15 m/s (0 would
#: mean the cruise speed), a photo every 0.1..6000 s, heights -200..500 m above take-off; a transit leg at most the
#: Mini SE's speed. Refused by argparse in one line naming the option and its range.
SPEED_KMH_RANGE = (round(litchi.MIN_SPEED_M_S * 3.6, 6), round(litchi.MAX_SPEED_M_S * 3.6, 6))
TRANSIT_SPEED_KMH_RANGE = (SPEED_KMH_RANGE[0], round(DJI_MINI_SE.max_speed_m_s * 3.6, 6))
height_m = number_within(litchi.MIN_ALTITUDE_M, litchi.MAX_ALTITUDE_M, "metres above take-off")


def _ring(text: str) -> Ring:
    """``RADIUS:HEIGHT`` or ``RADIUS:HEIGHT:PITCH`` (metres, metres above take-off, degrees)."""
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise argparse.ArgumentTypeError(f"a ring is RADIUS:HEIGHT[:PITCH], got {text!r}")
    try:
        numbers = [finite_number(p) for p in parts]
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"a ring is RADIUS:HEIGHT[:PITCH] with finite numbers, got {text!r}") from None
    try:
        height_m(parts[1])
    except argparse.ArgumentTypeError as error:
        raise argparse.ArgumentTypeError(f"a ring's HEIGHT is {str(error).removeprefix('expected ')}") from None
    return Ring(numbers[0], numbers[1], numbers[2] if len(numbers) == 3 else None)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (one-line errors, defaults in ``--help``, ``--version``)."""
    parser = Parser(
        prog=PROGRAM,
        description="Plan a circular orbit and export it as a Litchi Mission Hub CSV. "
        "Heights are metres above take-off.",
    )
    add_version(parser)
    where = parser.add_argument_group("centre (WGS84 degrees)")
    where.add_argument("--lat", type=finite_number, metavar="DEG", help="latitude of the orbit centre / POI")
    where.add_argument("--lon", type=finite_number, metavar="DEG", help="longitude of the orbit centre / POI")
    where.add_argument(
        "--demo",
        action="store_true",
        help=f"centre on the built-in demo location ({DEMO_ORIGIN.lat0_deg}, {DEMO_ORIGIN.lon0_deg})",
    )
    orbit = parser.add_argument_group("orbit")
    orbit.add_argument("--radius", type=finite_number, metavar="M", help=f"metres (default {DEFAULT_RADIUS_M:g})")
    orbit.add_argument(
        "--height", type=height_m, metavar="M",
        help=f"metres above take-off, {litchi.MIN_ALTITUDE_M:g}..{litchi.MAX_ALTITUDE_M:g} (default {DEFAULT_HEIGHT_M:g})"
    )
    orbit.add_argument(
        "--rings",
        type=_ring,
        nargs="+",
        metavar="R:H[:PITCH]",
        help="several rings instead of --radius/--height; PITCH fixes the gimbal (else it follows the POI)",
    )
    orbit.add_argument("--speed-kmh", type=number_within(*SPEED_KMH_RANGE, "km/h"), default=DEFAULT_SPEED_M_S * 3.6,
                       metavar="KMH", help="%g..%g (default 2.5)" % SPEED_KMH_RANGE)
    orbit.add_argument(
        "--interval", type=number_within(litchi.MIN_PHOTO_INTERVAL, litchi.MAX_PHOTO_INTERVAL, "seconds"),
        default=DEFAULT_PHOTO_INTERVAL_S, metavar="S",
        help=f"seconds between photos, {litchi.MIN_PHOTO_INTERVAL:g}..{litchi.MAX_PHOTO_INTERVAL:g} (default 1)"
    )
    orbit.add_argument("--waypoints", type=int, metavar="N", help="per ring (default: the fewest within --tolerance)")
    orbit.add_argument(
        "--tolerance",
        type=finite_number,
        default=DEFAULT_DEVIATION_TOLERANCE_M,
        metavar="M",
        help="max deviation of the flown path from the circle (default 0.25)",
    )
    orbit.add_argument("--direction", choices=("cw", "ccw"), default="cw", help="seen from above")
    orbit.add_argument("--start-bearing", type=finite_number, default=0.0, metavar="DEG", help="of the first waypoint (default 0)")
    orbit.add_argument("--poi-height", type=height_m, default=0.0, metavar="M",
                       help=f"above take-off, {litchi.MIN_ALTITUDE_M:g}..{litchi.MAX_ALTITUDE_M:g} (default 0)")
    orbit.add_argument(
        "--legal-height", type=finite_number, default=LEGAL_MAX_HEIGHT_M, metavar="M", help="above take-off (default 120: EU/US)"
    )
    area = parser.add_argument_group("area (instead of a centre): cover a field with orbits, one CSV per flight")
    area.add_argument("--area", type=Path, metavar="FIELD", help="field polygon, .kml or .geojson (WGS84); --out is then a folder")
    area.add_argument("--overlap", type=finite_number, default=DEFAULT_OVERLAP, metavar="F",
                      help="fraction of a well-covered disc's diameter shared with each neighbour")
    area.add_argument("--transit-speed-kmh", type=number_within(*TRANSIT_SPEED_KMH_RANGE, "km/h"),
                      default=DEFAULT_TRANSIT_SPEED_M_S * 3.6, metavar="KMH",
                      help="between orbits and to/from take-off, %g..%g" % TRANSIT_SPEED_KMH_RANGE)
    area.add_argument("--home", type=finite_number, nargs=2, metavar=("LAT", "LON"),
                      help="take-off point (default: the centroid of the field's vertices)")
    out = parser.add_argument_group("outputs")
    out.add_argument("--out", type=Path, required=True, metavar="CSV", help="Litchi CSV to write (with --area: a folder)")
    out.add_argument("--kml", type=Path, metavar="F", help="KML preview (Google Earth)")
    out.add_argument("--geojson", type=Path, metavar="F", help="GeoJSON preview")
    out.add_argument("--plot", type=Path, metavar="PNG", help="PNG plot")
    out.add_argument("--summary-json", type=Path, metavar="F", help="summary as JSON")
    return parser


def request_from_args(args: argparse.Namespace) -> OrbitRequest:
    """Turn parsed arguments into an :class:`OrbitRequest` (:class:`BadInput`/``ValueError`` on bad input)."""
    if args.demo:
        if args.lat is not None or args.lon is not None:
            raise BadInput("--demo sets the centre; leave out --lat/--lon")
        lat, lon = DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg
    elif args.lat is None or args.lon is None:
        raise BadInput("--lat and --lon are required (or --demo)")
    else:
        lat, lon = args.lat, args.lon
    if args.rings and (args.radius is not None or args.height is not None):
        raise BadInput("--rings replaces --radius/--height; give one or the other")
    radius = DEFAULT_RADIUS_M if args.radius is None else args.radius
    height = DEFAULT_HEIGHT_M if args.height is None else args.height
    rings = tuple(args.rings) if args.rings else (Ring(radius, height),)
    return OrbitRequest(
        center_lat_deg=lat,
        center_lon_deg=lon,
        rings=rings,
        speed_m_s=args.speed_kmh / 3.6,
        photo_interval_s=args.interval,
        direction=args.direction,
        start_bearing_deg=args.start_bearing,
        poi_height_m=args.poi_height,
        waypoints_per_ring=args.waypoints,
        deviation_tolerance_m=args.tolerance,
    )


def summary_text(plan: OrbitPlan) -> str:
    """The human-readable summary printed by the CLI on stdout (the warnings go to stderr)."""
    request = plan.request
    lines = [
        f"orbit centre {request.center_lat_deg:.7f}, {request.center_lon_deg:.7f}  "
        f"direction {request.direction}  start bearing {request.start_bearing_deg:g} deg",
        f"waypoints        {len(plan.mission)} rows ({' + '.join(str(r.waypoints) for r in plan.rings)} per ring, loop closed)",
        f"path length      {plan.path_length_m:.1f} m",
        f"flight time      {plan.flight_time_s:.0f} s ({plan.flight_time_s / 60:.1f} min) at {request.speed_m_s:.3f} m/s",
        f"photos           {plan.photo_count} (one every {request.photo_interval_s:g} s)",
        f"max deviation    {plan.max_deviation_m:.3f} m from the circle (flown path inside it)",
    ]
    for ring in plan.rings:
        lines.append(
            f"ring r={ring.radius_m:g} m h={ring.height_m:g} m: leg {ring.leg_m:.2f} m, curve {ring.curve_size_m:.2f} m, "
            f"gimbal {ring.gimbal_pitch_deg:.1f} deg, GSD {ring.gsd_at_center_cm_px:.2f} cm/px at the centre, "
            f"overlap {100 * ring.overlap_consecutive:.1f} %, heading error <= {ring.max_heading_error_deg:.3f} deg"
        )
    lines += [f"note: {note}" for note in plan.notes]
    return "\n".join(lines)


def _write_outputs(args: argparse.Namespace, plan: OrbitPlan, warnings: list[str]) -> list[Path]:
    """Write every output asked for, all or none (one that cannot be written leaves no other); their paths."""
    request = plan.request
    outputs = {name: path for name, path in output_paths(args).items() if path is not None}
    with atomic_paths(list(outputs.values())) as temporaries:
        files = dict(zip(outputs, temporaries))
        write_mission_csv(plan.mission, files["--out"])
        if "--kml" in files:
            preview.write_kml(plan.mission, files["--kml"], name=args.out.stem)
        if "--geojson" in files:
            preview.write_geojson(plan.mission, files["--geojson"])
        if "--plot" in files:
            preview.write_plot_png(plan.mission, request.center_lat_deg, request.center_lon_deg, files["--plot"])
        if "--summary-json" in files:
            summary = plan.summary_dict() | {"aircraft": DJI_MINI_SE.name, "warnings": warnings, "csv": str(args.out)}
            write_text_atomic(files["--summary-json"], json.dumps(summary, indent=2) + "\n")
    return list(outputs.values())


def output_paths(args: argparse.Namespace) -> dict[str, Path | None]:
    """Every file the command writes, by option."""
    return {"--out": args.out, "--kml": args.kml, "--geojson": args.geojson, "--plot": args.plot,
            "--summary-json": args.summary_json}


def refuse_oversized_rings(args: argparse.Namespace) -> None:
    """:class:`BadInput` naming ``--radius`` or ``--rings`` for a ring larger than any Litchi mission flies
    (:func:`flightplan.orbit.oversized_radius`), before any planning or reading."""
    given = [("--rings", ring.radius_m) for ring in args.rings or ()]
    given += [("--radius", args.radius)] if args.radius is not None else []
    for option, radius in given:
        if problem := oversized_radius(radius, len(args.rings or ()) or 1):
            raise BadInput(f"{option} {radius:g}: {problem}")


def run(args: argparse.Namespace) -> int:
    """Plan, check and write the mission of ``args``; print the summary (stdout) and warnings (stderr)."""
    refuse_oversized_rings(args)
    if args.area is not None:
        from flightplan.area_cli import run_area  # matplotlib and scipy only where an area is planned

        return run_area(args)
    refuse_clobbering({}, output_paths(args))
    refuse_folders(output_paths(args))
    plan, warnings = checks.checked_orbit(request_from_args(args), DJI_MINI_SE, args.legal_height)
    written = _write_outputs(args, plan, warnings)
    print(summary_text(plan))
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 2 bad input, failed checks or unwritable output, 130 Ctrl-C)."""
    return run_cli(PROGRAM, lambda: run(build_parser().parse_args(argv)))
