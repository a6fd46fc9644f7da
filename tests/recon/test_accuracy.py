"""recon.measure.accuracy against known truth: analytic meshes and poses with known offsets and rotations."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from recon.measure.accuracy import (depth_coverage, distances_to_surface, pose_alignment, pose_errors,
                                    pose_matrix, surface_errors, transform_poses)


def plane(size_m: float = 100.0, z: float = 0.0, cells: int = 4) -> trimesh.Trimesh:
    """A square z = const plane of 2 * cells^2 big triangles (bigger than the subdivision size)."""
    xs = np.linspace(-size_m / 2, size_m / 2, cells + 1)
    x, y = np.meshgrid(xs, xs)
    vertices = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
    faces = []
    for row in range(cells):
        for col in range(cells):
            a = row * (cells + 1) + col
            faces += [[a, a + 1, a + cells + 2], [a, a + cells + 2, a + cells + 1]]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def test_distances_to_a_plane_and_a_sphere_are_exact():
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(-40, 40, 500), rng.uniform(-40, 40, 500), rng.uniform(-3, 3, 500)])
    assert distances_to_surface(plane(), points) == pytest.approx(np.abs(points[:, 2]), abs=1e-9)
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=10.0)
    directions = rng.normal(size=(200, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = rng.uniform(10.5, 14.0, 200)
    # the icosphere's facets lie inside the sphere by at most ~1 mm at this subdivision
    assert distances_to_surface(sphere, directions * radii[:, None]) == pytest.approx(radii - 10.0, abs=5e-3)


def test_distance_near_a_big_wall_is_to_the_wall_not_to_its_far_centroid():
    wall = trimesh.Trimesh([[0, -50, 0], [0, 50, 0], [0, 50, 20], [0, -50, 20]], [[0, 1, 2], [0, 2, 3]])
    points = np.array([[0.3, -49.0, 1.0], [-2.0, 45.0, 19.0]])
    assert distances_to_surface(wall, points) == pytest.approx([0.3, 2.0], abs=1e-9)


def test_surface_errors_of_a_raised_plane_and_a_half_reconstruction():
    truth = plane(z=0.0)
    raised = plane(z=0.1)
    errors = surface_errors(raised, truth, (0.0, 0.0), 30.0, threshold_m=0.25, samples=4000)
    assert errors.accuracy_median_m == pytest.approx(0.1, abs=1e-9)
    assert errors.accuracy_p90_m == pytest.approx(0.1, abs=1e-9)
    assert errors.completeness == 1.0
    too_high = surface_errors(plane(z=0.4), truth, (0.0, 0.0), 30.0, threshold_m=0.25, samples=4000)
    assert too_high.completeness == 0.0
    # only the half-plane x < 0 reconstructed: completeness is the area fraction inside the disc (1/2)
    half = raised.submesh([np.flatnonzero(raised.triangles_center[:, 0] < 0)], append=True)
    half_errors = surface_errors(half, truth, (0.0, 0.0), 30.0, samples=20000, rng=np.random.default_rng(3))
    assert half_errors.completeness == pytest.approx(0.5, abs=0.03)
    assert half_errors.accuracy_median_m == pytest.approx(0.1, abs=1e-9)


def test_surface_errors_without_truth_in_the_area_is_an_error():
    with pytest.raises(ValueError, match="no surface within"):
        surface_errors(plane(), plane(), (500.0, 0.0), 10.0)


def test_pose_errors_of_known_offsets_and_rotations():
    rng = np.random.default_rng(2)
    truth = pose_matrix(rng.uniform(-50, 50, (5, 3)), Rotation.random(5, random_state=3).as_quat(scalar_first=True))
    estimated = truth.copy()
    estimated[:, :3, 3] += [3.0, 4.0, -2.0]                                    # 5 m horizontal, 2 m vertical
    estimated[:, :3, :3] = Rotation.from_euler("z", 2.0, degrees=True).as_matrix() @ truth[:, :3, :3]
    errors = pose_errors(estimated, truth)
    assert errors.count == 5
    assert errors.horizontal_m["median"] == pytest.approx(5.0)
    assert errors.vertical_m["max"] == pytest.approx(2.0)
    assert errors.position_m["rms"] == pytest.approx(np.sqrt(29.0))
    assert errors.rotation_deg["median"] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="pose stacks"):
        pose_errors(estimated[:3], truth)


def test_transform_to_moves_poses_between_origins_like_geodesy():
    a = LocalFrame(40.1792, 44.4991, 1000.0)
    b = LocalFrame(40.1800, 44.5000, 1003.0)
    point_in_a = np.array([12.0, -30.0, 25.0])
    lat, lon, h = a.to_geodetic(*point_in_a)
    expected = b.enu_points(lat, lon, h)
    T = a.transform_to(b)
    moved = transform_poses(T, pose_matrix(point_in_a, np.array([1.0, 0, 0, 0])))
    assert moved[0, :3, 3] == pytest.approx(expected, abs=1e-6)
    assert np.allclose(moved[0, :3, :3] @ moved[0, :3, :3].T, np.eye(3))


def test_depth_coverage_counts_true_pixels_the_prediction_also_sees():
    truth = np.array([[1.0, 2.0], [np.inf, 4.0]])
    predicted = np.array([[1.1, np.inf], [3.0, 0.0]])
    assert depth_coverage(predicted, truth) == pytest.approx(1 / 3)
    assert np.isnan(depth_coverage(predicted, np.full((2, 2), np.inf)))
    with pytest.raises(ValueError, match="sizes must match"):
        depth_coverage(predicted[:1], truth)


def test_pose_alignment_recovers_a_known_rigid_motion_from_cameras_on_a_straight_line():
    centres = np.column_stack([np.linspace(0, 20, 10), np.zeros(10), np.full(10, 30.0)])  # collinear centres
    truth = pose_matrix(centres, Rotation.random(10, random_state=5).as_quat(scalar_first=True))
    known = np.eye(4)
    known[:3, :3] = Rotation.from_euler("zyx", [3.0, 0.5, -0.4], degrees=True).as_matrix()
    known[:3, 3] = [1.0, -0.5, 0.3]
    estimated = transform_poses(np.linalg.inv(known), truth)
    assert pose_alignment(estimated, truth) == pytest.approx(known, abs=1e-9)


def test_pose_alignment_recovers_a_known_similarity_of_another_scale():
    angles = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    centres = np.column_stack([30 * np.cos(angles), 30 * np.sin(angles), np.full(8, 30.0)])
    truth = pose_matrix(centres, Rotation.random(8, random_state=2).as_quat(scalar_first=True))
    known = np.eye(4)
    known[:3, :3] = 1.25 * Rotation.from_euler("zyx", [30.0, 1.0, -2.0], degrees=True).as_matrix()
    known[:3, 3] = [-3.0, 6.0, 1.5]
    estimated = transform_poses(np.linalg.inv(known), truth)
    estimated[:, :3, :3] *= 1.25  # rigid camera axes in the estimate's frame
    assert pose_alignment(estimated, truth) == pytest.approx(known, abs=1e-9)
