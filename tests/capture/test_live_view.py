"""The live view (capture.live_view) on the virtual drone's real bytes: each flight fault of truth.json is warned within
2 s of its start, a clean flight raises nothing the flight did not do, the recording under the view is the link's
bytes, and the command shows its screen in a real terminal (tmux) and plain lines when redirected."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from capture.decode import timed_packets
from capture.duml import Deframer
from capture.live_plan import planned_path
from capture.live_state import LiveState
from capture.messages import default_registry
from capture.transports import replay_file
from flightplan import litchi
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.orbit import OrbitRequest, plan_orbit
from sim.drone import FlightFaults, Imperfections, fly
from sim.drone.flight_faults import BatteryDrain, GimbalStuck, Gust, LinkSilence
from sim.drone.link import CAMERA_STATE_HZ, FrameServer, MissionClock, duml_frames
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.session import watch_loopback
from tests.capture.virtual_flights import START
from tests.sim.drone_helpers import short_orbit_csv

ROOT = Path(__file__).resolve().parents[2]
SPEEDUP = 10.0
FAULT_S = 25.0  # on the short arc's mission (it reaches the first waypoint's height at about 15 s)
WARNED_WITHIN_S = 2.0
SEED = 5
#: Each fault and the warning it must raise.
FAULTS = {
    "gust": (FlightFaults(gust=Gust(FAULT_S, 6.0, 12.0)), "off_path"),
    "link_silence": (FlightFaults(link_silence=LinkSilence(FAULT_S, 4.0)), "link_silent"),
    "gimbal_stuck": (FlightFaults(gimbal_stuck=GimbalStuck(FAULT_S, 5.0, -80.0)), "gimbal"),
    "battery_drain": (FlightFaults(battery_drain=BatteryDrain(FAULT_S, 60.0)), "battery"),  # to the landing
}


@pytest.fixture(scope="module")
def mission_csv(tmp_path_factory):
    return short_orbit_csv(tmp_path_factory.mktemp("live") / "arc.csv")


def flown(mission_csv, faults: FlightFaults = FlightFaults()):
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    return fly(waypoints, home_below_first_waypoint(waypoints, 100.0), Imperfections.realistic(), seed=SEED,
               faults=faults)


def watch_loop_flight(mission_csv, mission, capture: Path, until_s: float | None = None):
    """Stream the flight's frames (up to ``until_s`` of flight time) through a ``loop://`` port at :data:`SPEEDUP`
    into the live recorder with a live view; returns the monitor (its times are flight seconds) and the frames."""
    frames = [frame for frame in duml_frames(mission) if until_s is None or frame.t_s <= until_s]
    monitor = watch_loopback(frames, capture, MissionClock(SPEEDUP, START),
                             planned_path(litchi.read_mission_csv(mission_csv)))
    assert monitor.error is None
    return monitor, frames


@pytest.mark.parametrize("fault", FAULTS)
def test_each_fault_is_warned_within_2_s_of_its_start_over_the_loop_link_at_10x(fault, mission_csv, tmp_path):
    faults, kind = FAULTS[fault]
    mission = flown(mission_csv, faults)
    truth = faults.truth(START, mission.flight.duration_s)[0]
    until_s = min(truth["end_s"], truth["start_s"] + 6.0) + 1.0  # the fault and the link's return after it
    monitor, frames = watch_loop_flight(mission_csv, mission, tmp_path / "flight.duml", until_s)
    warned = [alert for alert in monitor.state.warnings if alert.kind == kind]
    assert warned, [alert.kind for alert in monitor.state.warnings]
    latency = warned[0].start_t - truth["start_s"]
    assert 0.0 <= latency <= WARNED_WITHIN_S, (fault, latency)
    before = [alert for alert in monitor.state.warnings if alert.start_t < truth["start_s"]]
    assert_only_recorded_silences(before, tmp_path / "flight.duml", monitor.state.limits.silent_after_s)
    assert (tmp_path / "flight.duml").read_bytes() == b"".join(frame.data for frame in frames)


def assert_only_recorded_silences(alerts, capture: Path, limit_s: float) -> None:
    """Each alert is a link silence that the recording shows: no packet completed in the ``limit_s`` before it (the
    realistic noise's dropouts, or this shared machine pausing the sender or the receiver for a tenth of a second, a
    second of flight at 10x)."""
    received = np.array([timed.receive_time_monotonic for timed in timed_packets(replay_file(capture), Deframer())])
    for alert in alerts:
        assert alert.kind == "link_silent", alert
        assert alert.start_t - received[received < alert.start_t].max() > limit_s, alert


def test_a_clean_flight_raises_only_silences_the_recording_shows(mission_csv, tmp_path):
    """No fault at 10x: nothing but link silences the recording shows (:func:`assert_only_recorded_silences`); the
    recording is every byte sent."""
    mission = flown(mission_csv)
    monitor, frames = watch_loop_flight(mission_csv, mission, tmp_path / "flight.duml")
    assert_only_recorded_silences(monitor.state.warnings, tmp_path / "flight.duml", monitor.state.limits.silent_after_s)
    assert 0 <= len(mission.telemetry.shutter) - monitor.state.photos <= 3  # a few lost to byte damage
    assert monitor.state.progress.finished
    assert (tmp_path / "flight.duml").read_bytes() == b"".join(frame.data for frame in frames)


def replayed(orbit_csv: Path, mission) -> LiveState:
    """The flight's frames fed to a live state at their send times (no link, no threads), ticked every 0.05 s."""
    state = LiveState(planned_path(litchi.read_mission_csv(orbit_csv)))
    deframer, registry = Deframer(), default_registry()
    ticks = iter(np.arange(0.0, mission.flight.duration_s + 1.0, 0.05).tolist())
    tick = next(ticks)
    for frame in duml_frames(mission):
        while tick < frame.t_s:
            state.tick(tick)
            tick = next(ticks)
        for _, packet in deframer.feed(frame.data):
            state.on_packet(frame.t_s, registry.decode(packet))
        state.tick(frame.t_s)
    return state


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_a_clean_default_orbit_is_warned_only_in_the_links_own_dropouts(seed, tmp_path):
    """The full default orbit (8 min, 451 photos) with the realistic noise and no fault, replayed at its send times:
    every warning is a silence inside one of the link's own dropouts (truth.json's link_dropouts_s); no path, gimbal,
    shutter or battery warning."""
    orbit_csv = tmp_path / "orbit.csv"
    litchi.write_mission_csv(plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg)).mission, orbit_csv)
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(orbit_csv))
    mission = fly(waypoints, home_below_first_waypoint(waypoints, 100.0), Imperfections.realistic(), seed=seed)
    state = replayed(orbit_csv, mission)
    limit, spacing = state.limits.silent_after_s, 1 / CAMERA_STATE_HZ  # the sparsest stream: 0.2 s between sends
    for alert in state.warnings:  # silent from the last send before the dropout to the first after it
        assert alert.kind == "link_silent", alert
        assert any(start - spacing <= alert.start_t - limit and alert.end_t <= end + spacing
                   for start, end in mission.telemetry.dropouts_s), alert
    assert state.progress.finished and state.longest_gap_s <= 2 * 1.0 + 0.2
    assert 0 <= len(mission.telemetry.shutter) - state.photos <= 3  # shutter events sent; a few lost to byte damage


def record_command(mission_csv, port: int, out: Path, *options: str) -> list[str]:
    """``record --mission`` from the virtual drone's :class:`FrameServer`; the stream of :func:`gimbal_fault_frames`
    lasts 3.3 s at 10x, and the silence after it (host seconds) is not warned within 6 s."""
    return [sys.executable, "-m", "capture", "record", "--port", f"socket://127.0.0.1:{port}", "--out", str(out),
            "--mission", str(mission_csv), "--silent-after", "6", *options]


STUCK_WARNING = r"GIMBAL: gimbal pitch -(79\.\d|80\.\d) deg, planned -31\.0"


def gimbal_fault_frames(mission_csv, until_s: float = FAULT_S + 8.0):
    faults, _ = FAULTS["gimbal_stuck"]
    return [frame for frame in duml_frames(flown(mission_csv, faults)) if frame.t_s <= until_s]


def test_redirected_it_prints_plain_lines_and_each_warning_once(mission_csv, tmp_path):
    frames = gimbal_fault_frames(mission_csv)
    server = FrameServer(frames, SPEEDUP)
    server.start()
    done = subprocess.run(record_command(mission_csv, server.port, tmp_path / "r.duml", "--duration", "8"), cwd=ROOT,
                          capture_output=True, text=True, timeout=60)  # 8 s from the connection: the stream and more
    server.join(timeout=10)
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if line.startswith("WARNING")]
    assert len(warnings) == 1 and re.search(STUCK_WARNING, warnings[0]), done.stderr
    assert any(line.split()[1:3] == ["s", "link:"] for line in done.stderr.splitlines()), done.stderr  # a status line
    assert "live view: 1 warnings" in done.stdout and "warning:" in done.stdout
    assert "\x1b" not in done.stderr + done.stdout  # no screen control when redirected
    assert (tmp_path / "r.duml").read_bytes() == b"".join(frame.data for frame in frames)


TMUX = shutil.which("tmux")


def tmux(*args: str) -> str:
    return subprocess.run([TMUX, *args], capture_output=True, text=True, check=True, timeout=10).stdout


@pytest.mark.skipif(TMUX is None, reason="tmux is not installed: the live view's screen needs a real terminal to test")
def test_in_a_terminal_it_shows_the_screen_warns_and_ctrl_c_keeps_every_byte(mission_csv, tmp_path):
    frames = gimbal_fault_frames(mission_csv)
    server = FrameServer(frames, SPEEDUP)
    server.start()
    session = f"aerostereo-live-{server.port}"
    tmux("new-session", "-d", "-s", session, "-x", "150", "-y", "30")
    try:
        command = " ".join(record_command(mission_csv, server.port, tmp_path / "r.duml"))
        tmux("send-keys", "-t", session, f"cd {ROOT} && {command}", "Enter")
        screens = []  # read every 0.5 s until the stream (3.3 s from the connection, the fault at 2.5 s) is over
        for _ in range(60):
            time.sleep(0.5)
            screens.append(tmux("capture-pane", "-p", "-t", session))
            if server.stream_s:
                break
        time.sleep(0.5)
        screens.append(tmux("capture-pane", "-p", "-t", session))
        tmux("send-keys", "-t", session, "C-c", "")
        for _ in range(40):
            time.sleep(0.25)
            final = tmux("capture-pane", "-p", "-t", session)
            if "wrote " in final:
                break
    finally:
        tmux("kill-session", "-t", session)
    early = next(screen for screen in screens if "PATH" in screen)
    for topic in ("LINK", "GPS", "BATTERY", "HEIGHT", "PATH", "GIMBAL  pitch", "PHOTOS", "WARNINGS"):
        assert topic in early, early
    assert any(re.search(STUCK_WARNING, screen) for screen in screens), screens[-1]
    assert "live view: 1 warnings" in final and "wrote " in final, final
    assert (tmp_path / "r.duml").read_bytes() == b"".join(frame.data for frame in frames)


def test_at_the_links_fastest_rate_the_view_keeps_up_and_the_recording_is_every_byte(mission_csv, tmp_path):
    """The whole short arc sent at once (a backlog: packets sharing a chunk's receive time); it once stopped the view
    (a battery drop timed over 0 s) and ended the command with a traceback."""
    frames = duml_frames(flown(mission_csv))
    server = FrameServer(frames, speedup=1e6)
    server.start()
    done = subprocess.run(record_command(mission_csv, server.port, tmp_path / "r.duml", "--duration", "3"), cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    server.join(timeout=10)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert "note: the live view stopped" not in done.stderr
    assert "live view: " in done.stdout
    assert (tmp_path / "r.duml").read_bytes() == b"".join(frame.data for frame in frames)
