"""Benchmark the stereo renderer: time per stereo frame by stage, ray throughput, threads vs processes,
and samples per pixel against image error.

    .venv/bin/python tools/bench_render.py [--cells 1000] [--frames 3] [--scene DIR]

Scene: a ``2 * cells**2``-triangle height field over 1 km (default 2 M triangles, 1 m cells) and, with
``--scene``, any scene folder (e.g. the demo world written by ``sim.worlds``). Camera: 1280x720,
fx = fy = 1100 px, 400 m above the ground pitched 45 degrees down, stereo baseline 1 m, sun at 35 degrees
(the research notes' set-up, so Mray/s compare with their embreex / Open3D / Blender figures).
Each table prints time and error side by side; ratios are against a baseline measured in the same run.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from sim.camera import PinholeCamera, Rig, camera_rays, look_at  # noqa: E402
from sim.raycast import default_workers, intersect  # noqa: E402
from sim.render import StageTimes, Sun, render  # noqa: E402
from sim.scene import load_scene  # noqa: E402
from sim.synthetic import height_field_scene  # noqa: E402

CAMERA = PinholeCamera(1100.0, 1100.0, 639.5, 359.5, 1280, 720)
SUN = Sun(azimuth_deg=135.0, elevation_deg=35.0)
#: Research-note figures for 1280x720 at 2 M triangles on this 2-core machine (raycast-peers.md).
PEERS = (
    ("embreex run(), 1 thread (notes)", 4.45),
    ("embreex ThreadPool(2), 8 row blocks (notes)", 8.6),
    ("Open3D 0.20 cast_rays, 2 threads (notes)", 9.0),
)
BLENDER_S_PER_VIEW = 0.98


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
          f"(target <= 500, stretch 350; Blender Cycles: {1000 * 2 * BLENDER_S_PER_VIEW:.0f} ms for two views, "
          f"{2 * BLENDER_S_PER_VIEW / total:.1f}x)")
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
    """Mray/s: 1 thread, the thread pool, a fork process pool, against the research figures."""
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
    rows = [("sim.raycast.intersect, 1 thread", single), (f"sim.raycast.intersect, {workers} threads", threaded),
            (f"embree DISTANCE, {workers} fork processes", processes)] + list(PEERS)
    for name, rate in rows:
        print(f"{name:<46} {rate:>7.2f} {rate / single:>11.2f}x")


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
    args = parser.parse_args(argv)
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} (other jobs share these cores)")
    start = time.perf_counter()
    scene = height_field_scene(args.cells)
    print(f"height field: {len(scene.faces) / 1e6:.2f} M triangles, built in {time.perf_counter() - start:.1f} s")
    stereo_frame_table(scene, args.frames)
    throughput_table(scene)
    spp_table(scene)
    if args.scene:
        start = time.perf_counter()
        other = load_scene(args.scene)
        print(f"\n{args.scene}: {len(other.faces) / 1e6:.2f} M triangles, loaded in {time.perf_counter() - start:.1f} s")
        stereo_frame_table(other, args.frames)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
