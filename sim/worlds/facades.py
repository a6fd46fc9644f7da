"""Paint the building facades into their atlas slots: plaster with stains, a plinth, storeys of framed windows
with varied glass, curtains and shutters, and a door.

Every wall gets its own pixels, so no two walls look alike. Images are float32 RGB in 0-255.
"""

from __future__ import annotations

import cv2
import numpy as np

from sim.worlds.atlas import FACADE_ROW_PX, FacadeAtlas
from sim.worlds.layout import Building
from sim.worlds.noise import value_noise

WINDOW_WIDTH_M = 1.2
WINDOW_SILL_M, WINDOW_TOP_M = 0.9, 2.3  # above each storey's floor
FRAME_M = 0.1
GLASS_COLOURS = np.array([(48, 58, 70), (70, 84, 96), (30, 34, 40), (120, 130, 138), (200, 190, 160),
                          (90, 60, 40), (40, 90, 70)], dtype=np.float64)


def _plaster(rng: np.random.Generator, shape: tuple[int, int], colour, cell_px: float) -> np.ndarray:
    """Plaster of ``colour`` with blotches and vertical rain stains, (rows, cols, 3)."""
    blotches = value_noise(rng, shape, cell_px * 6) * 0.06 + value_noise(rng, shape, 1.0) * 0.03
    streak_rows = max(shape[0] // 8, 2)
    streaks = cv2.resize(value_noise(rng, (streak_rows, shape[1]), 2.0), (shape[1], shape[0]),
                         interpolation=cv2.INTER_LINEAR) * 0.05
    return np.asarray(colour, np.float32) * (1.0 + blotches + streaks)[..., None]


def _windows(rng: np.random.Generator, building: Building, along: np.ndarray, z: np.ndarray,
             length_m: float, image: np.ndarray, door: bool) -> None:
    """Storeys of framed windows (and a door on the ground floor when ``door``), in place."""
    spacing = rng.uniform(2.6, 3.6)
    count = int((length_m - 1.0) // spacing)
    if count < 1:
        return
    first = (length_m - (count - 1) * spacing) / 2
    index = np.clip(np.round((along - first) / spacing), 0, count - 1)
    offset = along - (first + index * spacing)
    height = z - building.floor_z
    storey = np.floor(height / 3.0)
    in_storey = height - 3.0 * storey
    window = (np.abs(offset) < WINDOW_WIDTH_M / 2) & (in_storey > WINDOW_SILL_M) & (in_storey < WINDOW_TOP_M)
    window &= (storey >= 0) & (storey < building.floors)
    door_index = count // 2 if door else -1
    door_pixels = (index == door_index) & (np.abs(offset) < 0.55) & (height > 0.0) & (height < 2.2)
    window &= ~((index == door_index) & (storey == 0))
    frame = window & ((np.abs(offset) > WINDOW_WIDTH_M / 2 - FRAME_M) | (in_storey < WINDOW_SILL_M + FRAME_M)
                      | (in_storey > WINDOW_TOP_M - FRAME_M) | (np.abs(offset) < FRAME_M / 2)
                      | (np.abs(in_storey - 1.75) < FRAME_M / 2))
    glass_kind = rng.integers(len(GLASS_COLOURS), size=(building.floors, count))
    storey_index = np.clip(storey, 0, building.floors - 1).astype(int)
    glass = GLASS_COLOURS[glass_kind[storey_index, index.astype(int)]]
    glass = glass * (1.0 + 0.25 * (in_storey - WINDOW_SILL_M) / (WINDOW_TOP_M - WINDOW_SILL_M))[..., None]
    image[window] = glass[window]
    image[frame] = (236, 236, 230)
    image[door_pixels] = np.array((96, 62, 40)) * rng.uniform(0.7, 1.3)


def paint_facades(rng: np.random.Generator, facades: FacadeAtlas, buildings: list[Building],
                  atlas: np.ndarray) -> None:
    """Paint every wall into its slot of the (texture_px, texture_px, 3) float32 ``atlas``, in place."""
    for wall_index, (wall, slot) in enumerate(zip(facades.walls, facades.slots, strict=True)):
        building = buildings[wall.building_index]
        cols = np.arange(slot.width_px) + 0.5
        rows = np.arange(FACADE_ROW_PX) + 0.5
        along = cols[None, :] * facades.metres_per_px_u
        z = wall.base_z + (FACADE_ROW_PX - rows[:, None]) * facades.metres_per_px_v
        along, z = np.broadcast_arrays(along, z)
        image = _plaster(rng, along.shape, building.plaster_rgb, 0.5 / facades.metres_per_px_u)
        plinth = z < building.floor_z + 0.5
        image[plinth] *= 0.62
        cornice = np.abs(z - (building.eave_z - 0.25)) < 0.15
        image[cornice] = np.array(building.plaster_rgb) * 0.8
        _windows(rng, building, along, z, wall.length_m, image, door=wall_index % 4 == 0)
        atlas[slot.row_top:slot.row_top + FACADE_ROW_PX, slot.col0:slot.col0 + slot.width_px] = image
