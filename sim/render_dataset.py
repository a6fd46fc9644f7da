"""Render a stereo dataset from a scene: poses and sun per frame, embree rendering, KITTI-layout writing.

The pipeline (what ``aerostereo-render`` runs):

1. :func:`prepare` loads the scene once in the calling process and checks everything that can be
   wrong with the input (scene folder, texture, geotags from another area, output folder) before any
   frame is rendered; it opens the dataset folder (``dataset.json`` with the command line) and lists
   the frames of this shard that are still missing (resume).
2. :class:`FrameRenderer` turns a frame index into a :class:`~sim.dataset.FrameRecord`. Pose, sun and the
   anti-aliasing jitter of frame ``i`` come from generators seeded by ``(seed, i)`` only, so a frame's
   bytes do not depend on the number of workers, the shard or the order.
3. :func:`render_dataset` renders the missing frames with ``workers`` processes (``1``: in this
   process). Each worker process loads the scene and builds embree once, pulls frame indices from a
   shared queue and writes its frames through its own :class:`~sim.dataset.AsyncFrameWriter`, so
   encoding overlaps with rendering. A tqdm bar shows frames/s and the ETA.
4. When every frame of the dataset exists it is finalized (``poses``, ``times.txt``, ``frames.jsonl``);
   otherwise the summary says how many frames other shards still have to render.

Every file is written atomically and a frame counts as done only when its record exists, so a run
killed at any moment and started again with the same arguments completes to the same bytes.
"""

from __future__ import annotations

import functools
import json
import math
import multiprocessing
import os
import queue
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from sim.camera import PinholeCamera, Rig
from sim.dataset import (
    DEFAULT_FORMATS,
    AsyncFrameWriter,
    DatasetError,
    DatasetSpec,
    FrameRecord,
    KittiDatasetWriter,
    finalize_dataset,
    shard_frames,
)
from sim.raycast import default_workers
from sim.render import miss_fraction, render
from sim.sampling import (
    RENDER_STREAM,
    PoseSample,
    RandomPoseSettings,
    SunSample,
    frame_rng,
    lawnmower,
    orbit,
    random_loop,
    random_pose,
    random_sun,
    replay_poses,
)
from sim.scene import Scene, SceneError, load_scene, read_scene_json
from sim.shade import Sun

MODES = ("random", "trajectory", "replay")
TRAJECTORIES = ("orbit", "lawnmower", "loop")
DEMO_SCENE = "demo"
#: The paper's sun "Strength" (Blender irradiance units, drawn in 5-10) times this is the renderer's
#: linear sun intensity: strength 10 lights a surface facing the sun at its full albedo (plus the sky).
SUN_STRENGTH_TO_INTENSITY = 0.1
#: Seconds between checks on the worker processes while waiting for their reports.
POLL_S = 0.5


class RenderInputError(ValueError):
    """Input that cannot be rendered (scene, geotags, options, output folder); the message names it."""


@dataclass(frozen=True)
class RenderOptions:
    """Settings of one dataset render (everything that decides the bytes, plus how to run it).

    ``frames`` None: 100 for random/trajectory, every photo for replay. Angles in degrees, lengths in
    metres, speeds in m/s. ``shard`` ``(I, N)`` renders frames ``I, I+N, ...``; ``workers`` processes.
    """

    frames: int | None = None
    mode: str = "random"
    geotags: Path | None = None
    width: int = 1280
    height: int = 720
    fov_deg: float = 80.0
    baseline_m: float = 0.54
    cameras: int = 2
    spp: int = 1
    seed: int = 0
    workers: int = 1
    shard: tuple[int, int] = (0, 1)
    formats: Sequence[str] = DEFAULT_FORMATS
    trajectory: str = "orbit"
    altitude_m: float = 50.0
    speed_m_s: float = 5.0
    frame_rate_hz: float = 10.0
    demo_variant: str = "default"

    def sampling_description(self) -> dict:
        """What ``dataset.json`` records about the sampling (settings that decide the bytes, no run details)."""
        description = {"mode": self.mode, "seed": self.seed, "samples_per_pixel": self.spp,
                       "sun_strength_to_intensity": SUN_STRENGTH_TO_INTENSITY}
        if self.mode == "random":
            description["random"] = asdict(RandomPoseSettings())
        elif self.mode == "trajectory":
            description["trajectory"] = {"path": self.trajectory, "altitude_m": self.altitude_m,
                                         "speed_m_s": self.speed_m_s, "frame_rate_hz": self.frame_rate_hz}
        else:
            description["geotags"] = Path(self.geotags).name
        return json.loads(json.dumps(description))  # as read back from dataset.json (lists, not tuples)


class SceneGround:
    """A scene as the pose samplers see it, except that where no surface lies under a point (a hole in
    the mesh) the ground is taken at the scene's lowest point, so sampled positions stay finite."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.valid_area = scene.valid_area

    def ground_height(self, x, y):
        return np.nan_to_num(self.scene.ground_height(x, y), nan=float(self.scene.bounds[0, 2]))


def build_rig(options: RenderOptions) -> Rig:
    """``cameras`` identical pinhole cameras in a row, camera k at ``k * baseline`` along camera x."""
    camera = PinholeCamera.from_fov(options.width, options.height, options.fov_deg)
    if options.cameras == 2:
        return Rig.stereo(camera, options.baseline_m)
    offsets = [np.eye(4) for _ in range(options.cameras)]
    for k, T in enumerate(offsets):
        T[0, 3] = k * options.baseline_m
    return Rig(tuple([camera] * options.cameras), tuple(offsets))


class PoseSource:
    """Frame index -> :class:`~sim.sampling.PoseSample` for the chosen mode, and the frame count."""

    def __init__(self, scene: Scene, options: RenderOptions, left_camera: PinholeCamera):
        self.options = options
        self.ground = SceneGround(scene)
        self.replayed: list[PoseSample] | None = None
        self.path = None
        if options.mode == "random":
            self._probe = functools.partial(miss_fraction, scene, left_camera)
        elif options.mode == "trajectory":
            self.path = self._trajectory()
        else:
            self.replayed = replay_poses(Path(options.geotags), scene.origin, self.ground)
        self.frame_count = self._frame_count()

    def _trajectory(self):
        o = self.options
        xmin, xmax, ymin, ymax = self.ground.valid_area
        if o.trajectory == "orbit":
            centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)
            radius = min(50.0, 0.3 * min(xmax - xmin, ymax - ymin))
            return orbit(self.ground, centre, radius, o.altitude_m, o.speed_m_s, o.frame_rate_hz)
        if o.trajectory == "lawnmower":
            spacing = min(40.0, 0.25 * (ymax - ymin))
            return lawnmower(self.ground, spacing, o.altitude_m, o.speed_m_s, o.frame_rate_hz)
        return random_loop(self.ground, o.seed, o.altitude_m, o.speed_m_s, o.frame_rate_hz)

    def _frame_count(self) -> int:
        requested = self.options.frames
        if self.replayed is not None:
            if requested is not None and requested > len(self.replayed):
                raise RenderInputError(f"{self.options.geotags}: {len(self.replayed)} photos, cannot replay "
                                       f"{requested} frames")
            return requested or len(self.replayed)
        count = 100 if requested is None else requested
        available = self.path.frames_available() if self.path is not None else None
        if available is not None and count > available:
            raise RenderInputError(f"the {self.options.trajectory} path holds {available} frames at "
                                   f"{self.options.speed_m_s} m/s and {self.options.frame_rate_hz} Hz, not {count}")
        return count

    def pose(self, index: int) -> PoseSample:
        if self.replayed is not None:
            return self.replayed[index]
        if self.path is not None:
            return self.path.pose(self.ground, index)
        return random_pose(self.ground, self.options.seed, index, miss_fraction=self._probe)


def frame_sun(sample: SunSample) -> Sun:
    """The renderer's sun for a sampled (paper-units) sun."""
    return Sun(sample.azimuth_deg, sample.elevation_deg, sample.intensity * SUN_STRENGTH_TO_INTENSITY)


@dataclass
class FrameStats:
    """What a worker reports about one rendered frame (sent to the parent for the progress bar)."""

    index: int
    rejected: int
    render_s: float
    done_s: float = math.nan  # seconds from the start of the run until the parent heard of it


class FrameRenderer:
    """Renders frames of one dataset: the scene and embree are built once, then :meth:`record` per frame.

    ``threads``: casting threads of this process (all CPUs for one process, fewer when several share them).
    """

    def __init__(self, scene_dir: Path, options: RenderOptions, threads: int | None = None):
        self.options = options
        try:
            self.scene = load_scene(scene_dir)
        except SceneError as error:
            raise RenderInputError(str(error)) from None
        self.rig = build_rig(options)
        try:
            self.poses = PoseSource(self.scene, options, self.rig.cameras[0])
        except ValueError as error:
            raise RenderInputError(str(error)) from None
        self.pool = ThreadPoolExecutor(threads or default_workers())

    @property
    def frame_count(self) -> int:
        return self.poses.frame_count

    def record(self, index: int) -> tuple[FrameRecord, FrameStats]:
        """Render frame ``index`` (its pose, sun and jitter depend only on ``(seed, index)``)."""
        start = time.perf_counter()
        sample = self.poses.pose(index)
        sun = random_sun(self.options.seed, index)
        frame = render(self.scene, self.rig, sample.T_world_cam, frame_sun(sun), self.options.spp,
                       rng=frame_rng(self.options.seed, index, RENDER_STREAM), pool=self.pool)
        elapsed = time.perf_counter() - start
        record = FrameRecord(index=index, views=frame.views, T_world_cam=frame.views[0].T_world_cam,
                             time_s=sample.time_s, seed=self.options.seed, sun=sun, render_time_s=elapsed,
                             extra=sample.record())
        return record, FrameStats(index, sample.rejected, elapsed)

    def close(self) -> None:
        self.pool.shutdown()


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
        lines = [f"{self.out_dir}: rendered {self.rendered} frames in {self.elapsed_s:.1f} s "
                 f"({self.frames_per_second:.2f} frames/s), "
                 f"{self.skipped} already complete",
                 f"sky/miss probe rejected {self.rejected_poses} sampled poses"]
        if self.finalized:
            lines.append(f"finalized: {self.frame_count} frames (poses, times.txt, frames.jsonl written)")
        else:
            lines.append(f"not finalized: {self.remaining} of {self.frame_count} frames are still missing (other "
                         "shards); rerun with the same arguments once they are in this folder")
        return "\n".join(lines)


@dataclass(frozen=True)
class Job:
    """What a worker process needs to render frames (picklable)."""

    scene_dir: Path
    out_dir: Path
    options: RenderOptions
    spec: DatasetSpec
    threads: int


def resolve_scene_dir(scene: str | os.PathLike | None, options: RenderOptions) -> Path:
    """The scene folder: ``None`` or ``"demo"`` is the built-in demo world (built once, then cached)."""
    if scene is None or str(scene) == DEMO_SCENE:
        try:
            from sim.worlds import demo_scene_dir
        except ImportError as error:
            raise RenderInputError(f"the built-in demo world is not available ({error}); pass --scene DIR") from None
        return Path(demo_scene_dir(options.demo_variant))
    path = Path(scene)
    if not path.is_dir():
        raise RenderInputError(f"{path}: scene folder not found")
    return path


def _check_options(options: RenderOptions) -> None:
    problems = []
    if options.mode not in MODES:
        problems.append(f"mode must be one of {MODES}, got {options.mode!r}")
    if options.mode == "replay" and options.geotags is None:
        problems.append("replay mode needs --geotags FILE")
    if options.trajectory not in TRAJECTORIES:
        problems.append(f"trajectory must be one of {TRAJECTORIES}, got {options.trajectory!r}")
    if options.cameras < 2:
        problems.append(f"a stereo dataset needs at least 2 cameras, got {options.cameras}")
    if options.frames is not None and options.frames < 1:
        problems.append(f"frames must be >= 1, got {options.frames}")
    for name in ("width", "height", "spp", "workers"):
        if getattr(options, name) < 1:
            problems.append(f"{name} must be >= 1, got {getattr(options, name)}")
    if not options.baseline_m > 0:
        problems.append(f"baseline must be positive, got {options.baseline_m}")
    if not 0 < options.fov_deg < 180:
        problems.append(f"field of view must be in (0, 180) degrees, got {options.fov_deg}")
    if problems:
        raise RenderInputError("; ".join(problems))


def _dataset_spec(renderer: FrameRenderer, scene_dir: Path, options: RenderOptions,
                  command_line: Sequence[str]) -> DatasetSpec:
    meta = read_scene_json(scene_dir)
    scene = {key: meta[key] for key in ("mesh", "valid_area_m", "ground_height_range_m", "provenance") if key in meta}
    return DatasetSpec.from_rig(renderer.rig, renderer.scene.origin, renderer.frame_count, formats=tuple(options.formats),
                                scene=scene, sampling=options.sampling_description(), command_line=list(command_line))


def _open_writer(out_dir: Path, spec: DatasetSpec) -> KittiDatasetWriter:
    try:
        return KittiDatasetWriter(out_dir, spec)
    except (DatasetError, ValueError) as error:
        raise RenderInputError(str(error)) from None
    except OSError as error:
        raise RenderInputError(f"{out_dir}: cannot write the dataset there ({error.strerror})") from None


def render_dataset(scene: str | os.PathLike | None, out_dir: str | os.PathLike, options: RenderOptions,
                   command_line: Sequence[str] | None = None, progress: bool = True) -> RenderSummary:
    """Render (or resume) the dataset of ``options`` from ``scene`` into ``out_dir``; see the module docstring.

    Raises :class:`RenderInputError` for bad input before anything is rendered.
    """
    start = time.perf_counter()
    _check_options(options)
    out_dir = Path(out_dir)
    scene_dir = resolve_scene_dir(scene, options)
    workers = options.workers
    renderer = FrameRenderer(scene_dir, options, threads=max(1, default_workers() // workers))
    try:
        spec = _dataset_spec(renderer, scene_dir, options, sys.argv if command_line is None else command_line)
        writer = _open_writer(out_dir, spec)
        pending = writer.pending(shard_frames(spec.frame_count, *options.shard))
        shard_size = len(shard_frames(spec.frame_count, *options.shard))
        bar = tqdm(total=len(pending), unit="frame", disable=not progress or not pending, file=sys.stderr,
                   desc=f"rendering {out_dir.name}")
        with bar:
            if workers == 1 or len(pending) <= 1:
                stats = _render_here(renderer, writer, pending, _Progress(bar, start))
            else:
                renderer.close()
                job = Job(scene_dir, out_dir, options, spec, max(1, default_workers() // workers))
                stats = _render_in_processes(job, pending, min(workers, len(pending)), _Progress(bar, start))
    finally:
        renderer.close()
    remaining = len(writer.pending(range(spec.frame_count)))
    if remaining == 0:
        finalize_dataset(out_dir)
    return RenderSummary(out_dir, spec.frame_count, len(stats), shard_size - len(pending),
                         sum(s.rejected for s in stats), time.perf_counter() - start, remaining == 0, remaining,
                         sorted(stats, key=lambda s: s.index))


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


def _worker(job: Job, tasks, results) -> None:
    """Worker process: build the scene once, render the frames it pulls, write them, report each one."""
    try:
        renderer = FrameRenderer(job.scene_dir, job.options, job.threads)
        writer = KittiDatasetWriter(job.out_dir, job.spec)
        with AsyncFrameWriter(writer) as frames:
            for index in iter(tasks.get, None):
                record, frame_stats = renderer.record(index)
                frames.submit(record)
                results.put(("frame", frame_stats))
        renderer.close()
        results.put(("done", None))
    except BaseException as error:  # noqa: BLE001 -- reported to the parent, which raises it
        results.put(("error", f"{type(error).__name__}: {error}"))


def _render_in_processes(job: Job, pending: Sequence[int], workers: int, progress: _Progress) -> list[FrameStats]:
    """Render ``pending`` with ``workers`` spawned processes pulling from one queue (dynamic balance)."""
    context = multiprocessing.get_context("spawn")  # never fork a process that already runs embree threads
    tasks, results = context.Queue(), context.Queue()
    for index in pending:
        tasks.put(index)
    for _ in range(workers):
        tasks.put(None)
    processes = [context.Process(target=_worker, args=(job, tasks, results), daemon=True) for _ in range(workers)]
    for process in processes:
        process.start()
    finished = 0
    try:
        while finished < workers:
            try:
                kind, payload = results.get(timeout=POLL_S)
            except queue.Empty:
                dead = [p for p in processes if p.exitcode not in (None, 0)]
                if dead:
                    raise RuntimeError(f"a render worker died (exit code {dead[0].exitcode})") from None
                continue
            if kind == "error":
                raise RuntimeError(f"a render worker failed: {payload}")
            if kind == "done":
                finished += 1
            else:
                progress.frame_done(payload)
    finally:
        for process in processes:
            process.join(timeout=None if finished == workers else 0)
            if process.is_alive():
                process.terminate()
                process.join()
    return progress.stats

