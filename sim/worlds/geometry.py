"""Triangle geometry of the demo world (ENU metres, z up) with atlas UVs, as plain numpy arrays.

Every part is a ``Part``: vertices (N, 3) float64, faces (M, 3) int64 counter-clockwise seen from outside, and
uv (N, 2) float64. Terrain and roofs take the orthophoto UVs of their x/y; walls take their own facade slot; trees
and hedges (sim/worlds/vegetation.py) take the vegetation patches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.render.classes import ROOF, TREE, WALL
from sim.render.labels import SceneLabels
from sim.worlds.atlas import FacadeAtlas, ortho_uv
from sim.worlds.ground_cover import GroundCover
from sim.worlds.layout import Building, Layout, WorldSpec


@dataclass(frozen=True)
class Part:
    """A piece of textured triangle mesh."""

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray


def concatenate(parts: list[Part]) -> Part:
    """One part holding all ``parts`` (face indices shifted)."""
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    return Part(np.vstack([p.vertices for p in parts]),
                np.vstack([p.faces + o for p, o in zip(parts, offsets, strict=True)]),
                np.vstack([p.uv for p in parts]))


def grid_faces(rows: int, cols: int) -> np.ndarray:
    """Two triangles per cell of a (rows x cols)-vertex grid stored row-major, normals towards +z when rows run
    along +y and columns along +x."""
    index = np.arange(rows * cols).reshape(rows, cols)
    v00, v10 = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    v01, v11 = index[1:, :-1].ravel(), index[1:, 1:].ravel()
    return np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])


def terrain_part(layout: Layout) -> Part:
    """The ground height field over the whole world rectangle, a regular grid of about ``grid_step_m``."""
    spec = layout.spec
    half_x, half_y = spec.half_extent_m
    xs = np.linspace(-half_x, half_x, int(round(spec.size_x_m / spec.grid_step_m)) + 1)
    ys = np.linspace(-half_y, half_y, int(round(spec.size_y_m / spec.grid_step_m)) + 1)
    grid_x, grid_y = np.meshgrid(xs, ys)
    xy = np.stack([grid_x.ravel(), grid_y.ravel()], 1)
    vertices = np.column_stack([xy, layout.terrain.height(xy[:, 0], xy[:, 1])])
    return Part(vertices, grid_faces(len(ys), len(xs)), ortho_uv(xy, spec))


def wall_part(facades: FacadeAtlas, wall_index: int) -> Part:
    """A vertical wall quad (plus its gable triangle), textured with its own facade slot."""
    wall = facades.walls[wall_index]
    mid = (wall.start + wall.end) / 2
    length = wall.length_m
    corners = 5 if wall.apex_z > wall.eave_z else 4  # the apex only where a gable triangle uses it
    xy = np.array([wall.start, wall.end, wall.end, wall.start, mid])[:corners]
    z = np.array([wall.base_z, wall.base_z, wall.eave_z, wall.eave_z, wall.apex_z])[:corners]
    along = np.array([0.0, length, length, 0.0, length / 2])[:corners]
    faces = [[0, 1, 2], [0, 2, 3]] + ([[3, 2, 4]] if corners == 5 else [])
    return Part(np.column_stack([xy, z]), np.array(faces), facades.uv(wall_index, along, z))


def roof_part(building: Building, spec: WorldSpec) -> Part:
    """A flat roof, or two slopes meeting at a ridge along the building's length."""
    corners = building.corners
    if not building.gable:
        xyz = np.column_stack([corners, np.full(4, building.eave_z)])
        return Part(xyz, np.array([[0, 1, 2], [0, 2, 3]]), ortho_uv(corners, spec))
    along, _ = building.axes
    ridge = building.center + np.outer([-0.5, 0.5], along * building.length_m)
    xy = np.vstack([corners, ridge])
    z = np.array([building.eave_z] * 4 + [building.ridge_z] * 2)
    faces = np.array([[0, 1, 5], [0, 5, 4], [2, 3, 4], [2, 4, 5]])
    return Part(np.column_stack([xy, z]), faces, ortho_uv(xy, spec))


def world_part(layout: Layout, facades: FacadeAtlas, cover: GroundCover,
               vegetation: list[Part]) -> tuple[Part, SceneLabels]:
    """The whole world: terrain, then buildings (walls and roofs), then the ``vegetation`` (one part per tree, then
    per hedge: sim/worlds/vegetation.py); and every face's exact label.

    Terrain faces take the class of the ``cover`` at their centroid; walls and roofs are building ``i``'s object
    ``i + 1``; every face of tree ``j`` (trunk, branches, leaves) is ``tree`` of object ``B + 1 + j`` (``B``
    buildings), as Cityscapes files trunks under vegetation, and hedge ``k`` is ``tree`` of object ``B + T + 1 + k``
    (``T`` trees); confidence 1 everywhere.
    """
    terrain = terrain_part(layout)
    # (part, its faces' class: one id for all or one per face, its object)
    labelled = [(terrain, cover.classify(terrain.vertices[terrain.faces, :2].mean(axis=1)), 0)]
    labelled += [(wall_part(facades, i), WALL, wall.building_index + 1) for i, wall in enumerate(facades.walls)]
    labelled += [(roof_part(b, layout.spec), ROOF, i + 1) for i, b in enumerate(layout.buildings)]
    first_tree = len(layout.buildings) + 1
    labelled += [(part, TREE, first_tree + j) for j, part in enumerate(vegetation)]
    counts = [len(part.faces) for part, _, _ in labelled]
    face_class = np.concatenate([np.broadcast_to(np.asarray(c, np.uint8), (n,)) for (_, c, _), n in
                                 zip(labelled, counts, strict=True)])
    face_instance = np.repeat([instance for _, _, instance in labelled], counts).astype(np.uint32)
    labels = SceneLabels(face_class, face_instance, np.ones(len(face_class), np.float32))
    return concatenate([part for part, _, _ in labelled]), labels
