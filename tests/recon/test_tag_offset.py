"""The tags' along-track offset: recovered on lines flown both ways, refused where the similarity absorbs it."""

from __future__ import annotations

import numpy as np
import pytest

from recon.inputs.similarity import Similarity
from recon.inputs.tag_offset import MAX_OFFSET_SIGMA_M, fit_tag_offset, offset_sigma_m, travel_directions

RTK_SIGMA = np.array([0.02, 0.02, 0.03])
GPS_SIGMA = np.array([3.0, 3.0, 5.0])
#: An arbitrary SfM frame: the model is the true camera path in this similarity's inverse.
TO_ENU = Similarity(2.5, np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.array([5.0, 6.0, 7.0]))


def lawnmower(lines: int = 4, per_line: int = 8, spacing_m: float = 3.0) -> np.ndarray:
    """Camera positions (ENU m) on east-west lines 10 m apart, flown alternately east and west, 30 m up."""
    rows = []
    for line in range(lines):
        xs = np.arange(per_line) * spacing_m
        rows += [[x, 10.0 * line, 30.0] for x in (xs[::-1] if line % 2 else xs)]
    return np.array(rows)


def sfm_centres(truth: np.ndarray) -> np.ndarray:
    return ((truth - TO_ENU.translation) @ TO_ENU.rotation) / TO_ENU.scale


def test_directions_follow_the_lines_and_vanish_when_hovering():
    truth = lawnmower()
    sigma = np.tile(RTK_SIGMA, (len(truth), 1))
    directions = travel_directions(truth, sigma)
    assert directions[1] == pytest.approx([1, 0, 0]) and directions[9] == pytest.approx([-1, 0, 0])
    hovering = np.zeros((5, 3)) + np.array([0.0, 0.0, 30.0])
    assert np.all(travel_directions(hovering, np.tile(RTK_SIGMA, (5, 1))) == 0)


def test_offset_is_recovered_on_lines_flown_both_ways():
    truth = lawnmower()
    sigma = np.tile(RTK_SIGMA, (len(truth), 1))
    noise = np.random.default_rng(0).normal(0.0, 0.01, truth.shape)
    tags = truth + 0.07 * travel_directions(truth, sigma) + noise
    similarity, offset = fit_tag_offset(sfm_centres(truth), tags, sigma)
    assert offset.applied and offset.sigma_m <= MAX_OFFSET_SIGMA_M
    assert offset.offset_m == pytest.approx(0.07, abs=3 * offset.sigma_m)
    assert np.sqrt(np.mean((similarity.apply(sfm_centres(truth)) - truth) ** 2)) < 0.01


@pytest.mark.parametrize("path, sigma, why", [
    (np.c_[np.arange(20) * 3.0, np.sin(np.arange(20)), np.full(20, 30.0)], RTK_SIGMA,
     "one way along a wavy line: mostly a translation"),
    (np.c_[50 * np.cos(np.linspace(0, 2 * np.pi, 60, endpoint=False)),
           50 * np.sin(np.linspace(0, 2 * np.pi, 60, endpoint=False)), np.full(60, 30.0)], RTK_SIGMA,
     "a circle: a rotation about its centre"),
    (lawnmower(), GPS_SIGMA, "consumer GPS: metres of noise hide centimetres"),
])
def test_offset_is_left_alone_where_it_is_not_observable(path, sigma, why):
    sigmas = np.tile(sigma, (len(path), 1))
    assert offset_sigma_m(path, travel_directions(path, sigmas), sigmas) > MAX_OFFSET_SIGMA_M, why
    tags = path + 0.07 * travel_directions(path, sigmas)
    _, offset = fit_tag_offset(sfm_centres(path), tags, sigmas)
    assert not offset.applied and offset.summary()["along_track_offset_m"] is None
