"""The closed loop over an area: field polygon -> plan -> fly every flight -> geotag -> recon area -> dataset,
every stage measured against the virtual drone's truth (issue 21).

Every stage runs the project's command line in a child process (:func:`tools.loops.closed_loop.run`: wall time and
the child's own peak RSS):

1. field: a GeoJSON polygon, by default the true world's ``valid_area_m`` rectangle less ``--field-inset`` metres
   (demo:large, 480 x 324 m, less 3 m: 474 x 318 m = 150,732 m^2, the paper's size); or ``--field FILE``;
2. ``aerostereo-mission --area FIELD --out plan`` (``--interval`` thins the photos, default 20 s);
3. ``aerostereo-render fly --mission plan/flight_01.csv ... --home TAKE_OFF`` flies every flight from the plan's
   take-off point (telemetry to a file, each flight its own GPS fix bias) into ``fly/flight_XX/``;
4. ``aerostereo-ingest geotag`` per flight into ``fly/flight_XX/geotags.csv``;
5. ``aerostereo-recon area fly/flight_XX ... --out area`` (recon options passed through; ``--scheduler``);
   with ``--workers-sweep local:1,local:2`` the same again per scheduler into ``recon_sweep/`` for its cost;
   with ``--fuller-flight F`` flight F is flown and reconstructed again with denser photos into ``fuller/``
   (what the thinning costs);
6. ``aerostereo-render --scene area --frames N`` renders the dataset at random poses from the merged twin;
7. the evaluation (:mod:`tools.loops.area_eval`) writes ``report.json`` and ``report.md`` and prints the tables.

A stage whose output exists is skipped (listed as such), so a rerun after a failure continues where it stopped;
``--reevaluate`` only evaluates the run in ``--out`` again.

    python tools/loops/area_loop.py --out area_run                      # demo:large, 150,732 m^2, 1000 frames
    python tools/loops/area_loop.py --out area_run --reevaluate         # score a finished run again
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from flightplan import litchi  # noqa: E402
from cliutil.atomic import write_text_atomic  # noqa: E402
from sim.render.scene import SceneError, read_scene_json  # noqa: E402
from tools.loops.area_eval import SEAM_DISTANCE_M, evaluate_area, write_report  # noqa: E402
from tools.loops.closed_loop import StageResult, cli, finished_report, run, skipped, world_folder  # noqa: E402


#: Stage statuses that let the next stage run: it ran now, or its output was there from an earlier run.
DONE = ("ok", "exists")


@dataclass
class AreaConfig:
    """Every knob of one area run (options of the stages)."""

    scene: str = "demo:large"
    field: str | None = None              # GeoJSON/KML field; None: the world's rectangle less field_inset_m
    field_inset_m: float = 3.0
    interval_s: float = 20.0
    photo_size: tuple[int, int] = (960, 720)
    noise: str | None = None              # None: the fly command's default (area: a GPS fix bias per flight)
    start_utc: str = "2026-06-01T09:00:00Z"
    seed: int = 0
    image_size: int | None = None         # recon --image-size (None: recon's default)
    dense_size: int | None = None
    workers: int | None = None
    scheduler: str | None = None
    recon_args: list[str] = dataclasses.field(default_factory=list)
    workers_sweep: list[str] = dataclasses.field(default_factory=list)
    fuller_flight: str | None = None      # e.g. flight_01: fly and reconstruct it again with denser photos
    fuller_interval_s: float = 2.0
    frames: int = 1000
    size: tuple[int, int] = (640, 360)
    fov_deg: float = 80.0
    oblique_views: int = 50
    surface_samples: int = 20000
    seam_m: float = SEAM_DISTANCE_M


def world_rectangle_field(world: Path, inset_m: float) -> tuple[dict, float]:
    """GeoJSON polygon (WGS84 lon/lat) of the world's ``valid_area_m`` rectangle less ``inset_m`` on every side,
    and its area (m^2, ENU)."""
    meta = read_scene_json(world)
    box = meta["valid_area_m"]
    x0, x1, y0, y1 = box["xmin"] + inset_m, box["xmax"] - inset_m, box["ymin"] + inset_m, box["ymax"] - inset_m
    if x1 <= x0 or y1 <= y0:
        raise ValueError(f"--field-inset {inset_m}: leaves nothing of the world's {box} rectangle")
    east, north = np.array([x0, x1, x1, x0, x0]), np.array([y0, y0, y1, y1, y0])
    lat, lon, _ = meta["origin_frame"].to_geodetic(east, north, np.zeros(5))
    polygon = {"type": "Feature", "properties": {"name": f"{world.name} less {inset_m:g} m"},
               "geometry": {"type": "Polygon", "coordinates": [[[float(a), float(b)] for a, b in zip(lon, lat)]]}}
    return polygon, (x1 - x0) * (y1 - y0)


def field_stage(config: AreaConfig, world: Path, out: Path) -> tuple[StageResult, Path]:
    """The field polygon: ``--field`` as given, else the world's rectangle written to ``out/field.geojson``."""
    if config.field:
        return StageResult("field", "ok", detail=f"{config.field} (given)"), Path(config.field)
    path = out / "field.geojson"
    t0 = time.perf_counter()
    polygon, area_m2 = world_rectangle_field(world, config.field_inset_m)
    write_text_atomic(path, json.dumps(polygon) + "\n")
    return StageResult("field", "ok", time.perf_counter() - t0, None, [],
                       f"{area_m2:,.0f} m2: the world's rectangle less {config.field_inset_m:g} m"), path


def done(name: str, output: Path) -> StageResult:
    """A stage skipped because its output exists (a rerun continues)."""
    return StageResult(name, "exists", detail=f"{output} exists (earlier run)")


def combined(name: str, results: list[StageResult]) -> StageResult:
    """One row for a stage run once per flight: summed wall time, the largest peak RSS, the failures."""
    failed = [r for r in results if r.status not in DONE]
    ran = [r for r in results if r.status == "ok"]
    rss = [r.max_rss_mib for r in results if r.max_rss_mib is not None]
    detail = "; ".join(r.detail for r in failed) or f"{len(ran)} run, {len(results) - len(ran)} already done"
    status = "failed" if failed else "ok" if ran else "exists"
    return StageResult(name, status, sum(r.wall_s for r in results), max(rss, default=None),
                       [], detail)


def fly_stage(config: AreaConfig, world: Path, plan: Path, fly: Path, log_dir: Path) -> StageResult:
    """``aerostereo-render fly`` of every mission of the plan into ``fly/<mission name>/`` (several missions: one
    folder per mission under ``--out``; one: ``--out`` is that flight's folder), taking off from the plan's
    ``take_off`` (the pilot's place: under an edge orbit's first waypoint there may be no ground); skipped when
    every flight has its truth, else flown anew over what an interrupted run left (``--overwrite``)."""
    missions = sorted(plan.glob("flight_*.csv"))
    flights = [fly / m.stem for m in missions]
    if flights and all((f / "truth.json").is_file() for f in flights):
        return done("fly", fly)
    take_off = json.loads((plan / "area.json").read_text(encoding="utf-8"))["take_off"]
    noise = ["--noise", config.noise] if config.noise else []
    return run("fly", cli("aerostereo-render fly") + [arg for m in missions for arg in ("--mission", str(m))] + [
        "--scene", str(world), "--out", str(flights[0] if len(flights) == 1 else fly),
        "--home", f"{take_off['lat_deg']:.9f}", f"{take_off['lon_deg']:.9f}",
        "--photo-size", *map(str, config.photo_size), "--start-utc", config.start_utc, "--seed", str(config.seed),
        "--overwrite", *noise], log_dir)


def geotag_stage(flights: list[Path], log_dir: Path) -> StageResult:
    """``aerostereo-ingest geotag`` of each flight folder not yet geotagged, as one row (:func:`combined`)."""
    return combined("geotag", [
        done("geotag", f / "geotags.csv") if (f / "geotags.csv").is_file() else run(
            f"geotag_{f.name}", cli("aerostereo-ingest") + [
                "geotag", "--photos", str(f / "photos"), "--log", str(f / "flight.duml"),
                "--out", str(f / "geotags.csv")], log_dir)
        for f in flights])


def denser_mission(mission_csv: Path, interval_s: float, out_csv: Path) -> None:
    """The same route with a photo every ``interval_s`` seconds where the mission takes timed photos."""
    mission = litchi.read_mission_csv(mission_csv)
    litchi.write_mission_csv(litchi.Mission(tuple(
        dataclasses.replace(w, photo_time_interval_s=interval_s) if w.photo_time_interval_s > 0 else w
        for w in mission.waypoints)), out_csv)


def fuller_stages(config: AreaConfig, world: Path, plan: Path, fuller: Path, log_dir: Path) -> list[StageResult]:
    """``--fuller-flight F``: flight F's mission with a photo every ``--fuller-interval`` s, flown from the same
    take-off (same seed and noise, so the same wind and imperfections draws where they do not depend on the photo
    count), geotagged and reconstructed on its own into ``fuller/``: what the area run's thinning costs."""
    name, flight = config.fuller_flight, fuller / config.fuller_flight
    mission = fuller / f"{name}.csv"
    if not (plan / f"{name}.csv").is_file():
        return [StageResult("fuller", "failed", detail=f"--fuller-flight {name}: no {plan / name}.csv in the plan")]
    fuller.mkdir(exist_ok=True)
    denser_mission(plan / f"{name}.csv", config.fuller_interval_s, mission)
    take_off = json.loads((plan / "area.json").read_text(encoding="utf-8"))["take_off"]
    noise = ["--noise", config.noise or "area"]
    stages = [done("fuller_fly", flight / "truth.json") if (flight / "truth.json").is_file() else run(
        "fuller_fly", cli("aerostereo-render fly") + [
            "--mission", str(mission), "--scene", str(world), "--out", str(flight),
            "--home", f"{take_off['lat_deg']:.9f}", f"{take_off['lon_deg']:.9f}",
            "--photo-size", *map(str, config.photo_size), "--start-utc", config.start_utc, "--seed",
            str(config.seed), "--overwrite", *noise], log_dir)]
    stages.append(geotag_stage([flight], log_dir) if stages[-1].status in DONE else skipped("fuller_geotag", "fly"))
    stages[-1].name = "fuller_geotag"
    recon_dir = fuller / f"recon_{name}"
    if stages[-1].status not in DONE:
        stages.append(skipped("fuller_recon", "fuller_geotag"))
    elif (recon_dir / "scene.json").is_file():
        stages.append(done("fuller_recon", recon_dir))
    else:
        stages.append(run("fuller_recon", cli("aerostereo-recon") + [
            "--photos", str(flight / "photos"), "--geotags", str(flight / "geotags.csv"), "--out", str(recon_dir),
            *recon_options(config)], log_dir))
    return stages


def recon_options(config: AreaConfig) -> list[str]:
    """The options passed through to ``aerostereo-recon area`` (no ``--scheduler``)."""
    options = []
    for flag, value in (("--image-size", config.image_size), ("--dense-size", config.dense_size),
                        ("--workers", config.workers)):
        if value is not None:
            options += [flag, str(value)]
    return options + list(config.recon_args)


def run_area_loop(config: AreaConfig, out: Path) -> dict:
    """Run (or continue) every stage into ``out`` and evaluate; returns the report (report.json/.md)."""
    out.mkdir(parents=True, exist_ok=True)
    log_dir = out / "logs"
    log_dir.mkdir(exist_ok=True)
    world = world_folder(config.scene)
    stages: list[StageResult] = []
    ok: set[str] = set()

    def add(result: StageResult) -> None:
        stages.append(result)
        if result.status in DONE:
            ok.add(result.name)

    result, field_path = field_stage(config, world, out)
    add(result)
    plan, fly, area = out / "plan", out / "fly", out / "area"
    add(done("plan", plan / "area.json") if (plan / "area.json").is_file() else run(
        "plan", cli("aerostereo-mission") + ["--area", str(field_path), "--out", str(plan), "--interval",
                                             str(config.interval_s)], log_dir))
    flights = [fly / m.stem for m in sorted(plan.glob("flight_*.csv"))]
    add(fly_stage(config, world, plan, fly, log_dir) if "plan" in ok else skipped("fly", "plan"))
    add(geotag_stage(flights, log_dir) if "fly" in ok else skipped("geotag", "fly"))

    def recon(name: str, target: Path, scheduler: str | None) -> StageResult:
        if (target / "area_report.json").is_file():
            return done(name, target / "area_report.json")
        return run(name, cli("aerostereo-recon") + ["area", *map(str, flights), "--out", str(target),
                                                   *recon_options(config),
                                                   *(["--scheduler", scheduler] if scheduler else [])], log_dir)

    add(recon("recon", area, config.scheduler) if "geotag" in ok else skipped("recon", "geotag"))
    if config.fuller_flight:
        for stage in (fuller_stages(config, world, plan, out / "fuller", log_dir) if "plan" in ok
                      else [skipped("fuller", "plan")]):
            add(stage)
    for scheduler in config.workers_sweep:
        safe = "".join(c if c.isalnum() else "_" for c in scheduler)  # a file name for the folder and the log
        label = f"recon_{safe}"
        add(recon(label, out / "recon_sweep" / safe, scheduler) if "geotag" in ok
            else skipped(label, "geotag"))
    dataset = out / "dataset"
    if "recon" not in ok:
        add(skipped("render", "recon"))
    elif (dataset / "sequences" / "00" / "frames.jsonl").is_file():
        add(done("render", dataset))
    else:
        add(run("render", cli("aerostereo-render") + [
            "--scene", str(area), "--out", str(dataset), "--frames", str(config.frames), "--width",
            str(config.size[0]), "--height", str(config.size[1]), "--fov", str(config.fov_deg), "--seed",
            str(config.seed), "--quiet"], log_dir))
    return evaluate_run(dataclasses.asdict(config), [dataclasses.asdict(s) for s in stages], world, out)


def evaluate_run(config: dict, stages: list[dict], world: Path, out: Path) -> dict:
    """Evaluate the stage outputs in ``out`` (layout of :func:`run_area_loop`) and write the report."""
    t0 = time.perf_counter()
    flights = {path.name: path for path in sorted((out / "fly").glob("flight_*")) if path.is_dir()}
    report = evaluate_area(config=config, stages=stages, world=world, fly_dirs=flights, area_dir=out / "area",
                           dataset_dir=out / "dataset", fuller_dir=out / "fuller")
    report["evaluation_s"] = time.perf_counter() - t0
    write_report(report, out)
    return report


def reevaluate(out: Path) -> dict:
    """Evaluate a finished run folder again (its ``report.json`` gives the stages and settings)."""
    previous = json.loads(finished_report(out).read_text(encoding="utf-8"))
    return evaluate_run(previous["config"], previous["stages"], world_folder(previous["config"]["scene"]), out)


def schedulers(text: str) -> list[str]:
    """``--workers-sweep local:1,local:2``: the schedulers to measure recon's cost with."""
    values = [value for value in text.split(",") if value]
    if not values:
        raise argparse.ArgumentTypeError("expected SCHEDULER[,SCHEDULER...], e.g. local:1,local:2")
    return values


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    defaults = AreaConfig()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    add = parser.add_argument
    add("--out", required=True, type=Path, help="run folder (stages, report.md, report.json); a rerun continues")
    add("--scene", default=defaults.scene, help="the true world: scene folder, or demo / demo:small / demo:large")
    add("--field", help="field polygon (.geojson/.kml); default: the world's rectangle less --field-inset")
    add("--field-inset", type=float, default=defaults.field_inset_m, dest="field_inset_m", metavar="M")
    add("--interval", type=float, default=defaults.interval_s, dest="interval_s", metavar="S",
        help="seconds between photos (thins the photos)")
    add("--photo-size", nargs=2, type=int, default=defaults.photo_size, metavar=("W", "H"))
    add("--noise", help="fly --noise (default: the fly command's, a GPS fix bias per flight)")
    add("--start-utc", default=defaults.start_utc, help="fly --start-utc (the sun)")
    add("--seed", type=int, default=defaults.seed)
    add("--image-size", type=int, help="recon --image-size (default: recon's)")
    add("--dense-size", type=int, help="recon --dense-size (default: recon's)")
    add("--workers", type=int, help="recon --workers (default: recon's)")
    add("--scheduler", help="recon --scheduler local:N or tcp://HOST:PORT")
    add("--recon-args", type=shlex.split, default=[], help="more recon options, one quoted string")
    add("--workers-sweep", type=schedulers, default=[], metavar="S1,S2",
        help="also run recon area once per scheduler (e.g. local:1,local:2) for its cost")
    add("--fuller-flight", metavar="FLIGHT", help="also fly and reconstruct this flight (e.g. flight_01) with a "
        "photo every --fuller-interval s, to measure what the thinning costs")
    add("--fuller-interval", type=float, default=defaults.fuller_interval_s, dest="fuller_interval_s", metavar="S")
    add("--frames", type=int, default=defaults.frames, help="dataset frames at random poses")
    add("--size", nargs=2, type=int, default=defaults.size, metavar=("W", "H"),
        help="dataset and oblique image size")
    add("--fov", type=float, default=defaults.fov_deg, dest="fov_deg", help="horizontal field of view, deg")
    add("--oblique-views", type=int, default=defaults.oblique_views, help="random poses of the twin-vs-truth score")
    add("--surface-samples", type=int, default=defaults.surface_samples, help="points drawn on the twin's surface")
    add("--seam", type=float, default=defaults.seam_m, dest="seam_m", metavar="M",
        help="surface points within M metres of a seam count as seam")
    add("--reevaluate", action="store_true", help="only evaluate the run in --out again")
    return parser.parse_args(argv)


def config_from_args(args: argparse.Namespace) -> AreaConfig:
    names = {f.name for f in dataclasses.fields(AreaConfig)}
    config = AreaConfig(**{k: v for k, v in vars(args).items() if k in names})
    config.photo_size, config.size = tuple(config.photo_size), tuple(config.size)
    return config


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        config = config_from_args(args)
        read_scene_json(world_folder(config.scene))
        report = reevaluate(args.out) if args.reevaluate else run_area_loop(config, args.out)
    except (ValueError, SceneError) as error:
        print(f"area_loop: error: {error}", file=sys.stderr)
        return 2
    print((args.out / "report.md").read_text(encoding="utf-8"))
    return 0 if report["complete"] else 1


if __name__ == "__main__":
    sys.exit(main())
