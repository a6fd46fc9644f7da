"""Issue 41's bad input for the flight faults (``aerostereo-render fly --gust/--link-silence/--gimbal-stuck/
--battery-drain``) and the live view (``aerostereo-ingest record --mission`` and its limits): each is refused with
one line naming the option or file and what was expected, exit code 2, nothing written. On the code before issue
41 every case fails its pattern: the options did not exist (argparse's "unrecognized arguments")."""

from __future__ import annotations

from pathlib import Path

import pytest

from flightplan.demo_location import DEMO_ORIGIN
from flightplan.litchi import Mission, Waypoint, write_mission_csv
from tests.bad_input.harness import Case, assert_refused, run_case
from tests.bad_input.test_limits import write_mission

RENDER, INGEST = "aerostereo-render", "aerostereo-ingest"
FLY = ["fly", "--mission", "{tmp}/m.csv", "--scene", "demo:small", "--out", "{tmp}/f", "--photos", "0",
       "--photo-size", "16", "12", "--start-utc", "2024-05-01T08:00:00Z"]
RECORD = ["record", "--port", "loop://", "--duration", "0.1", "--out", "{tmp}/r.duml", "--mission", "{tmp}/m.csv"]


def write_text(name: str, text: str):
    def setup(tmp: Path) -> None:
        (tmp / name).write_text(text)
    return setup


def write_one_waypoint(tmp: Path) -> None:
    write_mission_csv(Mission((Waypoint(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg, 30.0),)), tmp / "m.csv")


def write_two_missions(tmp: Path) -> None:
    """The small orbit twice: the flights of an area plan."""
    write_mission(tmp)
    (tmp / "m2.csv").write_bytes((tmp / "m.csv").read_bytes())


CASES = [
    Case("fly-gust-shorter-than-its-rise-and-fall", RENDER, [*FLY, "--gust", "10", "1", "5"],
         r"--gust: DURATION 1 s: a gust rises and falls over 1 s each, so it lasts at least 2 s", write_mission),
    Case("fly-gust-offset-huge", RENDER, [*FLY, "--gust", "10", "5", "1e6"],
         r"--gust: METRES 1e\+06: expected a push in \(0, 100\] m", write_mission),
    Case("fly-gust-nan", RENDER, [*FLY, "--gust", "10", "nan", "5"],
         r"argument --gust: expected a finite number, got 'nan'", write_mission),
    Case("fly-gust-two-values", RENDER, [*FLY, "--gust", "10", "5"], r"argument --gust: expected 3 arguments",
         write_mission),
    Case("fly-link-silence-negative-start", RENDER, [*FLY, "--link-silence", "-5", "3"],
         r"--link-silence: START -5 s: expected seconds of flight time in \[0, 6553\.5\]", write_mission),
    Case("fly-link-silence-too-long", RENDER, [*FLY, "--link-silence", "5", "1e9"],
         r"--link-silence: DURATION 1e\+09 s: expected seconds in \(0, 600\]", write_mission),
    Case("fly-link-silence-after-landing", RENDER, [*FLY, "--link-silence", "5000", "3"],
         r"--link-silence: START 5000 s: the flight lasts \d+\.\d s; expected a start within it", write_mission),
    Case("fly-area-fault-after-the-first-flight-lands", RENDER,
         [*FLY, "--mission", "{tmp}/m2.csv", "--link-silence", "5000", "3"],
         r"--link-silence: START 5000 s: the flight lasts \d+\.\d s; expected a start within it \(flight 1, .*m\.csv\)",
         write_two_missions),
    Case("fly-gimbal-stuck-above-the-horizon", RENDER, [*FLY, "--gimbal-stuck", "10", "5", "30"],
         r"--gimbal-stuck: PITCH 30: expected degrees in \[-90, 0\]", write_mission),
    Case("fly-battery-drain-slower", RENDER, [*FLY, "--battery-drain", "10", "0.5"],
         r"--battery-drain: FACTOR 0\.5: expected how many times faster, in \(1, 100\]", write_mission),
    Case("fly-battery-drain-inf", RENDER, [*FLY, "--battery-drain", "10", "inf"],
         r"argument --battery-drain: expected a finite number, got 'inf'", write_mission),
    Case("record-mission-not-litchi", INGEST, RECORD,
         r"--mission .*m\.csv: .*m\.csv:1: header lacks the required column\(s\) latitude, longitude",
         write_text("m.csv", "hello\nworld\n")),
    Case("record-mission-missing", INGEST, RECORD, r"--mission .*m\.csv: .*expected a Litchi mission CSV"),
    Case("record-mission-one-waypoint", INGEST, RECORD,
         r"--mission .*m\.csv: a mission needs at least 2 waypoints to fly along, got 1", write_one_waypoint),
    Case("record-mission-is-out", INGEST, [*RECORD[:-1], "{tmp}/r.duml"], r"--out .*r\.duml: is also --mission",
         write_text("r.duml", "latitude,longitude\n")),
    Case("record-off-path-zero", INGEST, [*RECORD, "--off-path", "0"],
         r"argument --off-path: expected metres in \[0\.1, 1000\], got '0'", write_mission),
    Case("record-silent-after-nan", INGEST, [*RECORD, "--silent-after", "nan"],
         r"argument --silent-after: expected seconds in \[0\.1, 600\], got 'nan'", write_mission),
    Case("record-battery-reserve-over-100", INGEST, [*RECORD, "--battery-reserve", "150"],
         r"argument --battery-reserve: expected percent in \[0, 100\], got '150'", write_mission),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)

