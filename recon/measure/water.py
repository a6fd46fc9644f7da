"""Water at its level: per pond of the true world, the share of its surface seen from above where the twin lies within
:data:`LEVEL_TOLERANCE_M` of the water's level (issue 39: "water coverage >= 97 % at its level within 0.2 m").

Every pond (the world's ``scene.json`` ``"objects"`` of kind ``pond``, written by sim/worlds/water.py: its object
``instance``, ``level_z_m`` and ``shoreline_m``) gets the grid of :data:`recon.measure.trees.CELL_M` cells over its
shoreline's bounding box. A nadir ray through each cell's centre finds the first surface from above in the true world
and in the twin (:func:`sim.render.raycast.from_above`, through the twin's similarity). The pond's cells
are those whose first TRUE surface is a face of the pond (an overhanging crown hides the water under it), less a
:data:`SHORE_INSET_M` band along their edge, where a bank and the water share a cell. A cell where the twin has no
surface counts as off.

Frames: world ENU metres; levels and errors are ENU z.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage

from recon.measure.oblique import TwinFrame
from recon.measure.trees import CELL_M
from recon.surface.grid import Grid
from sim.render.raycast import from_above
from sim.render.scene import Scene

LEVEL_TOLERANCE_M = 0.2
"""A twin cell is at the water's level within this many metres (the issue's target)."""
SHORE_INSET_M = 0.5
"""The band along the edge of a pond's cells left out, metres: there a cell mixes the water and its bank."""


@dataclass(frozen=True)
class TruePond:
    """One pond of the world's truth: its object ``instance`` (labels), water ``level_z`` (ENU m) and ``shoreline``
    (K, 2) ENU polygon."""

    instance: int
    level_z: float
    shoreline: np.ndarray

    @classmethod
    def from_record(cls, record: dict) -> "TruePond":
        """From one ``pond`` entry of scene.json's ``objects``."""
        return cls(int(record["instance"]), float(record["level_z_m"]), np.asarray(record["shoreline_m"], np.float64))


def read_true_ponds(meta: dict, source: str) -> list[TruePond]:
    """The ponds of a world's parsed ``scene.json`` (``source`` names it in errors; none where it lists none);
    ValueError where a pond's entry lacks a field."""
    try:
        return [TruePond.from_record(record) for record in meta.get("objects", []) if record.get("kind") == "pond"]
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{source}: objects: a pond without a usable {error}") from None


@dataclass(frozen=True)
class PondScore:
    """One pond, twin against truth, over its cells seen from above: ``cells`` their count; ``covered`` the share
    where the twin has surface; ``at_level`` the share where it lies within :data:`LEVEL_TOLERANCE_M` of the level
    (holes off); ``median_error_m`` the median of twin height minus level over the covered cells (NaN without any)."""

    instance: int
    cells: int
    covered: float
    at_level: float
    median_error_m: float

    def to_dict(self) -> dict:
        return asdict(self)


def score_pond(pond: TruePond, shape: tuple[int, int], true_instance: np.ndarray, twin_height: np.ndarray,
               cell_m: float = CELL_M) -> PondScore:
    """One pond's :class:`PondScore` from its grid's cells (row by row): the object of the first true surface (0:
    none) and the twin's height (NaN: a hole), each (cells,)."""
    water = (true_instance == pond.instance).reshape(shape)
    inset = int(round(SHORE_INSET_M / cell_m))
    if inset:
        water = ndimage.binary_erosion(water, iterations=inset)
    height = twin_height.reshape(shape)[water]
    error = height[np.isfinite(height)] - pond.level_z
    cells = len(height)
    if not cells:
        return PondScore(pond.instance, 0, math.nan, math.nan, math.nan)
    return PondScore(pond.instance, cells, len(error) / cells,
                     int(np.count_nonzero(np.abs(error) <= LEVEL_TOLERANCE_M)) / cells,
                     float(np.median(error)) if len(error) else math.nan)


def score_ponds(world: Scene, twin: Scene, frame: TwinFrame | None, ponds: Sequence[TruePond],
                pool: Executor | None = None, cell_m: float = CELL_M) -> list[PondScore]:
    """Every pond's :class:`PondScore`: the true ``world`` (with labels) and the ``twin`` seen from above over each
    pond's grid (``frame``: the twin's frame in the world's; None: it is the world's)."""
    if ponds and world.labels is None:
        raise ValueError(f"{world.source}: the true world has no face labels (labels.npz): its ponds cannot be found")
    scores = []
    for pond in ponds:
        grid = Grid.covering(pond.shoreline, cell_m)
        xy, shape = grid.centres(), (grid.rows, grid.cols)
        _, true_hits = from_above(world, xy, pool=pool)
        true_instance = np.where(true_hits.hit, world.labels.face_instance[np.maximum(true_hits.tri, 0)], 0)
        twin_height, _ = from_above(twin, xy, frame and frame.T_world_twin, pool)
        scores.append(score_pond(pond, shape, true_instance, twin_height, cell_m))
    return scores
