"""Camera effects (sim/run/options.py settings, sim/render/film.py, sim/motion/shutter.py): rolling shutter skews a
vertical edge under a pure yaw by what the line delay
predicts, motion blur of a camera at rest changes nothing, noise has the configured statistics, vignetting follows
its formula, and a dataset's ground truth (depth, poses) is byte for byte the same with every effect on."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from render_scene_helpers import write_scene
from sim.render.camera import PinholeCamera, Rig, project_world_points
from sim.dataset.images import read_png
from sim.render.film import (
    LINEAR_BYTES_PER_PIXEL,
    PHOTOMETRIC_BYTES_PER_PIXEL,
    add_sensor_noise,
    apply_photometric,
    effects_memory_bytes,
    vignetting_gain,
)
from sim.motion.shutter import render_in_time
from sim.run.options import CameraEffects, PoseOptions, RenderInputError, RenderOptions, RigOptions
from sim.render.renderer import render
from sim.run.render_dataset import render_dataset
from sim.sampling.pose import R_WORLD_NADIR
from sim.render.color import SRGB8_TO_LINEAR, to_srgb8
from sim.render.shade import UNLIT, Sun
from sim.worlds.synthetic import colored_scene, height_field_scene

CAMERA = PinholeCamera.from_fov(160, 120, 60.0)
#: A level camera looking north (+y): the nadir camera tilted up by 90 degrees about its x axis.
R_LEVEL_NORTH = R_WORLD_NADIR @ Rotation.from_euler("x", 90.0, degrees=True).as_matrix()
EDGE_X_M, WALL_Y_M = 20.0, 100.0
YAW_RATE_RAD_S = 2.0


def yawing(time_s: float) -> np.ndarray:
    """A camera at the origin turning about the vertical at :data:`YAW_RATE_RAD_S`, level, north at t = 0."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", YAW_RATE_RAD_S * time_s).as_matrix() @ R_LEVEL_NORTH
    return T


def wall_columns(image_linear: np.ndarray) -> np.ndarray:
    """Per row, how many pixels from the left see the white wall (the wall fills the left of the view)."""
    return (image_linear[..., 0] > 0.9).sum(axis=1)


@pytest.fixture(scope="module")
def wall():
    """A white wall at y = 100 m covering x < 20 m, far taller than the view: its right end is a vertical edge."""
    box = trimesh.creation.box(bounds=[[-400.0, WALL_Y_M, -300.0], [EDGE_X_M, WALL_Y_M + 5.0, 300.0]])
    return colored_scene(box, rgb=(255, 255, 255))


def test_rolling_shutter_under_a_pure_yaw_skews_a_vertical_edge_by_the_line_delay(wall):
    line_delay = 1e-3
    effects = CameraEffects(line_delay_s=line_delay)
    image = render_in_time(wall, Rig((CAMERA,)), yawing, 0.0, effects=effects, samples_per_pixel=1,
                           rng=lambda: np.random.default_rng(0), **UNLIT)[0]
    rows = np.arange(CAMERA.height)
    times = (rows - (CAMERA.height - 1) / 2) * line_delay
    edge = np.array([project_world_points(CAMERA, yawing(t), [[EDGE_X_M, WALL_Y_M, 0.0]])[0][0, 0] for t in times])
    counted = wall_columns(image)
    # the pixel centres 0, 1, ... left of the edge's column see the wall: the count is the edge column rounded up
    assert np.all((counted >= edge) & (counted <= edge + 1))
    skew = edge[-1] - edge[0]
    assert abs(skew - CAMERA.fx * YAW_RATE_RAD_S * line_delay * (CAMERA.height - 1)) < 0.05 * abs(skew)
    assert abs(counted[-1] - counted[0]) >= 30  # a visible skew, which a global shutter does not have:
    still = render_in_time(wall, Rig((CAMERA,)), yawing, 0.0, effects=CameraEffects(exposure_s=1e-6, blur_samples=1),
                           samples_per_pixel=1, rng=lambda: np.random.default_rng(0), **UNLIT)[0]
    assert np.ptp(wall_columns(still)) == 0


def test_motion_blur_and_rolling_shutter_of_a_camera_at_rest_change_nothing():
    scene = height_field_scene(30, size_m=300.0, texture_size=128, seed=4)
    rig = Rig.stereo(PinholeCamera.from_fov(64, 40, 60.0), 1.0)
    pose = np.eye(4)
    pose[:3, :3] = R_WORLD_NADIR
    pose[2, 3] = 150.0
    sun = Sun(30.0, 50.0)
    for spp, effects in ((2, CameraEffects(exposure_s=0.02, blur_samples=3)),  # the jitter of the frame's own render
                         (1, CameraEffects(line_delay_s=1e-3, exposure_s=0.02, blur_samples=3))):  # rows alone
        frame = render(scene, rig, pose, sun, spp, rng=np.random.default_rng(5))
        blurred = render_in_time(scene, rig, lambda t: pose, 4.0, sun, effects, spp, lambda: np.random.default_rng(5))
        for image, view in zip(blurred, frame.views):
            np.testing.assert_array_equal(to_srgb8(image), view.rgb)

    def sliding(time_s):  # east at 200 m/s
        T = pose.copy()
        T[0, 3] += 200.0 * time_s
        return T

    moving = render_in_time(scene, rig, sliding, 0.0, sun, effects, 2, lambda: np.random.default_rng(5))
    assert np.abs(to_srgb8(moving[0]).astype(int) - frame.views[0].rgb).mean() > 1  # a moving camera does blur


def test_sensor_noise_has_the_configured_shot_and_read_noise():
    full_well, read = 1000.0, 5.0
    flat = np.full((400, 500), 0.25)
    noisy = add_sensor_noise(flat, full_well, read, np.random.default_rng(1)) * full_well
    assert abs(noisy.mean() - 250.0) < 0.5
    assert abs(noisy.var() / (250.0 + read**2) - 1) < 0.02  # Poisson: variance = mean (electrons), plus read^2
    dark = add_sensor_noise(np.zeros((400, 500)), full_well, read, np.random.default_rng(2)) * full_well
    assert abs(dark.std() / read - 1) < 0.02
    np.testing.assert_array_equal(add_sensor_noise(flat, full_well, read, np.random.default_rng(1)) * full_well, noisy)


def test_vignetting_gain_follows_its_formula():
    camera = PinholeCamera(100.0, 110.0, 40.0, 30.0, 81, 61)
    v, u = np.mgrid[0:61, 0:81].astype(float)
    tan2 = ((u - 40.0) / 100.0) ** 2 + ((v - 30.0) / 110.0) ** 2
    cos_theta = 1.0 / np.sqrt(1.0 + tan2)
    np.testing.assert_allclose(vignetting_gain(camera, "cos4"), cos_theta**4, rtol=1e-12)
    np.testing.assert_allclose(vignetting_gain(camera, (-0.3, 0.05, -0.01)),
                               1 - 0.3 * tan2 + 0.05 * tan2**2 - 0.01 * tan2**3, rtol=1e-12)
    grey = np.full((61, 81, 3), SRGB8_TO_LINEAR[200], np.float64)
    out = apply_photometric(grey, camera, CameraEffects(vignetting="cos4"), None, np.random.default_rng(0))
    assert out[30, 40, 0] == 200 and out[0, 0, 0] < 200
    np.testing.assert_allclose(SRGB8_TO_LINEAR[out[..., 1]], grey[..., 1] * cos_theta**4, rtol=0.02, atol=1e-3)


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return write_scene(tmp_path_factory.mktemp("scene"))


def test_ground_truth_is_identical_with_every_effect_on(scene_dir, tmp_path):
    base = dict(seed=2, rig=RigOptions(width=64, height=40),
                poses=PoseOptions(mode="trajectory", frames=3, altitude_m=40.0, speed_m_s=15.0))
    effects = CameraEffects(line_delay_s=2e-4, exposure_s=0.01, blur_samples=2, full_well_e=500.0, read_noise_e=2.0,
                            vignetting="cos4", auto_exposure=True)
    plain, affected = tmp_path / "plain", tmp_path / "effects"
    render_dataset(scene_dir, plain, RenderOptions(**base), command_line=["test"], progress=False)
    render_dataset(scene_dir, affected, RenderOptions(**base, effects=effects), command_line=["test"], progress=False)
    truth = ["poses/00.txt", "sequences/00/times.txt", "sequences/00/depth_2/000001.exr",
             "sequences/00/depth_3/000002.exr", "sequences/00/disp_2/000001.exr"]
    for name in truth:
        if (plain / name).exists():
            assert (plain / name).read_bytes() == (affected / name).read_bytes(), name
    assert (plain / truth[2]).exists()
    image = "sequences/00/image_2/000001.png"
    assert (plain / image).read_bytes() != (affected / image).read_bytes()


def test_rolling_shutter_and_blur_need_a_trajectory():
    for effects in (CameraEffects(line_delay_s=1e-4), CameraEffects(exposure_s=0.01)):
        with pytest.raises(RenderInputError, match="--mode trajectory"):
            RenderOptions(poses=PoseOptions(mode="random"), effects=effects)


def test_the_memory_estimate_covers_the_photometric_effects():
    camera = PinholeCamera.from_fov(200, 120, 70.0)
    linear = np.random.default_rng(0).random((120, 200, 3))
    effects = CameraEffects(vignetting="cos4", full_well_e=1000.0, read_noise_e=3.0, auto_exposure=True)
    tracemalloc.start()
    try:
        apply_photometric(linear, camera, effects, np.ones(3), np.random.default_rng(1))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    pixels = camera.width * camera.height
    assert 0.5 * PHOTOMETRIC_BYTES_PER_PIXEL * pixels < peak <= PHOTOMETRIC_BYTES_PER_PIXEL * pixels
    assert effects_memory_bytes([pixels, pixels]) == (2 * LINEAR_BYTES_PER_PIXEL + PHOTOMETRIC_BYTES_PER_PIXEL) * pixels


def test_auto_exposure_scales_each_frame_by_its_recorded_gain(scene_dir, tmp_path):
    base = dict(seed=5, rig=RigOptions(width=48, height=30),
                poses=PoseOptions(mode="trajectory", frames=4, altitude_m=40.0, speed_m_s=40.0))
    plain, drifting = tmp_path / "plain", tmp_path / "drift"
    render_dataset(scene_dir, plain, RenderOptions(**base), command_line=["test"], progress=False)
    render_dataset(scene_dir, drifting, RenderOptions(**base, effects=CameraEffects(auto_exposure=True)),
                   command_line=["test"], progress=False)
    records = [json.loads(line) for line in (drifting / "sequences/00/frames.jsonl").read_text().splitlines()]
    gains = np.array([record["auto_exposure_gain"] for record in records])
    assert np.all((gains > 0.5) & (gains < 2.0)) and np.ptp(gains[:, 1]) > 0.005  # it drifts from frame to frame
    for index, gain in enumerate(gains):
        for camera in (2, 3):
            name = f"sequences/00/image_{camera}/{index:06d}.png"
            expected = to_srgb8(SRGB8_TO_LINEAR[read_png(plain / name)] * gain.astype(np.float32))
            assert np.abs(read_png(drifting / name).astype(int) - expected).max() <= 1
