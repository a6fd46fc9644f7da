"""The bad-input cases of ``aerostereo-mission --area``: fields that are not one simple polygon in a KML or GeoJSON
file, fields too large for any sane plan, and single-orbit options mixed in. Each is refused with one line naming
the file or option, exit code 2, nothing written."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.bad_input.harness import Case, assert_refused, run_case

MISSION = "aerostereo-mission"
SQUARE = [[44.499, 40.179], [44.5, 40.179], [44.5, 40.18], [44.499, 40.18], [44.499, 40.179]]


def files(**contents: bytes):
    """A setup writing ``name=bytes`` files into the case's folder (``_`` in a name stands for ``.``)."""
    def setup(tmp: Path) -> None:
        for name, data in contents.items():
            (tmp / name.replace("_", ".")).write_bytes(data)
    return setup


def geojson(geometry: dict) -> bytes:
    return json.dumps({"type": "Feature", "properties": {}, "geometry": geometry}).encode()


def kml(body: str) -> bytes:
    return f'<?xml version="1.0"?><kml xmlns="http://www.opengis.net/kml/2.2"><Document>{body}</Document></kml>'.encode()


def polygon_kml(coordinates: str) -> bytes:
    return kml(f"<Placemark><Polygon><outerBoundaryIs><LinearRing><coordinates>{coordinates}</coordinates>"
               "</LinearRing></outerBoundaryIs></Polygon></Placemark>")


BOWTIE = [[44.499, 40.179], [44.5, 40.18], [44.5, 40.179], [44.499, 40.18], [44.499, 40.179]]
COLLINEAR = [[44.499, 40.179], [44.4995, 40.179], [44.5, 40.179], [44.499, 40.179]]  # "0 m²": 4 orbits, 2 flights
SLIVER = [[44.499, 40.179], [44.5, 40.179], [44.5, 40.179005], [44.499, 40.179005], [44.499, 40.179]]  # 85 x 0.55 m
HUGE = [[44.45, 40.15], [44.53, 40.15], [44.53, 40.21], [44.45, 40.21], [44.45, 40.15]]  # about 6.8 x 6.7 km
VERY_WIDE = [[44.0, 40.0], [44.5, 40.0], [44.5, 40.01], [44.0, 40.01], [44.0, 40.0]]  # 42 km long
ENTITIES = (b'<?xml version="1.0"?><!DOCTYPE kml [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;">]>'
            b'<kml><Document><name>&b;</name></Document></kml>')
OUT = ["--out", "{tmp}/plan"]

CASES = [
    Case("area-not-kml-or-geojson", MISSION, ["--area", "{tmp}/field.txt", *OUT], r"field\.txt: expected a \.kml or \.geojson",
         files(field_txt=b"44.5,40.1\n")),
    Case("area-missing", MISSION, ["--area", "{tmp}/none.geojson", *OUT], r"none\.geojson"),
    Case("area-geojson-point", MISSION, ["--area", "{tmp}/f.geojson", *OUT], r"f\.geojson: the GeoJSON holds no Polygon",
         files(f_geojson=geojson({"type": "Point", "coordinates": [44.5, 40.1]}))),
    Case("area-geojson-not-json", MISSION, ["--area", "{tmp}/f.geojson", *OUT], r"f\.geojson: not GeoJSON",
         files(f_geojson=b"{not json")),
    Case("area-geojson-bad-coordinates", MISSION, ["--area", "{tmp}/f.geojson", *OUT],
         r"f\.geojson: the Polygon's exterior ring is not a list of \[lon, lat\] numbers",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [[["a", "b"], [1, 2], [3, 4]]]}))),
    Case("area-two-vertices", MISSION, ["--area", "{tmp}/f.geojson", *OUT], r"f\.geojson: a polygon needs at least 3",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE[:2] + SQUARE[:1]]}))),
    Case("area-latitude-out-of-range", MISSION, ["--area", "{tmp}/f.geojson", *OUT], r"f\.geojson: latitude must be within",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [[[44.5, 91.0], *SQUARE[1:]]]}))),
    Case("area-self-intersecting", MISSION, ["--area", "{tmp}/f.geojson", *OUT], r"f\.geojson: the polygon intersects itself",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [BOWTIE]}))),
    Case("area-collinear", MISSION, ["--area", "{tmp}/f.geojson", *OUT],
         r"f\.geojson: the polygon encloses 0\.00\d+ m² within its 170 m boundary, a sliver or a line; expected a "
         r"field at least 1 m wide \(85 m² or more\)",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [COLLINEAR]}))),
    Case("area-sliver", MISSION, ["--area", "{tmp}/f.kml", *OUT],
         r"f\.kml: the polygon encloses 47\.\d m² within its 171 m boundary, a sliver .* \(86 m² or more\)",
         files(f_kml=polygon_kml(" ".join(f"{lon},{lat}" for lon, lat in SLIVER)))),
    Case("area-too-many-orbits", MISSION, ["--area", "{tmp}/f.geojson", *OUT],
         r"f\.geojson: the field of 4\d\.\d\d km² needs about \d+ orbits .* at most 1000: split the field",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [HUGE]}))),
    Case("area-too-wide", MISSION, ["--area", "{tmp}/f.geojson", *OUT], r"f\.geojson: the field spans 42\.\d km across",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [VERY_WIDE]}))),
    Case("area-kml-no-polygon", MISSION, ["--area", "{tmp}/f.kml", *OUT], r"f\.kml: the KML holds no Polygon",
         files(f_kml=kml("<Placemark><Point><coordinates>44.5,40.1</coordinates></Point></Placemark>"))),
    Case("area-kml-polygon-without-ring", MISSION, ["--area", "{tmp}/f.kml", *OUT], r"f\.kml: the KML Polygon has no outerBoundaryIs",
         files(f_kml=kml("<Placemark><Polygon></Polygon></Placemark>"))),
    Case("area-kml-bad-coordinate", MISSION, ["--area", "{tmp}/f.kml", *OUT], r"f\.kml: KML coordinate 'x,y' is not",
         files(f_kml=polygon_kml("44.5,40.1 x,y 44.6,40.2"))),
    Case("area-kml-not-xml", MISSION, ["--area", "{tmp}/f.kml", *OUT], r"f\.kml: not a KML document",
         files(f_kml=b"PK\x03\x04 a KMZ is a zip")),
    Case("area-kml-entities", MISSION, ["--area", "{tmp}/f.kml", *OUT], r"f\.kml: not a KML document",
         files(f_kml=ENTITIES)),
    Case("area-with-a-centre", MISSION, ["--area", "{tmp}/f.geojson", "--demo", *OUT], r"--demo is for a single orbit",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-overlap-leaves-gaps", MISSION, ["--area", "{tmp}/f.geojson", "--overlap", "0.05", *OUT],
         r"--overlap must be 0\.134\.\.1",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-out-is-a-file", MISSION, ["--area", "{tmp}/f.geojson", "--out", "{tmp}/f.geojson"],
         r"--out .*f\.geojson", files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-out-holds-a-plan", MISSION, ["--area", "{tmp}/f.geojson", "--out", "{tmp}"],
         r"already holds a plan \(area\.json\)",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}), area_json=b"{}\n")),
    Case("area-out-holds-half-a-plan", MISSION, ["--area", "{tmp}/f.geojson", "--out", "{tmp}"],
         r"--out \S+: holds part of a plan \(no area\.json: an interrupted run\); delete flight_01\.csv there,",
         lambda tmp: (files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))(tmp),
                      (tmp / "flight_01.csv").write_bytes(b"latitude\n"))),
    Case("area-take-off-too-far", MISSION, ["--area", "{tmp}/f.geojson", "--home", "40.3", "44.5", *OUT],
         r"an orbit \d+ m from take-off does not fit one battery",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-orbit-above-the-law", MISSION, ["--area", "{tmp}/f.geojson", "--height", "150", *OUT],
         r"mission rejected: height 150 m above take-off on row 1 exceeds the legal 120 m",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-radius-zero", MISSION, ["--area", "{tmp}/f.geojson", "--radius", "0", *OUT],
         r"radius must be a positive number of metres, got 0",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-radius-1e308", MISSION, ["--area", "{tmp}/f.geojson", "--radius", "1e308", *OUT],
         r"--radius 1e\+308: expected at most 4775 m: no Litchi mission flies a larger orbit",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
    Case("area-take-off-latitude", MISSION, ["--area", "{tmp}/f.geojson", "--home", "91", "44.5", *OUT],
         r"--home: latitude must be within",
         files(f_geojson=geojson({"type": "Polygon", "coordinates": [SQUARE]}))),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    result = run_case(case, tmp_path)
    assert_refused(result, case, tmp_path)
    assert not result.out.strip(), f"{case.id}: stdout on a refusal: {result.out!r}"


@pytest.mark.timeout(30)  # the field was opened and read: a FIFO no one writes to waited for ever
def test_a_fifo_as_the_field_is_refused_before_it_is_read(tmp_path):
    case = Case("area-fifo", MISSION, ["--area", "{tmp}/f.geojson", *OUT],
                r"--area \S+f\.geojson: is not a regular file \(a FIFO, socket or device\); expected a \.kml or "
                r"\.geojson file", lambda tmp: os.mkfifo(tmp / "f.geojson"))
    assert_refused(run_case(case, tmp_path), case, tmp_path)


ROOT = Path(__file__).resolve().parents[2]
#: About 1 km² at the demo location: 305 orbits in 150 flights, whose CSVs take a few hundred ms to write.
LARGE_FIELD = [[44.49, 40.175], [44.502, 40.175], [44.502, 40.184], [44.49, 40.184], [44.49, 40.175]]


def test_an_area_plan_killed_while_writing_leaves_no_half_plan_and_the_rerun_completes(tmp_path):
    """kill -9 once a few of the 150 flight CSVs are on disk: --out shows no plan file (the half plan would refuse
    every rerun as 'already holds a plan'), and the same command then writes the whole plan, nothing else left."""
    files(f_geojson=geojson({"type": "Polygon", "coordinates": [LARGE_FIELD]}))(tmp_path)
    argv = ["--area", str(tmp_path / "f.geojson"), "--out", str(tmp_path / "plan")]
    process = subprocess.Popen([sys.executable, "-m", "flightplan", *argv], cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, env={**os.environ, "PYTHONPATH": str(ROOT)})
    deadline = time.monotonic() + 60
    while len(list(tmp_path.rglob("flight_*.csv"))) < 5 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    process.send_signal(signal.SIGKILL)
    assert process.wait() == -signal.SIGKILL, "the plan was written before the kill: the test needs a larger field"
    assert not [path.name for path in (tmp_path / "plan").iterdir() if not path.name.startswith(".")]
    rerun = run_case(Case("area-rerun", MISSION, argv, ""), tmp_path)
    assert rerun.code == 0, rerun.err
    plan = json.loads((tmp_path / "plan" / "area.json").read_text())
    assert len(plan["flights"]) == 150
    assert sorted(path.name for path in (tmp_path / "plan").iterdir()) == sorted(
        [*(f"flight_{number:02d}.csv" for number in range(1, 151)),
         "area.kml", "area.geojson", "area.png", "area.json"])
