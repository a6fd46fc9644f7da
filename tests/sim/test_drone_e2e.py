"""End to end: plan -> Litchi CSV -> virtual drone over the small demo world -> live DUML over a TCP link into
``aerostereo-ingest record`` -> ``aerostereo-ingest geotag`` -> compare the geotags with the drone's truth.

Streaming design: pyserial's ``loop://`` is per instance and ``record`` opens its own port, so the link is
TCP: the drone writes with ``serial.serial_for_url("socket://...")`` to a relay in the test, which forwards
to the ``record`` command's own ``socket://`` port -- both ends are the real pyserial code paths, and
``record`` runs through its CLI (parser, SerialSource, recorder, raw capture writer). The flight is paced 2x
faster than real time; ``record`` stamps arrivals with the host clock, which here is the drone's
:class:`MissionClock` at the same speed-up (injected through ``capture.transports.Clock``, the transports'
clock seam), so arrival times and the photos' EXIF share one time line as they do on a real flight. ``record``
stops when every byte sent has arrived (its stop event, instead of a guessed ``--duration``).

Why only 2x: the speed-up multiplies every scheduling hiccup of the recorder thread into flight time. At 5x, a
0.18 s stall on a loaded 2-core machine (the other test worker busy) made shutter events arrive 0.9 s late, and
with a photo every second the clock offset landed one whole photo off (1 run in 5; on a real 1x link the
latency stays under 0.3 s, see ``capture.logs.backlog``).
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
import socket
import threading
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import capture.cli
import capture.transports
from capture.cli import main as ingest
from sim.drone import Imperfections
from sim.drone.link import PHOTO_EVENT_ERROR_S, MissionClock, duml_frames
from sim.drone.photos import photo_camera, render_photos
from sim.drone.session import fly_litchi_mission, stream_to_port
from sim.render.scene import load_scene
from sim.worlds import demo_scene_dir
from tests.sim.drone_helpers import short_orbit_csv

SPEEDUP = 2.0
START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)


def relay(server: socket.socket) -> None:
    """Accept the recorder, then the drone; forward the drone's bytes to the recorder until the drone closes."""
    recorder, _ = server.accept()
    drone, _ = server.accept()
    with recorder, drone:
        while data := drone.recv(65536):
            recorder.sendall(data)


@pytest.mark.slow
def test_virtual_flight_streamed_to_record_geotags_within_the_noise_model(tmp_path, monkeypatch):
    scene = load_scene(demo_scene_dir("small"))  # the cached build and its sky bake, not a fresh build of its own
    imperfections = Imperfections.realistic()
    mission = fly_litchi_mission(short_orbit_csv(tmp_path / "mission.csv"), scene, seed=11,
                                 imperfections=imperfections)
    frames = duml_frames(mission)

    clock = MissionClock(SPEEDUP, START)
    monkeypatch.setattr(capture.transports, "Clock", lambda: clock)
    received_all = threading.Event()  # record stops when everything arrived, not after a guessed duration
    monkeypatch.setattr(capture.cli, "stop_after", lambda duration_s: received_all)
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    threading.Thread(target=relay, args=(server,), daemon=True).start()
    capture_path = tmp_path / "received.duml"
    recorder = threading.Thread(target=ingest, args=(["record", "--port", f"socket://127.0.0.1:{port}",
                                                      "--out", str(capture_path)],))
    recorder.start()
    while not capture_path.exists():  # record creates the capture after opening its port (the relay's 1st accept)
        threading.Event().wait(0.01)
    clock.restart()
    sent = stream_to_port(frames, f"socket://127.0.0.1:{port}", clock, progress=False)
    for _ in range(400):  # at most 20 s for the last bytes to pass the relay
        if capture_path.stat().st_size >= sent:
            break
        time.sleep(0.05)
    received_all.set()
    recorder.join(timeout=30)
    server.close()
    assert capture_path.read_bytes() == b"".join(f.data for f in frames)

    photos_dir = tmp_path / "photos"
    render_photos(mission, scene, photos_dir, photo_camera(160, 120), START, progress=False)
    geotags = tmp_path / "geotags.csv"
    assert ingest(["geotag", "--photos", str(photos_dir), "--log", str(capture_path), "--out", str(geotags)]) == 0

    truth = mission.photos
    taken = np.flatnonzero(truth.taken)
    sidecar = json.loads(geotags.with_suffix(".json").read_text(encoding="utf-8"))
    with geotags.open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert sidecar["untagged"] == [] and [r["image_name"] for r in rows] == [truth.names[i] for i in taken]
    # photo events come from 5 Hz camera-state pushes: the offset is known to half a push interval (+ arrival jitter)
    assert sidecar["clock_offset_s"] == pytest.approx(-imperfections.camera_clock_offset_s, abs=PHOTO_EVENT_ERROR_S + 0.05)

    frame = mission.flight.frame  # ENU at the TRUE home; the geotags' origin is the home GPS measured
    lat, lon, up = (np.array([float(r[k]) for r in rows]) for k in ("lat_deg", "lon_deg", "height_above_takeoff_m"))
    tagged = frame.enu_points(lat, lon, frame.h0_m + up)
    error = tagged - truth.position_enu_m[taken]
    gps_axis_std = math.hypot(imperfections.gps_noise_std_m, imperfections.gps_bias_std_m)
    baro_std = math.hypot(imperfections.baro_bias_std_m, imperfections.baro_noise_std_m)
    assert np.all(np.abs(error[:, :2]) < 4.0 * gps_axis_std)
    assert np.all(np.abs(error[:, 2]) < 4.0 * baro_std)
    assert np.sqrt(np.mean(error[:, :2] ** 2)) < 2.0 * gps_axis_std
    # the horizontal error is the GPS error (not a timing error): the same for consecutive photos
    assert np.abs(np.diff(error[:, :2], axis=0)).max() < 4.0 * math.sqrt(2) * imperfections.gps_noise_std_m

    quaternions = np.array([[float(r[k]) for k in ("qw", "qx", "qy", "qz")] for r in rows])
    R_tagged = Rotation.from_quat(quaternions, scalar_first=True)
    angle_deg = np.degrees((R_tagged * Rotation.from_matrix(truth.R_world_cam[taken]).inv()).magnitude())
    assert angle_deg.max() < 0.5
