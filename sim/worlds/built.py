"""The demo world's built details and water: what is placed, painted and meshed beyond buildings and trees, and the
truth of every such object.

In the generator's order (sim/worlds/demo.py): :func:`clear_sites` cuts a pond into the layout's terrain and places a
power line (dropping the standalone trees the pond's banks would swallow and those under the wires; both keep clear
of the forest stands and the hedges, which lose nothing) before anything is painted or the trees are meshed;
after the orthophoto (whose yards the fences follow), :func:`place_built` places chimneys and dormers, lamp posts,
fences and parked cars, each clear of the others and of the corridor under the wires, and :func:`paint_built`
paints what they look like from above; :func:`built_part` meshes them with their labels and per-object truth.

Objects and labels (docs/demo-world.md): a chimney, a lamp post (with its arm and lamp), a power pole (with its
crossarm), a wire (one per span and conductor), a fence (all its posts and rails), a car and the pond are each one
object with their own instance id, numbered in that order after the world's others (buildings, trees, hedges:
sim/worlds/geometry.py); a dormer's faces are ``wall`` and ``roof`` of its building's object.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sim.render.classes import CAR, CHIMNEY, CLASSES, FENCE, POLE, ROOF, WALL, WATER, WIRE
from sim.render.labels import SceneLabels
from sim.worlds.atlas import FacadeAtlas
from sim.worlds.geometry import Part, concatenate
from sim.worlds.ground_cover import Yard
from sim.worlds.layout import NEAR_ORIGIN_M, Layout, WorldSpec
from sim.worlds.roof_details import (Chimney, Dormer, chimney_part, chimney_truth, dormer_part, dormer_truth,
                                     paint_chimney, place_chimney, place_dormer)
from sim.worlds.street_furniture import (CROSSARM_HALF_M, WIRES, Car, Fence, LampPost, Obstacles, PowerLine,
                                         car_part, car_truth, fence_part, fence_truth, lamp_post_part,
                                         lamp_post_truth, paint_street_furniture, place_cars, place_fence,
                                         place_lamp_posts, place_power_line, power_pole_part, power_pole_truth,
                                         trees_clear_of_wires, wire_part, wire_truth)
from sim.worlds.water import Pond, PondTerrain, paint_pond, place_pond, pond_truth, trees_clear_of, water_part

CHIMNEY_SHARE, DORMER_SHARE, FENCE_SHARE = 0.75, 0.5, 0.4
"""Shares of buildings with a chimney, of gable roofs with a dormer (where one fits), of yards with a fence."""
CARS_PER_BUILDING = 0.5
#: The kinds of object in scene.json's "objects", in instance order.
OBJECT_KINDS = ("dormer", "chimney", "lamp_post", "power_pole", "wire", "fence", "car", "pond")


@dataclass(frozen=True)
class BuiltObjects:
    """Everything placed by :func:`place_built`, and the pond and power line of :func:`clear_sites`."""

    pond: Pond
    chimneys: list[Chimney]
    dormers: list[Dormer]
    power_line: PowerLine
    lamp_posts: list[LampPost]
    fences: list[Fence]
    cars: list[Car]


def clear_sites(rng: np.random.Generator, layout: Layout) -> tuple[Layout, Pond, PowerLine]:
    """The layout with a pond near the origin cut into its terrain (:class:`~sim.worlds.water.PondTerrain`) and a
    power line placed, clear of the forest stands and hedges, the (standalone) trees in the pond's way and under the
    wires left out (before the trees are meshed and their truth taken); the pond and the line."""
    radius = (8.0, 12.0) if layout.spec.size_x_m >= 300 else (6.0, 8.0)
    pond = place_pond(rng, layout, NEAR_ORIGIN_M, radius)
    trees = trees_clear_of(layout.trees, pond)
    line = place_power_line(rng, layout.spec, layout.terrain, trees, layout.buildings,
                            _obstacles(layout, trees, pond), NEAR_ORIGIN_M)
    cleared = replace(layout, terrain=PondTerrain(layout.terrain, pond), trees=trees_clear_of_wires(trees, line))
    return cleared, pond, line


def _obstacles(layout: Layout, trees: list, pond: Pond, line: PowerLine | None = None) -> Obstacles:
    """What objects keep clear of: roads, buildings, the forest stands, the crowns of ``trees``, the hedges (discs
    every metre along each, 0.3 m past its sides), the pond, and the power line's poles and the corridor under its
    wires (discs every 2 m along each span)."""
    obstacles = Obstacles(layout.roads, layout.buildings, areas=list(layout.forests),
                          discs=[(*t.position, t.radius_m) for t in trees])
    for hedge in layout.hedges:
        for point in hedge.points(1.0):
            obstacles.add(point, hedge.width_m / 2 + 0.3)
    obstacles.add(pond.center, pond.reach_m)
    if line is not None:
        for start, end in zip(line.positions[:-1], line.positions[1:], strict=True):
            for share in np.linspace(0.0, 1.0, int(np.linalg.norm(end - start) / 2.0) + 2):
                obstacles.add(start + share * (end - start), CROSSARM_HALF_M + 0.5)
    return obstacles


def _at_least_one(rng: np.random.Generator, count: int, share: float) -> np.ndarray:
    """Which of ``count`` items are chosen, each with probability ``share``; the first at least when none was."""
    chosen = rng.random(count) < share
    if count and not chosen.any():
        chosen[0] = True
    return chosen


def _roof_details(rng: np.random.Generator, layout: Layout) -> tuple[list[Chimney], list[Dormer]]:
    """Dormers on about half the gable roofs that fit one (at least one), then chimneys on about three quarters of
    the buildings (at least one), clear of the dormers."""
    fits = [d for i, b in enumerate(layout.buildings) if (d := place_dormer(rng, i, b)) is not None]
    dormers = [d for d, keep in zip(fits, _at_least_one(rng, len(fits), DORMER_SHARE), strict=True) if keep]
    by_building = {d.building_index: d for d in dormers}
    chimneys = []
    for index in np.flatnonzero(_at_least_one(rng, len(layout.buildings), CHIMNEY_SHARE)):
        chimney = place_chimney(rng, int(index), layout.buildings[index], by_building.get(int(index)))
        if chimney is not None:
            chimneys.append(chimney)
    return chimneys, dormers


def place_built(rng: np.random.Generator, layout: Layout, pond: Pond, line: PowerLine,
                yards: tuple[Yard, ...]) -> BuiltObjects:
    """Place the roof details, lamp posts, fences around some of the painted ``yards`` and cars, clear of the pond
    and the power line of :func:`clear_sites`."""
    chimneys, dormers = _roof_details(rng, layout)
    obstacles = _obstacles(layout, layout.trees, pond, line)
    spec, terrain = layout.spec, layout.terrain
    lamp_posts = place_lamp_posts(rng, spec, terrain, obstacles)
    fences = [f for yard, keep in zip(yards, _at_least_one(rng, len(yards), FENCE_SHARE), strict=True)
              if keep and (f := place_fence(rng, yard, terrain, obstacles, spec)) is not None]
    cars = place_cars(rng, spec, terrain, obstacles, layout.village_center, 0.6 * min(spec.half_extent_m),
                      max(int(round(CARS_PER_BUILDING * len(layout.buildings))), 1))
    return BuiltObjects(pond, chimneys, dormers, line, lamp_posts, fences, cars)


def paint_built(rng: np.random.Generator, image: np.ndarray, built: BuiltObjects, spec: WorldSpec) -> None:
    """Paint the objects as seen from above into the orthophoto ``image`` (after the roofs), in place."""
    paint_pond(rng, image, built.pond, spec)
    for chimney in built.chimneys:
        paint_chimney(image, chimney, spec)
    paint_street_furniture(image, built.lamp_posts, built.power_line, built.fences, built.cars, spec)


@dataclass(frozen=True)
class Piece:
    """A meshed object: its part, its faces' class (one id, or one per face), its ``kind`` and JSON truth, and the
    object id it belongs to when it is part of another (a dormer: its building's), else None (its own)."""

    part: Part
    face_class: int | np.ndarray
    kind: str
    truth: dict
    owner: int | None = None


def _roof_pieces(built: BuiltObjects, layout: Layout, facades: FacadeAtlas) -> list[Piece]:
    """The dormers (owned by their buildings) and the chimneys."""
    pieces = []
    for dormer in built.dormers:
        building = layout.buildings[dormer.building_index]
        walls, roof = dormer_part(dormer, building, facades, layout.spec)
        classes = np.repeat(np.array([WALL, ROOF], np.uint8), [len(walls.faces), len(roof.faces)])
        pieces.append(Piece(concatenate([walls, roof]), classes, "dormer", dormer_truth(dormer, building),
                            owner=dormer.building_index + 1))
    return pieces + [Piece(chimney_part(c, layout.spec), CHIMNEY, "chimney", chimney_truth(c)) for c in built.chimneys]


def _street_pieces(built: BuiltObjects, layout: Layout) -> list[Piece]:
    """Lamp posts, the power line's poles and wires, fences and cars."""
    spec, line = layout.spec, built.power_line
    pieces = [Piece(lamp_post_part(p, spec), POLE, "lamp_post", lamp_post_truth(p)) for p in built.lamp_posts]
    pieces += [Piece(power_pole_part(line, k, spec), POLE, "power_pole", power_pole_truth(line, k))
               for k in range(len(line.positions))]
    pieces += [Piece(wire_part(line, span, wire, spec), WIRE, "wire", wire_truth(line, span, wire))
               for span in range(len(line.positions) - 1) for wire in range(WIRES)]
    pieces += [Piece(fence_part(f, layout.terrain, spec), FENCE, "fence", fence_truth(f)) for f in built.fences]
    return pieces + [Piece(car_part(c, spec), CAR, "car", car_truth(c)) for c in built.cars]


def _pieces(built: BuiltObjects, layout: Layout, facades: FacadeAtlas) -> list[Piece]:
    """Every object's piece, in instance order (dormers, owned by their buildings, first)."""
    pond = Piece(water_part(built.pond, layout.spec), WATER, "pond", pond_truth(built.pond))
    return _roof_pieces(built, layout, facades) + _street_pieces(built, layout) + [pond]


def built_part(built: BuiltObjects, layout: Layout, facades: FacadeAtlas,
               first_instance: int) -> tuple[Part, SceneLabels, list[dict]]:
    """The objects' mesh, its faces' labels (objects of their own numbered from ``first_instance``) and the truth
    of every object: ``{"instance", "kind", "classes", ...}`` (positions ENU metres; see docs/demo-world.md)."""
    pieces = _pieces(built, layout, facades)
    instances, objects, next_instance = [], [], first_instance
    for piece in pieces:
        instance = piece.owner if piece.owner is not None else next_instance
        next_instance += piece.owner is None
        instances.append(instance)
        classes = [CLASSES[c].name for c in np.unique(piece.face_class)]
        objects.append({"instance": int(instance), "kind": piece.kind, "classes": classes, **piece.truth})
    counts = [len(p.part.faces) for p in pieces]
    face_class = np.concatenate([np.broadcast_to(np.asarray(p.face_class, np.uint8), (n,)) for p, n in
                                 zip(pieces, counts, strict=True)])
    face_instance = np.repeat(instances, counts).astype(np.uint32)
    labels = SceneLabels(face_class, face_instance, np.ones(len(face_class), np.float32))
    return concatenate([p.part for p in pieces]), labels, objects

