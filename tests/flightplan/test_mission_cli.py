"""aerostereo-mission: a real run writes readable files; bad input gives one line on stderr and exit code 2."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from flightplan import litchi
from flightplan.cli import main

REPO_ROOT = Path(__file__).resolve().parents[2]


def test_demo_writes_every_output(tmp_path, capsys):
    names = {"--out": "m.csv", "--kml": "m.kml", "--geojson": "m.geojson", "--plot": "m.png", "--summary-json": "s.json"}
    argv = ["--demo"] + [a for flag, name in names.items() for a in (flag, str(tmp_path / name))]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "waypoints        33 rows" in captured.out and "warning" not in captured.out  # the result on stdout
    assert "warning: photo interval 1 s" in captured.err
    mission = litchi.read_mission_csv(tmp_path / "m.csv")
    assert len(mission) == 33 and mission.waypoints[0].latitude_deg > 40.179
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["waypoints"] == 33 and summary["photo_count"] > 400
    assert any("2 s minimum" in w for w in summary["warnings"])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names.values())


def test_rings_and_options(tmp_path, capsys):
    argv = ["--lat", "-12", "--lon", "130", "--rings", "40:20", "60:45:-60", "--interval", "2", "--direction", "ccw"]
    assert main(argv + ["--start-bearing", "90", "--out", str(tmp_path / "r.csv")]) == 0
    assert "ring r=60 m h=45 m" in capsys.readouterr().out
    mission = litchi.read_mission_csv(tmp_path / "r.csv")
    assert {w.altitude_m for w in mission.waypoints} == {20.0, 45.0}
    assert {w.rotation_dir for w in mission.waypoints} == {litchi.ROTATION_CCW}


@pytest.mark.parametrize(
    "args, text",
    [
        (["--lat", "91", "--lon", "0"], "latitude must be within"),
        (["--lat", "nan", "--lon", "0"], "expected a finite number"),
        (["--lat", "north", "--lon", "0"], "argument --lat: expected a finite number, got 'north'"),
        (["--lat", "10", "--lon", "0", "--tolerance", "0"], "deviation tolerance must be positive"),
        (["--lat", "10", "--lon", "0", "--radius", "0"], "radius must be a positive"),
        (["--lat", "10", "--lon", "0", "--radius", "-3"], "radius must be a positive"),
        (["--lat", "10", "--lon", "0", "--speed-kmh", "50"], "DJI Mini SE speed (m/s) 13.8889"),
        (["--lat", "10", "--lon", "0", "--speed-kmh", "60"], "argument --speed-kmh: expected km/h in [0.36, 54]"),
        (["--lat", "10", "--lon", "0", "--height", "150"], "exceeds the legal 120 m"),
        (["--lat", "10", "--lon", "0", "--waypoints", "many"], "invalid int value"),
        (["--lat", "10", "--lon", "0", "--rings", "50"], "a ring is RADIUS:HEIGHT"),
        (["--lon", "0"], "--lat and --lon are required"),
        (["--demo", "--lat", "10"], "--demo sets the centre"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, text):
    assert main(args + ["--out", str(tmp_path / "m.csv")]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith("aerostereo-mission: error:")
    assert text in captured.err
    assert not (tmp_path / "m.csv").exists()


def test_unwritable_output(tmp_path, capsys):
    (tmp_path / "blocker").write_text("a file, not a folder")
    assert main(["--demo", "--out", str(tmp_path / "blocker" / "m.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{tmp_path / 'blocker'}" in err and "is a file, not a folder" in err


def test_python_dash_m(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "flightplan", "--lat", "91", "--lon", "0", "--out", str(tmp_path / "m.csv")],
        cwd=REPO_ROOT, capture_output=True, text=True, timeout=60,
    )
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip() == "aerostereo-mission: error: latitude must be within [-90, 90] degrees, got 91.0"
