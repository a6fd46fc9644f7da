"""Geotags that cannot be wrong silently: photos and logs from different flights are refused, unusable EXIF/XMP
numbers are named and left out, and photos in telemetry gaps fall back to their own EXIF GPS and XMP attitude.

Real photos (``/work/shared/data``) are read in place; modified copies (bad XMP values, a text EXIF field) are
written to ``tmp_path``.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import re
import shutil

import numpy as np
import pytest
from PIL import ExifTags, Image

from capture.cli import main
from capture.geotag import MAX_AUTO_CLOCK_OFFSET_S, PHOTO_SOURCE, geotag_photos
from capture.geotag_io import write_geotags
from capture.logs import read_track
from capture.logs.photos import read_photo, read_photos
from capture.logs.writers import write_litchi_csv
from capture.synthetic import Noise, Orbit, photos_for, shutter_times, telemetry
from capture.track import Track
from flightplan import litchi
from cliutil.errors import BadInput
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import geodesic_inverse
from flightplan.orbit import OrbitRequest, plan_orbit
from tests.capture.virtual_flights import START, assert_within_the_noise_model, virtual_flight
from tests.sim.drone_helpers import short_orbit_csv

YEREVAN_2024 = START.timestamp()
GPS_ALTITUDE_ENTRY = b"\x06\x00\x05\x00\x01\x00\x00\x00"  # little-endian GPS IFD entry: GPSAltitude, RATIONAL, 1


def yerevan_log(path, start_s=YEREVAN_2024, duration_s=120.0):
    """A Litchi flight log of the synthetic orbit around the demo origin (Yerevan), from ``start_s`` (UTC)."""
    rng = np.random.default_rng(3)
    orbit, noise = Orbit(DEMO_ORIGIN, start_s=start_s), Noise(interval_jitter_s=0.05)
    shutter = shutter_times(orbit, duration_s, 1.0, noise, rng)
    write_litchi_csv(telemetry(orbit, duration_s, 10.0, noise, rng, shutter), path)
    return orbit, shutter


def with_xmp_text(source, target, **texts):
    """Copy a DJI JPEG, replacing ``drone-dji:TAG`` attribute values by ``texts`` (padded with spaces to the
    old length, so no segment length changes; the reader strips them)."""
    data = source.read_bytes()
    for tag, text in texts.items():
        match = re.search(rb'drone-dji:%s="([^"]*)"' % tag.encode(), data)
        assert match and len(text) <= len(match.group(1)), tag
        data = data[:match.start(1)] + text.encode().ljust(len(match.group(1))) + data[match.end(1):]
    target.write_bytes(data)


def with_text_gps_altitude(source, target, text=b"abc"):
    """Copy a DJI JPEG whose EXIF GPSAltitude (a RATIONAL) becomes the ASCII text ``text`` (3 bytes + NUL,
    stored inline in the IFD entry)."""
    data = source.read_bytes()
    assert data.count(GPS_ALTITUDE_ENTRY) == 1 and len(text) == 3
    at = data.index(GPS_ALTITUDE_ENTRY)
    target.write_bytes(data[:at] + b"\x06\x00\x02\x00\x04\x00\x00\x00" + text + b"\x00" + data[at + 12:])


def rows(csv_path):
    with open(csv_path, encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))


# --- photos and logs from different flights -------------------------------------------------------------------

def test_minnesota_photos_against_a_yerevan_log_are_refused(shared_data, tmp_path):
    """The issue's case: 2016 Minnesota photos, a 2024 Yerevan log with shutter events. The automatic offset would
    be 7.85 years; it is bounded to what a camera clock can be off, so the match is refused, saying by how much."""
    yerevan_log(tmp_path / "yerevan.csv")
    photos, _ = read_photos(shared_data / "brighton_beach" / "images")
    with pytest.raises(BadInput, match=r"at least 7\.8\d years apart .*2016-06-23T16:31:59.*beyond the \+-14\.5 h "
                                       r".*give --clock-offset SECONDS"):
        geotag_photos(photos, [read_track(tmp_path / "yerevan.csv")])


def test_a_forced_clock_offset_still_meets_the_position_check(shared_data, tmp_path):
    """With the 7.85-year offset forced, the photos' own GPS (Minnesota) is thousands of km from the track
    (Yerevan): refused with the geodesic distance; --max-misfit above it accepts the match."""
    orbit, shutter = yerevan_log(tmp_path / "yerevan.csv")
    photos, _ = read_photos(shared_data / "brighton_beach" / "images")
    offset = shutter[0] - min(p.exif_time_s for p in photos)  # first photo onto the first shutter event
    distance_km = geodesic_inverse(photos[0].values["lat_deg"], photos[0].values["lon_deg"],
                                   DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg).distance_m / 1000
    track = read_track(tmp_path / "yerevan.csv")
    with pytest.raises(BadInput, match=r"median (\d+) km .*more than the 9 m .*--max-misfit \d+") as refused:
        geotag_photos(photos, [track], clock_offset=offset)
    median_km = float(re.search(r"median (\d+) km", str(refused.value)).group(1))
    assert median_km == pytest.approx(distance_km, abs=1.0)  # the orbit is 50 m around the origin
    forced = geotag_photos(photos, [track], clock_offset=offset, max_misfit_m=1e7)
    assert len(forced.tags) > 0 and any(re.search(r"photo GPS vs geotags.*median \d+\.\d+ m", n) for n in forced.notes)


@pytest.mark.parametrize("shift_m, lifted_m", [(300.0, 400.0), (30.0, 40.0)])
def test_photo_gps_far_from_the_track_at_the_same_time_is_refused(shift_m, lifted_m):
    """Same time, other place: every photo's own GPS is ``shift_m`` north of where the track puts it. Beyond the
    9 m a consumer GPS can be off (the photos' and the log's are one receiver), no clock offset fits: refused,
    naming the median; --max-misfit above it (photos whose GPS is known to be off) accepts the match."""
    orbit = Orbit(DEMO_ORIGIN)
    rng = np.random.default_rng(8)
    shutter = shutter_times(orbit, 120.0, 1.0, Noise(interval_jitter_s=0.05), rng)
    track = telemetry(orbit, 120.0, 10.0, Noise(interval_jitter_s=0.05), rng, shutter)
    photos = photos_for(shutter, 0.37, orbit)
    for photo in photos:
        east, north, _ = orbit.frame.to_enu(photo.values["lat_deg"], photo.values["lon_deg"], 0.0)
        lat, lon, _ = orbit.frame.to_geodetic(east, north + shift_m, 0.0)
        photo.values.update(lat_deg=float(lat), lon_deg=float(lon))
    with pytest.raises(BadInput, match=r"median [\d.]+ m \(max [\d.]+ m, \d+ photos\) from the logs' track at every "
                                       r"clock offset the shutter events allow .*more than the 9 m .*--max-misfit \d+"):
        geotag_photos(photos, [track])
    accepted = geotag_photos(photos, [track], max_misfit_m=lifted_m)
    assert len(accepted.tags) == len(photos) and abs(accepted.clock.offset_s - 0.37) < 0.1
    medians = [float(m.group(1)) for note in accepted.notes
               if (m := re.search(r"GPS vs geotags.*median ([\d.]+) m", note))]
    assert medians == [pytest.approx(shift_m, abs=0.1)]  # geodesic vs a north shift in the tangent plane: ~5 cm


@pytest.mark.parametrize("hours, refused", [(14.0, False), (-12.0, False), (15.0, True)])
def test_the_automatic_clock_offset_spans_every_time_zone_and_no_more(hours, refused):
    """A camera set to local time anywhere (UTC-12 .. UTC+14) is found; 15 h is beyond the bound."""
    orbit = Orbit(DEMO_ORIGIN)
    rng = np.random.default_rng(9)
    shutter = shutter_times(orbit, 120.0, 1.0, Noise(interval_jitter_s=0.05), rng)
    track = telemetry(orbit, 120.0, 10.0, Noise(interval_jitter_s=0.05), rng, shutter)
    camera_ahead_s = hours * 3600.0 + 0.37  # camera clock - UTC
    photos = photos_for(shutter, -camera_ahead_s, orbit)
    if refused:
        assert abs(camera_ahead_s) > MAX_AUTO_CLOCK_OFFSET_S
        with pytest.raises(BadInput, match=r"at least 15 h apart"):
            geotag_photos(photos, [track])
        return
    result = geotag_photos(photos, [track])
    assert result.clock.offset_s == pytest.approx(-camera_ahead_s, abs=0.1)
    assert len(result.tags) == len(photos) and not result.from_photos


# --- unusable EXIF/XMP numbers ---------------------------------------------------------------------------------

def test_bad_xmp_numbers_are_left_out_named_and_counted(shared_data, tmp_path):
    """inf / nan / 1e308 / text in XMP: that field is missing (the EXIF GPS value is used where there is one), the
    photo and the value are named, the photos with problems counted; nothing unphysical reaches geotags.csv."""
    images = sorted((shared_data / "p4m_rtk" / "images").glob("*.JPG"))[:4]
    photos = tmp_path / "photos"
    photos.mkdir()
    with_xmp_text(images[0], photos / images[0].name, GpsLatitude="inf", AbsoluteAltitude="1e308")
    with_xmp_text(images[1], photos / images[1].name, GimbalYawDegree="nan", FlightPitchDegree="abc")
    for image in images[2:]:
        shutil.copy(image, photos / image.name)

    bad, clean = read_photo(photos / images[0].name), read_photo(images[0])
    assert bad.values["lat_deg"] == pytest.approx(clean.values["lat_deg"], abs=1e-6)  # from EXIF GPS instead
    assert bad.values["absolute_height_m"] == pytest.approx(clean.values["absolute_height_m"], abs=0.05)
    assert bad.problems == ["XMP: drone-dji:GpsLatitude = 'inf' is not a finite number within [-90, 90], ignored",
                            "XMP: drone-dji:AbsoluteAltitude = '1e308' is not a finite number within [-1000, 12000], "
                            "ignored"]
    odd = read_photo(photos / images[1].name)
    assert "gimbal_yaw_deg" not in odd.values and "aircraft_pitch_deg" not in odd.values
    assert odd.values["gimbal_pitch_deg"] == read_photo(images[1]).values["gimbal_pitch_deg"]
    _, report = read_photos(photos)
    assert report.notes[-1] == (f"2 of 4 photos have unusable metadata, those fields treated as missing: "
                                f"{images[0].name}, {images[1].name}")

    out = tmp_path / "out" / "geotags.csv"
    code, _, err = run_cli(["geotag", "--photos", photos, "--log", photos, "--out", out])
    assert code == 0 and f"{images[0].name}: XMP: drone-dji:GpsLatitude = 'inf'" in err
    assert "2 of 4 photos have unusable metadata" in err
    table = rows(out)
    assert len(table) == 4
    numbers = np.array([[float(row[k]) for k in ("lat_deg", "lon_deg", "absolute_height_m")] for row in table])
    assert np.isfinite(numbers).all() and (np.abs(numbers[:, 2]) < 1000).all()


def test_a_text_exif_number_names_the_photo_and_the_rest_go_on(shared_data, tmp_path):
    """One photo's EXIF GPSAltitude is the text 'abc': the run goes on, that photo keeps its position, the field
    is named; every photo is geotagged."""
    images = sorted((shared_data / "brighton_beach" / "images").glob("*.JPG"))[:3]
    photos = tmp_path / "photos"
    photos.mkdir()
    with_text_gps_altitude(images[0], photos / images[0].name)
    for image in images[1:]:
        shutil.copy(image, photos / image.name)
    photo = read_photo(photos / images[0].name)
    assert photo.problems == ["EXIF GPS: GPSAltitude 'abc' is not a number, ignored"]
    assert {"lat_deg", "lon_deg"} <= set(photo.values)
    code, _, err = run_cli(["geotag", "--photos", photos, "--log", photos, "--out", tmp_path / "g.csv"])
    assert code == 0 and f"{images[0].name}: EXIF GPS: GPSAltitude 'abc' is not a number" in err
    assert len(rows(tmp_path / "g.csv")) == 3


def test_unreadable_exif_time_parts_are_named_and_the_time_kept(tmp_path):
    """A sub-second or time-zone field that is not what EXIF says it is: named, ignored, the whole-second
    DateTimeOriginal kept (read as UTC, the clock offset then finds the zone)."""
    exif = Image.Exif()
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    sub[ExifTags.Base.DateTimeOriginal] = "2024:05:01 10:00:07"
    sub[ExifTags.Base.SubsecTimeOriginal], sub[ExifTags.Base.OffsetTimeOriginal] = "4x", "+ab:cd"
    Image.new("RGB", (8, 8)).save(tmp_path / "odd.jpg", exif=exif)
    photo = read_photo(tmp_path / "odd.jpg")
    assert photo.exif_time_s == START.timestamp() + 7.0 and photo.time_resolution_s == 1.0
    assert photo.problems == ["EXIF: SubSecTimeOriginal '4x' is not digits, ignored (whole seconds)",
                              "EXIF: OffsetTimeOriginal '+ab:cd' is not '+HH:MM', ignored"]
    assert not photo.exif_time_is_utc


def test_a_photo_that_wrote_its_time_zone_is_timed_in_utc(tmp_path):
    exif = Image.Exif()
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    sub[ExifTags.Base.DateTimeOriginal], sub[ExifTags.Base.OffsetTimeOriginal] = "2024:05:01 12:00:07", "+02:00"
    Image.new("RGB", (8, 8)).save(tmp_path / "zoned.jpg", exif=exif)
    photo = read_photo(tmp_path / "zoned.jpg")
    assert photo.exif_time_is_utc and photo.exif_time_s == START.timestamp() + 7.0


def run_cli(argv):
    """``aerostereo-ingest ARGV`` in-process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


# --- falling back to the photo's own metadata ------------------------------------------------------------------

def test_virtual_drone_photos_in_a_telemetry_gap_fall_back_to_their_own_exif_and_xmp(tmp_path):
    """A short virtual flight (realistic noise): its DUML capture loses 10 s of telemetry. The photos taken in the
    gap are tagged from their own EXIF GPS / XMP attitude (source photo_exif), within the GPS/barometer noise
    model of their true position and the attitude noise of their true rotation; the others from the log."""
    mission, track = virtual_flight(short_orbit_csv(tmp_path / "mission.csv"), tmp_path, seed=4)
    gap = (START.timestamp() + 30.0, START.timestamp() + 40.0)
    keep = (track.time_s < gap[0]) | (track.time_s > gap[1])
    events = track.photo_times_s[(track.photo_times_s < gap[0]) | (track.photo_times_s > gap[1])]
    gapped = dataclasses.replace(Track.from_rows(track.time_s[keep], {k: v[keep] for k, v in track.columns.items()},
                                                 track.report, photo_times_s=events, home=track.home),
                                 event_time_error_s=track.event_time_error_s)
    result = geotag_photos(read_photos(tmp_path / "photos")[0], [gapped])

    truth = mission.photos
    taken = np.flatnonzero(truth.taken)

    def within(margin_s):
        return {truth.names[i] for i in taken
                if gap[0] + margin_s < START.timestamp() + truth.t_s[i] < gap[1] - margin_s}

    in_gap = {name for name, _ in result.from_photos}
    assert len(within(0.5)) >= 4 and within(0.5) <= in_gap <= within(-0.5)  # the edges: shutter vs telemetry rows
    assert result.untagged == [] and len(result.tags) == len(taken)
    assert all("telemetry gap" in reason for _, reason in result.from_photos)
    fallen = [tag for tag in result.tags if tag.image_name in in_gap]
    assert {tag.source for tag in fallen} == {PHOTO_SOURCE}
    # the others from the log (a damaged camera push may hide an event: that photo's time is its EXIF time)
    assert {t.source for t in result.tags if t.image_name not in in_gap} <= {"duml/event", "duml/exif"}
    assert_within_the_noise_model(fallen, mission)
    assert any(f"{len(in_gap)} photos the logs could not tag" in note for note in result.notes)
    _, sidecar = write_geotags(result, tmp_path / "geotags.csv")
    written = json.loads(sidecar.read_text(encoding="utf-8"))["from_photos"]
    assert {image["image_name"] for image in written["images"]} == in_gap and "consumer GPS" in written["accuracy"]
    assert {row["source"] for row in rows(tmp_path / "geotags.csv") if row["image_name"] in in_gap} == {"photo_exif"}


def test_the_default_virtual_orbit_tags_every_photo(tmp_path):
    """The default orbit (450 photos, realistic noise, seed 0; about 5 s), whose link dropouts left 2 photos in a
    2.3 s telemetry gap untagged: every photo is tagged now, those 2 from their own EXIF/XMP, within the noise
    model."""
    plan = plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg))
    litchi.write_mission_csv(plan.mission, tmp_path / "orbit.csv")
    mission, track = virtual_flight(tmp_path / "orbit.csv", tmp_path, seed=0)
    result = geotag_photos(read_photos(tmp_path / "photos")[0], [track])
    assert len(result.tags) == int(mission.photos.taken.sum()) == 450 and result.untagged == []
    assert [reason for _, reason in result.from_photos] == ["in a telemetry gap of 2.30 s (limit 2 s)"] * 2
    fallen = [tag for tag in result.tags if tag.source == PHOTO_SOURCE]
    assert len(fallen) == 2
    assert_within_the_noise_model(fallen, mission)
