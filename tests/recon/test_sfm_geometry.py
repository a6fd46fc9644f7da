"""Geo-registration and levelling (pure numpy), input checks, priors readers. Fast; no pycolmap runs."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from recon.inputs.priors import PosePriors, PriorsError, read_geotags
from recon.sfm.georegistration import georegister
from recon.sfm.matching import loop_pair
from recon.sfm.pipeline import auto_every_kth, check_inputs, select_core
from recon.inputs.similarity import Similarity
from tools.geotag_csv import ORIGIN, geotag_row, write_geotags


def orbit_cameras(n=30, radius=50.0, height=30.0):
    """Camera centres on a circle looking at the origin (ENU), ``R_world_cam`` with OpenCV axes."""
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    centres = np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.full(n, height)])
    rotations = []
    for c in centres:
        z = -c / np.linalg.norm(c)
        x = np.cross(z, [0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        rotations.append(np.column_stack([x, np.cross(z, x), z]))
    return centres, np.array(rotations)


def tilt_deg(r_a, r_b):
    """Angle between the world-up directions seen in two camera rotations (degrees, mean over cameras)."""
    up_a = np.einsum("nij,i->nj", r_a, [0, 0, 1.0])
    up_b = np.einsum("nij,i->nj", r_b, [0, 0, 1.0])
    return float(np.degrees(np.arccos(np.clip(np.sum(up_a * up_b, 1), -1, 1))).mean())


@pytest.fixture
def flight():
    rng = np.random.default_rng(5)
    centres, rotations = orbit_cameras()
    # SfM frame: an arbitrary similarity of the truth
    to_sfm = Similarity(0.37, Rotation.from_euler("xyz", [20, -40, 70], degrees=True).as_matrix(),
                        np.array([3.0, -1.0, 2.0]))
    sfm_centres = to_sfm.apply(centres)
    sfm_rotations = np.einsum("ij,njk->nik", to_sfm.rotation, rotations)
    # GPS: heights drift with east (a 1 deg tilt of the fitted plane), bias, white noise
    gps = centres + [1.5, -1.0, 4.0] + rng.normal(0, [0.5, 0.5, 0.3], centres.shape)
    gps[:, 2] += np.tan(np.radians(1.0)) * centres[:, 0]
    # attitude: pitch/roll good to 0.2 deg, yaw (compass) off by 5 deg
    yaw_error = Rotation.from_euler("z", 5, degrees=True).as_matrix()
    noise = Rotation.from_rotvec(rng.normal(0, np.radians(0.2), (len(centres), 3))).as_matrix()
    attitude = np.einsum("ij,njk,nkl->nil", yaw_error, rotations, noise)
    return centres, rotations, sfm_centres, sfm_rotations, gps, attitude


def test_levelling_removes_gps_tilt(flight):
    centres, rotations, sfm_centres, sfm_rotations, gps, attitude = flight
    names = tuple(f"p{i}.jpg" for i in range(len(centres)))
    without = georegister(sfm_centres, sfm_rotations, PosePriors(names, gps, None, ORIGIN))[0]
    levelled, tilt = georegister(sfm_centres, sfm_rotations, PosePriors(names, gps, attitude, ORIGIN))
    rot_without = np.einsum("ij,njk->nik", without.rotation, sfm_rotations)
    rot_levelled = np.einsum("ij,njk->nik", levelled.rotation, sfm_rotations)
    assert tilt_deg(rot_without, rotations) > 0.7  # GPS-only fit inherits the height drift
    assert tilt_deg(rot_levelled, rotations) < 0.1  # attitude fixes it
    assert 0.7 < tilt < 1.3
    # scale and horizontal position still come from GPS: scale within 0.5 %, centre near the GPS bias
    assert abs(levelled.scale * 0.37 - 1) < 0.005
    offset = (levelled.apply(sfm_centres) - centres).mean(axis=0)
    assert np.allclose(offset, [1.5, -1.0, 4.0], atol=0.5)


def test_georegister_without_attitude_matches_exact_positions(flight):
    centres, _, sfm_centres, sfm_rotations, _, _ = flight
    names = tuple(f"p{i}.jpg" for i in range(len(centres)))
    sim, tilt = georegister(sfm_centres, sfm_rotations, PosePriors(names, centres, None, ORIGIN))
    assert tilt is None
    assert np.allclose(sim.apply(sfm_centres), centres, atol=1e-8)


def test_loop_pair_and_core_selection():
    centres, _ = orbit_cameras(40)
    names = [f"p{i:02d}.jpg" for i in range(40)]
    priors = PosePriors(tuple(names), centres, None, ORIGIN)
    assert loop_pair(priors, names) == ("p00.jpg", "p39.jpg")
    line = PosePriors(tuple(names), np.column_stack([np.arange(40.0), np.zeros(40), np.zeros(40)]), None, ORIGIN)
    assert loop_pair(line, names) is None
    core = select_core(names, 3)
    assert core[0] == "p00.jpg" and core[-1] == "p39.jpg" and len(core) == 14
    assert select_core(names, 5)[-2:] == ["p35.jpg", "p39.jpg"]


def orbit_priors(count: int, radius_m: float, height_m: float, gps_sigma_m: float = 0.3) -> PosePriors:
    """``count`` photos around a circle ``height_m`` above the origin, GPS-noisy positions."""
    angles = np.linspace(0, 2 * np.pi, count, endpoint=False)
    centres = np.column_stack([radius_m * np.cos(angles), radius_m * np.sin(angles), np.full(count, height_m)])
    noisy = centres + np.random.default_rng(3).normal(0, gps_sigma_m, centres.shape)
    return PosePriors(tuple(f"p{i:03d}.jpg" for i in range(count)), noisy, None, ORIGIN)


@pytest.mark.parametrize("count, radius_m, height_m, expected", [
    (452, 50.0, 30.0, 4),   # the default orbit: 0.69 m steps, tan(5 deg) * 30 m = 2.6 m -> every 4th
    (452, 50.0, 60.0, 8),   # twice as high: twice as far apart
    (452, 50.0, 0.0, 1),    # EXIF priors: origin at the first photo, no height -> map every photo
    (24, 50.0, 30.0, 1),    # photos 13 m apart already
    (40, 2.0, 30.0, 4),     # tight circle would give k = 8: at least 10 photos stay in mapping
])
def test_auto_every_kth_spaces_mapped_photos_by_angle_from_the_flight_height(count, radius_m, height_m, expected):
    priors = orbit_priors(count, radius_m, height_m)
    assert auto_every_kth(priors, list(priors.names)) == expected


def test_check_inputs_errors():
    priors = PosePriors(("a.jpg", "b.jpg", "c.jpg"), np.zeros((3, 3)), None, ORIGIN)
    with pytest.raises(PriorsError, match="at least 3 photos"):
        check_inputs(["a.jpg"], priors)
    with pytest.raises(PriorsError, match="name none of the 3 photos"):
        check_inputs(["x.jpg", "y.jpg", "z.jpg"], priors)
    with pytest.raises(PriorsError, match="1 photo\\(s\\) have no geotag: d.jpg"):
        check_inputs(["a.jpg", "b.jpg", "d.jpg"], priors)


def test_read_geotags_positions_and_rotations(tmp_path):
    _, rotations = orbit_cameras(3)
    quats = Rotation.from_matrix(rotations).as_quat()  # x y z w
    rows = [geotag_row(f"p{i}.jpg", (i, 2 * i, 30.0), (q[3], q[0], q[1], q[2])) for i, q in enumerate(quats)]
    priors = read_geotags(write_geotags(tmp_path, rows))
    assert priors.names == ("p0.jpg", "p1.jpg", "p2.jpg")
    assert np.allclose(priors.positions_enu[2], [2, 4, 30])
    assert np.allclose(priors.rotations_world_cam, rotations, atol=1e-12)
    assert priors.origin == ORIGIN


def test_read_geotags_errors_name_file_and_line(tmp_path):
    good = geotag_row("p0.jpg", (0, 0, 30), (1, 0, 0, 0))
    path = write_geotags(tmp_path, [good, good.replace("p0.jpg", "p1.jpg").replace(",30,1,", ",abc,1,")])
    with pytest.raises(PriorsError, match=r"geotags.csv:3: east_m"):
        read_geotags(path)
    (tmp_path / "geotags.json").unlink()
    with pytest.raises(PriorsError, match="geotags.json"):
        read_geotags(path)
