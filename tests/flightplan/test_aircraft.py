"""The camera profile's pinhole geometry is self-consistent and matches the published numbers."""

import math

import pytest

from flightplan.aircraft import DJI_MINI_SE, MINI_SE_CAMERA


def test_fovs_and_focal_length_agree():
    camera = MINI_SE_CAMERA
    f = camera.focal_length_px()
    half_diagonal = 0.5 * math.hypot(4000, 3000)
    assert math.degrees(2 * math.atan(half_diagonal / f)) == pytest.approx(83.0)
    assert camera.horizontal_fov_deg == pytest.approx(math.degrees(2 * math.atan(2000 / f)))
    assert camera.vertical_fov_deg < camera.horizontal_fov_deg < 83.0
    assert camera.focal_length_mm == pytest.approx(4.5, abs=0.2)  # 24 mm equivalent / crop factor ~5.6
    assert camera.sensor_height_mm == pytest.approx(6.17 * 0.75)


def test_resized_intrinsics_keep_the_field_of_view():
    fx, fy, cx, cy = MINI_SE_CAMERA.pinhole_intrinsics(1280)
    assert fx == fy == pytest.approx(MINI_SE_CAMERA.focal_length_px() * 1280 / 4000)
    assert (cx, cy) == (639.5, 479.5)
    assert MINI_SE_CAMERA.pinhole_intrinsics(4000, 2250)[3] == 1124.5


def test_mini_se_profile_marks_unverified_values():
    assert DJI_MINI_SE.min_timed_shot_interval_s == 2.0
    assert "min_timed_shot_interval_s" in DJI_MINI_SE.unverified
    assert "diagonal_fov_deg" in MINI_SE_CAMERA.unverified
    assert DJI_MINI_SE.usable_flight_time_s < DJI_MINI_SE.rated_flight_time_s == 1800.0
