"""One virtual-drone session: read a Litchi mission, fly it over a scene, deliver the telemetry, take the photos,
write the ground truth. What ``aerostereo-render fly`` runs.

Output folder: ``photos/DJI_0001.JPG ...``, ``flight.duml`` + ``flight.duml.idx`` (the telemetry as received),
``truth.json`` + ``truth.csv``, and with ``logs`` a Litchi-style ``flight_log.csv`` and ``flight.srt``
(:data:`FLIGHT_OUTPUTS`). A folder already holding an earlier flight's outputs (or area-plan flights ``flight_NN/``)
is refused, unless ``FlyOptions.overwrite``: then those outputs, and nothing else, are removed once every check has
passed (:func:`remove_earlier_flight`). Order: the telemetry is delivered first (on a live link its clock fixes the
flight's start time), then the photos are rendered with EXIF times on that same time line, each lit by the real sun at
its UTC time unless ``FlyOptions.sun`` says otherwise (:mod:`sim.drone.sunlight`); a photo whose real sun is at or below
the horizon is refused before anything is written.

Links: ``file`` writes the capture with simulated arrival times (send time, no latency); ``loop`` streams the
frames through one pyserial ``loop://`` port, paced by the flight clock, and records what comes out of it with
:class:`capture.transports.SerialSource` and :func:`capture.recorder.record` (the ``aerostereo-ingest record``
code path); ``tcp`` streams to ``socket://host:port`` (someone must listen there, e.g. a relay to
``aerostereo-ingest record``) and also writes ``flight.duml`` as the file link does.
"""

from __future__ import annotations

import datetime as dt
import io
import os
import re
import shutil
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator

import numpy as np
import serial
from tqdm import tqdm

from capture.live_plan import PlannedPath
from capture.live_state import LiveLimits, LiveState
from capture.live_view import LineDisplay, LiveMonitor
from capture.messages import default_registry
from capture.raw import atomic_capture, index_path
from capture.recorder import record
from capture.transports import Chunk, SerialSource
from cliutil.atomic import remove_stale_temps
from cliutil.resources import require_memory
from flightplan.litchi import read_mission_csv
from sim.drone import FlownMission, Imperfections, fly, write_truth
from sim.drone.flight_faults import NO_FAULTS, FaultAfterLanding, FlightFaults
from sim.drone.logs import write_flight_logs
from sim.drone.link import Frame, MissionClock, duml_frames, stream, write_raw_capture
from sim.drone.mission import HomePoint, home_below_first_waypoint, waypoints_from_litchi
from sim.drone.photo_faults import PhotoFaultPlan, PhotoFaults
from sim.drone.photos import (RenderedPhotos, camera_truth, ground_height_ellipsoid_m, photo_camera,
                              render_photos)
from sim.drone.sunlight import (DEFAULT_START_NOTE, FlightLight, check_photos, default_start_utc, flight_light,
                                sun_truth)
from sim.render.camera import MAX_IMAGE_SIDE_PX
from sim.render.raycast import default_workers
from sim.render.renderer import render_memory_bytes
from sim.render.scene import Scene
from sim.sampling.light import SunSetting

LINKS = ("file", "loop", "tcp")
NOISE = {"realistic": Imperfections.realistic, "area": Imperfections.area, "rtk": Imperfections.rtk,
         "none": Imperfections.none}
CAPTURE_NAME = "flight.duml"
#: What one flight writes into its folder: the photos' folder, the capture and its index, the truth, the logs.
FLIGHT_OUTPUTS = ("photos", CAPTURE_NAME, index_path(CAPTURE_NAME).name, "truth.json", "truth.csv", "flight_log.csv",
                  "flight.srt")
#: The folders of an area plan's flights (:func:`flight_folder`).
FLIGHT_FOLDER = re.compile(r"flight_\d{2,}")
#: Largest geoid undulation N accepted (metres, either sign): Earth's geoid lies -107 m (Indian Ocean) to +86 m (New
#: Guinea) from the WGS84 ellipsoid (EGM2008); beyond it a height above sea level is no height on Earth.
MAX_GEOID_UNDULATION_M = 150.0
#: How far beyond the flight's start and end its time stamps may reach (the camera clock's offset is seconds at most).
TIME_LINE_SLACK_S = 86400.0
#: The years a flight's time stamps may lie in: EXIF's DateTimeOriginal holds a 4-digit year ("YYYY:MM:DD HH:MM:SS",
#: which year 1 broke as "1:01:01"), and Python's datetime ends with year 9999. The sun model (PyEphem's VSOP87)
#: holds over these millennia.
EARLIEST_UTC = dt.datetime(1000, 1, 1, tzinfo=dt.timezone.utc)
LATEST_UTC = dt.datetime(9999, 12, 31, 23, 59, 59, 999999, tzinfo=dt.timezone.utc)
#: Time on the ground between two flights of an area plan (land, swap the battery, re-acquire the fix, take off).
BATTERY_SWAP_S = 300.0


@dataclass(frozen=True)
class FlyOptions:
    """How to fly: render size (px), link, port URL for ``tcp``, pacing speed-up, imperfections, seed, start, and
    ``geoid_undulation_m`` (N: the geoid's height above the WGS84 ellipsoid at the scene, metres) that turns the
    flight's ellipsoidal heights into the heights above sea level the photos and logs carry (h - N). ``seed`` is
    an integer, or ``(seed, flight number)`` for one flight of an area plan (:func:`run_flights`). ``start_utc``:
    motors on (an aware datetime); None: :func:`sim.drone.sunlight.default_start_utc` over the scene, the same
    instant whenever it is flown (a live link's clock too). ``start_now`` (``--start-utc now``): motors on when the
    telemetry starts, on this machine's clock, which a recorder in another process stamps (``start_utc`` is then
    only when the flight was asked for: the flight's clock takes this machine's UTC when it is made, for the sun and
    time checks, and again as a ``tcp`` stream starts, before the photos and truth.json take it). ``sun``: the
    photos' light (:class:`~sim.sampling.light.SunSetting`, not the random form); None: the real sun over the scene
    at each photo's UTC time (:mod:`sim.drone.sunlight`). ``faults``: the flight and link faults asked for
    (:mod:`sim.drone.flight_faults`; each flight of an area plan gets them, on its own flight time)."""

    photo_size: tuple[int, int] = (800, 600)
    link: str = "file"
    port: str | None = None
    speedup: float = 1.0
    imperfections: Imperfections = field(default_factory=Imperfections.realistic)
    seed: int | tuple[int, int] = 0
    start_utc: dt.datetime | None = None
    start_now: bool = False  # motors on when the telemetry stream starts, on this machine's clock (--start-utc now)
    photo_limit: int | None = None
    logs: bool = False
    progress: bool = True
    geoid_undulation_m: float = 0.0
    home: tuple[float, float] | None = None  # take-off (lat, lon) WGS84 degrees; None: under the first waypoint
    sun: SunSetting | None = None
    overwrite: bool = False  # replace an earlier flight in the output folder (else it is refused)
    photo_faults: PhotoFaults = field(default_factory=PhotoFaults)  # skipped shots, motion blur (sim.drone.photo_faults)
    faults: FlightFaults = NO_FAULTS

    def __post_init__(self) -> None:
        if self.sun is not None and self.sun.form == "random":
            raise ValueError("a flight's photos take a fixed, real (time:), overcast or unlit sun, not the random "
                             "one drawn per dataset frame")
        if not abs(self.geoid_undulation_m) <= MAX_GEOID_UNDULATION_M:
            raise ValueError(f"geoid undulation must be a finite number of metres within +-{MAX_GEOID_UNDULATION_M:g} "
                             f"(Earth's: -107..+86 m), got {self.geoid_undulation_m}")
        if self.link not in LINKS:
            raise ValueError(f"link {self.link!r}: expected one of {', '.join(LINKS)}")
        if self.link == "tcp" and not (self.port or "").startswith("socket://"):
            raise ValueError(f"link tcp needs a port socket://HOST:PORT, got {self.port!r}")
        if not all(0 < side <= MAX_IMAGE_SIDE_PX for side in self.photo_size):
            raise ValueError(f"photo size must be 1..{MAX_IMAGE_SIDE_PX} pixels a side (the largest image rendered: "
                             f"beyond the largest photogrammetry sensors), got {self.photo_size}")


@dataclass
class FlyReport:
    """What a session produced."""

    mission: FlownMission
    start_utc: dt.datetime
    frames: int
    bytes_sent: int
    rendered: RenderedPhotos
    sun: dict  # truth.json's "sun" (sim.drone.sunlight.sun_truth)


def fly_litchi_mission(mission_csv, scene: Scene, seed, imperfections: Imperfections,
                       home: tuple[float, float] | None = None, faults: FlightFaults = NO_FAULTS) -> FlownMission:
    """Fly the Litchi CSV over ``scene`` with ``faults``, taking off from the scene's ground at ``home`` (lat, lon
    degrees: the pilot's place, e.g. an area plan's ``take_off``) or, when None, below the first waypoint."""
    waypoints = waypoints_from_litchi(read_mission_csv(mission_csv))
    if home is None:
        first = waypoints[0]
        take_off = home_below_first_waypoint(
            waypoints, ground_height_ellipsoid_m(scene, first.latitude_deg, first.longitude_deg))
    else:
        try:
            take_off = HomePoint(*home, ground_height_ellipsoid_m(scene, *home))
        except ValueError as error:
            raise ValueError(f"--home {home[0]} {home[1]}: {error}; expected a take-off point on the scene") from None
    try:
        mission = fly(waypoints, take_off, imperfections, seed=seed, faults=faults)
    except FaultAfterLanding:
        raise  # its option is what to change, not the mission
    except ValueError as error:
        raise ValueError(f"{mission_csv}: {error}") from None
    return mission


def until_received(source: SerialSource, total_bytes: int) -> Iterator[Chunk]:
    """The chunks of ``source`` until ``total_bytes`` have arrived (a virtual flight's whole stream)."""
    stop, received = threading.Event(), 0
    for chunk in source.chunks(stop):
        yield chunk
        received += len(chunk.data)
        if received >= total_bytes:
            stop.set()


def record_loopback(frames: list[Frame], path, clock: MissionClock, progress: bool = True, tap=None) -> int:
    """Stream ``frames`` into one ``loop://`` port from a thread and record its output to ``path`` (+ ``.idx``)
    with the live recorder, stamped by ``clock``; both files atomically. ``tap``: handed each recorded chunk (a
    live view's :meth:`capture.live_view.LiveMonitor.put`). Returns the bytes recorded."""
    port = serial.serial_for_url("loop://", timeout=0.05)
    source = SerialSource("loop://", clock=clock)
    source.connection = port
    with tqdm(total=len(frames), desc="telemetry", unit="frame", disable=not progress) as bar:
        sender = threading.Thread(target=stream, args=(frames, port.write, clock, bar.update), daemon=True)
        with atomic_capture(path) as writer:
            sender.start()
            status = record(until_received(source, sum(len(frame.data) for frame in frames)), writer,
                            default_registry(), tap=tap)
        sender.join()
    return status.bytes


def watch_loopback(frames: list[Frame], path, clock: MissionClock, plan: PlannedPath,
                   limits: LiveLimits = LiveLimits(), display=None) -> LiveMonitor:
    """:func:`record_loopback` under a live view of ``plan`` (:mod:`capture.live_view`) on ``clock``, so that its
    warnings' times are flight seconds, comparable with truth.json's faults; ``display``: where it shows (default:
    plain lines into nothing). Returns the monitor, closed."""
    monitor = LiveMonitor(LiveState(plan, limits), default_registry(), clock.monotonic,
                          display or LineDisplay(io.StringIO()))
    with monitor:
        record_loopback(frames, path, clock, progress=False, tap=monitor.put)
    return monitor


def stream_to_port(frames: list[Frame], url: str, clock: MissionClock, progress: bool = True) -> int:
    """Stream ``frames`` to a pyserial URL (``socket://host:port``, a serial device ...), paced by ``clock``."""
    try:
        port = serial.serial_for_url(url, timeout=0.05)
    except (serial.SerialException, ValueError) as error:
        raise OSError(f"cannot open {url}: {error}") from None
    with port, tqdm(total=len(frames), desc="telemetry", unit="frame", disable=not progress) as bar:
        sent = stream(frames, port.write, clock, bar.update)
        port.flush()
    return sent


def start_utc_of(options: FlyOptions, scene: Scene) -> dt.datetime:
    """The flight's motors-on UTC: ``options.start_utc``, else the default over the scene's origin."""
    return options.start_utc or default_start_utc(scene.origin)


def start_utc_from(options: FlyOptions) -> str:
    """What ``truth.json`` says of where ``start_utc`` comes from."""
    if options.start_now:
        return "this machine's clock when the flight's telemetry started (--start-utc now)"
    return "given" if options.start_utc is not None else f"the default: {DEFAULT_START_NOTE}"


def check_time_line(start_utc: dt.datetime, duration_s: float) -> None:
    """Refuse (``ValueError`` naming ``--start-utc``) a flight whose time stamps, from a day before ``start_utc`` to
    a day after its ``duration_s`` (:data:`TIME_LINE_SLACK_S`: room for the camera clock's offset), leave
    :data:`EARLIEST_UTC` .. :data:`LATEST_UTC`."""
    room = dt.timedelta(seconds=TIME_LINE_SLACK_S)
    if EARLIEST_UTC + room <= start_utc <= LATEST_UTC - room - dt.timedelta(seconds=duration_s):
        return
    raise ValueError(f"--start-utc {start_utc.isoformat()}: the {duration_s:.0f} s flight's time stamps (with a "
                     f"day's room for the camera clock) must lie within years {EARLIEST_UTC.year} to "
                     f"{LATEST_UTC.year} (EXIF's DateTimeOriginal holds a 4-digit year)")


def check_session(mission: FlownMission, start_utc: dt.datetime, options: FlyOptions,
                  scene: Scene) -> tuple[FlightLight, PhotoFaultPlan]:
    """Refuse (``ValueError``) a session whose time stamps would leave years 1000-9999 (:func:`check_time_line`),
    whose photo render needs more memory than is free, whose photos to render have the real sun at or below the
    horizon, or whose photo fault windows hold no photo, before anything is written. Returns the photos' light and
    their faults."""
    check_time_line(start_utc, mission.flight.duration_s)
    width, height = options.photo_size
    pixels = width * height
    require_memory(render_memory_bytes([pixels], 1, default_workers()) + 3 * pixels,  # + the JPEG encoder's copy
                   f"--photo-size {width} {height}")
    photos = mission.photos
    light = flight_light(options.sun, photos.t_s, start_utc, scene.origin)
    rendered = np.flatnonzero(photos.taken)[:options.photo_limit]
    check_photos(light, rendered, photos.names, scene.origin)
    return light, photo_fault_plan(mission, rendered, options.photo_faults)


def photo_fault_plan(mission: FlownMission, rendered: np.ndarray, faults: PhotoFaults) -> PhotoFaultPlan:
    """``faults`` resolved on the flight's photos ``rendered`` (indices of the scheduled photos taken and rendered)."""
    photos = mission.photos
    velocity = mission.flight.state_at(photos.t_s).velocity_enu_mps if len(photos.t_s) else np.zeros((0, 3))
    return faults.on(photos.t_s, photos.names, rendered, photos.R_world_cam, velocity)


def run_session(mission_csv, scene: Scene, out_dir, options: FlyOptions, mission: FlownMission | None = None,
                start_from: str | None = None) -> FlyReport:
    """Fly (unless ``mission`` is the flown model already), deliver the telemetry, take the photos and write the truth
    into ``out_dir`` (module docstring). ``start_from``: what truth.json says of where the start time comes from
    (default: :func:`start_utc_from`)."""
    out_dir = Path(out_dir)
    refuse_earlier_flight(out_dir, options.overwrite)
    mission = mission or fly_litchi_mission(mission_csv, scene, options.seed, options.imperfections, options.home,
                                           options.faults)
    clock = MissionClock(options.speedup, None if options.start_now else start_utc_of(options, scene))
    light, faults = check_session(mission, clock.start_utc, options, scene)
    if options.overwrite:
        remove_earlier_flight(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    frames = duml_frames(mission)
    capture = out_dir / CAPTURE_NAME
    if options.link == "loop":
        sent = record_loopback(frames, capture, clock, options.progress)
    else:
        if options.link == "tcp":
            clock.restart()  # motors on now: the recorder at the other end stamps from here
            stream_to_port(frames, options.port, clock, options.progress)
        write_raw_capture(frames, capture, clock.start_utc)
        sent = sum(len(frame.data) for frame in frames)
    if options.logs:
        write_flight_logs(mission, clock.start_utc, out_dir, options.geoid_undulation_m)
    camera = photo_camera(*options.photo_size, lens=options.imperfections.lens_distortion)
    rendered = render_photos(mission, scene, out_dir / "photos", camera, clock.start_utc, lights=light.photos,
                             limit=options.photo_limit, progress=options.progress,
                             geoid_undulation_m=options.geoid_undulation_m, faults=faults)
    sun, photo_suns = sun_truth(light, mission.flight.duration_s, scene.origin)
    write_truth(out_dir, mission.flight, mission.photos, options.seed, gains=rendered.gains, photo_suns=photo_suns,
                extra={
        "start_utc": clock.start_utc.isoformat(), "start_utc_from": start_from or start_utc_from(options),
        "telemetry_clock_note": "UTC = start_utc + t_s",
        "mission_csv": str(mission_csv), "scene": scene.source, "link": options.link,
        "photo_size_px": list(options.photo_size), "camera_K": camera.K.tolist(), "camera": camera_truth(camera),
        "geoid_undulation_m": options.geoid_undulation_m,
        "gps_fix_bias_enu_m": mission.sensors.gps_fix_bias_enu_m.tolist(),
        "gps_fix_bias_note": "the flight's constant GPS error (ENU m), part of every GPS fix: its fix offset",
        "height_note": "h_ellipsoid_m is above the WGS84 ellipsoid; photos and logs carry h_ellipsoid_m - "
                       "geoid_undulation_m as the height above sea level", "sun": sun,
        "faults": sorted(options.faults.truth(clock.start_utc, mission.flight.duration_s) + faults.truth(),
                         key=lambda fault: fault["start_s"]),
        "faults_note": "each fault's window start_s..end_s in flight seconds; flight faults (gust, link_silence, "
                       "gimbal_stuck, battery_drain) also in UTC, photo faults with the photos they hit; a "
                       "skipped_shot's photos fired (a shutter event) but are not on the card",
        "link_dropouts_s": sorted(mission.telemetry.dropouts_s.tolist()),
        "link_dropouts_note": "[start, end) flight seconds in which the link sent nothing: its own dropouts "
                              "(imperfections) and a link_silence fault"})
    return FlyReport(mission, clock.start_utc, len(frames), sent, rendered, sun)


def flight_folder(out_dir, number: int) -> Path:
    """Where flight ``number`` (1-based) of an area plan writes its outputs: ``OUT/flight_NN``."""
    return Path(out_dir) / f"flight_{number:02d}"


def run_flights(mission_csvs, scene: Scene, out_dir, options: FlyOptions) -> list[FlyReport]:
    """Fly the flights of an area plan in order, flight k (1-based) into :func:`flight_folder` with the seed
    ``(options.seed, k)`` (its own gusts, sensor errors and GPS fix offset), flight 1 at ``options.start_utc`` (or
    the default, :func:`start_utc_of`) and each next one :data:`BATTERY_SWAP_S` after the previous one landed. Every
    flight is flown as a model and checked (:func:`check_session`: hours later the sun may have set) before the first
    writes anything; an earlier flight in ``out_dir`` is refused or, with ``options.overwrite``, removed then. The
    flights are a time table from the first one's start, so ``options.start_now`` is the moment they were asked for
    (a clock that followed this machine's would start each flight when it is written, off the time table)."""
    refuse_earlier_flight(out_dir, options.overwrite)
    options = replace(options, start_now=False)
    flights, start = [], start_utc_of(options, scene)
    for number, mission_csv in enumerate(mission_csvs, start=1):
        flight_options = replace(options, seed=(int(options.seed), number), start_utc=start)
        try:
            mission = fly_litchi_mission(mission_csv, scene, flight_options.seed, options.imperfections,
                                         options.home, options.faults)
        except FaultAfterLanding as error:
            raise FaultAfterLanding(f"{error} (flight {number}, {mission_csv})") from None
        try:
            check_session(mission, start, flight_options, scene)
        except ValueError as error:
            raise ValueError(f"{mission_csv} (flight {number}): {error}") from None
        flights.append((mission_csv, mission, flight_options))
        start += dt.timedelta(seconds=mission.flight.duration_s + BATTERY_SWAP_S)
    if options.overwrite:
        remove_earlier_flight(out_dir)
    first_from = start_utc_from(options)
    return [run_session(mission_csv, scene, flight_folder(out_dir, number), flight_options, mission,
                        first_from if number == 1 else f"{BATTERY_SWAP_S:.0f} s after flight {number - 1} landed "
                                                       f"(flight 1: {first_from})")
            for number, (mission_csv, mission, flight_options) in enumerate(flights, start=1)]


def earlier_flight(out_dir) -> list[Path]:
    """The outputs (:data:`FLIGHT_OUTPUTS`) that earlier flights left in ``out_dir`` and in its area-plan flight
    folders ``flight_NN/``, in that order (``[]`` where ``out_dir`` is no folder)."""
    return [folder / name for folder in _flight_folders(out_dir) for name in FLIGHT_OUTPUTS
            if os.path.lexists(folder / name)]


def refuse_earlier_flight(out_dir, overwrite: bool) -> None:
    """``ValueError`` naming ``out_dir`` and the first earlier flight's output in it, unless ``overwrite``: a new
    flight would replace some of its files and keep others (photos beyond the new count), a mixed flight."""
    if not overwrite and (found := earlier_flight(out_dir)):
        raise ValueError(f"--out {out_dir}: holds an earlier flight ({found[0].relative_to(out_dir)}); pass "
                         "--overwrite to replace it, or choose another folder")


def remove_earlier_flight(out_dir) -> None:
    """Delete what earlier flights wrote into ``out_dir`` and its ``flight_NN/`` (:func:`earlier_flight`: the
    photos' folder whole, the capture, index, truth and logs, and the temporaries of interrupted writes), then the
    flight folders left empty; nothing else."""
    folders = _flight_folders(out_dir)
    for folder in folders:
        for path in (folder / name for name in FLIGHT_OUTPUTS):
            remove_stale_temps(path)
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            elif os.path.lexists(path):
                path.unlink()
    for folder in folders[1:]:
        if not folder.is_symlink() and not any(folder.iterdir()):
            folder.rmdir()


def _flight_folders(out_dir) -> list[Path]:
    """``out_dir`` and its area-plan flight folders (:data:`FLIGHT_FOLDER`); ``[]`` where it is no folder."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    return [out_dir, *sorted(path for path in out_dir.iterdir() if FLIGHT_FOLDER.fullmatch(path.name) and path.is_dir())]
