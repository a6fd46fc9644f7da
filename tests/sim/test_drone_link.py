"""The virtual drone's outputs against what was put in: Litchi adapter, DUML stream, sinks, photo metadata, CLI."""

from __future__ import annotations

import datetime as dt
import json
import socket
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from capture.attitude import gimbal_angles_from_camera
from capture.duml import Deframer
from capture.fakeusb import FakeUsbBackend
from capture.logs import read_track
from capture.logs.duml import read_duml_track
from capture.logs.photos import read_photo
from capture.messages import CameraState, default_registry, encode_message, is_shutter_edge
from capture.raw import read_index
from capture.transports import UsbBulkSource
from flightplan import litchi
from flightplan.geodesy import LocalFrame, geodesic_direct
from sim.cli import main
from sim.drone import Imperfections, fly, session
from sim.drone.link import MissionClock, duml_frames, stream, telemetry_messages, write_raw_capture
from sim.drone.logs import write_flight_logs
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.photos import photo_camera, photo_geotag, poses_in_scene, write_dji_jpeg
from sim.drone.session import record_loopback, stream_to_port
from sim.worlds.demo import build_demo_world
from tests.sim.drone_helpers import short_orbit_csv

START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)
HOME_H = 1000.0


@pytest.fixture(scope="module")
def mission_csv(tmp_path_factory):
    return short_orbit_csv(tmp_path_factory.mktemp("mission") / "short.csv")


def flown(mission_csv, imperfections, seed=4):
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    return fly(waypoints, home_below_first_waypoint(waypoints, HOME_H), imperfections, seed=seed)


def test_litchi_rows_become_drone_waypoints_field_by_field(mission_csv):
    rows = litchi.read_mission_csv(mission_csv).waypoints
    waypoints = waypoints_from_litchi(litchi.Mission(rows))
    for row, w in zip(rows, waypoints, strict=True):
        assert (w.latitude_deg, w.longitude_deg, w.altitude_m, w.heading_deg) == (
            row.latitude_deg, row.longitude_deg, row.altitude_m, row.heading_deg)
        assert (w.curvesize_m, w.gimbalmode, w.gimbalpitchangle_deg, w.speed_mps) == (
            row.curve_size_m, row.gimbal_mode, row.gimbal_pitch_deg, row.speed_m_s)
        assert (w.poi_latitude_deg, w.poi_longitude_deg, w.poi_altitude_m, w.photo_timeinterval_s) == (
            row.poi_latitude_deg, row.poi_longitude_deg, row.poi_altitude_m, row.photo_time_interval_s)
    home = home_below_first_waypoint(waypoints, 1234.5)
    assert (home.latitude_deg, home.longitude_deg, home.height_ellipsoid_m) == (
        rows[0].latitude_deg, rows[0].longitude_deg, 1234.5)


def test_litchi_rows_the_drone_cannot_fly_are_named(mission_csv):
    rows = litchi.read_mission_csv(mission_csv).waypoints
    with pytest.raises(ValueError, match="waypoint 2: only heights above take-off"):
        waypoints_from_litchi(litchi.Mission((rows[0], replace(rows[1], altitude_mode=1))))
    with pytest.raises(ValueError, match="waypoint 1: waypoint speed_mps"):
        waypoints_from_litchi(litchi.Mission((replace(rows[0], speed_m_s=20.0), rows[1])))


def test_photo_rotation_is_capture_attitude_of_the_true_gimbal_angles(mission_csv):
    photos = flown(mission_csv, Imperfections.realistic()).photos
    angles = gimbal_angles_from_camera(photos.R_world_cam)
    np.testing.assert_allclose(angles, photos.gimbal_ypr_deg, atol=1e-9)
    # the camera looks at the POI below the horizon, image x points right of the flight direction
    assert np.all(photos.R_world_cam[:, 2, 2] < 0)


def decoded_records(data: bytes):
    registry, records = default_registry(), []
    deframer = Deframer()
    for _, packet in deframer.feed(data) + deframer.flush():
        records.append(registry.decode(packet))
    return records, deframer.stats


def test_duml_stream_decodes_to_the_telemetry_records(mission_csv):
    mission = flown(mission_csv, Imperfections.none())
    messages = telemetry_messages(mission)
    frames = duml_frames(mission)
    assert [f.t_s for f in frames] == [t for t, _ in messages]
    records, stats = decoded_records(b"".join(f.data for f in frames))
    assert stats.packets == len(messages) and stats.total_skipped == 0
    for (_, sent), got in zip(messages, records, strict=True):
        assert type(got) is type(sent)
        assert got == default_registry().decode(encode_message(sent, 0))  # the wire form, field by field
    osd = [r for r in records if type(r).__name__ == "OsdGeneral"]
    truth = mission.telemetry.osd
    assert len(osd) == len(truth)
    assert all(o.latitude_deg == r.latitude_deg and o.longitude_deg == r.longitude_deg for o, r in zip(osd, truth))
    assert max(abs(o.yaw_deg - r.yaw_deg) for o, r in zip(osd, truth)) <= 0.05 + 1e-9  # sent in tenths
    cameras = [r for r in records if isinstance(r, CameraState)]
    edges = sum(is_shutter_edge(a, b) for a, b in zip(cameras, cameras[1:]))
    assert edges == len(mission.telemetry.shutter) == mission.photos.taken.sum()
    assert cameras[-1].photo_state == 0


def test_link_damage_loses_exactly_the_damaged_frames(mission_csv):
    imperfections = replace(Imperfections.none(), byte_corruption_rate=2e-3, byte_drop_rate=5e-4)
    mission = flown(mission_csv, imperfections)
    clean = [encode_message(record, seq).encode() for seq, (_, record) in enumerate(telemetry_messages(mission))]
    frames = duml_frames(mission)
    damaged = sum(f.data != c for f, c in zip(frames, clean))
    assert 0.3 * len(frames) > damaged > 0.05 * len(frames)
    records, stats = decoded_records(b"".join(f.data for f in frames))
    intact, _ = decoded_records(b"".join(c for f, c in zip(frames, clean) if f.data == c))
    assert len(intact) == len(frames) - damaged
    assert len(intact) - 0.01 * len(frames) <= len(records) <= len(intact)  # resync may cost a neighbour
    remaining = iter(intact)
    assert all(any(record == candidate for candidate in remaining) for record in records)  # in order, no false frame
    assert stats.total_skipped > 0


def test_raw_capture_carries_the_send_times_and_reads_back_as_a_track(mission_csv, tmp_path):
    mission = flown(mission_csv, Imperfections.realistic())
    frames = duml_frames(mission)
    path = tmp_path / "flight.duml"
    write_raw_capture(frames, path, START)
    kept = [f for f in frames if f.data]
    assert path.read_bytes() == b"".join(f.data for f in kept)
    index = read_index(f"{path}.idx")
    np.testing.assert_allclose(index.monotonic_s, [f.t_s for f in kept], atol=1e-9)
    np.testing.assert_allclose(index.utc_unix_s, [START.timestamp() + f.t_s for f in kept], atol=2e-6)
    track = read_duml_track(path)
    assert track.home.absolute_height_m == pytest.approx(mission.sensors.measured_home()[2], abs=0.01)
    assert len(track.photo_times_s) >= len(mission.telemetry.shutter) - 2  # a damaged camera push may hide one


def fast_frames(mission_csv):
    return duml_frames(flown(mission_csv, Imperfections.realistic()))


def test_loop_link_records_every_byte_on_the_flight_clock(mission_csv, tmp_path):
    frames = fast_frames(mission_csv)
    clock = MissionClock(speedup=2000.0, start_utc=START)
    received = record_loopback(frames, tmp_path / "flight.duml", clock, progress=False)
    assert (tmp_path / "flight.duml").read_bytes() == b"".join(f.data for f in frames)
    assert received == sum(len(f.data) for f in frames)
    index = read_index(tmp_path / "flight.duml.idx")
    assert index.monotonic_s[0] >= 0 and index.monotonic_s[-1] >= frames[-1].t_s  # arrival is not before sending
    assert np.all(np.diff(index.monotonic_s) >= 0)


def test_socket_link_delivers_every_byte(mission_csv):
    frames = fast_frames(mission_csv)
    server = socket.create_server(("127.0.0.1", 0))
    received = bytearray()

    def serve():
        connection, _ = server.accept()
        with connection:
            while chunk := connection.recv(65536):
                received.extend(chunk)

    thread = threading.Thread(target=serve)
    thread.start()
    url = f"socket://127.0.0.1:{server.getsockname()[1]}"
    sent = stream_to_port(frames, url, MissionClock(speedup=5000.0), progress=False)
    thread.join(timeout=10)
    server.close()
    assert bytes(received) == b"".join(f.data for f in frames) and sent == len(received)


def test_a_tcp_flight_started_now_takes_off_when_its_telemetry_reaches_the_recorder(mission_csv, tmp_path,
                                                                                       monkeypatch):
    """``fly --link tcp --start-utc now``: a recorder in another process stamps this machine's clock, so the flight's
    UTC must be that clock from its first packet on, however long the flight took to prepare (here 1.5 s more). The
    default orbit's closed loop took 3 s to load its world, and every packet arrived 3.04 s after the UTC the truth
    gave it: the geotagger's clock offset came out 2.9 s from the truth's."""
    server = socket.create_server(("127.0.0.1", 0))
    first_arrival = []

    def serve():
        connection, _ = server.accept()
        with connection:
            while chunk := connection.recv(65536):
                first_arrival[:] = first_arrival or [dt.datetime.now(dt.timezone.utc)]

    thread = threading.Thread(target=serve)
    thread.start()
    prepare = session.duml_frames
    monkeypatch.setattr(session, "duml_frames", lambda mission: time.sleep(1.5) or prepare(mission))
    argv = ["fly", "--mission", str(mission_csv), "--scene", "demo:small", "--out", str(tmp_path / "fly"), "--photos",
            "0", "--link", "tcp", "--port", f"socket://127.0.0.1:{server.getsockname()[1]}", "--speedup", "1000",
            "--start-utc", "now"]
    assert main(argv) == 0
    thread.join(timeout=10)
    server.close()
    truth = json.loads((tmp_path / "fly" / "truth.json").read_text(encoding="utf-8"))
    start = dt.datetime.fromisoformat(truth["start_utc"])
    assert abs((first_arrival[0] - start).total_seconds()) < 0.25  # the first packet is sent at flight time 0
    assert truth["start_utc_from"] == "this machine's clock when the flight's telemetry started (--start-utc now)"
    assert read_index(tmp_path / "fly" / "flight.duml.idx").utc_unix_s[0] == pytest.approx(start.timestamp())


def test_fake_usb_link_delivers_every_byte_through_pyusb(mission_csv):
    frames = fast_frames(mission_csv)
    backend = FakeUsbBackend()
    total = stream(frames, backend.push, MissionClock(speedup=1e6))
    source = UsbBulkSource(backend=backend)
    stop, received = threading.Event(), bytearray()
    for chunk in source.chunks(stop):
        received.extend(chunk.data)
        if len(received) >= total:
            stop.set()
    assert bytes(received) == b"".join(f.data for f in frames)


def test_photo_metadata_reads_back_as_written(mission_csv, tmp_path):
    mission = flown(mission_csv, Imperfections.realistic())
    photos, index = mission.photos, 5
    tag = photo_geotag(photos, index, HOME_H, "DJI_0006.JPG")
    camera_time = dt.datetime(2024, 5, 1, 10, 1, 2, 345000)
    rgb = np.random.default_rng(0).integers(0, 255, (30, 40, 3), dtype=np.uint8)
    write_dji_jpeg(tmp_path / tag.image_name, rgb, tag, camera_time, photo_camera(40, 30))
    info = read_photo(tmp_path / tag.image_name)
    assert info.problems == []
    assert info.exif_time_s == pytest.approx(camera_time.replace(tzinfo=dt.timezone.utc).timestamp(), abs=1e-6)
    assert info.time_resolution_s == pytest.approx(1e-3)
    v = info.values
    assert v["lat_deg"] == pytest.approx(photos.measured_latitude_deg[index], abs=5.1e-9)  # XMP: 8 decimals
    assert v["lon_deg"] == pytest.approx(photos.measured_longitude_deg[index], abs=5.1e-9)
    assert v["height_above_takeoff_m"] == pytest.approx(photos.measured_height_above_takeoff_m[index], abs=1e-6)
    assert v["absolute_height_m"] == pytest.approx(HOME_H + photos.measured_height_above_takeoff_m[index], abs=1e-6)
    np.testing.assert_allclose([v["gimbal_yaw_deg"], v["gimbal_pitch_deg"], v["gimbal_roll_deg"]],
                               photos.measured_gimbal_ypr_deg[index], atol=1e-6)
    np.testing.assert_allclose([v["aircraft_yaw_deg"], v["aircraft_pitch_deg"], v["aircraft_roll_deg"]],
                               photos.measured_aircraft_ypr_deg[index], atol=1e-6)


def test_poses_move_to_the_scene_frame_through_geodetic_coordinates():
    flight_frame = LocalFrame(40.0, 44.0, 1000.0)
    p = geodesic_direct(40.0, 44.0, 60.0, 400.0)
    scene_frame = LocalFrame(p.lat_deg, p.lon_deg, 990.0)
    rng = np.random.default_rng(1)
    positions = rng.uniform(-100, 100, (5, 3))
    rotations = np.linalg.qr(rng.standard_normal((5, 3, 3)))[0] * np.array([1, 1, 1])
    rotations[np.linalg.det(rotations) < 0] *= -1
    T = poses_in_scene(flight_frame, scene_frame, positions, rotations)
    expected = scene_frame.enu_points(*flight_frame.to_geodetic(*positions.T))
    np.testing.assert_allclose(T[:, :3, 3], expected, atol=1e-6)
    # ENU frames differ by the rotation (-dlat, dlon cos(lat), dlon sin(lat)): its angle is hypot(dlat, dlon)
    tilt = np.degrees(np.arccos(np.clip((np.trace(rotations.transpose(0, 2, 1) @ T[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1)))
    np.testing.assert_allclose(tilt, np.hypot(p.lat_deg - 40.0, p.lon_deg - 44.0), rtol=1e-3)
    same = poses_in_scene(flight_frame, flight_frame, positions, rotations)
    np.testing.assert_allclose(same[:, :3, :3], rotations, atol=1e-9)


def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("latitude,longitude\n40.1,nope\n", encoding="utf-8")
    assert main(["fly", "--mission", str(bad), "--scene", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "scene.json not found" in err
    assert main(["fly", "--mission", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o")]) == 2
    assert "missing.csv: not found; expected a Litchi mission CSV" in capsys.readouterr().err


def test_flight_logs_read_back_as_the_telemetry_sent(mission_csv, tmp_path):
    """Litchi's altitude(m) and the SRT's rel_alt are heights above take-off; the SRT's abs_alt is the height
    above sea level: the recorded home's ellipsoidal height - the stated geoid undulation + rel_alt."""
    mission = flown(mission_csv, Imperfections.realistic())
    undulation = -21.5
    csv_path, srt_path = write_flight_logs(mission, START, tmp_path, geoid_undulation_m=undulation)
    osd = mission.telemetry.osd
    relative = np.array([r.height_above_takeoff_m for r in osd])
    for path in (csv_path, srt_path):
        track = read_track(path)
        assert len(track) == len(osd)
        np.testing.assert_allclose(track.time_s, [START.timestamp() + r.t_s for r in osd], atol=1e-3)
        np.testing.assert_allclose(track["lat_deg"], [r.latitude_deg for r in osd], atol=1e-8)
        np.testing.assert_allclose(track["height_above_takeoff_m"], relative, atol=1e-3)
    assert len(read_track(csv_path).photo_times_s) == len(mission.telemetry.shutter)
    assert not np.isfinite(read_track(csv_path)["absolute_height_m"]).any()  # a Litchi log has no absolute height
    home_msl = mission.sensors.measured_home()[2] - undulation
    np.testing.assert_allclose(read_track(srt_path)["absolute_height_m"], home_msl + relative, atol=1e-3)


def test_cli_fly_over_the_small_demo_world_writes_every_output(mission_csv, tmp_path, capsys):
    scene_dir = build_demo_world(tmp_path / "world", variant="small", seed=0)
    out = tmp_path / "out"
    argv = ["fly", "--mission", str(mission_csv), "--scene", str(scene_dir), "--out", str(out), "--photo-size", "64",
            "48", "--link", "loop", "--speedup", "400", "--photos", "3", "--logs", "--start-utc", "2024-05-01T10:00:00Z"]
    assert main(argv) == 0
    assert "photos: 3 of" in capsys.readouterr().out
    assert sorted(p.name for p in (out / "photos").iterdir()) == ["DJI_0001.JPG", "DJI_0002.JPG", "DJI_0003.JPG"]
    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    assert truth["start_utc"] == "2024-05-01T10:00:00+00:00" and truth["photo_size_px"] == [64, 48]
    first = read_photo(out / "photos" / "DJI_0001.JPG")
    photo = truth["photos"][0]
    assert first.exif_time_s == pytest.approx(START.timestamp() + photo["camera_time_s"], abs=1e-3)
    track = read_duml_track(out / "flight.duml")
    assert len(track.photo_times_s) >= sum(p["taken"] for p in truth["photos"]) - 3
    assert {p.name for p in out.iterdir()} >= {"flight.duml", "flight.duml.idx", "flight_log.csv", "flight.srt",
                                              "truth.csv", "truth.json", "photos"}


def test_camera_pushes_count_the_shots_before_them_and_a_flight_without_photos_has_none():
    from sim.drone.link import CAMERA_STATE_HZ, camera_states
    from sim.drone.schedule import ShutterRecord

    period = 1.0 / CAMERA_STATE_HZ
    pushes = camera_states([ShutterRecord(2.0 * period, 0)], 4 * period, np.empty((0, 2)))
    assert [bool(state.status_flags & 8) for _, state in pushes] == [False, False, True, False, False]
    assert pushes[4][1].remaining_shots == pushes[1][1].remaining_shots - 1
    silent = camera_states([], 4 * period, np.empty((0, 2)))  # a mission that takes no photo (crashed before)
    assert len(silent) == 5 and not any(state.status_flags & 8 for _, state in silent)
