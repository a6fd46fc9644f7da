"""Similarity transforms between point sets (Umeyama 1991, closed form via SVD).

A similarity maps ``x -> scale * R @ x + t``. Points are ``(N, 3)`` float64 arrays in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Similarity:
    """``x -> scale * rotation @ x + translation`` (rotation 3x3 proper, scale > 0)."""

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform ``(N, 3)`` points."""
        return self.scale * np.asarray(points, dtype=np.float64) @ self.rotation.T + self.translation

    def matrix(self) -> np.ndarray:
        """4x4 homogeneous matrix."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.translation
        return m

    def rotation_angle_deg(self) -> float:
        """Angle of the rotation part in degrees."""
        cos = np.clip((np.trace(self.rotation) - 1.0) / 2.0, -1.0, 1.0)
        return float(np.degrees(np.arccos(cos)))


def umeyama(source: np.ndarray, target: np.ndarray, with_scale: bool = True, weights=None) -> Similarity:
    """Least-squares similarity taking ``source`` onto ``target`` (both ``(N, d)``, N >= d), each pair weighted
    by ``weights`` (``(N,)``, e.g. 1 / sigma^2 of the target; None: all equal).

    Closed form of Umeyama (1991) on weighted means and cross-covariance: SVD, with the reflection fix.
    Works in any dimension d (2 for horizontal fits, 3 in general). Raises ``ValueError`` for
    mismatched shapes, too few points or degenerate (collinear / coincident) configurations.
    """
    src = np.asarray(source, dtype=np.float64)
    dst = np.asarray(target, dtype=np.float64)
    if src.ndim != 2 or src.shape != dst.shape:
        raise ValueError(f"need two (N, d) point arrays of equal shape, got {src.shape} and {dst.shape}")
    n, dim = src.shape
    if n < dim:
        raise ValueError(f"need at least {dim} point pairs for a {dim}-D similarity, got {n}")
    w = np.full(n, 1.0 / n) if weights is None else np.asarray(weights, dtype=np.float64) / np.sum(weights)
    if w.shape != (n,) or not np.all(np.isfinite(w) & (w >= 0)):
        raise ValueError(f"need {n} finite non-negative weights with a positive sum")
    mu_src, mu_dst = w @ src, w @ dst
    src_c, dst_c = src - mu_src, dst - mu_dst
    var_src = float(w @ np.sum(src_c**2, axis=1))
    if var_src <= 1e-18:
        raise ValueError("source points are all at one place: the similarity is undetermined")
    covariance = (dst_c * w[:, None]).T @ src_c
    u, singular, vt = np.linalg.svd(covariance)
    if singular[dim - 2] <= 1e-12 * max(singular[0], 1e-300):
        raise ValueError("points are collinear: the rotation about their line is undetermined")
    sign = np.eye(dim)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[-1, -1] = -1.0
    rotation = u @ sign @ vt
    scale = float(np.trace(np.diag(singular) @ sign) / var_src) if with_scale else 1.0
    translation = mu_dst - scale * rotation @ mu_src
    return Similarity(scale, rotation, translation)


def residuals(sim: Similarity, source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Per-pair distances ``|sim(source_i) - target_i|`` in metres."""
    return np.linalg.norm(sim.apply(source) - np.asarray(target, dtype=np.float64), axis=1)
