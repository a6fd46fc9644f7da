"""Every real sample parses with zero rejects; spot values checked by hand against the files."""


import numpy as np
import pytest

from capture.logs import detect_kind, read_track
from capture.logs.photos import parse_dji_xmp, read_photo
from capture.track import format_utc

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
