"""Rendering on a Dask cluster (sim/run/cluster.py) against the single-machine run of the same frames.

A LocalCluster of 2 worker processes writes the same bytes as one process; so does a run whose worker is
killed with SIGKILL in the middle (Dask reruns its tasks); a task that fails for a reason of its own stops the
run with that reason; a rerun resumes. Needs ``distributed`` (the ``dask`` and ``test`` extras).
"""

from __future__ import annotations

import asyncio
import importlib.abc
import os
import re
import signal
import socket
import sys
import threading
import time
from pathlib import Path

import dask
import pytest
import yaml

distributed = pytest.importorskip("distributed")

import sim.run
from sim.run.cluster import (
    CONNECT_TIMEOUT_S,
    MAX_BATCH_FRAMES,
    TASKS_PER_WORKER,
    THREADS_PER_WORKER,
    WORKER_CONFIG,
    Scheduler,
    batch_size,
    batches,
    check_reachable,
    connect,
    environment_kept,
    parse_scheduler,
    peer_type,
)
from sim.run.options import PoseOptions, RenderInputError, RenderOptions, RigOptions, RunOptions
from sim.run.render_dataset import render_dataset

from render_scene_helpers import write_scene
from dataset_helpers import dataset_bytes

SMALL = dict(width=160, height=100, frames=8, seed=3)
#: Frames big enough that a worker is caught in the middle of one (a few tenths of a second each).
KILL = dict(width=480, height=300, frames=12, seed=4)


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return write_scene(tmp_path_factory.mktemp("scene"))


def _options(settings: dict, scheduler: str | None = None) -> RenderOptions:
    """Render options of ``settings`` (width, height, frames, seed), on ``scheduler`` (None: this machine)."""
    return RenderOptions(seed=settings["seed"], rig=RigOptions(width=settings["width"], height=settings["height"]),
                         poses=PoseOptions(frames=settings["frames"]), run=RunOptions(scheduler=scheduler))


def _single_machine(scene_dir, out, settings) -> dict[str, bytes]:
    render_dataset(scene_dir, out, _options(settings), progress=False)
    return dataset_bytes(out)


def test_scheduler_text_is_local_n_or_an_address():
    assert parse_scheduler("local:3") == Scheduler(local_workers=3)
    assert parse_scheduler("tcp://10.0.0.5:8786") == Scheduler(address="tcp://10.0.0.5:8786")
    for bad in ("local:0", "local:", "10.0.0.5:8786", "http://host:8786", "local:two"):
        with pytest.raises(RenderInputError, match="--scheduler"):
            parse_scheduler(bad)


def test_an_address_where_no_scheduler_listens_is_refused_before_any_file(scene_dir, tmp_path):
    with socket.socket() as probe:  # a loopback port that was free a moment ago
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    for address, reason in ((f"tcp://127.0.0.1:{port}", "no Dask scheduler answers"), ("tcp://127.0.0.1", "port")):
        with pytest.raises(RenderInputError, match=reason):
            render_dataset(scene_dir, tmp_path / "out", _options(SMALL, address), progress=False)
    assert not (tmp_path / "out").exists()


def test_only_a_dask_scheduler_passes_the_identity_probe():
    """The scheduler of a running cluster answers Dask's identity call as "Scheduler" (also asked from inside a
    running event loop, as a notebook calls); the address of one of its workers (a Dask server too, but no
    scheduler) is refused, naming what answered."""
    async def from_a_running_loop(address: str) -> str:
        return peer_type(address, CONNECT_TIMEOUT_S)

    with distributed.LocalCluster(n_workers=1, processes=False, protocol="tcp://", dashboard_address=":0") as cluster:
        check_reachable(Scheduler(address=cluster.scheduler_address))
        assert asyncio.run(from_a_running_loop(cluster.scheduler_address)) == "Scheduler"
        worker = next(iter(cluster.workers.values())).address
        assert peer_type(worker, CONNECT_TIMEOUT_S) == "it is a Dask Worker"
        with pytest.raises(RenderInputError, match=rf"--scheduler {worker}: .* not answer as a Dask scheduler "
                                                   r"\(it is a Dask Worker\)"):
            check_reachable(Scheduler(address=worker))


def test_without_dask_installed_a_scheduler_is_refused_and_nothing_is_written(scene_dir, tmp_path, monkeypatch):
    class NotInstalled(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "distributed":
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    monkeypatch.delitem(sys.modules, "distributed")
    monkeypatch.delitem(sys.modules, "sim.run.cluster")
    monkeypatch.delattr(sim.run, "cluster")
    monkeypatch.setattr(sys, "meta_path", [NotInstalled(), *sys.meta_path])
    with pytest.raises(RenderInputError, match=r"--scheduler needs Dask distributed: pip install 'aerostereo\[dask\]'"):
        render_dataset(scene_dir, tmp_path / "out", _options(SMALL, "local:2"), progress=False)
    assert not (tmp_path / "out").exists()


def test_batches_cover_every_frame_once_in_order_and_stay_small():
    pending = list(range(3, 1000, 3))
    for workers in (1, 2, 7, 100):
        size = batch_size(len(pending), workers)
        cut = batches(pending, size)
        assert [index for batch in cut for index in batch] == pending
        assert max(map(len, cut)) == size <= MAX_BATCH_FRAMES
        assert len(cut) >= min(len(pending), TASKS_PER_WORKER * workers) or size == MAX_BATCH_FRAMES
    assert batch_size(5, 2) == 1 and batch_size(10**6, 10) == MAX_BATCH_FRAMES


@pytest.mark.slow
def test_local_cluster_writes_the_same_bytes_and_resumes(scene_dir, tmp_path):
    expected = _single_machine(scene_dir, tmp_path / "here", SMALL)
    out = tmp_path / "cluster"
    summary = render_dataset(scene_dir, out, _options(SMALL, "local:2"), progress=False)
    assert (summary.rendered, summary.finalized) == (SMALL["frames"], True)
    assert sorted(s.index for s in summary.frames) == list(range(SMALL["frames"]))
    assert dataset_bytes(out) == expected
    (out / "sequences/00/frame_meta/000005.json").unlink()  # as if the run had stopped before frame 5's record
    resumed = render_dataset(scene_dir, out, _options(SMALL, "local:2"), progress=False)
    assert (resumed.rendered, resumed.skipped) == (1, SMALL["frames"] - 1)
    assert dataset_bytes(out) == expected


def _kill_a_busy_worker(client, out, pids: dict, killed: list) -> None:
    """Once the first frame is on disk, SIGKILL a worker process that is running a task (records its pid and
    the task's key)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not any((out / "sequences/00/frame_meta").glob("*.json")):
        time.sleep(0.01)
    busy = [(address, keys[0]) for address, keys in client.processing().items() if keys]
    if busy:
        address, key = busy[0]
        killed.append((pids[address], key))
        os.kill(pids[address], signal.SIGKILL)


@pytest.mark.slow
def test_a_worker_killed_mid_run_costs_only_its_tasks(scene_dir, tmp_path):
    expected = _single_machine(scene_dir, tmp_path / "here", KILL)
    out = tmp_path / "cluster"
    with environment_kept(), distributed.LocalCluster(n_workers=2, threads_per_worker=THREADS_PER_WORKER,
                                                      dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        killed: list[int] = []
        killer = threading.Thread(target=_kill_a_busy_worker, args=(client, out, pids, killed))
        killer.start()
        summary = render_dataset(scene_dir, out, _options(KILL, cluster.scheduler_address),
                                 progress=False)
        killer.join()
        assert killed, "no worker was running a task when the first frame was written"
        pid, key = killed[0]
        assert pid not in client.run(os.getpid).values()  # the nanny replaced the killed process
        runs = [event for event in client.story(key) if event[0] == "scheduler" and event[3] == "processing"]
        assert len(runs) == 2  # the killed worker's task ran again elsewhere, once
    assert summary.finalized and summary.rendered == KILL["frames"]
    assert dataset_bytes(out) == expected


@pytest.mark.slow
def test_a_task_failing_on_its_own_stops_the_run_with_its_reason(scene_dir, tmp_path):
    expected = _single_machine(scene_dir, tmp_path / "here", SMALL)
    out = tmp_path / "cluster"
    blocker = out / "sequences/00/image_3/000004.png"
    blocker.mkdir(parents=True)  # frame 4's right image cannot be written (as on a full or broken disk)
    with pytest.raises(IsADirectoryError, match="000004"):  # the reason, from the worker that met it
        render_dataset(scene_dir, out, _options(SMALL, "local:2"), progress=False)
    assert not (out / "sequences/00/frame_meta/000004.json").exists()
    blocker.rmdir()
    resumed = render_dataset(scene_dir, out, _options(SMALL, "local:2"), progress=False)
    assert resumed.finalized and 4 in {s.index for s in resumed.frames}
    assert dataset_bytes(out) == expected


def _worker_settings(keys: list[str]) -> dict:
    """On a worker: the Dask config values of ``keys`` and the allocator variable its nanny may have set."""
    return {"config": {key: dask.config.get(key) for key in keys},
            "MALLOC_TRIM_THRESHOLD_": os.environ.get("MALLOC_TRIM_THRESHOLD_")}


def test_local_workers_run_with_the_quiet_config_and_no_malloc_trim_threshold():
    """The settings that keep local:N's background CPU low reach the spawned workers (a nanny passes the client's
    config on; it would also set MALLOC_TRIM_THRESHOLD_=65536 unless told not to), and this process is left as it
    was (the nanny sets its variables here too)."""
    keys = [key for key in WORKER_CONFIG if not key.startswith("distributed.nanny.pre-spawn-environ")]
    before, tick_before = dict(os.environ), dask.config.get("distributed.admin.tick.interval")
    with connect(Scheduler(local_workers=1)) as client:
        (settings,) = client.run(_worker_settings, keys).values()
        assert dask.config.get("distributed.admin.tick.interval") == "1s"  # the scheduler runs here
    assert settings == {"config": {key: WORKER_CONFIG[key] for key in keys}, "MALLOC_TRIM_THRESHOLD_": None}
    assert dask.config.get("distributed.admin.tick.interval") == tick_before
    assert dict(os.environ) == before


def _flattened(tree: dict, prefix: str = "") -> dict:
    flat = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(_flattened(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def test_the_remote_worker_config_in_the_docs_is_the_one_local_n_uses():
    """docs/cluster.md's YAML for remote workers sets exactly sim.run.cluster.WORKER_CONFIG."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "cluster.md").read_text(encoding="utf-8")
    section = text[text.index("**Memory allocator and background CPU.**"):]
    block = section[section.index("```yaml\n") + len("```yaml\n"):section.index("```\n", section.index("```yaml"))]
    assert _flattened(yaml.safe_load(block)) == WORKER_CONFIG


def test_local_n_starts_no_more_workers_than_frames_and_says_what_it_needs(scene_dir, tmp_path, monkeypatch,
                                                                          capsys):
    """--scheduler local:64 for 2 frames starts 2 worker processes (and is sized for 2), saying before it starts
    what the run needs."""
    started = []
    monkeypatch.setattr(sim.run.cluster, "render_on_cluster",
                        lambda scheduler, job, pending, frame_done: started.append((scheduler, list(pending))))
    render_dataset(scene_dir, tmp_path / "out", _options(dict(SMALL, frames=2), "local:64"), progress=True)
    assert started == [(Scheduler(local_workers=2), [0, 1])]
    assert re.search(r"out: 2 frames to render: needs about [\d.]+ MiB of memory \(2 render processes here\) and "
                     r"[\d.]+ KiB on disk", capsys.readouterr().err)
