"""Render a rig's views of a scene: RGB, planar depth, ray distance, normals and a valid mask per camera.

Pipeline (whole numpy arrays, contiguous row blocks on a thread pool): camera rays -> closest hits ->
one shadow ray towards the sun per lit, sun-facing sample -> texture + Lambert shading (sky on misses)
-> film (average of the samples, exposure, 8-bit sRGB). Depth, distance and normals always come from
the pixel-centre ray, never from averaged samples (an average across an edge is a depth nobody sees).
"""

from __future__ import annotations

import time
from collections import defaultdict
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass

import numpy as np

from sim.camera import PinholeCamera, Rays, Rig, camera_rays, stratified_offsets
from sim.raycast import Hits, default_workers, intersect, map_blocks, occluded_local
from sim.scene import Scene
from sim.shade import Lighting, Sun, lambert, sky_radiance, surface_albedo, to_srgb8

__all__ = ["Frame", "Lighting", "Sun", "View", "miss_fraction", "render"]

#: Shadow-ray origins are pushed off the surface by this much plus a float32-precision term: the relative
#: factor times (ray length + the largest recentred coordinate in the scene) (metres).
SHADOW_BIAS_M = 1e-3
SHADOW_BIAS_RELATIVE = 4e-6


@dataclass(frozen=True)
class View:
    """One camera's image: ``rgb`` (H, W, 3) uint8 sRGB; ``depth`` planar z and ``distance`` ray length
    (H, W) float32 metres, +inf on miss; ``normal`` (H, W, 3) float32 ENU unit normals facing the camera
    (0 on miss); ``valid`` (H, W) bool (something was hit); the camera and its pose ``T_world_cam``."""

    rgb: np.ndarray
    depth: np.ndarray
    distance: np.ndarray
    normal: np.ndarray
    valid: np.ndarray
    camera: PinholeCamera
    T_world_cam: np.ndarray


@dataclass(frozen=True)
class Frame:
    """All views of one rig pose, in rig camera order, with the pose and sun they were rendered with."""

    views: tuple[View, ...]
    T_world_rig: np.ndarray
    sun: Sun


class StageTimes(defaultdict):
    """Wall-clock seconds per render stage ("rays", "cast", "shadows", "shade", "film"), summed over calls."""

    def __init__(self) -> None:
        super().__init__(float)

    @contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self[name] += time.perf_counter() - start


def render(
    scene: Scene,
    rig: Rig,
    T_world_rig: np.ndarray,
    sun: Sun,
    samples_per_pixel: int = 1,
    *,
    lighting: Lighting = Lighting(),
    rng: np.random.Generator | None = None,
    pool: Executor | None = None,
    timings: StageTimes | None = None,
) -> Frame:
    """Render every camera of ``rig`` at ``T_world_rig`` (4x4 rig-to-world, scene ENU) under ``sun``.

    ``samples_per_pixel`` > 1 supersamples with stratified jitter (seeded by ``rng``, default seed 0);
    1 samples the pixel centre. ``pool`` is the executor to cast and shade on (default: a thread per CPU);
    ``timings`` collects wall-clock seconds per stage.
    """
    timings = timings if timings is not None else StageTimes()
    rng = rng if rng is not None else np.random.default_rng(0)
    context = nullcontext(pool) if pool is not None else ThreadPoolExecutor(default_workers())
    with context as executor:
        views = tuple(
            _render_view(scene, camera, T_world_cam, sun, samples_per_pixel, lighting, rng, executor, timings)
            for camera, T_world_cam in zip(rig.cameras, rig.camera_poses(T_world_rig))
        )
    return Frame(views, np.asarray(T_world_rig, dtype=np.float64), sun)


def _render_view(scene, camera, T_world_cam, sun, spp, lighting, rng, executor, timings) -> View:
    """One camera: centre rays give depth/normals (and the colour at 1 spp), jittered samples the colour."""
    with timings.stage("rays"):
        centre = camera_rays(camera, T_world_cam)
    with timings.stage("cast"):
        centre_hits = intersect(scene, centre.origin, centre.directions, executor)
    if spp == 1:
        radiance = _radiance(scene, centre, centre_hits, sun, lighting, executor, timings)
    else:
        radiance = 0.0
        for offsets in stratified_offsets(spp, camera.width * camera.height, rng):
            with timings.stage("rays"):
                rays = camera_rays(camera, T_world_cam, offsets)
            with timings.stage("cast"):
                hits = intersect(scene, rays.origin, rays.directions, executor)
            radiance = radiance + _radiance(scene, rays, hits, sun, lighting, executor, timings)
        radiance = radiance / np.float32(spp)
    with timings.stage("film"):
        shape = camera.shape
        return View(
            rgb=to_srgb8(radiance).reshape(*shape, 3),
            depth=np.where(centre_hits.hit, centre_hits.t * centre.depth_scale, np.inf).astype(np.float32).reshape(shape),
            distance=centre_hits.t.reshape(shape),
            normal=centre_hits.normal.reshape(*shape, 3),
            valid=centre_hits.hit.reshape(shape),
            camera=camera,
            T_world_cam=T_world_cam,
        )


def _radiance(scene, rays: Rays, hits: Hits, sun: Sun, lighting: Lighting, executor, timings) -> np.ndarray:
    """Linear radiance ``(N, 3)`` of one sample per ray: shaded surface where hit, sky where missed."""
    with timings.stage("shadows"):
        lit = _sunlit(scene, rays, hits, sun, lighting, executor)
    with timings.stage("shade"):
        radiance = np.empty((len(hits.t), 3), np.float32)

        def shade(block: slice) -> None:
            hit = hits.tri[block] >= 0
            out = radiance[block]
            if not hit.all():
                out[~hit] = sky_radiance(rays.directions[block][~hit], lighting) * np.float32(lighting.exposure)
            else:
                hit = slice(None)  # all rays hit: views instead of copies
            albedo = surface_albedo(scene, hits.tri[block][hit], hits.u[block][hit], hits.v[block][hit])
            out[hit] = lambert(albedo, hits.normal[block][hit], sun, lit[block][hit], lighting)

        map_blocks(shade, len(hits.t), executor)
    return radiance


def _sunlit(scene: Scene, rays: Rays, hits: Hits, sun: Sun, lighting: Lighting, executor) -> np.ndarray:
    """1.0 where a hit sees the sun, 0.0 elsewhere (float32, per ray).

    Only hits whose (camera-facing) normal faces the sun get a shadow ray - the others are self-shadowed -
    and a shadow ray only has to reach the top of the scene's bounding box: nothing above it can occlude.
    """
    lit = np.zeros(len(hits.t), np.float32)
    if sun.elevation_deg <= 0:
        return lit
    sun_dir = sun.direction_enu
    sun32 = sun_dir.astype(np.float32)
    origin_local = (rays.origin - scene.centre_m).astype(np.float32)
    top_local = scene.bounds[1, 2] - scene.centre_m[2]
    # Hits lie inside the scene's box, so no recentred coordinate exceeds its half-extent.
    largest_coordinate = float(np.abs(scene.bounds - scene.centre_m).max())

    def trace(block: slice) -> None:
        normals = hits.normal[block]
        facing = (hits.tri[block] >= 0) & (np.einsum("ij,j->i", normals, sun32) > 0)
        if not lighting.shadows:
            lit[block][facing] = 1.0
            return
        # Every ray of the block is traced in image order (coherent); the others get a negative reach,
        # which embree skips, cheaper than gathering the candidates out and back.
        t = np.where(facing, hits.t[block], np.float32(0.0))
        starts = rays.directions[block] * t[:, None]
        starts += origin_local
        bias = np.float32(SHADOW_BIAS_M + SHADOW_BIAS_RELATIVE * largest_coordinate) + np.float32(SHADOW_BIAS_RELATIVE) * t
        starts += bias[:, None] * normals
        reach = np.maximum((np.float32(top_local) - starts[:, 2]) / sun32[2], 0.0) + np.float32(1.0)
        reach[~facing] = -1.0
        lit[block][facing & ~occluded_local(scene, starts, sun32[None], reach)] = 1.0

    map_blocks(trace, len(hits.t), executor)
    return lit


def miss_fraction(scene: Scene, camera: PinholeCamera, T_world_cam: np.ndarray, probe_width: int = 64) -> float:
    """Fraction of ``camera``'s view at ``T_world_cam`` that sees no surface (sky), estimated by casting the
    pixel-centre rays of the same lens scaled down to ``probe_width`` pixels across (cheap: 64 px wide is
    ~2.3 k rays for 16:9). For pose samplers: ``functools.partial(miss_fraction, scene, camera)``."""
    probe = camera.scaled(probe_width)
    rays = camera_rays(probe, T_world_cam)
    hits = intersect(scene, rays.origin, rays.directions)
    return float(np.count_nonzero(~hits.hit)) / len(hits.t)
