"""Render a stereo dataset from a scene: poses and sun per frame, embree rendering, KITTI-layout writing.

The pipeline (what ``aerostereo-render`` runs):

1. :func:`render_dataset` first loads the scene in the calling process and checks everything that can be
   wrong with the input (scene folder, texture, geotags from another area, output folder) before any
   frame is rendered; it opens the dataset folder (``dataset.json`` with the command line) and lists
   the frames of this shard that are still missing (resume).
2. :class:`~sim.run.frame_renderer.FrameRenderer` turns a frame index into a :class:`~sim.dataset.FrameRecord`;
   a frame's bytes depend only on ``(seed, index)``, not on the number of workers, the shard or the order.
3. It then renders the missing frames with ``workers`` processes (``1``: in this
   process). Each worker process loads the scene and builds embree once, pulls frame indices from a
   shared queue and writes its frames through its own :class:`~sim.dataset.AsyncFrameWriter`, so
   encoding overlaps with rendering. A tqdm bar shows frames/s and the ETA.
4. When every frame of the dataset exists it is finalized (``poses``, ``times.txt``, ``frames.jsonl``);
   otherwise the summary says how many frames other shards still have to render.

With ``options.run.scheduler`` step 3 runs as tasks on a Dask cluster instead (sim/run/cluster.py): the same frames,
written by the workers into the same folder, finalized here.

Every file is written atomically and a frame counts as done only when its record exists, so a run
killed at any moment and started again with the same arguments completes to the same bytes. Worker
processes die with the run (Linux: ``PR_SET_PDEATHSIG``): killing the run stops every write. A run that
fails (a full disk) deletes the frame it was writing; if it created the dataset folder and completed no
frame, it deletes the folder too. No dataset file holds a wall-clock time: each run's timings go to its run
log, ``OUT/logs/render-<UTC start>-<pid>.jsonl`` (:func:`write_run_log`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from cliutil.atomic import write_text_atomic
from cliutil.errors import BadInput
from cliutil.paths import path_problem
from cliutil.resources import format_bytes, require_disk, require_memory
from sim.dataset import (
    AsyncFrameWriter,
    DatasetError,
    DatasetSpec,
    KittiDatasetWriter,
    finalize_dataset,
    shard_frames,
)
from sim.run.description import sampling_description
from sim.run.frame_renderer import FrameRenderer, FrameStats
from sim.run.options import PoseOptions, RenderInputError, RenderOptions, RunOptions, check_options
from sim.run.processes import Job, render_in_processes
from sim.dataset.imu_file import DISK_BYTES_PER_SAMPLE, MEMORY_BYTES_PER_SAMPLE, write_imu_csv
from sim.dataset.kitti import KittiLayout
from sim.dataset.writer import frame_disk_bytes, needs_labels, recorded_frames
from sim.motion.imu import sample_count
from sim.render.raycast import default_workers
from sim.render.scene import read_scene_json

DEMO_SCENE = "demo"
#: Folder of the run logs, inside the dataset folder (not part of the dataset: its files differ run by run).
RUN_LOGS = "logs"


@dataclass
class RenderSummary:
    """Outcome of a run: frames rendered now, already present (resumed), poses the sky probe rejected."""

    out_dir: Path
    frame_count: int
    rendered: int
    skipped: int
    rejected_poses: int
    elapsed_s: float
    finalized: bool
    remaining: int = 0
    frames: list[FrameStats] = field(default_factory=list)

    @property
    def frames_per_second(self) -> float:
        """Frames rendered and written per wall-clock second (NaN for an empty run)."""
        return self.rendered / self.elapsed_s if self.rendered and self.elapsed_s > 0 else math.nan

    def text(self) -> str:
        """Human summary printed by the CLI."""
        rate = f" ({self.frames_per_second:.2f} frames/s)" if self.rendered else ""
        lines = [f"{self.out_dir}: rendered {self.rendered} frames in {self.elapsed_s:.1f} s{rate}, "
                 f"{self.skipped} already complete",
                 f"redrew {self.rejected_poses} sampled poses (sky/miss probe, or a view past the valid area)"]
        if self.finalized:
            lines.append(f"finalized: {self.frame_count} frames (poses, times.txt, frames.jsonl written)")
        else:
            lines.append(f"not finalized: {self.remaining} of {self.frame_count} frames are still missing (other "
                         "shards); rerun with the same arguments once they are in this folder")
        return "\n".join(lines)


def is_demo_scene(scene: str | os.PathLike | None) -> bool:
    """Whether ``scene`` names the built-in demo world: ``None``, ``"demo"`` or ``"demo:VARIANT"``."""
    return scene is None or str(scene) == DEMO_SCENE or str(scene).startswith(DEMO_SCENE + ":")


def resolve_scene_dir(scene: str | os.PathLike | None) -> Path:
    """The scene folder: the built-in demo world (:func:`is_demo_scene`; built once, cached) or a folder."""
    if is_demo_scene(scene):
        from sim.worlds import demo_scene_dir

        variant = str(scene or DEMO_SCENE).partition(":")[2] or "default"
        try:
            return Path(demo_scene_dir(variant))
        except ValueError as error:
            raise RenderInputError(str(error)) from None
    path = Path(scene)
    if problem := path_problem(path, folder=True):
        raise RenderInputError(f"{path}: {problem}; expected a scene folder (scene.json + mesh)")
    return path


def write_imu_record(renderer: FrameRenderer, out_dir: Path, spec: DatasetSpec) -> None:
    """Synthesize the IMU along the rendered smooth trajectory and write ``imu/NN.csv`` (sim/dataset/imu_file.py)."""
    options = renderer.options
    samples = renderer.poses.path.imu(spec.frame_count, options.poses.imu_rate_hz, options.seed)
    write_imu_csv(KittiLayout(out_dir, spec.sequence).imu_csv, samples)


def dataset_spec(renderer: FrameRenderer, scene_dir: Path, options: RenderOptions,
                 command_line: Sequence[str]) -> DatasetSpec:
    """The dataset's constant part: rig, origin, frame count, formats, scene provenance, sampling, command line, and
    the scene's ``labels`` and ``face_provenance`` entries (how its face labels and provenance codes were found, if it
    has them)."""
    formats = options.outputs.formats
    meta = read_scene_json(scene_dir, labels=needs_labels(formats), provenance="provenance_png" in formats)
    scene = {key: meta[key] for key in ("mesh", "valid_area_m", "ground_height_range_m", "provenance") if key in meta}
    return DatasetSpec.from_rig(renderer.rig, renderer.scene.origin, renderer.frame_count,
                                formats=tuple(options.outputs.formats), scene=scene,
                                sampling=sampling_description(options, renderer.scene.origin),
                                command_line=list(command_line), labels=meta.get("labels"),
                                face_provenance=meta.get("face_provenance"))


def _cluster_scheduler(run: RunOptions):
    """The parsed ``run.scheduler`` (:class:`sim.run.cluster.Scheduler`), or None to render on this machine."""
    if run.scheduler is None:
        return None
    try:
        from sim.run import cluster
    except ImportError as error:
        if not (error.name or "").startswith(("distributed", "dask")):
            raise
        raise RenderInputError("--scheduler needs Dask distributed: pip install 'aerostereo[dask]'") from None
    scheduler = cluster.parse_scheduler(run.scheduler)
    cluster.check_reachable(scheduler)
    return scheduler


@dataclass(frozen=True)
class RunNeeds:
    """What a run will take: render ``processes`` started here (at most one per missing frame), memory (the
    renderers', or the IMU record's if more: it is written after them) and disk (bytes)."""

    processes: int
    memory_bytes: float
    disk_bytes: float

    def text(self) -> str:
        processes = f"{self.processes} render process{'' if self.processes == 1 else 'es'} here"
        return (f"needs about {format_bytes(self.memory_bytes)} of memory ({processes}) and "
                f"{format_bytes(self.disk_bytes)} on disk")


def _check_resources(renderer: FrameRenderer, spec: DatasetSpec, out_dir: Path, shard: range, run: RunOptions,
                     workers: int) -> RunNeeds:
    """Refuse (:class:`RenderInputError`) a run whose render processes (``workers``, no more than the missing
    frames of ``shard``) would not fit in this machine's memory, whose IMU record would not, or whose missing
    frames and IMU record would not fit on the disk of ``out_dir``, before any file is written."""
    camera = renderer.rig.cameras[0]
    options_size = f"{camera.width}x{camera.height} pixels x {len(renderer.rig.cameras)} cameras"
    missing = missing_frames(out_dir, spec, shard)
    processes = min(workers, max(1, missing))
    poses = renderer.options.poses
    imu_samples = imu_sample_count(poses, spec.frame_count)
    imu_memory, imu_disk = imu_samples * MEMORY_BYTES_PER_SAMPLE, imu_samples * DISK_BYTES_PER_SAMPLE
    record = f"the IMU record of {imu_samples} samples (--imu-rate {poses.imu_rate_hz})" if imu_samples else ""
    disk = missing * frame_disk_bytes(spec) + imu_disk
    try:
        how = f"--scheduler {run.scheduler}" if run.scheduler else f"--workers {run.workers}"
        require_memory(renderer.memory_bytes(), f"rendering {options_size} at --spp {renderer.options.rig.spp} with "
                                                f"{how}", processes)
        if imu_samples:
            require_memory(imu_memory, f"writing {record}")
        require_disk(out_dir, disk, f"{missing} frames of {options_size}" + (f" and {record}" if imu_samples else ""))
    except BadInput as error:
        raise RenderInputError(str(error)) from None
    memory = max(processes * renderer.memory_bytes(), imu_memory)
    return RunNeeds(processes, memory, disk)


def missing_frames(out_dir: Path, spec: DatasetSpec, shard: range) -> int:
    """How many frames of ``shard`` the dataset in ``out_dir`` (of ``spec``'s sequence) has not recorded yet (all of
    them where there is none)."""
    return len(shard) - sum(index in shard for index in recorded_frames(KittiLayout(out_dir, spec.sequence)))


def imu_sample_count(poses: PoseOptions, frame_count: int) -> int:
    """Samples of the IMU record the run writes (0 without ``--imu``)."""
    if poses.imu_rate_hz is None:
        return 0
    return sample_count(frame_count, poses.frame_rate_hz, poses.imu_rate_hz)


def _open_writer(out_dir: Path, spec: DatasetSpec, overwrite: bool) -> KittiDatasetWriter:
    try:
        return KittiDatasetWriter(out_dir, spec, overwrite)
    except (DatasetError, ValueError) as error:
        raise RenderInputError(str(error)) from None
    except OSError as error:
        raise RenderInputError(f"{out_dir}: cannot write the dataset there ({error.strerror})") from None


def render_dataset(scene: str | os.PathLike | None, out_dir: str | os.PathLike, options: RenderOptions,
                   command_line: Sequence[str] | None = None, progress: bool = True,
                   overwrite: bool = False, check_spec: Callable[[DatasetSpec], None] | None = None) -> RenderSummary:
    """Render (or resume) the dataset of ``options`` from ``scene`` into ``out_dir``; see the module docstring.

    A dataset of other settings already in ``out_dir`` is refused, or with ``overwrite`` deleted first (only its
    own files). Raises :class:`RenderInputError` for bad input before anything is rendered; ``check_spec`` may
    refuse the dataset's constant part too (``render --export``: what the layouts need) before anything is written.
    """
    start, started_utc = time.perf_counter(), dt.datetime.now(dt.timezone.utc)
    check_options(options)
    out_dir = Path(out_dir)
    created = not out_dir.exists()
    scene_dir = resolve_scene_dir(scene)
    scheduler = _cluster_scheduler(options.run)
    workers = options.run.workers if scheduler is None else scheduler.local_workers or 0  # processes here
    threads = max(1, default_workers() // max(1, workers))  # casting threads per process
    renderer = FrameRenderer(scene_dir, options, threads)
    options = renderer.options  # with the random poses' heights, margin and draws fitted to the scene
    command_line = list(sys.argv if command_line is None else command_line)
    try:
        spec = dataset_spec(renderer, scene_dir, options, command_line)
        if check_spec is not None:
            check_spec(spec)
        shard = shard_frames(spec.frame_count, *options.run.shard)
        needs = _check_resources(renderer, spec, out_dir, shard, options.run, workers)
        writer = _open_writer(out_dir, spec, overwrite)
        if renderer.poses.fitted:  # said once every check has passed: a refusal stays one line
            print(f"{scene_dir}: {renderer.poses.fitted}", file=sys.stderr)
        pending = writer.pending(shard)
        if progress and pending:
            print(f"{out_dir}: {len(pending)} frames to render: {needs.text()}", file=sys.stderr)
        if scheduler is not None and scheduler.local_workers:
            scheduler = dataclasses.replace(scheduler, local_workers=needs.processes)
        shard_size = len(shard)
        bar = tqdm(total=len(pending), unit="frame", disable=not progress or not pending, file=sys.stderr,
                   desc=f"rendering {out_dir.name}")
        with bar:
            if scheduler is not None and pending:
                renderer.close()
                from sim.run.cluster import render_on_cluster

                job = Job(scene_dir, out_dir, options, spec, threads if scheduler.local_workers else None)
                progress = _Progress(bar, start)
                render_on_cluster(scheduler, job, pending, progress.frame_done)
                stats = progress.stats
            elif workers == 1 or len(pending) <= 1:
                stats = _render_here(renderer, writer, pending, _Progress(bar, start))
            else:
                renderer.close()  # the workers build their own; this one only checked the input
                job = Job(scene_dir, out_dir, options, spec, threads, os.getpid())
                progress = _Progress(bar, start)
                render_in_processes(job, pending, min(workers, len(pending)), progress.frame_done)
                stats = progress.stats
    except BaseException:
        if created:
            _remove_without_frames(out_dir)
        raise
    finally:
        renderer.close()
    remaining = len(writer.pending(range(spec.frame_count)))
    if remaining == 0:
        finalize_dataset(out_dir)
        if options.poses.imu_rate_hz is not None:
            write_imu_record(renderer, out_dir, spec)
    summary = RenderSummary(out_dir, spec.frame_count, len(stats), shard_size - len(pending),
                            sum(s.rejected for s in stats), time.perf_counter() - start, remaining == 0, remaining,
                            sorted(stats, key=lambda s: s.index))
    write_run_log(summary, started_utc, command_line, workers)
    return summary


def _remove_without_frames(out_dir: Path) -> None:
    """Delete the dataset folder a failed run created, unless it completed a frame (kept for the rerun)."""
    if not any(out_dir.glob("sequences/*/frame_meta/*.json")):
        shutil.rmtree(out_dir, ignore_errors=True)


def write_run_log(summary: RenderSummary, started_utc: dt.datetime, command_line: Sequence[str],
                  workers: int) -> Path:
    """Write the run's timings to ``OUT/logs/render-<UTC start>-<pid>.jsonl`` (atomically); return its path.

    The first line is ``{"run": {...}}`` (start time, command line, workers, frames rendered/skipped, rejected
    poses, wall time in s, finalized); then one line per frame rendered in this run: ``frame``, ``render_s``
    (seconds to render it), ``done_s`` (seconds from the start of the run until the parent heard of it),
    ``rejected_poses``. These are the only wall-clock values of a render; the dataset's own files hold none.
    """
    path = summary.out_dir / RUN_LOGS / f"render-{started_utc:%Y%m%dT%H%M%SZ}-{os.getpid()}.jsonl"
    run = {"started_utc": started_utc.isoformat(timespec="seconds"), "command_line": list(command_line),
           "workers": workers, "rendered": summary.rendered, "skipped": summary.skipped,
           "rejected_poses": summary.rejected_poses, "elapsed_s": round(summary.elapsed_s, 3),
           "finalized": summary.finalized}
    frames = [{"frame": s.index, "render_s": round(s.render_s, 4), "done_s": round(s.done_s, 4),
               "rejected_poses": s.rejected} for s in summary.frames]
    return write_text_atomic(path, "".join(json.dumps(line) + "\n" for line in [{"run": run}, *frames]))


class _Progress:
    """Collects frame reports: advances the bar and stamps each with the time since the run started."""

    def __init__(self, bar, start: float):
        self.bar, self.start, self.stats = bar, start, []

    def frame_done(self, stats: FrameStats) -> None:
        stats.done_s = time.perf_counter() - self.start
        self.stats.append(stats)
        self.bar.update(1)


def _render_here(renderer: FrameRenderer, writer: KittiDatasetWriter, pending: Sequence[int],
                 progress: _Progress) -> list[FrameStats]:
    with AsyncFrameWriter(writer) as frames:
        for index in pending:
            record, frame_stats = renderer.record(index)
            frames.submit(record)
            progress.frame_done(frame_stats)
    return progress.stats
