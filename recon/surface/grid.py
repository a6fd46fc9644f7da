"""A north-up raster over the ground (ENU metres): the cells that the area merge and the ground filter bin a
surface into."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Grid:
    """A north-up raster of the area's ground: cell (row, col) is centred at ENU x = ``x0_m + (col + 0.5) cell_m``,
    y = ``y0_m - (row + 0.5) cell_m`` (``x0_m``, ``y0_m``: the north-west corner)."""

    x0_m: float
    y0_m: float
    cell_m: float
    rows: int
    cols: int

    @classmethod
    def covering(cls, points_xy: np.ndarray, cell_m: float, margin_m: float | None = None) -> "Grid":
        """The grid whose cells cover every ``(N, 2)`` point, with ``margin_m`` (None: one cell) to spare on each
        side."""
        margin_m = cell_m if margin_m is None else margin_m
        lo, hi = points_xy.min(axis=0) - margin_m, points_xy.max(axis=0) + margin_m
        cols, rows = (int(np.ceil((hi - lo)[k] / cell_m)) for k in (0, 1))
        return cls(float(lo[0]), float(lo[1] + rows * cell_m), cell_m, rows, cols)

    def centres(self) -> np.ndarray:
        """``(rows * cols, 2)`` ENU x, y of the cell centres, row by row."""
        cols, rows = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.column_stack([self.x0_m + (cols.ravel() + 0.5) * self.cell_m,
                                self.y0_m - (rows.ravel() + 0.5) * self.cell_m])

    def cell_of(self, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of the cell holding each ``(N, 2)`` point (clipped to the grid)."""
        row, col = self.index_of(points_xy)
        return np.clip(row, 0, self.rows - 1), np.clip(col, 0, self.cols - 1)

    def index_of(self, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of the cell each ``(N, 2)`` point falls in, negative or past the last one for a point off
        the grid (:meth:`holds` tells)."""
        col = np.floor((points_xy[:, 0] - self.x0_m) / self.cell_m).astype(np.int64)
        row = np.floor((self.y0_m - points_xy[:, 1]) / self.cell_m).astype(np.int64)
        return row, col

    def holds(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Whether each (``row``, ``col``) is a cell of the grid."""
        return (row >= 0) & (row < self.rows) & (col >= 0) & (col < self.cols)

    def to_dict(self) -> dict:
        return {"x0_m": self.x0_m, "y0_m": self.y0_m, "cell_m": self.cell_m, "rows": self.rows, "cols": self.cols}
