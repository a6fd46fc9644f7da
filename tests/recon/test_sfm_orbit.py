"""SfM closed loop on a synthetic orbit over a textured plane: known poses, GPS with a height drift,
attitudes from the 'gimbal'. Checks registration, the orbit's loop pair, levelling and pose accuracy."""

import cv2
import numpy as np
import pycolmap
import pytest
from scipy.spatial.transform import Rotation

from recon.surface.dense import View
from recon.inputs.priors import CameraSeed, read_geotags
from recon.sfm.options import SfmOptions
from recon.sfm.cameras import camera_poses
from recon.sfm.pipeline import run_sfm
from tools.geotag_csv import geotag_row, write_geotags
from tests.recon.synthetic import FOCAL, HEIGHT, WIDTH, make_texture, render_plane

NUM_PHOTOS, RADIUS_M, HEIGHT_M, PITCH_DEG = 24, 15.0, 15.0, -60.0
GPS_BIAS = np.array([1.0, -0.5, 3.0])


def orbit_rotation(centre: np.ndarray) -> np.ndarray:
    """``R_world_cam`` of a camera at ``centre`` facing the orbit centre, pitched ``PITCH_DEG``."""
    heading = -centre[:2] / np.linalg.norm(centre[:2])
    pitch = np.radians(PITCH_DEG)
    forward = np.array([heading[0] * np.cos(pitch), heading[1] * np.cos(pitch), np.sin(pitch)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return np.column_stack([right, np.cross(forward, right), forward])


@pytest.fixture(scope="module")
def orbit(tmp_path_factory):
    folder = tmp_path_factory.mktemp("orbit")
    photos = folder / "photos"
    photos.mkdir()
    rng = np.random.default_rng(11)
    texture = make_texture()
    K = np.array([[FOCAL, 0, WIDTH / 2], [0, FOCAL, HEIGHT / 2], [0, 0, 1.0]])
    angles = np.linspace(0, 2 * np.pi, NUM_PHOTOS, endpoint=False)
    centres = np.column_stack([RADIUS_M * np.cos(angles), RADIUS_M * np.sin(angles), np.full(NUM_PHOTOS, HEIGHT_M)])
    rotations = np.array([orbit_rotation(c) for c in centres])
    gps = centres + GPS_BIAS + rng.normal(0, [0.3, 0.3, 0.2], centres.shape)
    gps[:, 2] += np.tan(np.radians(1.0)) * centres[:, 0]  # GPS heights drift: a 1 deg tilt
    attitude = Rotation.from_euler("z", 3.0, degrees=True) * Rotation.from_matrix(rotations) * \
        Rotation.from_rotvec(rng.normal(0, np.radians(0.15), (NUM_PHOTOS, 3)))
    quats = attitude.as_quat()  # x y z w
    rows = []
    for i, (centre, rotation) in enumerate(zip(centres, rotations)):
        name = f"orbit_{i:02d}.png"
        cv2.imwrite(str(photos / name), render_plane(texture, View(K, rotation.T, -rotation.T @ centre)))
        rows.append(geotag_row(name, gps[i], (quats[i, 3], *quats[i, :3])))
    geotags = write_geotags(folder, rows)
    return photos, read_geotags(geotags), centres, rotations


@pytest.mark.slow
def test_orbit_registers_closes_the_loop_and_is_levelled(orbit, tmp_path):
    photos, priors, centres, rotations = orbit
    pycolmap.logging.minloglevel = 2
    seed = CameraSeed.simple_radial(1.03 * FOCAL, WIDTH, HEIGHT, "test: 3 % too long")
    rec, report = run_sfm(photos, priors.names, priors, seed, tmp_path,
                          SfmOptions(max_num_features=2048, spatial_neighbors=8, focal="auto"))
    assert len(report.registered) == NUM_PHOTOS
    assert report.loop_pair == ["orbit_00.png", f"orbit_{NUM_PHOTOS - 1}.png"]
    assert report.loop_pair_inliers >= 50
    assert 0.6 < report.tilt_correction_deg < 1.4
    # converging oblique views determine the focal length: "auto" frees it and recovers the truth
    assert report.focal_refined and report.view_spread_deg > 20
    assert report.focal_final_px == pytest.approx(FOCAL, rel=0.005)
    assert pycolmap.logging.minloglevel == 2  # the focal bundle adjustment leaves the caller's log level alone
    poses = camera_poses(rec)
    est_centres = np.array([poses[n][:3, 3] for n in priors.names])
    est_rotations = np.array([poses[n][:3, :3] for n in priors.names])
    # tilt from the attitudes: within 0.1 deg (a GPS-only fit inherits the 1 deg height drift); yaw comes from
    # the GPS positions: within 3 sigma of its noise bound sigma / (radius * sqrt(N / 2))
    world_error = np.degrees(Rotation.from_matrix(np.einsum("nij,nkj->nik", est_rotations, rotations)).as_rotvec())
    assert np.abs(world_error[:, :2]).max() < 0.1
    yaw_sigma_deg = np.degrees(0.3 / (RADIUS_M * np.sqrt(NUM_PHOTOS / 2)))
    assert np.abs(world_error[:, 2]).max() < 3 * yaw_sigma_deg
    # positions: truth + the GPS bias, within the GPS noise
    offset = est_centres - centres
    assert np.allclose(offset.mean(axis=0), GPS_BIAS, atol=0.35)
    assert np.abs(offset - offset.mean(axis=0)).max() < 0.25


@pytest.mark.slow
def test_photos_left_out_of_mapping_register_by_absolute_pose(orbit, tmp_path):
    """Every 3rd photo mapped (8 + the last), the other 15 registered into that model without bundle adjustment
    of their own: all 24 land as close to the truth as when every photo is mapped."""
    photos, priors, centres, rotations = orbit
    pycolmap.logging.minloglevel = 2
    seed = CameraSeed.simple_radial(FOCAL, WIDTH, HEIGHT, "test: exact")
    rec, report = run_sfm(photos, priors.names, priors, seed, tmp_path,
                          SfmOptions(max_num_features=2048, spatial_neighbors=8, focal="fixed", every_kth=3))
    assert len(report.registered) == NUM_PHOTOS and not report.warnings
    assert "register_rest" in report.seconds
    poses = camera_poses(rec)
    offset = np.array([poses[n][:3, 3] for n in priors.names]) - centres
    assert np.abs(offset - offset.mean(axis=0)).max() < 0.25
    errors = Rotation.from_matrix(np.einsum("nij,nkj->nik", [poses[n][:3, :3] for n in priors.names], rotations))
    assert np.degrees((errors.mean().inv() * errors).magnitude()).max() < 0.1  # about their common yaw offset
    left_out = [rec.find_image_with_name(n) for n in priors.names[1::3]]
    assert all(image.num_points3D >= 100 for image in left_out)  # they observe points: dense can pair them
    finest = finest_keypoint_scales(tmp_path / "database.db")
    mapped = [name for i, name in enumerate(priors.names) if i % 3 == 0 or i == NUM_PHOTOS - 1]
    # SIFT on the doubled image finds scales from 0.8 px (the 2048-feature cap drops the finest); at the photo's own
    # size, from 1.6 px
    assert max(finest[name] for name in mapped) < 1.5
    assert min(scale for name, scale in finest.items() if name not in mapped) > 1.55


def finest_keypoint_scales(database) -> dict[str, float]:
    """Each photo's smallest SIFT keypoint scale in ``database`` (px of the photo: the root of the affine shape's
    determinant)."""
    with pycolmap.Database.open(database) as db:
        shapes = {image.name: db.read_keypoints(image.image_id)[:, 2:] for image in db.read_all_images()}
    return {name: float(np.sqrt(np.abs(s[:, 0] * s[:, 3] - s[:, 1] * s[:, 2])).min()) for name, s in shapes.items()}
