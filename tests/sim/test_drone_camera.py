"""The virtual drone's camera is as imperfect as a real one: auto-exposure gains per photo and channel, and the
aircraft profile's lens distortion, both exactly in the truth and (for the lens) in DJI's XMP."""

import csv
import datetime as dt
import json
import math
from dataclasses import replace

import numpy as np
import pytest
from defusedxml import ElementTree as SafeET
from PIL import Image
from scipy import ndimage

from capture.logs.photos import DRONE_DJI_NS
from flightplan.aircraft import MINI_SE_CAMERA
from sim.render.camera import Rig, look_at, project_world_points
from sim.drone import Imperfections
from sim.drone.exposure import GAIN_RANGE, auto_exposure_gains, metered_luminance
from sim.drone.photos import DEFAULT_SUN, photo_camera, poses_in_scene, render_photos
from sim.drone.session import FlyOptions, fly_litchi_mission, run_session
from sim.render.renderer import Lighting, Sun, render
from sim.render.scene import Scene, Surface, load_scene
from sim.render.classes import SKY
from sim.render.color import SRGB8_TO_LINEAR
from sim.sampling.sun import SUN_STRENGTH_TO_INTENSITY
from sim.worlds import demo_scene_dir
from tests.sim.drone_helpers import short_orbit_csv

START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)
#: Auto-exposure alone: no random part, no lag, so each gain is exactly what the metering asks for.
METERING_ONLY = replace(Imperfections.none(), exposure_metering=1.0)


@pytest.fixture(scope="module")
def world():
    return load_scene(demo_scene_dir("small"))


@pytest.fixture(scope="module")
def whole_orbit(tmp_path_factory):
    """The whole default orbit with a photo every 20 s: 24 photos, the camera facing every way round the POI."""
    return short_orbit_csv(tmp_path_factory.mktemp("orbit") / "orbit.csv", waypoints=100, photo_interval_s=20.0)


def linear(path) -> np.ndarray:
    """A JPEG's pixels in linear light, float (H, W, 3)."""
    with Image.open(path) as image:
        return SRGB8_TO_LINEAR[np.asarray(image.convert("RGB"))]


def measured_gain(photo_linear: np.ndarray, unit_linear: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """Per-channel linear gain of a photo against the unit-exposure render of the same view, over the pixels
    neither clipped nor near black in either, inside a surface of ``surface`` (the view's class image), 4 pixels or
    more from another class or the sky: the JPEG smears colour across such edges (a tree's ragged crown against the
    ground or the sky), which moves a channel's sum by a few percent in a small photo: at 160 x 120 the
    porous crowns and built details of the demo world leave too few clean pixels, so the photos here are 320 x 240."""
    usable = ((photo_linear > 0.02) & (photo_linear < 0.9) & (unit_linear > 0.02) & (unit_linear < 0.9)).all(axis=2)
    edge = ndimage.maximum_filter(surface, size=9) != ndimage.minimum_filter(surface, size=9)
    usable &= ~edge & (surface != SKY)
    return photo_linear[usable].sum(axis=0) / unit_linear[usable].sum(axis=0)


def sun_relative_heading_deg(mission, indices) -> np.ndarray:
    """Camera heading minus the sun's azimuth, wrapped to [-180, 180) degrees (0: the camera faces the sun)."""
    return (mission.photos.gimbal_ypr_deg[indices, 0] - DEFAULT_SUN.azimuth_deg + 180.0) % 360.0 - 180.0


def test_photo_gains_measured_against_unit_exposure_renders_equal_the_truth(world, tmp_path):
    """Each photo is its unit-exposure render under the sun truth.json gives it, times its gains."""
    options = FlyOptions(photo_size=(320, 240), seed=3, photo_limit=6, progress=False, start_utc=START)
    report = run_session(short_orbit_csv(tmp_path / "orbit.csv"), world, tmp_path / "fly", options)
    with open(tmp_path / "fly" / "truth.csv", newline="") as handle:
        truth = {row["image_name"]: row for row in csv.DictReader(handle) if row["gain_r"]}
    suns = {row["image_name"]: row["sun"] for row in json.loads((tmp_path / "fly" / "truth.json").read_text())["photos"]}
    assert len(truth) == 6
    photos = report.mission.photos
    taken = np.flatnonzero(photos.taken)[:6]
    poses = poses_in_scene(report.mission.flight.frame, world.origin, photos.position_enu_m[taken],
                           photos.R_world_cam[taken])
    camera = photo_camera(320, 240)
    measured, true = [], []
    for index, pose in zip(taken, poses):
        name = photos.names[index]
        sun = Sun(suns[name]["azimuth_deg"], suns[name]["elevation_deg"],
                  suns[name]["strength"] * SUN_STRENGTH_TO_INTENSITY)
        view = render(world, Rig((camera,)), pose, sun).views[0]
        measured.append(measured_gain(linear(tmp_path / "fly" / "photos" / name), SRGB8_TO_LINEAR[view.rgb],
                                      world.labels.class_image(view.triangle)))
        true.append([float(truth[name][f"gain_{c}"]) for c in "rgb"])
    measured, true = np.array(measured), np.array(true)
    np.testing.assert_allclose(measured, true, rtol=0.015)  # JPEG q92 and 8-bit rounding
    assert np.ptp(true[:, 1]) > 0.03  # the gains really differ from photo to photo


def test_the_camera_brightens_views_that_face_the_sun_and_evens_out_brightness(world, whole_orbit, tmp_path):
    mission = fly_litchi_mission(whole_orbit, world, 5, METERING_ONLY)
    rendered = render_photos(mission, world, tmp_path, photo_camera(160, 120, lens=0.0), START, progress=False)
    taken = np.flatnonzero(mission.photos.taken)
    gains = rendered.gains[taken, 1]
    relative = np.abs(sun_relative_heading_deg(mission, taken))
    # towards the sun the camera sees the shaded sides of walls and trees: darker, so the gain rises
    assert gains[relative < 60].mean() > 1.15 * gains[relative > 120].mean()
    assert GAIN_RANGE[0] <= gains.min() and gains.max() <= GAIN_RANGE[1]
    # metering then sees each photo about equally bright: gain x unit-exposure brightness = the flight's median
    photo_brightness = np.array([metered_luminance(linear(tmp_path / mission.photos.names[i])) for i in taken])
    unit_brightness = photo_brightness / gains
    assert np.std(np.log(photo_brightness)) < 0.25 * np.std(np.log(unit_brightness))


def test_gains_follow_a_brightness_step_with_the_lag():
    times = np.arange(0.0, 12.0, 2.0)
    metered = np.where(times < 5.0, 0.1, 0.2)  # a turn towards brighter views between 4 s and 6 s
    lagging = replace(METERING_ONLY, exposure_lag_s=3.0)
    gains = auto_exposure_gains(times, metered, np.zeros((6, 4)), lagging)[:, 0]
    median = math.sqrt(0.1 * 0.2)
    before, after = median / 0.1, median / 0.2
    log_expected = np.log(after) + (np.log(before) - np.log(after)) * np.exp(-(times - 4.0) / 3.0)
    expected = np.where(times < 5.0, before, np.exp(log_expected))
    np.testing.assert_allclose(gains, expected, rtol=1e-12)
    at_once = auto_exposure_gains(times, metered, np.zeros((6, 4)), METERING_ONLY)
    np.testing.assert_allclose(at_once[:, 2], np.where(times < 5.0, before, after), rtol=1e-12)
    # held to +-0.5 EV, and all ones when auto-exposure is off
    extreme = auto_exposure_gains(times[:3], [0.01, 0.1, 1.0], np.zeros((3, 4)), METERING_ONLY)
    np.testing.assert_allclose(extreme[:, 0], [GAIN_RANGE[1], 1.0, GAIN_RANGE[0]])
    np.testing.assert_array_equal(auto_exposure_gains(times, metered, np.ones((6, 4)), Imperfections.none()), 1.0)


def test_gains_reproduce_from_the_seed(world, tmp_path):
    csv_path = short_orbit_csv(tmp_path / "orbit.csv")

    def gains(seed, out):
        mission = fly_litchi_mission(csv_path, world, seed, Imperfections.realistic())
        return render_photos(mission, world, tmp_path / out, photo_camera(64, 48), START, limit=4,
                             progress=False).gains

    first, again, other = gains(1, "a"), gains(1, "b"), gains(2, "c")
    np.testing.assert_array_equal(first, again)
    rendered = np.isfinite(first[:, 0])
    assert rendered.sum() == 4 and not np.allclose(first[rendered], other[np.isfinite(other[:, 0])])
    assert np.std(np.log(first[rendered][:, 0] / first[rendered][:, 2])) > 0  # white balance differs by channel


def plates(centres: np.ndarray, side_m: float) -> Scene:
    """Horizontal grey squares of ``side_m`` centred on ``centres`` (N, 3) ENU, nothing else."""
    half = side_m / 2.0
    corners = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
    vertices = (centres[:, None, :] + corners).reshape(-1, 3)
    faces = (np.arange(len(centres))[:, None, None] * 4 + np.array([[0, 1, 2], [0, 2, 3]])).reshape(-1, 3)
    return Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 128, np.uint8)))


def test_a_world_point_lands_in_the_photo_where_the_distorted_camera_projects_it():
    camera = photo_camera(400, 300)
    pose = look_at([0.0, 0.0, 30.0], [0.0, 0.0, 0.0])  # nadir, image-up north
    # plate centres towards the image corners and edges, where the barrel distortion is largest
    centres = np.array([[x, y, 0.0] for x in (-19.0, 0.0, 19.0) for y in (-14.0, 14.0)] + [[10.0, 0.0, 0.0]])
    scene = plates(centres, 0.8)
    # black sky, evenly lit plates, 9 samples a pixel: a pixel's brightness is the plate's share of it
    black_sky = Lighting(sky_zenith=(0.0, 0.0, 0.0), sky_horizon=(0.0, 0.0, 0.0))
    rgb = render(scene, Rig((camera,)), pose, DEFAULT_SUN, samples_per_pixel=9, lighting=black_sky).views[0].rgb
    coverage = SRGB8_TO_LINEAR[rgb[..., 1]]
    labels, count = ndimage.label(coverage > 0)
    assert count == len(centres)
    found = np.array(ndimage.center_of_mass(coverage, labels, range(1, count + 1)))[:, ::-1]  # (row, col) -> (u, v)
    expected = project_world_points(camera, pose, centres)[0]
    found = found[np.argmin(np.linalg.norm(found[None] - expected[:, None], axis=2), axis=1)]  # plate by plate
    ideal = project_world_points(photo_camera(400, 300, lens=0.0), pose, centres)[0]
    np.testing.assert_allclose(found, expected, atol=0.1)  # < a half-pixel convention slip
    assert np.linalg.norm(ideal - expected, axis=1).max() > 10.0  # the distortion moves the corner ones a lot


def xmp_values(path) -> dict[str, str]:
    """The ``drone-dji:`` attributes of a JPEG's XMP packet, parsed with defusedxml."""
    with Image.open(path) as image:
        packet = image.info["xmp"]
    root = SafeET.fromstring(packet[packet.find(b"<x:xmpmeta"):packet.rfind(b"</x:xmpmeta>") + 12])
    prefix = "{" + DRONE_DJI_NS + "}"
    return {k[len(prefix):]: v for e in root.iter() for k, v in e.attrib.items() if k.startswith(prefix)}


def test_photo_xmp_carries_the_profile_calibration_in_djis_convention(world, tmp_path):
    options = FlyOptions(photo_size=(800, 600), seed=3, photo_limit=1, progress=False, start_utc=START)
    run_session(short_orbit_csv(tmp_path / "orbit.csv"), world, tmp_path, options)
    xmp = xmp_values(tmp_path / "photos" / "DJI_0001.JPG")
    assert (xmp["CalibratedOpticalCenterX"], xmp["CalibratedOpticalCenterY"]) == ("400.000000", "300.000000")
    assert xmp["DewarpFlag"] == "0"
    date, numbers = xmp["DewarpData"].split(";")
    assert dt.date.fromisoformat(date)
    fx, fy, dcx, dcy, *distortion = (float(v) for v in numbers.split(","))
    scale = 800 / MINI_SE_CAMERA.image_width_px
    assert fx == fy == pytest.approx(MINI_SE_CAMERA.focal_length_px(800), abs=1e-6)
    assert float(xmp["CalibratedFocalLength"]) == pytest.approx(fx, abs=1e-6)
    np.testing.assert_allclose([dcx, dcy], np.array(MINI_SE_CAMERA.principal_point_offset_px) * scale, atol=1e-9)
    np.testing.assert_allclose(distortion, MINI_SE_CAMERA.distortion, atol=1e-12)
    camera = photo_camera(800, 600)  # what the truth holds, in our convention (pixel centres): cx = 400 + dcx - 0.5
    assert (camera.cx, camera.cy) == pytest.approx((400.0 + dcx - 0.5, 300.0 + dcy - 0.5), abs=1e-9)


def test_the_ideal_profile_keeps_a_centred_pinhole_and_constant_exposure(world, tmp_path):
    camera = photo_camera(800, 600, lens=Imperfections.none().lens_distortion)
    assert camera.dist is None and (camera.cx, camera.cy) == (399.5, 299.5)
    mission = fly_litchi_mission(short_orbit_csv(tmp_path / "orbit.csv"), world, 1, Imperfections.none())
    rendered = render_photos(mission, world, tmp_path, photo_camera(32, 24), START, limit=3, progress=False)
    np.testing.assert_array_equal(rendered.gains[np.isfinite(rendered.gains)], 1.0)
