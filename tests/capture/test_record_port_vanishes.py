"""A port that vanishes mid-flight: ``record`` keeps every byte received before, says in one line what happened,
and says when it comes back (issue 41)."""

import socket
import subprocess
import sys
import threading
import time

import pytest
from duml_vectors import VECTORS, frame

from capture.transports import Backoff, SerialSource

pytestmark = pytest.mark.timeout(60)

STREAM = b"".join(frame(name) for name in sorted(VECTORS)) * 20


def serve_then_vanish(server: socket.socket) -> threading.Thread:
    """Accept one connection, send STREAM, then close the connection and the listening socket: the port is gone."""

    def serve():
        connection, _ = server.accept()
        time.sleep(0.3)  # pyserial's socket:// open discards input already waiting
        connection.sendall(STREAM)
        time.sleep(0.3)
        connection.close()
        server.close()

    thread = threading.Thread(target=serve)
    thread.start()
    return thread


@pytest.mark.parametrize("with_mission", [False, True], ids=["plain", "live-view"])
def test_a_vanished_port_keeps_the_recording_and_says_so(tmp_path, with_mission):
    server = socket.create_server(("127.0.0.1", 0))
    thread = serve_then_vanish(server)
    out = tmp_path / "flight.duml"
    command = [sys.executable, "-m", "capture", "record", "--port", f"socket://127.0.0.1:{server.getsockname()[1]}",
               "--out", str(out), "--duration", "3"]
    if with_mission:
        mission = tmp_path / "mission.csv"
        subprocess.run([sys.executable, "-m", "flightplan", "--demo", "--out", str(mission)], check=True,
                       capture_output=True)
        command += ["--mission", str(mission)]
    result = subprocess.run(command, capture_output=True, text=True, timeout=30)
    thread.join()
    assert result.returncode == 0, result.stderr
    assert out.read_bytes() == STREAM
    lines = result.stderr.splitlines()
    assert any("link lost (" in line and "every byte before it is kept" in line for line in lines), result.stderr
    vanished = [line for line in lines if "did not come back" in line]
    assert len(vanished) == 1 and f"keeps the {len(STREAM)} bytes received before" in vanished[0], result.stderr
    assert "Traceback" not in result.stderr


def test_a_port_that_comes_back_is_named_back_and_not_vanished():
    server = socket.create_server(("127.0.0.1", 0))

    def serve():
        for _ in range(2):
            connection, _ = server.accept()
            time.sleep(0.2)
            connection.sendall(STREAM[:50])
            connection.close()

    thread = threading.Thread(target=serve)
    thread.start()
    events = []
    source = SerialSource(f"socket://127.0.0.1:{server.getsockname()[1]}", read_timeout_s=0.01,
                          backoff=Backoff(initial_s=0.005, factor=2.0, maximum_s=0.05))
    source.on_link_event = events.append
    received = b""
    for chunk in source.chunks():
        received += chunk.data
        if len(received) >= 100:
            break
    thread.join()
    server.close()
    assert received == STREAM[:50] * 2 and source.reconnects == 1
    assert source.lost_since_s is None and source.link_events == events
    assert "link lost" in events[0] and events[1].startswith(source.description + ": link back after ")
