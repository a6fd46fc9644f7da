"""Every real sample parses with zero rejects; spot values checked by hand against the files."""


import numpy as np
import pytest
from PIL import Image

from capture.logs import detect_kind, read_track
from capture.logs.photos import (CameraXmp, FactoryCalibration, RtkStatus, parse_dji_xmp, read_camera_xmp,
                                 read_photo)
from capture.track import LogFormatError, format_utc

SRT_SAMPLES = {
    # file: (rows, clock, first lat, first lon, fields that must be present)
    "DJI_SRT_Parser__mavic_mini.SRT": (117, "relative", 48.0771, -121.7458, {"height_above_takeoff_m"}),
    "DJI_SRT_Parser__p4p_sample.SRT": (5, "relative", 47.4692, 8.2090, {"height_above_takeoff_m", "speed_m_s"}),
    "DJI_SRT_Parser__p4_rtk.SRT": (55, "relative", -34.237922, -58.851745, {"gimbal_pitch_deg", "aircraft_yaw_deg"}),
    "DJI_SRT_Parser__mavic_pro.SRT": (468, "utc", -20.2533, 149.0251, {"height_above_takeoff_m"}),
    "DJI_SRT_Parser__matrice_300.srt": (381, "utc", 36.6146, -6.1120, {"height_above_takeoff_m"}),
    "DJI_SRT_Parser__mavic_2_style.SRT": (468, "utc", -20.2533, 149.0251, set()),
    "DJI_SRT_Parser__mavic_air2.srt": (25, "utc", 41.420684, 2.162162, {"absolute_height_m"}),
    "DJI_SRT_Parser__air2s.srt": (17, "utc", 41.424724, 2.234156, {"absolute_height_m"}),
}


@pytest.mark.parametrize("name", sorted(SRT_SAMPLES))
def test_every_srt_sample_parses_without_rejects(shared_data, name):
    rows, clock, lat, lon, fields = SRT_SAMPLES[name]
    track = read_track(shared_data / "dji" / name)
    assert detect_kind(shared_data / "dji" / name) == "srt"
    assert track.report.rejected == [] and track.report.rows_used == track.report.rows_read == rows
    assert len(track) == rows and track.clock == clock
    assert (track["lat_deg"][0], track["lon_deg"][0]) == pytest.approx((lat, lon))
    assert fields <= track.fields and {"lat_deg", "lon_deg"} <= track.fields
    if name == "DJI_SRT_Parser__mavic_2_style.SRT":  # dates only, and the aircraft clock repeats seconds
        assert np.all(np.diff(track.time_s) >= 0) and any("5 cues repeat" in note for note in track.report.notes)
    else:
        assert np.all(np.diff(track.time_s) > 0)
    if clock == "relative":
        assert any("no wall-clock date" in note for note in track.report.notes)


def test_p4_rtk_pry_order_and_home(shared_data):
    track = read_track(shared_data / "dji" / "DJI_SRT_Parser__p4_rtk.SRT")
    # F.PRY (2.7°, -7.0°, 110.1°), G.PRY (-24.4°, 0.0°, 110.4°): (pitch, roll, yaw)
    assert [track[f"aircraft_{a}_deg"][0] for a in ("pitch", "roll", "yaw")] == pytest.approx([2.7, -7.0, 110.1])
    assert [track[f"gimbal_{a}_deg"][0] for a in ("pitch", "roll", "yaw")] == pytest.approx([-24.4, 0.0, 110.4])
    assert track["height_above_takeoff_m"][0] == pytest.approx(85.80)
    assert track["speed_m_s"][1] == pytest.approx(2.88)
    assert (track.home.lat_deg, track.home.lon_deg, track.home.absolute_height_m) == pytest.approx((-34.232707, -58.847509, -57.98))


def test_dated_srt_times(shared_data):
    m300 = read_track(shared_data / "dji" / "DJI_SRT_Parser__matrice_300.srt")
    assert format_utc(m300.time_s[0]).startswith("2022-06-21T16:06:17.")  # whole-second date + cue anchor
    assert m300["height_above_takeoff_m"][:5] == pytest.approx([0.3, 0.3, 0.8, 1.3, 4.1])
    mavic2 = read_track(shared_data / "dji" / "DJI_SRT_Parser__mavic_2_style.SRT")  # no timecodes, ',ms,us'
    assert format_utc(mavic2.time_s[0]) == "2017-08-05T14:11:51.393525Z"
    assert format_utc(mavic2.time_s[-1]) == "2017-08-05T14:19:39.393525Z"
    mavic_pro = read_track(shared_data / "dji" / "DJI_SRT_Parser__mavic_pro.SRT")  # dates repeat 14:16:31 ...
    assert np.diff(mavic_pro.time_s) == pytest.approx(1.0, abs=1e-6)
    assert any("jitter" in note for note in mavic_pro.report.notes)
    assert format_utc(mavic_pro.time_s[0]).startswith("2017-08-05T14:11:5")
    air2s = read_track(shared_data / "dji" / "DJI_SRT_Parser__air2s.srt")
    assert format_utc(air2s.time_s[1]) == "2022-08-07T13:40:40.808164Z"
    shifted = read_track(shared_data / "dji" / "DJI_SRT_Parser__air2s.srt", srt_utc_offset_h=2.0)
    assert shifted.time_s[0] == pytest.approx(air2s.time_s[0] - 7200.0)


def test_dateless_srt_anchored_by_start_time(shared_data):
    start = 1_600_000_000.0
    track = read_track(shared_data / "dji" / "DJI_SRT_Parser__mavic_mini.SRT", start_time_s=start)
    assert track.clock == "utc" and track.time_s[0] == start and track.time_s[1] == start + 1.0
    assert track["height_above_takeoff_m"][0] == pytest.approx(200.70)


def test_airdata_sample(shared_data):
    path = shared_data / "litchi" / "airdata_mini2_imperial_head.csv"
    track = read_track(path)
    assert detect_kind(path) == "airdata" and track.report.rejected == [] and len(track) == 50
    assert track["lat_deg"][0] == pytest.approx(47.5726976524126)
    assert track["lon_deg"][0] == pytest.approx(-122.62662335236)
    assert track["absolute_height_m"][0] == pytest.approx(17.367977261812 * 0.3048)  # feet -> m
    assert track["aircraft_pitch_deg"][0] == pytest.approx(3.3)  # " 3.3" under " pitch(degrees)"
    assert track["aircraft_yaw_deg"][0] == pytest.approx(79.2)
    assert track["gimbal_yaw_deg"][0] == pytest.approx(63.3)
    assert "gimbal_roll_deg" not in track.fields  # the 2021 export has no gimbal roll
    # whole-second datetime(utc) refined by time(millisecond): rows 100 ms apart, start 02:23:48.1 .. .2
    assert np.diff(track.time_s) == pytest.approx(0.1, abs=1e-6)
    assert format_utc(track.time_s[0]).startswith("2021-09-06T02:23:48.1")
    last_row_second = 1630895033.0  # 2021-09-06 02:23:53 in the file's last row (time 4900 ms)
    assert last_row_second <= track.time_s[-1] < last_row_second + 1.0


def test_photo_exif_and_xmp(shared_data):
    photo = read_photo(shared_data / "brighton_beach" / "images" / "DJI_0018.JPG")
    assert photo.problems == []
    assert format_utc(photo.exif_time_s) == "2016-06-23T16:31:59.000000Z" and photo.time_resolution_s == 1.0
    exif_lat = 46 + 50 / 60 + 33.3855 / 3600
    assert photo.values["lat_deg"] == pytest.approx(exif_lat, abs=1e-9)
    assert photo.values["lon_deg"] == pytest.approx(-(91 + 59 / 60 + 40.4156 / 3600), abs=1e-9)
    expected = {"absolute_height_m": 198.31, "height_above_takeoff_m": 39.80, "gimbal_yaw_deg": 45.0,
                "gimbal_pitch_deg": -89.9, "gimbal_roll_deg": 0.0, "aircraft_yaw_deg": 46.0,
                "aircraft_pitch_deg": 1.8, "aircraft_roll_deg": 3.0}
    assert {k: photo.values[k] for k in expected} == pytest.approx(expected)


def test_photo_folder_as_track(shared_data):
    track = read_track(shared_data / "brighton_beach" / "images")
    assert track.clock == "camera" and len(track) == 18 and track.report.rejected == []
    assert len(track.photo_times_s) == 18
    assert 123.0 <= track.time_s[-1] - track.time_s[0] <= 125.0  # 16:31:59 .. 16:34:03


XMP_ELEMENT_FORM = """<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">
<rdf:Description xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/" drone-dji:GpsLatitude="+34.03250565">
<drone-dji:GpsLongtitude>-118.1234</drone-dji:GpsLongtitude><drone-dji:GimbalYawDegree>-181.5</drone-dji:GimbalYawDegree>
</rdf:Description></rdf:RDF></x:xmpmeta>"""


def test_xmp_element_form_and_longtitude_typo():
    values = parse_dji_xmp(XMP_ELEMENT_FORM)
    assert values == pytest.approx({"lat_deg": 34.03250565, "lon_deg": -118.1234, "gimbal_yaw_deg": 178.5})


def test_xmp_entities_are_refused_not_expanded():
    bomb = ('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;">]>'
            '<x:xmpmeta xmlns:x="adobe:ns:meta/">&b;</x:xmpmeta>')
    with pytest.raises(ValueError, match="unreadable XMP"):
        parse_dji_xmp(bomb)
    with pytest.raises(ValueError, match="GimbalPitchDegree"):
        parse_dji_xmp(XMP_ELEMENT_FORM.replace('drone-dji:GpsLatitude="+34.03250565"', 'drone-dji:GimbalPitchDegree="abc"'))


P4M_DEWARP = (1973.0899658, 1955.6500244, -19.0419922, -11.4249878, -0.4227500, 0.3691010, 0.0040638, 0.0040638,
              -0.2643060)


def test_p4m_rtk_factory_calibration_and_rtk_from_xmp(shared_data):
    """Values as DJI_0010.JPG's XMP packet says (read by eye), and every photo of the set RTK fixed."""
    first = read_camera_xmp(shared_data / "p4m_rtk" / "images" / "DJI_0010.JPG")
    assert first.calibration == FactoryCalibration(1600, 1300, 1913.333374, (800.0, 650.0), P4M_DEWARP, False)
    assert first.rtk == RtkStatus(50, (0.01053, 0.01380, 0.02050)) and first.rtk.fixed
    photos = sorted((shared_data / "p4m_rtk" / "images").glob("*.JPG"))
    every = [read_camera_xmp(photo) for photo in photos]
    assert len(every) == 32 and {xmp.calibration for xmp in every} == {first.calibration}
    stds = np.array([xmp.rtk.std_enu_m for xmp in every])
    assert all(xmp.rtk.fixed for xmp in every) and np.all((stds > 0.005) & (stds < 0.03))


def with_xmp(tmp_path, description: str, name="IMG_0001.JPG"):
    """A 160x130 JPEG whose XMP holds ``description`` inside a drone-dji rdf:Description."""
    packet = ('<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
              f'<rdf:Description xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/" {description}</rdf:Description>'
              '</rdf:RDF></x:xmpmeta>')
    path = tmp_path / name
    Image.new("RGB", (160, 130)).save(path, xmp=packet.encode())
    return path


CALIBRATION_ELEMENTS = ('drone-dji:CalibratedFocalLength="191.3">'
                        '<drone-dji:CalibratedOpticalCenterX>80.0</drone-dji:CalibratedOpticalCenterX>'
                        '<drone-dji:CalibratedOpticalCenterY>65.0</drone-dji:CalibratedOpticalCenterY>'
                        '<drone-dji:DewarpData>2022-03-02;197.3,195.5,-1.9,-1.1,-0.42,0.37,0.004,0.004,-0.26'
                        '</drone-dji:DewarpData><drone-dji:DewarpFlag>1</drone-dji:DewarpFlag>'
                        '<drone-dji:RtkFlag>34</drone-dji:RtkFlag>')


def test_calibration_in_element_form_and_without_rtk_std(tmp_path):
    xmp = read_camera_xmp(with_xmp(tmp_path, CALIBRATION_ELEMENTS))
    assert xmp.calibration == FactoryCalibration(160, 130, 191.3, (80.0, 65.0),
                                                 (197.3, 195.5, -1.9, -1.1, -0.42, 0.37, 0.004, 0.004, -0.26), True)
    assert xmp.rtk == RtkStatus(34, None) and not xmp.rtk.fixed  # float solution, no std given
    assert read_camera_xmp(with_xmp(tmp_path, 'drone-dji:GimbalYawDegree="1.0">')) == CameraXmp(None, None)


@pytest.mark.parametrize("bad, tag", [
    ('drone-dji:CalibratedFocalLength="nan">', "CalibratedFocalLength"),
    ('drone-dji:CalibratedFocalLength="1e9">', "CalibratedFocalLength"),
    ('drone-dji:CalibratedFocalLength="191" drone-dji:CalibratedOpticalCenterX="-3">', "CalibratedOpticalCenterX"),
    ('drone-dji:CalibratedFocalLength="191" drone-dji:DewarpData="2022-03-02;197,195,-1,-1,-0.4,0.3,0,0">',
     "DewarpData"),
    ('drone-dji:CalibratedFocalLength="191" drone-dji:DewarpData="2022-03-02;197,inf,-1,-1,-0.4,0.3,0,0,0">',
     "DewarpData fy"),
    ('drone-dji:CalibratedFocalLength="191" drone-dji:DewarpData="x;197,195,-1,-1,-40,0.3,0,0,0">', "DewarpData k1"),
    ('drone-dji:RtkFlag="50" drone-dji:RtkStdLon="0.01" drone-dji:RtkStdLat="-0.01" drone-dji:RtkStdHgt="0.02">',
     "RtkStdLat"),
    ('drone-dji:RtkFlag="fixed">', "RtkFlag"),
    ('drone-dji:RtkFlag="50.5">', "RtkFlag"),
])
def test_absurd_calibration_or_rtk_values_are_refused_naming_the_photo(tmp_path, bad, tag):
    with pytest.raises(LogFormatError, match=rf"IMG_0001\.JPG: XMP drone-dji:{tag}"):
        read_camera_xmp(with_xmp(tmp_path, bad))
