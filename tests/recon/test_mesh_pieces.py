"""The 3-D surface keeps the pieces its points measure (a tree crown Poisson cut off its trunk) and drops the ones they
do not (skins, stray blobs): recon.surface.mesh.measured_pieces and surface_3d, on scenes with known pieces."""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from recon.surface.mesh import MIN_PIECE_EQUIVALENT_M2, measured_pieces, surface_3d

GROUND_POINTS_PER_M2 = 25.0
CELL_M = 0.25


def on_surface(mesh: trimesh.Trimesh, per_m2: float, seed: int) -> np.ndarray:
    """Points (N, 3) spread at random over ``mesh``, ``per_m2`` of them per m² on average."""
    points, _ = trimesh.sample.sample_surface(mesh, int(per_m2 * mesh.area), seed=seed)
    return np.asarray(points)


def ground(side_m: float) -> trimesh.Trimesh:
    """A flat square of ``side_m`` at z = 0, finely triangulated (like Poisson's ground)."""
    half = side_m / 2
    corners = [[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]]
    return trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]]).subdivide_to_size(0.5)


def crown(radius_m: float, centre) -> trimesh.Trimesh:
    """A closed crown: a sphere floating at ``centre`` (ENU metres)."""
    return trimesh.creation.icosphere(subdivisions=3, radius=radius_m).apply_translation(centre)


def kept_near(mesh: trimesh.Trimesh, centre, radius_m: float) -> int:
    """How many faces of ``mesh`` have their centroid within ``radius_m`` of ``centre``."""
    return int((np.linalg.norm(mesh.triangles_center - np.asarray(centre), axis=1) < radius_m).sum())


def test_a_crown_its_points_measure_stays_and_a_skin_without_points_goes():
    base, tree, skin = ground(30.0), crown(1.5, (5.0, 5.0, 6.0)), crown(1.0, (-8.0, -8.0, -3.0))
    points = np.concatenate([on_surface(base, GROUND_POINTS_PER_M2, 1), on_surface(tree, 100.0, 2),
                             on_surface(skin, 0.5, 3)])
    surface = measured_pieces(trimesh.util.concatenate([base, tree, skin]), points, CELL_M)
    assert kept_near(surface, (5.0, 5.0, 6.0), 2.0) == len(tree.faces)
    assert kept_near(surface, (-8.0, -8.0, -3.0), 1.5) == 0
    assert len(surface.faces) == len(base.faces) + len(tree.faces)


def test_a_piece_holds_too_few_points_below_the_grounds_density_or_count():
    base = ground(30.0)
    sparse_crown = crown(1.5, (5.0, 5.0, 6.0))  # 28 m2 measured at a fifth of the ground's density
    tiny_blob = crown(0.25, (-5.0, 5.0, 4.0))  # dense, but fewer points than 4 m2 of ground holds
    points = np.concatenate([on_surface(base, GROUND_POINTS_PER_M2, 1), on_surface(sparse_crown, 5.0, 2),
                             on_surface(tiny_blob, 100.0, 3)])
    assert len(on_surface(tiny_blob, 100.0, 3)) < MIN_PIECE_EQUIVALENT_M2 * GROUND_POINTS_PER_M2
    surface = measured_pieces(trimesh.util.concatenate([base, sparse_crown, tiny_blob]), points, CELL_M)
    assert len(surface.faces) == len(base.faces)


def test_points_farther_than_a_cell_do_not_measure_a_piece():
    centre = np.array([5.0, 5.0, 6.0])
    base, tree = ground(30.0), crown(1.5, centre)
    beside = centre + (on_surface(tree, 100.0, 2) - centre) * (1.5 + 2 * CELL_M) / 1.5  # half a metre outside it
    surface = measured_pieces(trimesh.util.concatenate([base, tree]),
                              np.concatenate([on_surface(base, GROUND_POINTS_PER_M2, 1), beside]), CELL_M)
    assert len(surface.faces) == len(base.faces)


def write_oriented_cloud(path: Path, points: np.ndarray, normals: np.ndarray) -> None:
    """A binary PLY point cloud with normals and colours, as pycolmap's fusion writes it."""
    record = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"),
                       ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    rows = np.zeros(len(points), record)
    for axis, name in enumerate("xyz"):
        rows[name], rows["n" + name] = points[:, axis], normals[:, axis]
    rows["red"] = rows["green"] = rows["blue"] = 128
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(rows)}\n"
              + "".join(f"property float {n}\n" for n in ("x", "y", "z", "nx", "ny", "nz"))
              + "".join(f"property uchar {c}\n" for c in ("red", "green", "blue")) + "end_header\n")
    path.write_bytes(header.encode() + rows.tobytes())


@pytest.mark.slow
def test_a_crown_above_a_wide_ground_survives_poisson_and_the_crop(tmp_path):
    """A 1 m crown 4 m above a 60 m square: less than 1 % of the surface's faces (the old floater rule dropped it),
    every point of it measured."""
    rng = np.random.default_rng(5)
    xy = rng.uniform(-30.0, 30.0, (int(60 * 60 * GROUND_POINTS_PER_M2), 2))
    directions = rng.normal(size=(4000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    centre = np.array([3.0, -2.0, 4.0])
    points = np.concatenate([np.column_stack([xy, np.zeros(len(xy))]), centre + 1.0 * directions])
    normals = np.concatenate([np.tile([0.0, 0.0, 1.0], (len(xy), 1)), directions])
    write_oriented_cloud(tmp_path / "fused.ply", points, normals)
    area = np.array([[-25.0, -25.0], [25.0, -25.0], [25.0, 25.0], [-25.0, 25.0]])

    surface = surface_3d(tmp_path / "fused.ply", tmp_path / "mesh.ply", area, 2.0, CELL_M, depth=8)

    near_crown = np.linalg.norm(surface.triangles_center - centre, axis=1) < 1.5
    assert near_crown.sum() < 0.01 * len(surface.faces)
    heights = surface.triangles_center[near_crown, 2]
    assert heights.max() == pytest.approx(centre[2] + 1.0, abs=0.15)  # the crown's top, not the ground under it
    assert heights.min() == pytest.approx(centre[2] - 1.0, abs=0.15)
    assert np.abs(surface.triangles_center[~near_crown, 2]).max() < 0.1  # nothing else floats: only ground
    assert trimesh.load(tmp_path / "mesh.ply").faces.shape == surface.faces.shape
