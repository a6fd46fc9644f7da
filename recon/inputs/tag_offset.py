"""The along-track offset of a flight's position tags: one number per flight, estimated where it is observable.

A receiver's position epoch and the shutter rarely coincide: a tag recorded a little before or after the exposure
sits ahead of or behind the camera along the direction of travel, by speed x delay. On p4m_rtk (RTK fixed,
~0.9 m/s) the SfM cameras sit 7 cm behind their tags on every line, whichever way it is flown (docs/recon.md).
A constant offset along the track is the tag's error, not the block's, so geo-registration should fit it:
targets ``p_i - offset * u_i`` with ``u_i`` the unit direction of travel at photo i (ENU, from its neighbours).

The offset is only observable when the directions of travel vary in a way the similarity cannot absorb: on
back-and-forth lines it is, along a straight line it is a translation, and on a circle it is a rotation about the
centre. :func:`fit_tag_offset` therefore computes its standard deviation from the linearised fit (rotation,
translation, scale and offset together, each photo weighted by its prior sigmas) and applies the offset only when
that is below :data:`MAX_OFFSET_SIGMA_M` — in practice RTK tags on lines flown both ways.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from recon.inputs.similarity import Similarity, umeyama

#: Fit the offset only when its standard deviation (1 sigma, from the priors' sigmas) is at most this.
MAX_OFFSET_SIGMA_M = 0.01
#: A photo whose neighbours are closer together than this many horizontal sigmas has no direction of travel.
MIN_STEP_SIGMAS = 3.0
ITERATIONS = 50
TOLERANCE_M = 1e-6


@dataclass(frozen=True)
class TagOffset:
    """The fitted offset (metres; positive: the tags lead the cameras) and its 1-sigma, or why none was fitted."""

    offset_m: float
    sigma_m: float
    applied: bool

    def summary(self) -> dict:
        return {"along_track_offset_m": round(self.offset_m, 4) if self.applied else None,
                "along_track_sigma_m": round(self.sigma_m, 4) if np.isfinite(self.sigma_m) else None,
                "applied": self.applied}


def travel_directions(positions_enu: np.ndarray, sigma_m: np.ndarray) -> np.ndarray:
    """(N, 3) unit directions of travel from each photo's neighbours in photo order (central differences, one-sided
    at the ends); zero where the neighbours are closer than :data:`MIN_STEP_SIGMAS` horizontal sigmas (hovering)."""
    positions = np.asarray(positions_enu, dtype=np.float64)
    if len(positions) < 2:
        return np.zeros_like(positions)
    ahead = np.vstack([positions[1:], positions[-1:]])
    behind = np.vstack([positions[:1], positions[:-1]])
    steps = ahead - behind
    lengths = np.linalg.norm(steps, axis=1)
    moving = lengths > MIN_STEP_SIGMAS * np.linalg.norm(sigma_m[:, :2], axis=1)
    directions = np.zeros_like(steps)
    directions[moving] = steps[moving] / lengths[moving, None]
    return directions


def offset_sigma_m(model_points: np.ndarray, directions: np.ndarray, sigma_m: np.ndarray) -> float:
    """1-sigma of the offset in the linearised joint fit of rotation (3), translation (3), log-scale (1) and offset
    (1) to targets with per-axis sigmas ``sigma_m`` (N, 3); ``inf`` when the offset is not separable."""
    centred = model_points - model_points.mean(axis=0)
    normal = np.zeros((8, 8))
    for point, direction, sigma in zip(centred, directions, sigma_m):
        jacobian = np.zeros((3, 8))
        jacobian[:, :3] = -_skew(point)  # d(R x)/d(omega) at omega = 0
        jacobian[:, 3:6] = np.eye(3)
        jacobian[:, 6] = point
        jacobian[:, 7] = direction
        normal += jacobian.T @ np.diag(1.0 / np.square(sigma)) @ jacobian
    if np.linalg.cond(normal) > 1e12:
        return float("inf")
    return float(np.sqrt(np.linalg.inv(normal)[7, 7]))


def fit_tag_offset(centres: np.ndarray, targets: np.ndarray, sigma_m: np.ndarray) -> tuple[Similarity, TagOffset]:
    """Similarity taking ``centres`` (SfM) to ``targets - offset * u`` and the along-track ``offset``, by alternating
    a weighted Umeyama fit with the offset's weighted least squares (translation re-solved with it).

    ``targets``: (N, 3) tag positions in photo order, ENU metres; ``sigma_m``: (N, 3) their sigmas. The offset is
    applied only when :func:`offset_sigma_m` is at most :data:`MAX_OFFSET_SIGMA_M`; otherwise the plain weighted
    fit is returned with ``applied`` False.
    """
    weights = 1.0 / np.mean(np.square(sigma_m), axis=1)
    directions = travel_directions(targets, sigma_m)
    similarity = umeyama(centres, targets, weights=weights)
    sigma = offset_sigma_m(similarity.apply(centres), directions, sigma_m)
    if not sigma <= MAX_OFFSET_SIGMA_M:
        return similarity, TagOffset(0.0, sigma, applied=False)
    offset = 0.0
    w = weights / weights.sum()
    centred_directions = directions - w @ directions
    for _ in range(ITERATIONS):
        residual = targets - similarity.apply(centres)
        residual -= w @ residual
        new_offset = float(np.sum(w * np.sum(centred_directions * residual, axis=1))
                           / np.sum(w * np.sum(centred_directions**2, axis=1)))
        similarity = umeyama(centres, targets - new_offset * directions, weights=weights)
        converged = abs(new_offset - offset) < TOLERANCE_M
        offset = new_offset
        if converged:
            break
    return similarity, TagOffset(offset, sigma, applied=True)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
