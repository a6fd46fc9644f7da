"""Benchmark: the live view of ``aerostereo-ingest record --mission`` (docs/at-the-field.md) on the virtual drone.

Rows:

- **latency**, per flight fault (sim.drone.flight_faults, as truth.json records it), at real time and at 10x: the
  short arc (the default orbit's first 3 waypoints) served over TCP by the virtual drone (sim.drone.link.FrameServer)
  to the live recorder reading ``socket://`` under the live view, both on the flight's clock, from 12 s before the
  fault to 1 s after it ends (6 s at most); latency = the warning's flight time - the fault's start.
  ``--battery-factors``: the battery drains measured (the warning waits for the drain to show in whole percent
  points); "lands with" is the battery the faulty flight lands with: whether a battery warning is due at all.
- **false alarms**, the full default orbit with no fault at 10x (``--clean-seeds``): each warning classed as a
  silence in the flight's own link dropouts (the realistic noise's, truth.json's ``link_dropouts_s``; one a little
  under the 1 s limit can still silence the link longer, from the send before it to the send after), a pause of
  this shared machine that the recording shows (no packet arrived for the limit), or a false alarm.
- **CPU**: the ``record`` command fed by the virtual drone over TCP (sim.drone.link.FrameServer) at real time for
  ``--cpu-seconds``, with and without ``--mission`` (plain lines: output redirected), the process's CPU time / wall.
- **bytes**: the recording under the live view against what the link sent, every byte of it: the default orbit's
  first 100 s paced to fill 115200 baud (8N1: 11520 B/s), and the whole orbit as fast as the socket goes.

    PYTHONPATH=. .venv/bin/python tools/bench/bench_live_view.py                 # about 3 minutes
    PYTHONPATH=. .venv/bin/python tools/bench/bench_live_view.py --quick         # 10x only, 1 clean seed, 10 s CPU
"""

from __future__ import annotations

import argparse
import datetime as dt
import io
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from capture.decode import timed_packets
from capture.duml import Deframer
from capture.live_plan import planned_path
from capture.live_state import LiveState
from capture.live_view import LineDisplay, LiveMonitor
from capture.messages import default_registry
from capture.raw import atomic_capture
from capture.recorder import record
from capture.transports import SerialSource, replay_file
from flightplan import litchi
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.orbit import OrbitRequest, plan_orbit
from sim.drone import FlightFaults, Imperfections, fly
from sim.drone.flight_faults import BatteryDrain, GimbalStuck, Gust, LinkSilence
from sim.drone.link import CAMERA_STATE_HZ, FrameServer, MissionClock, duml_frames
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.session import until_received, watch_loopback
from tests.sim.drone_helpers import short_orbit_csv

START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)
FAULT_S = 25.0
LEAD_S = 12.0  # streamed before the fault
BAUD_115200_BPS = 115200 / 10  # 8N1: ten bits a byte
#: A silence warned this long after a dropout of the link's own ended is still that dropout's (flight seconds): the
#: silence runs from the last packet before it to the first after it, and the view looks every 0.2 flight s at 10x.
DROPOUT_SLACK_S = 0.5


def faults(battery_factor: float) -> dict[str, tuple[FlightFaults, str]]:
    """Each fault of the bench and the warning kind that must name it."""
    return {"gust 12 m": (FlightFaults(gust=Gust(FAULT_S, 6.0, 12.0)), "off_path"),
            "link silence 4 s": (FlightFaults(link_silence=LinkSilence(FAULT_S, 4.0)), "link_silent"),
            "gimbal stuck at -80": (FlightFaults(gimbal_stuck=GimbalStuck(FAULT_S, 5.0, -80.0)), "gimbal"),
            f"battery drain x{battery_factor:g}": (FlightFaults(battery_drain=BatteryDrain(FAULT_S, battery_factor)),
                                                   "battery")}


def flown(mission_csv: Path, fault: FlightFaults = FlightFaults(), seed: int = 5):
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    return fly(waypoints, home_below_first_waypoint(waypoints, 100.0), Imperfections.realistic(), seed=seed,
               faults=fault)


def landing_battery_percent(mission_csv: Path, fault: FlightFaults) -> int:
    """The battery the faulty flight lands with (its last OSD): whether a battery warning is due at all."""
    return flown(mission_csv, fault).telemetry.osd[-1].battery_percent


def watch_tcp(frames, capture: Path, clock: MissionClock, from_s: float, plan) -> LiveMonitor:
    """The live recorder under a live view, reading ``socket://`` from the virtual drone's FrameServer, both on
    ``clock`` (the flight's time line, from ``from_s``); returns the monitor once the stream has ended."""
    server = FrameServer(frames, from_s=from_s, clock=clock)
    server.start()
    source = SerialSource(f"socket://127.0.0.1:{server.port}", clock=clock)
    monitor = LiveMonitor(LiveState(plan), default_registry(), clock.monotonic, LineDisplay(io.StringIO()))
    with monitor, atomic_capture(capture) as writer:
        record(until_received(source, sum(len(frame.data) for frame in frames)), writer, default_registry(),
               tap=monitor.put)
    server.join()
    return monitor


def latency_s(mission_csv: Path, fault: FlightFaults, kind: str, speedup: float, folder: Path) -> float | None:
    """Flight seconds from the fault's start (truth) to its warning over the TCP link; None when not warned."""
    mission = flown(mission_csv, fault)
    truth = fault.truth(START, mission.flight.duration_s)[0]
    first, last = truth["start_s"] - LEAD_S, min(truth["end_s"], truth["start_s"] + 6.0) + 1.0
    frames = [frame for frame in duml_frames(mission) if first <= frame.t_s <= last]
    monitor = watch_tcp(frames, folder / "flight.duml", MissionClock(speedup, START), first,
                        planned_path(litchi.read_mission_csv(mission_csv)))
    warned = [alert.start_t for alert in monitor.state.warnings if alert.kind == kind]
    return warned[0] - truth["start_s"] if warned else None


def clean_orbit(orbit_csv: Path, seed: int, folder: Path) -> dict:
    """Warnings of a full clean default orbit at 10x, each classed: ``dropout`` (a silence in one of the flight's own
    link dropouts, truth.json's link_dropouts_s), ``stall`` (a silence the recording shows though nothing was
    dropped: this machine paused the sender or the receiver, a tenth of a second being a second of flight at 10x),
    or ``false`` (a false alarm)."""
    mission = flown(orbit_csv, seed=seed)
    frames = duml_frames(mission)
    monitor = watch_loopback(frames, folder / "flight.duml", MissionClock(10.0, START),
                             planned_path(litchi.read_mission_csv(orbit_csv)))
    limit, spacing = monitor.state.limits.silent_after_s, 1 / CAMERA_STATE_HZ
    received = np.array([timed.receive_time_monotonic for timed in
                         timed_packets(replay_file(folder / "flight.duml"), Deframer())])
    classes = []
    for alert in monitor.state.warnings:
        in_dropout = any(a - spacing <= alert.start_t - limit and alert.start_t <= b + DROPOUT_SLACK_S
                         for a, b in mission.telemetry.dropouts_s)
        recorded_silence = alert.start_t - received[received < alert.start_t].max(initial=-np.inf) > limit
        classes.append("false" if alert.kind != "link_silent" else "dropout" if in_dropout else
                       "stall" if recorded_silence else "false")
    identical = (folder / "flight.duml").read_bytes() == b"".join(frame.data for frame in frames)
    return {"warnings": [alert.kind for alert in monitor.state.warnings], "classes": classes,
            "dropouts": int(np.count_nonzero(np.diff(mission.telemetry.dropouts_s, axis=1) > limit)),
            "photos": monitor.state.photos, "sent": len(mission.telemetry.shutter), "identical": identical}


def record_run(mission_csv: Path | None, frames, speedup: float, seconds: float, out: Path) -> dict:
    """``record`` (with ``--mission`` when given) fed by a FrameServer at ``speedup``: CPU / wall, bytes."""
    server = FrameServer(frames, speedup)
    server.start()
    command = [sys.executable, "-m", "capture", "record", "--port", f"socket://127.0.0.1:{server.port}", "--out",
               str(out), "--duration", f"{seconds:g}"]
    if mission_csv is not None:
        command += ["--mission", str(mission_csv)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    done = subprocess.run(command, capture_output=True, text=True)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    server.join(timeout=5)
    if done.returncode != 0:
        raise SystemExit(f"record failed: {done.stderr}")
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    recorded = out.read_bytes()
    stream = b"".join(frame.data for frame in frames)
    return {"cpu_s": cpu, "wall_s": wall, "bytes": len(recorded), "sent": server.sent, "stream_s": server.stream_s,
            "identical": recorded == stream[:server.sent] and server.sent == len(stream),
            "view_ok": mission_csv is None or "live view:" in done.stdout}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="10x latencies only, one clean seed, 10 s of CPU")
    parser.add_argument("--clean-seeds", type=int, default=2, help="clean default orbits flown (default 2)")
    parser.add_argument("--cpu-seconds", type=float, default=30.0, help="real-time seconds of the CPU rows")
    parser.add_argument("--battery-factors", type=float, nargs="+", default=[60.0, 30.0, 10.0])
    args = parser.parse_args(argv)
    speedups = [10.0] if args.quick else [1.0, 10.0]
    seeds = 1 if args.quick else args.clean_seeds
    cpu_seconds = 10.0 if args.quick else args.cpu_seconds
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        arc_csv = short_orbit_csv(folder / "arc.csv")
        orbit_csv = folder / "orbit.csv"
        litchi.write_mission_csv(plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg)).mission,
                                 orbit_csv)
        print("warning latency (flight seconds from the fault's start in truth.json; limit 2 s)")
        print(f"{'fault':<22} {'warning':<12} " + " ".join(f"{f'{s:g}x':>8}" for s in speedups) + "  lands with")
        cases = {**faults(args.battery_factors[0]),
                 **{name: case for factor in args.battery_factors[1:] for name, case in faults(factor).items()
                    if name.startswith("battery")}}
        for name, (fault, kind) in cases.items():
            values = [latency_s(arc_csv, fault, kind, speedup, folder) for speedup in speedups]
            print(f"{name:<22} {kind:<12} " + " ".join(f"{v:8.2f}" if v is not None else f"{'none':>8}"
                                                        for v in values)
                  + f"  {landing_battery_percent(arc_csv, fault)} % battery", flush=True)
        print("\nfalse alarms, full default orbit at 10x, no fault")
        for seed in range(seeds):
            row = clean_orbit(orbit_csv, seed, folder)
            classes = row["classes"]
            print(f"seed {seed}: {len(classes)} warnings {sorted(set(row['warnings']))}: {classes.count('dropout')} "
                  f"silences in the link's own dropouts ({row['dropouts']} of them > 1 s), {classes.count('stall')} "
                  f"pauses of this machine the recording shows; false alarms: {classes.count('false')}; photos "
                  f"{row['photos']} of {row['sent']} shutter events sent; recording identical: {row['identical']}",
                  flush=True)
        orbit_frames = duml_frames(flown(orbit_csv, seed=0))
        rate = sum(len(f.data) for f in orbit_frames) / orbit_frames[-1].t_s
        print(f"\nCPU, record at real time ({rate:.0f} B/s of telemetry) for {cpu_seconds:g} s, output redirected")
        cpu = {}
        for label, mission in (("without --mission", None), ("with --mission", orbit_csv)):
            run = cpu[label] = record_run(mission, orbit_frames, 1.0, cpu_seconds, folder / "cpu.duml")
            print(f"{label:<20} CPU {run['cpu_s']:.2f} s / wall {run['wall_s']:.1f} s = "
                  f"{100 * run['cpu_s'] / run['wall_s']:.1f} % of one core (Python start included)", flush=True)
            (folder / "cpu.duml").unlink()
            Path(f"{folder / 'cpu.duml'}.idx").unlink()
        view_cpu = cpu["with --mission"]["cpu_s"] - cpu["without --mission"]["cpu_s"]
        print(f"the live view's own cost: {view_cpu:.2f} s CPU over {cpu_seconds:g} s = "
              f"{100 * view_cpu / cpu_seconds:.1f} % of one core")
        print("\nbytes under the live view (the default orbit's frames as the link damaged them: its first 100 s at "
              "115200 baud, all of it at the fastest)")
        first_100_s = [frame for frame in orbit_frames if frame.t_s <= 100.0]
        for label, frames, speedup, seconds in (("115200 baud", first_100_s, BAUD_115200_BPS / rate, 15.0),
                                                ("fastest", orbit_frames, 1e6, 10.0)):
            run = record_run(orbit_csv, frames, speedup, seconds, folder / "bytes.duml")
            rate_sent = run["sent"] / max(run["stream_s"], 1e-9)
            print(f"{label:<12} {run['bytes']} bytes recorded of {run['sent']} sent at {rate_sent:.0f} B/s, "
                  f"identical to what was sent: {run['identical']}, view ran: {run['view_ok']}", flush=True)
            (folder / "bytes.duml").unlink()
            Path(f"{folder / 'bytes.duml'}.idx").unlink()
    return 0


if __name__ == "__main__":
    sys.exit(main())
