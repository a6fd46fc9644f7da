"""Lamp posts, a power line, fences and parked cars in the demo world: where they stand, their solids, their paint.

ENU metres, z up. Every object stands on the terrain it is given (its foot sunk a little into it) and keeps clear of
the roads' bands, the buildings, the trees' crowns and the objects placed before it (:class:`Obstacles`). Poles and
wires are tubes, and fences boxes, of one colour: the texel painted at the pole's (first post's) foot
(:func:`~sim.worlds.shapes.swatch_uv`); cars are boxes whose tops are painted from above in the orthophoto. The
``*_truth`` functions give each object's JSON truth for scene.json (ENU metres, rounded to 0.1 mm).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.worlds.geometry import Part, concatenate
from sim.worlds.ground_cover import Yard
from sim.worlds.layout import Building, Road, WorldSpec, distance_to_polyline
from sim.worlds.shapes import (box_part, footprint_corners, json_point, paint_local_mask, paint_swatch, swatch_uv,
                               tube_part)

LAMP_RGB, WOOD_POLE_RGB = (112, 114, 118), (74, 62, 50)
FENCE_COLOURS = [(134, 104, 72), (222, 220, 212), (92, 96, 90)]
CAR_COLOURS = [(196, 30, 36), (28, 52, 140), (230, 230, 226), (24, 24, 26), (150, 152, 156), (40, 110, 60),
               (210, 170, 40), (110, 30, 40)]
GLASS_RGB = (36, 44, 52)
POLE_SIDES, WIRE_SIDES = 8, 3
POWER_POLE_HEIGHT_M, POWER_POLE_RADIUS_M = 9.0, 0.125
CROSSARM_Z_M, CROSSARM_HALF_M = 8.4, 1.0
"""Crossarm height above the pole's foot and half length (m); wires hang from its ends and from the pole top."""
WIRE_RADIUS_M = 0.015
WIRE_SAG_PER_M = 0.02
"""A wire's sag at mid-span, per metre of span."""
MIN_POLES = 4
"""The fewest poles in a row that make the power line."""
WIRES = 3
"""Wires per span: from the crossarm's two ends and the pole top."""
WIRE_POINTS = 9
"""Points per span along a wire's parabola."""
ORIGIN_CLEARANCE_M = 10.0
"""The power line passes at least this far (m) from the ENU origin, the centre of the demo flight's orbit."""
FOOT_SINK_M = 0.2
"""How far (m) posts and poles reach into the ground."""


@dataclass
class Obstacles:
    """What a new object must keep out of: the roads' bands, the buildings' footprints, ``areas`` (the forest
    stands: anything with a ``covers(xy, margin_m)`` test) and discs (ENU x, y, radius: trees' crowns, hedges, the
    pond, objects placed before); grows as objects are placed."""

    roads: list[Road]
    buildings: list[Building]
    areas: list = field(default_factory=list)
    discs: list[tuple[float, float, float]] = field(default_factory=list)

    def clear(self, xy: np.ndarray, radius_m: float, road_gap_m: float | None,
              building_gap_m: float = 1.0, own_building: Building | None = None) -> bool:
        """Whether a disc of ``radius_m`` around ENU ``xy`` stays out of every disc and area and ``building_gap_m``
        off every footprint (but ``own_building``'s), and, unless ``road_gap_m`` is None, ``xy`` lies ``road_gap_m``
        off every road's band."""
        if any(area.covers(np.asarray(xy, np.float64)[None], radius_m)[0] for area in self.areas):
            return False
        if self.discs:
            discs = np.asarray(self.discs)
            if np.any(np.hypot(discs[:, 0] - xy[0], discs[:, 1] - xy[1]) < discs[:, 2] + radius_m):
                return False
        if any(b.covers_local(*b.local(xy[0], xy[1]), radius_m + building_gap_m) for b in self.buildings
               if b is not own_building):
            return False
        if road_gap_m is None:
            return True
        return all(distance_to_polyline(np.asarray(xy)[None], r.points)[0] > r.width_m / 2 + road_gap_m
                   for r in self.roads)

    def add(self, xy: np.ndarray, radius_m: float) -> None:
        """Keep later objects out of a disc of ``radius_m`` around ``xy``."""
        self.discs.append((float(xy[0]), float(xy[1]), float(radius_m)))


def _inside(xy: np.ndarray, spec: WorldSpec, margin_m: float) -> bool:
    half_x, half_y = spec.half_extent_m
    return abs(xy[0]) <= half_x - margin_m and abs(xy[1]) <= half_y - margin_m


def _road_frames(road: Road, step_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points every ``step_m`` along the road's centreline, their unit tangents and left normals (ENU)."""
    arclength = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(road.points, axis=0), axis=1))])
    s = np.arange(0.0, arclength[-1], step_m)
    points = np.stack([np.interp(s, arclength, road.points[:, k]) for k in range(2)], 1)
    tangent = np.gradient(points, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return points, tangent, np.stack([-tangent[:, 1], tangent[:, 0]], 1)


# --- lamp posts -------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LampPost:
    """A street lamp at ENU ``position`` on ground ``ground_z``: a pole of ``radius_m`` up to ``height_m`` above the
    ground, an arm reaching ``arm_m`` towards ``towards`` (unit ENU x, y: over the road) and a lamp at its end."""

    position: np.ndarray
    ground_z: float
    radius_m: float
    height_m: float
    towards: np.ndarray
    arm_m: float = 1.4


def place_lamp_posts(rng: np.random.Generator, spec: WorldSpec, terrain, obstacles: Obstacles) -> list[LampPost]:
    """Lamp posts every 25-35 m along one side of each asphalt road, each moved up to 6 m along the road to a spot
    clear of trees and buildings (skipped where there is none)."""
    posts = []
    for road in (r for r in obstacles.roads if r.surface == "asphalt"):
        height, radius = rng.uniform(5.0, 8.0), rng.uniform(0.075, 0.125)
        side = rng.choice([-1.0, 1.0])
        points, _, normal = _road_frames(road, 1.0)
        spacing = int(rng.uniform(25.0, 35.0))
        for i in range(int(rng.integers(0, spacing)), len(points), spacing):
            for shift in (0, 2, -2, 4, -4, 6, -6):
                k = min(max(i + shift, 0), len(points) - 1)
                xy = points[k] + side * normal[k] * (road.width_m / 2 + 0.6)
                if _inside(xy, spec, 2.0) and obstacles.clear(xy, 0.8, road_gap_m=0.4):
                    obstacles.add(xy, 0.8)
                    posts.append(LampPost(xy, float(terrain.height(*xy)), float(radius), float(height),
                                          -side * normal[k]))
                    break
    return posts


def lamp_post_part(post: LampPost, spec: WorldSpec) -> Part:
    """Pole (a capped 8-sided tube), arm and lamp (boxes), all in the grey painted at the pole's foot."""
    uv = swatch_uv(post.position, spec)
    top = post.ground_z + post.height_m
    pole = tube_part(np.array([[*post.position, post.ground_z - FOOT_SINK_M], [*post.position, top]]),
                     post.radius_m, POLE_SIDES, spec, uv, cap=True)
    heading = float(np.arctan2(post.towards[1], post.towards[0]))
    arm_centre = post.position + post.towards * post.arm_m / 2
    arm = box_part(arm_centre, heading, post.arm_m, 0.08, top - 0.18, top - 0.1, spec, uv, uv, bottom=True)
    lamp = box_part(post.position + post.towards * (post.arm_m - 0.25), heading, 0.6, 0.28, top - 0.32, top - 0.18,
                    spec, uv, uv, bottom=True)
    return concatenate([pole, arm, lamp])


def _pole_truth(xy: np.ndarray, ground_z: float, height_m: float, radius_m: float) -> dict:
    return {"position_m": json_point(xy), "ground_z_m": round(float(ground_z), 4),
            "top_z_m": round(float(ground_z) + height_m, 4), "radius_m": round(float(radius_m), 4)}


def lamp_post_truth(post: LampPost) -> dict:
    """Foot (ENU x, y and ground z), top and radius of a lamp post's pole."""
    return _pole_truth(post.position, post.ground_z, post.height_m, post.radius_m)


# --- power line -------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PowerLine:
    """Wooden poles (ENU x, y and ground z each) in a row along ``direction``; wires hang between neighbours from
    the crossarm's ends and the pole tops."""

    positions: np.ndarray  # (P, 2)
    ground_z: np.ndarray  # (P,)
    direction: np.ndarray  # unit ENU x, y

    def attachments(self, pole: int) -> np.ndarray:
        """(3, 3) ENU points where the wires hang on pole ``pole``: the crossarm's two ends, then the pole top."""
        across = np.array([-self.direction[1], self.direction[0]])
        xy = self.positions[pole] + np.outer([-CROSSARM_HALF_M + 0.1, CROSSARM_HALF_M - 0.1, 0.0], across)
        z = self.ground_z[pole] + np.array([CROSSARM_Z_M + 0.06] * 2 + [POWER_POLE_HEIGHT_M])
        return np.column_stack([xy, z])

    def wire_points(self, span: int, wire: int) -> np.ndarray:
        """(WIRE_POINTS, 3) ENU points of wire ``wire`` between poles ``span`` and ``span + 1``: a parabola sagging
        :data:`WIRE_SAG_PER_M` per metre of span at its middle."""
        start, end = self.attachments(span)[wire], self.attachments(span + 1)[wire]
        t = np.linspace(0.0, 1.0, WIRE_POINTS)[:, None]
        sag = WIRE_SAG_PER_M * np.linalg.norm(end[:2] - start[:2])
        return start + t * (end - start) - np.array([0.0, 0.0, 4.0 * sag]) * t * (1 - t)


BUILDING_CONFLICT = 1000
"""A building near a candidate line counts as this many trees: a line passes any number of trees before one."""


def _line_conflicts(through: np.ndarray, direction: np.ndarray, trees, buildings, corridor_m: float) -> int:
    """How many trees, and :data:`BUILDING_CONFLICT` times how many buildings, reach within ``corridor_m`` of the
    infinite line."""
    normal = np.array([-direction[1], direction[0]])
    count = sum(abs((t.position - through) @ normal) < t.radius_m + corridor_m for t in trees)
    return count + BUILDING_CONFLICT * sum(abs((b.center - through) @ normal) < b.radius_m + corridor_m
                                           for b in buildings)


def _nearest_run(stations: np.ndarray, spacing_m: float) -> np.ndarray:
    """Of the runs of consecutive stations (metres along the line, increasing) no more than 1.5 spacings apart and
    of :data:`MIN_POLES` at least, the one that comes nearest the origin (station 0); empty when there is none."""
    breaks = np.flatnonzero(np.diff(stations) > 1.5 * spacing_m) + 1
    runs = [stations[a:b] for a, b in zip(np.r_[0, breaks], np.r_[breaks, len(stations)], strict=True)
            if b - a >= MIN_POLES]
    return min(runs, key=lambda run: np.abs(run).min()) if runs else np.zeros(0)


def _stations(through: np.ndarray, direction: np.ndarray, spacing_m: float, offset_m: float, spec: WorldSpec,
              obstacles: Obstacles) -> np.ndarray:
    """Where poles can stand along the line (metres from the origin's foot on it): every ``spacing_m`` from
    ``offset_m``, each moved up to 8 m along the line off roads and obstacles, or left out."""
    reach = float(np.hypot(*spec.half_extent_m))
    stations = []
    for s in np.arange(-reach, reach, spacing_m) + offset_m:
        for shift in (0, 3, -3, 6, -6, 8, -8):
            xy = through + (s + shift) * direction
            if _inside(xy, spec, 3.0) and obstacles.clear(xy, CROSSARM_HALF_M + 0.3, road_gap_m=1.0):
                stations.append(through @ direction + s + shift)
                break
    return np.array(stations)


def place_power_line(rng: np.random.Generator, spec: WorldSpec, terrain, trees, buildings, obstacles: Obstacles,
                     within_m: float) -> PowerLine:
    """A straight power line through a point within ``within_m`` of the origin but passing at least
    :data:`ORIGIN_CLEARANCE_M` from it (no wires over the orbit's centre): of 40 drawn lines, the first in order of
    fewest buildings then fewest trees near it where :data:`MIN_POLES` poles at least stand in a row passing the
    line's point nearest the origin, every 35-45 m, each moved up to 8 m along the line off roads and obstacles, and
    no building rises near its wires nor do they cross one of the obstacles' areas (the forest stands)."""
    candidates = []
    for index in range(40):
        angle, distance, bearing = rng.uniform(0, np.pi), within_m * np.sqrt(rng.random()), rng.uniform(0, 2 * np.pi)
        through = distance * np.array([np.cos(bearing), np.sin(bearing)])
        direction = np.array([np.cos(angle), np.sin(angle)])
        if abs(through @ [-direction[1], direction[0]]) >= ORIGIN_CLEARANCE_M:
            conflicts = _line_conflicts(through, direction, trees, buildings, CROSSARM_HALF_M + 1.0)
            candidates.append((conflicts, index, through, direction))
    spacing, offset = rng.uniform(35.0, 45.0), rng.uniform(0.0, 45.0)
    for _, _, through, direction in sorted(candidates, key=lambda c: c[:2]):
        stations = _nearest_run(_stations(through, direction, spacing, offset, spec, obstacles), spacing)
        if not len(stations) or np.abs(stations).min() > spacing:  # the wires must pass the point nearest the origin
            continue
        positions = (through - (through @ direction) * direction) + stations[:, None] * direction
        line = PowerLine(positions, terrain.height(positions[:, 0], positions[:, 1]), direction)
        if _wires_clear_of(line, buildings, obstacles.areas):
            for xy in positions:
                obstacles.add(xy, CROSSARM_HALF_M + 0.3)
            return line
    raise ValueError(f"no room for a power line of {MIN_POLES} poles passing within {within_m:.0f} m of the origin")


def _span_floors(line: PowerLine) -> list[tuple[np.ndarray, float]]:
    """Per span, its two poles' (2, 2) ENU x, y and its lowest wire's lowest point (ENU z)."""
    return [(line.positions[k:k + 2], min(line.wire_points(k, wire)[:, 2].min() for wire in range(WIRES)))
            for k in range(len(line.positions) - 1)]


def _wires_clear_of(line: PowerLine, buildings, areas) -> bool:
    """Whether no building within :data:`CROSSARM_HALF_M` + 0.5 m of a span rises to 1 m under its lowest wire, and
    no span passes within that of one of the ``areas`` (a forest stand is never cut through)."""
    for ends, lowest in _span_floors(line):
        steps = np.linspace(0.0, 1.0, int(np.linalg.norm(ends[1] - ends[0])) + 2)[:, None]  # about every metre
        along = ends[0] + steps * (ends[1] - ends[0])
        if any(np.any(area.covers(along, CROSSARM_HALF_M + 0.5)) for area in areas):
            return False
        for building in buildings:
            near = building.covers_local(*building.local(along[:, 0], along[:, 1]), CROSSARM_HALF_M + 0.5)
            if np.any(near) and building.ridge_z > lowest - 1.0:
                return False
    return True


def trees_clear_of_wires(trees: list, line: PowerLine) -> list:
    """The trees but those whose crowns reach within :data:`CROSSARM_HALF_M` + 0.5 m of a span and above its lowest
    wire less 0.5 m: the corridor a utility keeps clear."""
    spans = _span_floors(line)

    def under_wires(tree) -> bool:
        return any(distance_to_polyline(tree.position[None], ends)[0] - tree.radius_m < CROSSARM_HALF_M + 0.5
                   and tree.ground_z + tree.height_m > lowest - 0.5 for ends, lowest in spans)

    return [tree for tree in trees if not under_wires(tree)]


def power_pole_part(line: PowerLine, pole: int, spec: WorldSpec) -> Part:
    """A wooden pole (a capped 8-sided tube of 0.25 m) with its crossarm, in the brown painted at its foot."""
    xy, ground = line.positions[pole], float(line.ground_z[pole])
    uv = swatch_uv(xy, spec)
    shaft = tube_part(np.array([[*xy, ground - FOOT_SINK_M], [*xy, ground + POWER_POLE_HEIGHT_M]]),
                      POWER_POLE_RADIUS_M, POLE_SIDES, spec, uv, cap=True)
    heading = float(np.arctan2(line.direction[1], line.direction[0])) + np.pi / 2
    arm = box_part(xy, heading, 2 * CROSSARM_HALF_M, 0.12, ground + CROSSARM_Z_M - 0.06,
                   ground + CROSSARM_Z_M + 0.06, spec, uv, uv, bottom=True)
    return concatenate([shaft, arm])


def wire_part(line: PowerLine, span: int, wire: int, spec: WorldSpec) -> Part:
    """One wire of a span: a 3-sided tube of 3 cm along its parabola, in the colour painted at its first pole."""
    return tube_part(line.wire_points(span, wire), WIRE_RADIUS_M, WIRE_SIDES, spec,
                     swatch_uv(line.positions[span], spec))


def power_pole_truth(line: PowerLine, pole: int) -> dict:
    """Foot (ENU x, y and ground z), top and radius of a power pole."""
    return _pole_truth(line.positions[pole], float(line.ground_z[pole]), POWER_POLE_HEIGHT_M, POWER_POLE_RADIUS_M)


def wire_truth(line: PowerLine, span: int, wire: int) -> dict:
    """A wire's span (between poles ``span`` and ``span + 1``), its ends, lowest point, radius and sag."""
    points = line.wire_points(span, wire)
    return {"span": span, "start_m": json_point(points[0]), "end_m": json_point(points[-1]),
            "lowest_z_m": round(float(points[:, 2].min()), 4), "radius_m": WIRE_RADIUS_M,
            "sag_per_m": WIRE_SAG_PER_M}


# --- fences -----------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Fence:
    """A fence of posts and two rails along the ENU polyline ``corners`` (each side a straight run), ``height_m``
    high, painted ``rgb``."""

    corners: np.ndarray  # (K, 2)
    height_m: float
    rgb: tuple[int, int, int]
    post_spacing_m: float = 2.4

    def posts(self) -> np.ndarray:
        """(N, 2) ENU post positions: every corner, and evenly between them no more than the spacing apart."""
        points = [self.corners[:1]]
        for start, end in zip(self.corners[:-1], self.corners[1:], strict=True):
            count = max(int(np.ceil(np.linalg.norm(end - start) / self.post_spacing_m)), 1)
            points.append(start + np.linspace(0, 1, count + 1)[1:, None] * (end - start))
        return np.vstack(points)


def place_fence(rng: np.random.Generator, yard: Yard, terrain, obstacles: Obstacles, spec: WorldSpec) -> Fence | None:
    """A fence 0.5 m outside the yard on its three sides away from the nearest road (the open side faces the
    street), or None where it would cross a road, a tree or another object."""
    building = yard.building
    half_l, half_w = building.length_m / 2 + yard.margin_m + 0.5, building.width_m / 2 + yard.margin_m + 0.5
    nearest = min(obstacles.roads, key=lambda r: distance_to_polyline(building.center[None], r.points)[0])
    road_point = nearest.points[np.argmin(np.linalg.norm(nearest.points - building.center, axis=1))]
    street_side = 1.0 if building.local(*road_point)[1] > 0 else -1.0
    local = np.array([[-half_l, street_side * half_w], [-half_l, -street_side * half_w],
                      [half_l, -street_side * half_w], [half_l, street_side * half_w]])
    along, across = building.axes
    corners = building.center + local[:, :1] * along + local[:, 1:] * across
    fence = Fence(corners, float(rng.uniform(1.0, 1.4)), FENCE_COLOURS[rng.integers(len(FENCE_COLOURS))])
    samples = np.vstack([a + np.linspace(0, 1, 20)[:, None] * (b - a) for a, b in zip(corners[:-1], corners[1:])])
    if not all(_inside(p, spec, 1.0) and obstacles.clear(p, 0.3, road_gap_m=0.6, own_building=building)
               for p in samples):
        return None
    for p in fence.posts():
        obstacles.add(p, 0.3)
    return fence


def fence_part(fence: Fence, terrain, spec: WorldSpec) -> Part:
    """Posts (0.1 m square) and two rails (4-sided tubes 8 cm across, at 40 % and 85 % of the height above each
    post's ground, so they follow the slope post to post), in the colour painted at the first post's foot."""
    uv = swatch_uv(fence.corners[0], spec)
    posts = fence.posts()
    ground = terrain.height(posts[:, 0], posts[:, 1])
    parts = [box_part(p, 0.0, 0.1, 0.1, g - FOOT_SINK_M, g + fence.height_m, spec, uv, uv) for p, g in
             zip(posts, ground, strict=True)]
    feet = np.column_stack([posts, ground])
    parts += [tube_part(feet + [0.0, 0.0, share * fence.height_m], 0.04, 4, spec, uv) for share in (0.4, 0.85)]
    return concatenate(parts)


def fence_truth(fence: Fence) -> dict:
    """A fence's polyline (ENU x, y), height and number of posts."""
    return {"corners_m": [json_point(c) for c in fence.corners], "height_m": round(fence.height_m, 4),
            "posts": len(fence.posts())}


# --- parked cars ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Car:
    """A parked car: a body box ``length_m`` x ``width_m`` up to 0.85 m above the highest ground under it and a
    cabin on it up to ``height_m``, on ENU ``center`` facing ``heading_rad``; ``base_z`` is under the lowest
    ground under it."""

    center: np.ndarray
    heading_rad: float
    length_m: float
    width_m: float
    height_m: float
    base_z: float
    ground_z: float  # the highest ground under the car
    rgb: tuple[int, int, int]

    BODY_M = 0.85

    @property
    def cabin(self) -> tuple[np.ndarray, float, float]:
        """Centre (ENU x, y), length and width of the cabin: 55 % of the body, set back 10 % of it."""
        along = np.array([np.cos(self.heading_rad), np.sin(self.heading_rad)])
        return self.center - 0.1 * self.length_m * along, 0.55 * self.length_m, self.width_m - 0.12


def _car(rng: np.random.Generator, terrain, center: np.ndarray, heading: float) -> Car:
    length, width, height = rng.uniform(4.0, 4.6), rng.uniform(1.75, 1.9), rng.uniform(1.4, 1.55)
    corners = footprint_corners(center, heading, length, width)
    ground = terrain.height(corners[:, 0], corners[:, 1])
    return Car(center, heading, float(length), float(width), float(height), float(ground.min()) - 0.1,
               float(ground.max()), CAR_COLOURS[rng.integers(len(CAR_COLOURS))])


def place_cars(rng: np.random.Generator, spec: WorldSpec, terrain, obstacles: Obstacles, near: np.ndarray,
               near_m: float, count: int) -> list[Car]:
    """Up to ``count`` cars parked along the asphalt roads' edges (on the road, in its direction), within
    ``near_m`` of ``near`` (the village), each clear of trees, buildings and other objects."""
    cars = []
    streets = [r for r in obstacles.roads if r.surface == "asphalt"]
    for _ in range(count * 40):
        if len(cars) == count:
            break
        road = streets[rng.integers(len(streets))]
        points, tangent, normal = _road_frames(road, 1.0)
        k = int(rng.integers(len(points)))
        side = rng.choice([-1.0, 1.0])
        center = points[k] + side * normal[k] * (road.width_m / 2 - 1.15)
        if np.linalg.norm(center - near) > near_m or not _inside(center, spec, 4.0):
            continue
        if not obstacles.clear(center, 2.5, road_gap_m=None):
            continue
        heading = float(np.arctan2(tangent[k, 1], tangent[k, 0]) + (np.pi if side < 0 else 0.0))
        obstacles.add(center, 2.5)
        cars.append(_car(rng, terrain, center, heading))
    return cars


def car_part(car: Car, spec: WorldSpec) -> Part:
    """Body and cabin boxes: tops as painted from above, body sides in the car's colour, cabin sides in glass
    (texels of its painted roof and windows)."""
    along = np.array([np.cos(car.heading_rad), np.sin(car.heading_rad)])
    body_top = car.ground_z + Car.BODY_M
    body = box_part(car.center, car.heading_rad, car.length_m, car.width_m, car.base_z, body_top, spec,
                    swatch_uv(car.center + 0.4 * car.length_m * along, spec))
    cabin_centre, cabin_length, cabin_width = car.cabin
    glass = swatch_uv(cabin_centre + (cabin_length / 2 - 0.15) * along, spec)
    cabin = box_part(cabin_centre, car.heading_rad, cabin_length, cabin_width, body_top - 0.02,
                     car.ground_z + car.height_m, spec, glass)
    return concatenate([body, cabin])


def paint_car(image: np.ndarray, car: Car, spec: WorldSpec) -> None:
    """The car from above, in place: its colour, the cabin's roof a little darker, windscreens dark around it."""
    cabin_centre, cabin_length, cabin_width = car.cabin
    set_back = float(np.linalg.norm(cabin_centre - car.center))

    def paint(along, across, pixels):
        body = (np.abs(along) < car.length_m / 2) & (np.abs(across) < car.width_m / 2)
        pixels[body] = car.rgb
        cabin_along = along + set_back
        glass = (np.abs(cabin_along) < cabin_length / 2) & (np.abs(across) < cabin_width / 2)
        pixels[glass] = GLASS_RGB
        roof = (np.abs(cabin_along) < cabin_length / 2 - 0.35) & (np.abs(across) < cabin_width / 2 - 0.12)
        pixels[roof] = np.asarray(car.rgb) * 0.85

    paint_local_mask(image, spec, car.center, car.heading_rad, car.length_m / 2 + 0.2, paint)


def car_truth(car: Car) -> dict:
    """A car's centre, heading, size, top and the highest ground under it."""
    return {"position_m": json_point(car.center), "heading_deg": round(float(np.degrees(car.heading_rad)), 3),
            "length_m": round(car.length_m, 4), "width_m": round(car.width_m, 4),
            "top_z_m": round(car.ground_z + car.height_m, 4), "ground_z_m": round(car.ground_z, 4)}


def paint_street_furniture(image: np.ndarray, lamp_posts: list[LampPost], line: PowerLine, fences: list[Fence],
                           cars: list[Car], spec: WorldSpec) -> None:
    """Into the orthophoto, in place: the swatch at each pole's foot (and the first fence post's) that colours it,
    and every car seen from above."""
    for post in lamp_posts:
        paint_swatch(image, post.position, spec, LAMP_RGB)
    for xy in line.positions:
        paint_swatch(image, xy, spec, WOOD_POLE_RGB)
    for fence in fences:
        paint_swatch(image, fence.corners[0], spec, fence.rgb)
    for car in cars:
        paint_car(image, car, spec)
