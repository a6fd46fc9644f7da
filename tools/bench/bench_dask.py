"""Rendering on a Dask cluster: overhead against the built-in pool, scheduler throughput, a scaling table.

Four parts, one run:

1. The same frames rendered by :func:`sim.run.render_dataset.render_dataset` with the built-in pool
   (``--workers J``) and with ``--scheduler local:J``, each for two frame counts: the cost per frame and the
   fixed cost, in CPU seconds of all processes (robust to other jobs on the machine) and in wall seconds, and
   the cluster's overhead per frame in % (median of ``--repeats``).
2. The scheduler's throughput: thousands of tasks that do nothing on ``local:J``
   (tasks/s, so per-task overhead = 1 / that); and what an idle ``local:J`` costs in the background (cores used by
   the scheduler, nannies and workers while no task runs), with Dask's defaults and with
   :data:`sim.run.cluster.WORKER_CONFIG`.
3. Reconstruction, depth maps per view (recon/surface/dense.py ``pair_depth`` + ``fuse_pair_depths``, what the depth
   stage runs per view): ``--views`` synthetic 640x480 nadir photos of a textured plane, each view's depth from its
   two neighbours, in this process (OpenCV's threads) and as one task per view on local:J (start-up included).
4. On paper: wall time for 10^4..10^6 frames on 1..100 machines of ``--cores`` cores each, from the measured
   per-frame cost (core-seconds), the per-task overhead at :func:`sim.run.cluster.batch_size` frames per task and
   the bytes per frame over a shared disk of ``--disk-mb-s``; the column ``limit`` names the term that
   dominates (render, coordinator, disk).

Usage: ``python tools/bench/bench_dask.py [--frames N1 N2] [--width W --height H] [--workers J] [--repeats R]
[--tasks T] [--idle-seconds S] [--views V] [--cores N] [--disk-mb-s B]`` (demo world).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import dask
import distributed
import numpy as np
import psutil

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "recon"))

from recon.surface.dense import fuse_pair_depths, pair_depth  # noqa: E402
from synthetic import look_down_view, make_texture, render_plane  # noqa: E402
from sim.run.cluster import THREADS_PER_WORKER, WORKER_CONFIG, Scheduler, batch_size, connect, environment_kept  # noqa: E402,E501
from sim.run.options import PoseOptions, RenderOptions, RigOptions, RunOptions  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.run.render_dataset import render_dataset, resolve_scene_dir  # noqa: E402

FRAME_COUNTS = (10**4, 10**5, 10**6)
#: Synthetic orbit for the depth-map part: height and spacing of the nadir views (m), their depth search range.
VIEW_HEIGHT_M, VIEW_SPACING_M, DEPTH_RANGE_M = 30.0, 3.0, (20.0, 45.0)
MACHINES = (1, 10, 100)


def cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and of its finished child processes (the pool's workers,
    the LocalCluster's nannies and their workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def compare_runs(scene_dir: Path, options: RenderOptions, workers: int, frame_counts: tuple[int, int], repeats: int,
                 scratch: Path) -> list[tuple]:
    """(name, fixed CPU s, CPU s per frame, fixed wall s, wall s per frame) of the built-in pool and local:J,
    each the median of ``repeats`` measurements (the two configurations alternate).

    A measurement renders the first ``frame_counts[0]`` and then ``frame_counts[1]`` frames of the same dataset
    (a frame depends only on (seed, index)); the difference of the two runs is the cost per frame, the rest the
    fixed cost (processes, imports, scene loads, the cluster). CPU time does not count other jobs' load, so it
    shows the overhead on a busy machine where wall time cannot.
    """
    configurations = ((f"built-in pool, --workers {workers}", RunOptions(workers=workers)),
                      (f"Dask, --scheduler local:{workers}", RunOptions(scheduler=f"local:{workers}")))
    small, large = frame_counts
    measured: dict[str, list] = {name: [] for name, _ in configurations}
    for repeat in range(repeats):
        for name, how in configurations:
            costs = []
            for frames in frame_counts:
                out = scratch / f"{name.split(',')[0].replace(' ', '_')}{frames}-{repeat}"
                cpu, start = cpu_seconds(), time.perf_counter()
                render_dataset(scene_dir, out, dataclasses.replace(options, poses=PoseOptions(frames=frames), run=how),
                               command_line=["bench"], progress=False)
                costs.append((cpu_seconds() - cpu, time.perf_counter() - start))
            (cpu_small, wall_small), (cpu_large, wall_large) = costs
            cpu_per_frame = (cpu_large - cpu_small) / (large - small)
            wall_per_frame = (wall_large - wall_small) / (large - small)
            measured[name].append((cpu_small - small * cpu_per_frame, cpu_per_frame,
                                   wall_small - small * wall_per_frame, wall_per_frame))
    return [(name, *np.median(rows, axis=0)) for name, rows in measured.items()]


def bytes_per_frame(dataset: Path, frames: int) -> float:
    """Bytes a rendered frame put on disk (every file of the dataset's sequences, divided by ``frames``)."""
    return sum(path.stat().st_size for path in (dataset / "sequences").rglob("*") if path.is_file()) / frames


def _nothing(index: int) -> int:
    return index


def tasks_per_second(tasks: int, workers: int) -> float:
    """Tasks that do nothing, submitted at once and gathered, per second of wall time on ``local:J``."""
    with connect(Scheduler(local_workers=workers)) as client:
        client.gather(client.map(_nothing, range(100), pure=False))  # warm up (imports, connections)
        start = time.perf_counter()
        client.gather(client.map(_nothing, range(tasks), pure=False))
        return tasks / (time.perf_counter() - start)


def process_tree_cpu_seconds() -> float:
    """CPU seconds so far of this process and every live process below it (a LocalCluster's nannies, workers)."""
    total = 0.0
    for process in [psutil.Process(), *psutil.Process().children(recursive=True)]:
        with contextlib.suppress(psutil.Error):
            times = process.cpu_times()
            total += times.user + times.system
    return total


def idle_cores(workers: int, config: dict, seconds: float) -> float:
    """Cores an idle LocalCluster of ``workers`` processes (as ``local:J`` starts them, under ``config``) uses:
    CPU seconds of all its processes (and this one's) over ``seconds`` of wall time, after 3 s to settle."""
    with environment_kept(), dask.config.set(config), distributed.LocalCluster(
            n_workers=workers, threads_per_worker=THREADS_PER_WORKER, processes=True, dashboard_address=":0") as cluster:
        with distributed.Client(cluster):
            time.sleep(3.0)
            cpu, start = process_tree_cpu_seconds(), time.perf_counter()
            time.sleep(seconds)
            return (process_tree_cpu_seconds() - cpu) / (time.perf_counter() - start)


def view_depth(images: list[np.ndarray], views: list, k: int) -> float:
    """Depth map of view ``k`` from its neighbours (as the depth stage does per view); its valid fraction."""
    neighbours = [j for j in (k - 1, k + 1) if 0 <= j < len(views)]
    depth = fuse_pair_depths([pair_depth(images[k], images[j], views[k], views[j], DEPTH_RANGE_M)
                              for j in neighbours], 0.02)
    return float(np.mean(np.isfinite(depth)))


def depth_maps_here_and_on_cluster(count: int, workers: int) -> tuple[float, float, float]:
    """Seconds for ``count`` depth maps in this process, on local:J once started, and local:J's start-up (worker
    processes, importing recon.surface.dense there, sending the images)."""
    texture = make_texture()
    views = [look_down_view((k * VIEW_SPACING_M - count * VIEW_SPACING_M / 2, 0.0, VIEW_HEIGHT_M), 0.0)
             for k in range(count)]
    images = [render_plane(texture, view) for view in views]
    start = time.perf_counter()
    here = [view_depth(images, views, k) for k in range(count)]
    here_s = time.perf_counter() - start
    start = time.perf_counter()
    with connect(Scheduler(local_workers=workers)) as client:
        client.run(importlib.import_module, "recon.surface.dense")
        shared = client.scatter([images, views], broadcast=True)
        startup_s = time.perf_counter() - start
        start = time.perf_counter()
        on_cluster = client.gather(client.map(view_depth, *[[item] * count for item in shared], range(count)))
        cluster_s = time.perf_counter() - start
    if not np.allclose(here, on_cluster):
        raise SystemExit("the depth maps on the cluster differ from those computed here")
    return here_s, cluster_s, startup_s


def scaling_rows(core_s_per_frame: float, task_overhead_s: float, frame_bytes: float, cores: int,
                 disk_bytes_s: float) -> list[tuple]:
    """(frames, machines, render s, coordinator s, disk s, wall s, limit) on paper: the three terms overlap, so
    the wall time is the largest; one worker process per machine (casting with all its cores)."""
    rows = []
    for frames in FRAME_COUNTS:
        for machines in MACHINES:
            render_s = frames * core_s_per_frame / (machines * cores)
            coordinator_s = frames / batch_size(frames, machines) * task_overhead_s
            disk_s = frames * frame_bytes / disk_bytes_s
            terms = {"render": render_s, "coordinator": coordinator_s, "disk": disk_s}
            limit = max(terms, key=terms.get)
            rows.append((frames, machines, render_s, coordinator_s, disk_s, terms[limit], limit))
    return rows


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:8.2f} h" if seconds >= 3600 else f"{seconds / 60:8.1f} m"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, nargs=2, default=(8, 24), help="the two frame counts")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--workers", type=int, default=2, help="processes of the pool and of local:J")
    parser.add_argument("--repeats", type=int, default=3, help="measurements of each configuration (median)")
    parser.add_argument("--tasks", type=int, default=5000, help="tiny tasks for the scheduler's throughput")
    parser.add_argument("--idle-seconds", type=float, default=15.0,
                        help="how long an idle local:J is watched for its background CPU")
    parser.add_argument("--views", type=int, default=16, help="depth maps in the reconstruction part")
    parser.add_argument("--cores", type=int, default=32, help="cores per machine in the table")
    parser.add_argument("--disk-mb-s", type=float, default=1000.0, help="shared disk write bandwidth in the table")
    args = parser.parse_args()
    scene_dir = resolve_scene_dir(None)
    options = RenderOptions(seed=1, rig=RigOptions(width=args.width, height=args.height))
    scratch = Path(tempfile.mkdtemp(prefix="bench_dask_"))
    try:
        runs = compare_runs(scene_dir, options, args.workers, tuple(args.frames), args.repeats, scratch)
        frame_bytes = bytes_per_frame(scratch / f"built-in_pool{args.frames[1]}-0", args.frames[1])
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    rate = tasks_per_second(args.tasks, args.workers)
    idle = {"Dask's defaults": idle_cores(args.workers, {}, args.idle_seconds),
            "sim.run.cluster.WORKER_CONFIG": idle_cores(args.workers, WORKER_CONFIG, args.idle_seconds)}
    depth_here_s, depth_cluster_s, cluster_startup_s = depth_maps_here_and_on_cluster(args.views, args.workers)
    cpus = default_workers()
    pool_cpu, pool_wall = runs[0][2], runs[0][4]
    print(f"demo world, {args.width}x{args.height} stereo with depth + disparity, {args.frames[0]} and "
          f"{args.frames[1]} frames, median of {args.repeats}, {args.workers} processes on {cpus} CPUs")
    print(f"{'run':<32} {'CPU s/frame':>11} {'overhead':>9} {'fixed CPU s':>11} {'wall s/frame':>12} {'overhead':>9} "
          f"{'fixed wall s':>12}")
    for name, cpu_fixed, cpu_per_frame, wall_fixed, wall_per_frame in runs:
        print(f"{name:<32} {cpu_per_frame:11.3f} {100 * (cpu_per_frame / pool_cpu - 1):8.1f}% {cpu_fixed:11.2f} "
              f"{wall_per_frame:12.3f} {100 * (wall_per_frame / pool_wall - 1):8.1f}% {wall_fixed:12.2f}")
    print(f"\nscheduler: {args.tasks} no-op tasks on local:{args.workers}: {rate:.0f} tasks/s "
          f"({1e3 / rate:.2f} ms per task)")
    print(f"idle local:{args.workers} (scheduler, nannies, workers; {args.idle_seconds:.0f} s): "
          + ", ".join(f"{name} {cores:.3f} cores" for name, cores in idle.items()))
    print(f"\ndepth maps, {args.views} views of 640x480, 2 neighbours each: {depth_here_s:.2f} s in this process "
          f"({depth_here_s / args.views:.3f} s/view), {depth_cluster_s:.2f} s on local:{args.workers} one task per "
          f"view, after {cluster_startup_s:.2f} s of start-up (processes, imports, images sent)")
    core_s = pool_cpu
    print(f"\non paper: {core_s:.2f} core-s per frame (measured), {1e3 / rate:.2f} ms per task at the scheduler, "
          f"{frame_bytes / 1e6:.2f} MB per frame onto a shared disk of {args.disk_mb_s:.0f} MB/s; machines of "
          f"{args.cores} cores, up to {batch_size(10**9, 1)} frames per task")
    print(f"{'frames':>8} {'machines':>8} {'render':>11} {'coordinator':>11} {'disk':>11} {'wall':>11}  limit")
    for frames, machines, render_s, coordinator_s, disk_s, wall, limit in scaling_rows(
            core_s, 1 / rate, frame_bytes, args.cores, args.disk_mb_s * 1e6):
        print(f"{frames:>8} {machines:>8} {_hours(render_s):>11} {_hours(coordinator_s):>11} {_hours(disk_s):>11} "
              f"{_hours(wall):>11}  {limit}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
