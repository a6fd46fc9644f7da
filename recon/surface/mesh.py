"""Surface from the fused point cloud: a 2.5-D height field (default for aerial scenes) or Poisson.

Height field: points (ENU metres) are binned on a square grid (cell size from the ground sampling
distance); each cell's height is a high percentile of its points' z (roofs win over stray low points), colour
the mean of its points. The well-observed area is the observed cells closed by a few cells with interior
holes filled; holes inside it are filled from the nearest observed cell, then a 3x3 median removes spikes.
Before that, observed cells that no neighbour supports (none of their 8 neighbours observed within
``support_m`` of their height) are dropped: in the sparse far field single stray points otherwise become
columns metres tall once the hole filling spreads them.
Outside it there are no faces (cropped). Poisson: ``pycolmap.poisson_meshing`` with trim = depth - 3.
3-D surface (:func:`surface_3d`, keeps walls and overhangs): the fused cloud cropped to the observed area plus a
margin, screened Poisson of that, faces outside the area dropped and floaters removed: every connected piece but the
largest that the fused points do not measure (:func:`measured_pieces`). A tree crown that Poisson's density trim cuts
off its trunk is a piece of its own, and measured: it stays.
Decimation: ``pycolmap.simplify_mesh`` (QEM) bounded by a target error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pycolmap
import trimesh
from scipy import ndimage, sparse
from scipy.spatial import cKDTree

from cliutil.atomic import atomic_path, write_failed
from cliutil.resources import require_memory
from recon.surface.observed import inside, observed_area
from sim.render.scene import Scene, Surface


#: Peak bytes per cell of gridding a height field (127 measured with tracemalloc on a million cells with a point each:
#: counts, heights, colours, nearest-cell indices, filled copies) and of triangulating it (122) ...
HEIGHT_FIELD_BYTES_PER_CELL = 130
#: ... plus per point of the cloud (its cell index, the sort; 47 measured with a hundred points per cell).
HEIGHT_FIELD_BYTES_PER_POINT = 48


def require_height_field_memory(width_m: float, height_m: float, cell_m: float, what: str, points: int = 0) -> None:
    """Raise :class:`~cliutil.errors.BadInput` if a height field of ``width_m`` x ``height_m`` (metres) at
    ``cell_m`` cells from ``points`` points needs more memory than is free; ``what`` says where the size comes from."""
    cells = (math.floor(width_m / cell_m) + 1.0) * (math.floor(height_m / cell_m) + 1.0)
    require_memory(cells * HEIGHT_FIELD_BYTES_PER_CELL + points * HEIGHT_FIELD_BYTES_PER_POINT,
                   f"--grid {cell_m:g} over {what} of {width_m:.1f} x {height_m:.1f} m ({cells:.3g} cells)")


@dataclass(frozen=True)
class HeightField:
    """Heights ``z`` (rows = north, cols = east; NaN outside the valid area) on a grid whose cell (0, 0)
    centre is at ENU ``(x0, y0)``; ``colors`` (rows, cols, 3) uint8."""

    z: np.ndarray
    colors: np.ndarray
    x0: float
    y0: float
    cell_m: float

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.z)


def cell_size_from_gsd(median_depth_m: float, focal_px: float, pixels_per_cell: float = 2.0) -> float:
    """Grid cell (metres) = ``pixels_per_cell`` ground pixels of the depth maps (GSD = depth / focal)."""
    return pixels_per_cell * median_depth_m / focal_px


def cell_size_for_density(points: np.ndarray, cell_m: float, min_mean_points: float = 4.0) -> float:
    """Grow ``cell_m`` until the occupied cells hold on average ``min_mean_points`` points (sparse clouds)."""
    xy = np.floor((points[:, :2] - points[:, :2].min(axis=0)) / cell_m).astype(np.int64)
    occupied = len(np.unique(xy[:, 0] * (xy[:, 1].max() + 1) + xy[:, 1]))
    mean_points = len(points) / occupied
    return cell_m if mean_points >= min_mean_points else cell_m * float(np.sqrt(min_mean_points / mean_points))


def per_cell_percentile(cells: np.ndarray, values: np.ndarray, num_cells: int, percentile: float) -> np.ndarray:
    """``percentile`` of ``values`` per flat cell index (NaN for empty cells), without Python loops."""
    order = np.lexsort((values, cells))
    cells_sorted, values_sorted = cells[order], values[order]
    counts = np.bincount(cells_sorted, minlength=num_cells)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    result = np.full(num_cells, np.nan)
    filled = counts > 0
    pick = starts[filled] + np.floor((counts[filled] - 1) * percentile / 100.0 + 0.5).astype(int)
    result[filled] = values_sorted[pick]
    return result


def supported(z: np.ndarray, support_m: float, min_neighbours: int = 1) -> np.ndarray:
    """Cells (finite ``z``) with at least ``min_neighbours`` of their 8 neighbours finite and within ``support_m``."""
    padded = np.pad(z, 1, constant_values=np.nan)
    rows, cols = z.shape
    count = np.zeros(z.shape, int)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                neighbour = padded[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
                with np.errstate(invalid="ignore"):
                    count += np.abs(neighbour - z) <= support_m
    return np.isfinite(z) & (count >= min_neighbours)


def height_field(points: np.ndarray, colors: np.ndarray | None, cell_m: float, percentile: float = 75.0,
                 min_points: int = 2, closing_cells: int = 3, support_m: float = 0.5) -> HeightField:
    """Grid the ``(N, 3)`` ENU points into a :class:`HeightField` (see module docstring)."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) < 3:
        raise ValueError(f"need an (N >= 3, 3) point array, got shape {points.shape}")
    x0, y0 = points[:, 0].min(), points[:, 1].min()
    require_height_field_memory(points[:, 0].max() - x0, points[:, 1].max() - y0, cell_m, "the point cloud",
                                len(points))
    col = np.floor((points[:, 0] - x0) / cell_m).astype(int)
    row = np.floor((points[:, 1] - y0) / cell_m).astype(int)
    shape = (row.max() + 1, col.max() + 1)
    cells = row * shape[1] + col
    n_cells = shape[0] * shape[1]
    counts = np.bincount(cells, minlength=n_cells)
    z = per_cell_percentile(cells, points[:, 2], n_cells, percentile).reshape(shape)
    observed = (counts >= min_points).reshape(shape)
    z[~observed] = np.nan
    observed &= supported(z, support_m)
    z[~observed] = np.nan
    rgb = np.zeros((n_cells, 3))
    if colors is not None:
        for channel in range(3):
            rgb[:, channel] = np.bincount(cells, weights=colors[:, channel], minlength=n_cells)
        rgb /= np.maximum(counts, 1)[:, None]
    rgb = rgb.reshape(shape + (3,))
    area = ndimage.binary_fill_holes(ndimage.binary_closing(observed, iterations=closing_cells,
                                                            border_value=0) | observed)
    nearest = ndimage.distance_transform_edt(~observed, return_distances=False, return_indices=True)
    z_filled = z[tuple(nearest)]
    rgb_filled = rgb[tuple(nearest)]
    z_smooth = ndimage.median_filter(z_filled, size=3, mode="nearest")
    z_smooth[~area] = np.nan
    return HeightField(z_smooth, np.clip(rgb_filled, 0, 255).astype(np.uint8), x0 + cell_m / 2, y0 + cell_m / 2,
                       cell_m)


def height_field_mesh(field: HeightField) -> trimesh.Trimesh:
    """Triangulate the valid cells: two triangles per grid square whose four corners are valid (ENU m)."""
    rows, cols = field.z.shape
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    vertices = np.column_stack([field.x0 + c.ravel() * field.cell_m, field.y0 + r.ravel() * field.cell_m,
                                field.z.ravel()])
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b, c2, d = index[:-1, :-1], index[:-1, 1:], index[1:, :-1], index[1:, 1:]
    valid = field.valid
    quad = valid[:-1, :-1] & valid[:-1, 1:] & valid[1:, :-1] & valid[1:, 1:]
    faces = np.concatenate([np.stack([a[quad], b[quad], d[quad]], 1), np.stack([a[quad], d[quad], c2[quad]], 1)])
    colors = np.column_stack([field.colors.reshape(-1, 3), np.full(rows * cols, 255)]).astype(np.uint8)
    mesh = trimesh.Trimesh(np.nan_to_num(vertices), faces, vertex_colors=colors, process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


def scene_from_mesh(mesh: trimesh.Trimesh) -> Scene:
    """A ray-castable sim scene of an ENU mesh (grey vertex colours: only the geometry matters here)."""
    grey = np.full((len(mesh.vertices), 3), 128, np.uint8)
    return Scene(np.asarray(mesh.vertices), np.asarray(mesh.faces), Surface(vertex_colors=grey), source="<recon mesh>")


def poisson_mesh(fused_ply: Path, output_ply: Path, depth: int = 10, trim: float | None = None) -> None:
    """Screened Poisson surface of the fused cloud (needs normals), trimmed where the point density is below
    ``trim`` (None: ``depth - 3``)."""
    options = pycolmap.PoissonMeshingOptions()
    options.depth = depth
    options.trim = depth - 3 if trim is None else trim
    with atomic_path(output_ply) as tmp:
        pycolmap.poisson_meshing(fused_ply, tmp, options)
        check_ply_written(tmp, output_ply)


def decimate(input_ply: Path, output_ply: Path, max_error_m: float, min_face_ratio: float = 0.01) -> None:
    """QEM decimation (``pycolmap.simplify_mesh``) stopping at the quadric error bound ``max_error_m``
    (metres, applied as the squared-distance QEM bound) or at ``min_face_ratio`` of the faces."""
    options = pycolmap.MeshSimplificationOptions()
    options.target_face_ratio = min_face_ratio
    options.max_error = max_error_m**2
    with atomic_path(output_ply) as tmp:
        pycolmap.simplify_mesh(input_ply, tmp, options)
        check_ply_written(tmp, output_ply)


def check_ply_written(written: Path, target: Path) -> None:
    """``OSError`` naming ``target`` unless trimesh reads the PLY mesh COLMAP wrote to ``written`` whole: COLMAP's
    PLY writers report no error, and a full disk leaves the file cut short."""
    try:
        trimesh.load(written, process=False)
    except (ValueError, IndexError, KeyError) as error:  # trimesh's PLY reader on a short or empty file
        raise write_failed(target, f"COLMAP's PLY is incomplete ({error})") from None


def read_point_cloud(ply: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (N, 3) float64 and colours (N, 3) uint8 (or None) of a PLY point cloud; ValueError naming the file
    when it holds no point."""
    cloud = trimesh.load(ply, process=False)
    if not hasattr(cloud, "vertices") or len(cloud.vertices) == 0:
        raise ValueError(f"{ply}: no points in this point cloud")
    points = np.asarray(cloud.vertices, dtype=np.float64)
    colors = getattr(cloud, "colors", None)
    colors = None if colors is None or len(colors) != len(points) else np.asarray(colors)[:, :3]
    return points, colors


def read_binary_ply_vertices(ply: Path) -> tuple[bytes, np.ndarray]:
    """Header (bytes, through ``end_header``) and vertex records (structured array) of a binary little-endian PLY
    holding one ``vertex`` element (what pycolmap's fusion writes); ValueError naming the file otherwise."""
    data = Path(ply).read_bytes()
    end = data.find(b"end_header\n")
    header = data[:end + len(b"end_header\n")] if end >= 0 else b""
    lines = header.decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in lines or not lines[-1] == "end_header":
        raise ValueError(f"{ply}: expected a binary little-endian PLY point cloud")
    types = {"float": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1", "int": "<i4", "uint": "<u4"}
    fields, count = [], None
    for line in lines:
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            count = int(words[2])
        elif words[:1] == ["element"]:
            raise ValueError(f"{ply}: expected only a vertex element, found {line!r}")
        elif words[:1] == ["property"] and len(words) == 3 and words[1] in types:
            fields.append((words[2], types[words[1]]))
        elif words[:1] == ["property"]:
            raise ValueError(f"{ply}: unsupported property {line!r}")
    records = np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=len(header))
    return header, records


def crop_point_cloud(input_ply: Path, output_ply: Path, polygon: np.ndarray) -> int:
    """Write the points of ``input_ply`` whose ENU (x, y) lie inside ``polygon`` ((K, 2) metres) to
    ``output_ply``, every property kept; returns how many."""
    header, records = read_binary_ply_vertices(input_ply)
    kept = records[inside(polygon, np.column_stack([records["x"], records["y"]]))]
    count_line = f"element vertex {len(records)}".encode()
    with atomic_path(output_ply) as tmp:
        tmp.write_bytes(header.replace(count_line, f"element vertex {len(kept)}".encode(), 1) + kept.tobytes())
    return len(kept)


MIN_PIECE_DENSITY_SHARE = 0.5
"""A piece of the 3-D surface besides the largest is measured when it is the nearest surface of at least this share of
the fused points per m² that the largest piece is (on the default orbit: tree crowns 70-150 points/m² against the
ground's 27; the skins Poisson closes under the ground and round the crop's edge under 5)..."""
MIN_PIECE_EQUIVALENT_M2 = 4.0
"""... and of at least as many points as this many m² of the largest piece are: a few stray points' blob is not."""


def piece_of_face(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F,) index of the edge-connected piece each face of ``mesh`` belongs to."""
    adjacency = np.asarray(mesh.face_adjacency)
    graph = sparse.coo_matrix((np.ones(len(adjacency)), (adjacency[:, 0], adjacency[:, 1])),
                              shape=(len(mesh.faces), len(mesh.faces)))
    return sparse.csgraph.connected_components(graph, directed=False)[1]


def measured_pieces(mesh: trimesh.Trimesh, points: np.ndarray, cell_m: float) -> trimesh.Trimesh:
    """``mesh`` (ENU metres) without the pieces the fused ``points`` ((N, 3) ENU metres) do not measure (floaters):
    its largest edge-connected piece (by area) stays, and every other piece that is the nearest surface, within
    ``cell_m``, of enough points (:data:`MIN_PIECE_DENSITY_SHARE`, :data:`MIN_PIECE_EQUIVALENT_M2`)."""
    if len(mesh.faces) == 0:
        return mesh
    piece = piece_of_face(mesh)
    area = np.bincount(piece, weights=mesh.area_faces)
    distance, nearest = cKDTree(mesh.triangles_center).query(points, distance_upper_bound=cell_m)
    explained = np.bincount(piece[nearest[np.isfinite(distance)]], minlength=len(area)).astype(np.float64)
    largest = int(np.argmax(area))
    density = explained[largest] / max(area[largest], 1e-12)
    keep = ((explained >= MIN_PIECE_DENSITY_SHARE * density * area)
            & (explained >= MIN_PIECE_EQUIVALENT_M2 * density))
    keep[largest] = True
    return face_subset(mesh, keep[piece])


def face_subset(mesh: trimesh.Trimesh, keep: np.ndarray) -> trimesh.Trimesh:
    """The faces ``keep`` (boolean mask) of ``mesh`` with their vertices (and vertex colours) only."""
    part = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False,
                           vertex_colors=mesh.visual.vertex_colors if mesh.visual.kind == "vertex" else None)
    part.remove_unreferenced_vertices()
    return part


def surface_3d(fused_ply: Path, output_ply: Path, area: np.ndarray, margin_m: float, cell_m: float, depth: int = 10,
               trim: float | None = None) -> trimesh.Trimesh:
    """3-D surface of the fused cloud (ENU metres) over the observed ``area`` ((K, 2) polygon) grown by
    ``margin_m``: Poisson of the cloud cropped to that, faces with their centroid outside it and the pieces its points
    do not measure within ``cell_m`` dropped (:func:`measured_pieces`). Written to ``output_ply`` and returned."""
    grown = grow_polygon(area, margin_m)
    cropped = Path(output_ply).with_name(f".{Path(output_ply).stem}.cropped.ply")
    crop_point_cloud(fused_ply, cropped, grown)
    try:
        poisson_mesh(cropped, output_ply, depth, trim)
        points, _ = read_point_cloud(cropped)
    finally:
        cropped.unlink(missing_ok=True)
    surface = trimesh.load(output_ply, process=False)
    surface = face_subset(surface, inside(grown, np.asarray(surface.triangles_center)))
    surface = measured_pieces(surface, points, cell_m)
    with atomic_path(output_ply) as tmp:
        surface.export(tmp)
    return surface


def grow_polygon(polygon: np.ndarray, margin_m: float, corners: int = 16) -> np.ndarray:
    """The convex hull of a convex ``polygon`` ((K, 2), metres) grown outwards by ``margin_m`` (its corners
    rounded with ``corners`` points each)."""
    angles = np.linspace(0.0, 2.0 * np.pi, corners, endpoint=False)
    ring = margin_m * np.column_stack([np.cos(angles), np.sin(angles)])
    return observed_area((np.asarray(polygon, dtype=np.float64)[:, None, :] + ring[None]).reshape(-1, 2))
