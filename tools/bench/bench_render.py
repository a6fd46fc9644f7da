"""Benchmark the stereo renderer: time per stereo frame by stage, ray throughput, threads vs processes,
and samples per pixel against image error.

    .venv/bin/python tools/bench/bench_render.py [--cells 1000] [--frames 3] [--scene DIR]

Scene: a ``2 * cells**2``-triangle height field over 1 km (default 2 M triangles, 1 m cells) and, with
``--scene``, any scene folder (e.g. the demo world written by ``sim.worlds``). Camera: 1280x720,
fx = fy = 1100 px, 400 m above the ground pitched 45 degrees down, stereo baseline 1 m, sun at 35 degrees.
Each table prints time and error side by side; ratios are against a baseline measured in the same run.

Peers are measured in the same run, on the same scene (``--peers-scene``, default the demo world's mesh), camera,
resolution and thread count, when installed: Open3D's ``RaycastingScene.cast_rays`` (the ``bench`` extra) and
Blender's Cycles through ``bpy`` in its own interpreter (tools/peers/blender_cycles.py: ``$AEROSTEREO_BPY_PYTHON`` or
``.venv-bpy``; 1 spp at the pixel centres, the scene's GLB imported as it is: +Y up becomes Blender's ENU), each
against our embree caster's planar depth; "not installed (why)" otherwise.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from sim.render.camera import PinholeCamera, Rig, camera_rays, look_at  # noqa: E402
from sim.render.raycast import default_workers, intersect, map_blocks  # noqa: E402
from sim.render.renderer import StageTimes, Sun, render  # noqa: E402
from sim.render.scene import Scene, load_scene, read_scene_json  # noqa: E402
from sim.worlds.synthetic import height_field_scene  # noqa: E402
from sim.worlds import demo_scene_dir  # noqa: E402
from tools.peers.blender_cycles import (PIXEL_CENTRE_FILTER_PX, BpyUnavailable, CyclesJob, bpy_python,  # noqa: E402
                                        read_depth, run_cycles)

CAMERA = PinholeCamera(1100.0, 1100.0, 639.5, 359.5, 1280, 720)
SUN = Sun(azimuth_deg=135.0, elevation_deg=35.0)


def oblique_pose(scene, height_m=400.0, pitch_deg=45.0):
    """Rig pose looking north at the scene centre's ground from ``height_m`` above it, pitched down."""
    x0, y0 = 0.5 * (scene.bounds[0, :2] + scene.bounds[1, :2])
    target = np.array([x0, y0, float(np.nan_to_num(scene.ground_height(x0, y0), nan=scene.bounds[0, 2]))])
    return look_at(target + [0.0, -height_m / np.tan(np.radians(pitch_deg)), height_m], target)


def stereo_frame_table(scene, frames: int) -> float:
    """Median seconds per 1 spp stereo frame and its split by stage; returns the median frame time."""
    rig = Rig.stereo(CAMERA, 1.0)
    pose = oblique_pose(scene)
    render(scene, rig, pose, SUN)  # warm-up (page faults, thread pool)
    totals, stages = [], []
    for _ in range(frames):
        timings = StageTimes()
        start = time.perf_counter()
        frame = render(scene, rig, pose, SUN, timings=timings)
        totals.append(time.perf_counter() - start)
        stages.append(timings)
    total = statistics.median(totals)
    print(f"\n1280x720 stereo frame, 1 spp, {default_workers()} threads, median of {frames}: {1000 * total:.0f} ms "
          f"(target <= 500, stretch 350; Blender: see the peers table)")
    # Every block runs all stages on one thread, so stages overlap in time: split the frame's wall time by
    # each stage's share of the summed thread time.
    names = ("rays", "cast", "shadows", "shade", "film")
    thread_s = {name: statistics.median(s[name] for s in stages) for name in names}
    print(f"{'stage':<10} {'thread ms':>9} {'share':>6} {'ms/frame':>9}")
    for name in names:
        share = thread_s[name] / sum(thread_s.values())
        print(f"{name:<10} {1000 * thread_s[name]:>9.1f} {share:>6.0%} {1000 * share * total:>9.1f}")
    hit = sum(v.valid.mean() for v in frame.views) / len(frame.views)
    print(f"hit fraction {hit:.4f}")
    return total


def cast_rate(scene, rays, runs=3, pool=None) -> float:
    """Primary-ray Mray/s of :func:`intersect` (median of ``runs``)."""
    seconds = []
    for _ in range(runs):
        start = time.perf_counter()
        intersect(scene, rays.origin, rays.directions, pool)
        seconds.append(time.perf_counter() - start)
    return len(rays.directions) / statistics.median(seconds) / 1e6


_FORKED = {}


def _cast_rows(block):
    """Process worker: generate the rays of rows ``block`` itself (no ray pickling) and cast them."""
    scene, rays = _FORKED["scene"], _FORKED["rays"]
    rows = slice(block[0] * CAMERA.width, block[1] * CAMERA.width)
    directions = rays.directions[rows]
    origins = np.broadcast_to(scene.to_local(rays.origin), directions.shape)  # embreex takes N from origins
    return scene.embree.run(origins, directions, query="DISTANCE")


def throughput_table(scene) -> None:
    """Mray/s: 1 thread, the thread pool, a fork process pool (peers: :func:`peers_table`)."""
    rays = camera_rays(CAMERA, oblique_pose(scene))
    workers = default_workers()
    single = cast_rate(scene, rays, pool=ThreadPoolExecutor(1))
    with ThreadPoolExecutor(workers) as pool:
        threaded = cast_rate(scene, rays, pool=pool)
    _FORKED.update(scene=scene, rays=rays)
    edges = np.linspace(0, CAMERA.height, 8 * workers + 1).astype(int)
    blocks = list(zip(edges[:-1], edges[1:]))
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
        list(pool.map(_cast_rows, blocks))  # warm-up
        start = time.perf_counter()
        np.concatenate(list(pool.map(_cast_rows, blocks)))
        processes = len(rays.directions) / (time.perf_counter() - start) / 1e6
    print(f"\nprimary rays (closest hit + barycentrics + normals), {len(scene.faces) / 1e6:.2f} M triangles")
    print(f"{'caster':<46} {'Mray/s':>7} {'vs 1 thread':>12}")
    rows = [("sim.render.raycast.intersect, 1 thread", single), (f"sim.render.raycast.intersect, {workers} threads", threaded),
            (f"embree DISTANCE, {workers} fork processes", processes)]
    for name, rate in rows:
        print(f"{name:<46} {rate:>7.2f} {rate / single:>11.2f}x")


@dataclass(frozen=True)
class PeerRun:
    """One caster's run on the peers' view: setup seconds (scene build or import), median seconds per view, and
    planar depth (H*W,) float32 metres in image order, +inf on miss."""

    setup_s: float
    view_s: float
    depth: np.ndarray


def median_seconds(function, runs: int = 5) -> float:
    """Median wall time of ``runs`` calls of ``function()`` after one warm-up call."""
    function()
    seconds = []
    for _ in range(runs):
        start = time.perf_counter()
        function()
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds)


def ours_run(scene, rays, workers: int) -> PeerRun:
    """Our caster (:func:`sim.render.raycast.intersect`: embree via embreex; closest hit, barycentrics, normals, misses
    cast again) on ``rays``, ``workers`` threads; setup: building the :class:`Scene` (embree BVH) again."""
    start = time.perf_counter()
    Scene(scene.vertices, scene.faces, scene.surface)
    setup_s = time.perf_counter() - start
    with ThreadPoolExecutor(workers) as pool:
        seconds = median_seconds(lambda: intersect(scene, rays.origin, rays.directions, pool))
        t = intersect(scene, rays.origin, rays.directions, pool).t
    return PeerRun(setup_s, seconds, t * rays.depth_scale)


def embree_distance_run(scene, rays, workers: int) -> PeerRun:
    """embreex's bare ``DISTANCE`` query (t only, no normals, no second cast of misses) in ``workers`` threads:
    the caster under :func:`ours_run`, for a like-for-like time against the peers."""
    origins = np.broadcast_to(scene.to_local(rays.origin), rays.directions.shape)
    t = np.empty(len(rays.directions), np.float32)

    def cast(block: slice) -> None:
        t[block] = scene.embree.run(origins[block], rays.directions[block], query="DISTANCE")

    with ThreadPoolExecutor(workers) as pool:
        seconds = median_seconds(lambda: map_blocks(cast, len(t), pool))
    t[t >= 1e37] = np.inf  # embree's miss value
    return PeerRun(0.0, seconds, t * rays.depth_scale)


def open3d_run(scene, rays, workers: int) -> PeerRun | str:
    """Open3D's ``RaycastingScene.cast_rays`` on the same recentred float32 triangles and rays, ``workers``
    threads; or why it was not measured."""
    try:
        import open3d as o3d
    except (ImportError, OSError) as error:  # OSError: a system library it links is missing
        return f"not installed ({type(error).__name__}: {error})"
    start = time.perf_counter()
    raycaster = o3d.t.geometry.RaycastingScene()
    raycaster.add_triangles(o3d.core.Tensor(scene.to_local(scene.vertices)),
                            o3d.core.Tensor(scene.faces.astype(np.uint32)))
    origins = np.broadcast_to(scene.to_local(rays.origin), rays.directions.shape)
    tensor = o3d.core.Tensor(np.ascontiguousarray(np.hstack([origins, rays.directions]), dtype=np.float32))
    raycaster.cast_rays(tensor[:1], nthreads=workers)  # Open3D builds its BVH on the first cast
    setup_s = time.perf_counter() - start
    seconds = median_seconds(lambda: raycaster.cast_rays(tensor, nthreads=workers))
    t = raycaster.cast_rays(tensor, nthreads=workers)["t_hit"].numpy()
    return PeerRun(setup_s, seconds, t * rays.depth_scale)


def blender_run(scene_dir: Path, pose: np.ndarray, workers: int) -> PeerRun | str:
    """Blender Cycles in ``bpy``'s own interpreter (:mod:`tools.peers.blender_cycles`): the scene's GLB imported as it
    is, a camera with :data:`CAMERA`'s intrinsics at ``pose``, 1 sample at each pixel centre, ``workers`` threads, the
    depth pass written through the compositor; setup: the GLB import and scene set-up (not the interpreter's start
    or ``import bpy``); or why it was not measured."""
    try:
        bpy_python()
    except BpyUnavailable as reason:
        return f"not installed ({reason})"
    with tempfile.TemporaryDirectory() as folder:
        depth_exr = Path(folder) / "depth.exr"
        job = CyclesJob(glb=str(Path(scene_dir) / read_scene_json(scene_dir)["mesh"]), fx=CAMERA.fx, fy=CAMERA.fy,
                        cx=CAMERA.cx, cy=CAMERA.cy, width=CAMERA.width, height=CAMERA.height,
                        T_world_cam=pose.tolist(), sun=None, world=0.0, samples=1, threads=workers,
                        pixel_filter_px=PIXEL_CENTRE_FILTER_PX, repeats=5, depth_exr=str(depth_exr))
        times = run_cycles(job)
        depth = read_depth(depth_exr)
    return PeerRun(times.setup_s, statistics.median(times.render_s[1:]), depth.reshape(-1))


def depth_agreement(ours: np.ndarray, theirs: np.ndarray) -> tuple[float, float, float]:
    """(percent of pixels where one hits and the other misses, median and 99th-percentile |depth difference| in
    millimetres where both hit)."""
    ours_hit, theirs_hit = np.isfinite(ours), np.isfinite(theirs)
    both = ours_hit & theirs_hit
    difference = 1000.0 * np.abs(ours[both].astype(np.float64) - theirs[both])
    return 100.0 * float(np.mean(ours_hit != theirs_hit)), float(np.median(difference)), \
        float(np.percentile(difference, 99))


def peers_table(scene_dir: Path, height_m: float = 80.0) -> None:
    """Our caster against Open3D and Blender on one 1280x720 depth view of ``scene_dir``: time, ratio, agreement."""
    scene = load_scene(scene_dir)
    pose = oblique_pose(scene, height_m=height_m)
    rays = camera_rays(CAMERA, pose)
    workers = default_workers()
    ours = ours_run(scene, rays, workers)
    print(f"\npeers: depth of one 1280x720 view of {scene_dir} ({len(scene.faces) / 1e6:.2f} M triangles), "
          f"{height_m:g} m above the centre pitched 45 deg, {workers} threads, median of 5 after a warm-up, "
          f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'caster':<34}{'setup s':>8}{'ms/view':>9}{'vs ours':>8}{'hit/miss differ %':>18}"
          f"{'|dz| median mm':>15}{'p99 mm':>8}")
    print(f"{'ours (sim.render.raycast.intersect)':<34}{ours.setup_s:>8.2f}{1000 * ours.view_s:>9.0f}{1.0:>7.2f}x")
    for name, run in (("embreex DISTANCE query only", embree_distance_run(scene, rays, workers)),
                      ("Open3D RaycastingScene.cast_rays", open3d_run(scene, rays, workers)),
                      ("Blender Cycles 1 spp (bpy)", blender_run(scene_dir, pose, workers))):
        if isinstance(run, str):
            print(f"{name:<34}{run}")
            continue
        differ, median_mm, p99_mm = depth_agreement(ours.depth, run.depth)
        print(f"{name:<34}{run.setup_s:>8.2f}{1000 * run.view_s:>9.0f}{run.view_s / ours.view_s:>7.2f}x"
              f"{differ:>18.3f}{median_mm:>15.3f}{p99_mm:>8.2f}")


def srgb_error_percent(a, b) -> float:
    """Photorealism error (DESIGN.md formula 3) between two 8-bit RGB images, percent."""
    return 100.0 * np.abs(a.astype(np.int32) - b.astype(np.int32)).sum() / (a.size * 255.0)


def spp_table(scene) -> None:
    """Samples per pixel against time and error w.r.t. a 64-spp reference (one 640x360 view)."""
    camera = PinholeCamera(550.0, 550.0, 319.5, 179.5, 640, 360)
    rig, pose = Rig((camera,)), oblique_pose(scene)
    reference = render(scene, rig, pose, SUN, 64, rng=np.random.default_rng(64)).views[0].rgb
    print("\nsamples per pixel, 640x360 view, error vs 64 spp (formula 3, % of full scale)")
    print(f"{'spp':>4} {'ms/view':>8} {'vs 1 spp':>9} {'error %':>8}")
    base = None
    for spp in (1, 2, 4, 8, 16):
        start = time.perf_counter()
        rgb = render(scene, rig, pose, SUN, spp, rng=np.random.default_rng(spp)).views[0].rgb
        seconds = time.perf_counter() - start
        base = base or seconds
        print(f"{spp:>4} {1000 * seconds:>8.0f} {seconds / base:>8.1f}x {srgb_error_percent(rgb, reference):>8.3f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=1000, help="height-field cells per side (2*cells^2 triangles)")
    parser.add_argument("--frames", type=int, default=3, help="stereo frames to time")
    parser.add_argument("--scene", help="also benchmark this scene folder (e.g. the demo world)")
    parser.add_argument("--peers-scene", default="demo",
                        help="scene folder of the peers' table ('demo': the demo world, built once into its cache)")
    parser.add_argument("--peers-only", action="store_true", help="print only the peers' table")
    args = parser.parse_args(argv)
    peers_dir = demo_scene_dir() if args.peers_scene == "demo" else Path(args.peers_scene)
    if args.peers_only:
        peers_table(peers_dir)
        return 0
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} (other jobs share these cores)")
    start = time.perf_counter()
    scene = height_field_scene(args.cells)
    print(f"height field: {len(scene.faces) / 1e6:.2f} M triangles, built in {time.perf_counter() - start:.1f} s")
    stereo_frame_table(scene, args.frames)
    throughput_table(scene)
    peers_table(peers_dir)
    spp_table(scene)
    if args.scene:
        start = time.perf_counter()
        other = load_scene(args.scene)
        print(f"\n{args.scene}: {len(other.faces) / 1e6:.2f} M triangles, loaded in {time.perf_counter() - start:.1f} s")
        stereo_frame_table(other, args.frames)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
