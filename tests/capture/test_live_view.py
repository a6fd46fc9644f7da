"""The live view (capture.live_view) on the virtual drone's real bytes: each flight fault of truth.json is warned within
2 s of its start, a clean flight raises nothing the flight did not do, the recording under the view is the link's
bytes, and the command shows its screen in a real terminal (tmux) and plain lines when redirected."""

from __future__ import annotations

import io
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from capture.live_plan import planned_path
from capture.live_state import LiveLimits, LiveState
from capture.live_view import TICK_S, LineDisplay, LiveMonitor
from capture.messages import default_registry
from flightplan import litchi
from sim.drone import FlightFaults, Imperfections, fly
from sim.drone.flight_faults import BatteryDrain, GimbalStuck, Gust, LinkSilence
from sim.drone.link import MissionClock, duml_frames, stream
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.session import record_loopback
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
    clock = MissionClock(SPEEDUP, START)
    state = LiveState(planned_path(litchi.read_mission_csv(mission_csv)), LiveLimits())
    monitor = LiveMonitor(state, default_registry(), clock.monotonic, LineDisplay(io.StringIO()))
    with monitor:
        record_loopback(frames, capture, clock, progress=False, tap=monitor.put)
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
    assert [alert for alert in monitor.state.warnings if alert.start_t < truth["start_s"]] == []
    assert (tmp_path / "flight.duml").read_bytes() == b"".join(frame.data for frame in frames)


def test_a_clean_flight_raises_only_what_its_link_really_did(mission_csv, tmp_path):
    """No fault: the only warnings allowed are silences of the link's own dropouts (the realistic noise's, listed in
    truth.json as link_dropouts_s) longer than the limit; the recording is every byte sent."""
    mission = flown(mission_csv)
    monitor, frames = watch_loop_flight(mission_csv, mission, tmp_path / "flight.duml")
    silent_after = monitor.state.limits.silent_after_s
    long_dropouts = [(start, end) for start, end in mission.telemetry.dropouts_s if end - start > silent_after]
    for alert in monitor.state.warnings:
        assert alert.kind == "link_silent", alert
        assert any(start + silent_after <= alert.start_t <= end + 0.5 for start, end in long_dropouts), alert
    assert len(monitor.state.warnings) <= len(long_dropouts)
    taken = np.count_nonzero(mission.photos.taken)
    assert taken - 3 <= monitor.state.photos <= taken
    assert monitor.state.progress.finished
    assert (tmp_path / "flight.duml").read_bytes() == b"".join(frame.data for frame in frames)
