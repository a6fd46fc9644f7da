"""Chimneys and dormers on the demo world's roofs: where they stand, their solids and their paint.

Building-local coordinates as in :class:`~sim.worlds.layout.Building`: ``along`` the ridge and ``across`` it, metres
from the footprint's centre. A chimney is a brick box of 0.6-1.0 m square standing 1-2 m above the roof where it
stands, sunk into the roof below. A dormer is a flat-roofed box on a gable roof's slope: a front wall 1.2-1.5 m high
0.9 m in from the eaves, two triangular cheeks, a flat roof back to where it meets the slope; its walls wear the
building's own facade (the top storey's windows), its roof the building's tiles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.worlds.atlas import FacadeAtlas
from sim.worlds.geometry import Part
from sim.worlds.layout import Building, WorldSpec
from sim.worlds.shapes import box_part, json_point, paint_local_mask, quad_part, swatch_uv

BRICK_COLOURS = [(150, 70, 52), (128, 60, 48), (170, 150, 130), (110, 104, 100)]
#: Chimney top: brick rim around a dark flue of this share of the chimney's size.
FLUE_SHARE = 0.4
CHIMNEY_SINK_M = 0.1
"""How far (m) a chimney reaches below the lowest roof point under it."""
DORMER_FROM_EAVES_M = 0.9
DORMER_OVERHANG_M = 0.15
"""How far (m) a dormer's flat roof reaches past its front wall."""


@dataclass(frozen=True)
class Chimney:
    """A chimney on building ``building_index``: square of ``size_m`` on ENU ``center``, from ``base_z`` (inside the
    roof) up to ``top_z``, 1-2 m above ``roof_z``, the highest point of the roof under it."""

    building_index: int
    center: np.ndarray  # ENU x, y
    heading_rad: float
    size_m: float
    base_z: float
    top_z: float
    roof_z: float
    rgb: tuple[int, int, int]


@dataclass(frozen=True)
class Dormer:
    """A dormer on building ``building_index``, on the slope towards ``side`` (+1: +across, -1: -across),
    ``width_m`` wide around ``along`` (local metres); its front wall at ``front_across`` (local, unsigned) from
    ``front_z`` (the roof there) up to ``top_z``, its flat roof back to ``back_across`` where the slope reaches
    ``top_z``."""

    building_index: int
    side: int
    along: float
    width_m: float
    front_across: float
    back_across: float
    front_z: float
    top_z: float


def roof_height(building: Building, across_m) -> np.ndarray:
    """Height (ENU z) of the building's roof at local ``across_m`` metres from the ridge line."""
    slope = (building.ridge_z - building.eave_z) / (building.width_m / 2)
    return building.ridge_z - slope * np.abs(across_m)


def _to_enu(building: Building, along, across) -> np.ndarray:
    """ENU (x, y) of building-local points (arrays that broadcast), stacked on the last axis."""
    axis_along, axis_across = building.axes
    return (building.center + np.asarray(along)[..., None] * axis_along
            + np.asarray(across)[..., None] * axis_across)


def place_dormer(rng: np.random.Generator, index: int, building: Building) -> Dormer | None:
    """A dormer on a random slope of a gable roof, or None when the roof is too small or too flat for one."""
    if not building.gable:
        return None
    width, height = rng.uniform(1.8, 2.4), rng.uniform(1.2, 1.5)
    front = building.width_m / 2 - DORMER_FROM_EAVES_M
    front_z = float(roof_height(building, front))
    top_z = front_z + height
    slope = (building.ridge_z - building.eave_z) / (building.width_m / 2)
    back = (building.ridge_z - top_z) / slope
    room = building.length_m / 2 - width / 2 - 1.0
    if back < 0.4 or front - back < 0.8 or room < 0:
        return None
    return Dormer(index, int(rng.choice([-1, 1])), float(rng.uniform(-room, room)), float(width), float(front),
                  float(back), front_z, float(top_z))


def place_chimney(rng: np.random.Generator, index: int, building: Building, dormer: Dormer | None) -> Chimney | None:
    """A chimney somewhere on the roof clear of the dormer, or None when none of a few tries fits."""
    size = float(rng.uniform(0.6, 1.0))
    rise = float(rng.uniform(1.0, 2.0))
    rgb = BRICK_COLOURS[rng.integers(len(BRICK_COLOURS))]
    along_room, across_room = building.length_m / 2 - 1.2, building.width_m / 2 - 1.5
    for _ in range(10):
        along = rng.uniform(-along_room, along_room)
        across = 0.0 if building.gable and rng.random() < 0.5 else rng.uniform(-across_room, across_room)
        if dormer is not None and abs(along - dormer.along) < (dormer.width_m + size) / 2 + 0.3:
            continue
        nearest_ridge, farthest = max(abs(across) - size / 2, 0.0), abs(across) + size / 2
        roof_top, roof_low = (roof_height(building, np.array([nearest_ridge, farthest])) if building.gable
                              else (building.eave_z, building.eave_z))
        center = _to_enu(building, along, across)
        return Chimney(index, center, building.heading_rad, size, float(roof_low) - CHIMNEY_SINK_M,
                       float(roof_top) + rise, float(roof_top), rgb)
    return None


def chimney_part(chimney: Chimney, spec: WorldSpec) -> Part:
    """The chimney's box: brick sides (one texel of its painted rim), its top seen from above (rim and flue)."""
    return box_part(chimney.center, chimney.heading_rad, chimney.size_m, chimney.size_m, chimney.base_z,
                    chimney.top_z, spec, side_uv=swatch_uv(_rim_point(chimney), spec))


def _rim_point(chimney: Chimney) -> np.ndarray:
    """A point of the chimney's brick rim, halfway between flue and edge, whose texel colours its sides."""
    along = np.array([np.cos(chimney.heading_rad), np.sin(chimney.heading_rad)])
    return chimney.center + along * chimney.size_m * (0.5 + FLUE_SHARE / 2) / 2


def paint_chimney(image: np.ndarray, chimney: Chimney, spec: WorldSpec) -> None:
    """The chimney seen from above, in place: a brick square with a dark flue in its middle."""

    def paint(along, across, pixels):
        reach = np.maximum(np.abs(along), np.abs(across))
        pixels[reach < chimney.size_m / 2] = chimney.rgb
        pixels[reach < FLUE_SHARE * chimney.size_m / 2] = (28, 24, 22)

    paint_local_mask(image, spec, chimney.center, chimney.heading_rad, chimney.size_m, paint)


def dormer_part(dormer: Dormer, building: Building, facades: FacadeAtlas, spec: WorldSpec) -> tuple[Part, Part]:
    """The dormer's walls (front and cheeks, textured with the facade of the building's wall on that side, the top
    storey's band) and its flat roof (the orthophoto's tiles), as (walls, roof)."""
    s = dormer.side
    half = dormer.width_m / 2
    sink = dormer.front_z - 0.05
    front = [(dormer.along + half * s, dormer.front_across, sink), (dormer.along - half * s, dormer.front_across, sink),
             (dormer.along - half * s, dormer.front_across, dormer.top_z),
             (dormer.along + half * s, dormer.front_across, dormer.top_z)]
    cheeks = []
    for end in (-1, 1):  # each cheek counter-clockwise seen from outside (its end of the dormer)
        a = dormer.along + end * half
        triangle = [(a, dormer.front_across, sink), (a, dormer.back_across, dormer.top_z),
                    (a, dormer.front_across, dormer.top_z)]
        cheeks.append(triangle if end * s < 0 else triangle[::-1])
    local = np.array(front + cheeks[0] + cheeks[1], np.float64)
    xyz = np.column_stack([_to_enu(building, local[:, 0], s * local[:, 1]), local[:, 2]])
    wall_index = _wall_on_side(facades, dormer)
    wall = facades.walls[wall_index]
    along_wall = (xyz[:, :2] - wall.start) @ ((wall.end - wall.start) / wall.length_m)
    along_wall[4:] = 0.2 + np.abs(local[4:, 1] - dormer.front_across) + np.repeat([0.0, 2.5], 3)
    storey_z = building.floor_z + 3.0 * (building.floors - 1) + 0.7 + (local[:, 2] - sink)
    walls = Part(xyz, np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [7, 8, 9]]),
                 facades.uv(wall_index, along_wall, storey_z))
    back = dormer.back_across - 0.2  # under the slope, which is higher there
    low, high = sorted((s * back, s * (dormer.front_across + DORMER_OVERHANG_M)))
    corners = _to_enu(building, dormer.along + np.array([-half, half, half, -half]), np.array([low, low, high, high]))
    return walls, quad_part(np.column_stack([corners, np.full(4, dormer.top_z)]), spec, None)


def _wall_on_side(facades: FacadeAtlas, dormer: Dormer) -> int:
    """Index of the building's long wall on the dormer's side: edge 2 (+across) or edge 0 (-across)."""
    return 4 * dormer.building_index + (2 if dormer.side > 0 else 0)


def dormer_truth(dormer: Dormer, building: Building) -> dict:
    """JSON-ready truth of a dormer: its front wall's middle (ENU) and top height."""
    return {"position_m": json_point(_to_enu(building, dormer.along, dormer.side * dormer.front_across)),
            "width_m": round(dormer.width_m, 4), "front_z_m": round(dormer.front_z, 4),
            "top_z_m": round(dormer.top_z, 4)}


def chimney_truth(chimney: Chimney) -> dict:
    """JSON-ready truth of a chimney: its building's object, centre (ENU), heading (its sides along and across the
    ridge), size, top, the highest roof point under it."""
    return {"building_instance": chimney.building_index + 1, "position_m": json_point(chimney.center),
            "heading_deg": round(float(np.degrees(chimney.heading_rad)), 3), "size_m": round(chimney.size_m, 4),
            "top_z_m": round(chimney.top_z, 4), "roof_z_m": round(chimney.roof_z, 4),
            "height_above_roof_m": round(chimney.top_z - chimney.roof_z, 4)}
