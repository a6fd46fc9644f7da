"""The built-in process pool of a dataset render: ``workers`` spawned processes, each loading the scene and building
embree once, pulling frame indices from one queue and writing their frames themselves; a worker dies with the render
process (Linux ``PR_SET_PDEATHSIG``), so killing the run stops every write."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import queue
import signal
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from sim.dataset import AsyncFrameWriter, DatasetSpec, KittiDatasetWriter
from sim.run.frame_renderer import FrameRenderer, FrameStats
from sim.run.options import RenderInputError, RenderOptions

#: Seconds between checks on the worker processes while waiting for their reports.
POLL_S = 0.5
#: prctl(2) option: the signal the kernel sends this process when its parent dies.
PR_SET_PDEATHSIG = 1


@dataclass(frozen=True)
class Job:
    """What a worker process needs to render frames (picklable)."""

    scene_dir: Path
    out_dir: Path
    options: RenderOptions
    spec: DatasetSpec
    threads: int | None  # casting threads per process (None: the cluster worker's own)
    parent_pid: int | None = None  # the built-in pool's workers die with this process


def _die_with_parent(parent_pid: int) -> None:
    """Have the kernel SIGKILL this worker when the render process dies (Linux ``PR_SET_PDEATHSIG``; kill -9
    included), so no worker goes on writing frames that nobody will finalize; exit now if it already died."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent_pid:
        os._exit(1)


def _worker(job: Job, tasks, results) -> None:
    """Worker process: build the scene once, render the frames it pulls, write them, report each one."""
    _die_with_parent(job.parent_pid)
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
    except OSError as error:  # a full disk: the parent raises it again, naming the file
        results.put(("oserror", (error.errno, error.strerror, error.filename)))
    except BaseException as error:  # noqa: BLE001 -- reported to the parent, which raises it
        results.put(("error", (isinstance(error, RenderInputError), f"{type(error).__name__}: {error}")))


def render_in_processes(job: Job, pending: Sequence[int], workers: int,
                        frame_done: Callable[[FrameStats], None]) -> None:
    """Render ``pending`` with ``workers`` spawned processes pulling from one queue (dynamic balance); each frame's
    report goes to ``frame_done`` as it arrives."""
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
            if kind == "oserror":
                raise OSError(*payload)
            if kind == "error":
                bad_input, message = payload
                raise (RenderInputError if bad_input else RuntimeError)(f"a render worker failed: {message}")
            if kind == "done":
                finished += 1
            else:
                frame_done(payload)
    finally:
        for process in processes:
            process.join(timeout=None if finished == workers else 0)
            if process.is_alive():
                process.terminate()
                process.join()

