"""Closest-hit and occlusion queries on a :class:`sim.render.scene.Scene`, in contiguous row blocks on threads.

embreex (>= 4.4) releases the GIL inside ``run()``, so a thread pool casting contiguous blocks of
image-ordered rays uses every core without copying rays to other processes (``tools/bench/bench_render.py``
measures threads against processes). Inputs are ENU float64; they are recentred in float64 and cast to
float32 here, the only place rays meet embree.
"""

from __future__ import annotations

import os
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass

import numpy as np

from sim.render.camera import row_dots
from sim.render.scene import Scene

#: embree's "no hit" distance.
_EMBREE_MISS = 1e30
#: Direction change for re-casting a missed ray (see :func:`_recast_misses`), for unit directions.
RECAST_NUDGE = np.array([3e-6, -2e-6, 1e-6], np.float32)
#: Contiguous blocks per worker thread: enough to balance far (costly) and near rows, few enough to keep
#: per-call overhead small (research notes: 8-32 blocks per frame beat halves and 128 blocks).
BLOCKS_PER_WORKER = 8
#: Rays per block are at least this many (small queries run as one block).
MIN_BLOCK_RAYS = 16384


@dataclass(frozen=True)
class Hits:
    """Closest hits of N rays: ``t`` ray parameter (float32, +inf on miss; metres for unit directions),
    ``tri`` triangle index into ``scene.faces`` (int32, -1 on miss), barycentrics ``u, v`` (float32; the hit
    is ``(1-u-v)*v0 + u*v1 + v*v2``) and ``normal`` unit geometric normals (float32 ENU, facing back along the ray; 0 on miss).
    ``back``: True where the ray meets the side of the face its winding normal points away from (None: not known).
    """

    t: np.ndarray
    tri: np.ndarray
    u: np.ndarray
    v: np.ndarray
    normal: np.ndarray
    back: np.ndarray | None = None

    @property
    def hit(self) -> np.ndarray:
        """Boolean mask of rays that hit something."""
        return self.tri >= 0


def default_workers() -> int:
    """Threads to cast with: the CPUs this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def block_slices(n_rays: int, workers: int) -> list[slice]:
    """Split ``range(n_rays)`` into contiguous blocks (image order is kept inside each block)."""
    n_blocks = max(1, min(workers * BLOCKS_PER_WORKER, n_rays // MIN_BLOCK_RAYS))
    edges = np.linspace(0, n_rays, n_blocks + 1).astype(int)
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def map_blocks(function, n_rays: int, pool: Executor | None) -> None:
    """Call ``function(block)`` for every block, on ``pool`` (or a transient thread pool); a query small
    enough for one block runs in the calling thread."""
    blocks = block_slices(n_rays, default_workers())
    if len(blocks) == 1:
        function(blocks[0])
        return
    context = nullcontext(pool) if pool is not None else ThreadPoolExecutor(default_workers())
    with context as executor:
        for future in [executor.submit(function, block) for block in blocks]:
            future.result()


def _as_rays32(scene: Scene, origins_enu: np.ndarray,
               directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Recentred float32 origins and float32 directions, each ``(N, 3)`` or one shared ``(1, 3)`` row, and the
    number of rays ``N`` (0 where either side has no rows: a shared row with nothing to pair is no ray)."""
    origins = scene.to_local(origins_enu).reshape(-1, 3)
    dirs = np.asarray(directions).reshape(-1, 3)
    if not np.all(np.isfinite(dirs)):
        raise ValueError("ray directions must be finite")
    dirs = dirs.astype(np.float32, copy=False)
    if len(origins) != len(dirs) and 1 not in (len(origins), len(dirs)):
        raise ValueError(f"{len(origins)} ray origins do not match {len(dirs)} directions")
    return origins, dirs, len(dirs) if len(origins) == 1 else len(origins)


def _rows(array: np.ndarray, block: slice) -> np.ndarray:
    """Rows ``block`` of a per-ray array, or the shared row broadcast to the block's length."""
    if len(array) == 1:
        return np.broadcast_to(array, (block.stop - block.start, 3))
    return array[block]


def intersect(scene: Scene, origins_enu: np.ndarray, directions: np.ndarray, pool: Executor | None = None) -> Hits:
    """Closest hit of every ray ``origin + t * direction`` (ENU; ``(N, 3)`` or a shared ``(1, 3)`` origin).

    Normals are flipped to face back along the ray (meshes are two-sided).
    """
    origins, dirs, n = _as_rays32(scene, origins_enu, directions)
    t = np.empty(n, np.float32)
    tri = np.empty(n, np.int32)
    u = np.empty(n, np.float32)
    v = np.empty(n, np.float32)
    normal = np.empty((n, 3), np.float32)
    back = np.empty(n, bool)

    def cast(block: slice) -> None:
        hits = intersect_local(scene, _rows(origins, block), _rows(dirs, block))
        t[block], tri[block], u[block], v[block], normal[block] = hits.t, hits.tri, hits.u, hits.v, hits.normal
        back[block] = hits.back

    map_blocks(cast, n, pool)
    return Hits(t, tri, u, v, normal, back)


def from_above(scene: Scene, xy: np.ndarray, T_world_scene: np.ndarray | None = None,
               pool: Executor | None = None) -> tuple[np.ndarray, Hits]:
    """The first surface of ``scene`` straight down (world -z) through each world ``(x, y)`` (``(N, 2)``, m): its
    world height (ENU z, m; NaN where nothing is hit) and the hits (in the scene's frame; ``t`` in scene units).
    ``T_world_scene``: the similarity ``[s R | t]`` (4x4) placing the scene's ENU frame in the world's (None: the
    scene is in the world's frame). The rays start 1 m above the whole scene."""
    T = np.eye(4) if T_world_scene is None else np.asarray(T_world_scene, dtype=np.float64)
    scale = float(np.cbrt(np.linalg.det(T[:3, :3])))
    rotation, shift = T[:3, :3] / scale, T[:3, 3]
    corners = np.stack(np.meshgrid(*scene.bounds.T, indexing="ij"), axis=-1).reshape(-1, 3)
    top = float((corners @ T[:3, :3].T + shift)[:, 2].max()) + 1.0
    origins = np.column_stack([np.asarray(xy, dtype=np.float64).reshape(-1, 2), np.full(len(xy), top)])
    hits = intersect(scene, (origins - shift) @ rotation / scale, (rotation.T @ [0.0, 0.0, -1.0])[None], pool)
    return np.where(hits.hit, top - scale * hits.t.astype(np.float64), np.nan), hits


def intersect_local(scene: Scene, origins32: np.ndarray, directions32: np.ndarray) -> Hits:
    """Single-threaded :func:`intersect` on recentred float32 inputs (:meth:`Scene.to_local`), both ``(N, 3)``
    (a shared row may be broadcast to ``(N, 3)``)."""
    out = scene.embree.run(origins32, directions32, output=1)
    _recast_misses(scene, origins32, directions32, out)
    tri, t, ng = out["primID"], out["tfar"], out["Ng"]
    with np.errstate(divide="ignore"):
        scale = np.float32(1.0) / np.sqrt(row_dots(ng, ng))
    back = row_dots(ng, directions32) > 0  # embree's Ng is the winding normal (v1 - v0) x (v2 - v0)
    np.negative(scale, out=scale, where=back)
    miss = tri < 0
    if miss.any():
        t[miss], out["u"][miss], out["v"][miss], scale[miss] = np.inf, 0.0, 0.0, 0.0
    scale[~np.isfinite(scale)] = 0.0  # a zero-length normal (float32 sliver)
    for axis in range(3):
        ng[:, axis] *= scale
    return Hits(t, tri, out["u"], out["v"], ng, back)


def _recast_misses(scene: Scene, origins32: np.ndarray, dirs32: np.ndarray, out: dict) -> None:
    """Cast every missed ray once more with its direction nudged by ~4e-6 rad and keep the hits, in place.

    Even in robust mode embree lets ~1e-4 of the rays aimed exactly at a shared vertex through
    (research notes; RenderKit/embree#387). A nudged ray crosses the interior of a neighbouring
    triangle instead, so a miss is only reported when both rays miss (sky stays sky).
    """
    missed = np.flatnonzero(out["primID"] < 0)
    if missed.size == 0:
        return
    nudged = dirs32[missed] + RECAST_NUDGE
    again = scene.embree.run(np.ascontiguousarray(origins32[missed]), nudged, output=1)
    found = again["primID"] >= 0
    for key in ("primID", "geomID", "tfar", "u", "v", "Ng"):
        out[key][missed[found]] = again[key][found]


def occluded_local(scene: Scene, origins32: np.ndarray, directions32: np.ndarray, tfar32: np.ndarray) -> np.ndarray:
    """Single-threaded occlusion test on recentred float32 inputs (:meth:`Scene.to_local`): True where the
    segment ``origin + t * direction``, ``0 <= t < tfar``, hits the scene. ``directions32`` may be ``(1, 3)``."""
    # OCCLUDED returns 0 for blocked, -1 for free. Never pass output= here (embreex drops the result).
    result = scene.embree.run(origins32, directions32, dists=np.array(tfar32, dtype=np.float32), query="OCCLUDED")
    return result == 0


def occluded(
    scene: Scene,
    origins_enu: np.ndarray,
    directions: np.ndarray,
    max_distance: np.ndarray | float | None = None,
    pool: Executor | None = None,
) -> np.ndarray:
    """True where the segment ``origin + t * direction``, ``0 <= t < max_distance``, hits the scene.

    ``origins_enu`` and ``directions`` are ``(N, 3)`` or one shared ``(1, 3)`` row (e.g. towards the sun).
    embree's tnear is fixed at 0, so callers offset origins off the surface they start on.
    """
    origins, dirs, n = _as_rays32(scene, origins_enu, directions)
    limit = _EMBREE_MISS if max_distance is None else max_distance
    tfar = np.broadcast_to(np.asarray(limit, dtype=np.float32), (n,))
    blocked = np.empty(n, bool)

    def cast(block: slice) -> None:
        block_dirs = dirs if len(dirs) == 1 else dirs[block]
        blocked[block] = occluded_local(scene, _rows(origins, block), block_dirs, tfar[block])

    map_blocks(cast, n, pool)
    return blocked
