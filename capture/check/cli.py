"""The ``check`` subcommand's arguments (:mod:`capture.check.command` runs it): kept apart so that
``aerostereo-ingest`` starts without the check's image and plotting libraries."""

from __future__ import annotations

from pathlib import Path

from capture.check import MAP_NAME, REFLY_NAME, REPORT_NAME
from capture.cli_logs import parse_clock_offset
from capture.geotag_limits import DEFAULT_MAX_MISFIT_M
from cliutil.argtypes import positive_number


def register(subparsers) -> None:
    """Add the ``check`` subcommand."""
    parser = subparsers.add_parser(
        "check", help="after landing: is the capture complete for reconstruction? verdict, map, re-fly CSV",
        description="Check a flight's photos for reconstruction: geotag them, compare them with the mission's arcs "
                    "and the log's shutter events, score each photo (blur, clipping, GPS, gimbal pitch, forward "
                    f"overlap). Writes OUT/{REPORT_NAME} (also printed), OUT/{MAP_NAME} and, where arcs need "
                    f"flying again, OUT/{REFLY_NAME}; the one-line verdict goes to stderr.")
    parser.add_argument("--photos", required=True, type=Path, help="the card's folder of JPEG photos")
    parser.add_argument("--log", type=Path, action="append", default=[],
                        help="flight log (DUML capture NAME.duml (+ .idx), Litchi/Airdata CSV, DJI SRT); repeatable; "
                             "without it the photos' own EXIF GPS is used and shutter events are not checked")
    parser.add_argument("--clock-offset", default="auto", type=parse_clock_offset,
                        help="as geotag's: 'auto' or seconds to add to the camera clock to get telemetry UTC")
    parser.add_argument("--max-misfit", type=positive_number, default=DEFAULT_MAX_MISFIT_M,
                        help="as geotag's: largest median distance (m) between the photos' own GPS and their geotags "
                             "from the logs (default %(default)s)")
    parser.add_argument("--mission", type=Path, help="the Litchi mission CSV flown (its photo legs are the arcs)")
    parser.add_argument("--out", required=True, type=Path, help="folder for the report, the map and the re-fly CSV")
    parser.set_defaults(handler=run)


def run(args) -> int:
    """Run the check (:func:`capture.check.command.run_check`)."""
    from capture.check.command import run_check
    return run_check(args)
