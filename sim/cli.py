"""``aerostereo-render``: render stereo datasets from a scene, compare renders with photos, fly the virtual drone.

``aerostereo-render [options]`` renders a dataset (the default command, :mod:`sim.render_cli`);
``aerostereo-render compare ...``, ``aerostereo-render fly ...`` and ``aerostereo-render export ...`` are
subcommands. Their parser is assembled
from small ``add_<command>_parser(subparsers)`` functions listed in :data:`SUBCOMMANDS` (the one place where
subcommands are named); each sets ``handler(args) -> int``. Bad input ends with a one-line message on stderr
and exit code 2.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path

from capture.track import parse_utc
from flightplan.litchi import LitchiFormatError
from flightplan.argtypes import finite_number
from sim.drone.session import LINKS, NOISE, FlyOptions, run_session
from sim.export_cli import add_export_parser
from sim.render_cli import add_compare_parser, render_main
from sim.render_dataset import resolve_scene_dir
from sim.scene import SceneError, load_scene


class CliError(Exception):
    """Bad user input: printed as one line, exit code 2."""


def utc_time(text: str) -> dt.datetime:
    """``--start-utc``: ISO 8601 (``2024-05-01T10:00:00Z``) read by :func:`capture.track.parse_utc` (naive = UTC)."""
    try:
        return dt.datetime.fromtimestamp(parse_utc(text), dt.timezone.utc)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an ISO 8601 time like 2024-05-01T10:00:00Z") from None


def add_fly_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "fly", help="fly a Litchi mission over a scene: DJI photos, DUML telemetry, ground truth",
        description="Fly a Litchi mission CSV with the virtual drone: writes OUT/photos/DJI_*.JPG (EXIF + DJI XMP), "
                    "OUT/flight.duml (+ .idx, the telemetry as received) and OUT/truth.json + truth.csv.")
    parser.add_argument("--mission", required=True, type=Path, help="Litchi Mission Hub CSV")
    parser.add_argument("--scene", default="demo", help="scene folder, or 'demo' / 'demo:small' (default: demo)")
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument("--photo-size", nargs=2, type=int, default=(800, 600), metavar=("W", "H"),
                        help="render size in pixels (default 800 600; the Mini SE field of view is kept)")
    parser.add_argument("--link", choices=LINKS, default="file",
                        help="file: capture with simulated arrival times; loop: through a pyserial loop:// port into "
                             "the live recorder; tcp: stream to --port socket://HOST:PORT (default file)")
    parser.add_argument("--port", help="for --link tcp: socket://HOST:PORT to stream to")
    parser.add_argument("--speedup", type=float, default=1.0,
                        help="pace live links this many times faster than real time (default 1)")
    parser.add_argument("--noise", choices=sorted(NOISE), default="realistic", help="imperfections (default realistic)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--start-utc", type=utc_time, help="UTC of motors-on (default: now)")
    parser.add_argument("--photos", type=int, dest="photo_limit", help="render only the first N photos")
    parser.add_argument("--logs", action="store_true", help="also write flight_log.csv (Litchi) and flight.srt")
    parser.add_argument("--geoid-undulation", type=finite_number, default=0.0, metavar="N",
                        help="geoid height above the WGS84 ellipsoid at the scene (m): photos and logs carry "
                             "ellipsoidal height - N as height above sea level (default 0: the ellipsoid)")
    parser.set_defaults(handler=run_fly)


#: Subcommands; anything else on the command line goes to the dataset renderer (the default command).
SUBCOMMANDS = (add_fly_parser, add_compare_parser, add_export_parser)


def build_parser() -> tuple[argparse.ArgumentParser, set[str]]:
    """The parser of the subcommands in :data:`SUBCOMMANDS`, and their names."""
    parser = argparse.ArgumentParser(
        prog="aerostereo-render",
        description="Render stereo datasets from scenes, and fly the virtual drone over them.")
    subparsers = parser.add_subparsers(dest="command", required=True)
    for add_parser in SUBCOMMANDS:
        add_parser(subparsers)
    return parser, set(subparsers.choices)


def main(argv: list[str] | None = None) -> int:
    """``aerostereo-render ...`` -> exit code: a subcommand, or the dataset render for any other arguments."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser, subcommands = build_parser()
    if not argv or argv[0] not in subcommands:
        return render_main(argv)
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except (CliError, LitchiFormatError, SceneError, ValueError, OSError) as error:
        print(f"aerostereo-render {args.command}: error: {error}", file=sys.stderr)
        return 2


def run_fly(args) -> int:
    if not args.mission.is_file():
        raise CliError(f"{args.mission}: no such mission file")
    if args.photo_limit is not None and args.photo_limit < 0:
        raise CliError(f"--photos {args.photo_limit}: expected a count >= 0")
    options = FlyOptions(photo_size=tuple(args.photo_size), link=args.link, port=args.port, speedup=args.speedup,
                         imperfections=NOISE[args.noise](), seed=args.seed, start_utc=args.start_utc,
                         photo_limit=args.photo_limit, logs=args.logs, geoid_undulation_m=args.geoid_undulation)
    scene = load_scene(resolve_scene_dir(args.scene))
    report = run_session(args.mission, scene, args.out, options)
    flight, photos = report.mission.flight, report.mission.photos
    print(f"flew {args.mission} over {scene.source}: {flight.duration_s:.1f} s from {report.start_utc.isoformat()}")
    print(f"telemetry: {report.frames} DUML frames, {report.bytes_sent} bytes -> {args.out / 'flight.duml'} (+ .idx)")
    print(f"photos: {report.rendered.photos} of {int(photos.taken.sum())} taken ({len(photos.t_s)} scheduled) "
          f"-> {args.out / 'photos'}; truth -> {args.out / 'truth.json'}, {args.out / 'truth.csv'}")
    return 0
