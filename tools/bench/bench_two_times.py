"""A twin relit to another time of day: the same mission flown at 08:00 and at 15:00, the twin built from the first.

    .venv/bin/python tools/bench/bench_two_times.py --work DIR [--quick] [--photo-interval S] [--seed N] [--json F]

Through the command lines, as a user runs them (``tools/loops/closed_loop.py``'s stages, each in a child process):

1. ``aerostereo-mission`` plans the closed loop's orbit over the demo world's origin; ``aerostereo-render fly`` flies
   it twice, ``--start-utc`` at 08:00 and at 15:00 mean local solar time over the scene's origin (UTC = local solar
   time - longitude / 15 h; the equation of time, up to 16 min, is left out) on :data:`FLIGHT_DATE`, 2026-05-01: on
   the demo world (40.18 N, 44.50 E) the sun stands at azimuth 98 deg, elevation 33 deg, then at 251 deg, 43 deg,
   their directions 100 deg apart. The second flight has the next seed (another day: its own gusts, GPS errors and
   exposure drift).
2. ``aerostereo-ingest geotag`` geotags the 08:00 photos (their geotags carry UTC), ``aerostereo-recon`` builds the
   twin from them alone: its atlas is the albedo, the capture sun divided out ("relit albedo"). The same
   reconstruction with ``--keep-capture-light`` (its work folder copied: only the texture stage is redone) is the
   twin as it was before delighting ("lit texture", the 08:00 light baked in).
3. Each twin is rendered at every photo of each flight: the photo's TRUE pose and camera (``truth.json``: pose,
   intrinsics, lens distortion), its TRUE sun (the real sun at its UTC time), and its TRUE auto-exposure gain per
   channel as the renderer's exposure (``truth.json``'s ``gain_r/g/b``: photo = gain x the unit-exposure render, in
   linear light, exactly as the virtual drone rendered the photo). The twin is placed on the world by the
   similarity that takes its registered cameras onto the true ones (:func:`recon.measure.oblique.twin_frame`), which
   removes the GPS georeference's error. The true world is rendered the same way as a check of that handling
   (it differs from the photos by their JPEG coding only).
4. Formula 3 (:func:`sim.evaluation.realism.photorealism_error_masked`) of each render against its photo over the
   pixels the twin covers (where the twin has surface), and again after one gain per channel fitted to the photo
   (:func:`sim.evaluation.realism.fit_channel_gains`: what is left when no exposure is known).

Printed (stdout): per twin and flight the mean and median formula 3 (true gain), the mean with fitted gains, the
covered fraction; per twin the difference other - own (issue 28's criterion: the relit twin within 1 point of
itself at its own flight); at the later flight, how each twin carries the light
(:func:`recon.measure.oblique.score_light`, over the area the first flight stood over and looked at,
:func:`flight_area`): the ghost ratio (twin / truth luminance where the 08:00 sun cast a shadow that the 15:00 sun
lights: 1 when the capture's shadows are gone), formula 3 where both suns light the surface, and the twin as captured
against the truth under the 08:00 sun (the texture's floor at those poses); the time of every stage. Progress on stderr.
``--work`` is resumed: a finished stage (its output present and its time recorded in ``stages.json``) is not run again.

Defaults: the closed loop's (``tools/loops/closed_loop.py``'s ``LoopConfig``): the demo world, the mission's full orbit
(50 m radius, 30 m up), 800x600 photos, SfM at 800 px, depth maps at recon's default (the photos' 800 px), a photo every
:data:`DEFAULT_INTERVAL_S` s. The mission's own interval is 1 s (452 photos); 2 s (226 photos) keeps the run near 30 min
on the 2-core machine (a 452-photo reconstruction alone takes 12-23 min there, tools/bench/bench_recon_orbit.py, and
every photo is rendered six times). ``--quick``: the closed loop's reduced settings (demo:small, a 3-waypoint arc,
480x360 photos).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import shutil
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from cliutil.atomic import write_text_atomic  # noqa: E402
from flightplan.geodesy import LocalFrame  # noqa: E402
from recon.measure.oblique import LightScores, TwinFrame, score_light, summarise_light, twin_frame  # noqa: E402
from recon.surface.observed import viewed_area  # noqa: E402
from recon.measure.scene_cameras import truth_poses  # noqa: E402
from sim.evaluation.realism import (  # noqa: E402
    fit_channel_gains, photorealism_error_masked, photorealism_error_percent, read_rgb)
from sim.render.camera import PinholeCamera, Rig  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.render.renderer import View, render  # noqa: E402
from sim.render.scene import Scene, load_scene, read_scene_json  # noqa: E402
from sim.render.shade import UNLIT, Lighting, Sun  # noqa: E402
from sim.sampling.light import SunSetting, frame_light, real_sun, utc_text  # noqa: E402
from tools.loops.closed_loop import (LoopConfig, StageResult, cli, plan_mission, recon_options, run,  # noqa: E402
                                     world_folder)

#: The day both flights are flown.
FLIGHT_DATE = dt.date(2026, 5, 1)
#: Mean local solar times (hours) of the two take-offs: the twin's flight, then the other.
LOCAL_SOLAR_HOURS = (8.0, 15.0)
#: Default seconds between photos (the module docstring says why not the mission's 1 s).
DEFAULT_INTERVAL_S = 2.0
#: Each take-off's sun must stand higher than this (degrees): a lower one lights little but long shadows.
MIN_SUN_ELEVATION_DEG = 5.0
#: The two suns must be at least this far apart (degrees) for the relighting to be a test.
MIN_SUN_SEPARATION_DEG = 45.0
#: The twins: label -> whether recon keeps the capture light.
TWINS = {"lit texture": True, "relit albedo": False}
#: What stands beside the twins: the true world, rendered the same way (the gain and sun handling's floor).
TRUE_WORLD = "true world"


def utc_at_local_solar_time(day: dt.date, hours: float, lon_deg: float) -> dt.datetime:
    """The UTC instant (aware, to the second) at which mean local solar time at longitude ``lon_deg`` (degrees east)
    reads ``hours`` on ``day``: UTC = local solar time - lon / 15 h. The equation of time is left out."""
    midnight = dt.datetime(day.year, day.month, day.day, tzinfo=dt.timezone.utc)
    return midnight + dt.timedelta(seconds=round(3600.0 * (hours - lon_deg / 15.0)))


def sun_separation_deg(first: Sun, second: Sun) -> float:
    """Angle (degrees) between the directions towards two suns."""
    return math.degrees(math.acos(float(np.clip(first.direction_enu @ second.direction_enu, -1.0, 1.0))))


@dataclass(frozen=True)
class Flight:
    """One flight of the mission: its label, its take-off UTC, its seed and its folder."""

    label: str
    start_utc: dt.datetime
    seed: int
    folder: Path


def flights(work: Path, origin: LocalFrame, seed: int) -> list[Flight]:
    """The twin's flight (own) and the later one (other), at :data:`LOCAL_SOLAR_HOURS` over ``origin``."""
    return [Flight(f"{label} {int(hours):02d}:{round(60 * (hours % 1)):02d}",
                   utc_at_local_solar_time(FLIGHT_DATE, hours, origin.lon0_deg), seed + k, work / f"fly_{k + 1}")
            for k, (label, hours) in enumerate(zip(("own", "other"), LOCAL_SOLAR_HOURS))]


def check_suns(flown: list[Flight], origin: LocalFrame) -> None:
    """Print each take-off's sun (stderr); ``ValueError`` when one is down or they are too alike to test relighting."""
    suns = []
    for flight in flown:
        light = real_sun(flight.start_utc, origin)
        record = light.record
        print(f"{flight.label}: take-off {utc_text(flight.start_utc)}, sun azimuth {record['azimuth_deg']:.1f} deg, "
              f"elevation {record['elevation_deg']:.1f} deg, strength {record['strength']:.2f}", file=sys.stderr)
        if record["elevation_deg"] <= MIN_SUN_ELEVATION_DEG:
            raise ValueError(f"{flight.label}: the sun is at {record['elevation_deg']:.1f} deg at take-off")
        suns.append(light.keywords["sun"])
    separation = sun_separation_deg(*suns)
    print(f"the two suns are {separation:.0f} deg apart", file=sys.stderr)
    if separation < MIN_SUN_SEPARATION_DEG:
        raise ValueError(f"the suns are only {separation:.0f} deg apart (< {MIN_SUN_SEPARATION_DEG:g})")


class Stages:
    """The stages of one ``--work`` folder, resumed: a stage whose output exists and whose time ``stages.json``
    records is not run again (its recorded time is reported)."""

    def __init__(self, work: Path):
        self.work, self.log_dir = work, work / "logs"
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.path = work / "stages.json"
        self.seconds = json.loads(self.path.read_text(encoding="utf-8")) if self.path.is_file() else {}
        self.results: list[StageResult] = []

    def done(self, name: str, output: Path) -> bool:
        """Whether stage ``name`` finished in an earlier run (its ``output`` exists, its time is recorded)."""
        if output.exists() and name in self.seconds:
            self.results.append(StageResult(name, "resumed", self.seconds[name]))
            print(f"[{name}] resumed ({output} exists)", file=sys.stderr)
            return True
        return False

    def record(self, result: StageResult) -> StageResult:
        """Keep a finished stage's time; ``RuntimeError`` with the stage's reason when it failed."""
        self.results.append(result)
        if result.status != "ok":
            raise RuntimeError(f"stage {result.name} failed: {result.detail}")
        self.seconds[result.name] = result.wall_s
        write_text_atomic(self.path, json.dumps(self.seconds, indent=1) + "\n")
        print(f"[{result.name}] {result.wall_s:.1f} s", file=sys.stderr)
        return result

    def command(self, name: str, output: Path, argv: list[str]) -> None:
        """Run a command-line stage unless it is done."""
        if not self.done(name, output):
            print(f"[{name}] running: {' '.join(argv[1:])}", file=sys.stderr)
            self.record(run(name, argv, self.log_dir))


def fly_and_reconstruct(config: LoopConfig, stages: Stages, world: Path, flown: list[Flight]) -> dict[str, Path]:
    """Plan, fly both flights, geotag the first and reconstruct its two twins; their scene folders by label."""
    work, origin = stages.work, read_scene_json(world)["origin_frame"]
    mission = work / "mission"
    if not stages.done("plan", mission / "mission.csv"):
        mission.mkdir(exist_ok=True)
        stages.record(plan_mission(config, origin, mission, stages.log_dir))
    for flight in flown:
        stages.command(f"fly {flight.label}", flight.folder / "truth.json", cli("aerostereo-render fly") + [
            "--mission", str(mission / "mission.csv"), "--scene", str(world), "--out", str(flight.folder),
            "--photo-size", *map(str, config.photo_size), "--noise", config.noise, "--seed", str(flight.seed),
            "--start-utc", utc_text(flight.start_utc), "--overwrite"])  # over what an interrupted run left
    own = flown[0].folder
    geotags = work / "geotag" / "geotags.csv"
    stages.command("geotag", geotags, cli("aerostereo-ingest") + [
        "geotag", "--photos", str(own / "photos"), "--log", str(own / "flight.duml"), "--out", str(geotags)])
    scenes = {}
    for label, keep_light in sorted(TWINS.items(), key=lambda twin: twin[1]):  # the albedo's work folder first
        scene = work / ("recon_lit" if keep_light else "recon")
        if keep_light and not (scene / "work").exists():
            shutil.copytree(work / "recon" / "work", scene / "work")  # only the texture stage is redone
        stages.command(f"recon ({label})", scene / "scene.json", cli("aerostereo-recon") + [
            "--photos", str(own / "photos"), "--geotags", str(geotags), "--out", str(scene), *recon_options(config),
            *(["--keep-capture-light"] if keep_light else [])])
        scenes[label] = scene
    return scenes


def truth_camera(truth: dict) -> PinholeCamera:
    """The drone's photo camera as ``truth.json`` states it (:func:`sim.drone.photos.camera_truth`)."""
    camera = truth["camera"]
    return PinholeCamera(camera["fx"], camera["fy"], camera["cx"], camera["cy"], camera["width"], camera["height"],
                         dist=tuple(camera["distortion"]))


@dataclass(frozen=True)
class Photo:
    """One photo of a flight as the virtual drone took it: its file, TRUE pose (world ENU ``T_world_cam``), sun
    (world ENU) and exposure gain per channel (photo = gain x the unit-exposure render, linear light)."""

    path: Path
    T_world_cam: np.ndarray
    sun: Sun
    gain: tuple[float, float, float]


def flight_photos(truth: dict, folder: Path, world_origin: LocalFrame) -> list[Photo]:
    """Every photo the flight in ``folder`` wrote, with its ``truth`` (``truth.json``) moved into the world's ENU
    frame."""
    to_world = LocalFrame.from_dict(truth["origin"]).transform_to(world_origin)
    poses = truth_poses(truth)
    photos = []
    for row in truth["photos"]:
        path = folder / "photos" / row["image_name"]
        if row["image_name"] in poses and path.is_file():
            sun = row["sun"]
            setting = SunSetting("fixed", sun["azimuth_deg"], sun["elevation_deg"], sun["strength"])
            photos.append(Photo(path, to_world @ poses[row["image_name"]],
                                frame_light(setting, 0, 0, world_origin).keywords["sun"],
                                (row["gain_r"], row["gain_g"], row["gain_b"])))
    return photos


def render_photo(scene: Scene, frame: TwinFrame | None, camera: PinholeCamera, photo: Photo, pool,
                 sun: Sun | None = None) -> View:
    """``scene`` seen as ``photo`` was taken (its pose and exposure) under ``sun`` (world ENU; None: the photo's own);
    ``frame`` places a twin on the world (None: the world itself)."""
    sun = sun or photo.sun
    pose, sun = ((photo.T_world_cam, sun) if frame is None else (frame.camera_pose(photo.T_world_cam), frame.sun(sun)))
    return render(scene, Rig((camera,)), pose, sun, lighting=Lighting(exposure=photo.gain), pool=pool).views[0]


def render_as_captured(scene: Scene, frame: TwinFrame, camera: PinholeCamera, photo: Photo, pool) -> View:
    """A twin's texture as photographed (:data:`sim.render.shade.UNLIT`) at ``photo``'s pose and exposure."""
    lighting = replace(UNLIT["lighting"], exposure=photo.gain)
    return render(scene, Rig((camera,)), frame.camera_pose(photo.T_world_cam), UNLIT["sun"], lighting=lighting,
                  pool=pool).views[0]


def score(photo: np.ndarray, rendered: np.ndarray, covered: np.ndarray) -> tuple[float, float]:
    """Formula 3 (%) over the ``covered`` pixels, as rendered and with one gain per channel fitted to the photo."""
    fitted = fit_channel_gains(photo[covered], rendered[covered])
    return photorealism_error_masked(photo, rendered, covered), photorealism_error_percent(photo[covered], fitted)


@dataclass(frozen=True)
class Bench:
    """What every photo is rendered and scored with: the true ``world``, the ``twins`` (scene and its place on the
    world, by label), the ``area`` its flight observed (world ENU polygon, :func:`flight_area`) and its
    ``capture_sun`` (world ENU: the sun at the twin's flight's take-off)."""

    world: Scene
    twins: dict[str, tuple[Scene, TwinFrame]]
    area: np.ndarray
    capture_sun: Sun


def photo_scores(bench: Bench, camera: PinholeCamera, photo: Photo, pool) -> tuple[dict, np.ndarray, dict]:
    """One photo against the twins' and the true world's renders over the pixels every twin covers: per label
    (formula 3 with the true gain, with fitted gains); the covered mask; the renders."""
    rgb = read_rgb(photo.path)
    scenes = {**bench.twins, TRUE_WORLD: (bench.world, None)}
    views = {label: render_photo(scene, frame, camera, photo, pool) for label, (scene, frame) in scenes.items()}
    covered = np.logical_and.reduce([views[label].valid for label in bench.twins])
    scores = {label: score(rgb, view.rgb, covered) if covered.any() else (math.nan, math.nan)
              for label, view in views.items()}
    return scores, covered, views


def light_scores(bench: Bench, camera: PinholeCamera, photo: Photo, views: dict, pool) -> dict[str, LightScores]:
    """How each twin carries the light at a photo of the later flight (:func:`recon.measure.oblique.score_light`): the
    true world under the photo's sun and under the capture sun, each twin relit and as captured, over the observed
    area."""
    captured = render_photo(bench.world, None, camera, photo, pool, sun=bench.capture_sun)
    return {label: score_light(views[TRUE_WORLD], captured, views[label],
                               render_as_captured(scene, frame, camera, photo, pool), bench.area)
            for label, (scene, frame) in bench.twins.items()}


def score_flight(bench: Bench, folder: Path, relit: bool) -> dict[str, dict]:
    """Every photo of the flight in ``folder``: per label the per-photo formula 3 (``error``: true gain, ``fitted``:
    fitted gains) and ``covered`` fractions (:func:`photo_scores`); with ``relit`` (the later flight) also each
    twin's light scores summarised (``light``, :func:`recon.measure.oblique.summarise_light`)."""
    truth = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
    camera, photos = truth_camera(truth), flight_photos(truth, folder, bench.world.origin)
    labels = (*bench.twins, TRUE_WORLD)
    scores = {label: {"error": [], "fitted": [], "covered": []} for label in labels}
    light = {label: [] for label in bench.twins}
    with ThreadPoolExecutor(default_workers()) as pool:
        for index, photo in enumerate(photos):
            errors, covered, views = photo_scores(bench, camera, photo, pool)
            for label in labels:
                for key, value in zip(("error", "fitted", "covered"), (*errors[label], float(covered.mean()))):
                    scores[label][key].append(value)
            if relit:
                for label, scored in light_scores(bench, camera, photo, views, pool).items():
                    light[label].append(scored)
            if (index + 1) % 10 == 0 or index + 1 == len(photos):
                print(f"{folder.name}: {index + 1}/{len(photos)} photos scored", file=sys.stderr)
    if relit:
        for label, scored in light.items():
            scores[label]["light"] = summarise_light(scored)
    return scores


def flight_area(world: Scene, photos: list[Photo]) -> np.ndarray:
    """What a flight stood over and looked at (:func:`recon.surface.observed.viewed_area` of its true poses on the
    world's ground under them, world ENU polygon): for a whole orbit its disc, for a short arc also the centre it looks
    at."""
    poses = np.array([photo.T_world_cam for photo in photos])
    ground = np.nanmedian(world.ground_height(poses[:, 0, 3], poses[:, 1, 3]))
    return viewed_area(poses, float(ground))


def measure(stages: Stages, world_dir: Path, scenes: dict[str, Path], flown: list[Flight]) -> dict:
    """Score both flights against every twin (per flight, per label: :func:`score_flight`'s lists)."""
    world = load_scene(world_dir)
    own_truth = json.loads((flown[0].folder / "truth.json").read_text(encoding="utf-8"))
    twins = {label: (load_scene(folder), twin_frame(folder, own_truth, world.origin))
             for label, folder in scenes.items()}
    bench = Bench(world, twins, flight_area(world, flight_photos(own_truth, flown[0].folder, world.origin)),
                  real_sun(flown[0].start_utc, world.origin).keywords["sun"])
    results = {}
    for flight in flown:
        started = time.perf_counter()
        results[flight.label] = score_flight(bench, flight.folder, relit=flight is not flown[0])
        stages.results.append(StageResult(f"render + score {flight.label}", "ok", time.perf_counter() - started))
    return results


def summary(values: list[float]) -> tuple[float, float]:
    """Mean and median over the finite values."""
    finite = np.asarray(values, float)
    finite = finite[np.isfinite(finite)]
    return (float(finite.mean()), float(np.median(finite))) if len(finite) else (math.nan, math.nan)


def print_scores(results: dict, flown: list[Flight]) -> None:
    """Formula 3 per twin and flight (mean, median; with fitted gains) and the covered fraction (stdout)."""
    print("| twin | flight | photos | f3 mean % | f3 median % | f3 fitted gains mean % | covered |")
    print("|---|---|---|---|---|---|---|")
    for label in (*TWINS, TRUE_WORLD):
        for flight in flown:
            scores = results[flight.label][label]
            mean, median = summary(scores["error"])
            print(f"| {label} | {flight.label} | {len(scores['error'])} | {mean:.2f} | {median:.2f} | "
                  f"{summary(scores['fitted'])[0]:.2f} | {100 * np.mean(scores['covered']):.1f} % |")


def print_differences(results: dict, own: str, other: str) -> None:
    """Per twin, the later flight's formula 3 less its own flight's, and whether the mean is within 1 point."""
    print(f"| twin | {other} - {own}: mean | median | fitted gains mean | within 1 point |")
    print("|---|---|---|---|---|")
    for label in (*TWINS, TRUE_WORLD):
        deltas = [np.subtract(summary(results[other][label][key]), summary(results[own][label][key]))
                  for key in ("error", "fitted")]
        print(f"| {label} | {deltas[0][0]:+.2f} | {deltas[0][1]:+.2f} | {deltas[1][0]:+.2f} | "
              f"{'yes' if abs(deltas[0][0]) <= 1.0 else 'no'} |")


def print_light(results: dict, own: str, other: str) -> None:
    """Per twin, how it carries the light at the later flight (:func:`light_scores`)."""
    print(f"| twin at {other} | ghost ratio | ghost px | f3 lit by both suns % | f3 as captured vs {own} sun % |")
    print("|---|---|---|---|---|")
    for label in TWINS:
        light = results[other][label]["light"]
        print(f"| {label} | {light['ghost_ratio']:.3f} | {light['ghost_pixels']} | {light['error_lit']:.2f} | "
              f"{light['error_unlit_at_capture']:.2f} |")


def print_stages(stages: list[StageResult]) -> None:
    """Each stage's wall time (a resumed stage: the time it took when it ran)."""
    print("| stage | status | s |\n|---|---|---|")
    for stage in stages:
        print(f"| {stage.name} | {stage.status} | {stage.wall_s:.1f} |")
    print(f"| total | | {sum(stage.wall_s for stage in stages):.1f} |")


def print_tables(results: dict, flown: list[Flight], stages: list[StageResult]) -> None:
    """Every table, in Markdown on stdout."""
    own, other = (flight.label for flight in flown)
    for table in (lambda: print_scores(results, flown), lambda: print_differences(results, own, other),
                  lambda: print_light(results, own, other), lambda: print_stages(stages)):
        table()
        print()


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--work", required=True, type=Path, help="scratch folder, resumed on a rerun")
    parser.add_argument("--quick", action="store_true",
                        help="the closed loop's reduced settings: demo:small, 3-waypoint arc, 480x360 photos")
    parser.add_argument("--photo-interval", type=float,
                        help=f"seconds between photos (default {DEFAULT_INTERVAL_S:g}; --quick: 1)")
    parser.add_argument("--seed", type=int, default=0, help="the first flight's seed; the second takes the next")
    parser.add_argument("--json", type=Path, help="write every photo's scores and the stage times here")
    return parser.parse_args(argv)


def loop_config(args: argparse.Namespace) -> LoopConfig:
    """The closed loop's settings (its quick ones with ``--quick``), with this bench's photo interval."""
    config = LoopConfig.quick() if args.quick else LoopConfig(photo_interval_s=DEFAULT_INTERVAL_S)
    if args.photo_interval is not None:
        config.photo_interval_s = args.photo_interval
    return config


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    config = loop_config(args)
    world = world_folder(config.scene)
    origin = read_scene_json(world)["origin_frame"]
    flown = flights(args.work, origin, args.seed)
    try:
        check_suns(flown, origin)
    except ValueError as error:
        print(f"bench_two_times: error: {error}", file=sys.stderr)
        return 2
    stages = Stages(args.work)
    try:
        scenes = fly_and_reconstruct(config, stages, world, flown)
    except RuntimeError as error:
        print(f"bench_two_times: {error}", file=sys.stderr)
        return 1
    results = measure(stages, world, scenes, flown)
    print_tables(results, flown, stages.results)
    if args.json:
        write_text_atomic(args.json, json.dumps({"flights": {f.label: utc_text(f.start_utc) for f in flown},
                                                 "scores": results,
                                                 "stages": {s.name: s.wall_s for s in stages.results}}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
