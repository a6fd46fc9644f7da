"""Render a dataset's frames as tasks on a Dask cluster (``aerostereo-render --scheduler``).

``--scheduler local:N`` starts a ``LocalCluster`` of ``N`` worker processes here; ``--scheduler
tcp://HOST:PORT`` uses a running scheduler (``dask scheduler`` + ``dask worker``, dask-jobqueue on
SLURM/PBS, dask-kubernetes). The client (the ``aerostereo-render`` process) checks the input, opens the
dataset folder and lists the missing frames as today (resume); then:

- a :class:`RendererPlugin` is registered on every worker (and on any worker that joins or is restarted
  later): it loads the scene and builds embree once per worker process and opens the dataset writer there;
- the missing frames become tasks of :func:`batch_size` frames each; a task renders its frames with the
  worker's renderer and writes them into the output folder (atomically, as every run does), so the scene
  folder and the output folder must be the same path on every worker (a shared filesystem);
- the client follows the tasks as the scheduler finishes them (the tqdm bar on stderr) and finalizes once.

A frame's bytes depend only on ``(seed, index)``, so the dataset is the same whatever the number of workers
or the batches. A worker that dies (kill -9, out of memory) costs only its running tasks: the scheduler
reruns them on another worker, up to ``distributed.scheduler.allowed-failures`` times per task (default 3),
then the run stops with ``KilledWorker``. A task that raises (a bad pose, a full disk) is not retried
(``retries=0``): the run stops with that error and the other tasks are cancelled.

``distributed`` is an optional dependency (``pip install aerostereo[dask]``): this module needs it, and
sim/run/render_dataset.py imports this module only when a scheduler is given.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import math
import os
import re
import socket
import sys
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import dask
import distributed
from distributed.comm.addressing import parse_address, parse_host_port
from distributed.diagnostics.plugin import WorkerPlugin
from tqdm import tqdm

from sim.dataset import AsyncFrameWriter, KittiDatasetWriter
from sim.run.frame_renderer import FrameRenderer, FrameStats
from sim.run.options import RenderInputError

#: Tasks per worker the frames are cut into at least (balance: a slow worker holds back a small share).
TASKS_PER_WORKER = 8
#: Most frames in one task (a lost worker costs at most this many frames per task it was running).
MAX_BATCH_FRAMES = 32
PLUGIN_NAME = "aerostereo-renderer"
#: Dask config of the cluster ``local:N`` starts (scheduler, nannies, workers). A nanny sets
#: ``MALLOC_TRIM_THRESHOLD_=65536`` for its workers by default, which turns off glibc's adaptive mmap threshold: every
#: frame-sized array is then mmap'ed and zeroed afresh, and a frame costs 1.5-2x the CPU (tools/bench/bench_dask.py).
#: Dask's statistical profiler samples every worker thread's stack every 10 ms. Every Dask process also wakes its
#: event loop every 20 ms to see whether it is blocked ("tick") and each worker checks its memory every 100 ms: an
#: idle local:2 cluster used 0.065 cores with those, 0.011 with ticks every 1 s, memory checks every 1 s and the
#: system monitor (dashboard plots) every 5 s (tools/bench/bench_dask.py "idle"), CPU that renders would otherwise get.
#: A render neither blocks an event loop nor grows its memory within a second. Remote workers need the same
#: settings (docs/cluster.md).
WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                 "distributed.worker.profile.enabled": False,
                 "distributed.admin.tick.interval": "1s",
                 "distributed.worker.memory.monitor-interval": "1s",
                 "distributed.admin.system-monitor.interval": "5s"}
#: Task threads of a worker started by ``local:N``: one task renders while the one before it writes its files.
THREADS_PER_WORKER = 2
#: Seconds to wait for a scheduler's port to accept a connection before the run is refused.
CONNECT_TIMEOUT_S = 10.0
_SCHEDULER = re.compile(r"^(?:local:(?P<local>\d+)|(?P<address>(?:tcp|tls)://\S+))$")


@dataclass(frozen=True)
class Scheduler:
    """A parsed ``--scheduler``: ``local_workers`` processes started here, or the ``address`` of a scheduler."""

    local_workers: int | None = None
    address: str | None = None


def parse_scheduler(text: str) -> Scheduler:
    """``local:N`` (N >= 1) or ``tcp://HOST:PORT`` (or tls://); RenderInputError otherwise."""
    match = _SCHEDULER.match(text.strip())
    if match is None or (match["local"] is not None and int(match["local"]) < 1):
        raise RenderInputError(f"--scheduler must be local:N (N >= 1 worker processes started here) or the address "
                               f"of a running Dask scheduler such as tcp://HOST:8786, got {text!r}")
    if match["local"] is not None:
        return Scheduler(local_workers=int(match["local"]))
    return Scheduler(address=match["address"])


def check_reachable(scheduler: Scheduler, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse (:class:`RenderInputError`) a scheduler address whose port does not accept a TCP connection, or
    whose server does not answer Dask's ``identity`` call as a scheduler (a web or SSH server: its reply, read as
    a Dask message length, once ended the run as "out of memory"), before the dataset folder is opened (a wrong
    address leaves no file behind)."""
    if scheduler.address is None:
        return
    try:
        host, port = parse_host_port(parse_address(scheduler.address)[1])
    except ValueError as error:
        raise RenderInputError(f"--scheduler {scheduler.address}: {error}; expected tcp://HOST:PORT") from None
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except OSError as error:
        raise RenderInputError(f"--scheduler {scheduler.address}: no Dask scheduler answers there "
                               f"({error.strerror or error}); start one with 'dask scheduler' or use local:N") from None
    peer = peer_type(scheduler.address, timeout_s)
    if peer != "Scheduler":
        raise RenderInputError(f"--scheduler {scheduler.address}: the server there does not answer as a Dask "
                               f"scheduler ({peer}); give the address 'dask scheduler' prints (tcp://HOST:8786) or "
                               "use local:N")


def peer_type(address: str, timeout_s: float) -> str:
    """What answers at ``address``: ``"Scheduler"`` for a Dask scheduler (the ``type`` of its ``identity`` reply),
    else a phrase saying what it is (another Dask server; one that gives no Dask reply within ``timeout_s``)."""

    async def identity() -> dict:
        comm = await distributed.comm.connect(address, timeout=timeout_s,
                                              **distributed.Security().get_connection_args("client"))
        try:
            return await distributed.core.send_recv(comm, op="identity")
        finally:
            comm.abort()

    async def within_timeout() -> dict:
        return await asyncio.wait_for(identity(), timeout_s)

    # on a thread of its own: the caller may be running an event loop already (a notebook)
    with logs_silenced(), concurrent.futures.ThreadPoolExecutor(max_workers=1) as thread:
        try:
            reply = thread.submit(asyncio.run, within_timeout()).result()
        except Exception:  # anything but a reply (its bytes read as a huge Dask frame, a reset, a timeout): not Dask
            return "it does not speak Dask's protocol"
    kind = reply.get("type") if isinstance(reply, dict) else None
    return kind if kind == "Scheduler" else f"it is a Dask {kind}" if isinstance(kind, str) else "not a Dask reply"


@contextlib.contextmanager
def logs_silenced() -> Iterator[None]:
    """Within the block no logger prints (Dask logs a failed handshake): a refusal stays one line."""
    saved = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    try:
        yield
    finally:
        logging.disable(saved)


def batch_size(pending: int, workers: int) -> int:
    """Frames per task: at least :data:`TASKS_PER_WORKER` tasks per worker, at most :data:`MAX_BATCH_FRAMES`
    frames per task (>= 1)."""
    return max(1, min(MAX_BATCH_FRAMES, math.ceil(pending / (TASKS_PER_WORKER * max(1, workers)))))


def batches(pending: Sequence[int], size: int) -> list[list[int]]:
    """``pending`` cut into consecutive lists of ``size`` frames (the last may be shorter)."""
    return [list(pending[start:start + size]) for start in range(0, len(pending), size)]


class RendererPlugin(WorkerPlugin):
    """Worker plugin: one :class:`FrameRenderer` and dataset writer per worker process for one render job.

    ``job`` is a :class:`sim.run.render_dataset.Job`. One task renders at a time (a frame already casts with
    ``job.threads`` threads, all CPUs when None); a task that has rendered its frames waits for their files
    outside the lock, so on a worker of :data:`THREADS_PER_WORKER` threads the next task renders meanwhile
    (encoding overlaps rendering across tasks as it does in the built-in pool).
    """

    def __init__(self, job):
        self.job = job
        self.renderer: FrameRenderer | None = None
        self.writer: KittiDatasetWriter | None = None
        self.render_lock: threading.Lock | None = None

    def setup(self, worker=None) -> None:
        self.render_lock = threading.Lock()
        self.renderer = FrameRenderer(self.job.scene_dir, self.job.options, self.job.threads)
        self.writer = KittiDatasetWriter(self.job.out_dir, self.job.spec)

    def teardown(self, worker=None) -> None:
        if self.renderer is not None:
            self.renderer.close()

    def render(self, indices: Sequence[int]) -> list[FrameStats]:
        """Render and write ``indices`` (every file is on disk when this returns)."""
        if self.writer is None:  # setup failed on a worker that joined after the run started (Dask logs why)
            raise RuntimeError("this worker could not load the scene or open the dataset folder (see its log)")
        stats = []
        with AsyncFrameWriter(self.writer) as frames:
            with self.render_lock:
                for index in indices:
                    record, frame_stats = self.renderer.record(index)
                    frames.submit(record)
                    stats.append(frame_stats)
        return stats


def render_batch(indices: list[int]) -> list[FrameStats]:
    """Task: render ``indices`` with the :class:`RendererPlugin` of the worker it runs on."""
    return distributed.get_worker().plugins[PLUGIN_NAME].render(indices)


@contextlib.contextmanager
def connect(scheduler: Scheduler) -> Iterator:
    """A ``distributed.Client`` of ``scheduler`` (a LocalCluster of spawned worker processes for ``local:N``)."""
    if scheduler.address is not None:
        with distributed.Client(scheduler.address) as client:
            yield client
        return
    with environment_kept(), dask.config.set(WORKER_CONFIG), distributed.LocalCluster(
            n_workers=scheduler.local_workers, threads_per_worker=THREADS_PER_WORKER, processes=True,
            dashboard_address=":0") as cluster:
        with distributed.Client(cluster) as client:
            yield client


@contextlib.contextmanager
def environment_kept() -> Iterator[None]:
    """Restore ``os.environ`` afterwards: a Dask nanny sets its workers' variables in its own process too (and
    ``local:N`` runs the nannies here), which would reach every process this one starts later."""
    saved = dict(os.environ)
    try:
        yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


def dashboard_line(client) -> str:
    """Where the scheduler's dashboard is, or why there is none (it needs bokeh on the scheduler)."""
    if "dashboard" in client.scheduler_info().get("services", {}):
        return f"Dask dashboard: {client.dashboard_link}"
    return f"Dask scheduler {client.scheduler.address}: no dashboard (install bokeh where the scheduler runs)"


def render_on_cluster(scheduler: Scheduler, job, pending: Sequence[int], frame_done) -> None:
    """Render ``pending`` frames of ``job`` as tasks on ``scheduler``; ``frame_done(FrameStats)`` per frame.

    Raises the first task's own error (its type and message) after cancelling the rest; a task whose worker
    died ``allowed-failures`` times raises ``distributed.KilledWorker``.
    """
    with connect(scheduler) as client:
        tqdm.write(dashboard_line(client), file=sys.stderr)
        client.register_plugin(RendererPlugin(job), name=PLUGIN_NAME)
        try:
            workers = max(1, len(client.scheduler_info()["workers"]))
            tasks = batches(pending, batch_size(len(pending), workers))
            futures = client.map(render_batch, tasks, pure=False, retries=0)
            try:
                for future in distributed.as_completed(futures):
                    for stats in future.result():
                        frame_done(stats)
            finally:
                client.cancel(futures)
        finally:
            client.unregister_worker_plugin(PLUGIN_NAME)
