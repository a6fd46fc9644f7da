"""The closed loop: plan -> fly (virtual drone) -> record -> geotag -> reconstruct -> render, measured against truth.

Every stage runs the project's real command line in a child process (see :func:`cli`), so its wall time and
peak memory (the child's own max RSS from ``os.wait4``) are measured per stage:

1. ``aerostereo-mission`` plans the default orbit around the world's origin; ``--arc N`` keeps its first N
   waypoints (a short arc for quick runs).
2. ``aerostereo-render fly`` flies it with realistic noise. ``--link tcp`` (default): the drone streams DUML to
   a local TCP relay (``socket://``) that forwards it to ``aerostereo-ingest record`` in another process --
   pyserial's ``loop://`` is one object inside one process, so two processes need a socket. The recorder
   stamps arrivals with the host clock, so this link runs in real time. ``--link loop`` (quick runs): the fly
   command streams through a pyserial ``loop://`` port into the recorder's code path inside its own process,
   on the flight clock, so it may run ``--speedup`` times faster than real time.
3. ``aerostereo-ingest geotag`` geotags the photos from the recorded capture.
4. ``aerostereo-recon`` reconstructs the scene from photos + geotags.
5. ``aerostereo-render --mode replay --geotags`` renders the photos' stereo poses twice: from the
   reconstruction (the twin) and from the true world; and ``aerostereo-render --mode replay`` renders the twin at
   its own cameras (what a user renders from it), beside the true world at the true cameras: the twin apart
   from its georeference error.
6. The evaluation (in this process) writes ``report.json``, ``report.md`` and plots into ``--out``.

A stage that fails or whose inputs are missing is reported as failed/skipped with the reason, and the metrics
that need it say "not measured" -- never a silent gap. ``--sweep KNOB=v1,v2`` reruns the loop per value and
prints time against error.

    python tools/loops/closed_loop.py --out closed_loop                   # demo world, whole orbit (real time)
    python tools/loops/closed_loop.py --out cl_quick --quick              # small world, short arc, low resolution
    python tools/loops/closed_loop.py --out cl_sweep --quick --sweep sfm_image_size=400,800
    python tools/loops/closed_loop.py --out cl_quick --reevaluate        # evaluate a finished run again
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from flightplan import litchi  # noqa: E402
from cliutil.atomic import write_text_atomic  # noqa: E402
from flightplan.geodesy import LocalFrame  # noqa: E402
from sim.render.scene import SceneError, read_scene_json  # noqa: E402
from sim.sampling.light import parse_sun  # noqa: E402
from tools.loops.closed_loop_eval import evaluate, sweep_table, write_report  # noqa: E402
from tools.geotag_csv import geotag_row, write_geotags  # noqa: E402


def recon_options(config: LoopConfig) -> list[str]:
    """aerostereo-recon's size, mesh and worker options for ``config``; a size left None is recon's own default."""
    options = ["--image-size", str(config.sfm_image_size), "--mesh", config.mesh, "--workers", str(config.workers)]
    for flag, value in (("--dense-size", config.dense_size), ("--grid", config.grid_m),
                        ("--decimate-error", config.decimate_error_m)):
        if value is not None:
            options += [flag, str(value)]
    return options


def capture_sun_option(sun: str) -> list[str]:
    """recon's ``--capture-sun AZ,EL`` for fly's fixed ``--sun AZ,EL,STRENGTH`` (the photos' sun is not the one of the
    geotags' UTC times: the live link runs on the host clock); nothing for the other forms (recon times the photos)."""
    setting = parse_sun(sun)
    return ["--capture-sun", f"{setting.azimuth_deg:g},{setting.elevation_deg:g}"] if setting.form == "fixed" else []


def cli(script: str) -> list[str]:
    """The command line that runs ``script``: its module run with this Python, so the loop works whether or not
    the console scripts are on PATH."""
    python = sys.executable
    return {
        "aerostereo-mission": [python, "-m", "flightplan"],
        "aerostereo-ingest": [python, "-m", "capture"],
        "aerostereo-recon": [python, "-m", "recon"],
        "aerostereo-render fly": [python, "-m", "sim", "fly"],
        "aerostereo-render": [python, "-m", "sim"],
    }[script]


@dataclass
class LoopConfig:
    """Every knob of one closed-loop run (CLI options of the stages)."""

    scene: str = "demo"                  # "demo", "demo:small" or a scene folder
    radius_m: float = 50.0
    height_m: float = 30.0
    photo_interval_s: float = 1.0
    arc_waypoints: int = 0               # 0: the whole orbit
    photo_size: tuple[int, int] = (800, 600)
    noise: str = "realistic"
    # fly --sun: the tcp link runs on the host clock (fly gets --start-utc now: the recorder in the other process stamps
    # that clock), so the photos take a fixed sun rather than the real one of the hour the loop happens to run at (none
    # at night); the sun they had before it existed.
    sun: str = "150,50,10"
    link: str = "tcp"
    speedup: float = 1.0
    seed: int = 0
    sfm_image_size: int = 800
    dense_size: int | None = None        # None: recon's default, as a user gets it (depth maps at the photo size)
    mesh: str = "3d"
    grid_m: float | None = None
    decimate_error_m: float | None = None
    spp: int = 1
    render_size: tuple[int, int] | None = None   # None: the photo size
    workers: int = 2
    surface_samples: int = 20000

    @classmethod
    def quick(cls) -> "LoopConfig":
        """The reduced loop of the CI test: small world, a short arc, low resolution, 10x faster flight."""
        return cls(scene="demo:small", arc_waypoints=3, photo_size=(480, 360), link="loop", speedup=10.0,
                   sfm_image_size=480, dense_size=320, spp=1, surface_samples=8000)


class Knob(NamedTuple):
    """A sweep knob: the :class:`LoopConfig` field it sets, its value parser, the allowed values (None: any) and
    what it is (the option's help)."""

    field: str
    parse: Callable[[str], object]
    choices: tuple[str, ...] | None
    what: str


#: Sweep knobs by name (also one ``--NAME`` option each). ``noise`` is the fly command's ``--noise``: it switches
#: ALL the flight's imperfections (GPS, barometer, attitude, gimbal, wind, camera clock offset), not the GPS alone.
KNOBS = {
    "noise": Knob("noise", str, ("realistic", "none"),
                  "flight imperfections, all together (GPS, baro, attitude, gimbal, wind, clock offset)"),
    "photo_interval": Knob("photo_interval_s", float, None, "seconds between photos"),
    "sfm_image_size": Knob("sfm_image_size", int, None, "recon --image-size, px"),
    "dense_size": Knob("dense_size", int, None, "recon --dense-size, px"),
    "mesh": Knob("mesh", str, ("3d", "2.5d", "poisson"), "recon --mesh"),
    "decimate_error": Knob("decimate_error_m", float, None, "recon --decimate-error, m"),
    "grid": Knob("grid_m", float, None, "recon --grid, m"),
    "spp": Knob("spp", int, None, "render samples per pixel"),
}


@dataclass
class StageResult:
    """One stage: ``status`` ok / failed / skipped, wall time (s), the child's peak RSS (MiB), the command, and
    why it failed or was skipped."""

    name: str
    status: str
    wall_s: float = 0.0
    max_rss_mib: float | None = None
    command: list[str] = field(default_factory=list)
    detail: str = ""


def child_env() -> dict:
    """Environment of the stages: this checkout first on the import path, one BLAS thread per process."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def _log_tail(log: Path, lines: int = 3) -> str:
    text = log.read_text(encoding="utf-8", errors="replace").strip().splitlines() if log.exists() else []
    return " | ".join(line.strip() for line in text[-lines:])


def start(name: str, argv: list[str], log_dir: Path) -> tuple[subprocess.Popen, float, Path]:
    """Start a stage's child process with its output in ``log_dir/NAME.log``."""
    log = log_dir / f"{name}.log"
    with log.open("wb") as handle:
        process = subprocess.Popen(argv, stdout=handle, stderr=subprocess.STDOUT, env=child_env())
    return process, time.perf_counter(), log


def finish(name: str, started: tuple[subprocess.Popen, float, Path], timeout_s: float | None = None) -> StageResult:
    """Wait for a started stage (killed after ``timeout_s``); its own peak RSS comes from ``os.wait4``
    (ru_maxrss, KiB on Linux)."""
    process, t0, log = started
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    pid, status, usage = os.wait4(process.pid, os.WNOHANG)
    while pid == 0 and (deadline is None or time.monotonic() < deadline):
        time.sleep(0.05)
        pid, status, usage = os.wait4(process.pid, os.WNOHANG)
    if pid == 0:
        process.kill()
        _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    ok = process.returncode == 0
    why = f"killed after {timeout_s} s" if pid == 0 else f"exit code {process.returncode}"
    return StageResult(name, "ok" if ok else "failed", wall, usage.ru_maxrss / 1024.0, list(map(str, process.args)),
                       "" if ok else f"{why}: {_log_tail(log)} (log: {log})")


def run(name: str, argv: list[str], log_dir: Path) -> StageResult:
    return finish(name, start(name, argv, log_dir))


class Relay:
    """A local TCP listener joining two pyserial ``socket://`` clients: the first to connect (the recorder)
    receives every byte the second (the drone) sends, until the drone closes."""

    def __init__(self) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self.server.getsockname()[1]}"
        self.recorder_connected = threading.Event()
        self.drone_closed = threading.Event()
        self.forwarded = 0
        self._recorder: socket.socket | None = None
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        self._recorder, _ = self.server.accept()
        self.recorder_connected.set()
        drone, _ = self.server.accept()
        with drone:
            while data := drone.recv(65536):
                self._recorder.sendall(data)
                self.forwarded += len(data)
        self.drone_closed.set()

    def close(self) -> None:
        if self._recorder is not None:
            self._recorder.close()
        self.server.close()


def fly_over_tcp(fly_args: list[str], capture: Path, log_dir: Path) -> list[StageResult]:
    """``aerostereo-ingest record`` and ``aerostereo-render fly --link tcp`` in two processes through a
    :class:`Relay`; the recorder is stopped with Ctrl-C (SIGINT) once every byte sent is on its disk."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        # a background job starts with SIGINT ignored and its children inherit that, so the recorder could not be
        # stopped with Ctrl-C; a handler here resets to the default in the children (exec keeps only "ignored")
        signal.signal(signal.SIGINT, signal.default_int_handler)
    relay = Relay()
    try:
        recorder = start("record", cli("aerostereo-ingest") + ["record", "--port", relay.url, "--out", str(capture)],
                         log_dir)
        if not relay.recorder_connected.wait(60):
            never = StageResult("fly", "skipped", detail="not run: the recorder never connected to the relay")
            return [never, finish("record", recorder, timeout_s=0)]
        # the recorder stamps this machine's clock: the flight must start "now", not at fly's fixed default
        drone = run("fly", fly_args + ["--link", "tcp", "--port", relay.url, "--start-utc", "now"], log_dir)
        relay.drone_closed.wait(30 if drone.status == "ok" else 1)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and (not capture.exists() or capture.stat().st_size < relay.forwarded):
            time.sleep(0.05)
        recorder[0].send_signal(signal.SIGINT)
        recorded = finish("record", recorder, timeout_s=30)
        size = capture.stat().st_size if capture.exists() else 0
        recorded.detail = (f"{size} of {relay.forwarded} bytes streamed over {relay.url}" if recorded.status == "ok"
                           else recorded.detail)
        if recorded.status == "ok" and size != relay.forwarded:
            recorded.status = "failed"
        return [drone, recorded]
    finally:
        relay.close()


def plan_mission(config: LoopConfig, centre: LocalFrame, out: Path, log_dir: Path) -> StageResult:
    """Plan the orbit around ``centre``; with ``arc_waypoints`` keep the first N waypoints (a short arc)."""
    full = out / "mission_full.csv"
    result = run("plan", cli("aerostereo-mission") + [
        "--lat", f"{centre.lat0_deg:.9f}", "--lon", f"{centre.lon0_deg:.9f}", "--radius", str(config.radius_m),
        "--height", str(config.height_m), "--interval", str(config.photo_interval_s), "--out", str(full),
        "--summary-json", str(out / "mission_summary.json")], log_dir)
    if result.status == "ok":
        mission = litchi.read_mission_csv(full)
        rows = mission.waypoints
        if config.arc_waypoints:
            rows = rows[:config.arc_waypoints]
            rows = rows[:-1] + (dataclasses.replace(rows[-1], curve_size_m=litchi.MIN_CURVE_M),)
        litchi.write_mission_csv(litchi.Mission(rows), out / "mission.csv")
        result.detail = f"{len(rows)} of {len(mission.waypoints)} waypoints"
    return result


def world_folder(scene: str) -> Path:
    """The scene folder of ``--scene`` (the demo world is built once into the cache)."""
    from sim.run.render_dataset import resolve_scene_dir
    return resolve_scene_dir(scene)


def photo_hfov_deg(truth_json: Path) -> float:
    """Horizontal field of view (deg) of the drone's photo camera, from ``truth.json``'s camera matrix."""
    truth = json.loads(truth_json.read_text(encoding="utf-8"))
    return math.degrees(2 * math.atan(truth["photo_size_px"][0] / 2 / truth["camera_K"][0][0]))


def photo_lens_options(truth_json: Path) -> list[str]:
    """``aerostereo-render`` options that give its views the drone camera's lens distortion (from ``truth.json``),
    so that renders compare with the photos pixel for pixel; with distortion, depth only (disparity needs
    rectified images). The principal point's offset (a few pixels) is not passed: the renderer has no option."""
    camera = json.loads(truth_json.read_text(encoding="utf-8")).get("camera", {})
    distortion = camera.get("distortion", [0.0] * 5)
    if not any(distortion):
        return []
    return ["--distortion=" + ",".join(f"{k:.12g}" for k in distortion), "--formats", "depth_exr"]  # "=": k1 < 0


def skipped(name: str, needs: str) -> StageResult:
    return StageResult(name, "skipped", detail=f"not run: {needs} did not succeed")


def refuse_non_empty(out: Path) -> None:
    """ValueError saying what to do when ``out`` already holds a run (a second run would mix with it)."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: not empty (an earlier run?); remove it (rm -r {out}), give another --out, or "
                         f"add --reevaluate to evaluate that run again")


def run_loop(config: LoopConfig, out: Path) -> dict:
    """Run every stage into ``out`` (new or empty: the recorder appends to a capture and recon resumes, so a
    second run into the same folder would mix runs) and evaluate; returns the report (report.json/.md)."""
    refuse_non_empty(out)
    out.mkdir(parents=True, exist_ok=True)
    log_dir = out / "logs"
    log_dir.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    world = world_folder(config.scene)
    world_origin = read_scene_json(world)["origin_frame"]
    stages = [StageResult("world", "ok", time.perf_counter() - t0, None, [], f"{world} (in-process, cached)")]
    ok = {s.name for s in stages}

    def add(*results: StageResult) -> None:
        stages.extend(results)
        ok.update(r.name for r in results if r.status == "ok")

    mission_dir, fly_dir, record_dir = out / "mission", out / "fly", out / "record"
    for folder in (mission_dir, record_dir, out / "geotag"):
        folder.mkdir(exist_ok=True)
    add(plan_mission(config, world_origin, mission_dir, log_dir))
    fly_args = cli("aerostereo-render fly") + [
        "--mission", str(mission_dir / "mission.csv"), "--scene", str(world), "--out", str(fly_dir),
        "--photo-size", *map(str, config.photo_size), "--noise", config.noise, "--seed", str(config.seed),
        "--sun", config.sun]
    if "plan" not in ok:
        add(skipped("fly", "plan"), skipped("record", "plan"))
        capture = None
    elif config.link == "tcp":
        capture = record_dir / "received.duml"
        add(*fly_over_tcp(fly_args, capture, log_dir))
    else:
        capture = fly_dir / "flight.duml"
        flown = run("fly", fly_args + ["--link", "loop", "--speedup", str(config.speedup)], log_dir)
        add(flown, StageResult("record", flown.status,
                        detail="--link loop: recorded inside the fly process (pyserial loop:// into the "
                               "recorder's code path, time and memory counted in fly), not by the "
                               "aerostereo-ingest record command"))
    geotags = out / "geotag" / "geotags.csv"
    if {"fly", "record"} <= ok:
        add(run("geotag", cli("aerostereo-ingest") + ["geotag", "--photos", str(fly_dir / "photos"), "--log",
                                                     str(capture), "--out", str(geotags)], log_dir))
    else:
        add(skipped("geotag", "fly/record"))
    recon_dir = out / "recon"
    if "geotag" in ok:
        add(run("recon", cli("aerostereo-recon") + ["--photos", str(fly_dir / "photos"), "--geotags", str(geotags),
                                                   "--out", str(recon_dir), *recon_options(config),
                                                   *capture_sun_option(config.sun)], log_dir))
    else:
        add(skipped("recon", "geotag"))
    # the twin and the true world at the geotags; the twin at its own cameras and the true world (its depth: unlit)
    # at the true ones
    true_cameras = out / "render" / "true_cameras" / "geotags.csv"
    renders = {"twin": (recon_dir, geotags, {"geotag", "recon"}, []), "true": (world, geotags, {"geotag"}, []),
               "twin_own": (recon_dir, None, {"recon"}, []),
               "true_own": (world, true_cameras, {"fly"}, ["--sun", "unlit"])}
    for label, (scene, poses, needs, extra) in renders.items():
        if not needs <= ok:
            add(skipped(f"render_{label}", " and ".join(sorted(needs - ok))))
            continue
        if poses == true_cameras:
            write_true_cameras(fly_dir / "truth.json", true_cameras.parent)
        add(run(f"render_{label}", cli("aerostereo-render") + [
            "--scene", str(scene), "--out", str(out / "render" / label), "--mode", "replay",
            *render_camera_options(config, poses, fly_dir / "truth.json"), *extra,
            "--spp", str(config.spp), "--seed", str(config.seed), "--workers", "1", "--quiet"], log_dir))
    return evaluate_run(dataclasses.asdict(config), [dataclasses.asdict(s) for s in stages], world, out)


def render_camera_options(config: LoopConfig, poses: Path | None, truth_json: Path) -> list[str]:
    """``aerostereo-render --mode replay`` options for the cameras of one render: at ``poses`` (a geotags.csv) with
    the drone camera's field of view and lens (from ``truth.json``), or, with None, at the reconstructed scene's own
    cameras, each with the lens SfM found for it (what a user renders from the twin), scaled to the render width."""
    width, height = config.render_size or config.photo_size
    if poses is None:
        return ["--width", str(width)]
    return ["--geotags", str(poses), "--width", str(width), "--height", str(height),
            "--fov", f"{photo_hfov_deg(truth_json):.6f}", *photo_lens_options(truth_json)]


def write_true_cameras(truth_json: Path, folder: Path) -> Path:
    """The true camera poses of the photos taken (``truth.json``, its ENU frame) as ``folder/geotags.csv`` +
    ``geotags.json``, for a render of the true world where the photos were really taken."""
    truth = json.loads(truth_json.read_text(encoding="utf-8"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = [geotag_row(row["image_name"], (row["east_m"], row["north_m"], row["up_m"]),
                       (row["qw"], row["qx"], row["qy"], row["qz"]))
            for row in truth["photos"] if row["taken"] and row["image_name"]]
    return write_geotags(folder, rows, origin=LocalFrame.from_dict(truth["origin"]))


def evaluate_run(config: dict, stages: list[dict], world: Path, out: Path) -> dict:
    """Evaluate the stage outputs in ``out`` (layout of :func:`run_loop`) and write the report."""
    report = evaluate(config=config, stages=stages, ok={s["name"] for s in stages if s["status"] == "ok"},
                      world=world, out=out, geotags=out / "geotag" / "geotags.csv", recon_dir=out / "recon",
                      render_dirs={label: out / "render" / label for label in ("twin", "true", "twin_own", "true_own")},
                      truth_json=out / "fly" / "truth.json", photos=out / "fly" / "photos",
                      mission_summary=out / "mission" / "mission_summary.json")
    write_report(report, out)
    return report


def finished_report(out: Path) -> Path:
    """``out/report.json``; ValueError when ``out`` holds no finished run."""
    path = out / "report.json"
    if not path.is_file():
        raise ValueError(f"{path}: not found; --reevaluate needs the folder of a finished run")
    return path


def reevaluate(out: Path) -> dict:
    """Evaluate a finished run folder again (its ``report.json`` gives the stages and settings)."""
    previous = json.loads(finished_report(out).read_text(encoding="utf-8"))
    return evaluate_run(previous["config"], previous["stages"], world_folder(previous["config"]["scene"]), out)


def arc_waypoints(text: str) -> int:
    """``--arc``: 0 (the whole orbit) or at least 2 waypoints (one waypoint is no flight)."""
    value = int(text)
    if value != 0 and value < 2:
        raise argparse.ArgumentTypeError(f"must be 0 (the whole orbit) or at least 2 waypoints, got {text}")
    return value


def fixed_sun(text: str) -> str:
    """``--sun``: a fixed sun ``AZ,EL,STRENGTH`` (the tcp link runs on the host clock, so the loop's photos cannot take
    the sun of their time); argparse's error otherwise."""
    try:
        numbers = [float(value) for value in text.split(",")]
    except ValueError:
        numbers = []
    if len(numbers) != 3:
        raise argparse.ArgumentTypeError(f"expected a fixed sun AZ,EL,STRENGTH (three numbers), got {text!r}")
    try:
        parse_sun(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, type=Path, help="output folder (report.md, report.json, stages)")
    parser.add_argument("--quick", action="store_true",
                        help="the reduced loop: small world, 3-waypoint arc, 480x360 photos, loop link at 10x")
    parser.add_argument("--scene", help="scene folder, or demo / demo:small (default demo)")
    parser.add_argument("--arc", type=arc_waypoints, dest="arc_waypoints",
                        help="fly only the first N >= 2 waypoints (0: all)")
    parser.add_argument("--photo-size", nargs=2, type=int, metavar=("W", "H"))
    parser.add_argument("--link", choices=("tcp", "loop"))
    parser.add_argument("--speedup", type=float, help="flight pace for --link loop (tcp runs in real time)")
    parser.add_argument("--seed", type=int)
    parser.add_argument("--sun", type=fixed_sun, metavar="AZ,EL,STRENGTH",
                        help=f"the photos' fixed sun (fly --sun; default {LoopConfig.sun}): e.g. 105,25,10 for a "
                             "morning's low sun")
    for name, knob in KNOBS.items():
        parser.add_argument(f"--{name.replace('_', '-')}", type=knob.parse, choices=knob.choices, dest=knob.field,
                            help=f"{knob.what} (sweep knob {name})")
    parser.add_argument("--reevaluate", action="store_true",
                        help="only evaluate the finished run in --out again (after changing the evaluation)")
    parser.add_argument("--sweep", metavar="KNOB=V1,V2,...",
                        help=f"rerun the loop per value of one knob ({', '.join(KNOBS)})")
    return parser.parse_args(argv)


def config_from_args(args: argparse.Namespace) -> LoopConfig:
    config = LoopConfig.quick() if args.quick else LoopConfig()
    for name in ("scene", "arc_waypoints", "link", "speedup", "seed", "sun", *(knob.field for knob in KNOBS.values())):
        if getattr(args, name) is not None:
            setattr(config, name, getattr(args, name))
    if args.photo_size:
        config.photo_size = tuple(args.photo_size)
    if config.link == "tcp" and config.speedup != 1.0:
        raise ValueError("--link tcp runs in real time (the recorder stamps with the host clock); "
                         "use --link loop for --speedup")
    return config


def parse_sweep(text: str) -> tuple[str, list]:
    knob, _, values = text.partition("=")
    if knob not in KNOBS or not values:
        raise ValueError(f"--sweep {text!r}: expected KNOB=V1,V2,... with KNOB one of {', '.join(KNOBS)}")
    parse, choices = KNOBS[knob].parse, KNOBS[knob].choices
    try:
        parsed = [parse(value) for value in values.split(",")]
    except ValueError:
        raise ValueError(f"--sweep {text!r}: values of {knob} must be {parse.__name__}") from None
    if choices and not set(parsed) <= set(choices):
        raise ValueError(f"--sweep {text!r}: values of {knob} must be among {', '.join(choices)}")
    return knob, parsed


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        config = config_from_args(args)
        sweep = parse_sweep(args.sweep) if args.sweep else None
        if sweep and args.reevaluate:
            raise ValueError("--sweep runs new loops; --reevaluate evaluates one finished run: give one of them")
        read_scene_json(world_folder(config.scene))
        if args.reevaluate:
            finished_report(args.out)
        else:
            refuse_non_empty(args.out)
    except (ValueError, SceneError) as error:
        print(f"closed_loop: error: {error}", file=sys.stderr)
        return 2
    if sweep is None:
        report = reevaluate(args.out) if args.reevaluate else run_loop(config, args.out)
        print((args.out / "report.md").read_text(encoding="utf-8"))
        return 0 if report["complete"] else 1
    knob, values = sweep
    reports = []
    for value in values:
        setattr(config, KNOBS[knob].field, value)
        reports.append((value, run_loop(config, args.out / f"{knob}={value}")))
    table = sweep_table(knob, reports)
    write_text_atomic(args.out / "sweep.md", table + "\n")
    print(table)
    return 0 if all(report["complete"] for _, report in reports) else 1


if __name__ == "__main__":
    sys.exit(main())
