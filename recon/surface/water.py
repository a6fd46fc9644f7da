"""Open water found in the fused dense cloud, and the level plane that stands in for its surface (issue 39: "water a
plane at its level, if that is what the photos support and it measures better than a raw surface").

Dense stereo measures water badly: a pond is dark and nearly without texture, so its matched points scatter a few
decimetres round the level (the default orbit's pond: 5 % of its surface more than 0.2 m off, 14 % under a low sun),
and the mesh ripples where the water is flat. Still water is level, so where the photos show a body of it, the surface
is better as one plane at the level its points measure.

A body of water is found on a grid of ``cell_m`` cells over the fused points (ENU metres), per cell the median height
of its points and, over it and its 8 neighbours, their luminance's standard deviation:

1. **Plain**: cells whose luminance varies by less than :data:`MAX_TEXTURE` (8-bit sRGB luma) are candidates; each
   8-connected group of them of at least :data:`MIN_AREA_M2` is a possible body.
2. **Level**: its level is the median of its cells' heights, and at least :data:`MIN_LEVEL_SHARE` of its cells lie
   within :data:`LEVEL_BAND_M` of it (a sloping road is not water). The body is those cells, grown by up to
   :data:`GROW_CELLS` cells over neighbours also within the band (the shore's cells, where the window takes in the
   bank's texture), with the holes it encloses (cells without points, a crown's) and the cells without points in
   the notches of its edge.
3. **Basin**: water lies below its shore. At least :data:`MIN_RING_SEEN` of the ring :data:`RING_CELLS` cells wide
   round the body is observed (a plain patch at the edge of what the photos cover has no shore to judge by), and of
   its observed cells at least :data:`MIN_BANK_SHARE` lie :data:`BANK_RISE_M` or more above the level (a flat roof
   stands above the ground round it; a car park or a shadowed lawn is level with it).

The mesh's vertices over a body's cells within :data:`SNAP_BAND_M` of its level are moved onto it
(:func:`flatten_onto`): a crown over the water, or a wall, keeps its height. The faces on the plane are a ``proxy``
in the scene's face provenance (:func:`on_water`), so a dataset says where its depth is the plane's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

from cliutil.atomic import atomic_path, write_text_atomic
from cliutil.errors import BadInput
from cliutil.jsonfile import is_finite_number, read_json
from recon.surface.grid import Grid
from recon.surface.mesh import cell_size_for_density, per_cell_percentile, read_point_cloud

FORMAT = "aerostereo-water/1"
WATER_FILE = "water.json"
"""The bodies found, in a reconstruction's work folder (:func:`write_water`)."""
CELL_M = 0.5
"""The grid's cell (metres), grown where the fused points are sparser than :data:`MIN_MEAN_POINTS` per cell."""
MIN_MEAN_POINTS = 8.0
MAX_TEXTURE = 6.0
"""Luma standard deviation (0-255) over a cell and its neighbours below which the cell is plain enough for water."""
MIN_AREA_M2 = 12.0
"""The least area (m²) of a plain group to be a body of water."""
LEVEL_BAND_M = 0.2
"""A cell is at the level when its median height is within this many metres of it."""
MIN_LEVEL_SHARE = 0.7
"""The least share of a plain group's cells at its level."""
GROW_CELLS = 2
"""How many cells a body grows over its neighbours at the level (its shore's cells)."""
RING_CELLS = 3
"""Width (cells) of the ring round a body whose heights say whether it lies in a basin."""
BANK_RISE_M = 0.1
"""A ring cell is bank when its median height is at least this many metres above the level ..."""
MIN_BANK_SHARE = 0.75
"""... and a body lies in a basin when at least this share of its observed ring cells are bank ..."""
MIN_RING_SEEN = 0.8
"""... and at least this share of its ring is observed (the default orbit's pond: 95 %; a plain patch in shadow at the
edge of p4m_rtk's reconstruction, beside a row of trees: 34 %, and 93 % of that bank)."""
SNAP_BAND_M = 0.6
"""Mesh vertices over a body within this many metres of its level are moved onto it."""
ON_PLANE_M = 0.005
"""A face whose corners all lie within this many metres of a body's level, over it, is the plane (a proxy)."""
MIN_POINTS = 3
"""Cells with fewer fused points are not observed."""


@dataclass(frozen=True)
class WaterBody:
    """One body of water: its ``level_z`` (ENU z, metres) over the ``cells`` (rows, cols) boolean mask of ``grid``."""

    level_z: float
    grid: Grid
    cells: np.ndarray

    @property
    def area_m2(self) -> float:
        return float(self.cells.sum()) * self.grid.cell_m ** 2

    def over(self, points_xy: np.ndarray) -> np.ndarray:
        """Whether each ``(N, 2)`` ENU point lies over one of the body's cells."""
        row, col = self.grid.index_of(points_xy)
        inside = self.grid.holds(row, col)
        result = np.zeros(len(points_xy), bool)
        result[inside] = self.cells[row[inside], col[inside]]
        return result

    def to_dict(self) -> dict:
        rows, cols = np.nonzero(self.cells)
        return {"level_z_m": round(self.level_z, 4), "area_m2": round(self.area_m2, 2), "grid": self.grid.to_dict(),
                "cells": np.column_stack([rows, cols]).tolist()}

    @classmethod
    def from_dict(cls, record: dict) -> "WaterBody":
        """The body :meth:`to_dict` stored; ValueError (or KeyError, TypeError) saying what is not as it wrote it."""
        level_z, grid = record["level_z_m"], stored_grid(record["grid"])
        if not is_finite_number(level_z):
            raise ValueError(f"level_z_m: expected a finite height in metres, got {level_z!r}")
        index = np.asarray(record["cells"])
        if index.ndim != 2 or index.shape[1:] != (2,) or not len(index) or index.dtype.kind not in "iu":
            raise ValueError("cells: expected a non-empty list of [row, col] integer pairs")
        if not np.all(grid.holds(index[:, 0], index[:, 1])):
            raise ValueError(f"cells: a [row, col] off the {grid.rows} x {grid.cols} grid")
        cells = np.zeros((grid.rows, grid.cols), bool)
        cells[index[:, 0], index[:, 1]] = True
        return cls(float(level_z), grid, cells)


MAX_STORED_CELLS = 400_000_000
"""Most cells a stored body's grid may have (400 MB of mask: a 10 km square at 0.5 m)."""


def stored_grid(record: dict) -> Grid:
    """The :class:`Grid` a water file stores; ValueError where its origin or cell size is not finite, its cell size
    not positive, or its rows and columns not whole numbers from 1 with at most :data:`MAX_STORED_CELLS` cells."""
    if not isinstance(record, dict):
        raise TypeError(f"grid: expected a JSON object, got {record!r}")
    grid = Grid(**record)
    if not all(map(is_finite_number, (grid.x0_m, grid.y0_m, grid.cell_m))) or grid.cell_m <= 0:
        raise ValueError(f"grid: expected a finite corner and a cell size > 0 m, got {record}")
    counts = (grid.rows, grid.cols)
    if not all(type(n) is int and n >= 1 for n in counts) or grid.rows * grid.cols > MAX_STORED_CELLS:
        raise ValueError(f"grid: expected 1 to {MAX_STORED_CELLS} cells in whole rows and columns, got {counts}")
    return grid


@dataclass(frozen=True)
class CellStats:
    """Per cell of ``grid``: the median height of its points (NaN: unobserved) and the luma standard deviation over
    it and its 8 neighbours (NaN: none)."""

    grid: Grid
    height: np.ndarray
    texture: np.ndarray


def luma(colors: np.ndarray) -> np.ndarray:
    """Rec. 601 luma (0-255) of ``(N, 3)`` sRGB colours."""
    return np.asarray(colors, np.float64) @ np.array([0.299, 0.587, 0.114])


def cell_stats(points: np.ndarray, colors: np.ndarray, cell_m: float) -> CellStats:
    """:class:`CellStats` of the fused ``points`` ((N, 3) ENU metres) and their ``colors`` ((N, 3) sRGB)."""
    grid = Grid.covering(points[:, :2], cell_m, margin_m=(RING_CELLS + 2) * cell_m)  # a ring round every body
    row, col = grid.cell_of(points[:, :2])
    flat = row * grid.cols + col
    size = grid.rows * grid.cols
    count = np.bincount(flat, minlength=size).astype(np.float64)
    height = per_cell_percentile(flat, points[:, 2], size, 50.0)
    height[count < MIN_POINTS] = np.nan
    y = luma(colors)
    window = np.ones((3, 3))
    sums = [ndimage.convolve(np.bincount(flat, weights=w, minlength=size).reshape(grid.rows, grid.cols), window,
                             mode="constant") for w in (None, y, y * y)]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums[1] / sums[0]
        texture = np.sqrt(np.maximum(sums[2] / sums[0] - mean ** 2, 0.0))
    return CellStats(grid, height.reshape(grid.rows, grid.cols), texture)


def find_water(points: np.ndarray, colors: np.ndarray, cell_m: float) -> list[WaterBody]:
    """The bodies of water in the fused ``points`` ((N, 3) ENU metres) with their ``colors`` ((N, 3) sRGB), on a
    grid of ``cell_m`` metres (module docstring)."""
    if len(points) == 0:
        return []
    stats = cell_stats(np.asarray(points, np.float64), colors, cell_m)
    observed = np.isfinite(stats.height)
    plain = observed & (stats.texture < MAX_TEXTURE)
    groups, _ = ndimage.label(plain, structure=np.ones((3, 3)))
    min_cells = MIN_AREA_M2 / cell_m ** 2
    large = np.flatnonzero(np.bincount(groups.ravel()) >= min_cells)
    bodies = [level_body(stats, groups == index, min_cells) for index in large[large > 0]]
    return [body for body in bodies if body is not None]


def level_body(stats: CellStats, group: np.ndarray, min_cells: float) -> WaterBody | None:
    """The body of water a plain ``group`` of cells is, grown over its shore, or None where it is not level or
    does not lie in a basin."""
    level = float(np.median(stats.height[group]))
    with np.errstate(invalid="ignore"):
        at_level = np.abs(stats.height - level) <= LEVEL_BAND_M
    core = group & at_level
    if core.sum() < max(min_cells, MIN_LEVEL_SHARE * group.sum()):
        return None
    grown = ndimage.binary_dilation(core, np.ones((3, 3)), iterations=GROW_CELLS, mask=at_level)
    notches = ndimage.binary_closing(grown, np.ones((3, 3))) & ~np.isfinite(stats.height)
    body = ndimage.binary_fill_holes(grown | notches)
    ring = ndimage.binary_dilation(body, np.ones((3, 3)), iterations=RING_CELLS) & ~body
    seen = ring & np.isfinite(stats.height)
    if seen.sum() < MIN_RING_SEEN * ring.sum() or np.mean(stats.height[seen] >= level + BANK_RISE_M) < MIN_BANK_SHARE:
        return None
    return WaterBody(level, stats.grid, body)


def flatten_onto(vertices: np.ndarray, bodies: list[WaterBody]) -> np.ndarray:
    """``vertices`` ((V, 3) ENU metres) with those over a body within :data:`SNAP_BAND_M` of its level moved onto it
    (a new array)."""
    vertices = np.array(vertices, np.float64)
    for body in bodies:
        near = body.over(vertices[:, :2]) & (np.abs(vertices[:, 2] - body.level_z) <= SNAP_BAND_M)
        vertices[near, 2] = body.level_z
    return vertices


def on_water(vertices: np.ndarray, faces: np.ndarray, bodies: list[WaterBody]) -> np.ndarray:
    """(F,) whether each face (``faces`` into ``vertices``, ENU metres) is a body's plane: its centroid over the body
    and its corners on the level (within :data:`ON_PLANE_M`)."""
    corners = np.asarray(vertices, np.float64)[np.asarray(faces)]
    result = np.zeros(len(corners), bool)
    for body in bodies:
        level = np.all(np.abs(corners[:, :, 2] - body.level_z) <= ON_PLANE_M, axis=1)
        result |= level & body.over(corners.mean(axis=1)[:, :2])
    return result


def flatten_water(mesh_ply: Path, fused_ply: Path) -> list[WaterBody]:
    """Find the bodies of water in the fused cloud ``fused_ply`` and move the surface ``mesh_ply`` (a PLY mesh, ENU
    metres) onto their levels (rewritten atomically where one is found); the bodies. A cloud without colours has
    none."""
    points, colors = read_point_cloud(fused_ply)
    if colors is None:
        return []
    bodies = find_water(points, colors, cell_size_for_density(points, CELL_M, MIN_MEAN_POINTS))
    if bodies:
        mesh = trimesh.load(mesh_ply, process=False)
        colours = mesh.visual.vertex_colors if mesh.visual.kind == "vertex" else None
        flat = trimesh.Trimesh(flatten_onto(mesh.vertices, bodies), mesh.faces, vertex_colors=colours, process=False)
        with atomic_path(mesh_ply) as tmp:
            flat.export(tmp)
    return bodies


def describe(bodies: list[WaterBody]) -> str:
    """One line for the log: how many bodies, their areas and levels."""
    if not bodies:
        return "none found"
    return f"{len(bodies)} bod{'y' if len(bodies) == 1 else 'ies'} made planes: " + ", ".join(
        f"{body.area_m2:.0f} m2 at z {body.level_z:+.2f} m" for body in bodies)


def write_water(path: Path, bodies: list[WaterBody]) -> None:
    """Store ``bodies`` as JSON (:data:`FORMAT`) at ``path``, atomically."""
    write_text_atomic(path, json.dumps({"format": FORMAT, "bodies": [b.to_dict() for b in bodies]}))


def read_water(path: Path) -> list[WaterBody]:
    """The bodies stored at ``path`` by :func:`write_water` (none where it does not exist); :class:`BadInput` naming
    the file where it is not one."""
    if not Path(path).exists():
        return []
    record = read_json(path)
    try:
        if not isinstance(record, dict) or record.get("format") != FORMAT:
            raise ValueError(f"expected a JSON object whose format is {FORMAT!r}")
        if not isinstance(record["bodies"], list) or not all(isinstance(body, dict) for body in record["bodies"]):
            raise ValueError("bodies: expected a list of JSON objects")
        return [WaterBody.from_dict(body) for body in record["bodies"]]
    except KeyError as error:
        raise unreadable_water(path, f"no {error.args[0]!r} field") from None
    except (TypeError, ValueError) as error:
        raise unreadable_water(path, str(error)) from None


def unreadable_water(path: Path, reason: str) -> BadInput:
    """The refusal of a water file at ``path`` that is not as :func:`write_water` writes it, and why."""
    return BadInput(f"{path}: not a water file as recon writes it: {reason}; rerun recon's mesh stage to rewrite it")
