"""Where things are in the demo world: size, roads, buildings, trees, a forest stand and hedges, in ENU metres (x east,
y north).

Pure functions of a ``WorldSpec`` and a ``numpy.random.Generator``; no geometry or pixels here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scipy.spatial import cKDTree

from sim.worlds.noise import HeightField


@dataclass(frozen=True)
class WorldSpec:
    """Size and budgets of one variant of the demo world.

    The ground covers ``[-size_x_m/2, size_x_m/2] x [-size_y_m/2, size_y_m/2]`` (ENU metres); the top
    ``ortho_rows`` rows of the square ``texture_px`` atlas are an orthophoto of exactly that rectangle, the rows
    below hold the building facades (and the vegetation's texture patches, sim/worlds/atlas.py). ``tree_count``
    standalone trees are tried (alleys, groves, singles; ~90 % find room), plus one forest stand of
    ``forest_size_m`` (length, width) and ``hedge_count`` hedges.
    """

    size_x_m: float
    texture_px: int
    ortho_rows: int
    grid_step_m: float
    building_count: int
    tree_count: int
    forest_size_m: tuple[float, float]
    hedge_count: int
    relief_m: float = 5.0

    @property
    def texel_m(self) -> float:
        """Orthophoto texel size in metres (square texels)."""
        return self.size_x_m / self.texture_px

    @property
    def size_y_m(self) -> float:
        """North-south extent of the ground in metres."""
        return self.ortho_rows * self.texel_m

    @property
    def half_extent_m(self) -> tuple[float, float]:
        """Half sizes (x, y) of the ground rectangle in metres."""
        return self.size_x_m / 2.0, self.size_y_m / 2.0


VARIANTS: dict[str, WorldSpec] = {
    # 384 m x 312 m, 9.4 cm texels, a 1 m terrain grid (the hills are smooth), ~0.45 M triangles (generator 10).
    "default": WorldSpec(size_x_m=384.0, texture_px=4096, ortho_rows=3328, grid_step_m=1.0,
                         building_count=45, tree_count=600, forest_size_m=(52.0, 40.0), hedge_count=10),
    # 192 m x 156 m, same texel size and grid, ~93 k triangles: for tests.
    "small": WorldSpec(size_x_m=192.0, texture_px=2048, ortho_rows=1664, grid_step_m=1.0,
                       building_count=12, tree_count=60, forest_size_m=(24.0, 18.0), hedge_count=3),
    # 480 m x 324 m = 155,520 m^2 (the paper's 153,000 m^2), same texel size and grid; buildings and trees scaled
    # with the area (facade strips: 8 x 5120 texels). ~0.58 M triangles: for area plans (issue 21).
    "large": WorldSpec(size_x_m=480.0, texture_px=5120, ortho_rows=3456, grid_step_m=1.0,
                       building_count=56, tree_count=720, forest_size_m=(60.0, 44.0), hedge_count=12),
}
"""Variants by name; the order is part of each variant's random streams (sim/worlds/demo.py), so append only."""


@dataclass(frozen=True)
class Road:
    """A road centreline (N, 2) ENU metres, its full width and its surface (``"asphalt"`` or ``"dirt"``)."""

    points: np.ndarray
    width_m: float
    surface: str

    def covers(self, xy: np.ndarray) -> np.ndarray:
        """Whether each ENU point of ``xy`` (M, 2) lies on the road: within ``width_m / 2`` of its centreline, the
        band the orthophoto paints it in (sim/worlds/orthophoto.py)."""
        return near_polyline(xy, self.points, self.width_m / 2)


@dataclass(frozen=True)
class Building:
    """A box building on a rectangular footprint, optionally with a gable roof whose ridge runs along ``length``.

    ``corners`` (4, 2) ENU metres counter-clockwise seen from above, starting at the local (-length/2, -width/2)
    corner; ``base_z`` is below the ground everywhere under the footprint, ``eave_z`` the top of the walls,
    ``ridge_z`` the roof ridge (equal to ``eave_z`` for a flat roof); storeys are 3 m high and the ground floor is at
    ``floor_z``.
    """

    center: np.ndarray
    heading_rad: float
    length_m: float
    width_m: float
    base_z: float
    eave_z: float
    ridge_z: float
    floors: int
    plaster_rgb: tuple[int, int, int]
    roof_rgb: tuple[int, int, int]

    @property
    def gable(self) -> bool:
        """True when the building has a gable roof."""
        return self.ridge_z > self.eave_z

    @property
    def floor_z(self) -> float:
        """Height (ENU z) of the ground floor: the storeys fill the walls below the eaves."""
        return self.eave_z - 3.0 * self.floors - 0.3

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors along the ridge (length) and across it (width), ENU x/y."""
        along = np.array([np.cos(self.heading_rad), np.sin(self.heading_rad)])
        return along, np.array([-along[1], along[0]])

    @property
    def corners(self) -> np.ndarray:
        """Footprint corners (4, 2), counter-clockwise from above."""
        return rectangle(self.center, self.heading_rad, self.length_m, self.width_m)

    def local(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Building-local coordinates (metres from the centre along the ridge, and across it) of the ENU points
        ``x``, ``y`` (arrays that broadcast)."""
        along, across = self.axes
        x, y = x - self.center[0], y - self.center[1]
        return x * along[0] + y * along[1], x * across[0] + y * across[1]

    def covers_local(self, along_m: np.ndarray, across_m: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """Whether building-local points (see :meth:`local`) lie on the footprint grown by ``margin_m`` on every
        side."""
        return (np.abs(along_m) < self.length_m / 2 + margin_m) & (np.abs(across_m) < self.width_m / 2 + margin_m)

    @property
    def radius_m(self) -> float:
        """Radius of the footprint's bounding circle."""
        return 0.5 * float(np.hypot(self.length_m, self.width_m))


@dataclass(frozen=True)
class Tree:
    """A tree whose stem stands at ``position`` (ENU x, y) on ground height ``ground_z``: a conifer in whorls or a
    broadleaf tree, its crown within ``radius_m`` of the stem and at most ``height_m`` above the ground
    (sim/worlds/vegetation.py builds it); ``forest`` when it belongs to the forest stand."""

    position: np.ndarray
    ground_z: float
    radius_m: float
    height_m: float
    conifer: bool
    forest: bool = False


@dataclass(frozen=True)
class ForestStand:
    """A closed stand of trees on the rectangle ``corners`` (4, 2) ENU metres (counter-clockwise from above): its
    trees stand inside it with their crowns within it, so its outline is the forest's edge."""

    corners: np.ndarray

    def covers(self, xy: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """Whether each ENU point of ``xy`` (M, 2) lies inside the rectangle grown by ``margin_m`` on every side."""
        edges = np.roll(self.corners, -1, axis=0) - self.corners
        edges /= np.linalg.norm(edges, axis=1, keepdims=True)
        rel = xy[:, None, :] - self.corners[None]
        left = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]  # metres inside each edge
        return np.all(left >= -margin_m, axis=1)


@dataclass(frozen=True)
class Hedge:
    """A straight hedge from ``start`` to ``end`` (ENU x, y) along the ground, ``width_m`` thick and ``height_m``
    high above the ground under it."""

    start: np.ndarray
    end: np.ndarray
    width_m: float
    height_m: float

    def points(self, step_m: float = 1.0) -> np.ndarray:
        """Points (M, 2) every ``step_m`` metres or less along the hedge's centreline, both ends included."""
        count = int(np.ceil(np.linalg.norm(self.end - self.start) / step_m)) + 1
        return self.start + np.linspace(0.0, 1.0, count)[:, None] * (self.end - self.start)


@dataclass(frozen=True)
class Layout:
    """Everything placed in one world."""

    spec: WorldSpec
    terrain: HeightField
    roads: list[Road]
    buildings: list[Building]
    trees: list[Tree]
    village_center: np.ndarray
    forests: list[ForestStand]
    hedges: list[Hedge]


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Euclidean distance (metres) from each of ``points`` (M, 2) to the polyline (N, 2)."""
    starts, ends = polyline[:-1], polyline[1:]
    seg = ends - starts
    rel = points[:, None, :] - starts[None]
    t = np.clip((rel * seg).sum(-1) / np.maximum((seg * seg).sum(-1), 1e-12), 0.0, 1.0)
    closest = starts[None] + t[..., None] * seg[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=-1).min(axis=1)


def near_polyline(points: np.ndarray, polyline: np.ndarray, radius_m: float) -> np.ndarray:
    """Whether each of ``points`` (M, 2) lies within ``radius_m`` metres of the polyline (N, 2); for many points
    (a k-d tree finds each segment's candidates, :func:`distance_to_polyline` decides)."""
    near = np.zeros(len(points), bool)
    starts, ends = polyline[:-1], polyline[1:]
    reach = np.linalg.norm(ends - starts, axis=1) / 2 + radius_m
    for start, end, candidates in zip(starts, ends, cKDTree(points).query_ball_point((starts + ends) / 2, reach),
                                      strict=True):
        candidates = np.asarray(candidates, dtype=np.int64)
        near[candidates] |= distance_to_polyline(points[candidates], np.array([start, end])) <= radius_m
    return near


def _curved_road(rng: np.random.Generator, spec: WorldSpec, north_south: bool, offset_m: float,
                 width_m: float, surface: str) -> Road:
    """A gently meandering road crossing the whole world east-west (or north-south), at ``offset_m`` from 0."""
    half = max(spec.half_extent_m) + 20.0
    s = np.arange(-half, half + 1e-9, 2.0)
    wavelength = rng.uniform(250.0, 450.0)
    lateral = offset_m + rng.uniform(4.0, 9.0) * np.sin(2 * np.pi * s / wavelength + rng.uniform(0, 2 * np.pi))
    points = np.stack([lateral, s], 1) if north_south else np.stack([s, lateral], 1)
    return Road(points, width_m, surface)


def _straight_track(rng: np.random.Generator, spec: WorldSpec, avoid_center: np.ndarray, avoid_m: float) -> Road:
    """A straight dirt track across the fields, passing at least ``avoid_m`` from the village centre."""
    half_x, half_y = spec.half_extent_m
    while True:
        angle = rng.uniform(0.0, np.pi)
        through = rng.uniform([-half_x, -half_y], [half_x, half_y])
        direction = np.array([np.cos(angle), np.sin(angle)])
        s = np.arange(-1.5 * max(half_x, half_y), 1.5 * max(half_x, half_y), 4.0)
        points = through + s[:, None] * direction
        if distance_to_polyline(avoid_center[None], points)[0] > avoid_m:
            return Road(points, 3.0, "dirt")


def _inside(points: np.ndarray, spec: WorldSpec, margin_m: float) -> bool:
    half_x, half_y = spec.half_extent_m
    return bool(np.all(np.abs(points[:, 0]) <= half_x - margin_m) and np.all(np.abs(points[:, 1]) <= half_y - margin_m))


def _clear_of_roads(points: np.ndarray, roads: list[Road], clearance_m: float) -> bool:
    return all(np.all(distance_to_polyline(points, r.points) > r.width_m / 2 + clearance_m) for r in roads)


PLASTER_COLOURS = [(222, 206, 176), (236, 232, 220), (204, 160, 96), (214, 170, 150), (168, 166, 160),
                   (160, 82, 60), (196, 200, 176), (230, 214, 140)]
ROOF_COLOURS = [(150, 62, 44), (120, 52, 40), (96, 96, 100), (70, 76, 84), (176, 96, 60), (132, 120, 108)]


def _random_building(rng: np.random.Generator, terrain: HeightField, center: np.ndarray,
                     heading: float) -> Building:
    length = rng.uniform(8.0, 18.0)
    width = rng.uniform(6.0, min(12.0, length))
    floors = int(rng.choice([1, 1, 2, 2, 2, 3, 4]))
    probe = Building(center, heading, length, width, 0.0, 0.0, 0.0, 1, (0, 0, 0), (0, 0, 0))
    ground = terrain.height(*np.vstack([probe.corners, center]).T)
    eave = ground.max() + 3.0 * floors + rng.uniform(0.3, 0.8)
    gable = floors <= 3 and rng.random() < 0.6
    rise = width / 2 * np.tan(np.radians(rng.uniform(25.0, 40.0))) if gable else 0.0
    return Building(center=center, heading_rad=heading, length_m=length, width_m=width,
                    base_z=float(ground.min() - 0.5), eave_z=float(eave), ridge_z=float(eave + rise), floors=floors,
                    plaster_rgb=PLASTER_COLOURS[rng.integers(len(PLASTER_COLOURS))],
                    roof_rgb=ROOF_COLOURS[rng.integers(len(ROOF_COLOURS))] if gable else (128, 126, 120))


def _place_buildings(rng: np.random.Generator, spec: WorldSpec, terrain: HeightField, roads: list[Road],
                     village_center: np.ndarray, village_radius: float) -> list[Building]:
    """Buildings along the asphalt roads, facing them, mostly within the village radius, none overlapping."""
    streets = [r for r in roads if r.surface == "asphalt"]
    buildings: list[Building] = []
    for _ in range(spec.building_count * 60):
        if len(buildings) == spec.building_count:
            break
        road = streets[rng.integers(len(streets))]
        i = int(rng.integers(1, len(road.points) - 1))
        tangent = road.points[i + 1] - road.points[i - 1]
        tangent /= np.linalg.norm(tangent)
        normal = np.array([-tangent[1], tangent[0]]) * rng.choice([-1.0, 1.0])
        center = road.points[i] + normal * (road.width_m / 2 + rng.uniform(9.0, 16.0)) + rng.normal(0, 1.0, 2)
        in_village = np.linalg.norm(center - village_center) < village_radius
        if not in_village and rng.random() > 0.15:
            continue
        heading = float(np.arctan2(tangent[1], tangent[0]) + rng.normal(0.0, 0.05))
        building = _random_building(rng, terrain, center, heading)
        outline = np.vstack([building.corners, center])
        if not (_inside(outline, spec, 8.0) and _clear_of_roads(outline, roads, 2.0)):
            continue
        if any(np.linalg.norm(b.center - center) < b.radius_m + building.radius_m + 2.5 for b in buildings):
            continue
        buildings.append(building)
    return buildings


def _tree_candidates(rng: np.random.Generator, spec: WorldSpec, roads: list[Road], count: int) -> np.ndarray:
    """Candidate tree positions: alleys along the asphalt roads, a few woods, and scattered singles."""
    half = np.array(spec.half_extent_m)
    alleys = []
    for road in (r for r in roads if r.surface == "asphalt"):
        step = int(rng.integers(4, 7))  # road points are 2 m apart: a tree every 8-12 m
        pts, nxt = road.points[:-1:step], road.points[1::step]
        tangent = (nxt - pts[: len(nxt)]) / np.linalg.norm(nxt - pts[: len(nxt)], axis=1, keepdims=True)
        normal = np.stack([-tangent[:, 1], tangent[:, 0]], 1)
        offset = road.width_m / 2 + 3.0
        alleys += [pts[: len(nxt)] + normal * offset, pts[: len(nxt)] - normal * offset]
    woods = [rng.uniform(-half * 0.85, half * 0.85) + rng.normal(0, rng.uniform(8.0, 18.0), (count // 8, 2))
             for _ in range(4)]
    singles = rng.uniform(-half, half, (count, 2))
    candidates = np.vstack(alleys + woods + [singles])
    return candidates[rng.permutation(len(candidates))]


def _clear_of_buildings(points: np.ndarray, buildings: list[Building], clearance_m: float) -> bool:
    """Whether every point (M, 2) lies more than ``clearance_m`` outside every building's bounding circle."""
    return all(np.all(np.linalg.norm(points - b.center, axis=1) > b.radius_m + clearance_m) for b in buildings)


def rectangle(center: np.ndarray, heading: float, length_m: float, width_m: float) -> np.ndarray:
    """Corners (4, 2) of a rectangle centred at ``center`` with its length along ``heading`` (radians from east),
    counter-clockwise from above, starting at its local (-length/2, -width/2) corner."""
    along = np.array([np.cos(heading), np.sin(heading)])
    across = np.array([-along[1], along[0]])
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64)
    return center + signs[:, :1] * (length_m / 2) * along + signs[:, 1:] * (width_m / 2) * across


FOREST_SPACING_M = 4.0
"""Distance between neighbouring stems of the forest stand (before a jitter of up to 0.8 m)."""
FOREST_CROWN_M = 3.0
"""Largest crown radius in the forest stand: its stems stand at least this far inside its edge."""
FOREST_CLEARING_M = 5.0
"""Open ground around the forest stand: no other tree's crown or hedge comes closer to its edge."""
NEAR_ORIGIN_M = 45.0
"""The pond's centre and a point of the power line lie this close to the ENU origin, which the demo flight circles
(sim/worlds/built.py); the forest stand keeps out of this disc, so they find room clear of it."""


def _place_forest(rng: np.random.Generator, spec: WorldSpec, terrain: HeightField, roads: list[Road],
                  buildings: list[Building]) -> tuple[ForestStand, list[Tree]]:
    """A rectangular stand in the open, clear of roads, buildings and the disc of :data:`NEAR_ORIGIN_M`
    around the origin, filled with trees on a jittered grid of
    :data:`FOREST_SPACING_M` (mixed, a third conifers) whose crowns overlap, every crown within the rectangle: a
    closed canopy with a clear edge."""
    length, width = spec.forest_size_m
    half = np.array(spec.half_extent_m)
    for _ in range(2000):
        corners = rectangle(rng.uniform(-half * 0.8, half * 0.8), rng.uniform(0.0, np.pi), length, width)
        inner = corners.mean(0) + (corners - corners.mean(0)) * np.linspace(0.0, 1.0, 6)[:, None, None]
        outline = np.vstack([inner.reshape(-1, 2), (corners + np.roll(corners, -1, axis=0)) / 2])
        if _inside(outline, spec, 4.0) and _clear_of_roads(outline, roads, 3.0) \
                and _clear_of_buildings(outline, buildings, 4.0) \
                and not ForestStand(corners).covers(np.zeros((1, 2)), NEAR_ORIGIN_M)[0]:
            break
    else:
        raise ValueError(f"no room for a {length} m x {width} m forest stand")
    along, across = (corners[1] - corners[0]) / length, (corners[3] - corners[0]) / width
    stems = [np.linspace(FOREST_CROWN_M, side - FOREST_CROWN_M,
                         int((side - 2 * FOREST_CROWN_M) // FOREST_SPACING_M) + 1) for side in (length, width)]
    trees = []
    for a in stems[0]:
        for c in stems[1]:
            jitter = np.clip(np.array([a, c]) + rng.uniform(-0.8, 0.8, 2), FOREST_CROWN_M,
                             np.array([length, width]) - FOREST_CROWN_M)
            position = corners[0] + jitter[0] * along + jitter[1] * across
            conifer = bool(rng.random() < 0.35)
            radius = rng.uniform(1.8, 2.6) if conifer else rng.uniform(2.2, FOREST_CROWN_M)
            height = rng.uniform(12.0, 17.0) if conifer else rng.uniform(11.0, 15.0)
            trees.append(Tree(position, float(terrain.height(*position)), float(radius), float(height), conifer,
                              forest=True))
    return ForestStand(corners), trees


def _place_hedges(rng: np.random.Generator, spec: WorldSpec, roads: list[Road], buildings: list[Building],
                  forest: ForestStand) -> list[Hedge]:
    """Straight hedges of 10-25 m parallel to a road, a few metres off its edge (garden and field hedges), clear
    of roads, buildings, the forest and each other."""
    hedges: list[Hedge] = []
    for _ in range(spec.hedge_count * 80):
        if len(hedges) == spec.hedge_count:
            break
        road = roads[rng.integers(len(roads))]
        i = int(rng.integers(1, len(road.points) - 1))
        tangent = road.points[i + 1] - road.points[i - 1]
        tangent /= np.linalg.norm(tangent)
        normal = np.array([-tangent[1], tangent[0]]) * rng.choice([-1.0, 1.0])
        middle = road.points[i] + normal * (road.width_m / 2 + rng.uniform(2.5, 5.0))
        length = rng.uniform(10.0, 25.0)
        hedge = Hedge(middle - tangent * length / 2, middle + tangent * length / 2, float(rng.uniform(0.8, 1.3)),
                      float(rng.uniform(1.2, 2.2)))
        line = hedge.points()
        if not (_inside(line, spec, 3.0) and _clear_of_roads(line, roads, hedge.width_m / 2 + 0.5)
                and _clear_of_buildings(line, buildings, 2.5) and not np.any(forest.covers(line, FOREST_CLEARING_M))):
            continue
        if any(distance_to_polyline(line, np.array([h.start, h.end])).min() < 3.0 for h in hedges):
            continue
        hedges.append(hedge)
    return hedges


def _place_trees(rng: np.random.Generator, spec: WorldSpec, terrain: HeightField, roads: list[Road],
                 buildings: list[Building], forest: ForestStand, hedges: list[Hedge]) -> list[Tree]:
    """Standalone trees (alleys, groves, singles) clear of roads, buildings, the forest, the hedges and each other's
    stems."""
    trees: list[Tree] = []
    centers = np.array([b.center for b in buildings]).reshape(-1, 2)
    radii = np.array([b.radius_m for b in buildings])
    for position in _tree_candidates(rng, spec, roads, spec.tree_count):
        if len(trees) == spec.tree_count:
            break
        conifer = bool(rng.random() < 0.35)
        radius = rng.uniform(1.4, 2.8) if conifer else rng.uniform(2.0, 4.2)
        height = rng.uniform(6.0, 14.0) if conifer else rng.uniform(2.0, 2.8) * radius
        if not _inside(position[None], spec, radius + 2.0) or not _clear_of_roads(position[None], roads, radius * 0.6):
            continue
        if len(centers) and np.any(np.linalg.norm(centers - position, axis=1) < radii + radius + 1.5):
            continue
        if any(np.hypot(*(t.position - position)) < 0.8 * (t.radius_m + radius) for t in trees):
            continue
        if forest.covers(position[None], radius + FOREST_CLEARING_M)[0] or any(
                distance_to_polyline(position[None], np.array([h.start, h.end]))[0] < radius + h.width_m / 2 + 0.3
                for h in hedges):
            continue
        trees.append(Tree(position, float(terrain.height(*position)), float(radius), float(height), conifer))
    return trees


def generate_layout(spec: WorldSpec, rng: np.random.Generator) -> Layout:
    """Terrain, roads, buildings, the forest stand, hedges and trees of one world, deterministic for a given
    generator state. The forest's trees come first in ``trees``, then the standalone ones."""
    terrain = HeightField.random(rng, spec.relief_m)
    half_x, half_y = spec.half_extent_m
    ew_offset = rng.uniform(12.0, 25.0) * rng.choice([-1.0, 1.0])
    ns_offset = rng.uniform(15.0, 35.0) * rng.choice([-1.0, 1.0])
    roads = [
        _curved_road(rng, spec, north_south=False, offset_m=ew_offset, width_m=7.0, surface="asphalt"),
        _curved_road(rng, spec, north_south=True, offset_m=ns_offset, width_m=6.0, surface="asphalt"),
    ]
    village_center = np.array([ns_offset, ew_offset]) * 0.6
    village_radius = 0.45 * min(half_x, half_y)
    roads += [_straight_track(rng, spec, village_center, village_radius) for _ in range(3)]
    buildings = _place_buildings(rng, spec, terrain, roads, village_center, village_radius)
    forest, forest_trees = _place_forest(rng, spec, terrain, roads, buildings)
    hedges = _place_hedges(rng, spec, roads, buildings, forest)
    trees = forest_trees + _place_trees(rng, spec, terrain, roads, buildings, forest, hedges)
    return Layout(spec, terrain, roads, buildings, trees, village_center, [forest], hedges)
