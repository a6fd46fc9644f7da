"""DJI angle conventions against hand-derived directions, gimbal lock, yaw wrap, roll and round trips."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from capture.attitude import (
    AttitudeSeries,
    camera_matrix_world,
    gimbal_angles_from_camera,
    ned_angles,
    ned_rotation,
    wrap_deg,
)


def forward_enu(yaw_deg, pitch_deg):
    """Independent formula: viewing direction in ENU for yaw from north clockwise, pitch up positive."""
    y, p = np.radians(yaw_deg), np.radians(pitch_deg)
    return np.array([np.sin(y) * np.cos(p), np.cos(y) * np.cos(p), np.sin(p)])


@pytest.mark.parametrize("yaw", [-170.0, -90.0, 0.0, 37.5, 90.0, 179.9])
@pytest.mark.parametrize("pitch", [-89.0, -31.0, 0.0, 20.0])
def test_optical_axis_follows_yaw_and_pitch(yaw, pitch):
    R = camera_matrix_world(yaw, pitch, 0.0)
    np.testing.assert_allclose(R[:, 2], forward_enu(yaw, pitch), atol=1e-12)
    assert abs(R[2, 0]) < 1e-12  # no roll: image x axis stays horizontal
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


@pytest.mark.parametrize("yaw, up_enu", [(0.0, (0, 1, 0)), (90.0, (1, 0, 0)), (180.0, (0, -1, 0)), (-90.0, (-1, 0, 0))])
def test_nadir_yaw_still_defines_image_up(yaw, up_enu):
    R = camera_matrix_world(yaw, -90.0, 0.0)
    np.testing.assert_allclose(R[:, 2], [0, 0, -1], atol=1e-12)  # looking straight down
    np.testing.assert_allclose(-R[:, 1], up_enu, atol=1e-12)  # top of the image points along yaw


def test_nadir_round_trip_puts_the_rotation_in_yaw():
    R = camera_matrix_world(30.0, -90.0, 20.0)  # at gimbal lock yaw and roll mix
    yaw, pitch, roll = gimbal_angles_from_camera(R)
    assert pitch == pytest.approx(-90.0) and roll == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(camera_matrix_world(yaw, pitch, roll), R, atol=1e-9)


def test_positive_roll_lowers_the_right_side():
    R = camera_matrix_world(0.0, 0.0, 10.0)  # looking north, rolled right
    assert R[2, 0] == pytest.approx(-np.sin(np.radians(10.0)))  # image x (right) points down a bit


def test_aircraft_body_axes_are_forward_right_down():
    R = ned_rotation(90.0, 0.0, 0.0).as_matrix()  # R_ned_body, columns in NED
    np.testing.assert_allclose(R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)  # fwd=E, right=S, down=down


def test_slerp_crosses_the_yaw_wrap_the_short_way():
    series = AttitudeSeries([0.0, 1.0], ned_rotation([179.0, -179.0], [-30.0, -30.0], [0.0, 0.0]))
    yaw, pitch, _ = ned_angles(series(0.5))
    assert abs(wrap_deg(yaw - 180.0)) < 1e-9 and pitch == pytest.approx(-30.0)
    quarter = ned_angles(series(0.25))
    assert wrap_deg(quarter[0] - 179.5) == pytest.approx(0.0, abs=1e-9)


def test_wrap_deg():
    np.testing.assert_allclose(wrap_deg([180.0, -180.0, 359.0, 540.0, -181.0]), [-180.0, -180.0, -1.0, -180.0, 179.0])


angles = st.tuples(st.floats(-180, 179.999), st.floats(-89.5, 89.5), st.floats(-179.5, 179.5))


@settings(max_examples=200, deadline=None)
@given(angles)
def test_gimbal_angles_round_trip(ypr):
    recovered = gimbal_angles_from_camera(camera_matrix_world(*ypr))
    assert abs(wrap_deg(recovered[0] - ypr[0])) < 1e-6
    assert recovered[1] == pytest.approx(ypr[1], abs=1e-6)
    assert abs(wrap_deg(recovered[2] - ypr[2])) < 1e-6


@settings(max_examples=100, deadline=None)
@given(st.floats(-180, 180), st.floats(-180, 180), st.sampled_from([-90.0, 90.0]))
def test_rotation_round_trip_at_gimbal_lock(yaw, roll, pitch):
    R = camera_matrix_world(yaw, pitch, roll)
    np.testing.assert_allclose(camera_matrix_world(*gimbal_angles_from_camera(R)), R, atol=1e-8)


def test_vectorised_matches_scalar():
    ypr = np.array([[10.0, -20.0, 3.0], [-170.0, -90.0, 0.0]])
    batch = camera_matrix_world(ypr[:, 0], ypr[:, 1], ypr[:, 2])
    for row, matrix in zip(ypr, batch):
        np.testing.assert_allclose(camera_matrix_world(*row), matrix)
    assert isinstance(ned_rotation(0, 0, 0), Rotation)
