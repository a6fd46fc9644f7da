"""The one texture atlas of the demo world: where each surface's texels live.

The atlas is ``texture_px`` square. Its top ``ortho_rows`` rows are an orthophoto of the ground rectangle (north
up): the terrain and the roofs are textured by straight-down projection of their ENU x/y. The rows below are strips
of building facades, each wall getting its own unique piece (no repeated tiles, which would confuse feature
matching), left of a column of vegetation patches: leaves, needles and bark, one square each, which every tree and
hedge samples at its own offsets (sim/worlds/vegetation.py).

UV convention (OBJ/glTF-as-trimesh): u = column / width, v = 1 - row / height, with (0, 0) the bottom-left corner
of the image and pixel ``(row, col)`` covering ``[row, row + 1) x [col, col + 1)`` in continuous coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.worlds.layout import Building, WorldSpec

FACADE_ROW_PX = 192
"""Height in texels of one strip of facades."""
FACADE_GAP_PX = 4
"""Empty texels between two walls in a strip, so bilinear lookups never bleed between walls."""
VEGETATION_PATCH_PX = 128
"""Side in texels of each vegetation patch."""
VEGETATION_PATCHES = ("leaves", "needles", "bark")
"""The vegetation patches, stacked in this order from the top of the facade rows in the atlas's rightmost
``VEGETATION_PATCH_PX`` columns."""
PATCH_MARGIN_PX = 2
"""Texels along each patch's edge that no UV reaches, so bilinear lookups never bleed into a neighbour."""


def ortho_pixels(xy: np.ndarray, spec: WorldSpec) -> np.ndarray:
    """Continuous orthophoto pixel coordinates (col, row) of ENU points ``xy`` (..., 2)."""
    half_x, half_y = spec.half_extent_m
    col = (xy[..., 0] + half_x) / spec.texel_m
    row = (half_y - xy[..., 1]) / spec.texel_m
    return np.stack([col, row], -1)


def pixels_to_uv(col_row: np.ndarray, spec: WorldSpec) -> np.ndarray:
    """Atlas UVs of continuous pixel coordinates (col, row)."""
    return np.stack([col_row[..., 0] / spec.texture_px, 1.0 - col_row[..., 1] / spec.texture_px], -1)


def ortho_uv(xy: np.ndarray, spec: WorldSpec) -> np.ndarray:
    """Atlas UVs of the straight-down projection of ENU points ``xy`` (..., 2)."""
    return pixels_to_uv(ortho_pixels(xy, spec), spec)


def vegetation_patch_origin(spec: WorldSpec, name: str) -> tuple[int, int]:
    """Atlas pixel (column, row) of the top-left corner of the vegetation patch ``name``."""
    return spec.texture_px - VEGETATION_PATCH_PX, spec.ortho_rows + VEGETATION_PATCHES.index(name) * VEGETATION_PATCH_PX


def vegetation_patch_uv(spec: WorldSpec, name: str, st: np.ndarray) -> np.ndarray:
    """Atlas UVs of patch coordinates ``st`` (..., 2) in [0, 1] (s rightwards, t downwards) of the patch ``name``,
    squeezed ``PATCH_MARGIN_PX`` inside its edges."""
    col0, row0 = vegetation_patch_origin(spec, name)
    span = VEGETATION_PATCH_PX - 2 * PATCH_MARGIN_PX
    col_row = np.array([col0, row0], np.float64) + PATCH_MARGIN_PX + np.clip(st, 0.0, 1.0) * span
    return pixels_to_uv(col_row, spec)


@dataclass(frozen=True)
class Wall:
    """One outer wall: the footprint edge ``start -> end`` (ENU x/y, building outside on its right) from
    ``base_z`` up to ``eave_z``, with a gable triangle up to ``apex_z`` at mid-edge when ``apex_z > eave_z``."""

    building_index: int
    start: np.ndarray
    end: np.ndarray
    base_z: float
    eave_z: float
    apex_z: float

    @property
    def length_m(self) -> float:
        """Length of the wall along the ground in metres."""
        return float(np.linalg.norm(self.end - self.start))


def building_walls(buildings: list[Building]) -> list[Wall]:
    """The four walls of every building; the two short ends carry the gable triangles of gable roofs."""
    walls = []
    for index, building in enumerate(buildings):
        corners = building.corners
        for edge in range(4):
            gable_end = edge % 2 == 1  # edges 1 and 3 cross the ridge
            walls.append(Wall(index, corners[edge], corners[(edge + 1) % 4], building.base_z, building.eave_z,
                              building.ridge_z if gable_end else building.eave_z))
    return walls


@dataclass(frozen=True)
class FacadeSlot:
    """Where one wall lives in the facade strips: pixel column range and the strip's top row."""

    col0: int
    width_px: int
    row_top: int


@dataclass(frozen=True)
class FacadeAtlas:
    """Facade placement: one slot per wall, and the metres per texel along (u) and up (v) the walls."""

    spec: WorldSpec
    walls: list[Wall]
    slots: list[FacadeSlot]
    metres_per_px_u: float
    metres_per_px_v: float

    def pixels(self, wall_index: int, along_m: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Continuous atlas pixel (col, row) of the point ``along_m`` metres from the wall start at height ``z``."""
        wall, slot = self.walls[wall_index], self.slots[wall_index]
        col = slot.col0 + np.asarray(along_m) / self.metres_per_px_u
        row = slot.row_top + FACADE_ROW_PX - (np.asarray(z) - wall.base_z) / self.metres_per_px_v
        return np.stack(np.broadcast_arrays(col, row), -1)

    def uv(self, wall_index: int, along_m: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Atlas UVs of points on a wall (see ``pixels``)."""
        return pixels_to_uv(self.pixels(wall_index, along_m, z), self.spec)


def _pack(lengths_m: np.ndarray, metres_per_px: float, strips: int, strip_width: int) -> list[FacadeSlot] | None:
    """Greedy left-to-right packing of walls into strips (``row_top`` holds the strip index), or None when they
    do not fit."""
    slots, strip, col = [], 0, FACADE_GAP_PX
    for length in lengths_m:
        width = int(np.ceil(length / metres_per_px)) + 1
        if col + width + FACADE_GAP_PX > strip_width:
            strip, col = strip + 1, FACADE_GAP_PX
            if strip >= strips:
                return None
        slots.append(FacadeSlot(col, width, strip))
        col += width + FACADE_GAP_PX
    return slots


def allocate_facades(buildings: list[Building], spec: WorldSpec) -> FacadeAtlas:
    """Give every wall its own piece of the facade strips (left of the vegetation patches) at the finest common
    texel size that fits."""
    walls = building_walls(buildings)
    strips = (spec.texture_px - spec.ortho_rows) // FACADE_ROW_PX
    if strips < 1 or spec.texture_px - spec.ortho_rows < len(VEGETATION_PATCHES) * VEGETATION_PATCH_PX:
        raise ValueError(f"no room for facades and vegetation patches: texture {spec.texture_px} px, orthophoto "
                         f"{spec.ortho_rows} rows")
    strip_width = spec.texture_px - VEGETATION_PATCH_PX
    tallest = max((w.apex_z - w.base_z for w in walls), default=1.0)
    lengths = np.array([w.length_m for w in walls])
    usable = strips * (strip_width - FACADE_GAP_PX * (len(walls) // strips + 2))
    metres_per_px = max(float(lengths.sum()) / max(usable, 1), 1e-3)
    while (packed := _pack(lengths, metres_per_px, strips, strip_width)) is None:
        metres_per_px *= 1.03
    slots = [FacadeSlot(s.col0, s.width_px, spec.ortho_rows + s.row_top * FACADE_ROW_PX) for s in packed]
    return FacadeAtlas(spec, walls, slots, metres_per_px, (tallest + 0.5) / FACADE_ROW_PX)
