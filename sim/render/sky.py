"""Sky visibility: the fraction of the sky's irradiance that reaches a surface point past the scene itself (ambient
occlusion, cosine-weighted), baked once per scene at its face corners and interpolated at render time.

``V = (1/pi) * integral over the hemisphere of visible(w) * cos(w, n) dw``: 1 on open flat ground, about 0.5 on a
wall standing on open ground (the ground hides the lower half of its sky), less in courtyards, under eaves and
crowns. A corner's point is its vertex's position with the corner's normal (:func:`corner_normals`: a box corner
keeps one normal per side, a smooth surface one per vertex, and an atlas's copies of a vertex at a chart seam are one
point); each distinct point is estimated once, with :data:`SKY_RAYS`
cosine-weighted rays per side (the stratified directions of a Fibonacci disk lifted to the hemisphere, turned by a
random angle per point so neighbouring points do not share their sampling error's pattern), each tested for
occlusion by embree over the whole scene.

A reconstruction stores its bake in the scene folder (:mod:`sim.render.sky_file`); :func:`scene_sky_visibility`
uses it where it was baked from the very mesh loaded with today's settings (:func:`baked_from`), and bakes otherwise,
storing the bake where the folder keeps it as a cache (a demo world's: ``Scene.sky_cache``).

Meshes are two-sided and their winding is not always consistent, so each point gets two values, one for the side
its winding normal points to (``front``) and one for the other; a hit takes the side that faces the ray.
"""

from __future__ import annotations

import logging
import math
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from sim.render.camera import row_dots
from sim.render.raycast import Hits, default_workers, occluded_local
from sim.render.scene import Scene, unit_face_normals
from sim.render.sky_file import SkyVisibility, StoredSky, mesh_sha256, write_sky_visibility

#: Bump when the bake computes other values from the same mesh and settings: stored bakes are then baked again.
#: 2: points are told apart by position, not vertex index (an atlas's seam vertices are one point).
BAKE_VERSION = 2
#: Rays per point and side; the standard error of V is at most 0.5 / sqrt(SKY_RAYS) (0.044 at 128).
SKY_RAYS = 128
#: Ray origins start this far off the surface along the corner normal (metres), past float32 noise and the
#: faceting of a curved surface near the vertex...
SKY_BIAS_M = 0.05
#: ...and this far into the corner's face (at most a quarter of the way to its centroid), so that a corner where
#: two surfaces meet (a wall's foot on the ground) is not sampled exactly on the other surface.
SKY_INSET_M = 0.05
#: Points per occlusion query (memory: rays x 40 bytes).
SKY_POINTS_PER_QUERY = 2048
#: Faces around a vertex that turn more than this from a corner's own face do not share its normal (a crease).
CREASE_DEG = 60.0
#: Seed of the random turn of each point's rays.
SKY_SEED = 0


def corner_normals(vertices: np.ndarray, faces: np.ndarray, crease_deg: float = CREASE_DEG) -> np.ndarray:
    """Unit normals ``(F, 3, 3)`` of every face corner: the area-weighted mean of the winding normals of the faces
    around its vertex that turn less than ``crease_deg`` from its own face (a box's corner keeps three normals, one
    per side; a smooth surface one per vertex). Vertices are told apart by index: weld those that share a position
    first (:func:`weld_by_position`) for the faces around a point."""
    corners = vertices[faces]
    weighted = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])  # length: twice the area
    unit = unit_face_normals(vertices, faces)
    vertex = faces.ravel()  # corner c = 3 * face + k
    order = np.argsort(vertex, kind="stable")
    starts = np.searchsorted(vertex[order], np.arange(len(vertices) + 1))
    first, second = _pairs_within_groups(order, starts)
    face_a, face_b = first // 3, second // 3
    smooth = np.einsum("ij,ij->i", unit[face_a], unit[face_b]) > math.cos(math.radians(crease_deg))
    sums = np.zeros((len(vertex), 3))
    np.add.at(sums, first[smooth], weighted[face_b[smooth]])
    sums /= np.maximum(np.linalg.norm(sums, axis=1, keepdims=True), 1e-300)
    return sums.reshape(-1, 3, 3)


def _pairs_within_groups(order: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every ordered pair (itself included) of corners that share a vertex: ``order`` sorts the corners by vertex,
    ``starts`` the first sorted corner of each vertex."""
    sizes = np.diff(starts)
    group = np.repeat(np.arange(len(sizes)), sizes)  # the vertex of each sorted corner
    repeats = sizes[group]
    first = np.repeat(order, repeats)
    offsets = np.arange(repeats.sum()) - np.repeat(np.cumsum(repeats) - repeats, repeats)
    second = order[np.repeat(starts[group], repeats) + offsets]
    return first, second


def hemisphere_directions(count: int) -> np.ndarray:
    """``(count, 3)`` cosine-weighted directions about +z: a Fibonacci spiral on the unit disk, lifted."""
    k = np.arange(count) + 0.5
    radius = np.sqrt(k / count)
    angle = k * math.pi * (3.0 - math.sqrt(5.0))
    x, y = radius * np.cos(angle), radius * np.sin(angle)
    return np.column_stack([x, y, np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))])


def _tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents ``(V, 3)`` perpendicular to each unit normal and to each other."""
    helper = np.where(np.abs(normals[:, [2]]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(helper, normals)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return tangent, np.cross(normals, tangent)


def bake_sky_visibility(scene: Scene, rays: int = SKY_RAYS, seed: int = SKY_SEED,
                        pool: Executor | None = None) -> SkyVisibility:
    """The sky visibility of every face corner of ``scene`` (:class:`SkyVisibility`), baked once per surface point:
    a vertex position with each of its corner normals (:func:`corner_normals` over the faces around the position, so
    the copies of a vertex that a texture atlas splits at its chart seams are one point). Reproducible from
    ``seed``."""
    vertices = scene.vertices
    faces = weld_by_position(vertices)[scene.faces]
    normals = corner_normals(vertices, faces).reshape(-1, 3)
    normals[~np.any(normals, axis=1)] = (0.0, 0.0, 1.0)
    keys = np.column_stack([faces.ravel(), np.round(normals * 1e4).astype(np.int64)])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    points, point_normals = _inset(vertices, faces, first), normals[first]
    turn = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi, len(first))
    local = hemisphere_directions(rays)
    reach = np.float32(2.0 * np.linalg.norm(scene.bounds[1] - scene.bounds[0]) + 1.0)
    values = np.empty((len(first), 2), np.float32)
    chunks = [slice(start, min(start + SKY_POINTS_PER_QUERY, len(first)))
              for start in range(0, len(first), SKY_POINTS_PER_QUERY)]

    def bake(chunk: slice) -> None:
        for side, sign in enumerate((1.0, -1.0)):
            values[chunk, side] = _visible_fraction(scene, points[chunk], point_normals[chunk] * sign, turn[chunk],
                                                    local, reach)

    context = nullcontext(pool) if pool is not None else ThreadPoolExecutor(default_workers())
    with context as executor:
        list(executor.map(bake, chunks))
    return SkyVisibility(inverse.reshape(-1, 3).astype(np.int32), values)


def weld_by_position(vertices: np.ndarray) -> np.ndarray:
    """``(V,)`` the first index of each vertex's exact position: vertices that share a position map to one index."""
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    return first[inverse.ravel()]


def _inset(vertices: np.ndarray, faces: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """ENU points ``(K, 3)`` of face corners (``3 * face + k``), each moved :data:`SKY_INSET_M` (at most a quarter
    of the way) towards its face's centroid."""
    corner_faces = faces[corners // 3]
    points = vertices[corner_faces[np.arange(len(corners)), corners % 3]]
    inward = vertices[corner_faces].mean(axis=1) - points
    length = np.linalg.norm(inward, axis=1, keepdims=True)
    step = np.minimum(SKY_INSET_M, 0.25 * length) / np.maximum(length, 1e-12)
    return points + step * inward


def _visible_fraction(scene: Scene, points: np.ndarray, normals: np.ndarray, turn: np.ndarray, local: np.ndarray,
                      reach: np.float32) -> np.ndarray:
    """The fraction of ``local`` hemisphere rays (turned by ``turn`` about each normal) that leave the scene from
    just off ``points`` along ``normals``."""
    tangent, bitangent = _tangent_frames(normals)
    cos, sin = np.cos(turn)[:, None], np.sin(turn)[:, None]
    t1, t2 = cos * tangent + sin * bitangent, cos * bitangent - sin * tangent
    directions = (local[None, :, [0]] * t1[:, None] + local[None, :, [1]] * t2[:, None]
                  + local[None, :, [2]] * normals[:, None])
    starts = scene.to_local(points + SKY_BIAS_M * normals)
    origins = np.broadcast_to(starts[:, None], directions.shape).reshape(-1, 3)
    blocked = occluded_local(scene, np.ascontiguousarray(origins, np.float32),
                             np.ascontiguousarray(directions.reshape(-1, 3), np.float32),
                             np.full(len(origins), reach, np.float32))
    return 1.0 - blocked.reshape(len(normals), -1).mean(axis=1)


def bake_settings() -> dict:
    """What :func:`scene_sky_visibility` bakes with, beyond the mesh (stored with a bake, sim/render/sky_file.py)."""
    return {"bake_version": BAKE_VERSION, "rays": SKY_RAYS, "seed": SKY_SEED, "bias_m": SKY_BIAS_M,
            "inset_m": SKY_INSET_M, "crease_deg": CREASE_DEG}


def baked_from(scene: Scene) -> dict:
    """What the sky visibility of ``scene`` depends on: its face count, the SHA-256 of its vertices and faces as loaded
    and :func:`bake_settings`."""
    return {"faces": len(scene.faces), "mesh_sha256": mesh_sha256(scene.vertices, scene.faces), **bake_settings()}


def bake_fits(stored: StoredSky | None, scene: Scene) -> bool:
    """Whether the ``stored`` sky visibility was baked from ``scene``'s very mesh with today's settings
    (:func:`baked_from`): then it holds the numbers a bake of ``scene`` gives."""
    return stored is not None and stored.baked_from == baked_from(scene)


def write_scene_sky_visibility(path: Path, scene: Scene) -> None:
    """Bake the sky visibility of ``scene`` as a render would (:func:`scene_sky_visibility`) and store it at ``path``
    with what it was baked from."""
    write_sky_visibility(path, bake_sky_visibility(scene), baked_from(scene))


def scene_sky_visibility(scene: Scene) -> SkyVisibility:
    """The scene's sky visibility, kept on the scene for its later renders: the one its folder stores
    (``scene.stored_sky``) where that was baked from this very mesh with today's settings (:func:`baked_from`), else
    baked now (:func:`bake_sky_visibility`)."""
    if scene.sky_visibility is None:
        stored, scene.stored_sky = scene.stored_sky, None
        fits = bake_fits(stored, scene)
        scene.sky_visibility = stored.visibility if fits else bake_sky_visibility(scene)
        if not fits and scene.sky_cache is not None:
            _store_in_cache(scene)
    return scene.sky_visibility


def _store_in_cache(scene: Scene) -> None:
    """Store the scene's fresh bake in its cache file (``scene.sky_cache``) for the renders after this one; a folder
    that cannot be written to only costs them the bake again (said on stderr)."""
    try:
        write_sky_visibility(scene.sky_cache, scene.sky_visibility, baked_from(scene))
    except OSError as error:
        logging.getLogger(__name__).warning("%s: sky visibility not stored, later renders bake it again (%s)",
                                            scene.sky_cache, error.strerror or error)


def sky_at(scene: Scene, hits: Hits, directions: np.ndarray) -> np.ndarray:
    """Sky visibility ``(N,)`` float32 at ray hits (all hit): the hit face's corner values on the side that faces the
    ray, mixed by the barycentric weights."""
    row = 2 * hits.tri.astype(np.intp)
    row += hits.back if hits.back is not None else row_dots(scene.face_normals.take(hits.tri, axis=0), directions) > 0
    corners = scene_sky_visibility(scene).by_face_side.take(row, axis=0)
    visibility = corners[:, 0] * (1.0 - hits.u - hits.v)
    visibility += corners[:, 1] * hits.u
    visibility += corners[:, 2] * hits.v
    return visibility
