"""Standing objects the 3-D surface lost, put back from the fused points' height field (ENU metres throughout).

Screened Poisson smooths small standing things into the ground: a shelter's roof, a young tree, a crown whose
points are few beside the lawn's many. The fused points still hold them, and so does their 2.5-D height field
(:func:`recon.surface.mesh.height_field`: each cell's 75th-percentile height, holes among observed cells filled
from the nearest). Where the height field stands more than :data:`MIN_RISE_M` over the highest first surface from
above of the 3-D surface in the cell and its 8 neighbours (:func:`highest_around`: an edge the 3-D surface keeps,
a roof's or a crown's, is not lost), in a patch holding at least :data:`MIN_CELLS` cells the points observe, the
height field's surface over the patch (grown by one cell, so that its quads reach down to the surface round it as
walls) is added to the 3-D surface. The Poisson surface stays beneath: every ray meets the nearer of the two, as in
the 2.5-D field there. The patch is measured like the rest of the surface (face provenance,
:mod:`recon.surface.provenance`): its faces farther than the gap from every fused point, the walls and the filled
holes, are ``surface_filled``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

from cliutil.atomic import atomic_path
from recon.surface.mesh import HeightField, height_field, height_field_mesh, scene_from_mesh

#: The height field over the 3-D surface by more than this (m) marks a standing object Poisson lost: above the
#: 75th percentile's own spread on open ground and the fattening at a crown's rim (a few tenths of a metre).
MIN_RISE_M = 1.0
#: Fewest observed cells of a patch put back: a stray cell or two of outliers is not an object.
MIN_CELLS = 4
#: Fewest fused points in a cell for it to count as observed.
MIN_POINTS = 2


def highest_around(heights: np.ndarray) -> np.ndarray:
    """The highest of ``heights`` (rows, cols; NaN: none) over each cell and its 8 neighbours (NaN where all are):
    the height field's cell straddles an edge the 3-D surface draws inside the cell (a roof's, a crown's), and
    stands over the surface's height at the cell's centre without anything being lost."""
    known = np.where(np.isfinite(heights), heights, -np.inf)
    highest = ndimage.maximum_filter(known, size=3, mode="nearest")
    return np.where(np.isfinite(highest), highest, np.nan)


def observed_cells(field: HeightField, points: np.ndarray) -> np.ndarray:
    """(rows, cols) True where at least :data:`MIN_POINTS` of ``points`` fall in the cell of ``field``."""
    rows, cols = field.z.shape
    col = np.floor((points[:, 0] - field.x0) / field.cell_m + 0.5).astype(np.int64)
    row = np.floor((points[:, 1] - field.y0) / field.cell_m + 0.5).astype(np.int64)
    ok = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
    counts = np.bincount(row[ok] * cols + col[ok], minlength=rows * cols).reshape(rows, cols)
    return counts >= MIN_POINTS


def lost_cells(field: HeightField, observed: np.ndarray, below: np.ndarray) -> np.ndarray:
    """(rows, cols) True in the patches (8-connected) of cells where ``field`` stands more than :data:`MIN_RISE_M`
    over the 3-D surface's heights ``below`` (NaN: none there) that hold at least :data:`MIN_CELLS` ``observed``
    cells."""
    with np.errstate(invalid="ignore"):
        risen = field.z - below > MIN_RISE_M
    patches, count = ndimage.label(risen, structure=np.ones((3, 3), bool))
    sizes = np.bincount(patches.ravel(), weights=observed.ravel(), minlength=count + 1)
    keep = sizes >= MIN_CELLS
    keep[0] = False
    return keep[patches]


def standing_patches(surface: trimesh.Trimesh, points: np.ndarray, colors: np.ndarray | None,
                     cell_m: float) -> tuple[trimesh.Trimesh, int]:
    """The height field of the fused ``points`` (N, 3) (their ``colors``, N x 3, as vertex colours) at ``cell_m``
    over the standing objects ``surface`` lost (module docstring), and how many cells they cover; an empty mesh
    when none is lost."""
    field = height_field(points, colors, cell_m)
    rows, cols = field.z.shape
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    xy = np.column_stack([field.x0 + c.ravel() * cell_m, field.y0 + r.ravel() * cell_m])
    if len(surface.faces):
        heights = scene_from_mesh(surface).ground_height(xy[:, 0], xy[:, 1])
    else:
        heights = np.full(len(xy), np.nan)
    below = highest_around(heights.reshape(rows, cols))
    lost = lost_cells(field, observed_cells(field, points), below)
    if not lost.any():
        return trimesh.Trimesh(), 0
    grown = ndimage.binary_dilation(lost, structure=np.ones((3, 3), bool))
    patch = HeightField(np.where(grown, field.z, np.nan), field.colors, field.x0, field.y0, cell_m)
    return height_field_mesh(patch), int(lost.sum())


def put_back(surface: trimesh.Trimesh, ply: Path, points: np.ndarray, colors: np.ndarray | None,
             cell_m: float) -> int:
    """Add :func:`standing_patches` to ``surface`` (the 3-D surface written at ``ply``), rewriting ``ply``
    atomically when any cell was lost; the cells put back."""
    restored, cells = with_standing_objects(surface, points, colors, cell_m)
    if cells:
        with atomic_path(ply) as tmp:
            restored.export(tmp)
    return cells


def with_standing_objects(surface: trimesh.Trimesh, points: np.ndarray, colors: np.ndarray | None,
                          cell_m: float) -> tuple[trimesh.Trimesh, int]:
    """``surface`` with :func:`standing_patches` added (its faces first, in its order), and the cells put back."""
    patches, cells = standing_patches(surface, points, colors, cell_m)
    if cells == 0:
        return surface, 0
    return trimesh.util.concatenate([surface, patches]), cells
