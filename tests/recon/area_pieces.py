"""Synthetic pieces of one area for recon/area/align.py's tests and tools/bench/bench_area_align.py: a hilly terrain
(area ENU, metres) cut into squares, each moved by a known rigid error."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from sim.worlds.synthetic import grid_mesh

AREA = LocalFrame(50.85, -0.15, 40.0)
PIECE_M, CELL_M = 60.0, 1.0


def terrain_height(xy: np.ndarray) -> np.ndarray:
    """Hills on several scales, in both directions (so that a shift along the ground is observable), metres."""
    x, y = xy[:, 0], xy[:, 1]
    return (3.0 * np.sin(x / 9.0) * np.cos(y / 11.0) + 1.5 * np.sin((x + 2.0 * y) / 6.0)
            + 0.8 * np.cos((3.0 * x - y) / 5.0))


def frame_at(east_m: float, north_m: float, up_m: float) -> LocalFrame:
    """An ENU frame whose origin is at that point of the area's frame."""
    return LocalFrame(*(float(c) for c in AREA.to_geodetic(east_m, north_m, up_m)))


def rigid(rotvec_deg, shift_m, about) -> np.ndarray:
    """4x4 rotation by ``rotvec_deg`` about the point ``about``, then a shift (area ENU metres)."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    m[:3, 3] = np.asarray(about) + np.asarray(shift_m) - m[:3, :3] @ np.asarray(about)
    return m


def terrain_piece(x0: float, y0: float, error: np.ndarray, seed: int, noise_m: float = 0.0,
                  relief: float = 1.0, cell_m: float = CELL_M) -> trimesh.Trimesh:
    """A PIECE_M square of the terrain (heights times ``relief``; 0: flat) with its south-west corner at ``(x0, y0)``
    (area ENU), a grid of ``cell_m`` cells, heights with ``noise_m`` (1 sigma) of independent noise, moved by the
    rigid 4x4 ``error``; grey vertex colours."""
    cells = int(round(PIECE_M / cell_m))
    vertices, faces, _ = grid_mesh(cells, cells, (x0, x0 + PIECE_M, y0, y0 + PIECE_M))
    noise = noise_m * np.random.default_rng(seed).standard_normal(len(vertices))
    vertices[:, 2] = relief * terrain_height(vertices) + noise
    moved = vertices @ error[:3, :3].T + error[:3, 3]
    return trimesh.Trimesh(moved, faces, vertex_colors=np.full((len(moved), 4), 160, np.uint8), process=False)


def correction_error(correction: np.ndarray, error: np.ndarray, at: np.ndarray) -> tuple[float, float]:
    """How far ``correction`` is from undoing ``error``: displacement at ``at`` (mm) and rotation (millideg)."""
    residual = correction @ error
    shift = np.linalg.norm(residual[:3, :3] @ at + residual[:3, 3] - at)
    return 1e3 * shift, 1e3 * np.degrees(Rotation.from_matrix(residual[:3, :3]).magnitude())


def centre_of(i: int, step_m: float) -> np.ndarray:
    """Centre of the i-th piece of a row along east, ``step_m`` apart (area ENU, z = 0)."""
    return np.array([i * step_m + PIECE_M / 2, PIECE_M / 2, 0.0])
