"""Pose and sun samplers: the paper's ranges, determinism per (seed, index), trajectories, replay of geotags."""

from __future__ import annotations

import json
import math
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from sim.render.camera import pose_from_position
from sim.sampling.pose import R_WORLD_NADIR, camera_rotation
from sim.sampling.random_poses import RandomPoseSettings, random_pose
from sim.sampling.trajectories import lawnmower, orbit, random_loop
from sim.sampling.sun import random_sun
from sim.sampling.replay import replay_poses

SCENE_ORIGIN = LocalFrame(40.1792, 44.4991, 1000.0)


class SlopedGround:
    """Analytic ground: a slope east plus a wave north, over a 400 m x 300 m valid area."""

    valid_area = (-200.0, 200.0, -150.0, 150.0)

    def ground_height(self, x, y):
        return 0.02 * np.asarray(x) + 3.0 * np.sin(np.asarray(y) / 40.0)


GROUND = SlopedGround()


def optical_axis(T: np.ndarray) -> np.ndarray:
    return T[:3, 2]


def angle_from_nadir_deg(T: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip(-optical_axis(T)[2], -1, 1)))


def test_heading_zero_looks_down_with_north_at_the_image_top():
    R = camera_rotation(0.0)
    north_point_in_camera = R.T @ np.array([0.0, 10.0, -50.0])  # 10 m north, 50 m below
    assert north_point_in_camera[2] > 0 and north_point_in_camera[1] < 0  # in front, above the image centre
    east_in_camera = camera_rotation(90.0).T @ np.array([10.0, 0.0, -50.0])
    assert east_in_camera[1] < 0 and abs(east_in_camera[0]) < 1e-12  # heading 90: image top faces east
    forward = optical_axis(np.pad(camera_rotation(90.0, 30.0), ((0, 1), (0, 1))))
    np.testing.assert_allclose(forward, [math.sin(math.radians(30)), 0, -math.cos(math.radians(30))], atol=1e-12)


def test_random_poses_respect_the_papers_ranges():
    settings = RandomPoseSettings(margin_m=25.0)
    samples = [random_pose(GROUND, 11, index, settings) for index in range(300)]
    for sample in samples:
        x, y, z = sample.T_world_cam[:3, 3]
        assert -175 <= x <= 175 and -125 <= y <= 125
        assert 20.0 <= z - GROUND.ground_height(x, y) <= 100.0
        # Undo heading and nadir: what is left must be Rx(a) @ Ry(b) with |a|, |b| <= 45 deg.
        heading = sample.details["heading_deg"]
        unturn = Rotation.from_euler("z", heading, degrees=True).as_matrix()
        tilt = R_WORLD_NADIR.T @ unturn @ sample.T_world_cam[:3, :3]
        a, b = math.degrees(math.atan2(tilt[2, 1], tilt[1, 1])), math.degrees(math.atan2(tilt[0, 2], tilt[0, 0]))
        assert abs(a) <= 45 and abs(b) <= 45 and abs(tilt[1, 0]) < 1e-12
        assert 0 <= heading < 360 and angle_from_nadir_deg(sample.T_world_cam) <= 60.0 + 1e-9
        assert sample.time_s == pytest.approx(sample.index / settings.frame_rate_hz)
    headings = [sample.details["heading_deg"] for sample in samples]
    assert max(headings) - min(headings) > 300 and np.std([s.height_above_ground_m for s in samples]) > 15


def test_random_poses_depend_only_on_seed_and_index():
    forward = {index: random_pose(GROUND, 3, index) for index in range(10)}
    for index in (7, 2, 9, 0):
        np.testing.assert_array_equal(random_pose(GROUND, 3, index).T_world_cam, forward[index].T_world_cam)
        assert random_sun(3, index) == random_sun(3, index)
    assert not np.array_equal(random_pose(GROUND, 4, 2).T_world_cam, forward[2].T_world_cam)


def test_views_with_too_much_sky_are_rejected_and_counted():
    calls = []

    def steep_views_see_sky(T_world_cam):
        calls.append(1)
        return 1.0 if angle_from_nadir_deg(T_world_cam) > 20.0 else 0.0

    samples = [random_pose(GROUND, 5, index, miss_fraction=steep_views_see_sky) for index in range(40)]
    assert all(angle_from_nadir_deg(sample.T_world_cam) <= 20.0 for sample in samples)
    assert sum(sample.rejected for sample in samples) == len(calls) - len(samples) > 40
    assert [s.rejected for s in samples] == [random_pose(GROUND, 5, i, miss_fraction=steep_views_see_sky).rejected
                                             for i in range(40)]
    with pytest.raises(RuntimeError, match="frame 3 \\(seed 5\\): no pose with at most 2% sky"):
        random_pose(GROUND, 5, 3, RandomPoseSettings(max_attempts=10), miss_fraction=lambda T: 1.0)


def test_sun_covers_the_papers_ranges_with_their_physical_meaning():
    suns = [random_sun(8, index) for index in range(500)]
    elevation = np.array([sun.elevation_deg for sun in suns])
    assert elevation.min() >= 30.0 and elevation.max() <= 90.0 and elevation.min() < 32 and elevation.max() > 88
    assert all(5.0 <= sun.intensity <= 10.0 for sun in suns)
    assert all(0.0 <= sun.azimuth_deg < 360.0 for sun in suns)
    for sun in suns:  # the sweep angle is elevation measured through the zenith
        assert sun.elevation_deg == pytest.approx(sun.sweep_angle_deg if sun.sweep_angle_deg <= 90
                                                  else 180.0 - sun.sweep_angle_deg)
    assert 130 < sum(sun.azimuth_deg >= 180.0 for sun in suns) < 370


def test_orbit_flies_a_circle_at_constant_speed_looking_at_the_centre():
    centre, radius, height, speed, rate = (30.0, -20.0), 50.0, 30.0, 2.5, 2.0
    path = orbit(GROUND, centre, radius, height, speed, rate)
    samples = [path.pose(GROUND, index) for index in range(0, 400, 7)]
    target = np.array([*centre, GROUND.ground_height(*centre)])
    for sample in samples:
        position = sample.T_world_cam[:3, 3]
        assert np.hypot(*(position[:2] - centre)) == pytest.approx(radius, rel=1e-4)
        assert position[2] == pytest.approx(target[2] + height)
        to_target = (target - position) / np.linalg.norm(target - position)
        np.testing.assert_allclose(optical_axis(sample.T_world_cam), to_target, atol=1e-3)
    one, two = path.pose(GROUND, 10), path.pose(GROUND, 11)
    step = np.linalg.norm(two.T_world_cam[:3, 3] - one.T_world_cam[:3, 3])
    assert step == pytest.approx(2 * radius * math.sin(speed / rate / radius / 2), rel=1e-4)
    assert two.time_s - one.time_s == pytest.approx(1 / rate)


def test_lawnmower_covers_the_area_and_ends():
    path = lawnmower(GROUND, spacing_m=60.0, height_m=40.0, speed_m_s=10.0, frame_rate_hz=1.0)
    count = path.frames_available()
    samples = [path.pose(GROUND, index) for index in range(count)]
    positions = np.array([s.T_world_cam[:3, 3] for s in samples])
    assert positions[:, 0].min() >= -180 and positions[:, 0].max() <= 180
    assert positions[:, 1].min() == pytest.approx(-130) and positions[:, 1].max() <= 130
    np.testing.assert_allclose([s.height_above_ground_m for s in samples], 40.0, atol=1e-4)
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)  # along the sloping rows, chords in the turns
    assert np.all(steps <= 10.0 + 1e-6) and np.median(steps) == pytest.approx(10.0, abs=1e-6)
    with pytest.raises(ValueError, match=f"lawnmower path is .* m long: {count} frames"):
        path.pose(GROUND, count)


def test_random_loop_is_smooth_and_flown_at_the_chosen_speed():
    speed, rate = 8.0, 10.0
    path = random_loop(GROUND, seed=4, height_m=60.0, speed_m_s=speed, frame_rate_hz=rate)
    samples = [path.pose(GROUND, index) for index in range(600)]
    positions = np.array([s.T_world_cam[:3, 3] for s in samples])
    xmin, xmax, ymin, ymax = GROUND.valid_area
    assert positions[:, 0].min() >= xmin + 20 and positions[:, 0].max() <= xmax - 20
    assert positions[:, 1].min() >= ymin + 20 and positions[:, 1].max() <= ymax - 20
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)  # chords of a smooth path: just under the arc
    np.testing.assert_allclose(steps, speed / rate, rtol=0.005)
    motion = positions[2:, :2] - positions[:-2, :2]
    image_top = np.array([-s.T_world_cam[:2, 1] for s in samples[1:-1]])  # camera -y axis, horizontal part
    cosine = np.sum(motion * image_top, axis=1) / np.linalg.norm(motion, axis=1) / np.linalg.norm(image_top, axis=1)
    assert cosine.min() > 0.999
    same = random_loop(GROUND, seed=4, height_m=60.0, speed_m_s=speed, frame_rate_hz=rate).pose(GROUND, 123)
    np.testing.assert_array_equal(same.T_world_cam, samples[123].T_world_cam)


GEOTAG_HEADER = ("image_name,utc_time,lat_deg,lon_deg,height_above_takeoff_m,absolute_height_m,aircraft_yaw_deg,"
                 "aircraft_pitch_deg,aircraft_roll_deg,gimbal_yaw_deg,gimbal_pitch_deg,gimbal_roll_deg,source,"
                 "time_offset_s,east_m,north_m,up_m,qw,qx,qy,qz")


def write_geotags(folder, origin: LocalFrame, poses, start=datetime(2026, 5, 1, 10, 0, tzinfo=timezone.utc),
                  sidecar_extra=None):
    rows = [GEOTAG_HEADER]
    for number, T in enumerate(poses):
        qx, qy, qz, qw = Rotation.from_matrix(T[:3, :3]).as_quat()
        time = (start + timedelta(seconds=2.5 * number)).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
        east, north, up = (float(value) for value in T[:3, 3])
        qx, qy, qz, qw = (float(value) for value in (qx, qy, qz, qw))
        numbers = ",".join(repr(value) for value in (east, north, up, qw, qx, qy, qz))
        rows.append(f"DJI_{number:04d}.JPG,{time},,,,,,,,,,,test,0,{numbers}")
    csv_path = folder / "geotags.csv"
    csv_path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    sidecar = {"origin": origin.to_dict(), **(sidecar_extra or {})}
    (folder / "geotags.json").write_text(json.dumps(sidecar), encoding="utf-8")
    return csv_path


def test_replay_moves_geotag_poses_into_the_scene_frame(tmp_path):
    takeoff = LocalFrame(40.1810, 44.5010, 1003.0)  # about 260 m from the scene origin
    poses = [np.eye(4) for _ in range(3)]
    for number, T in enumerate(poses):
        T[:3, :3] = camera_rotation(40.0 * number, 30.0)
        T[:3, 3] = (10.0 * number - 20.0, 5.0 * number, 30.0)
    samples = replay_poses(write_geotags(tmp_path, takeoff, poses), SCENE_ORIGIN, GROUND)
    assert [s.time_s for s in samples] == [0.0, 2.5, 5.0]
    assert [s.details["image_name"] for s in samples] == ["DJI_0000.JPG", "DJI_0001.JPG", "DJI_0002.JPG"]
    for sample, T in zip(samples, poses):
        for offset in (0.0, 20.0):  # the camera centre and a point 20 m along its optical axis
            point = T[:3, 3] + offset * T[:3, 2]
            expected = np.ravel(SCENE_ORIGIN.to_enu(*takeoff.to_geodetic(*point)))
            np.testing.assert_allclose(sample.T_world_cam[:3, 3] + offset * sample.T_world_cam[:3, 2], expected,
                                       atol=1e-4)


def test_replay_refuses_geotags_from_another_area(tmp_path):
    far_away = LocalFrame(40.6, 44.9, 1200.0)
    path = write_geotags(tmp_path, far_away, [np.eye(4)])
    with pytest.raises(ValueError, match=r"geotags.csv: photo DJI_0000.JPG lies \d+ m outside .* 5\d\.\d+ km from the "
                                         r"scene origin -- geotags from another area"):
        replay_poses(path, SCENE_ORIGIN, GROUND)


def test_replay_names_the_bad_line_and_a_missing_file(tmp_path):
    path = write_geotags(tmp_path, SCENE_ORIGIN, [np.eye(4), np.eye(4)])
    good = path.read_text()
    lines = good.splitlines()
    lines[2] = lines[2].replace(",0.0,0.0,0.0,1.0,", ",0.0,north?,0.0,1.0,")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"geotags.csv:3: .*'north\?'"):
        replay_poses(path, SCENE_ORIGIN, GROUND)
    path.write_text(good.replace("2026-05-01T10:00:02.500000Z", "ten past ten"))
    with pytest.raises(ValueError, match="geotags.csv:3: .*utc_time ISO 8601"):
        replay_poses(path, SCENE_ORIGIN, GROUND)
    path.write_bytes(b"\xff" + good.encode())
    with pytest.raises(ValueError, match="geotags.csv: not UTF-8 text \\(byte 0"):
        replay_poses(path, SCENE_ORIGIN, GROUND)
    path.write_text(good.replace(",1.0,0.0,0.0,0.0\n", ",,,,\n", 1))
    with pytest.raises(ValueError, match="geotags.csv: photo DJI_0000.JPG has no attitude"):
        replay_poses(path, SCENE_ORIGIN, GROUND)
    path.unlink()
    with pytest.raises(ValueError, match="geotags.csv: geotags file not found"):
        replay_poses(path, SCENE_ORIGIN, GROUND)
    (tmp_path / "geotags.json").unlink()
    with pytest.raises(ValueError, match="geotags.json: cannot read the origin"):
        replay_poses(path, SCENE_ORIGIN, GROUND)


TAKE_OFF = LocalFrame(40.1800, 44.5000, 0.0)  # ~90 m north, ~80 m east of the scene origin; h0 = 0 as capture
# writes it when the take-off height is unknown (the scene origin is at 1000 m)


def nadir_poses_over_take_off(heights_m) -> list[np.ndarray]:
    """Nadir cameras straight above the take-off point (geotags frame), ``heights_m`` above it."""
    return [pose_from_position((0.0, 0.0, height), R_WORLD_NADIR) for height in heights_m]


def test_replay_refuses_photos_below_the_ground(tmp_path):
    path = write_geotags(tmp_path, TAKE_OFF, nadir_poses_over_take_off([30.0, 40.0]))  # h0 = 0 taken at its word
    with pytest.raises(ValueError, match=r"geotags.csv: photo DJI_0000.JPG lies 9\d\d\.\d m below the scene's ground "
                                         r"under it -- is the origin height in geotags.json right\?"):
        replay_poses(path, SCENE_ORIGIN, GROUND)


def test_replay_puts_an_unknown_take_off_height_on_the_scene_ground(tmp_path):
    path = write_geotags(tmp_path, TAKE_OFF, nadir_poses_over_take_off([30.0, 40.0]),
                         sidecar_extra={"origin_height_known": False})
    samples = replay_poses(path, SCENE_ORIGIN, GROUND)
    h0 = samples[0].details["take_off_h0_ellipsoid_m"]
    take_off = np.ravel(SCENE_ORIGIN.to_enu(TAKE_OFF.lat0_deg, TAKE_OFF.lon0_deg, h0))
    assert take_off[2] == pytest.approx(float(GROUND.ground_height(*take_off[:2])), abs=1e-3)  # on the ground
    for sample, height in zip(samples, (30.0, 40.0)):
        np.testing.assert_allclose(sample.T_world_cam[:3, 3], take_off + [0.0, 0.0, height], atol=1e-3)
        assert sample.height_above_ground_m == pytest.approx(height, abs=1e-3)
    far_take_off = LocalFrame(40.1900, 44.5000, 0.0)  # 1.2 km north: outside the valid area
    path = write_geotags(tmp_path, far_take_off, nadir_poses_over_take_off([30.0]),
                         sidecar_extra={"origin_height_known": False})
    with pytest.raises(ValueError, match=r"geotags.json: origin_height_known is false and the take-off point lies "
                                         r"\d+ m outside the scene's valid area"):
        replay_poses(path, SCENE_ORIGIN, GROUND)
