"""A pond in the demo world: where it lies, the terrain cut into banks around it, its flat water surface and paint.

The water is a flat, dark, faintly textured surface at a known level ``level_z`` (ENU metres). The terrain is cut so
that the water is seen: inside the shoreline it falls below the level along banks of slope :data:`BANK_SLOPE` down to
a bed ``depth_m`` under the water; outside it rises above the level, so the surface, which reaches
:data:`SURFACE_OVERLAP_M` past the shoreline, ends under the banks (no seam to see). The level is
:data:`FREEBOARD_M` under the lowest natural ground on the shoreline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.worlds.geometry import Part
from sim.worlds.layout import Layout, Tree, WorldSpec, distance_to_polyline
from sim.worlds.noise import HeightField, value_noise
from sim.worlds.shapes import json_point, paint_local_mask, polygon_part

BANK_SLOPE = 0.5
"""Rise (m) per metre of the cut banks, inside and outside the shoreline."""
FREEBOARD_M = 0.3
"""How far (m) the water lies below the lowest natural ground on its shoreline."""
SURFACE_OVERLAP_M = 0.4
"""How far (m) past the shoreline the water surface reaches, under the banks."""
OUTLINE_POINTS = 64
ORIGIN_CLEARANCE_M = 3.0
"""How far (m) the pond's banks keep off the ENU origin."""
#: The water's colour (sRGB) and the bank's (wet mud), painted into the orthophoto.
WATER_RGB, BANK_RGB = np.array([34.0, 46.0, 54.0]), np.array([92.0, 80.0, 60.0])
BANK_WIDTH_M = 1.2
"""Width (m) of the mud painted along the shoreline, outside it."""
WATER_PAINT_MARGIN_M = 0.1
"""The water's paint reaches this far (m) past the shoreline, so no texel of the open water is mud."""


@dataclass(frozen=True)
class Pond:
    """A pond around ENU ``center`` (x, y): its shoreline at ``radius_m * (1 + wobble(angle))`` from the centre,
    the water at ``level_z``, the bed ``depth_m`` under it."""

    center: np.ndarray
    radius_m: float
    wobble: tuple[tuple[float, int, float], ...]  # (relative amplitude, harmonic, phase) terms
    level_z: float
    depth_m: float

    def shore_radius(self, angle: np.ndarray) -> np.ndarray:
        """Distance (m) from the centre to the shoreline in the directions ``angle`` (radians from east)."""
        wobble = sum(amplitude * np.sin(harmonic * angle + phase) for amplitude, harmonic, phase in self.wobble)
        return self.radius_m * (1.0 + wobble)

    def radial_offset(self, x, y) -> np.ndarray:
        """Metres beyond the shoreline (negative inside) of ENU points, along the ray from the centre."""
        dx, dy = np.asarray(x) - self.center[0], np.asarray(y) - self.center[1]
        return np.hypot(dx, dy) - self.shore_radius(np.arctan2(dy, dx))

    def outline(self, offset_m: float = 0.0) -> np.ndarray:
        """(K, 2) ENU points of the shoreline pushed ``offset_m`` outwards, counter-clockwise from above."""
        angle = 2 * np.pi * np.arange(OUTLINE_POINTS) / OUTLINE_POINTS
        radius = self.shore_radius(angle) + offset_m
        return self.center + radius[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)

    @property
    def reach_m(self) -> float:
        """Radius (m) of a circle around the centre holding the pond and its banks."""
        return self.radius_m * (1.0 + sum(abs(a) for a, _, _ in self.wobble)) + self.depth_m / BANK_SLOPE + 1.0


@dataclass(frozen=True)
class PondTerrain:
    """The natural terrain with the pond's basin cut into it: same interface as :class:`HeightField`."""

    natural: HeightField
    pond: Pond

    def height(self, x, y) -> np.ndarray:
        """Ground height (ENU z, metres) at ENU ``x``/``y``: the natural ground, lowered to the banks and the bed."""
        pond = self.pond
        cut = np.maximum(pond.level_z + BANK_SLOPE * pond.radial_offset(x, y), pond.level_z - pond.depth_m)
        return np.minimum(self.natural.height(x, y), cut)


def _clear_of(center: np.ndarray, reach_m: float, layout: Layout) -> bool:
    """Whether a disc of ``reach_m`` around ``center`` stays 2 m off every road, building, forest stand and hedge."""
    margin = reach_m + 2.0
    if any(distance_to_polyline(center[None], r.points)[0] < r.width_m / 2 + margin for r in layout.roads):
        return False
    if any(forest.covers(center[None], margin)[0] for forest in layout.forests):
        return False
    if any(distance_to_polyline(center[None], np.array([h.start, h.end]))[0] < h.width_m / 2 + margin
           for h in layout.hedges):
        return False
    return all(np.linalg.norm(b.center - center) > b.radius_m + margin for b in layout.buildings)


def _trees_inside(center: np.ndarray, reach_m: float, trees: list[Tree]) -> int:
    """How many trees' crowns reach into the disc of ``reach_m`` around ``center``."""
    return sum(np.linalg.norm(t.position - center) < t.radius_m + reach_m for t in trees)


def place_pond(rng: np.random.Generator, layout: Layout, within_m: float, radius_m: tuple[float, float],
               candidates: int = 200) -> Pond:
    """A pond whose centre lies within ``within_m`` of the ENU origin (where the demo flight looks) but whose banks
    keep :data:`ORIGIN_CLEARANCE_M` off it (the orbit's centre), off the roads, buildings, forest stands and hedges,
    of the drawn candidates the one whose banks would swallow the fewest (standalone) trees."""
    wobble = tuple((float(rng.uniform(0.04, 0.12)), harmonic, float(rng.uniform(0, 2 * np.pi)))
                   for harmonic in (2, 3))
    radius, depth = float(rng.uniform(*radius_m)), float(rng.uniform(0.8, 1.5))
    probe = Pond(np.zeros(2), radius, wobble, 0.0, depth)
    best, best_trees = None, np.inf
    for _ in range(candidates):
        distance, angle = within_m * np.sqrt(rng.random()), rng.uniform(0, 2 * np.pi)
        center = distance * np.array([np.cos(angle), np.sin(angle)])
        if distance < probe.reach_m + ORIGIN_CLEARANCE_M:
            continue
        if not _clear_of(center, probe.reach_m, layout):
            continue
        trees = _trees_inside(center, probe.reach_m, layout.trees)
        if trees < best_trees:
            best, best_trees = center, trees
    if best is None:
        raise ValueError(f"no room for a pond of {radius:.1f} m within {within_m:.0f} m of the origin")
    shore = Pond(best, radius, wobble, 0.0, depth).outline()
    level = float(layout.terrain.height(shore[:, 0], shore[:, 1]).min()) - FREEBOARD_M
    return Pond(best, radius, wobble, level, depth)


def trees_clear_of(trees: list[Tree], pond: Pond) -> list[Tree]:
    """The trees whose crowns stay out of the pond and its banks."""
    return [t for t in trees if np.linalg.norm(t.position - pond.center) >= t.radius_m + pond.reach_m]


def water_part(pond: Pond, spec: WorldSpec) -> Part:
    """The water surface: a flat fan at the level out to :data:`SURFACE_OVERLAP_M` past the shoreline, its faces
    upwards, textured with the orthophoto (where :func:`paint_pond` paints it)."""
    outline = pond.outline(SURFACE_OVERLAP_M)
    level = np.full((len(outline), 1), pond.level_z)
    return polygon_part(np.array([*pond.center, pond.level_z]), np.hstack([outline, level]), spec)


def paint_pond(rng: np.random.Generator, image: np.ndarray, pond: Pond, spec: WorldSpec) -> None:
    """Paint the water (dark, with faint ripples of ~1 m) and a band of mud along the shoreline into the
    orthophoto, in place."""
    reach = pond.reach_m + BANK_WIDTH_M

    def paint(along, across, pixels):
        offset = pond.radial_offset(pond.center[0] + along, pond.center[1] + across)
        ripples = 1.0 + 0.04 * value_noise(rng, along.shape, 1.0 / spec.texel_m)
        pixels[offset < BANK_WIDTH_M] = BANK_RGB * rng.uniform(0.95, 1.05)
        water = offset < WATER_PAINT_MARGIN_M
        pixels[water] = (WATER_RGB * ripples[..., None])[water]

    paint_local_mask(image, spec, pond.center, 0.0, reach, paint)


def pond_truth(pond: Pond) -> dict:
    """The pond's centre, water level, radius, depth and shoreline (ENU metres)."""
    return {"center_m": json_point(pond.center), "level_z_m": round(pond.level_z, 4),
            "radius_m": round(pond.radius_m, 4), "depth_m": round(pond.depth_m, 4),
            "shoreline_m": [json_point(p) for p in pond.outline()]}
