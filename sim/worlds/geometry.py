"""Triangle geometry of the demo world (ENU metres, z up) with atlas UVs, as plain numpy arrays.

Every part is a ``Part``: vertices (N, 3) float64, faces (M, 3) int64 counter-clockwise seen from outside, and
uv (N, 2) float64. Terrain, roofs and tree crowns take the orthophoto UVs of their x/y; walls take their own
facade slot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.render.classes import ROOF, TREE, WALL
from sim.render.labels import SceneLabels
from sim.worlds.atlas import FacadeAtlas, ortho_uv
from sim.worlds.ground_cover import GroundCover
from sim.worlds.layout import Building, Layout, Tree, WorldSpec


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


def _ring_faces(upper: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """Triangles joining two rings of vertex indices (counter-clockwise from above), normals outwards."""
    u_next, l_next = np.roll(upper, -1), np.roll(lower, -1)
    return np.concatenate([np.stack([upper, lower, l_next], 1), np.stack([upper, l_next, u_next], 1)])


def tree_part(tree: Tree, rng: np.random.Generator, spec: WorldSpec, sides: int = 10) -> Part:
    """A cone (conifer) or a lumpy ellipsoid crown (broadleaf) standing on the ground, slightly sunk into it."""
    angles = np.linspace(0.0, 2 * np.pi, sides, endpoint=False) + rng.uniform(0, 2 * np.pi)
    direction = np.stack([np.cos(angles), np.sin(angles)], 1)
    if tree.conifer:
        ring_xy = tree.position + direction * tree.radius_m * rng.uniform(0.85, 1.15, (sides, 1))
        xyz = np.vstack([np.column_stack([ring_xy, np.full(sides, tree.ground_z - 0.3)]),
                         [*tree.position, tree.ground_z + tree.height_m]])
        faces = np.stack([np.arange(sides), np.roll(np.arange(sides), -1), np.full(sides, sides)], 1)
        return Part(xyz, faces, ortho_uv(xyz[:, :2], spec))
    polar = np.linspace(0.0, np.pi, 7)[1:-1]  # five rings between the poles
    lumps = rng.uniform(0.8, 1.15, (len(polar), sides, 1))
    ring_xy = tree.position + np.sin(polar)[:, None, None] * direction[None] * tree.radius_m * lumps
    center_z = tree.ground_z + tree.height_m / 2 - 0.2
    ring_z = center_z + np.cos(polar)[:, None] * tree.height_m / 2 * lumps[..., 0]
    rings_xyz = np.concatenate([ring_xy, ring_z[..., None]], -1).reshape(-1, 3)
    top, bottom = len(rings_xyz), len(rings_xyz) + 1
    xyz = np.vstack([rings_xyz, [*tree.position, center_z + tree.height_m / 2],
                     [*tree.position, center_z - tree.height_m / 2]])
    ring = np.arange(len(polar) * sides).reshape(len(polar), sides)
    faces = [np.stack([np.full(sides, top), ring[0], np.roll(ring[0], -1)], 1)]
    faces += [_ring_faces(ring[k], ring[k + 1]) for k in range(len(polar) - 1)]
    faces += [np.stack([np.full(sides, bottom), np.roll(ring[-1], -1), ring[-1]], 1)]
    return Part(xyz, np.concatenate(faces), ortho_uv(xyz[:, :2], spec))


def world_part(layout: Layout, facades: FacadeAtlas, rng: np.random.Generator,
               cover: GroundCover) -> tuple[Part, SceneLabels]:
    """The whole world: terrain, then buildings (walls and roofs), then trees; and every face's exact label.

    Terrain faces take the class of the ``cover`` at their centroid; walls and roofs are building ``i``'s object
    ``i + 1``, trees object ``B + 1 + j`` (``B`` buildings); confidence 1 everywhere.
    """
    terrain = terrain_part(layout)
    # (part, its faces' class: one id for all or one per face, its object)
    labelled = [(terrain, cover.classify(terrain.vertices[terrain.faces, :2].mean(axis=1)), 0)]
    labelled += [(wall_part(facades, i), WALL, wall.building_index + 1) for i, wall in enumerate(facades.walls)]
    labelled += [(roof_part(b, layout.spec), ROOF, i + 1) for i, b in enumerate(layout.buildings)]
    first_tree = len(layout.buildings) + 1
    labelled += [(tree_part(t, rng, layout.spec), TREE, first_tree + j) for j, t in enumerate(layout.trees)]
    counts = [len(part.faces) for part, _, _ in labelled]
    face_class = np.concatenate([np.broadcast_to(np.asarray(c, np.uint8), (n,)) for (_, c, _), n in
                                 zip(labelled, counts, strict=True)])
    face_instance = np.repeat([instance for _, _, instance in labelled], counts).astype(np.uint32)
    labels = SceneLabels(face_class, face_instance, np.ones(len(face_class), np.float32))
    return concatenate([part for part, _, _ in labelled]), labels
