"""Virtual-drone flights for the geotag tests: a DUML capture (arrival stamps as the link delivered it) and tiny
photos with the metadata the drone's camera writes, and checks of geotags against the flight's truth."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from capture.geotag import PHOTO_SOURCE
from capture.logs import read_track
from flightplan import litchi
from sim.drone import Imperfections, fly
from sim.drone.link import Frame, duml_frames, write_raw_capture
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi
from sim.drone.photos import photo_camera, photo_geotag, write_dji_jpeg

START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)  # the virtual flights' start (UTC)


def virtual_flight(mission_csv, folder, seed, arrival=None, start=START):
    """Fly a Litchi mission with realistic noise from ``start`` (UTC); write its DUML capture
    (``folder/flight.duml``) and tiny photos with the metadata the drone's camera writes (``folder/photos``).
    ``arrival(t_s)``: when the link delivered the frame sent at flight time ``t_s`` (s; default: as it was sent).
    Returns the mission (truth) and the track."""
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    mission = fly(waypoints, home_below_first_waypoint(waypoints, 1000.0), Imperfections.realistic(), seed=seed)
    frames = duml_frames(mission)
    if arrival is not None:
        frames = [Frame(arrival(frame.t_s), frame.data) for frame in frames]
    write_raw_capture(frames, folder / "flight.duml", start)
    (folder / "photos").mkdir()
    truth, home_h = mission.photos, mission.sensors.measured_home()[2]
    rgb = np.full((30, 40, 3), 128, np.uint8)
    for index in np.flatnonzero(truth.taken):
        camera_time = start.replace(tzinfo=None) + dt.timedelta(seconds=float(truth.camera_time_s[index]))
        write_dji_jpeg(folder / "photos" / truth.names[index], rgb,
                       photo_geotag(truth, index, home_h, truth.names[index]), camera_time, photo_camera(40, 30))
    return mission, read_track(folder / "flight.duml")


def position_errors(tags, mission) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) ENU error (m) of each tag's position against its photo's true position, and (N,) the horizontal error
    (m) of the photo's own GPS (what the camera wrote into its EXIF)."""
    truth, frame = mission.photos, mission.flight.frame
    names = truth.names
    index = [names.index(tag.image_name) for tag in tags]
    tagged = np.array([frame.enu_points(tag.lat_deg, tag.lon_deg, frame.h0_m + tag.height_above_takeoff_m)
                       for tag in tags])
    own = frame.enu_points(truth.measured_latitude_deg[index], truth.measured_longitude_deg[index], frame.h0_m)
    true = truth.position_enu_m[index]
    return tagged - true, np.hypot(*(own - true)[:, :2].T)


def assert_within_the_noise_model(tags, mission, attitude_deg=0.5):
    """Each tag's position within 4 sigma of the GPS (horizontal) and barometer (vertical) models of its true
    position, its camera rotation within ``attitude_deg`` of the true one; a tag from the photo's own metadata has
    its latitude."""
    truth, imperfections = mission.photos, mission.flight.imperfections
    gps_axis = np.hypot(imperfections.gps_noise_std_m, imperfections.gps_bias_std_m)
    baro = np.hypot(imperfections.baro_bias_std_m, imperfections.baro_noise_std_m)
    errors, _ = position_errors(tags, mission)
    names = truth.names
    for tag, error in zip(tags, errors):
        i = names.index(tag.image_name)
        assert np.all(np.abs(error[:2]) < 4 * gps_axis) and abs(error[2]) < 4 * baro, (tag.image_name, error)
        angle = np.degrees((Rotation.from_matrix(tag.R_world_cam)
                            * Rotation.from_matrix(truth.R_world_cam[i]).inv()).magnitude())
        assert angle < attitude_deg, (tag.image_name, angle)
        if tag.source == PHOTO_SOURCE:
            assert tag.lat_deg == pytest.approx(truth.measured_latitude_deg[i], abs=1e-8)
