"""What covers the demo world's ground, as surface classes (sim/render/classes.py): the orthophoto's layers, kept
by the painter (sim/worlds/orthophoto.py) so that the labels of the terrain faces say what their texture shows.

The painter lays, in this order: crop fields everywhere (hedges between the parcels), the village lawn over them,
small shapes, a yard around every building, the roads; then the roofs, which texture the buildings' own meshes
(trees and hedges are meshes with texture patches of their own: sim/worlds/vegetation.py). So a ground point is a
``road`` on a road (asphalt or dirt track), else ``ground`` on a yard or where the lawn outweighs the fields in the
painter's blend, else ``field``. Hedge strips (0.8 m strips painted flat between parcels, no height; the 3-D hedges
are meshes) are the fields' margins: ``field``. The shapes (bushes, stones, soil patches, flowers of
0.25-1.5 m, painted flat) are clutter on whatever they lie on: they change no class. Ground under a roof is the
building's yard (``ground``, never seen); ground under a crown keeps the class of its cover.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.render.classes import FIELD, GROUND, ROAD
from sim.worlds.atlas import ortho_pixels
from sim.worlds.layout import Building, Road, WorldSpec

LAWN_MIN_WEIGHT = 0.5
"""The lawn covers the texels where its weight in the painter's lawn/field blend is at least this."""


@dataclass(frozen=True)
class Yard:
    """The paved apron the painter lays around ``building``: its footprint grown by ``margin_m`` on every side."""

    building: Building
    margin_m: float

    def covers(self, xy: np.ndarray) -> np.ndarray:
        """Whether each ENU point of ``xy`` (M, 2) lies on the yard (the footprint included)."""
        return self.building.covers_local(*self.building.local(xy[:, 0], xy[:, 1]), self.margin_m)


@dataclass(frozen=True)
class GroundCover:
    """The painted ground cover: ``lawn`` (ortho_rows, texture_px) bool, the orthophoto texels the village lawn
    covers; the ``yards`` and ``roads`` as painted, in painting order."""

    spec: WorldSpec
    lawn: np.ndarray
    yards: tuple[Yard, ...]
    roads: tuple[Road, ...]

    def lawn_at(self, xy: np.ndarray) -> np.ndarray:
        """Whether the texel holding each ENU point of ``xy`` (M, 2) is lawn."""
        col, row = np.floor(ortho_pixels(xy, self.spec)).astype(np.int64).T
        return self.lawn[np.clip(row, 0, self.spec.ortho_rows - 1), np.clip(col, 0, self.spec.texture_px - 1)]

    def classify(self, xy: np.ndarray) -> np.ndarray:
        """uint8 class ids (``field``, ``ground`` or ``road``) of the ENU points ``xy`` (M, 2) on the ground, the
        later layers of the painting over the earlier ones."""
        classes = np.full(len(xy), FIELD, np.uint8)
        classes[self.lawn_at(xy)] = GROUND
        for yard in self.yards:
            classes[yard.covers(xy)] = GROUND
        for road in self.roads:
            classes[road.covers(xy)] = ROAD
        return classes
