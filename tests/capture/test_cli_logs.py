"""`geotag` and `track` subcommands through the real aerostereo-ingest entry point."""

import csv
import json
import xml.etree.ElementTree as ET
from datetime import datetime, timezone

import numpy as np
import pytest
from PIL import ExifTags, Image

from capture.cli import main
from capture.geotag_io import deg_to_dms, load_geotags
from capture.logs.photos import read_photo
from capture.logs.writers import write_litchi_csv
from capture.synthetic import Noise, Orbit, shutter_times, telemetry
from capture.track import source_name
from flightplan.demo_location import DEMO_ORIGIN

KML = "http://www.opengis.net/kml/2.2"


def run(argv):
    return main([str(a) for a in argv])


def write_jpeg(path, camera_time_s, lat_deg, lon_deg):
    """A tiny JPEG with the EXIF a DJI camera writes: DateTimeOriginal (whole seconds) and GPS."""
    exif = Image.Exif()
    stamp = datetime.fromtimestamp(np.floor(camera_time_s), tz=timezone.utc).strftime("%Y:%m:%d %H:%M:%S")
    exif.get_ifd(ExifTags.IFD.Exif)[ExifTags.Base.DateTimeOriginal] = stamp
    gps = exif.get_ifd(ExifTags.IFD.GPSInfo)
    gps[ExifTags.GPS.GPSLatitudeRef], gps[ExifTags.GPS.GPSLatitude] = "N", deg_to_dms(lat_deg)
    gps[ExifTags.GPS.GPSLongitudeRef], gps[ExifTags.GPS.GPSLongitude] = "E", deg_to_dms(lon_deg)
    Image.new("RGB", (16, 12), (90, 120, 60)).save(path, exif=exif)


@pytest.fixture()
def synthetic_flight(tmp_path):
    rng = np.random.default_rng(11)
    orbit, noise = Orbit(DEMO_ORIGIN), Noise(interval_jitter_s=0.05)
    shutter = shutter_times(orbit, 40.0, 1.0, noise, rng)
    write_litchi_csv(telemetry(orbit, 40.0, 10.0, noise, rng, shutter), tmp_path / "flight.csv")
    photos = tmp_path / "photos"
    photos.mkdir()
    lat, lon, _ = orbit.frame.to_geodetic(*orbit.enu(shutter).T)
    for i, s in enumerate(shutter):
        write_jpeg(photos / f"IMG_{i:04d}.JPG", s - 0.37, lat[i], lon[i])
    return orbit, shutter, tmp_path


def test_geotag_command_end_to_end(synthetic_flight, capsys):
    orbit, shutter, folder = synthetic_flight
    out = folder / "out" / "geotags.csv"
    code = run(["geotag", "--photos", folder / "photos", "--log", folder / "flight.csv", "--out", out,
                "--colmap-ref", folder / "out" / "ref.txt", "--write-exif"])
    printed = capsys.readouterr()
    assert code == 0 and f"{len(shutter)} photos geotagged, 0 untagged" in printed.out  # the result on stdout
    assert "clock offset" in printed.err and "[litchi]: 400 of 400 rows used" in printed.err  # the log on stderr
    sidecar = json.loads(out.with_suffix(".json").read_text())
    error = abs(sidecar["clock_offset_s"] - 0.37)  # 36 photos: the shutter phase spans little of a second
    assert error < 3 * sidecar["clock_offset_std_s"] + 0.02 and sidecar["clock_offset_std_s"] < 0.3
    priors = load_geotags(out)
    truth = orbit.frame.enu_points(*orbit.frame.to_geodetic(*orbit.enu(shutter).T))
    frame = priors[0].origin
    estimate = orbit.frame.enu_points(*frame.to_geodetic(*np.array([p.position_enu_m for p in priors]).T))
    assert np.abs(estimate[:, :2] - truth[:, :2]).max() < 0.07  # horizontal; h0 unknown in a Litchi log
    rows = list(csv.DictReader(out.open()))
    assert {row["source"] for row in rows} == {"litchi/event"}
    assert len((folder / "out" / "ref.txt").read_text().splitlines()) == len(shutter)
    tagged = read_photo(folder / "out" / "geotagged" / "IMG_0000.JPG")
    assert tagged.values["lat_deg"] == pytest.approx(float(rows[0]["lat_deg"]), abs=1e-8)
    assert tagged.values["gimbal_pitch_deg"] == pytest.approx(float(rows[0]["gimbal_pitch_deg"]), abs=1e-6)


def test_track_command_real_samples(shared_data, tmp_path, capsys):
    assert run(["track", shared_data / "litchi" / "airdata_mini2_imperial_head.csv",
                "--out", tmp_path / "t.csv", "--kml", tmp_path / "t.kml"]) == 0
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 51
    assert "<LineString>" in (tmp_path / "t.kml").read_text()
    # the layer (document) is named after the log file, without the folder it was read from
    names = [element.text for element in ET.parse(tmp_path / "t.kml").iter(f"{{{KML}}}name")]
    assert names == ["airdata_mini2_imperial_head", "track"]
    assert run(["track", shared_data / "dji" / "DJI_SRT_Parser__mavic_mini.SRT", "--start-time",
                "2020-01-01T10:00:00Z", "--out", tmp_path / "m.csv"]) == 0
    assert (tmp_path / "m.csv").read_text().splitlines()[1].startswith("2020-01-01T10:00:00.000000Z,")
    printed = capsys.readouterr().err
    assert "117 of 117 rows used" in printed


def test_track_names_are_file_names_without_folder_or_extension():
    assert source_name("/home/me/logs/DJIFlightRecord_2024-05-01.txt") == "DJIFlightRecord_2024-05-01"
    assert source_name("/data/a.SRT + /data/photos") == "a + photos"  # a merged track names each part
    assert source_name("synthetic") == "synthetic"


def test_geotag_from_the_photos_own_metadata(shared_data, tmp_path, capsys):
    images = shared_data / "brighton_beach" / "images"
    assert run(["geotag", "--photos", images, "--log", images, "--out", tmp_path / "g.csv"]) == 0
    priors = load_geotags(tmp_path / "g.csv")
    assert len(priors) == 18 and priors[0].position_enu_m[2] == pytest.approx(39.8)
    assert "(same-clock)" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["track", "{data}/brighton_beach/LICENSE", "--out", "{tmp}/x.csv"], "unknown log format"),
    (["track", "{tmp}/missing.csv", "--out", "{tmp}/x.csv"], "no such file"),
    (["track", "{data}/litchi/airdata_mini2_imperial_head.csv"], "give --out track.csv, --kml track.kml and/or --gpx"),
    (["geotag", "--photos", "{data}/brighton_beach/images", "--log", "{data}/dji/DJI_SRT_Parser__mavic_mini.SRT",
      "--out", "{tmp}/x.csv"], "no wall-clock time"),
    (["geotag", "--photos", "{data}/brighton_beach/images", "--log", "{data}/dji/DJI_SRT_Parser__mavic_pro.SRT",
      "--out", "{tmp}/x.csv"], "no photo could be geotagged"),
    (["geotag", "--photos", "{tmp}", "--log", "{data}/dji/DJI_SRT_Parser__mavic_pro.SRT", "--out", "{tmp}/x.csv"],
     "no readable JPEG"),
    (["geotag", "--photos", "{data}/brighton_beach/images", "--log", "{data}/brighton_beach/images",
      "--out", "{tmp}/x.csv", "--write-exif", "--exif-dir", "{data}/brighton_beach/images"],
     "images: is also --photos"),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(shared_data, tmp_path, capsys, argv, message):
    argv = [a.format(data=shared_data, tmp=tmp_path) for a in argv]
    assert run(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"aerostereo-ingest {argv[0]}: error: ") and message in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option, value, expected", [
    ("--clock-offset", "nan", "expected 'auto' or a finite number of seconds, got 'nan'"),
    ("--max-gap", "nan", "expected a positive number, got 'nan'"),
    ("--max-gap", "-1", "expected a positive number, got '-1'"),
    ("--srt-utc-offset", "inf", "expected a finite number, got 'inf'"),
])
def test_geotag_number_options_reject_nan_and_out_of_range(tmp_path, capsys, option, value, expected):
    assert run(["geotag", "--photos", tmp_path, "--log", tmp_path, "--out", tmp_path / "g.csv", option, value]) == 2
    assert f"aerostereo-ingest geotag: error: argument {option}: {expected}" in capsys.readouterr().err


def test_geotag_out_named_like_its_sidecar_is_refused_before_reading(tmp_path, capsys):
    assert run(["geotag", "--photos", tmp_path / "none", "--log", tmp_path / "none.csv",
                "--out", tmp_path / "geotags.json"]) == 2
    err = capsys.readouterr().err
    assert "geotags.json: the geotags CSV would overwrite its own .json sidecar; name it e.g. geotags.csv" in err
    assert list(tmp_path.iterdir()) == []


def test_geotag_counts_rejected_photos_per_reason(shared_data, tmp_path, capsys):
    photos = tmp_path / "photos"
    photos.mkdir()
    for source in sorted((shared_data / "brighton_beach" / "images").glob("*.JPG"))[:3]:
        (photos / source.name).write_bytes(source.read_bytes())
    for name in ("BAD1.JPG", "BAD2.JPG"):
        (photos / name).write_text("not a JPEG")
    assert run(["geotag", "--photos", photos, "--log", photos, "--out", tmp_path / "g.csv"]) == 0
    printed = capsys.readouterr().err
    assert f"{photos} [photos]: 3 of 5 rows used; rejected 2 unreadable photo\n" in printed


def test_photo_position_out_of_range_is_ignored_and_said_why(tmp_path):
    write_jpeg(tmp_path / "IMG_0000.JPG", 1.7e9, 95.0, 18.5)  # 95 degrees north
    photo = read_photo(tmp_path / "IMG_0000.JPG")
    assert "lat_deg" not in photo.values and "lon_deg" not in photo.values
    assert photo.problems == ["GPS: position out of range: latitude must be within [-90, 90] degrees, got 95.0, "
                              "ignored"]
