"""Geotagging a synthetic orbit with known poses: positions, attitude, clock offset, gaps, files."""

import dataclasses
import json
import math
import re

import numpy as np
import pytest
from defusedxml import ElementTree as SafeET
from PIL import Image
from scipy.spatial.transform import Rotation

from capture.geotag import HEIGHT_UNKNOWN, MEAN_SEA_LEVEL, Geotag, geotag_photos
from capture.geotag_export import colmap_reference_text
from capture.geotag_io import GEOTAG_COLUMNS, dji_calibration_attributes, dji_xmp_packet, load_geotags, write_geotags
from capture.logs import read_track
from capture.logs.photos import DRONE_DJI_NS, PhotoInfo
from capture.logs.writers import write_airdata_csv, write_litchi_csv, write_srt
from capture.synthetic import NOISE_FREE, Noise, Orbit, photos_for, shutter_times, telemetry
from capture.track import ReadReport, Track
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import LocalFrame

CAMERA_OFFSET_S = 0.37  # telemetry UTC - camera clock
NOISE = Noise(interval_jitter_s=0.05)


def flight(noise=NOISE, duration_s=460.0, rate_hz=10.0, seed=0):
    rng = np.random.default_rng(seed)
    orbit = Orbit(DEMO_ORIGIN)
    shutter = shutter_times(orbit, duration_s, 1.0, noise, rng)
    return orbit, shutter, telemetry(orbit, duration_s, rate_hz, noise, rng, shutter)


def errors(result, orbit, shutter):
    """Per tagged photo: position error (m) and attitude error (deg; None when a tag has no attitude) against the
    orbit's truth."""
    index = np.array([int(tag.image_name[4:8]) for tag in result.tags])
    h0 = result.origin.h0_m if result.origin_height_known else orbit.frame.h0_m
    truth_frame = LocalFrame(result.origin.lat0_deg, result.origin.lon0_deg, h0)
    truth = truth_frame.enu_points(*orbit.frame.to_geodetic(*orbit.enu(shutter[index]).T))
    estimate = np.array([tag.enu_m for tag in result.tags])
    if any(tag.R_world_cam is None for tag in result.tags):
        return np.linalg.norm(estimate - truth, axis=1), None
    rotations = Rotation.from_matrix(np.array([tag.R_world_cam for tag in result.tags]))
    angle = np.degrees((Rotation.from_matrix(orbit.R_world_cam(shutter[index])).inv() * rotations).magnitude())
    return np.linalg.norm(estimate - truth, axis=1), angle


def test_noisy_orbit_within_5cm_and_a_tenth_of_a_degree():
    orbit, shutter, track = flight()
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S, orbit), [track])
    assert len(result.tags) == len(shutter) > 400 and result.untagged == []
    assert all(tag.time_source == "event" for tag in result.tags)
    assert result.clock.method == "auto" and abs(result.clock.offset_s - CAMERA_OFFSET_S) < 0.05
    assert result.clock.std_s < 0.05
    position_error, angle_error = errors(result, orbit, shutter)
    assert position_error.max() < 0.05 and angle_error.max() < 0.1


def test_noise_free_orbit_within_1cm():
    orbit, shutter, track = flight(dataclasses.replace(NOISE_FREE, interval_jitter_s=0.05), seed=1)
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S, orbit), [track])
    assert abs(result.clock.offset_s - CAMERA_OFFSET_S) < 0.05
    position_error, angle_error = errors(result, orbit, shutter)
    assert position_error.max() < 0.01 and angle_error.max() < 0.01


def test_missing_and_extra_shutter_events():
    orbit, shutter, track = flight(duration_s=240.0, seed=2)
    rng = np.random.default_rng(5)
    events = track.photo_times_s
    dropped = rng.choice(len(events), size=10, replace=False)
    spurious = rng.uniform(events[0], events[-1], size=6)
    track = dataclasses.replace(track, photo_times_s=np.sort(np.concatenate([np.delete(events, dropped), spurious])))
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S, orbit), [track])
    # fewer clean pairs: the sub-second offset is less certain (offsets 0.15 .. 0.85 s fit within one agreeing pair,
    # and the photos' GPS cannot tell 0.7 s of a 0.7 m/s orbit apart), but never off by more than it says, and
    # never by a whole second
    assert abs(result.clock.offset_s - CAMERA_OFFSET_S) < min(3 * result.clock.std_s + 0.02, 0.5)
    from_exif = {tag.image_name for tag in result.tags if tag.time_source == "exif"}
    assert {f"IMG_{i:04d}.JPG" for i in dropped} <= from_exif and len(from_exif) <= 10 + 6
    position_error, _ = errors(result, orbit, shutter)
    by_event = np.array([tag.time_source == "event" for tag in result.tags])
    # a photo whose event is missing may catch a spurious one inside its EXIF second: +-0.5 s of flight at most
    assert np.mean(position_error[by_event] < 0.05) > 0.95
    assert position_error.max() < 0.5 * orbit.speed_m_s + 0.05


def test_photos_without_gps_still_align_or_say_ambiguous():
    orbit, shutter, track = flight(duration_s=240.0, seed=3)
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S), [track])
    if "ambiguous" not in result.clock.note:
        assert abs(result.clock.offset_s - CAMERA_OFFSET_S) < 0.05


def test_manual_offset_and_gaps_are_reported_not_extrapolated():
    """Photos in a telemetry gap are tagged from their own GPS (source photo_exif) with the gap as the reason;
    a photo outside the track without GPS of its own stays untagged, saying both."""
    orbit, shutter, track = flight(duration_s=120.0, seed=4)
    keep = (track.time_s < orbit.start_s + 50.0) | (track.time_s > orbit.start_s + 56.0)
    gapped = Track.from_rows(track.time_s[keep], {k: v[keep] for k, v in track.columns.items()}, track.report,
                             photo_times_s=track.photo_times_s)
    early = PhotoInfo(photos_for(shutter[:1], 0.0)[0].path.with_name("EARLY.JPG"), orbit.start_s - 30.0)
    photos = photos_for(shutter, CAMERA_OFFSET_S, orbit) + [early]
    result = geotag_photos(photos, [gapped], clock_offset=CAMERA_OFFSET_S, max_gap_s=2.0)
    assert result.clock.method == "manual" and result.clock.offset_s == CAMERA_OFFSET_S
    in_gap = [f"IMG_{i:04d}.JPG" for i, s in enumerate(shutter) if orbit.start_s + 50.0 < s < orbit.start_s + 56.0]
    reasons = dict(result.from_photos)
    assert in_gap and sorted(reasons) == in_gap
    assert all(re.search(r"telemetry gap of 6\.\d+ s", reasons[name]) for name in in_gap)
    assert [name for name, _ in result.untagged] == ["EARLY.JPG"]
    assert re.search(r"outside the track's time span.*no usable GPS position", result.untagged[0][1])
    assert len(result.tags) == len(shutter)
    fallen = [tag for tag in result.tags if tag.image_name in reasons]
    assert {tag.source for tag in fallen} == {"photo_exif"} and all(tag.R_world_cam is None for tag in fallen)
    assert {tag.source for tag in result.tags} - {"photo_exif"} == {"synthetic/event"}
    # the photo's own GPS is the truth here: the fallback position is it, in the geotags' frame
    position_error, _ = errors(dataclasses.replace(result, tags=fallen), orbit, shutter)
    assert position_error.max() < 0.01
    assert any(f"{len(in_gap)} photos the logs could not tag" in note for note in result.notes)


@pytest.mark.parametrize("writer", ["litchi", "airdata", "airdata-metric"])
def test_flight_log_files_end_to_end(tmp_path, writer):
    orbit, shutter, track = flight(duration_s=150.0, seed=6)
    path = tmp_path / f"{writer}.csv"
    if writer == "litchi":
        write_litchi_csv(track, path)
    else:
        write_airdata_csv(track, path, "metric" if writer.endswith("metric") else "imperial")
    log = read_track(path)
    assert log.report.rejected == [] and len(log.photo_times_s) == len(shutter)
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S, orbit), [log])
    assert abs(result.clock.offset_s - CAMERA_OFFSET_S) < 0.05
    position_error, angle_error = errors(result, orbit, shutter)
    # 10 Hz photo flags: a rising edge places the shutter within +-50 ms (+-3.5 cm of flight)
    assert position_error.max() < 0.07 and angle_error.max() < 0.1


def test_dated_srt_has_no_events_so_exif_times_are_used(tmp_path):
    orbit, shutter, track = flight(duration_s=60.0, seed=7)
    write_srt(track, tmp_path / "flight.srt", "dated")
    log = read_track(tmp_path / "flight.srt")
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S, orbit), [log], clock_offset=CAMERA_OFFSET_S)
    assert result.untagged == [] and {tag.time_source for tag in result.tags} == {"exif"}
    position_error, _ = errors(result, orbit, shutter)
    assert position_error.max() < 0.5 * orbit.speed_m_s + 0.05


def test_nadir_across_the_yaw_wrap():
    times = np.array([0.0, 1.0, 2.0]) + 1.6e9
    columns = {"lat_deg": np.full(3, 40.0), "lon_deg": np.full(3, 44.0), "height_above_takeoff_m": np.full(3, 30.0),
               "gimbal_yaw_deg": np.array([178.0, -179.0, -176.0]), "gimbal_pitch_deg": np.full(3, -90.0)}
    track = Track.from_rows(times, columns, ReadReport("nadir", "synthetic"), photo_times_s=[times[0] + 0.5])
    result = geotag_photos([PhotoInfo(photos_for(times[:1], 0.0)[0].path, times[0])], [track])
    tag = result.tags[0]
    assert tag.gimbal_ypr_deg[0] == pytest.approx(179.5) and tag.gimbal_ypr_deg[1] == pytest.approx(-90.0)
    up = -tag.R_world_cam[:, 1]  # top of the image: along yaw 179.5 (south, 0.5 deg east of it)
    np.testing.assert_allclose(up, [np.sin(np.radians(179.5)), np.cos(np.radians(179.5)), 0.0], atol=1e-9)
    assert np.isnan(tag.aircraft_ypr_deg).all() and np.isnan(tag.absolute_height_m)


def test_geotag_files_round_trip(tmp_path):
    orbit, shutter, track = flight(duration_s=40.0, seed=8)
    result = geotag_photos(photos_for(shutter, CAMERA_OFFSET_S, orbit), [track])
    csv_path, json_path = write_geotags(result, tmp_path / "geotags.csv")
    lines = csv_path.read_text().splitlines()
    assert lines[0].split(",") == GEOTAG_COLUMNS and len(lines) == len(result.tags) + 1
    assert lines[1].split(",")[1].endswith("Z") and ".0" not in lines[1].split(",")[0]
    sidecar = json.loads(json_path.read_text())
    assert sidecar["origin"] == result.origin.to_dict() and sidecar["untagged"] == []
    assert sidecar["clock_offset_s"] == pytest.approx(result.clock.offset_s)
    priors = load_geotags(csv_path)
    for prior, tag in zip(priors, result.tags):
        np.testing.assert_allclose(prior.position_enu_m, tag.enu_m, atol=1e-8)
        np.testing.assert_allclose(prior.R_world_cam, tag.R_world_cam, atol=1e-8)
        assert prior.utc_time_s == pytest.approx(tag.time_s, abs=1e-6)
        assert (prior.lat_deg, prior.lon_deg) == pytest.approx((tag.lat_deg, tag.lon_deg), abs=1e-9)
        assert prior.absolute_height_m == pytest.approx(tag.absolute_height_m, abs=1e-6)
    first = colmap_reference_text(priors).splitlines()[0].split()
    assert first[0] == priors[0].image_name and [float(v) for v in first[1:]] == pytest.approx(priors[0].position_enu_m, abs=1e-4)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["geotags.csv", "geotags.json"]  # no temporaries left


@pytest.mark.parametrize("offset_s, subsecond", [(CAMERA_OFFSET_S, True), (-3600.0 + CAMERA_OFFSET_S, False)])
def test_subsecond_exif_and_an_hour_off_camera_clock(offset_s, subsecond):
    orbit, shutter, track = flight(duration_s=200.0, seed=9)
    result = geotag_photos(photos_for(shutter, offset_s, orbit, subsecond=subsecond), [track])
    # whole-second EXIF: the sub-second phases the pattern fits within one agreeing pair, which the photos' GPS
    # cannot tell apart on a 0.7 m/s orbit, set how well the offset is known (its std says it)
    assert abs(result.clock.offset_s - offset_s) < (0.01 if subsecond else min(3 * result.clock.std_s + 0.02, 0.5))
    position_error, _ = errors(result, orbit, shutter)
    assert position_error.max() < 0.05


def test_origin_height_datum_says_where_h0_came_from(tmp_path):
    orbit, shutter, track = flight(duration_s=40.0)
    photos = photos_for(shutter, CAMERA_OFFSET_S, orbit)
    result = geotag_photos(photos, [track])  # the synthetic log has absolute heights and no home record
    assert result.origin_height_datum == MEAN_SEA_LEVEL and result.origin.h0_m == pytest.approx(orbit.frame.h0_m)
    write_geotags(result, tmp_path / "g.csv")
    sidecar = json.loads((tmp_path / "g.json").read_text())
    assert sidecar["origin_height_datum"] == "mean_sea_level" and sidecar["origin_height_known"] is True
    without = Track.from_rows(track.time_s, {k: v for k, v in track.columns.items() if k != "absolute_height_m"},
                              track.report, photo_times_s=track.photo_times_s)
    # no absolute height in the log (a Litchi log): the photos' own minus the log's height above take-off then
    from_photos = geotag_photos(photos, [without])
    assert from_photos.origin_height_datum == MEAN_SEA_LEVEL
    assert from_photos.origin.h0_m == pytest.approx(orbit.frame.h0_m, abs=0.05)
    assert any(note.startswith("origin h0 = ") and f"median of {len(photos)} photos" in note for note in from_photos.notes)
    heights = np.array([tag.absolute_height_m for tag in from_photos.tags])
    np.testing.assert_allclose(heights, [p.values["absolute_height_m"] for p in photos], atol=0.1)  # baro noise
    bare = [dataclasses.replace(p, values={k: v for k, v in p.values.items() if k != "absolute_height_m"})
            for p in photos]
    unknown = geotag_photos(bare, [without])
    assert unknown.origin_height_datum == HEIGHT_UNKNOWN and not unknown.origin_height_known
    assert "take-off absolute height unknown: origin h0 = 0" in unknown.notes
    assert all(math.isnan(tag.absolute_height_m) for tag in unknown.tags)


def drone_dji_attributes(packet: bytes) -> dict[str, str]:
    """The ``drone-dji:`` attributes of an XMP packet, parsed with defusedxml."""
    root = SafeET.fromstring(packet[packet.find(b"<x:xmpmeta"):packet.rfind(b"</x:xmpmeta>") + len(b"</x:xmpmeta>")])
    prefix = "{" + DRONE_DJI_NS + "}"
    return {k[len(prefix):]: v for e in root.iter() for k, v in e.attrib.items() if k.startswith(prefix)}


def test_dji_xmp_packet_escapes_odd_values():
    tag = Geotag(image_name="DJI_0001.JPG", time_s=0.0, time_source="camera", source="drone", lat_deg=40.1,
                 lon_deg=44.5, height_above_takeoff_m=30.0, absolute_height_m=math.nan,
                 aircraft_ypr_deg=np.array([10.0, -2.0, 1.0]), gimbal_ypr_deg=np.array([10.0, -30.0, 0.0]),
                 enu_m=np.full(3, np.nan), R_world_cam=None)
    odd = {"DewarpData": 'a&b<c>"d\'e\n\tf;1,2', "Note": "]]></x:xmpmeta>"}
    values = drone_dji_attributes(dji_xmp_packet(tag, odd))
    assert {k: values[k] for k in odd} == odd
    assert float(values["GpsLatitude"]) == 40.1 and "AbsoluteAltitude" not in values  # NaN: left out


def test_dji_calibration_attributes_rebuild_a_real_p4m_photos_calibration(shared_data):
    with Image.open(shared_data / "p4m_rtk" / "images" / "DJI_0010.JPG") as image:  # factory calibration in XMP
        real, (width, height) = drone_dji_attributes(image.info["xmp"]), image.size
    date, numbers = real["DewarpData"].split(";")
    fx, fy, dcx, dcy, *distortion = (float(v) for v in numbers.split(","))
    # DJI's principal point is an offset from the image centre W/2, H/2 in pixel-corner coordinates; ours is
    # pixel-centre based (0.5 px less)
    rebuilt = dji_calibration_attributes(fx, fy, width / 2 + dcx - 0.5, height / 2 + dcy - 0.5, width, height,
                                         distortion, date)
    for key in ("CalibratedOpticalCenterX", "CalibratedOpticalCenterY", "DewarpFlag"):
        assert rebuilt[key] == real[key]
    rebuilt_date, rebuilt_numbers = rebuilt["DewarpData"].split(";")
    assert rebuilt_date == date
    np.testing.assert_allclose([float(v) for v in rebuilt_numbers.split(",")], [fx, fy, dcx, dcy, *distortion],
                               rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="5 distortion coefficients"):
        dji_calibration_attributes(fx, fy, 800, 650, width, height, distortion[:4], date)
