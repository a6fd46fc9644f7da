"""The geometric path and its speed profile, in the home point's ENU frame (metres, m/s).

A path is a chain of pieces: straight lines and circular arcs. Litchi's "curved turns" are modelled as the
straight legs between waypoints with each interior corner replaced by a circular arc tangent to both legs,
starting ``curvesize`` metres before the waypoint and ending ``curvesize`` metres after it, so the flown path
stays inside the waypoints (Litchi itself uses a spline of about that size). Speeds are limited per piece
(leg speed, and on arcs by the lateral acceleration ``sqrt(a * R)``); the aircraft stops wherever the
direction jumps (sharp corners, the top of the climb) and accelerates/brakes at a constant rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Junctions whose tangent directions differ by more than this are sharp: the aircraft stops there.
SHARP_TURN_RAD = np.radians(1.0)
#: Corners turning by more than this get no arc (a reversal: stop and fly back).
MAX_ARC_TURN_RAD = np.radians(179.0)


@dataclass(frozen=True)
class Piece:
    """A line (``radius_m`` = inf) or an arc of the path.

    Position at local arc length ``s``: ``start + R (cos(s/R) - 1) inward_out + R sin(s/R) direction``, where
    ``inward_out`` is the unit vector from the arc centre to ``start``; for a line ``start + s direction``.
    ``leg`` is the index of the waypoint whose leg this piece belongs to (-1 before the mission, -2 after).
    """

    start: np.ndarray
    direction: np.ndarray
    outward: np.ndarray
    radius_m: float
    length_m: float
    speed_mps: float
    leg: int
    phase: str

    def end_tangent(self) -> np.ndarray:
        """Unit tangent at the end of the piece."""
        return _frame_at(self, np.array([self.length_m]))[1][0]


def line(start, end, speed_mps: float, leg: int, phase: str) -> Piece:
    """A straight piece from ``start`` to ``end`` (ENU metres)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.linalg.norm(end - start))
    direction = (end - start) / length if length > 0 else np.array([1.0, 0.0, 0.0])
    return Piece(start, direction, np.zeros(3), np.inf, length, speed_mps, leg, phase)


def _frame_at(piece: Piece, s: np.ndarray):
    """Positions, unit tangents and curvature vectors (1/m, towards the centre) at local arc lengths ``s``."""
    s = np.asarray(s, float)[:, None]
    if np.isinf(piece.radius_m):
        pos = piece.start + s * piece.direction
        tangent = np.broadcast_to(piece.direction, pos.shape)
        return pos, tangent, np.zeros_like(pos)
    r = piece.radius_m
    phi = s / r
    pos = piece.start + r * (np.cos(phi) - 1.0) * piece.outward + r * np.sin(phi) * piece.direction
    tangent = -np.sin(phi) * piece.outward + np.cos(phi) * piece.direction
    curvature = -(np.cos(phi) * piece.outward + np.sin(phi) * piece.direction) / r
    return pos, tangent, curvature


def split_arc(piece: Piece, at_m: float, legs: tuple[int, int], speeds: tuple[float, float]) -> tuple[Piece, Piece]:
    """Split an arc at local arc length ``at_m`` into two pieces with their own legs and speed limits."""
    pos, tangent, curvature = (a[0] for a in _frame_at(piece, np.array([at_m])))
    outward = -curvature * piece.radius_m
    first = Piece(piece.start, piece.direction, piece.outward, piece.radius_m, at_m, speeds[0], legs[0], piece.phase)
    second = Piece(pos, tangent, outward, piece.radius_m, piece.length_m - at_m, speeds[1], legs[1], piece.phase)
    return first, second


def corner_tangent_lengths(points: np.ndarray, curvesizes_m: np.ndarray) -> np.ndarray:
    """How far before/after each waypoint its curve starts/ends (m); 0 at the first and last waypoint.

    Where the requested curves of two neighbours do not fit on the leg between them, both shrink in
    proportion, so they meet but never overlap.
    """
    n = len(points)
    wanted = np.asarray(curvesizes_m, float).copy()
    wanted[[0, -1]] = 0.0
    legs = np.linalg.norm(np.diff(points, axis=0), axis=1)
    fits = np.ones(n)
    for i in range(n - 1):
        total = wanted[i] + wanted[i + 1]
        if total > legs[i]:
            share = legs[i] / total
            fits[i] = min(fits[i], share)
            fits[i + 1] = min(fits[i + 1], share)
    return wanted * fits


def corner_arc(before: np.ndarray, corner: np.ndarray, after: np.ndarray, tangent_m: float, phase: str) -> Piece | None:
    """The arc rounding ``corner`` (tangent to both legs, ``tangent_m`` from it), or None for no arc."""
    d_in = (corner - before) / np.linalg.norm(corner - before)
    d_out = (after - corner) / np.linalg.norm(after - corner)
    turn = float(np.arccos(np.clip(d_in @ d_out, -1.0, 1.0)))
    if tangent_m <= 0 or turn < 1e-9 or turn > MAX_ARC_TURN_RAD:
        return None
    radius = tangent_m / np.tan(turn / 2.0)
    inward = d_out - (d_out @ d_in) * d_in
    inward /= np.linalg.norm(inward)
    return Piece(corner - tangent_m * d_in, d_in, -inward, float(radius), radius * turn, np.inf, 0, phase)


@dataclass(frozen=True)
class SpeedProfile:
    """Arc length ``s_m``, speed ``v_mps`` and time ``t_s`` at the nodes of the path; constant acceleration between."""

    s_m: np.ndarray
    v_mps: np.ndarray
    t_s: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1])

    def at(self, t):
        """Arc length, speed and tangential acceleration at times ``t`` (s since the motion started)."""
        t = np.clip(np.asarray(t, float), 0.0, self.duration_s)
        i = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, len(self.t_s) - 2)
        dt = self.t_s[i + 1] - self.t_s[i]
        accel = np.where(dt > 0, (self.v_mps[i + 1] - self.v_mps[i]) / np.where(dt > 0, dt, 1.0), 0.0)
        tau = t - self.t_s[i]
        s = self.s_m[i] + self.v_mps[i] * tau + 0.5 * accel * tau**2
        return np.minimum(s, self.s_m[i + 1]), self.v_mps[i] + accel * tau, accel

    def time_at(self, s):
        """Time (s) at which arc length ``s`` is reached (inverse of :meth:`at`, exact for the node model)."""
        s = np.asarray(s, float)
        i = np.clip(np.searchsorted(self.s_m, s, side="right") - 1, 0, len(self.s_m) - 2)
        ds = np.clip(s - self.s_m[i], 0.0, None)
        v0, v1 = self.v_mps[i], self.v_mps[i + 1]
        fraction = ds / (self.s_m[i + 1] - self.s_m[i])
        v_here = np.sqrt(v0**2 + (v1**2 - v0**2) * fraction)
        return self.t_s[i] + 2.0 * ds / np.maximum(v0 + v_here, 1e-300)


def speed_profile(pieces: list[Piece], accel_mps2: float, node_spacing_m: float = 0.05) -> SpeedProfile:
    """The fastest profile that respects every piece's speed limit, ``accel_mps2`` and the stops.

    Limits: the piece's speed, ``sqrt(accel * R)`` on arcs, 0 at the ends and at sharp junctions.
    Between nodes v^2 changes linearly in s (constant acceleration), which makes the times exact.
    """
    s_parts, limit_parts, stop_nodes = [np.zeros(1)], [np.zeros(1)], [0]
    offset = 0.0
    for k, piece in enumerate(pieces):
        n = max(2, int(np.ceil(piece.length_m / node_spacing_m)) + 1)
        local = np.linspace(0.0, piece.length_m, n)[1:]
        limit = min(piece.speed_mps, np.sqrt(accel_mps2 * piece.radius_m))
        s_parts.append(offset + local)
        if k:  # the node shared with the previous piece obeys both limits
            limit_parts[-1][-1] = min(limit_parts[-1][-1], limit)
        limit_parts.append(np.full(n - 1, limit))
        offset += piece.length_m
        if k + 1 < len(pieces):
            turn = np.arccos(np.clip(piece.end_tangent() @ pieces[k + 1].direction, -1.0, 1.0))
            if turn > SHARP_TURN_RAD:
                stop_nodes.append(sum(len(p) for p in s_parts) - 1)
    s = np.concatenate(s_parts)
    limit = np.concatenate(limit_parts)
    limit[stop_nodes] = 0.0
    limit[-1] = 0.0
    v = _accel_limited(s, limit, accel_mps2)
    dt = 2.0 * np.diff(s) / np.maximum(v[:-1] + v[1:], 1e-300)
    return SpeedProfile(s, v, np.concatenate([[0.0], np.cumsum(dt)]))


def _accel_limited(s: np.ndarray, limit: np.ndarray, accel: float) -> np.ndarray:
    """Forward (accelerate) and backward (brake) passes: v[i] <= limit[i], |d(v^2)/ds| <= 2 accel."""
    v = limit.copy()
    two_a_ds = 2.0 * accel * np.diff(s)
    for i in range(len(v) - 1):
        v[i + 1] = min(v[i + 1], np.sqrt(v[i] ** 2 + two_a_ds[i]))
    for i in range(len(v) - 2, -1, -1):
        v[i] = min(v[i], np.sqrt(v[i + 1] ** 2 + two_a_ds[i]))
    return v


def evaluate(pieces: list[Piece], s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions (N,3), unit tangents (N,3), curvature vectors (N,3) and piece indices at path arc lengths ``s``."""
    s = np.atleast_1d(np.asarray(s, float))
    starts = np.concatenate([[0.0], np.cumsum([p.length_m for p in pieces])])
    index = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(pieces) - 1)
    pos, tangent, curvature = (np.empty((len(s), 3)) for _ in range(3))
    for k in np.unique(index):
        mask = index == k
        local = np.clip(s[mask] - starts[k], 0.0, pieces[k].length_m)
        pos[mask], tangent[mask], curvature[mask] = _frame_at(pieces[k], local)
    return pos, tangent, curvature, index
