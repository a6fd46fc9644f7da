"""The curved-turns path model against hand-computed geometry."""

import math

import numpy as np
import pytest

from flightplan import flown_path


def test_corner_is_the_tangent_arc():
    vertices = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    path = flown_path.curved_turns_path(vertices, np.array([0.2, 2.0, 0.2]), samples_per_turn=17)
    # Turn of 90 deg with curve 2 m: arc centre (8, 2), radius 2 m, from (8, 0) to (10, 2).
    arc = path[np.linalg.norm(path - [8.0, 2.0], axis=1) < 2.0 + 1e-9]
    np.testing.assert_allclose(np.linalg.norm(arc - [8.0, 2.0], axis=1), 2.0, atol=1e-9)
    for point in ([8.0, 0.0], [10.0, 2.0], [8.0 + math.sqrt(2.0), 2.0 - math.sqrt(2.0)], [0.0, 0.0], [10.0, 10.0]):
        assert np.linalg.norm(path - point, axis=1).min() < 1e-9
    arc_as_16_chords = 16 * 2 * 2.0 * math.sin(math.pi / 2 / 16 / 2)  # pi, less 0.1 % for the polyline
    assert flown_path.path_length_m(path) == pytest.approx(20.0 - 4.0 + arc_as_16_chords, abs=1e-9)


def test_heading_error_is_zero_when_the_heading_stays_on_the_centre():
    # Moving radially towards the centre keeps the bearing to it constant.
    vertices = np.array([[0.0, 50.0], [0.0, 30.0]])
    assert flown_path.heading_error_along_legs_deg(vertices, np.array([180.0, 180.0])) == pytest.approx(0.0, abs=1e-9)
    # A chord of a quarter circle: the true bearing swings non-linearly; its worst gap is a fraction of a degree.
    chord = np.array([[0.0, 50.0], [50.0, 0.0]])
    error = flown_path.heading_error_along_legs_deg(chord, np.array([180.0, 270.0]))
    assert 0.0 < error < 10.0


def test_max_radial_deviation():
    points = np.array([[3.0, 4.0], [0.0, 4.5]])
    assert flown_path.max_radial_deviation_m(points, 5.0) == pytest.approx(0.5)


def test_a_leg_of_no_length_is_passed_through_without_a_turn(recwarn):
    """Two waypoints on one spot (two rings of one radius and height meet there) have no direction between them:
    the path passes the vertex, with no division by the zero length (it once warned 'invalid value')."""
    vertices = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    path = flown_path.curved_turns_path(vertices, np.full(4, 2.0))
    assert np.isfinite(path).all()
    assert [10.0, 0.0] in path.tolist()
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
