"""The virtual drone's photo faults (``fly --skip-shots``, ``--blur``): the blur kernel against its analytic shape, the
windows resolved on a flight's photos, and a flight whose card lacks the skipped shots the telemetry reports."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from capture.logs import read_track
from sim.cli import main as render_main
from sim.drone.photo_faults import (LINE_SAMPLES_PER_PX, MOTION_BLUR, SKIPPED_SHOT, FaultWindow, PhotoFaults,
                                    image_motion_direction, line_kernel, motion_blur)
from sim.render.color import SRGB8_TO_LINEAR
from tests.sim.drone_helpers import short_orbit_csv

#: A camera looking north, level: OpenCV x right = east, y down = -up, z forward = north (columns of R_world_cam).
LOOKING_NORTH = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@pytest.mark.parametrize("length", [2.0, 5.0, 12.5])
@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 90.0])
def test_line_kernel_is_a_uniform_segment_of_the_length(length, angle_deg):
    """Weights sum to 1, are centred, and spread along the direction as the segment's N evenly spaced points do
    (variance L^2/12 (N+1)/(N-1)) plus the bilinear splat's 1/6 px^2, and hardly across it."""
    direction = (np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg)))
    kernel = line_kernel(length, direction)
    y, x = np.indices(kernel.shape) - kernel.shape[0] // 2
    along, across = x * direction[0] + y * direction[1], -x * direction[1] + y * direction[0]
    assert kernel.sum() == pytest.approx(1.0)
    assert np.sum(kernel * along) == pytest.approx(0.0, abs=1e-9)
    points = int(LINE_SAMPLES_PER_PX * length) + 1
    splat = 1.0 / 6.0
    assert np.sum(kernel * along ** 2) == pytest.approx(length ** 2 / 12 * (points + 1) / (points - 1) + splat, abs=0.02)
    assert np.sum(kernel * across ** 2) < 0.2  # at most a splat across


def test_motion_blur_smears_a_point_into_a_line_and_keeps_a_flat_image():
    image = np.full((41, 41, 3), 40, np.uint8)
    assert np.array_equal(motion_blur(image, 7.0, (1.0, 0.0)), image)
    image[20, 20] = 255
    blurred = motion_blur(image, 7.0, (1.0, 0.0))
    lit = SRGB8_TO_LINEAR[blurred[..., 1]] - SRGB8_TO_LINEAR[40]
    columns = np.flatnonzero(lit[20] > 1e-3)
    assert lit[19].max() < 1e-3 and lit[21].max() < 1e-3  # nothing across the motion
    assert 7 <= columns[-1] - columns[0] + 1 <= 9  # the line's length, plus the splat's pixel
    assert lit.sum() == pytest.approx(SRGB8_TO_LINEAR[255] - SRGB8_TO_LINEAR[40], rel=0.02)  # light is kept


def test_the_image_moves_along_the_camera_velocity():
    assert image_motion_direction(LOOKING_NORTH, [2.0, 0.0, 0.0]) == pytest.approx((1.0, 0.0))  # east: right
    assert image_motion_direction(LOOKING_NORTH, [0.0, 0.0, 1.0]) == pytest.approx((0.0, -1.0))  # up: image up
    assert image_motion_direction(LOOKING_NORTH, [0.0, 3.0, 0.0]) == (1.0, 0.0)  # along the axis: no direction


@pytest.mark.parametrize("window", [(SKIPPED_SHOT, -1.0, 5.0), (SKIPPED_SHOT, 5.0, 5.0), (SKIPPED_SHOT, 1.0, 1e6),
                                    (MOTION_BLUR, 1.0, 2.0, 0.0), (MOTION_BLUR, 1.0, 2.0, 101.0),
                                    (MOTION_BLUR, 1.0, 2.0, float("nan"))])
def test_out_of_bounds_windows_are_refused(window):
    with pytest.raises(ValueError):
        FaultWindow(*window)


def test_windows_resolve_to_the_photos_taken_in_them():
    t_s = np.arange(10.0)
    names = [f"DJI_{k:04d}.JPG" for k in range(1, 11)]
    rendered = np.arange(8)  # the last two not rendered (--photos 8)
    faults = PhotoFaults((FaultWindow(SKIPPED_SHOT, 2.5, 3.5), FaultWindow(MOTION_BLUR, 5.0, 6.0, 4.0)))
    plan = faults.on(t_s, names, rendered, np.tile(LOOKING_NORTH, (10, 1, 1)), np.tile([1.0, 0, 0], (10, 1)))
    assert plan.missing == {3}
    assert plan.blur_px == {5: 4.0, 6: 4.0} and plan.blur_direction[5] == pytest.approx((1.0, 0.0))
    assert plan.truth() == [{"kind": SKIPPED_SHOT, "start_s": 2.5, "end_s": 3.5, "photos": ["DJI_0004.JPG"]},
                            {"kind": MOTION_BLUR, "start_s": 5.0, "end_s": 6.0, "blur_px": 4.0,
                             "photos": ["DJI_0006.JPG", "DJI_0007.JPG"]}]
    with pytest.raises(ValueError, match=r"--blur 8,9.5,4: no photo is taken in that window"):
        PhotoFaults((FaultWindow(MOTION_BLUR, 8.0, 9.5, 4.0),)).on(t_s, names, rendered, np.tile(LOOKING_NORTH, (10, 1, 1)),
                                                                  np.zeros((10, 3)))


@pytest.mark.slow
def test_a_flight_with_photo_faults_has_them_on_its_card_and_in_its_truth(tmp_path):
    """The skipped shots fire (a shutter event each in the DUML capture) but are not on the card; the blurred photos
    are blurred against the same flight flown clean; truth.json lists both."""
    mission = short_orbit_csv(tmp_path / "m.csv")
    common = ["fly", "--mission", str(mission), "--scene", "demo:small", "--photo-size", "80", "60", "--seed", "0"]
    assert render_main([*common, "--out", str(tmp_path / "clean")]) == 0
    assert render_main([*common, "--out", str(tmp_path / "faulty"), "--skip-shots", "30,31.5",
                        "--blur", "40,43,4"]) == 0
    faults = json.loads((tmp_path / "faulty" / "truth.json").read_text())["faults"]
    skipped, blurred = faults
    assert skipped["kind"] == SKIPPED_SHOT and len(skipped["photos"]) >= 1
    assert blurred["kind"] == MOTION_BLUR and blurred["blur_px"] == 4.0 and len(blurred["photos"]) >= 3
    truth = json.loads((tmp_path / "faulty" / "truth.json").read_text())["photos"]
    for row in truth:
        in_window = skipped["start_s"] <= row["t_s"] <= skipped["end_s"]
        assert (row["image_name"] in skipped["photos"]) == (row["taken"] and in_window)
    card = {path.name for path in (tmp_path / "faulty" / "photos").iterdir()}
    assert card == {row["image_name"] for row in truth if row["taken"]} - set(skipped["photos"])
    events = read_track(tmp_path / "faulty" / "flight.duml").photo_times_s
    assert len(events) == sum(row["taken"] for row in truth)  # the skipped shots fired
    for name in blurred["photos"]:
        clean, faulty = (np.asarray(Image.open(tmp_path / run / "photos" / name).convert("L"), float)
                         for run in ("clean", "faulty"))
        assert np.abs(np.diff(faulty, axis=1)).mean() < 0.8 * np.abs(np.diff(clean, axis=1)).mean()
