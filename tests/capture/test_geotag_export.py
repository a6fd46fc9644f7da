"""Geotag exports, each read the way its consumer reads it: GPX against the GPX 1.1 schema (subset, tests/data),
ODM's geo.txt split the way ODM's docs define it, COLMAP's reference columns; every height is the geotag's."""

import csv
import json
from pathlib import Path
from xml.etree import ElementTree

import pytest
import xmlschema

from capture.cli import main
from capture.track import parse_utc

GPX_SCHEMA = Path(__file__).parents[1] / "data" / "gpx-1.1-subset.xsd"
GPX = "{http://www.topografix.com/GPX/1/1}"


def run(argv):
    return main([str(a) for a in argv])


def geotag_rows(csv_path) -> dict[str, dict[str, str]]:
    with open(csv_path, newline="") as handle:
        return {row["image_name"]: row for row in csv.DictReader(handle)}


def read_odm_geo(path) -> tuple[str, dict[str, list[float]]]:
    """ODM's image geolocation file as its docs define it: line 1 the projection; then per line
    ``image_name geo_x geo_y [geo_z] ...`` split on whitespace (blank lines and ``#`` comments skipped)."""
    lines = [line.strip() for line in Path(path).read_text().strip().split("\n")]
    entries = {}
    for line in lines[1:]:
        if line and not line.startswith("#"):
            name, *numbers = line.split()
            entries[name] = [float(v) for v in numbers]
    return lines[0], entries


@pytest.fixture(scope="module")
def brighton_geotags(shared_data, tmp_path_factory):
    """Real DJI photos geotagged from their own EXIF/XMP: absolute heights above sea level (datum known)."""
    out = tmp_path_factory.mktemp("brighton") / "geotags.csv"
    images = shared_data / "brighton_beach" / "images"
    assert run(["geotag", "--photos", images, "--log", images, "--out", out]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["origin_height_datum"] == "mean_sea_level"
    return out


def test_gpx_validates_and_carries_each_photos_time_position_and_height(brighton_geotags, tmp_path):
    gpx = tmp_path / "photos.gpx"
    assert run(["export", brighton_geotags, "--gpx", gpx]) == 0
    xmlschema.XMLSchema(GPX_SCHEMA).validate(gpx)
    rows = geotag_rows(brighton_geotags)
    tracks = ElementTree.parse(gpx).getroot().findall(f"{GPX}trk")
    assert len(tracks) == 1 and len(tracks[0].findall(f"{GPX}trkseg")) == 1
    points = tracks[0].findall(f"{GPX}trkseg/{GPX}trkpt")
    assert len(points) == len(rows) == 18
    times = [parse_utc(p.find(f"{GPX}time").text) for p in points]
    assert times == sorted(times)
    for point, time_s in zip(points, times):
        row = rows[point.find(f"{GPX}name").text]
        assert time_s == pytest.approx(parse_utc(row["utc_time"]), abs=1e-6)
        assert float(point.get("lat")) == pytest.approx(float(row["lat_deg"]), abs=1e-9)
        assert float(point.get("lon")) == pytest.approx(float(row["lon_deg"]), abs=1e-9)
        assert float(point.find(f"{GPX}ele").text) == pytest.approx(float(row["absolute_height_m"]), abs=1e-6)
    assert "." in points[0].find(f"{GPX}time").text  # sub-second time kept


def test_odm_geo_txt_is_epsg_4326_lon_lat_and_absolute_height(brighton_geotags, tmp_path):
    geo = tmp_path / "geo.txt"
    assert run(["export", brighton_geotags, "--odm-geo", geo]) == 0
    crs, entries = read_odm_geo(geo)
    rows = geotag_rows(brighton_geotags)
    assert crs == "EPSG:4326" and set(entries) == set(rows)
    for name, (x, y, z) in entries.items():
        assert (x, y) == pytest.approx((float(rows[name]["lon_deg"]), float(rows[name]["lat_deg"])), abs=1e-9)
        assert z == pytest.approx(float(rows[name]["absolute_height_m"]), abs=1e-6)
    assert entries["DJI_0018.JPG"][0] < 0  # Brighton Beach, Minnesota: x is the (western) longitude


def test_colmap_reference_is_name_and_enu_metres(brighton_geotags, tmp_path):
    ref = tmp_path / "ref.txt"
    assert run(["export", brighton_geotags, "--colmap-ref", ref]) == 0
    rows = geotag_rows(brighton_geotags)
    lines = ref.read_text().splitlines()
    assert len(lines) == len(rows)
    for line in lines:
        name, *xyz = line.split()
        assert len(xyz) == 3 and name in rows
        assert [float(v) for v in xyz] == pytest.approx([float(rows[name][k]) for k in ("east_m", "north_m", "up_m")],
                                                        abs=1e-4)


def test_geotag_writes_the_same_exports_as_export(shared_data, brighton_geotags, tmp_path):
    images = shared_data / "brighton_beach" / "images"
    direct = {"--gpx": tmp_path / "a.gpx", "--odm-geo": tmp_path / "a.txt", "--colmap-ref": tmp_path / "a.ref"}
    later = {option: path.with_name("b" + path.suffix) for option, path in direct.items()}
    assert run(["geotag", "--photos", images, "--log", images, "--out", tmp_path / "g.csv",
                *[v for pair in direct.items() for v in pair]]) == 0
    assert run(["export", tmp_path / "g.csv", *[v for pair in later.items() for v in pair]]) == 0
    for option in direct:
        assert direct[option].read_bytes() == later[option].read_bytes()


def test_unknown_absolute_heights_are_left_out_not_invented(brighton_geotags, tmp_path, capsys):
    """A log without absolute heights (Litchi) gives geotags whose datum is unknown: no GPX ele, no geo.txt z."""
    csv_path = tmp_path / "g.csv"
    csv_path.write_bytes(brighton_geotags.read_bytes())
    sidecar = json.loads(brighton_geotags.with_suffix(".json").read_text())
    csv_path.with_suffix(".json").write_text(json.dumps(sidecar | {"origin_height_datum": "unknown"}))
    assert run(["export", csv_path, "--gpx", tmp_path / "x.gpx", "--odm-geo", tmp_path / "geo.txt"]) == 0
    assert "18 of 18 geotags have no absolute height of known datum" in capsys.readouterr().err
    xmlschema.XMLSchema(GPX_SCHEMA).validate(tmp_path / "x.gpx")
    assert ElementTree.parse(tmp_path / "x.gpx").getroot().find(f".//{GPX}ele") is None
    assert {len(v) for v in read_odm_geo(tmp_path / "geo.txt")[1].values()} == {2}


@pytest.mark.parametrize("outputs, message", [
    ([], "give at least one of --gpx"),
    (["--gpx", "{csv}"], "--gpx {csv}: is also geotags"),
    (["--odm-geo", "{json}"], "is also (sidecar)"),
    (["--gpx", "{tmp}/same", "--colmap-ref", "{tmp}/same"], "--colmap-ref {tmp}/same: is also --gpx"),
])
def test_export_refusals_are_one_line_and_write_nothing(brighton_geotags, tmp_path, capsys, outputs, message):
    names = {"csv": brighton_geotags, "json": brighton_geotags.with_suffix(".json"), "tmp": tmp_path}
    before = {p: p.read_bytes() for p in (brighton_geotags, brighton_geotags.with_suffix(".json"))}
    assert run(["export", brighton_geotags, *[o.format(**names) for o in outputs]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message.format(**names) in err
    assert {p: p.read_bytes() for p in before} == before and list(tmp_path.iterdir()) == []


def test_image_names_with_whitespace_are_refused_for_line_formats(brighton_geotags, tmp_path, capsys):
    csv_path = tmp_path / "g.csv"
    csv_path.write_text(brighton_geotags.read_text().replace("DJI_0018.JPG", "DJI 0018.JPG"))
    csv_path.with_suffix(".json").write_bytes(brighton_geotags.with_suffix(".json").read_bytes())
    assert run(["export", csv_path, "--odm-geo", tmp_path / "geo.txt"]) == 2
    assert "'DJI 0018.JPG' holds whitespace" in capsys.readouterr().err
    assert not (tmp_path / "geo.txt").exists()


def test_track_gpx_of_a_real_airdata_log_carries_its_sea_level_heights(shared_data, tmp_path):
    log = shared_data / "litchi" / "airdata_mini2_imperial_head.csv"
    assert run(["track", log, "--gpx", tmp_path / "t.gpx", "--out", tmp_path / "t.csv"]) == 0
    xmlschema.XMLSchema(GPX_SCHEMA).validate(tmp_path / "t.gpx")
    points = ElementTree.parse(tmp_path / "t.gpx").getroot().findall(f".//{GPX}trkpt")
    with open(tmp_path / "t.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(points) == len(rows) == 50
    for point, row in zip(points, rows):
        assert parse_utc(point.find(f"{GPX}time").text) == pytest.approx(parse_utc(row["utc_time"]), abs=1e-6)
        assert float(point.get("lat")) == pytest.approx(float(row["lat_deg"]), abs=1e-9)
        # altitude_above_seaLevel(feet) in the log, metres here; not the height above take-off
        assert float(point.find(f"{GPX}ele").text) == pytest.approx(float(row["absolute_height_m"]), abs=1e-6)
        assert float(row["absolute_height_m"]) != pytest.approx(float(row["height_above_takeoff_m"]), abs=1.0)


def test_track_gpx_refuses_a_track_not_on_utc(shared_data, tmp_path, capsys):
    images = shared_data / "brighton_beach" / "images"  # photos: the camera's clock, not UTC
    assert run(["track", images, "--gpx", tmp_path / "t.gpx"]) == 2
    assert "GPX times are UTC, but this track's clock is 'camera'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_geotag_refuses_a_line_format_export_before_writing_anything(shared_data, tmp_path, capsys):
    photos = tmp_path / "photos"
    photos.mkdir()
    source = shared_data / "brighton_beach" / "images" / "DJI_0018.JPG"
    (photos / "DJI 0018.JPG").write_bytes(source.read_bytes())
    out = tmp_path / "out"
    out.mkdir()
    assert run(["geotag", "--photos", photos, "--log", photos, "--out", out / "g.csv",
                "--colmap-ref", out / "ref.txt"]) == 2
    assert "'DJI 0018.JPG' holds whitespace" in capsys.readouterr().err
    assert list(out.iterdir()) == []
