"""``aerostereo-ingest geotag``, ``export`` and ``track``: subcommands registered on capture's CLI.

``register(subparsers)`` adds them (``export``: geotags.csv -> GPX, ODM geo.txt, COLMAP reference); each sets
``handler`` to a function taking the parsed args and returning an exit code. Bad input raises
:class:`~cliutil.errors.BadInput` (or a ``ValueError``/``OSError``), which ``aerostereo-ingest`` reports as
one line on stderr with exit code 2, nothing written. Outputs that name an input (a photo, a log) or each other
are refused before anything is read. The readers' reports go to stderr, the result lines to stdout.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from cliutil.argtypes import finite_number, positive_number
from cliutil.atomic import staged_folder
from cliutil.errors import BadInput
from cliutil.paths import folder_inputs, path_problem, refuse_clobbering, refuse_folders

from .geotag_limits import DEFAULT_MAX_GAP_S, DEFAULT_MAX_MISFIT_M
from .raw import index_path
from .track import LOG_KINDS, ReadReport, parse_utc

# The geotagger, its exports and the log readers (scipy, Pillow) are imported by the commands that use them, so
# that 'aerostereo-ingest decode' and 'record' start without them.


def register(subparsers) -> None:
    """Add the ``geotag`` and ``track`` subcommands to an argparse subparsers object."""
    geotag = subparsers.add_parser("geotag", help="photos + flight logs -> geotags.csv (+ .json sidecar)")
    geotag.add_argument("--photos", required=True, help="folder of JPEG photos")
    geotag.add_argument("--log", action="append", required=True,
                        help="flight log (Litchi/Airdata CSV, DJI SRT, DUML capture NAME.duml (+ .idx) or pcap, "
                             "or a folder of photos); repeatable")
    geotag.add_argument("--clock-offset", default="auto", type=parse_clock_offset,
                        help="'auto' or seconds to add to the camera clock to get telemetry UTC")
    geotag.add_argument("--max-gap", type=positive_number, default=DEFAULT_MAX_GAP_S,
                        help="longest telemetry gap (s) to interpolate across (default %(default)s)")
    geotag.add_argument("--max-misfit", type=positive_number, default=DEFAULT_MAX_MISFIT_M,
                        help="largest median distance (m) between the photos' own GPS and their geotags from the "
                             "logs (default %(default)s: 3 sigma of a consumer GPS); the automatic clock offset only "
                             "accepts shifts within it, and a larger one is refused as photos from another place or "
                             "a wrong clock offset; give more for photos whose GPS is known to be off the logs")
    add_time_options(geotag)
    geotag.add_argument("--out", required=True, help="geotags.csv to write (the .json sidecar goes beside it)")
    add_export_options(geotag, "also ")
    geotag.add_argument("--write-exif", action="store_true",
                        help="write geotagged copies of the photos (EXIF GPS + DJI XMP) into --exif-dir")
    geotag.add_argument("--exif-dir", help="folder for the geotagged copies (default: <out folder>/geotagged)")
    geotag.set_defaults(handler=run_geotag)

    export = subparsers.add_parser(
        "export", help="geotags.csv -> GPX (exiftool -geotag, QGIS), ODM geo.txt, COLMAP model_aligner reference",
        description="Export the geotags of a geotags.csv (+ its .json sidecar) for other tools. Heights are copied: "
                    "GPX ele and geo.txt z are the geotags' absolute_height_m (left out when the sidecar says its "
                    "datum is unknown), COLMAP X Y Z the ENU position in the geotags' frame.")
    export.add_argument("geotags", type=Path, help="geotags.csv written by 'aerostereo-ingest geotag'")
    add_export_options(export, "")
    export.set_defaults(handler=run_export)

    track = subparsers.add_parser("track", help="read any flight log and export it as CSV, KML or GPX")
    track.add_argument("file", help="flight log (Litchi/Airdata CSV, DJI SRT, DUML capture NAME.duml (+ .idx) "
                                      "or pcap, or a folder of photos)")
    track.add_argument("--kind", choices=LOG_KINDS, help="force the reader instead of detecting it")
    add_time_options(track)
    track.add_argument("--out", help="track CSV to write")
    track.add_argument("--kml", help="track KML to write")
    track.add_argument("--gpx", type=Path, help="track GPX 1.1 to write (ele: the log's absolute height, if any)")
    track.set_defaults(handler=run_track)


def add_export_options(parser: argparse.ArgumentParser, also: str) -> None:
    """``--gpx``, ``--odm-geo``, ``--colmap-ref``: the exports of :mod:`capture.geotag_export`."""
    parser.add_argument("--gpx", type=Path,
                        help=f"{also}write a GPX 1.1 track, a point per photo (exiftool -geotag, QGIS)")
    parser.add_argument("--odm-geo", type=Path,
                        help=f"{also}write an OpenDroneMap geo.txt (EPSG:4326; image_name lon lat z)")
    parser.add_argument("--colmap-ref", type=Path,
                        help=f"{also}write a COLMAP model_aligner reference 'image_name X Y Z' (ENU metres; "
                             "--ref_is_gps 0 --alignment_type custom)")


def export_outputs(args) -> dict[str, Path | None]:
    return {"--gpx": args.gpx, "--odm-geo": args.odm_geo, "--colmap-ref": args.colmap_ref}


def add_time_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--start-time", type=parse_time_arg,
                        help="UTC start (ISO 8601) of SRT logs that carry no date (e.g. a Mini's video)")
    parser.add_argument("--srt-utc-offset", type=finite_number, default=0.0,
                        help="UTC offset (hours) of the aircraft clock in dated SRT files (default 0)")


def parse_clock_offset(text: str):
    """``'auto'`` or a finite number of seconds."""
    if text == "auto":
        return text
    try:
        return finite_number(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected 'auto' or a finite number of seconds, got {text!r}") from None


def parse_time_arg(text: str) -> float:
    try:
        return parse_utc(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an ISO 8601 time like 2021-09-06T02:23:48Z, got {text!r}") from None


def log_inputs(paths) -> list[Path]:
    """What flight log arguments read: each file and its ``.idx`` (a DUML capture), or a folder and its files."""
    return [input_path for path in map(Path, paths) for input_path in (*folder_inputs(path), index_path(path))]


def run_geotag(args) -> int:
    """Geotag the photos; print a per-source summary and the clock offset (stderr), the result line (stdout)."""
    from .geotag_export import check_line_names, write_exports
    from .geotag_folder import geotag_folder
    from .geotag_io import geotag_paths, write_exif_copies, write_geotags

    csv_path, json_path = geotag_paths(args.out)  # a bad --out fails before the logs are read
    if problem := path_problem(args.photos, folder=True):
        raise BadInput(f"--photos {args.photos}: {problem}; expected a folder of JPEG photos")
    exif_dir = Path(args.exif_dir) if args.exif_dir else Path(args.out).resolve().parent / "geotagged"
    files = {"--out": csv_path, "--out's sidecar": json_path, **export_outputs(args)}
    refuse_clobbering({"--photos": folder_inputs(args.photos), "--log": log_inputs(args.log)},
                      {**files, "--exif-dir": exif_dir if args.write_exif else None})
    refuse_folders(files)
    if args.write_exif and exif_dir.is_file():
        raise BadInput(f"--exif-dir {exif_dir}: is a file; expected a folder for the geotagged copies")
    result, photo_report = geotag_folder(args.photos, args.log, clock_offset=args.clock_offset,
                                         max_gap_s=args.max_gap, max_misfit_m=args.max_misfit,
                                         start_time_s=args.start_time, srt_utc_offset_h=args.srt_utc_offset)
    if args.odm_geo or args.colmap_ref:
        check_line_names([tag.image_name for tag in result.tags])  # before anything is written
    # the copies first, beside --exif-dir: a photo whose metadata cannot be edited leaves no output at all
    with staged_folder(exif_dir) if args.write_exif else contextlib.nullcontext() as staging:
        if staging is not None:
            write_exif_copies(result, args.photos, staging)
        write_geotags(result, csv_path)
        export_notes = write_exports(csv_path, args.gpx, args.odm_geo, args.colmap_ref)
    for report in result.sources:
        print_report(report, shown_rejects=0)  # counts per reason; `track` lists a log's rejects
    if photo_report.source not in {report.source for report in result.sources}:
        print_report(photo_report)  # which photos could not be read or had unusable values
    print(result.clock.summary(), file=sys.stderr)
    for note in result.notes + export_notes:
        print(f"note: {note}", file=sys.stderr)
    for name, reason in result.untagged:
        print(f"  untagged {name}: {reason}", file=sys.stderr)
    own = f" ({len(result.from_photos)} from their own EXIF/XMP)" if result.from_photos else ""
    print(f"{len(result.tags)} photos geotagged{own}, {len(result.untagged)} untagged -> {csv_path} "
          f"(+ {json_path.name})")
    return 0


def run_export(args) -> int:
    """Write the requested exports of a geotags.csv; one line per file written (stdout), notes on stderr."""
    from .geotag_export import write_exports
    from .geotag_io import sidecar_path

    outputs = export_outputs(args)
    if not any(outputs.values()):
        raise BadInput("give at least one of --gpx, --odm-geo, --colmap-ref")
    refuse_clobbering({"geotags": args.geotags, "(sidecar)": sidecar_path(args.geotags)}, outputs)
    refuse_folders(outputs)
    for note in write_exports(args.geotags, args.gpx, args.odm_geo, args.colmap_ref):
        print(f"note: {note}", file=sys.stderr)
    for option, path in outputs.items():
        if path:
            print(f"{option[2:]}: {path}")
    return 0


def print_report(report: ReadReport, shown_rejects: int = 20) -> None:
    """A reader's summary (rejects counted per reason), its notes and its first rejects with file:line (stderr)."""
    lines = [report.summary(), *(f"  note: {note}" for note in report.notes),
             *(f"  rejected {problem}" for problem in report.rejected[:shown_rejects])]
    if len(report.rejected) > shown_rejects:
        lines.append(f"  ... and {len(report.rejected) - shown_rejects} more rejected")
    print("\n".join(lines), file=sys.stderr)


def run_track(args) -> int:
    """Read one log, print its report (stderr), export CSV, KML and/or GPX, print the result line (stdout)."""
    from .geotag_export import write_track_gpx
    from .logs import read_track

    if not (args.out or args.kml or args.gpx):
        raise BadInput("give --out track.csv, --kml track.kml and/or --gpx track.gpx")
    outputs = {"--out": args.out, "--kml": args.kml, "--gpx": args.gpx}
    refuse_clobbering({"FILE": log_inputs([args.file])}, outputs)
    refuse_folders(outputs)
    track = read_track(args.file, kind=args.kind, start_time_s=args.start_time, srt_utc_offset_h=args.srt_utc_offset)
    if args.gpx:
        write_track_gpx(track, args.gpx)
    if args.out:
        track.write_csv(args.out)
    if args.kml:
        track.write_kml(args.kml)
    print_report(track.report)
    print(f"{len(track)} rows, {len(track.photo_times_s)} photo events, clock {track.clock}, "
          f"fields: {', '.join(sorted(track.fields))}")
    return 0
