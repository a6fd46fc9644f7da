"""Geo-registration: the similarity that takes an SfM model into the priors' ENU frame (a weighted Umeyama fit to
the prior positions), and levelling with the geotag attitudes where the positions cannot level the block better."""

from __future__ import annotations

import numpy as np
import pycolmap

from recon.inputs.priors import PosePriors
from recon.inputs.similarity import Similarity, umeyama


def compose(outer: Similarity, inner: Similarity) -> Similarity:
    """The similarity ``x -> outer(inner(x))``."""
    return Similarity(
        outer.scale * inner.scale,
        outer.rotation @ inner.rotation,
        outer.scale * outer.rotation @ inner.translation + outer.translation,
    )


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector ``a`` onto unit vector ``b`` (Rodrigues)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    axis = np.cross(a, b)
    sin, cos = np.linalg.norm(axis), float(a @ b)
    if sin < 1e-15:
        if cos > 0:
            return np.eye(3)
        raise ValueError("vectors are opposite: the levelling rotation is ambiguous")
    k = axis / sin
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sin * skew + (1 - cos) * skew @ skew


def levelling_rotation(r_world_cam_sfm: np.ndarray, r_world_cam_attitude: np.ndarray) -> np.ndarray:
    """Rotation (3x3) that makes the model's "up" agree with the attitude-derived up.

    For each camera, world up expressed in the camera frame from the attitude, ``R_att^T e_z``, depends only
    on pitch and roll (not on the compass-derived yaw); mapped through the SfM rotation it is where the model
    thinks up is. The mean of those is rotated onto +z. Inputs are (N, 3, 3) ``R_world_cam``.
    """
    up_in_cam = np.einsum("nij,i->nj", r_world_cam_attitude, np.array([0.0, 0.0, 1.0]))
    model_up = np.einsum("nij,nj->ni", r_world_cam_sfm, up_in_cam).mean(axis=0)
    return rotation_between(model_up, np.array([0.0, 0.0, 1.0]))


def fit_level_similarity(centres: np.ndarray, targets: np.ndarray, sigma_m: np.ndarray) -> Similarity:
    """Similarity with rotation about z only (plus scale and translation) taking centres to targets.

    Used after levelling: horizontal Umeyama for yaw and scale (weights 1 / horizontal variance), then the
    vertical offset as the mean weighted by 1 / vertical variance. ``sigma_m``: (N, 3) target sigmas east/north/up.
    """
    horizontal = umeyama(centres[:, :2], targets[:, :2], weights=1.0 / np.mean(np.square(sigma_m[:, :2]), axis=1))
    rotation = np.eye(3)
    rotation[:2, :2] = horizontal.rotation
    scaled = horizontal.scale * centres @ rotation.T
    dz = float(np.average(targets[:, 2] - scaled[:, 2], weights=1.0 / np.square(sigma_m[:, 2])))
    return Similarity(horizontal.scale, rotation, np.array([*horizontal.translation, dz]))


#: Level the model with the attitudes only when the prior positions fix its tilt worse than this (1 sigma).
LEVEL_ABOVE_TILT_DEG = 0.1


def position_tilt_sigma_deg(priors: PosePriors) -> float:
    """How well the prior positions alone fix the block's tilt (degrees, 1 sigma): the vertical sigma over the
    photos' horizontal spread, as a weighted plane fit would: ``1 / sqrt(sum_i d_i^2 / sigma_up_i^2)`` with
    ``d_i`` the horizontal distance of photo i from the centroid."""
    horizontal = priors.positions_enu[:, :2] - priors.positions_enu[:, :2].mean(axis=0)
    information = np.sum(np.sum(horizontal**2, axis=1) / np.square(priors.sigma_m[:, 2]))
    return float(np.degrees(1.0 / np.sqrt(information))) if information > 0 else np.inf


def georegister(centres: np.ndarray, rotations: np.ndarray, priors: PosePriors) -> tuple[Similarity, float | None]:
    """Similarity taking SfM camera centres/rotations into the priors' ENU frame, and the tilt removed (deg).

    A 3-D Umeyama fit to the prior positions, each weighted by 1 / its mean variance (an RTK camera outweighs
    a GPS one ~10^4 times). When attitudes exist and the positions fix the tilt worse than
    :data:`LEVEL_ABOVE_TILT_DEG` (:func:`position_tilt_sigma_deg`: a consumer GPS, not RTK), the levelling
    rotation about the centroid follows, then a yaw/scale/translation-only refit to the positions.
    """
    first = umeyama(centres, priors.positions_enu, weights=1.0 / np.mean(np.square(priors.sigma_m), axis=1))
    if priors.rotations_world_cam is None or position_tilt_sigma_deg(priors) <= LEVEL_ABOVE_TILT_DEG:
        return first, None
    centres1 = first.apply(centres)
    rotations1 = np.einsum("ij,njk->nik", first.rotation, rotations)
    level = levelling_rotation(rotations1, priors.rotations_world_cam)
    centroid = centres1.mean(axis=0)
    about_centroid = Similarity(1.0, level, centroid - level @ centroid)
    refit = fit_level_similarity(about_centroid.apply(centres1), priors.positions_enu, priors.sigma_m)
    tilt = Similarity(1.0, level, np.zeros(3)).rotation_angle_deg()
    return compose(refit, compose(about_centroid, first)), tilt


def apply_similarity(rec: pycolmap.Reconstruction, sim: Similarity) -> None:
    """Transform the model in place (points and poses)."""
    rec.transform(pycolmap.Sim3d(sim.scale, pycolmap.Rotation3d(sim.rotation), sim.translation))
