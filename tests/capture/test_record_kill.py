"""kill -9 of ``aerostereo-ingest record`` while a local TCP sender streams at 10 MB/s: every byte the process
had read is on disk.

How the assertion is exact. The process's read position on the TCP stream is what the kernel counts as copied to
it: sent bytes ``S`` minus what the sender's kernel still holds unacknowledged (``tx_queue``) minus what the
receiver's kernel holds unread (``rx_queue``), both from ``/proc/net/tcp`` once the sender has stopped and the
queues are still. That count is only readable while the receiver lives, so it is frozen first (``SIGSTOP``); but a
process frozen between a ``recv`` and its ``write`` holds read bytes that no code could have written yet. So it is
frozen again (after ``SIGCONT``) until ``/proc/PID/syscall`` shows it stopped in a ``write`` to the capture or its
index: its last read is then being written, and no read is pending. Then ``SIGKILL``, and the capture file must be
exactly the first ``S - tx_queue - rx_queue`` bytes of the stream: a prefix (nothing corrupted or reordered) and
not one byte short; every chunk's ``.idx`` line lies inside the streaming window.
"""

from __future__ import annotations

import functools
import inspect
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from capture.raw import index_path, read_index
from capture.transports import SerialSource

pytestmark = [pytest.mark.timeout(120),
              pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="needs Linux /proc/net/tcp")]

ROOT = Path(__file__).resolve().parents[2]
RATE_BPS = 10e6
PIECE = 10_000  # bytes per send, one every millisecond at 10 MB/s
MAX_CHUNK = inspect.signature(SerialSource).parameters["max_chunk_bytes"].default  # the most one read returns
WRITE_SYSCALLS = {1, 20}  # x86_64 write, writev


@functools.cache
def stream() -> bytes:
    """64 MiB of seeded random bytes: 6 s at 10 MB/s, more than the test streams (built on first use)."""
    return np.random.default_rng(7).integers(0, 256, 64 << 20, dtype=np.uint8).tobytes()


class Sender(threading.Thread):
    """Streams :func:`stream` to one connection at :data:`RATE_BPS`; ``sent`` counts bytes the kernel took."""

    def __init__(self, connection: socket.socket) -> None:
        super().__init__(daemon=True)
        self.connection, self.sent, self.stop = connection, 0, threading.Event()
        self.connection.settimeout(0.01)

    def run(self) -> None:
        start, data = time.monotonic(), stream()
        while not self.stop.is_set() and self.sent < len(data):
            due = int((time.monotonic() - start) * RATE_BPS)
            if self.sent >= due:
                time.sleep(PIECE / RATE_BPS)
                continue
            try:
                self.sent += self.connection.send(data[self.sent:min(due, self.sent + PIECE)])
            except TimeoutError:
                continue


def _tcp_queues(local_port: int, remote_port: int) -> tuple[int, int]:
    """``(tx_queue, rx_queue)`` in bytes of the IPv4 TCP socket ``127.0.0.1:local_port -> :remote_port``."""
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        local, remote = (int(address.split(":")[1], 16) for address in fields[1:3])
        if (local, remote) == (local_port, remote_port):
            tx, rx = fields[4].split(":")
            return int(tx, 16), int(rx, 16)
    raise AssertionError(f"no TCP socket {local_port} -> {remote_port} in /proc/net/tcp")


def _stopped(pid: int) -> bool:
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "T"


def _writing_capture(pid: int, capture: Path) -> bool:
    """Whether the stopped process sits in a write to ``capture`` or its index."""
    fields = Path(f"/proc/{pid}/syscall").read_text().split()
    if fields[0] in ("running", "-1") or int(fields[0]) not in WRITE_SYSCALLS:
        return False
    target = os.readlink(f"/proc/{pid}/fd/{int(fields[1], 16)}")
    return target in (str(capture.resolve()), str(index_path(capture).resolve()))


def _freeze_while_writing(pid: int, capture: Path, tries: int = 5000) -> None:
    rng = np.random.default_rng(0)
    for _ in range(tries):
        os.kill(pid, signal.SIGSTOP)
        while not _stopped(pid):
            time.sleep(0.0001)
        if _writing_capture(pid, capture):
            return
        os.kill(pid, signal.SIGCONT)
        time.sleep(float(rng.uniform(0, 0.002)))
    raise AssertionError(f"record never caught writing its capture in {tries} freezes: it holds what it reads")


def _settled_queues(sender_port: int, receiver_port: int) -> tuple[int, int]:
    """Sender tx and receiver rx queues once three readings 20 ms apart agree (nothing left in flight)."""
    readings = []
    while len(readings) < 3 or len(set(readings[-3:])) > 1:
        readings.append((_tcp_queues(sender_port, receiver_port)[0], _tcp_queues(receiver_port, sender_port)[1]))
        time.sleep(0.02)
    return readings[-1]


@pytest.mark.skipif(sys.platform != "linux" or os.uname().machine != "x86_64", reason="x86_64 syscall numbers")
def test_kill_9_while_streaming_10_mb_per_s_loses_no_byte_read(tmp_path):
    capture = tmp_path / "live.duml"
    stream()  # built before the clock starts
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]
        started = time.time()
        process = subprocess.Popen([sys.executable, "-m", "capture", "record", "--port", f"socket://127.0.0.1:{port}",
                                    "--out", str(capture)], cwd=ROOT, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL)
        try:
            server.settimeout(30)
            connection, (_, receiver_port) = server.accept()
            sender = Sender(connection)
            sender.start()
            time.sleep(1.0)
            _freeze_while_writing(process.pid, capture)
            sender.stop.set()
            sender.join()
            tx, rx = _settled_queues(port, receiver_port)
            process.kill()
            process.wait()
            ended = time.time()
        finally:
            process.kill()
            process.wait()
        connection.close()

    read_by_process = sender.sent - tx - rx
    data = capture.read_bytes()
    assert data == stream()[:len(data)], "the capture is not a prefix of the stream"
    assert len(data) == read_by_process, (f"{read_by_process - len(data)} bytes read by record were lost "
                                          f"(sent {sender.sent}, unacknowledged {tx}, unread {rx})")
    assert sender.sent > 5e6, f"only {sender.sent} bytes sent in 1 s (record too slow to keep up)"
    index = read_index(index_path(capture))
    indexed = int(index.offsets[-1] + index.lengths[-1])  # short by the chunk being written at the freeze, if any
    assert int(index.offsets[0]) == 0 and len(data) - MAX_CHUNK <= indexed <= len(data)
    assert np.all(np.diff(index.offsets) == index.lengths[:-1]), "chunks of the index are not contiguous"
    assert started <= index.utc_unix_s[0] and index.utc_unix_s[-1] <= ended
    assert np.all(np.diff(index.utc_unix_s) >= 0) and np.all(np.diff(index.monotonic_s) >= 0)
