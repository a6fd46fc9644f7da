"""Standing objects the 3-D surface smoothed away come back from the fused points' height field
(recon.surface.standing), on a flat surface with a known object: a 3 m block the points hold and Poisson lost."""

import numpy as np
import trimesh

from recon.surface.mesh import HeightField, scene_from_mesh
from recon.surface.standing import MIN_RISE_M, highest_around, lost_cells, with_standing_objects
from tests.recon.test_mesh_pieces import GROUND_POINTS_PER_M2, ground, on_surface

CELL_M = 0.25
BLOCK_HEIGHT_M = 3.0


def block_points(centre_xy, side_m: float, height_m: float, per_m2: float, seed: int) -> np.ndarray:
    """Points on the top of a ``side_m`` square block ``height_m`` tall at ``centre_xy`` (what stereo sees from
    above), ``per_m2`` per m²."""
    rng = np.random.default_rng(seed)
    count = int(per_m2 * side_m * side_m)
    xy = np.asarray(centre_xy) + rng.uniform(-side_m / 2, side_m / 2, (count, 2))
    return np.column_stack([xy, np.full(count, height_m)])


def heights_over(mesh: trimesh.Trimesh, xy) -> np.ndarray:
    xy = np.asarray(xy, dtype=float)
    return scene_from_mesh(mesh).ground_height(xy[:, 0], xy[:, 1])


def test_a_block_the_points_hold_comes_back_at_its_height_and_the_ground_stays():
    surface = ground(20.0)  # Poisson smoothed the block into the ground
    points = np.concatenate([on_surface(surface, GROUND_POINTS_PER_M2, 1),
                             block_points((3.0, -2.0), 2.0, BLOCK_HEIGHT_M, 200.0, 2)])
    restored, cells = with_standing_objects(surface, points, None, CELL_M)
    # the block's 2 m x 2 m top is 64 cells (the 75th percentile's edge cells and the median filter may trim a row)
    assert 48 <= cells <= 72
    assert np.array_equal(restored.faces[:len(surface.faces)], surface.faces)  # the 3-D surface is kept, first
    on_top = heights_over(restored, [[3.0, -2.0], [3.6, -1.4], [2.4, -2.6]])
    np.testing.assert_allclose(on_top, BLOCK_HEIGHT_M, atol=0.01)
    assert np.allclose(heights_over(restored, [[-5.0, 5.0], [6.0, 6.0], [3.0, 2.0]]), 0.0, atol=1e-6)


def test_nothing_comes_back_below_the_rise_or_from_a_few_stray_points():
    surface = ground(20.0)
    flat = np.concatenate([on_surface(surface, GROUND_POINTS_PER_M2, 1),
                           block_points((3.0, -2.0), 2.0, 0.8 * MIN_RISE_M, 200.0, 2),  # a low object: a hedge, a car
                           block_points((-4.1, 4.1), 0.2 * CELL_M, 5.0, 400.0, 3)])  # 16 points, < MIN_CELLS cells
    restored, cells = with_standing_objects(surface, flat, None, CELL_M)
    assert cells == 0 and restored is surface


def test_an_object_the_surface_already_holds_is_not_doubled():
    base = ground(20.0)
    box = trimesh.creation.box((2.0, 2.0, BLOCK_HEIGHT_M)).apply_translation((3.0, -2.0, BLOCK_HEIGHT_M / 2))
    surface = trimesh.util.concatenate([base, box])
    points = np.concatenate([on_surface(base, GROUND_POINTS_PER_M2, 1),
                             block_points((3.0, -2.0), 2.0, BLOCK_HEIGHT_M, 200.0, 2)])
    restored, cells = with_standing_objects(surface, points, None, CELL_M)
    assert cells == 0 and restored is surface


def test_an_edge_the_surface_draws_inside_a_cell_is_not_lost():
    """A roof 3 m up over columns 5-9: the height field's 75th percentile takes column 4, which straddles the wall, for
    roof; the 3-D surface's height at that cell's centre is the ground's, one column away the roof's."""
    field_z = np.zeros((10, 14))
    field_z[:, 4:10] = 3.0
    surface_z = np.zeros((10, 14))
    surface_z[:, 5:10] = 3.0
    field = HeightField(field_z, np.zeros((10, 14, 3), np.uint8), 0.0, 0.0, CELL_M)
    observed = np.ones((10, 14), bool)
    assert lost_cells(field, observed, surface_z)[:, 4].all()  # against the centres alone: an edge lost
    assert not lost_cells(field, observed, highest_around(surface_z)).any()
    np.testing.assert_array_equal(highest_around(np.full((3, 3), np.nan)), np.full((3, 3), np.nan))
