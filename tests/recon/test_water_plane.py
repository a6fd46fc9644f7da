"""recon.surface.water on fused clouds of known shape: a round pond of radius 6 m whose level lies 0.3 m under a
textured lawn, its points scattered as stereo scatters them over water; and the plain flat things that are not water
(a car park level with its lawn, a flat roof, a plain road down a slope)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from recon.surface.grid import Grid
from recon.surface.provenance import SurfaceEvidence, face_codes
from recon.surface.water import (LEVEL_BAND_M, SNAP_BAND_M, WaterBody, find_water, flatten_onto, flatten_water,
                                 on_water, read_water, write_water)
from sim.render.provenance import PROXY
from sim.worlds.synthetic import grid_mesh

LEVEL_Z, RADIUS_M, CELL_M = -0.3, 6.0, 0.5
LAWN_LUMA_SIGMA, WATER_LUMA_SIGMA = 25.0, 2.0
WATER_SCATTER_M = 0.12


def lawn_points(rng: np.random.Generator, half_m: float = 15.0, per_m2: float = 30.0) -> np.ndarray:
    """Uniform (x, y) over the square of half-width ``half_m`` at ``per_m2`` points per m²."""
    return rng.uniform(-half_m, half_m, (int(per_m2 * (2 * half_m) ** 2), 2))


def cloud(rng: np.random.Generator, height, plain) -> tuple[np.ndarray, np.ndarray]:
    """Fused points over the lawn with ``height(xy)`` (ENU z) and, where ``plain(xy)``, a dark plain colour and the
    water's scatter; elsewhere a textured green."""
    xy = lawn_points(rng)
    is_plain = plain(xy)
    z = height(xy) + np.where(is_plain, rng.normal(0.0, WATER_SCATTER_M, len(xy)), rng.normal(0.0, 0.02, len(xy)))
    base = np.where(is_plain[:, None], [[34.0, 46.0, 54.0]], [[90.0, 120.0, 60.0]])
    sigma = np.where(is_plain, WATER_LUMA_SIGMA, LAWN_LUMA_SIGMA)
    colors = np.clip(base + rng.normal(0.0, 1.0, (len(xy), 1)) * sigma[:, None], 0, 255)
    return np.column_stack([xy, z]), colors


def in_pond(xy: np.ndarray, radius_m: float = RADIUS_M) -> np.ndarray:
    return np.hypot(xy[:, 0], xy[:, 1]) < radius_m


def pond_height(xy: np.ndarray, radius_m: float = RADIUS_M) -> np.ndarray:
    """The water at its level inside the shore; outside, banks rising 1:2 from 0.3 m above it to the lawn at 0."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    return np.where(r < radius_m, LEVEL_Z, np.minimum(0.0, LEVEL_Z + 0.3 + 0.5 * (r - radius_m)))


@pytest.mark.parametrize("radius_m, seed", [(RADIUS_M, 0), (RADIUS_M / 2, 1), (RADIUS_M / 2, 2), (10.0, 3)])
def test_a_pond_is_found_at_its_level_over_its_surface(radius_m, seed):
    points, colors = cloud(np.random.default_rng(seed), lambda xy: pond_height(xy, radius_m),
                           lambda xy: in_pond(xy, radius_m))
    [body] = find_water(points, colors, CELL_M)
    assert body.level_z == pytest.approx(LEVEL_Z, abs=0.03)
    assert in_pond(body.grid.centres()[body.cells.ravel()], radius_m + CELL_M).all()  # the shore's cells at most
    centres = body.grid.centres()
    inner = centres[in_pond(centres, radius_m - 0.5)]
    assert body.over(inner).all()  # all the open water, up to 0.5 m from the shore


def test_plain_flat_things_that_are_not_water_are_left_alone():
    """A plain car park level with the lawn, a plain flat roof 4 m up, a plain road falling 1 m in 10 m."""
    car_park = lambda xy: (np.abs(xy[:, 0] + 8) < 4) & (np.abs(xy[:, 1]) < 4)
    roof = lambda xy: (np.abs(xy[:, 0] - 8) < 4) & (np.abs(xy[:, 1] - 6) < 4)
    road = lambda xy: (np.abs(xy[:, 0] - 8) < 2) & (xy[:, 1] < -2) & (xy[:, 1] > -14)
    plain = lambda xy: car_park(xy) | roof(xy) | road(xy)
    height = lambda xy: np.where(roof(xy), 4.0, np.where(road(xy), 0.1 * xy[:, 1], 0.0))
    points, colors = cloud(np.random.default_rng(4), height, plain)
    assert find_water(points, colors, CELL_M) == []


def test_a_textured_hollow_is_not_water():
    points, colors = cloud(np.random.default_rng(5), pond_height, lambda xy: np.zeros(len(xy), bool))
    assert find_water(points, colors, CELL_M) == []


def square_body(level_z: float = LEVEL_Z) -> WaterBody:
    """A body over x, y in -2..2 m (cells of 1 m)."""
    return WaterBody(level_z, Grid(-2.0, 2.0, 1.0, 4, 4), np.ones((4, 4), bool))


def test_vertices_over_the_water_near_its_level_move_onto_it_and_nothing_else_does():
    vertices = np.array([[0.0, 0.0, LEVEL_Z + 0.2],  # the water's ripple
                         [1.0, 0.5, LEVEL_Z - SNAP_BAND_M + 0.01],
                         [0.5, 1.0, LEVEL_Z + 3.0],  # a crown over the water
                         [3.0, 0.0, LEVEL_Z + 0.2]])  # beyond the shore
    flat = flatten_onto(vertices, [square_body()])
    np.testing.assert_array_equal(flat[:, 2], [LEVEL_Z, LEVEL_Z, LEVEL_Z + 3.0, LEVEL_Z + 0.2])
    np.testing.assert_array_equal(flat[:, :2], vertices[:, :2])
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 1]])
    flat[3, 2] = LEVEL_Z
    # the first face has a corner on the crown, the second its centroid over the water but a corner beyond the
    # shore: on the plane all the same; the third lies wholly on it
    np.testing.assert_array_equal(on_water(flat, faces, [square_body()]), [False, True, True])
    assert not on_water(flat, faces, [square_body(LEVEL_Z + LEVEL_BAND_M)]).any()


def test_bodies_survive_their_file(tmp_path):
    body = square_body()
    body.cells[0, 0] = False
    write_water(tmp_path / "water.json", [body])
    [back] = read_water(tmp_path / "water.json")
    assert back.level_z == body.level_z and back.grid == body.grid
    np.testing.assert_array_equal(back.cells, body.cells)
    assert read_water(tmp_path / "none.json") == []


def test_the_mesh_over_a_pond_becomes_its_plane_and_says_so(tmp_path):
    """Through the files the mesh stage reads and writes: a 0.25 m grid mesh of the fused points' own heights (the
    water's scatter in it) is flattened at the level over the water, left as it was elsewhere, keeps its vertex
    colours; the face provenance marks the plane's faces proxy, and only those."""
    points, colors = cloud(np.random.default_rng(6), pond_height, in_pond)
    trimesh.PointCloud(points, colors=colors.astype(np.uint8)).export(tmp_path / "fused.ply")
    vertices, faces, _ = grid_mesh(100, 100, (-12.5, 12.5, -12.5, 12.5))
    nearest = cKDTree(points[:, :2]).query(vertices[:, :2])[1]
    vertices[:, 2] = points[nearest, 2]
    trimesh.Trimesh(vertices, faces, vertex_colors=np.full((len(vertices), 3), 77, np.uint8),
                    process=False).export(tmp_path / "mesh.ply")
    [body] = flatten_water(tmp_path / "mesh.ply", tmp_path / "fused.ply")
    flat = trimesh.load(tmp_path / "mesh.ply", process=False)
    np.testing.assert_array_equal(flat.visual.vertex_colors[:, :3], 77)
    z = np.asarray(flat.vertices)[:, 2]
    water = in_pond(vertices[:, :2], RADIUS_M - 0.5)
    assert np.allclose(z[water], body.level_z, rtol=0, atol=1e-5) and abs(body.level_z - LEVEL_Z) < 0.03  # float32
    lawn = ~in_pond(vertices[:, :2], RADIUS_M + 1.0)
    np.testing.assert_allclose(z[lawn], vertices[lawn, 2], rtol=0, atol=1e-5)
    codes = face_codes(flat.vertices, faces, SurfaceEvidence(points, 0.3, water=(body,)))
    centroids = vertices[faces].mean(axis=1)
    proxy = (codes & PROXY) > 0
    assert proxy[in_pond(centroids, RADIUS_M - 0.5)].all() and not proxy[~in_pond(centroids, RADIUS_M + 1.0)].any()
    assert not (face_codes(flat.vertices, faces, SurfaceEvidence(points, 0.3)) & PROXY).any()


def test_a_plain_hollow_at_the_edge_of_the_cloud_has_no_shore_to_judge_by():
    """The pond with the cloud cut 1 m east of its centre, as at the edge of what the photos cover: its west bank
    alone rises above it, and that is not enough."""
    points, colors = cloud(np.random.default_rng(7), pond_height, in_pond)
    keep = points[:, 0] < 1.0
    assert find_water(points[keep], colors[keep], CELL_M) == []
