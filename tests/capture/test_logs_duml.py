"""DUML raw captures and pcaps read as a ``Track``: a synthetic capture with known truth, and the real pcaps."""

import csv
import dataclasses
import datetime as dt
import json
import math

import numpy as np
import pytest
from defusedxml import ElementTree as SafeET
from hypothesis import given, settings
from hypothesis import strategies as st
from test_cli_logs import write_jpeg

from capture.cli import main
from capture.geotag_io import load_geotags
from capture.logs import detect_kind, read_track
from capture.logs.writers import write_duml_capture
from capture.duml import Packet, make_cmd_type
from capture.messages import (HOME_NOT_SET_RADIANS, CameraState, GimbalParams, HomePoint, OsdGeneral,
                              encode_message)
from capture.raw import RawCaptureWriter, index_path
from capture.synthetic import NOISE_FREE, Orbit, telemetry
from capture.synthetic import shutter_times as random_shutter_times
from capture.track import LogFormatError
from flightplan.demo_location import DEMO_ORIGIN

RATE_HZ = 10.0
DURATION_S = 24.0
PRE_FIX_S = 1.0  # OSD says lat/lon 0 and the home point is not set before this
SHUTTER_INTERVAL_S = 1.27  # not a multiple of the push interval: the shutter-to-push lag varies
CAMERA_OFFSET_S = 0.37  # telemetry UTC - camera clock
OSD_PHASE_S, GIMBAL_PHASE_S, CAMERA_PHASE_S, HOME_PHASE_S = 0.013, 0.047, 0.071, 0.089
SPLIT_LEAD_S = 0.004  # each OSD frame arrives in two chunks; its first half this much earlier

OSD_TEMPLATE = OsdGeneral(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ctrl_info=6, latest_app_command=0,
                          controller_state=0, gps_satellites=14, gohome_reason=0, motor_start_fail=0,
                          ctrl_state_ext=0, battery_percent=87, ultrasonic_height_m=0.0, fly_time_s=0.0,
                          motor_start_count=1, battery_alarm1=0, battery_alarm2=0, version_match=1,
                          product_type=2, imu_init_fail_reason=0)
CAMERA_IDLE = CameraState(status_flags=1 << 9, camera_mode=0, sd_total_mb=30000, sd_free_mb=20000,
                          remaining_shots=999, remaining_time_s=0, file_index_mode=0)
HOME_NOT_SET = HomePoint(math.degrees(HOME_NOT_SET_RADIANS), math.degrees(HOME_NOT_SET_RADIANS), 0.0, 0, 60, 0,
                         0, 0, 0, 219)


def utc(time_s: float) -> dt.datetime:
    return dt.datetime.fromtimestamp(time_s, dt.timezone.utc)


def grid(phase_s: float) -> np.ndarray:
    """Push times at RATE_HZ, rounded to the microseconds the index keeps."""
    return np.round(ORBIT.start_s + phase_s + np.arange(0.0, DURATION_S, 1.0 / RATE_HZ), 6)


ORBIT = Orbit(DEMO_ORIGIN, start_s=1_700_000_000.0)


def osd_at(time_s: float) -> OsdGeneral:
    """The OSD the aircraft would send at ``time_s`` (lat/lon 0 before the fix)."""
    if time_s < ORBIT.start_s + PRE_FIX_S:
        return OSD_TEMPLATE
    lat, lon, h = ORBIT.frame.to_geodetic(*ORBIT.enu([time_s])[0])
    yaw, pitch, roll = ORBIT.aircraft_ypr([time_s])[0]
    heading = math.radians(yaw - 90.0)  # flying counter-clockwise: velocity 90 deg left of the nose direction
    v_north, v_east = ORBIT.speed_m_s * math.cos(heading), ORBIT.speed_m_s * math.sin(heading)
    return dataclasses.replace(OSD_TEMPLATE, latitude_deg=float(lat), longitude_deg=float(lon),
                               height_above_takeoff_m=float(h) - ORBIT.frame.h0_m, velocity_x_mps=v_north,
                               velocity_y_mps=v_east, yaw_deg=float(yaw), pitch_deg=float(pitch), roll_deg=float(roll))


def gimbal_at(time_s: float) -> GimbalParams:
    yaw, pitch, roll = ORBIT.gimbal_ypr([time_s])[0]
    return GimbalParams(float(pitch), float(roll), float(yaw), 0, 0.0, 0.0, 0, 1)


def home_at(time_s: float) -> HomePoint:
    if time_s < ORBIT.start_s + PRE_FIX_S:
        return HOME_NOT_SET
    return dataclasses.replace(HOME_NOT_SET, home_latitude_deg=ORBIT.frame.lat0_deg,
                               home_longitude_deg=ORBIT.frame.lon0_deg, home_altitude_m=ORBIT.frame.h0_m, home_state=1)


def shutter_times() -> np.ndarray:
    return ORBIT.start_s + 2.2 + np.arange(0.0, DURATION_S - 4.0, SHUTTER_INTERVAL_S)


def camera_states(times: np.ndarray, shutters: np.ndarray) -> tuple[list[CameraState], np.ndarray]:
    """Camera pushes at ``times``: photo_state 1 (single) on the first push at or after each shutter; and the
    photo events a reader must find: midway between that push and the one before."""
    edges = np.searchsorted(times, shutters)
    is_edge = np.isin(np.arange(len(times)), edges)
    taken = np.cumsum(is_edge)  # shots taken up to and including each push
    states = [dataclasses.replace(CAMERA_IDLE, status_flags=CAMERA_IDLE.status_flags | int(edge) << 3,
                                  remaining_shots=CAMERA_IDLE.remaining_shots - int(shots))
              for edge, shots in zip(is_edge, taken)]
    return states, 0.5 * (times[edges - 1] + times[edges])


def write_capture(path, corrupt_gimbal_index: int | None = None, garbage: bytes = b""):
    """Encode the synthetic flight and write it through RawCaptureWriter, one chunk per frame (OSD frames in
    two chunks, the second at the push time). Returns the truth: push times per kind and photo events."""
    osd_t, gimbal_t, camera_t, home_t = (grid(p) for p in (OSD_PHASE_S, GIMBAL_PHASE_S, CAMERA_PHASE_S,
                                                             HOME_PHASE_S))
    home_t = home_t[::10]  # 1 Hz
    states, event_t = camera_states(camera_t, shutter_times())
    frames = [(t, osd_at(t)) for t in osd_t] + [(t, gimbal_at(t)) for t in gimbal_t]
    frames += list(zip(camera_t, states)) + [(t, home_at(t)) for t in home_t]
    frames.sort(key=lambda pair: pair[0])
    gimbal_seen = 0
    with RawCaptureWriter(path) as writer:
        for seq, (t, record) in enumerate(frames):
            data = encode_message(record, seq).encode()
            if isinstance(record, GimbalParams):
                if gimbal_seen == corrupt_gimbal_index:
                    data = data[:14] + bytes([data[14] ^ 0xFF]) + data[15:]
                    writer.append(utc(t - 0.001), t - ORBIT.start_s, garbage)
                gimbal_seen += 1
            if isinstance(record, OsdGeneral):
                writer.append(utc(t - SPLIT_LEAD_S), t - SPLIT_LEAD_S - ORBIT.start_s, data[:20])
                data = data[20:]
            writer.append(utc(t), t - ORBIT.start_s, data)
    return {"osd": osd_t, "gimbal": gimbal_t, "events": event_t, "home": home_t}


def angle_error(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    path = tmp_path_factory.mktemp("duml") / "flight.duml"
    truth = write_capture(path, corrupt_gimbal_index=50, garbage=b"\x00\x13not a frame\x55\x02")
    return path, truth


def test_synthetic_capture_reads_back_to_the_truth(capture):
    path, truth = capture
    assert detect_kind(path) == "duml"
    track = read_track(path)
    assert track.clock == "utc" and track.report.kind == "duml"

    fixed = truth["osd"][truth["osd"] >= ORBIT.start_s + PRE_FIX_S]
    rows = track.positions_mask()
    np.testing.assert_array_equal(track.time_s[rows], fixed)  # the LAST chunk of each split frame
    lat, lon, h = ORBIT.frame.to_geodetic(*ORBIT.enu(fixed).T)
    np.testing.assert_allclose(track["lat_deg"][rows], lat, rtol=0, atol=1e-12)
    np.testing.assert_allclose(track["lon_deg"][rows], lon, rtol=0, atol=1e-12)
    assert np.abs(track["height_above_takeoff_m"][rows] - (h - ORBIT.frame.h0_m)).max() <= 0.05 + 1e-9
    aircraft = ORBIT.aircraft_ypr(fixed)
    for k, axis in enumerate(("yaw", "pitch", "roll")):
        assert angle_error(track[f"aircraft_{axis}_deg"][rows], aircraft[:, k]).max() <= 0.05 + 1e-9
    # speed from 0.1 m/s velocity components: each off by at most 0.05
    assert np.abs(track["speed_m_s"][rows] - ORBIT.speed_m_s).max() <= 0.05 * math.sqrt(2) + 1e-9

    gimbal_rows = np.isfinite(track["gimbal_yaw_deg"])
    gimbal_t = np.delete(truth["gimbal"], 50)  # the corrupted frame is gone, nothing else
    np.testing.assert_array_equal(track.time_s[gimbal_rows], gimbal_t)
    gimbal = ORBIT.gimbal_ypr(gimbal_t)
    for k, axis in enumerate(("yaw", "pitch", "roll")):
        assert angle_error(track[f"gimbal_{axis}_deg"][gimbal_rows], gimbal[:, k]).max() <= 0.05 + 1e-9

    np.testing.assert_allclose(track.photo_times_s, truth["events"], rtol=0, atol=1e-6)
    shutter_error = track.photo_times_s - shutter_times()  # against the true shutter times
    assert np.abs(shutter_error).max() <= track.event_time_error_s + 1e-6 and abs(shutter_error.mean()) < 0.01
    assert track.event_time_error_s == pytest.approx(0.5 / RATE_HZ)
    assert (track.home.lat_deg, track.home.lon_deg, track.home.absolute_height_m) == pytest.approx(
        (ORBIT.frame.lat0_deg, ORBIT.frame.lon0_deg, ORBIT.frame.h0_m), abs=1e-12)


def test_synthetic_capture_report_counts_every_message(capture):
    path, truth = capture
    report = read_track(path).report
    pre_fix_osd = int((truth["osd"] < ORBIT.start_s + PRE_FIX_S).sum())
    pre_fix_home = int((truth["home"] < ORBIT.start_s + PRE_FIX_S).sum())
    assert pre_fix_osd == 10 and pre_fix_home == 1
    assert report.reasons() == {"no GPS fix": pre_fix_osd, "home point not set": pre_fix_home}
    telemetry = len(truth["osd"]) + len(truth["gimbal"]) - 1 + len(grid(CAMERA_PHASE_S)) + len(truth["home"])
    assert report.rows_read == telemetry and report.rows_used == telemetry - pre_fix_osd - pre_fix_home
    deframer = next(note for note in report.notes if note.startswith("deframer:"))
    # the flipped byte costs the whole gimbal frame (13 + 12 bytes); of the 15 garbage bytes, the 0x55 is a
    # candidate header whose CRC8 fails, the rest are searched past
    assert "skipped bytes: no_sync 14, bad_header_crc 1, bad_packet_crc 25;" in deframer
    assert "rejected frames: bad_header_crc 1, bad_packet_crc 1" in deframer
    assert "messages not used for the track: none" in report.notes
    assert f"{len(shutter_times())} photo events from" in " ".join(report.notes)


def test_track_written_as_a_capture_reads_back(tmp_path):
    rng = np.random.default_rng(5)
    track = telemetry(ORBIT, 12.0, RATE_HZ, NOISE_FREE, rng, random_shutter_times(ORBIT, 12.0, 1.0, NOISE_FREE, rng))
    write_duml_capture(track, tmp_path / "written.duml")
    back = read_track(tmp_path / "written.duml")
    assert not back.report.rejected and len(back) == 2 * len(track)  # an OSD row and a gimbal row per row
    for name, mask, tolerance in (("lat_deg", back.positions_mask(), 1e-12), ("height_above_takeoff_m", None, 0.05),
                                  ("aircraft_yaw_deg", None, 0.05), ("gimbal_pitch_deg", None, 0.05),
                                  ("speed_m_s", None, 0.05 * math.sqrt(2))):
        rows = np.isfinite(back[name]) if mask is None else mask
        np.testing.assert_allclose(back.time_s[rows], track.time_s, rtol=0, atol=1e-6)  # index keeps microseconds
        assert angle_error(back[name][rows], track[name]).max() <= tolerance + 1e-9  # wraps only angles this big
    first_row_after = np.searchsorted(track.time_s, track.photo_times_s)
    midway = 0.5 * (track.time_s[first_row_after - 1] + track.time_s[first_row_after])
    np.testing.assert_allclose(back.photo_times_s, midway, rtol=0, atol=1e-6)
    assert back.home.absolute_height_m == pytest.approx(ORBIT.frame.h0_m, abs=1e-4)  # f32 tenths of a metre


def test_packets_after_the_end_of_the_index_are_rejected_not_dropped(tmp_path):
    path = tmp_path / "killed.duml"
    write_capture(path)
    late = encode_message(osd_at(ORBIT.start_s + 5.0), 7).encode() + encode_message(gimbal_at(0.0), 8).encode()
    with open(path, "ab") as handle:  # a kill between the data flush and its index line
        handle.write(late)
    report = read_track(path).report
    assert report.reasons()["no arrival time"] == 2
    assert any("has no index line" in str(problem) for problem in report.rejected)


def test_malformed_and_response_packets_are_rejected_with_their_offset(tmp_path):
    path = tmp_path / "odd.duml"
    good = encode_message(gimbal_at(ORBIT.start_s), 1)
    short_osd = Packet(good.sender, good.receiver, 2, make_cmd_type(), 0x03, 0x43, bytes(20))
    answer = good._replace(seq=3, cmd_type=make_cmd_type(is_response=True))
    with RawCaptureWriter(path) as writer:
        for k, packet in enumerate((good, short_osd, answer)):
            writer.append(utc(ORBIT.start_s + k), float(k), packet.encode())
    report = read_track(path).report
    assert (report.rows_read, report.rows_used) == (3, 1)
    assert [str(p).split(": ", 1)[1] for p in report.rejected] == [
        f"malformed message: osd_general payload of 20 bytes, expected 50..55 at stream byte {good.frame_length}",
        f"response packet: GimbalParams at stream byte {good.frame_length + 33} is an answer, not a telemetry push"]


def test_bad_index_line_is_a_clear_error(tmp_path):
    path = tmp_path / "flight.duml"
    write_capture(path)
    lines = index_path(path).read_text().splitlines(keepends=True)
    lines[5] = "96,yesterday,0.5,12\n"
    index_path(path).write_text("".join(lines))
    with pytest.raises(LogFormatError, match=r"flight\.duml\.idx:6: expected 'offset,utc_unix_s,monotonic_s,length'"):
        read_track(path)


@pytest.fixture(scope="module")
def short_capture(tmp_path_factory):
    """The first 3 s of the synthetic flight: (data bytes, index text)."""
    path = tmp_path_factory.mktemp("short") / "flight.duml"
    write_capture(path)
    index = index_path(path).read_text().splitlines(keepends=True)
    kept = [line for line in index[1:] if float(line.split(",")[1]) < ORBIT.start_s + 3.0]
    end = sum(int(line.split(",")[3]) for line in kept)
    return path.read_bytes()[:end], index[0] + "".join(kept)


@settings(max_examples=40, deadline=None)
@given(flips=st.lists(st.tuples(st.floats(0.0, 1.0, exclude_max=True), st.integers(1, 255)), max_size=20),
       cut=st.floats(0.0, 1.0))
def test_damaged_captures_read_or_fail_clearly(short_capture, tmp_path_factory, flips, cut):
    data, index = short_capture
    damaged = bytearray(data[:int(len(data) * cut)])
    for where, mask in flips:
        if damaged:
            damaged[int(where * len(damaged))] ^= mask
    path = tmp_path_factory.mktemp("fuzz") / "damaged.duml"
    path.write_bytes(bytes(damaged))
    index_path(path).write_text(index)
    try:
        track = read_track(path)
    except LogFormatError as error:
        assert str(error).startswith(str(path))
        return
    report = track.report
    assert report.rows_read == report.rows_used + len(report.rejected)
    assert np.all(np.diff(track.time_s) >= 0) and np.all(track.time_s >= ORBIT.start_s)


def test_raw_capture_without_index_is_a_clear_error(tmp_path, capsys):
    path = tmp_path / "flight.duml"
    write_capture(path)
    index_path(path).unlink()
    with pytest.raises(LogFormatError, match=r"flight\.duml\.idx"):
        read_track(path)
    assert main(["track", str(path), "--out", str(tmp_path / "t.csv")]) == 2
    assert "flight.duml.idx" in capsys.readouterr().err and not (tmp_path / "t.csv").exists()


def test_not_a_duml_capture_is_a_clear_error(tmp_path):
    path = tmp_path / "noise.duml"
    path.write_bytes(np.random.default_rng(3).integers(0, 0x55, 5000, dtype=np.uint8).tobytes())
    index_path(path).write_text("# aerostereo-duml-idx/1 offset,utc_unix_s,monotonic_s,length\n0,1.0,0.0,5000\n")
    with pytest.raises(LogFormatError, match="no DUML frame found in 5000 bytes"):
        read_track(path)


@pytest.mark.parametrize("run, gimbal_rows, osd_rows", [("run1", 1168, 227), ("run3", 1918, 377)])
def test_real_pcaps_read_as_attitude_only_tracks(shared_data, run, gimbal_rows, osd_rows):
    path = shared_data / "dji" / f"dji-packet-dumps__p3x_ofdm_to_center_{run}.pcap"
    assert detect_kind(path) == "duml"
    track = read_track(path)
    # recorded indoors before a GPS fix: every OSD row rejected as such, the home point never set
    assert track.report.reasons()["no GPS fix"] == osd_rows
    assert set(track.report.reasons()) == {"no GPS fix", "home point not set"}
    assert f"no GPS fix in any of the {osd_rows} OSD messages: the track has no positions" in track.report.notes
    assert not track.positions_mask().any() and track.home is None
    assert len(track) == gimbal_rows and track.fields == {"gimbal_yaw_deg", "gimbal_pitch_deg", "gimbal_roll_deg"}
    assert np.all(np.diff(track.time_s) >= 0)
    assert utc(track.time_s[0]).date() == dt.date(2017, 12, 20)
    assert np.all((track["gimbal_pitch_deg"] >= -90.0) & (track["gimbal_pitch_deg"] <= 47.0))
    assert "skipped bytes: none" in track.report.notes[0]


def test_pcap_cut_short_is_read_up_to_the_cut_with_a_note(shared_data, tmp_path):
    path = tmp_path / "killed.pcap"
    path.write_bytes((shared_data / "dji" / "dji-packet-dumps__p3x_ofdm_to_center_run1.pcap").read_bytes()[:-3])
    track = read_track(path)
    assert len(track) == 1168  # every gimbal row: the cut last frame is an undecoded one
    assert f"{path}: truncated record at byte 250996: 35 of 38 bytes there, kept" in track.report.notes


def test_geotag_with_a_pcap_without_fix_is_a_clear_error(shared_data, tmp_path, capsys):
    (tmp_path / "photos").mkdir()
    write_jpeg(tmp_path / "photos" / "IMG_0000.JPG", 1513801780.0, 54.37, 18.56)
    pcap = shared_data / "dji" / "dji-packet-dumps__p3x_ofdm_to_center_run1.pcap"
    out = tmp_path / "geotags.csv"
    assert main(["geotag", "--photos", str(tmp_path / "photos"), "--log", str(pcap), "--out", str(out)]) == 2
    assert "the track has no position to use as origin" in capsys.readouterr().err and not out.exists()


def test_track_command_on_a_capture(capture, tmp_path, capsys):
    path, truth = capture
    assert main(["track", str(path), "--out", str(tmp_path / "t.csv"), "--kml", str(tmp_path / "t.kml")]) == 0
    printed = capsys.readouterr().err  # the reader's report is a log: stderr
    assert "[duml]:" in printed and "10 no GPS fix" in printed
    rows = list(csv.DictReader((tmp_path / "t.csv").open()))
    assert sum(row["photo_event"] == "1" for row in rows) == len(truth["events"])
    assert (tmp_path / "t.kml").read_text().count(",") > 2 * 200


def test_geotag_command_with_a_duml_log(capture, tmp_path, capsys):
    path, truth = capture
    photos = tmp_path / "photos"
    photos.mkdir()
    shutters = shutter_times()
    lat, lon, _ = ORBIT.frame.to_geodetic(*ORBIT.enu(shutters).T)
    for i, shutter in enumerate(shutters):
        write_jpeg(photos / f"IMG_{i:04d}.JPG", shutter - CAMERA_OFFSET_S, lat[i], lon[i])
    out = tmp_path / "out" / "geotags.csv"
    gpx = tmp_path / "out" / "photos.gpx"
    assert main(["geotag", "--photos", str(photos), "--log", str(path), "--out", str(out), "--gpx", str(gpx)]) == 0
    printed = capsys.readouterr().out
    assert f"{len(shutters)} photos geotagged, 0 untagged" in printed
    rows = list(csv.DictReader(out.open()))
    assert {row["source"] for row in rows} == {"duml/event"}
    sidecar = json.loads(out.with_suffix(".json").read_text())
    assert sidecar["origin"]["h0_ellipsoid_m"] == pytest.approx(ORBIT.frame.h0_m)  # the home point's altitude
    assert sidecar["origin_height_datum"] == "home_point_altitude"
    # the shutter events are within half a camera push interval (0.05 s) of the shutter, unbiased
    assert abs(sidecar["clock_offset_s"] - CAMERA_OFFSET_S) < 0.05 + 3 * sidecar["clock_offset_std_s"]
    priors = load_geotags(out)
    estimate = np.array([p.position_enu_m for p in priors])
    np.testing.assert_allclose(estimate, ORBIT.enu(truth["events"]), atol=0.01)  # at the event times
    assert np.abs(estimate - ORBIT.enu(shutters)).max() < 0.05 * ORBIT.speed_m_s + 0.01  # at the true shutter
    pitch = np.array([float(row["gimbal_pitch_deg"]) for row in rows])
    assert np.abs(pitch - ORBIT.gimbal_ypr(shutters)[:, 1]).max() < 0.1
    # the log has no absolute height but a home point: absolute height = its altitude + the height above take-off,
    # so exiftool -geotag gets an <ele> for every photo (it deletes GPSAltitude where there is none)
    gpx_ns = "{http://www.topografix.com/GPX/1/1}"
    points = SafeET.parse(gpx).getroot().iter(f"{gpx_ns}trkpt")
    ele = np.array([float(point.findtext(f"{gpx_ns}ele")) for point in points])
    true_height = ORBIT.frame.to_geodetic(*ORBIT.enu(truth["events"]).T)[2]
    assert len(ele) == len(shutters) and np.abs(ele - true_height).max() < 0.01
    np.testing.assert_allclose([float(row["absolute_height_m"]) for row in rows], ele, atol=1e-6)
