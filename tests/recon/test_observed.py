"""The observed area (recon/surface/observed.py) against analytic shapes: a circle of cameras and a grid of points."""

import math

import numpy as np
import pytest

from recon.surface.observed import inside, observed_area, viewed_area


def test_a_circle_of_cameras_observes_its_disc():
    radius, count = 50.0, 36
    angles = np.linspace(0.0, 2 * math.pi, count, endpoint=False)
    centres = np.column_stack([radius * np.cos(angles) + 7.0, radius * np.sin(angles) - 3.0, np.full(count, 30.0)])
    polygon = observed_area(centres)
    assert polygon.shape == (count, 2)
    signed_area = 0.5 * np.sum(polygon[:, 0] * np.roll(polygon[:, 1], -1) - np.roll(polygon[:, 0], -1) * polygon[:, 1])
    assert signed_area == pytest.approx(0.5 * count * radius**2 * math.sin(2 * math.pi / count))  # counter-clockwise

    grid = np.stack(np.meshgrid(np.linspace(-80, 80, 161), np.linspace(-80, 80, 161)), axis=-1) + [7.0, -3.0]
    distance = np.hypot(grid[..., 0] - 7.0, grid[..., 1] + 3.0)
    mask = inside(polygon, grid)
    assert mask.shape == grid.shape[:2]
    inner_radius = radius * math.cos(math.pi / count)  # the polygon's inscribed circle
    assert mask[distance < inner_radius - 1e-6].all()
    assert not mask[distance > radius + 1e-6].any()
    # the 36-gon's area against the count of 1 m cells inside it
    assert mask.sum() == pytest.approx(signed_area, rel=0.01)


def test_inside_a_square_on_a_grid_with_heights():
    square = observed_area(np.array([[0, 0], [10, 0], [10, 4], [0, 4], [5, 2], [3, 1]], float))
    assert len(square) == 4  # inner cameras are not hull vertices
    points = np.array([[[1.0, 1.0, 99.0], [9.5, 3.5, -5.0]], [[10.5, 2.0, 0.0], [5.0, -0.1, 0.0]]])
    np.testing.assert_array_equal(inside(square, points), [[True, True], [False, False]])


@pytest.mark.parametrize("centres", [np.zeros((2, 3)), np.array([[0, 0], [1, 1], [2, 2], [3, 3]], float)])
def test_cameras_on_a_line_observe_no_area(centres):
    with pytest.raises(ValueError, match="span no area"):
        observed_area(centres)


def test_a_short_arc_looking_at_the_centre_views_the_centre():
    """Three cameras on a 50 m circle, 30 m up, looking at its centre on the ground: the cameras alone span a
    sliver at the rim; with their optical axes' ground points the area reaches the centre (and no further)."""
    from sim.render.camera import look_at

    angles = np.radians([0.0, 10.0, 20.0])
    poses = np.array([look_at((50.0 * math.cos(a), 50.0 * math.sin(a), 30.0), (0.0, 0.0, 0.0)) for a in angles])
    assert not inside(observed_area(poses[:, :3, 3]), np.array([[1.0, 1.0]]))[0]
    area = viewed_area(poses, ground_z=0.0)
    assert inside(area, np.array([[25.0, 4.0], [0.5, 0.05]])).all()
    assert np.abs(area).max() <= 50.0 + 1e-9 and area[:, 0].min() == pytest.approx(0.0, abs=1e-9)
    # a camera looking above the horizon adds its own position only (its axis never meets the ground)
    looking_up = look_at((0.0, -40.0, 30.0), (0.0, 0.0, 60.0))
    with_it = viewed_area(np.concatenate([poses, looking_up[None]]), ground_z=0.0)
    assert with_it[:, 1].min() == pytest.approx(-40.0)
