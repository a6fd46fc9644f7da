"""One scene from an area's aligned pieces: who owns each patch of ground, seams blended, colours matched.

All in the area's ENU frame (metres, z up), after :func:`recon.area.align.align_area`'s corrections. The ground is a
grid of ``cell_m`` cells (:class:`~recon.surface.grid.Grid`, row 0 north). Steps:

1. **Surface**: where each piece has any surface, by casting a ray down through every cell centre (embree).
2. **Ownership**: each cell goes to the piece that sees it best, among the pieces with surface there: the piece whose
   cameras' look-at points (optical axis meets the ground, :func:`look_at_points`) come closest to the cell. An orbit
   looks at its centre from every side, a nadir block under each photo; the cell nearest to where a piece points is
   the one it saw most often and most squarely. Each piece keeps its faces whose centroid lies in a cell it owns.
3. **Seams in geometry** (:func:`blend_seams`): within ``width_m`` of a cell owned by piece ``b``, a vertex of piece
   ``a`` moves towards ``b``'s surface (its closest point) with weight ``0.5 (1 - d / width_m)``: at the seam both
   surfaces meet half-way, a band's width away each is itself. Offsets over ``max_step_m`` (a wall of one piece
   against the ground of the other) are left alone.
4. **Seams in colour** (:func:`colour_gains`): one gain per piece and colour channel (linear light), from the median
   log-ratio of the two pieces' mean albedo over 8 m blocks both saw well, solved jointly (geometric mean 1),
   so a flight flown in brighter light does not leave a patchwork.
5. **Covered area** (:func:`covered_polygon`): the union of the pieces' observed areas where the owner has surface,
   shrunk by two cells, as one polygon (non-convex in general): scene.json's ``observed_area_m``.
"""

from __future__ import annotations

import cv2
import numpy as np
from matplotlib.path import Path as PolygonPath
from scipy.spatial import cKDTree

from recon.area.align import SurfaceQuery
from recon.surface.grid import Grid
from sim.render.scene import Scene, Surface
from sim.render.shade import surface_albedo
from sim.render.raycast import from_above

NO_OWNER = -1
#: Look-at points of cameras whose optical axis rises or meets the ground beyond this many metres are left out.
MAX_LOOK_AT_M = 1000.0
#: Colours of neighbouring pieces are compared as means over blocks this wide (metres).
COLOUR_BLOCK_M = 8.0


def ray_scene(vertices: np.ndarray, faces: np.ndarray) -> Scene:
    """An embree scene of a mesh (ENU metres) for casting only (plain grey)."""
    return Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 128, np.uint8)))


def surface_mask(scene: Scene, grid: Grid) -> np.ndarray:
    """``(rows, cols)`` True where a ray cast straight down through the cell centre meets the scene."""
    xy = grid.centres()
    return np.isfinite(scene.ground_height(xy[:, 0], xy[:, 1])).reshape(grid.rows, grid.cols)


def look_at_points(T_world_cam: np.ndarray, ground_z: float) -> np.ndarray:
    """``(M, 2)`` ENU x, y where each camera's optical axis (``(N, 4, 4)`` poses, OpenCV axes) meets the plane
    ``z = ground_z``; cameras looking level or up, or meeting it beyond MAX_LOOK_AT_M, give none."""
    centres, axes = T_world_cam[:, :3, 3], T_world_cam[:, :3, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        along = (ground_z - centres[:, 2]) / axes[:, 2]
    ok = (axes[:, 2] < -1e-6) & (along > 0) & (along < MAX_LOOK_AT_M)
    return (centres[ok] + along[ok, None] * axes[ok])[:, :2]


def ownership(grid: Grid, surfaces: list[np.ndarray], look_ats: list[np.ndarray]) -> np.ndarray:
    """``(rows, cols)`` int: per cell, the index of the piece whose look-at points come closest among the pieces
    with surface there; NO_OWNER where none has surface."""
    centres = grid.centres()
    best = np.full(len(centres), np.inf)
    owner = np.full(len(centres), NO_OWNER, np.int64)
    for index, (surface, points) in enumerate(zip(surfaces, look_ats)):
        has = surface.ravel()
        if not len(points) or not has.any():
            continue
        distance, _ = cKDTree(points).query(centres[has])
        cells = np.flatnonzero(has)
        closer = distance < best[cells]
        best[cells[closer]], owner[cells[closer]] = distance[closer], index
    return owner.reshape(grid.rows, grid.cols)


def kept_faces(vertices: np.ndarray, faces: np.ndarray, owner: np.ndarray, grid: Grid, index: int) -> np.ndarray:
    """Boolean per face: its centroid's cell belongs to piece ``index``."""
    row, col = grid.cell_of(vertices[faces].mean(axis=1)[:, :2])
    return owner[row, col] == index


def distance_to_owner(owner: np.ndarray, index: int, cell_m: float) -> np.ndarray:
    """``(rows, cols)`` distance (metres) from each cell's centre to the nearest cell owned by ``index``, less half
    a cell (so about the distance to the seam); 0 inside its own cells, inf when it owns none."""
    others = (owner != index).astype(np.uint8)
    if others.all():
        return np.full(owner.shape, np.inf)
    distance = cv2.distanceTransform(others, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * cell_m
    return np.maximum(distance - 0.5 * cell_m, 0.0)


def blend_seams(vertices: list[np.ndarray], queries: list[SurfaceQuery], owner: np.ndarray, grid: Grid,
                neighbours: dict[int, set[int]], width_m: float, max_step_m: float) -> list[np.ndarray]:
    """Each piece's vertices moved towards its neighbours' surfaces near the seams (module docstring, step 3).

    ``vertices[a]`` are piece ``a``'s (kept) vertices, ``queries[b]`` closest-point queries on piece ``b``'s whole
    aligned mesh, ``neighbours[a]`` the pieces that share a seam with ``a``. Returns new arrays (metres, area ENU)."""
    distances = {b: distance_to_owner(owner, b, grid.cell_m) for b in {n for ns in neighbours.values() for n in ns}}
    blended = []
    for a, points in enumerate(vertices):
        moved = points.copy()
        row, col = grid.cell_of(points[:, :2])
        for b in sorted(neighbours.get(a, ())):
            weight = 0.5 * np.clip(1.0 - distances[b][row, col] / width_m, 0.0, 1.0)
            near = np.flatnonzero(weight > 0)
            if not len(near):
                continue
            closest, _ = queries[b].closest(points[near])
            step = closest - points[near]
            small = np.linalg.norm(step, axis=1) <= max_step_m
            moved[near[small]] += weight[near[small], None] * step[small]
        blended.append(moved)
    return blended


def seam_neighbours(owner: np.ndarray) -> dict[int, set[int]]:
    """Pieces whose owned cells touch (4-neighbourhood): ``{a: {b, ...}}``, both ways."""
    pairs = set()
    for first, second in ((owner[:, :-1], owner[:, 1:]), (owner[:-1, :], owner[1:, :])):
        differ = (first != second) & (first != NO_OWNER) & (second != NO_OWNER)
        pairs |= set(zip(first[differ].tolist(), second[differ].tolist()))
    neighbours: dict[int, set[int]] = {}
    for a, b in pairs:
        neighbours.setdefault(a, set()).add(b)
        neighbours.setdefault(b, set()).add(a)
    return neighbours


def albedo_under(scene: Scene, xy: np.ndarray) -> np.ndarray:
    """Linear albedo ``(N, 3)`` of the topmost surface under each ENU ``(x, y)``; NaN rows where there is none."""
    hits = from_above(scene, xy)[1]
    albedo = np.full((len(xy), 3), np.nan, np.float32)
    hit = hits.tri >= 0
    albedo[hit] = surface_albedo(scene, hits.tri[hit], hits.u[hit], hits.v[hit])
    return albedo


def block_log_colours(colours: np.ndarray, cells: np.ndarray, grid: Grid, block_m: float) -> dict[int, np.ndarray]:
    """Log of the mean linear colour per ``block_m`` square block of the grid, from ``colours`` ``(N, 3)`` sampled at
    the flat cell indices ``cells``; only blocks with at least half their cells sampled (validly) count."""
    side = max(1, int(round(block_m / grid.cell_m)))
    row, col = np.divmod(cells, grid.cols)
    block = (row // side) * (grid.cols // side + 1) + col // side
    valid = np.all(colours > 1e-3, axis=1)
    ids, inverse, counts = np.unique(block[valid], return_inverse=True, return_counts=True)
    sums = np.zeros((len(ids), 3))
    np.add.at(sums, inverse, colours[valid])
    full = counts >= side * side / 2
    return dict(zip(ids[full].tolist(), np.log(sums[full] / counts[full, None])))


def colour_gains(scenes: list[Scene], well_seen: list[np.ndarray], grid: Grid, neighbours: dict[int, set[int]],
                 block_m: float = COLOUR_BLOCK_M) -> tuple[np.ndarray, list[dict]]:
    """Per piece, a gain per linear RGB channel ``(K, 3)`` that best matches neighbouring pieces' colour where both
    saw the ground well (``well_seen``: surface inside the observed footprint; elsewhere a texture holds the few
    photos that grazed it), and per pair the median absolute log-ratio before and after (``{"a", "b", "blocks", "before",
    "after"}``; 0.05 is 5 %). Colours are compared as means over ``block_m`` blocks: cell by cell the texture's
    detail and the pieces' residual misalignment (centimetres to decimetres) would drown an exposure difference.
    The gains are the joint least-squares fit of the pairs' median block log-ratios (geometric mean gain 1)."""
    centres = grid.centres()
    rows, ratios = [], []
    for a in sorted(neighbours):
        for b in sorted(n for n in neighbours[a] if n > a):
            both = np.flatnonzero((well_seen[a] & well_seen[b]).ravel())
            blocks_a, blocks_b = (block_log_colours(albedo_under(scenes[k], centres[both]), both, grid, block_m)
                                  for k in (a, b))
            shared = sorted(set(blocks_a) & set(blocks_b))
            if len(shared) < 3:
                continue
            rows.append((a, b, len(shared)))
            ratios.append(np.array([blocks_a[k] - blocks_b[k] for k in shared]))
    count = len(scenes)
    if not rows:
        return np.ones((count, 3)), []
    system = np.zeros((len(rows) + 1, count))
    for k, (a, b, _) in enumerate(rows):
        system[k, a], system[k, b] = 1.0, -1.0
    system[-1] = 1.0  # the gains' geometric mean is 1
    medians = np.array([np.median(r, axis=0) for r in ratios])
    log_gain, *_ = np.linalg.lstsq(system, np.vstack([-medians, np.zeros((1, 3))]), rcond=None)
    report = [{"a": a, "b": b, "blocks": blocks,
               "before": float(np.median(np.abs(r))),
               "after": float(np.median(np.abs(r + log_gain[a] - log_gain[b])))}
              for (a, b, blocks), r in zip(rows, ratios)]
    return np.exp(log_gain), report


def footprint_mask(grid: Grid, footprint: np.ndarray) -> np.ndarray:
    """``(rows, cols)`` True where the cell centre lies inside the ``(K, 2)`` ENU polygon."""
    return PolygonPath(footprint).contains_points(grid.centres()).reshape(grid.rows, grid.cols)


def covered_polygon(grid: Grid, seen: list[np.ndarray], owner: np.ndarray) -> tuple[np.ndarray, float]:
    """The well-covered ground as one polygon ``(K, 2)`` (ENU metres): cells inside any piece's observed footprint
    (``seen``, :func:`footprint_mask`) whose owner has surface, shrunk by two cells (so the simplified outline stays
    inside), the largest connected part. Also the area (m²) of uncovered holes inside it (0 when there are none)."""
    mask = (np.logical_or.reduce(seen) & (owner != NO_OWNER)).astype(np.uint8)
    mask = cv2.erode(mask, np.ones((3, 3), np.uint8), iterations=2)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=4)
    if count < 2:
        raise ValueError("no ground is covered by any piece's observed area and surface")
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    region = (labels == largest).astype(np.uint8)
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    outline = cv2.approxPolyDP(max(contours, key=cv2.contourArea), 0.5, True).reshape(-1, 2).astype(np.float64)
    filled = np.zeros_like(region)
    cv2.drawContours(filled, [outline.astype(np.int32).reshape(-1, 1, 2)], -1, 1, thickness=cv2.FILLED)
    holes_m2 = float(np.count_nonzero(filled & (1 - region))) * grid.cell_m ** 2
    x = grid.x0_m + (outline[:, 0] + 0.5) * grid.cell_m
    y = grid.y0_m - (outline[:, 1] + 0.5) * grid.cell_m
    return np.column_stack([x, y]), holes_m2
