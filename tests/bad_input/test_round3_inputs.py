"""Hostile inputs of issue 40's re-run: numbers too small for a Litchi mission, a refusal whose advice would
delete the field it planned, a capture sun at a noise azimuth, a labeller run over exact labels, a damaged EXIF
and a truncated photo under ``geotag --write-exif``.

Refusals are one stderr line naming the argument or file, exit 2, nothing written (:mod:`tests.bad_input.harness`).
Where the input is valid but tiny (a height of 1e-300 m), the plan is written with numbers of bounded length.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from flightplan import litchi
from sim.worlds import demo_scene_dir
from tests.bad_input.harness import Case, assert_refused, run_case
from tests.bad_input.test_ingest_geotag import GEOTAG, flight

MISSION = "aerostereo-mission"
SQUARE = [[44.499, 40.179], [44.5, 40.179], [44.5, 40.18], [44.499, 40.18], [44.499, 40.179]]
#: Longest number a Litchi CSV or KML holds: 17 significant digits after at most 10 zeros, a sign and a point.
LONGEST_NUMBER = 30


def field_file(path: Path) -> None:
    """A GeoJSON field of about 85 x 111 m at ``path`` (its folder created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"type": "Polygon", "coordinates": [SQUARE]}))


def field_in_out_named_like_the_plan(tmp: Path) -> None:
    """The field is ``plan/area.geojson``: the name the plan's overview takes in ``--out plan``."""
    field_file(tmp / "plan" / "area.geojson")


def half_plan_beside_the_field(tmp: Path) -> None:
    """``plan`` holds an interrupted run's flight_01.csv and area.kml, and the field ``area.old.geojson``, which
    an ``area.*`` pattern would match."""
    field_file(tmp / "plan" / "area.old.geojson")
    (tmp / "plan" / "flight_01.csv").write_text("latitude\n")
    (tmp / "plan" / "area.kml").write_text("<kml/>\n")


def demo_world_folder(tmp: Path) -> None:
    """A copy of the small demo world's scene folder (exact labels from the generator) in ``tmp/world``."""
    shutil.copytree(demo_scene_dir("small"), tmp / "world")


def flight_with_a_truncated_photo(tmp: Path) -> None:
    """The synthetic flight with DJI_0005.JPG cut 2 bytes short: its EOI marker is gone (PIL still reads its
    EXIF and geotag tags it)."""
    flight(tmp)
    photo = tmp / "photos" / "DJI_0005.JPG"
    photo.write_bytes(photo.read_bytes()[:-2])


def cut_ifd_pointer(photo: Path, tag: int) -> None:
    """Point ``photo``'s IFD0 entry ``tag`` (0x8769: the Exif IFD) 4 bytes before the end of its EXIF block, so the
    sub-IFD's entries run past it (PIL: "Corrupt EXIF data")."""
    data = bytearray(photo.read_bytes())
    tiff = data.index(b"Exif\x00\x00") + 6
    tiff_length = int.from_bytes(data[tiff - 8:tiff - 6], "big") - 8
    order = "<" if data[tiff:tiff + 2] == b"II" else ">"
    ifd0 = tiff + struct.unpack_from(f"{order}L", data, tiff + 4)[0]
    for k in range(struct.unpack_from(f"{order}H", data, ifd0)[0]):
        entry = ifd0 + 2 + 12 * k
        if struct.unpack_from(f"{order}H", data, entry)[0] == tag:
            struct.pack_into(f"{order}L", data, entry + 8, tiff_length - 4)
    photo.write_bytes(bytes(data))


CASES = [
    Case("mission-speed-and-interval-1e-300", MISSION,
         ["--demo", "--speed-kmh", "1e-300", "--interval", "1e-300", "--out", "{tmp}/M.csv"],
         r"argument --speed-kmh: expected km/h in \[0\.36, 54\], got '1e-300'"),
    Case("mission-speed-1e-300", MISSION, ["--demo", "--speed-kmh", "1e-300", "--out", "{tmp}/M.csv"],
         r"argument --speed-kmh: expected km/h in \[0\.36, 54\]"),
    Case("mission-interval-1e-300", MISSION, ["--demo", "--interval", "1e-300", "--out", "{tmp}/M.csv"],
         r"argument --interval: expected seconds in \[0\.1, 6000\], got '1e-300'"),
    Case("mission-ring-height-beyond-litchi", MISSION, ["--demo", "--rings", "10:1000", "--out", "{tmp}/M.csv"],
         r"argument --rings: a ring's HEIGHT is metres above take-off in \[-200, 500\], got '1000'"),
    Case("mission-area-speed-and-interval-1e-300", MISSION,
         ["--area", "{tmp}/f.geojson", "--speed-kmh", "1e-300", "--interval", "1e-300", "--out", "{tmp}/plan"],
         r"argument --speed-kmh: expected km/h in \[0\.36, 54\]", lambda tmp: field_file(tmp / "f.geojson")),
    Case("mission-area-transit-speed-1e-300", MISSION,
         ["--area", "{tmp}/f.geojson", "--transit-speed-kmh", "1e-300", "--out", "{tmp}/plan"],
         r"argument --transit-speed-kmh: expected km/h in \[0\.36, 46\.8\]", lambda tmp: field_file(tmp / "f.geojson")),
    Case("mission-area-field-in-out-under-a-plan-name", MISSION,
         ["--area", "{tmp}/plan/area.geojson", "--out", "{tmp}/plan"],
         r"--area \S+area\.geojson: lies in --out \S+plan under a name the plan writes; move the field",
         field_in_out_named_like_the_plan),
    Case("mission-area-half-plan-beside-the-field", MISSION,
         ["--area", "{tmp}/plan/area.old.geojson", "--out", "{tmp}/plan"],
         r"holds part of a plan \(no area\.json: an interrupted run\); delete area\.kml flight_01\.csv there, or",
         half_plan_beside_the_field),
    Case("recon-capture-sun-azimuth-1e308", "aerostereo-recon",
         ["--photos", "{tmp}/photos", "--out", "{tmp}/scene", "--capture-sun", "1e308,45"],
         r"argument --capture-sun: expected an azimuth in \[-360, 360\] and an elevation in \(0, 90\] degrees, "
         r"got '1e308,45'"),
    Case("recon-labels-on-a-demo-world", "aerostereo-recon", ["labels", "{tmp}/world"],
         r"world: its labels \(labels\.npz\) are exact, from the world generator", demo_world_folder),
    Case("geotag-write-exif-truncated-photo", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv", "--write-exif"],
         r"photos/DJI_0005\.JPG: JPEG: truncated: the file ends at byte \d+ before the image data's EOI marker",
         flight_with_a_truncated_photo),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_refused_labels_run_leaves_the_exact_labels_as_they_were(tmp_path):
    case = next(c for c in CASES if c.id == "recon-labels-on-a-demo-world")
    demo_world_folder(tmp_path)
    before = {p.name: p.read_bytes() for p in (tmp_path / "world").iterdir()}
    assert run_case(Case(case.id, case.program, case.argv, case.expect), tmp_path).code == 2
    assert {p.name: p.read_bytes() for p in (tmp_path / "world").iterdir()} == before


@pytest.mark.parametrize("argv", [["--demo", "--height", "1e-300"], ["--demo", "--poi-height", "1e-300"],
                                  ["--demo", "--height", "5e-324"], ["--demo", "--rings", "10:1e-300"],
                                  ["--lat", "1e-300", "--lon", "0"]], ids=" ".join)
def test_a_tiny_valid_number_is_written_with_bounded_text(argv, tmp_path):
    """A height of 1e-300 m is 0 m to Litchi and the aircraft: written as ``0`` (not 302 digits) in the CSV and the
    KML; a centre 1e-300 deg from 0,0 keeps its POI (Litchi reads a written 0,0 as none)."""
    case = Case("tiny", MISSION, [*argv, "--out", "{tmp}/M.csv", "--kml", "{tmp}/M.kml"], "")
    result = run_case(case, tmp_path)
    assert result.code == 0, result.err
    csv_text, kml_text = (tmp_path / "M.csv").read_text(), (tmp_path / "M.kml").read_text()
    cells = [cell for line in csv_text.splitlines()[1:] for cell in line.split(",")]
    kml_numbers = [n for block in kml_text.split("<coordinates>")[1:]
                   for n in block.split("</coordinates>")[0].replace(" ", ",").split(",")]
    assert max(map(len, cells + kml_numbers)) <= LONGEST_NUMBER
    mission = litchi.parse_mission_csv(csv_text)
    tiny = {"--height": "altitude_m", "--poi-height": "poi_altitude_m", "--rings": "altitude_m"}.get(argv[1])
    if tiny:
        assert set(mission.column(tiny)) == {0.0}
    assert all(w.has_poi for w in mission.waypoints)


def test_a_damaged_exif_is_a_counted_note_not_a_pil_warning(tmp_path):
    """PIL warns "Corrupt EXIF data" for a photo whose Exif IFD runs past its EXIF block and reads on: geotag says
    so as a note of the photo report (the photo untagged: its time was in that IFD), and no warning reaches
    stderr; --write-exif copies the other photos."""
    flight(tmp_path)
    cut_ifd_pointer(tmp_path / "photos" / "DJI_0005.JPG", 0x8769)
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in [*GEOTAG, "--out", "{tmp}/g.csv", "--write-exif"]]
    run = subprocess.run([sys.executable, "-m", "capture", *argv], capture_output=True, text=True, cwd=tmp_path,
                         env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(Path(__file__).parents[2])})
    assert run.returncode == 0, run.stderr
    assert "Warning" not in run.stderr and "warnings.warn" not in run.stderr, run.stderr
    assert "note: DJI_0005.JPG: EXIF: damaged (Corrupt EXIF data." in run.stderr
    assert "1 of 8 photos have unusable metadata" in run.stderr
    assert "untagged DJI_0005.JPG: no EXIF DateTimeOriginal" in run.stderr
    assert sorted(p.name for p in (tmp_path / "geotagged").iterdir()) == [f"DJI_{i:04d}.JPG" for i in range(8) if i != 5]
