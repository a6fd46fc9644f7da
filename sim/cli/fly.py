"""``aerostereo-render fly``: fly Litchi missions with the virtual drone over a scene (:mod:`sim.drone.session`):
DJI photos, DUML telemetry and the ground truth."""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path

from capture.track import parse_utc
from cliutil.argtypes import finite_number, non_negative_integer, number_within
from cliutil.paths import folder_holds, folder_inputs, path_problem, refuse_clobbering
from cliutil.errors import BadInput
from sim.cli.light import flight_sun_value
from sim.drone.flight_faults import (GUST_RISE_S, MAX_DRAIN_FACTOR, MAX_FAULT_DURATION_S, MAX_GUST_OFFSET_M,
                                     BatteryDrain, FlightFaults, GimbalStuck, Gust, LinkSilence)
from sim.drone.session import (BATTERY_SWAP_S, LINKS, MAX_GEOID_UNDULATION_M, NOISE, FlyOptions, FlyReport,
                               flight_folder, refuse_earlier_flight, run_flights, run_session)
from sim.drone.photo_faults import MAX_BLUR_PX, MOTION_BLUR, SKIPPED_SHOT, FaultWindow, PhotoFaults
from sim.drone.sunlight import DEFAULT_START_NOTE
from sim.render.camera import MAX_IMAGE_SIDE_PX
from sim.render.scene import load_scene
from sim.run.render_dataset import is_demo_scene, resolve_scene_dir


#: ``--start-utc``'s word for the current time (the only way a flight starts "now").
NOW = "now"


def utc_time(text: str) -> dt.datetime | str:
    """``--start-utc``: ISO 8601 (``2024-05-01T10:00:00Z``) read by :func:`capture.track.parse_utc` (naive = UTC), or
    :data:`NOW` as it is (the flight takes this machine's clock when its telemetry starts: ``FlyOptions.start_now``)."""
    if text == NOW:
        return NOW
    try:
        return dt.datetime.fromtimestamp(parse_utc(text), dt.timezone.utc)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an ISO 8601 time like 2024-05-01T10:00:00Z, nor "
                                         f"'{NOW}'") from None


def photo_side(text: str) -> int:
    """``--photo-size``: one side, 1..:data:`~sim.render.camera.MAX_IMAGE_SIDE_PX` pixels."""
    try:
        side = int(text)
    except ValueError:
        side = 0
    if not 1 <= side <= MAX_IMAGE_SIDE_PX:
        raise argparse.ArgumentTypeError(f"expected 1..{MAX_IMAGE_SIDE_PX} pixels a side (the largest image "
                                         f"rendered, as the dataset render's --width/--height), got {text!r}")
    return side


def fault_window(kind: str, fields: tuple[str, ...]):
    """An argparse type reading ``fields`` comma-separated numbers into a :class:`FaultWindow` of ``kind``."""
    def parse(text: str) -> FaultWindow:
        try:
            values = [float(part) for part in text.split(",")]
            if len(values) != len(fields):
                raise ValueError(f"expected {len(fields)} comma-separated numbers")
            return FaultWindow(kind, *values)
        except ValueError as error:
            raise argparse.ArgumentTypeError(f"expected {','.join(fields)} ({error}), got {text!r}") from None
    return parse


def add_photo_fault_options(parser) -> None:
    """The ``photo faults`` group of ``fly`` (:mod:`sim.drone.photo_faults`), all off by default."""
    group = parser.add_argument_group("photo faults", "off by default; each repeatable, recorded in truth.json's "
                                                      "'faults' with the photos it hit (times: seconds since motors on)")
    group.add_argument("--skip-shots", type=fault_window(SKIPPED_SHOT, ("START", "END")), action="append",
                       default=[], metavar="START,END",
                       help="skipped shots: the camera fires (a shutter event in the telemetry) but no photo reaches "
                            "the card for every shot taken from START to END s")
    group.add_argument("--blur", type=fault_window(MOTION_BLUR, ("START", "END", "LENGTH")), action="append",
                       default=[], metavar="START,END,LENGTH",
                       help="motion blur on every photo taken from START to END s: a line kernel LENGTH pixels long "
                            f"(at --photo-size; 0 < LENGTH <= {MAX_BLUR_PX:g}) along the camera's motion in the image, "
                            "applied in linear light")


def add_fly_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "fly", help="fly a Litchi mission over a scene: DJI photos, DUML telemetry, ground truth",
        description="Fly a Litchi mission CSV with the virtual drone: writes OUT/photos/DJI_*.JPG (EXIF + DJI XMP), "
                    "OUT/flight.duml (+ .idx, the telemetry as received) and OUT/truth.json + truth.csv. Several "
                    "--mission (the flights of an area plan) are flown in order, flight k into OUT/flight_0k/, each "
                    "with the seed (SEED, k): its own gusts, sensor errors and GPS fix offset.")
    parser.add_argument("--mission", required=True, type=Path, action="append",
                        help="Litchi Mission Hub CSV; repeat it for each flight of an area plan")
    parser.add_argument("--scene", default="demo",
                        help="scene folder, or 'demo' / 'demo:small' / 'demo:large' (default: demo)")
    parser.add_argument("--out", required=True, type=Path,
                        help="output folder; one holding an earlier flight is refused unless --overwrite")
    parser.add_argument("--overwrite", action="store_true",
                        help="if --out holds an earlier flight, delete it first (its photos/, flight.duml + .idx, "
                             "truth.json/.csv, flight_log.csv, flight.srt, and those of its flight_NN/ folders; "
                             "anything else in --out is kept)")
    parser.add_argument("--photo-size", nargs=2, type=photo_side, default=(800, 600), metavar=("W", "H"),
                        help=f"render size in pixels, 1..{MAX_IMAGE_SIDE_PX} a side (default 800 600; the Mini SE "
                             "field of view is kept)")
    parser.add_argument("--link", choices=LINKS, default="file",
                        help="file: capture with simulated arrival times; loop: through a pyserial loop:// port into "
                             "the live recorder; tcp: stream to --port socket://HOST:PORT (default file)")
    parser.add_argument("--port", help="for --link tcp: socket://HOST:PORT to stream to")
    parser.add_argument("--speedup", type=float, default=1.0,
                        help="pace live links this many times faster than real time (default 1)")
    parser.add_argument("--noise", choices=sorted(NOISE), help="imperfections (default: realistic for one --mission; "
                                                                  "area, realistic + a GPS fix offset per flight, "
                                                                  "for several; rtk: area on an RTK fixed solution, "
                                                                  "stated in the photos' XMP)")
    parser.add_argument("--seed", type=non_negative_integer, default=0, help="random seed, >= 0 (default 0)")
    parser.add_argument("--start-utc", type=utc_time, metavar="ISO8601|now",
                        help=f"UTC of motors-on, in years 1000-9999, or '{NOW}' (this machine's clock; default: "
                             f"{DEFAULT_START_NOTE}, the same whenever it is run: said on stderr and in truth.json); "
                             f"with several --mission, of the first flight, the next ones taking off "
                             f"{BATTERY_SWAP_S:.0f} s after the previous landed")
    parser.add_argument("--sun", type=flight_sun_value, metavar="SUN",
                        help="the photos' light: AZ,EL,STRENGTH (degrees clockwise from north, degrees above the "
                             "horizon, the paper's strength: 10 lights a surface facing the sun at its full albedo), "
                             "time:ISO8601 (the real sun as if flown from that UTC), overcast (sky light only) or "
                             "unlit (the scene's texture as captured); default: the real sun over the scene at each "
                             "photo's UTC time (--start-utc + flight time), refused when it is down. A value starting "
                             "with a minus sign is taken as it is (--sun -45,60,8)")
    parser.add_argument("--home", nargs=2, type=finite_number, metavar=("LAT", "LON"),
                        help="take-off point, WGS84 degrees, on the scene's ground (default: under the first "
                             "waypoint); an area plan's take_off (area.json) for its flights")
    parser.add_argument("--photos", type=int, dest="photo_limit", help="render only the first N photos")
    parser.add_argument("--logs", action="store_true", help="also write flight_log.csv (Litchi) and flight.srt")
    parser.add_argument("--geoid-undulation", type=number_within(-MAX_GEOID_UNDULATION_M, MAX_GEOID_UNDULATION_M,
                                                                 "metres"), default=0.0, metavar="N",
                        help="geoid height above the WGS84 ellipsoid at the scene (m, within "
                             f"+-{MAX_GEOID_UNDULATION_M:g}: Earth's is -107..+86): photos and logs carry "
                             "ellipsoidal height - N as height above sea level (default 0: the ellipsoid)")
    add_photo_fault_options(parser)
    add_flight_fault_arguments(parser)
    parser.set_defaults(handler=run_fly)


def add_flight_fault_arguments(parser) -> None:
    """The "flight faults" group (:mod:`sim.drone.flight_faults`): each off unless given, times in seconds of flight
    time (since the motors started), recorded in truth.json's "faults"."""
    group = parser.add_argument_group("flight faults", "faults to test a live view on (each off by default; START "
                                                       "and DURATION in seconds of flight time; truth.json lists "
                                                       "them under \"faults\")")
    group.add_argument("--gust", nargs=3, type=finite_number, metavar=("START", "DURATION", "METRES"),
                       help=f"push the aircraft METRES (at most {MAX_GUST_OFFSET_M:g}) to the right of its path for "
                            f"DURATION s (at least {2 * GUST_RISE_S:g}: the push rises and falls over "
                            f"{GUST_RISE_S:g} s)")
    group.add_argument("--link-silence", nargs=2, type=finite_number, metavar=("START", "DURATION"),
                       help=f"the link sends nothing for DURATION s (at most {MAX_FAULT_DURATION_S:g}); the photos "
                            "are still taken")
    group.add_argument("--gimbal-stuck", nargs=3, type=finite_number, metavar=("START", "DURATION", "PITCH"),
                       help="the gimbal stays at PITCH degrees (-90..0) for DURATION s")
    group.add_argument("--battery-drain", nargs=2, type=finite_number, metavar=("START", "FACTOR"),
                       help=f"from START to the landing the battery runs down FACTOR times faster (1 < FACTOR <= "
                            f"{MAX_DRAIN_FACTOR:g}; normally 100 %% lasts 25 min)")


def flight_faults_from(args) -> FlightFaults:
    """The faults the "flight faults" options ask for (``ValueError`` naming the option where one is out of its
    bounds)."""
    def made(kind, values):
        return None if values is None else kind(*values)

    return FlightFaults(gust=made(Gust, args.gust), link_silence=made(LinkSilence, args.link_silence),
                        gimbal_stuck=made(GimbalStuck, args.gimbal_stuck),
                        battery_drain=made(BatteryDrain, args.battery_drain))


def refuse_clobbering_fly(args) -> None:
    """Refuse (:class:`BadInput`) an ``--out`` folder that is, or holds, the mission or the scene (fly writes fixed
    names, photos/, flight.duml, truth.json..., into it), and without ``--overwrite`` one holding an earlier
    flight (:func:`sim.drone.session.refuse_earlier_flight`), before the scene is loaded."""
    scene = None if is_demo_scene(args.scene) else Path(args.scene)
    inputs = {"--mission": args.mission, "--scene": folder_inputs(scene)}
    refuse_clobbering(inputs, {"--out": args.out})
    for name, path in [*(("--mission", mission) for mission in args.mission), ("--scene", scene)]:
        if path is not None and folder_holds(args.out, path):
            raise BadInput(f"--out {args.out}: holds {name} {path}, which the flight's outputs could overwrite; "
                           "choose an --out folder outside it")
    refuse_earlier_flight(args.out, args.overwrite)


def run_fly(args) -> int:
    for mission in args.mission:
        if problem := path_problem(mission, folder=False):
            raise BadInput(f"{mission}: {problem}; expected a Litchi mission CSV")
    if args.photo_limit is not None and args.photo_limit < 0:
        raise BadInput(f"--photos {args.photo_limit}: expected a count >= 0")
    faults = flight_faults_from(args)
    refuse_clobbering_fly(args)
    several = len(args.mission) > 1
    noise = args.noise or ("area" if several else "realistic")
    start_now = args.start_utc == NOW
    start_utc = dt.datetime.now(dt.timezone.utc) if start_now else args.start_utc
    options = FlyOptions(photo_size=tuple(args.photo_size), link=args.link, port=args.port, speedup=args.speedup,
                         imperfections=NOISE[noise](), seed=args.seed, start_utc=start_utc, start_now=start_now,
                         photo_limit=args.photo_limit, logs=args.logs, geoid_undulation_m=args.geoid_undulation,
                         home=tuple(args.home) if args.home else None, sun=args.sun, overwrite=args.overwrite,
                         photo_faults=PhotoFaults(tuple(args.skip_shots + args.blur)),
                         faults=faults)
    scene = load_scene(resolve_scene_dir(args.scene), with_labels=False, with_provenance=False)
    if not several:
        reports = [run_session(args.mission[0], scene, args.out, options)]
    else:
        reports = run_flights(args.mission, scene, args.out, options)
    if args.start_utc is None:  # said once every check has passed: a refusal stays one line
        print(f"no --start-utc: took off at {reports[0].start_utc.isoformat()}, {DEFAULT_START_NOTE}: the same "
              f"whenever it is run (--start-utc {NOW} for this machine's clock)", file=sys.stderr)
    for number, report in enumerate(reports, start=1):
        folder = args.out if not several else flight_folder(args.out, number)
        print_flight(report, args.mission[number - 1], scene.source, folder)
    return 0


def print_flight(report: FlyReport, mission: Path, scene_source, out: Path) -> None:
    """The summary of one flight on stdout: duration, telemetry, photos, where each went."""
    flight, photos = report.mission.flight, report.mission.photos
    bias = ", ".join(f"{v:+.2f}" for v in report.mission.sensors.gps_fix_bias_enu_m)
    print(f"flew {mission} over {scene_source}: {flight.duration_s:.1f} s from {report.start_utc.isoformat()}, "
          f"GPS fix offset ENU ({bias}) m")
    print(f"telemetry: {report.frames} DUML frames, {report.bytes_sent} bytes -> {out / 'flight.duml'} (+ .idx)")
    print(f"photos: {report.rendered.photos} of {int(photos.taken.sum())} taken ({len(photos.t_s)} scheduled) "
          f"-> {out / 'photos'}; truth -> {out / 'truth.json'}, {out / 'truth.csv'}")
    print(f"sun: {sun_summary(report.sun)}")


def sun_summary(sun: dict) -> str:
    """One line of truth.json's ``sun``: the real sun from the flight's start to its end, or the one form."""
    if sun["form"] != "time":
        values = ", ".join(f"{key} {value:g}" for key, value in sun.items() if isinstance(value, float))
        return f"{sun['form']}" + (f" ({values})" if values else "")
    start, end = sun["start"], sun["end"]
    return (f"real, azimuth {start['azimuth_deg']:.1f} -> {end['azimuth_deg']:.1f} deg, elevation "
            f"{start['elevation_deg']:.1f} -> {end['elevation_deg']:.1f} deg, strength {start['strength']:.1f} -> "
            f"{end['strength']:.1f} over the flight")
