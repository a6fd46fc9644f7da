"""A model of the path Litchi really flies through a list of waypoints, in a horizontal plane.

Coordinates are ``(east, north)`` metres in a local ENU frame (``geodesy.LocalFrame``); heights are ignored.

Model ("curved turns", Litchi's classic path mode, research/litchi.md section 2): the aircraft does **not** pass
through interior waypoints. It flies straight along each leg and rounds every interior waypoint with a turn that
leaves the incoming leg ``curve_size`` metres before the waypoint and joins the outgoing leg ``curve_size`` metres
after it. Litchi builds that turn with a spline; we model it as the circular arc tangent to both legs at those
two points (radius ``curve_size / tan(turn / 2)``), which has the same end points and end tangents. The first and
last waypoints are passed exactly. On an orbit whose waypoints lie on a circle of radius ``R``, with ``N`` equal
legs and curves shorter than half a leg, the path is inside the circle everywhere; it is furthest from it at
the middle of each straight piece, by the sagitta ``R (1 - cos(pi / N))``. In Litchi's "straight lines" mode
the path is the polygon itself and the deviation is the same sagitta.

Between waypoints Litchi interpolates the heading linearly (research/litchi.md section 2, [LUwhy]), so the nose
points slightly off the centre except at waypoints and at mid-leg: :func:`heading_error_along_legs_deg`.
"""

from __future__ import annotations

import numpy as np


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _corner_arc(previous: np.ndarray, vertex: np.ndarray, following: np.ndarray, curve_m: float, samples: int):
    """Points of the circular turn at ``vertex``, from the incoming tangent point to the outgoing one (just the
    vertex where a leg has no length: there is no turn to round)."""
    if not (np.any(vertex != previous) and np.any(following != vertex)):
        return vertex[None, :]
    u_in, u_out = _unit(vertex - previous), _unit(following - vertex)
    turn = np.arctan2(u_in[0] * u_out[1] - u_in[1] * u_out[0], u_in @ u_out)  # signed, counter-clockwise > 0
    curve_m = min(curve_m, 0.5 * np.linalg.norm(vertex - previous), 0.5 * np.linalg.norm(following - vertex))
    if abs(turn) < 1e-12 or curve_m <= 0.0:
        return vertex[None, :]
    entry = vertex - curve_m * u_in
    radius = curve_m / np.tan(abs(turn) / 2.0)
    left_normal = np.array([-u_in[1], u_in[0]])
    centre = entry + np.sign(turn) * radius * left_normal
    start = np.arctan2(*(entry - centre)[::-1])
    angles = start + np.linspace(0.0, turn, samples)
    return centre + radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)


def curved_turns_path(vertices_en: np.ndarray, curve_sizes_m: np.ndarray, samples_per_turn: int = 16) -> np.ndarray:
    """The flown path through ``vertices_en`` ``(M, 2)`` as a dense ``(K, 2)`` polyline (east, north metres).

    ``curve_sizes_m`` ``(M,)`` is each waypoint's curve size; those of the first and last waypoint are ignored
    (Litchi flies through them). The middle of every straight piece is included, so the polyline contains the
    points of an orbit's path that are furthest from the circle.
    """
    vertices_en = np.asarray(vertices_en, dtype=np.float64)
    pieces = [vertices_en[:1]]
    for i in range(1, len(vertices_en) - 1):
        pieces.append(_corner_arc(vertices_en[i - 1], vertices_en[i], vertices_en[i + 1], curve_sizes_m[i], samples_per_turn))
    pieces.append(vertices_en[-1:])
    with_midpoints = [pieces[0]]
    for piece in pieces[1:]:
        straight_middle = 0.5 * (with_midpoints[-1][-1] + piece[0])
        with_midpoints += [straight_middle[None, :], piece]
    return np.concatenate(with_midpoints)


def path_length_m(points: np.ndarray) -> float:
    """Length of a polyline ``(K, D)`` in metres."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def max_radial_deviation_m(points_en: np.ndarray, radius_m: float, centre_en=(0.0, 0.0)) -> float:
    """Largest ``| |p - centre| - radius |`` over the polyline's points (metres)."""
    distances = np.linalg.norm(np.asarray(points_en) - np.asarray(centre_en), axis=1)
    return float(np.abs(distances - radius_m).max())


def heading_error_along_legs_deg(
    vertices_en: np.ndarray, headings_deg: np.ndarray, centre_en=(0.0, 0.0), samples_per_leg: int = 65
) -> float:
    """Largest angle (degrees) between the linearly interpolated heading and the true bearing to ``centre_en``.

    Evaluated along the straight legs between consecutive waypoints; headings are interpolated the short way
    round, as the aircraft turns.
    """
    t = np.linspace(0.0, 1.0, samples_per_leg)[None, :, None]
    start, end = np.asarray(vertices_en)[:-1, None, :], np.asarray(vertices_en)[1:, None, :]
    points = start + t * (end - start)
    to_centre = np.asarray(centre_en) - points
    true_heading = np.degrees(np.arctan2(to_centre[..., 0], to_centre[..., 1]))
    h0, h1 = np.asarray(headings_deg)[:-1, None], np.asarray(headings_deg)[1:, None]
    step = (h1 - h0 + 180.0) % 360.0 - 180.0
    interpolated = h0 + t[..., 0] * step
    error = (interpolated - true_heading + 180.0) % 360.0 - 180.0
    return float(np.abs(error).max())
