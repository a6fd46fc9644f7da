"""Render a rig's views of a scene: RGB, planar depth, ray distance, normals, the triangle hit and a valid mask per
camera.

Pipeline, run on contiguous image-order blocks of pixels, each block through every stage on one thread of a
pool: camera rays -> closest hits -> one shadow ray towards the sun per sun-facing hit -> texture + Lambert
shading (sky on misses) -> film (average of the samples, exposure, 8-bit sRGB). Depth, distance and normals always come from
the pixel-centre ray, never from averaged samples (an average across an edge is a depth nobody sees).
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass

import numpy as np

from sim.render.camera import PinholeCamera, Rays, Rig, camera_rays, row_dots, stratified_offsets
from sim.render.raycast import Hits, default_workers, intersect, intersect_local, occluded_local
from sim.render.scene import Scene
from sim.render.shade import (Lighting, Sun, as_captured, lambert, sky_radiance, surface_albedo,
                              surface_capture_light)
from sim.render.sky import scene_sky_visibility, sky_at
from sim.render.color import to_srgb8

__all__ = ["Frame", "Lighting", "Sun", "View", "miss_fraction", "render"]

#: Shadow-ray origins are pushed off the surface by this much plus a float32-precision term: the relative
#: factor times (ray length + the largest recentred coordinate in the scene) (metres).
SHADOW_BIAS_M = 1e-3
SHADOW_BIAS_RELATIVE = 4e-6


@dataclass(frozen=True)
class View:
    """One camera's image: ``rgb`` (H, W, 3) uint8 sRGB; ``depth`` planar z and ``distance`` ray length
    (H, W) float32 metres, +inf on miss; ``normal`` (H, W, 3) float32 ENU unit normals facing the camera
    (0 on miss); ``triangle`` (H, W) int32 the index into ``scene.faces`` of the face hit (-1 on miss: what class
    and instance images look up, :class:`sim.render.labels.SceneLabels`); ``valid`` (H, W) bool (something was hit);
    the camera and its pose ``T_world_cam``."""

    rgb: np.ndarray
    depth: np.ndarray
    distance: np.ndarray
    normal: np.ndarray
    triangle: np.ndarray
    valid: np.ndarray
    camera: PinholeCamera
    T_world_cam: np.ndarray

    def camera_normal(self) -> np.ndarray:
        """``normal`` in the camera frame (OpenCV axes: x right, y down, z forward), (H, W, 3) float32 unit vectors
        facing the camera (negative z), 0 on miss."""
        rotation = np.asarray(self.T_world_cam, dtype=np.float64)[:3, :3]
        return (self.normal.reshape(-1, 3) @ rotation.astype(np.float32)).reshape(self.normal.shape)


@dataclass(frozen=True)
class Frame:
    """All views of one rig pose, in rig camera order, with the pose and sun they were rendered with."""

    views: tuple[View, ...]
    T_world_rig: np.ndarray
    sun: Sun


#: Most pixels per render task. A view is split into contiguous image-order runs of this many pixels, and each run
#: goes through every stage (rays, hits, shadow rays, shading, film) on one thread while its arrays are still in
#: cache, with no barrier between stages. Fixed, so supersampled images do not depend on the number of CPUs.
BLOCK_PIXELS = 131072
#: Bytes per pixel of one view's output arrays (rgb 3, depth 4, distance 4, normal 12, triangle 4, valid 1); see
#: ``_ViewImages``.
VIEW_BYTES_PER_PIXEL = 28


def render_memory_bytes(pixels_per_view: Sequence[int], samples_per_pixel: int, threads: int) -> int:
    """Peak memory (bytes) of one :func:`render` call: every view's output arrays, plus, when supersampling, one
    block's stratified sample pattern per busy thread (2 bytes per sample and pixel, twice while it is permuted)."""
    outputs = VIEW_BYTES_PER_PIXEL * sum(pixels_per_view)
    if samples_per_pixel == 1:
        return outputs
    return outputs + threads * 2 * 2 * samples_per_pixel * min(BLOCK_PIXELS, max(pixels_per_view))


class StageTimes(defaultdict):
    """Seconds per render stage ("rays", "cast", "shadows", "shade", "film"), summed over calls and over the
    render tasks (thread time: on N busy threads the stages add up to about N times the wall-clock time)."""

    def __init__(self) -> None:
        super().__init__(float)

    @contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self[name] += time.perf_counter() - start

    def add(self, other: "StageTimes") -> None:
        """Add another task's stage times to these."""
        for name, seconds in other.items():
            self[name] += seconds


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
    1 samples the pixel centre. ``pool`` is the executor to render on (default: a thread per CPU);
    ``timings`` collects seconds per stage (:class:`StageTimes`).
    """
    if samples_per_pixel < 1:
        raise ValueError(f"samples_per_pixel must be at least 1, got {samples_per_pixel}")
    if not lighting.as_captured:
        scene_sky_visibility(scene)  # baked here, once, before the render threads read it
    rng = rng if rng is not None else np.random.default_rng(0)
    seed = int(rng.integers(2**63)) if samples_per_pixel > 1 else 0
    targets = [
        _ViewImages(camera, T_world_cam, seed=(seed, index))
        for index, (camera, T_world_cam) in enumerate(zip(rig.cameras, rig.camera_poses(T_world_rig)))
    ]
    tasks = [(target, pixels) for target in targets for pixels in target.blocks()]

    def run(task) -> StageTimes:
        return _render_pixels(scene, *task, sun, samples_per_pixel, lighting)

    context = nullcontext(pool) if pool is not None else ThreadPoolExecutor(default_workers())
    with context as executor:
        for task_times in executor.map(run, tasks):
            if timings is not None:
                timings.add(task_times)
    return Frame(tuple(target.view() for target in targets), np.asarray(T_world_rig, dtype=np.float64), sun)


class _ViewImages:
    """The output arrays of one camera's view, filled block by block by :func:`_render_pixels`."""

    def __init__(self, camera: PinholeCamera, T_world_cam: np.ndarray, seed: tuple[int, int]) -> None:
        self.camera, self.T_world_cam, self.seed = camera, T_world_cam, seed
        n = camera.width * camera.height
        self.rgb = np.empty((n, 3), np.uint8)
        self.depth = np.empty(n, np.float32)
        self.distance = np.empty(n, np.float32)
        self.normal = np.empty((n, 3), np.float32)
        self.triangle = np.empty(n, np.int32)
        self.valid = np.empty(n, bool)

    def blocks(self) -> list[slice]:
        """The contiguous image-order pixel runs this view is rendered in: equal, of at most :data:`BLOCK_PIXELS`."""
        n = len(self.valid)
        edges = np.linspace(0, n, -(-n // BLOCK_PIXELS) + 1).astype(int)
        return [slice(start, stop) for start, stop in zip(edges[:-1], edges[1:])]

    def store(self, pixels: slice, radiance: np.ndarray, centre: Rays, centre_hits: Hits) -> None:
        """Film: 8-bit sRGB of the averaged radiance, and depth, distance, normals, triangles, validity of the centre
        rays."""
        self.rgb[pixels] = to_srgb8(radiance)
        self.depth[pixels] = np.where(centre_hits.hit, centre_hits.t * centre.depth_scale, np.float32(np.inf))
        self.distance[pixels] = centre_hits.t
        self.normal[pixels] = centre_hits.normal
        self.triangle[pixels] = centre_hits.tri
        self.valid[pixels] = centre_hits.hit

    def view(self) -> View:
        shape = self.camera.shape
        return View(
            rgb=self.rgb.reshape(*shape, 3), depth=self.depth.reshape(shape), distance=self.distance.reshape(shape),
            normal=self.normal.reshape(*shape, 3), triangle=self.triangle.reshape(shape), valid=self.valid.reshape(shape),
            camera=self.camera,
            T_world_cam=self.T_world_cam,
        )


def _render_pixels(scene, images: _ViewImages, pixels: slice, sun, spp, lighting) -> StageTimes:
    """Render one run of pixels through every stage (one thread); centre rays give depth and normals (and the
    colour at 1 spp), jittered samples the colour. Returns the seconds spent per stage."""
    times = StageTimes()
    camera, T_world_cam = images.camera, images.T_world_cam
    with times.stage("rays"):
        centre = camera_rays(camera, T_world_cam, pixels=pixels)
    with times.stage("cast"):
        origin = scene.to_local(centre.origin)
        centre_hits = intersect_local(scene, np.broadcast_to(origin, centre.directions.shape), centre.directions)
    if spp == 1:
        radiance = _radiance(scene, origin, centre, centre_hits, sun, lighting, times)
    else:
        radiance = np.zeros((len(centre_hits.t), 3), np.float32)
        rng = np.random.default_rng((*images.seed, pixels.start))
        for offsets in stratified_offsets(spp, len(centre_hits.t), rng):
            with times.stage("rays"):
                rays = camera_rays(camera, T_world_cam, offsets, pixels=pixels)
            with times.stage("cast"):
                hits = intersect_local(scene, np.broadcast_to(origin, rays.directions.shape), rays.directions)
            radiance += _radiance(scene, origin, rays, hits, sun, lighting, times)
        radiance /= np.float32(spp)
    with times.stage("film"):
        images.store(pixels, radiance, centre, centre_hits)
    return times


def _radiance(scene, origin32, rays: Rays, hits: Hits, sun: Sun, lighting: Lighting, times) -> np.ndarray:
    """Linear radiance ``(N, 3)`` of one sample per ray: shaded surface where hit, sky where missed."""
    with times.stage("shadows"):
        lit = None if lighting.as_captured else _sunlit(scene, origin32, rays, hits, sun, lighting)
    with times.stage("shade"):
        hit = hits.hit
        if hit.all():  # views instead of copies, and the radiance written in place
            return _surface_radiance(scene, hits, rays.directions, sun, lit, lighting)
        radiance = np.empty((len(hits.t), 3), np.float32)
        radiance[~hit] = sky_radiance(rays.directions[~hit], lighting) * lighting.channel_exposure
        surface = Hits(hits.t[hit], hits.tri[hit], hits.u[hit], hits.v[hit], hits.normal[hit], hits.back[hit])
        radiance[hit] = _surface_radiance(scene, surface, rays.directions[hit], sun,
                                          None if lit is None else lit[hit], lighting)
    return radiance


def _surface_radiance(scene: Scene, hits: Hits, directions: np.ndarray, sun: Sun, lit: np.ndarray | None,
                      lighting: Lighting) -> np.ndarray:
    """Linear radiance ``(N, 3)`` of surface hits (all hit), written over their albedo: as captured, or lit by the sun
    (``lit``: its visibility) and the sky."""
    albedo = surface_albedo(scene, hits.tri, hits.u, hits.v)
    if lighting.as_captured:
        return as_captured(albedo, surface_capture_light(scene, hits.tri, hits.u, hits.v), lighting, out=albedo)
    return lambert(albedo, hits.normal, sun, lit, lighting, sky_at(scene, hits, directions), out=albedo)


def _sunlit(scene: Scene, origin32: np.ndarray, rays: Rays, hits: Hits, sun: Sun, lighting: Lighting) -> np.ndarray:
    """1.0 where a hit sees the sun, 0.0 elsewhere (float32, per ray; ``origin32`` the rays' recentred origin).

    Only hits whose (camera-facing) normal faces the sun get a shadow ray - the others are self-shadowed -
    and a shadow ray only has to reach the top of the scene's bounding box: nothing above it can occlude.
    Every ray is traced in image order (coherent); rays without a shadow ray get a negative reach, which embree
    skips, cheaper than gathering the candidates out and back.
    """
    lit = np.zeros(len(hits.t), np.float32)
    if sun.elevation_deg <= 0:
        return lit
    sun32 = sun.direction_enu.astype(np.float32)
    facing = hits.hit & (row_dots(hits.normal, sun32) > 0)
    if not lighting.shadows:
        lit[facing] = 1.0
        return lit
    # Hits lie inside the scene's box, so no recentred coordinate exceeds its half-extent.
    largest_coordinate = float(np.abs(scene.bounds - scene.centre_m).max())
    top_local = np.float32(scene.bounds[1, 2] - scene.centre_m[2])
    t = np.where(facing, hits.t, np.float32(0.0))
    bias = np.float32(SHADOW_BIAS_M + SHADOW_BIAS_RELATIVE * largest_coordinate) + np.float32(SHADOW_BIAS_RELATIVE) * t
    starts = np.empty_like(hits.normal)
    for axis in range(3):  # origin + t * direction + bias * normal, by columns (2x faster than broadcasting rows)
        column = starts[:, axis]
        np.multiply(rays.directions[:, axis], t, out=column)
        column += origin32[0, axis]
        column += bias * hits.normal[:, axis]
    reach = np.maximum((top_local - starts[:, 2]) / sun32[2], np.float32(0.0)) + np.float32(1.0)
    reach[~facing] = -1.0
    lit[facing & ~occluded_local(scene, starts, sun32[None], reach)] = 1.0
    return lit


def miss_fraction(scene: Scene, camera: PinholeCamera, T_world_cam: np.ndarray, probe_width: int = 64) -> float:
    """Fraction of ``camera``'s view at ``T_world_cam`` that sees no surface (sky), estimated by casting the
    pixel-centre rays of the same lens scaled down to ``probe_width`` pixels across (cheap: 64 px wide is
    ~2.3 k rays for 16:9). For pose samplers: ``functools.partial(miss_fraction, scene, camera)``."""
    probe = camera.scaled(probe_width)
    rays = camera_rays(probe, T_world_cam)
    hits = intersect(scene, rays.origin, rays.directions)
    return float(np.count_nonzero(~hits.hit)) / len(hits.t)
