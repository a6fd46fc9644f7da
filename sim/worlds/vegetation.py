"""Trees and hedges of the demo world as textured triangle meshes (ENU metres, z up), and their per-object truth.

- A broadleaf tree is a tapered trunk (a prism sunk :data:`SINK_M` into the ground) that goes on up into the crown as
  a leader, 4-6 main branches from the crown's base out and up, and a porous crown of leaf sprays: small cupped
  cards (two triangles folded 24 degrees along a diagonal), mostly facing up as leaves do, scattered through a
  rounded drum. Of a pool of them, as many are kept, in order, as leave :data:`BROADLEAF_GAP_FRACTION` of the
  crown's disc open from above (counted on a :data:`GAP_CELL_M` grid), so ground and branches show through its
  gaps, as under a summer park tree.
- A conifer is a trunk and whorls: stacked star-shaped double cones (a lens whose rim is a ring of needle spikes),
  each whorl's rim above the next whorl's top by :data:`WHORL_GAP_SHARE` of their spacing, so from the side the
  trunk shows between whorls.
- A hedge is a long low box of smaller sprays turned every way, kept until :data:`HEDGE_GAP_FRACTION` of its
  footprint is open from above.

Sprays are cards rather than closed blobs because they cover the most for the fewest corners: the renderer bakes
the sky's visibility once per vertex and normal (sim/render/sky.py), a blob's corners have one normal per face.
Leaves and needles take the atlas's ``leaves`` and ``needles`` patches, trunks and branches its ``bark`` patch
(sim/worlds/atlas.py), each spray or prism at its own offset and turn in the patch. Every part is a
``sim.worlds.geometry.Part`` whose vertices are all used by its faces.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import ConvexHull

from sim.worlds.atlas import VEGETATION_PATCH_PX, vegetation_patch_uv
from sim.worlds.geometry import Part, concatenate
from sim.worlds.layout import Hedge, Layout, Tree, WorldSpec

BROADLEAF_GAP_FRACTION = 0.28
"""Target share of straight-down sight lines through a broadleaf crown's disc that pass through it, counted on the
:data:`GAP_CELL_M` grid, where a cell a spray touches counts as covered: straight-down rays find ~0.30."""
HEDGE_GAP_FRACTION = 0.08
"""The same over a hedge's footprint (its sprays are smaller, so the rays find more: ~0.11)."""
LEAF_TEXTURE_M = 0.01
"""Metres of leaf or needle surface per patch texel (leaves of 5-10 cm span 5-10 texels)."""
GAP_CELL_M = 0.02
"""Cell size of the grid on which a crown's or hedge's shadow from above is drawn to count its gaps."""
SPRAY_POOL = 5.0
"""Sprays drawn for a crown per spray area (size^2) over its footprint; as many are kept as reach the target gap
fraction."""
HEDGE_SPRAY_POOL = 16.0
"""The same for a hedge, whose sprays turn every way (so each covers less from above) and whose target is denser."""
SPRAY_FOLD = 0.15
"""How far (in spray sizes) a spray's two side corners rise off its diagonal along its normal: a 24 degree fold."""
SINK_M = 0.3
"""How far trunks reach below the ground at their stem, so no slope leaves a gap under them."""
WHORL_GAP_SHARE = 0.35
"""Share of the spacing between two whorls left open between the upper one's rim and the lower one's top."""
_SUBPIXEL_BITS = 4  # cv2 drawing with 1/16 cell precision
_SPRAY_FACES = np.array([[0, 1, 2], [0, 2, 3]], np.int64)  # counter-clockwise seen from the spray's normal side


def leaf_sprays(rng: np.random.Generator, centres: np.ndarray, sizes: np.ndarray, max_tilt_deg: float,
                spec: WorldSpec) -> Part:
    """Leaf sprays at ``centres`` (N, 3): cupped cards of ``sizes`` (N,) metres by 0.7-1 of that, their normals
    tilted from the vertical by up to ``max_tilt_deg`` (uniform over that cap of directions), turned at random, each
    textured with its own window of the ``leaves`` patch at about 1:1 scale."""
    count = len(centres)
    tilt = np.arccos(rng.uniform(np.cos(np.radians(max_tilt_deg)), 1.0, count))
    azimuth, turn = rng.uniform(0.0, 2 * np.pi, (2, count))
    normal = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    helper = np.where(np.abs(normal[:, [2]]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    first = np.cross(helper, normal)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = np.cross(normal, first)
    across = np.cos(turn)[:, None] * first + np.sin(turn)[:, None] * second
    along = np.cross(normal, across)
    half = np.column_stack([sizes, sizes * rng.uniform(0.7, 1.0, count)]) / 2
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], np.float64)  # in half sizes; 1 and 3 fold up
    lift = np.array([0.0, 1.0, 0.0, 1.0]) * SPRAY_FOLD
    vertices = (centres[:, None] + corners[None, :, :1] * (half[:, None, :1] * across[:, None])
                + corners[None, :, 1:] * (half[:, None, 1:] * along[:, None])
                + lift[None, :, None] * sizes[:, None, None] * normal[:, None]).reshape(-1, 3)
    patch_m = VEGETATION_PATCH_PX * LEAF_TEXTURE_M
    reach = np.hypot(*half.T)
    scale = np.minimum(1.0, 0.45 * patch_m / reach)
    spin = rng.uniform(0.0, 2 * np.pi, count)
    flat = corners[None] * half[:, None, :] * scale[:, None, None]
    seen = np.stack([flat[..., 0] * np.cos(spin)[:, None] - flat[..., 1] * np.sin(spin)[:, None],
                     flat[..., 0] * np.sin(spin)[:, None] + flat[..., 1] * np.cos(spin)[:, None]], -1)
    room = (reach * scale)[:, None]
    st = (rng.uniform(room, patch_m - room, (count, 2))[:, None, :] + seen) / patch_m
    faces = (_SPRAY_FACES[None] + 4 * np.arange(count)[:, None, None]).reshape(-1, 3)
    return Part(vertices, faces, vegetation_patch_uv(spec, "leaves", st.reshape(-1, 2)))


def _sprays_subset(sprays: Part, kept: np.ndarray | slice) -> Part:
    """The sprays ``kept`` (a mask or slice over them) of a part made by :func:`leaf_sprays`."""
    corners = np.arange(len(sprays.vertices)).reshape(-1, 4)[kept].ravel()
    faces = (_SPRAY_FACES[None] + 4 * np.arange(len(corners) // 4)[:, None, None]).reshape(-1, 3)
    return Part(sprays.vertices[corners], faces, sprays.uv[corners])


def sprays_for_gap(fixed: list[np.ndarray], sprays_xy: np.ndarray, region: np.ndarray, gap_fraction: float) -> int:
    """How many sprays, taken in order, leave open (covered by nothing) only ``gap_fraction`` of the cells of
    ``region`` (H, W) bool seen from above; all of them when they cannot. ``sprays_xy`` (N, 4, 2): each spray's
    corners in cells of the region's grid; ``fixed``: the corners (k, 2) of the convex pieces always there (trunk,
    branches), whose shadow is their convex hull."""
    first = np.full(region.shape, len(sprays_xy), np.int32)  # per cell, the first spray covering it
    for index in range(len(sprays_xy) - 1, -1, -1):
        for triangle in _SPRAY_FACES:
            cv2.fillConvexPoly(first, _fixed_point(sprays_xy[index, triangle]), index, cv2.LINE_8, _SUBPIXEL_BITS)
    for piece in fixed:
        cv2.fillConvexPoly(first, cv2.convexHull(_fixed_point(piece)), -1, cv2.LINE_8, _SUBPIXEL_BITS)
    values = np.sort(first[region])
    closed = len(values) - int(gap_fraction * len(values))  # cells that must be covered
    return int(np.clip(values[closed - 1] + 1, 1, len(sprays_xy))) if closed > 0 else 1


def _fixed_point(cells_xy: np.ndarray) -> np.ndarray:
    """Grid coordinates (cell ``i`` spans ``[i, i + 1)``) as cv2's fixed-point pixel coordinates, int32 (k, 2)."""
    return np.round((cells_xy - 0.5) * (1 << _SUBPIXEL_BITS)).astype(np.int32)


def _points_in_crown(rng: np.random.Generator, count: int, radius_m: float, half_depth_m: float) -> np.ndarray:
    """``count`` points (count, 3) uniform in the origin-centred crown volume ``(rho / radius)^4 + (z / half_depth)^4
    <= 1`` (``rho`` the horizontal distance from its axis): a rounded drum, nearly as deep near its rim as in its
    middle, so that sprays can close the crown's edge from above as well as its middle."""
    points = np.empty((0, 3))
    while len(points) < count:
        trial = rng.uniform(-1.0, 1.0, (2 * count + 8, 3))
        inside = (trial[:, 0] ** 2 + trial[:, 1] ** 2) ** 2 + trial[:, 2] ** 4 <= 1.0
        points = np.vstack([points, trial[inside]])
    return points[:count] * [radius_m, radius_m, half_depth_m]


def prism(rng: np.random.Generator, start: np.ndarray, end: np.ndarray, radii_m: tuple[float, float],
          spec: WorldSpec, sides: int) -> Part:
    """A tapered prism (trunk or branch) from ``start`` to ``end`` (ENU), ``radii_m`` at its two ends, capped at
    ``end``; bark-textured around and along, a seam vertex pair closing the ring in texture space."""
    axis = end - start
    length = float(np.linalg.norm(axis))
    axis = axis / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    across = np.cross(axis, helper)
    across /= np.linalg.norm(across)
    beside = np.cross(axis, across)
    angles = np.linspace(0.0, 2 * np.pi, sides + 1) + rng.uniform(0, 2 * np.pi)
    ring = np.cos(angles)[:, None] * across + np.sin(angles)[:, None] * beside
    vertices = np.vstack([start + radii_m[0] * ring, end + radii_m[1] * ring, end])
    low, high, tip = np.arange(sides + 1), np.arange(sides + 1) + sides + 1, 2 * sides + 2
    faces = np.concatenate([np.stack([low[:-1], low[1:], high[1:]], 1), np.stack([low[:-1], high[1:], high[:-1]], 1),
                            np.stack([high[:-1], high[1:], np.full(sides, tip)], 1)])
    s0, t0 = rng.uniform(0.0, 0.3, 2)
    s = s0 + 0.7 * np.linspace(0.0, 1.0, sides + 1)
    st = np.vstack([np.column_stack([s, np.full(sides + 1, t0 + 0.7)]), np.column_stack([s, np.full(sides + 1, t0)]),
                    [[s0 + 0.35, t0]]])
    return Part(vertices, faces, vegetation_patch_uv(spec, "bark", st))


def _trunk_radius(tree: Tree) -> float:
    """Trunk radius at the ground, metres: thicker for taller trees."""
    return 0.06 + 0.018 * tree.height_m


def _crown_grid(tree: Tree) -> tuple[np.ndarray, np.ndarray]:
    """The cells of a crown's disc seen from above (H, W) bool, and the ENU x/y of the grid's (0, 0) corner."""
    cells = int(np.ceil(2 * tree.radius_m / GAP_CELL_M))
    corner = tree.position - cells * GAP_CELL_M / 2
    centres = (np.arange(cells) + 0.5) * GAP_CELL_M - cells * GAP_CELL_M / 2
    return np.hypot(centres[None, :], centres[:, None]) <= tree.radius_m, corner


def broadleaf_part(tree: Tree, rng: np.random.Generator, spec: WorldSpec) -> Part:
    """A broadleaf tree: trunk and leader, main branches and a porous crown of leaf sprays (module docstring), the
    whole crown within ``tree.radius_m`` of the stem and below ``tree.height_m``."""
    base = np.array([*tree.position, tree.ground_z])
    crown_base = tree.height_m * rng.uniform(0.28, 0.4)
    half_depth = (tree.height_m - crown_base) / 2
    centre = base + [0.0, 0.0, crown_base + half_depth]
    spray = float(np.clip(0.25 * tree.radius_m, 0.5, 0.9))
    trunk_r = _trunk_radius(tree)
    wood = [prism(rng, base - [0.0, 0.0, SINK_M], centre + [0.0, 0.0, 0.3 * half_depth], (trunk_r, 0.4 * trunk_r),
                  spec, sides=6)]
    branches = int(rng.integers(4, 7))
    for angle in rng.uniform(0, 2 * np.pi) + np.arange(branches) * 2 * np.pi / branches + rng.normal(0, 0.3, branches):
        reach = (tree.radius_m - spray) * rng.uniform(0.5, 0.75)
        tip = centre + [reach * np.cos(angle), reach * np.sin(angle), half_depth * rng.uniform(-0.1, 0.5)]
        start = base + [0.0, 0.0, crown_base + rng.uniform(0.0, 0.25 * half_depth)]
        wood.append(prism(rng, start, tip, (0.5 * trunk_r, 0.2 * trunk_r), spec, sides=4))
    pool = int(SPRAY_POOL * np.pi * tree.radius_m ** 2 / spray ** 2)
    centres = centre + _points_in_crown(rng, pool, tree.radius_m - 0.4 * spray, half_depth - 0.4 * spray)
    sprays = leaf_sprays(rng, centres, spray * rng.uniform(0.8, 1.0, pool), 60.0, spec)
    corners = sprays.vertices.reshape(-1, 4, 3)
    inside = (np.hypot(*(corners[..., :2] - tree.position).transpose(2, 0, 1)).max(axis=1) <= tree.radius_m) \
        & (corners[..., 2].max(axis=1) <= tree.ground_z + tree.height_m)
    sprays = _sprays_subset(sprays, inside)
    region, corner = _crown_grid(tree)
    keep = sprays_for_gap([(w.vertices[:, :2] - corner) / GAP_CELL_M for w in wood],
                          (sprays.vertices[:, :2].reshape(-1, 4, 2) - corner) / GAP_CELL_M, region,
                          BROADLEAF_GAP_FRACTION)
    return concatenate(wood + [_sprays_subset(sprays, slice(keep))])


def _whorl(rng: np.random.Generator, axis_xy: np.ndarray, top_z: float, spacing: float, radius: float,
           spec: WorldSpec, spikes: int = 8) -> Part:
    """One whorl: a lens from the trunk at ``top_z`` down to a star-shaped rim of ``spikes`` needle spikes
    (``radius`` at their tips) ``(1 - WHORL_GAP_SHARE) * spacing`` below, closed underneath; needle-textured."""
    angles = np.arange(2 * spikes) * np.pi / spikes + rng.uniform(0, 2 * np.pi)
    reach = radius * np.where(np.arange(2 * spikes) % 2 == 0, rng.uniform(0.85, 1.0, 2 * spikes), 0.5)
    rim_z = top_z - (1.0 - WHORL_GAP_SHARE) * spacing
    ring = np.column_stack([axis_xy + reach[:, None] * np.column_stack([np.cos(angles), np.sin(angles)]),
                            np.full(2 * spikes, rim_z)])
    under_z = top_z - 0.45 * (1.0 - WHORL_GAP_SHARE) * spacing
    vertices = np.vstack([ring, [*axis_xy, top_z], [*axis_xy, under_z]])
    index = np.arange(2 * spikes)
    top, under = 2 * spikes, 2 * spikes + 1
    faces = np.concatenate([np.stack([index, np.roll(index, -1), np.full(2 * spikes, top)], 1),
                            np.stack([np.roll(index, -1), index, np.full(2 * spikes, under)], 1)])
    turn = rng.uniform(0, 2 * np.pi)
    local = (vertices[:, :2] - axis_xy) / radius
    st = 0.5 + 0.45 * local @ np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    st[under] += 0.02  # the two apexes apart in texture space too
    return Part(vertices, faces, vegetation_patch_uv(spec, "needles", st))


def conifer_part(tree: Tree, rng: np.random.Generator, spec: WorldSpec) -> Part:
    """A conifer: a trunk and whorls widening downwards from the top (at exactly ``tree.height_m``) to the crown's
    base, with open gaps between them (module docstring)."""
    base = np.array([*tree.position, tree.ground_z])
    crown_base = tree.height_m * rng.uniform(0.15, 0.3)
    whorls = max(4, int(round((tree.height_m - crown_base) / 1.2)))
    spacing = (tree.height_m - crown_base) / whorls
    top = tree.ground_z + tree.height_m
    parts = [prism(rng, base - [0.0, 0.0, SINK_M], base + [0.0, 0.0, tree.height_m - 0.5 * spacing],
                   (_trunk_radius(tree), 0.3 * _trunk_radius(tree)), spec, sides=6)]
    for k in range(whorls):
        radius = tree.radius_m * (0.2 + 0.8 * (k + 1) / whorls)
        parts.append(_whorl(rng, tree.position, top - k * spacing, spacing, radius, spec))
    return concatenate(parts)


def hedge_part(hedge: Hedge, layout: Layout, rng: np.random.Generator) -> Part:
    """A hedge: leaf sprays turned every way, centred in its box from the ground to its height along the terrain
    (so they reach up to 0.3 m out of it), as many as leave :data:`HEDGE_GAP_FRACTION` of its footprint open from
    above."""
    length = float(np.linalg.norm(hedge.end - hedge.start))
    along_unit = (hedge.end - hedge.start) / length
    normal = np.array([-along_unit[1], along_unit[0]])
    spray = 0.4
    pool = int(HEDGE_SPRAY_POOL * length * hedge.width_m / spray ** 2)
    along = rng.uniform(0.0, length, pool)
    across = rng.uniform(-0.5, 0.5, pool) * hedge.width_m
    xy = hedge.start + along[:, None] * along_unit + across[:, None] * normal
    height = rng.uniform(0.3 * spray, hedge.height_m - 0.5 * spray, pool)
    centres = np.column_stack([xy, layout.terrain.height(xy[:, 0], xy[:, 1]) + height])
    sprays = leaf_sprays(rng, centres, spray * rng.uniform(0.8, 1.0, pool), 90.0, layout.spec)
    # The footprint's grid in the hedge's own frame: cells along it, across it.
    region = np.ones((int(np.ceil(hedge.width_m / GAP_CELL_M)), int(np.ceil(length / GAP_CELL_M))), bool)
    rel = sprays.vertices[:, :2] - hedge.start
    local = np.column_stack([rel @ along_unit, rel @ normal + hedge.width_m / 2]) / GAP_CELL_M
    return _sprays_subset(sprays, slice(sprays_for_gap([], local.reshape(-1, 4, 2), region, HEDGE_GAP_FRACTION)))


def vegetation_parts(layout: Layout, rng: np.random.Generator) -> list[Part]:
    """One part per tree (layout order), then one per hedge."""
    trees = [(conifer_part if t.conifer else broadleaf_part)(t, rng, layout.spec) for t in layout.trees]
    return trees + [hedge_part(h, layout, rng) for h in layout.hedges]


def _object_faces(face_instance: np.ndarray, instances: np.ndarray) -> list[np.ndarray]:
    """For each of ``instances``, the indices of its faces."""
    order = np.argsort(face_instance, kind="stable")
    bounds = np.searchsorted(face_instance[order], np.stack([instances, instances + 1]))
    return [order[a:b] for a, b in bounds.T]


def _footprint(points_xy: np.ndarray) -> list[list[float]]:
    """The convex hull, counter-clockwise, of ``points_xy`` (M, 2) rounded to the centimetre (so no point lies more
    than 7 mm outside it)."""
    rounded = np.round(points_xy, 2)
    return rounded[ConvexHull(rounded).vertices].tolist()


def vegetation_truth(layout: Layout, vertices: np.ndarray, faces: np.ndarray, face_instance: np.ndarray,
                     first_instance: int) -> dict:
    """What the benchmarks need per tree, hedge and forest stand, from the built mesh (ENU metres) and its faces'
    objects: trees are objects ``first_instance + j``, hedges follow them (see docs/demo-world.md)."""
    count = len(layout.trees)
    instances = first_instance + np.arange(count + len(layout.hedges))
    own = _object_faces(face_instance, instances)
    trees = []
    for tree, instance, tree_faces in zip(layout.trees, instances[:count], own[:count], strict=True):
        points = vertices[np.unique(faces[tree_faces])]
        trees.append({
            "instance": int(instance), "kind": "conifer" if tree.conifer else "broadleaf", "forest": tree.forest,
            "position_m": np.round(tree.position, 3).tolist(), "ground_z_m": round(tree.ground_z, 4),
            "top_height_m": round(float(points[:, 2].max()) - tree.ground_z, 4),
            "crown_radius_m": round(tree.radius_m, 4), "crown_footprint_m": _footprint(points[:, :2]),
        })
    hedges = []
    for hedge, instance, hedge_faces in zip(layout.hedges, instances[count:], own[count:], strict=True):
        points = vertices[np.unique(faces[hedge_faces])]
        hedges.append({"instance": int(instance), "start_m": np.round(hedge.start, 3).tolist(),
                       "end_m": np.round(hedge.end, 3).tolist(), "width_m": round(hedge.width_m, 3),
                       "height_m": round(hedge.height_m, 3), "top_z_m": round(float(points[:, 2].max()), 4)})
    forest_instances = [t["instance"] for t in trees if t["forest"]]
    forests = [{"corners_m": np.round(f.corners, 3).tolist(), "tree_instances": forest_instances}
               for f in layout.forests]
    return {"trees": trees, "hedges": hedges, "forest_stands": forests}
