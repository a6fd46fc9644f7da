"""The bare ground under a reconstructed twin: a height grid fitted to its mesh, and heights above it.

A progressive morphological filter (Zhang et al. 2003, "A progressive morphological filter for removing nonground
measurements from airborne LIDAR data"): the lowest mesh point of each grid cell is opened (grey erosion then
dilation) with square windows (3 cells, then about doubling) up to ``max_window_m``; a cell that an opening lowers by
more than the terrain could rise over the window's growth (``tolerance_m``, then ``slope`` x growth + ``tolerance_m``,
at most ``max_step_m``) holds an object, not ground. The ground cells left are smoothed into the ground surface, which
fills the object cells from the ground around them (normalized convolution: a Gaussian-weighted mean of the ground
cells nearby, widened where none is near).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from recon.surface.grid import Grid


@dataclass(frozen=True)
class GroundFilter:
    """The filter's knobs: grid ``cell_m``; the largest opening window ``max_window_m`` (wider than the widest
    building); terrain ``slope`` (rise over run) the ground may have; height steps it lets through (``tolerance_m``
    at the smallest window, at most ``max_step_m``); ``smooth_m``: the Gaussian sigma the ground is smoothed with."""

    cell_m: float = 1.0
    max_window_m: float = 48.0
    slope: float = 1.0
    tolerance_m: float = 0.3
    max_step_m: float = 2.0
    smooth_m: float = 1.5


@dataclass(frozen=True)
class GroundSurface:
    """The ground heights (ENU z, metres) of a :class:`~recon.surface.grid.Grid`'s cells, and which cells hold ground
    seen in the mesh (the others are filled from the ground around them)."""

    grid: Grid
    height_m: np.ndarray  # (rows, cols) float64
    seen: np.ndarray  # (rows, cols) bool

    def height_at(self, points_xy: np.ndarray) -> np.ndarray:
        """The ground height under each ENU ``(N, 2)`` point, bilinear between cell centres (edges held)."""
        col = (points_xy[:, 0] - self.grid.x0_m) / self.grid.cell_m - 0.5
        row = (self.grid.y0_m - points_xy[:, 1]) / self.grid.cell_m - 0.5
        return ndimage.map_coordinates(self.height_m, [row, col], order=1, mode="nearest")


def lowest_per_cell(grid: Grid, points: np.ndarray) -> np.ndarray:
    """``(rows, cols)`` lowest z of the ENU ``(N, 3)`` points in each cell; NaN where none falls."""
    row, col = grid.cell_of(points[:, :2])
    lowest = np.full(grid.rows * grid.cols, np.inf)
    np.minimum.at(lowest, row * grid.cols + col, points[:, 2])
    lowest[np.isinf(lowest)] = np.nan
    return lowest.reshape(grid.rows, grid.cols)


def fill_nearest(values: np.ndarray, known: np.ndarray) -> np.ndarray:
    """``values`` with every cell not ``known`` set to its nearest known cell's value."""
    nearest = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
    return values[tuple(nearest)]


def object_cells(lowest: np.ndarray, options: GroundFilter) -> np.ndarray:
    """``(rows, cols)`` True where the progressive opening of the (filled) lowest surface flags an object."""
    surface = lowest.copy()
    flagged = np.zeros(lowest.shape, bool)
    previous, window = 3, 3  # the first window lets through tolerance_m only
    while True:
        opened = ndimage.grey_opening(surface, size=(window, window))
        step = min(options.tolerance_m + options.slope * (window - previous) * options.cell_m, options.max_step_m)
        flagged |= surface - opened > step
        surface = opened
        if window * options.cell_m >= options.max_window_m:
            return flagged
        previous, window = window, 2 * window - 1


def smooth_known(values: np.ndarray, known: np.ndarray, sigma_cells: float) -> np.ndarray:
    """Normalized convolution: every cell gets the Gaussian-weighted mean of the ``known`` cells around it, at
    ``sigma_cells`` where some are near and at four, then sixteen times that where none is (the wide gaps under
    buildings); cells still out of reach take the nearest value found."""
    smoothed = np.full(values.shape, np.nan)
    for sigma in (sigma_cells, 4 * sigma_cells, 16 * sigma_cells):
        weight = ndimage.gaussian_filter(known.astype(np.float64), sigma)
        total = ndimage.gaussian_filter(np.where(known, values, 0.0), sigma)
        fill = np.isnan(smoothed) & (weight > 1e-3)
        smoothed[fill] = total[fill] / weight[fill]
    found = np.isfinite(smoothed)
    return fill_nearest(smoothed, found) if found.any() else np.zeros(values.shape)


def fit_ground(points: np.ndarray, options: GroundFilter = GroundFilter()) -> GroundSurface:
    """The ground surface under ENU ``(N, 3)`` mesh points (module docstring)."""
    grid = Grid.covering(points[:, :2], options.cell_m)
    lowest = lowest_per_cell(grid, points)
    observed = np.isfinite(lowest)
    ground = observed & ~object_cells(fill_nearest(lowest, observed), options)
    return GroundSurface(grid, smooth_known(lowest, ground, options.smooth_m / options.cell_m), ground)
