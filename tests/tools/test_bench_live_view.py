"""tools/bench/bench_live_view.py: over the virtual drone's TCP link (FrameServer to a socket:// recorder on one flight
clock) at 10x, a fault is warned within 2 s of its start in truth, and the record rows keep every byte."""

from __future__ import annotations

import pytest

from sim.drone.link import duml_frames
from tests.sim.drone_helpers import short_orbit_csv
from tools.bench.bench_live_view import faults, flown, latency_s, record_run


@pytest.mark.parametrize("name", ["gust 12 m", "link silence 4 s", "gimbal stuck at -80"])
def test_over_tcp_at_10x_a_fault_is_warned_within_2_s(name, tmp_path):
    fault, kind = faults(battery_factor=60.0)[name]
    latency = latency_s(short_orbit_csv(tmp_path / "arc.csv"), fault, kind, 10.0, tmp_path)
    assert latency is not None and 0.0 <= latency <= 2.0


def test_a_record_run_at_the_fastest_rate_keeps_every_byte_under_the_view(tmp_path):
    mission_csv = short_orbit_csv(tmp_path / "arc.csv")
    frames = duml_frames(flown(mission_csv))
    run = record_run(mission_csv, frames, 1e6, 3.0, tmp_path / "r.duml")
    assert run["identical"] and run["view_ok"] and run["bytes"] == sum(len(frame.data) for frame in frames)
