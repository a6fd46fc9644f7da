"""Live sources through the libraries' own seams: pyserial loop:// and socket://, pyusb with the fake backend,
an injected hidapi-shaped device; disconnects mid-stream, reconnects, and nothing lost in the raw file."""

import socket
import threading
import time

import pytest
import usb.core
from duml_vectors import VECTORS, frame

from capture.duml import Deframer
from capture.fakeusb import FakeUsbBackend, disconnect_error
from capture.messages import default_registry
from capture.raw import RawCaptureWriter, read_capture_chunks
from capture.recorder import record
from capture.transports import Backoff, HidSource, SerialSource, TransportError, UsbBulkSource

pytestmark = pytest.mark.timeout(30)

STREAM = b"".join(frame(name) for name in sorted(VECTORS))
FAST = Backoff(initial_s=0.005, factor=2.0, maximum_s=0.05)


def _until(chunks, total_bytes):
    """Pass chunks through until ``total_bytes`` have been seen (live sources never end on their own)."""
    seen = 0
    for chunk in chunks:
        yield chunk
        seen += len(chunk.data)
        if seen >= total_bytes:
            return


def _record_to(tmp_path, chunks, total_bytes):
    path = tmp_path / "live.duml"
    with RawCaptureWriter(path) as writer:
        status = record(_until(chunks, total_bytes), writer, default_registry())
    return path, status


def _packets_in(path):
    deframer = Deframer()
    packets = [p for chunk in read_capture_chunks(path) for _, p in deframer.feed(chunk[2])] + deframer.flush()
    return packets, deframer.stats


def test_serial_loop_url_delivers_every_byte(tmp_path):
    source = SerialSource("loop://", read_timeout_s=0.01)

    def write_in_pieces():
        while source.connection is None:
            time.sleep(0.001)
        for start in range(0, len(STREAM), 7):
            source.connection.write(STREAM[start:start + 7])

    writer = threading.Thread(target=write_in_pieces)
    writer.start()
    path, status = _record_to(tmp_path, source.chunks(), len(STREAM))
    writer.join()
    assert path.read_bytes() == STREAM
    assert status.packets == len(VECTORS) and status.last_osd.gps_satellites == 5
    chunks = list(read_capture_chunks(path))
    times = [c[1] for c in chunks]
    assert times == sorted(times) and all(c[0].tzinfo is not None for c in chunks)


def test_socket_disconnect_then_reconnect_loses_nothing(tmp_path):
    server = socket.create_server(("127.0.0.1", 0))
    halves = (STREAM[:100], STREAM[100:])
    done = threading.Event()

    def serve():
        for half in halves:
            connection, _ = server.accept()
            time.sleep(0.2)  # pyserial's socket:// open discards input already waiting; real links start later too
            for start in range(0, len(half), 13):
                connection.sendall(half[start:start + 13])
                time.sleep(0.001)
            if half is halves[0]:
                connection.close()  # the link drops mid-frame
            else:
                done.wait(10)
                connection.close()

    thread = threading.Thread(target=serve)
    thread.start()
    source = SerialSource(f"socket://127.0.0.1:{server.getsockname()[1]}", read_timeout_s=0.01, backoff=FAST)
    path, _ = _record_to(tmp_path, source.chunks(), len(STREAM))
    done.set()
    thread.join()
    server.close()
    assert path.read_bytes() == STREAM and source.reconnects == 1
    packets, stats = _packets_in(path)
    assert len(packets) == len(VECTORS) and stats.total_skipped == 0


def test_socket_bytes_arriving_with_the_disconnect_are_kept(tmp_path):
    server = socket.create_server(("127.0.0.1", 0))

    def serve():
        connection, _ = server.accept()
        time.sleep(0.2)  # pyserial's socket:// open discards input already waiting
        connection.sendall(STREAM)
        connection.close()  # the last bytes and the end of the connection arrive together

    thread = threading.Thread(target=serve)
    thread.start()
    source = SerialSource(f"socket://127.0.0.1:{server.getsockname()[1]}", read_timeout_s=0.01, backoff=FAST)
    path, _ = _record_to(tmp_path, source.chunks(), len(STREAM))
    thread.join()
    server.close()
    assert path.read_bytes() == STREAM


def test_usb_bulk_with_fake_backend_survives_a_disconnect(tmp_path):
    pieces = [STREAM[:40], STREAM[40:41], STREAM[41:150]]
    rest = STREAM[150:]
    backend = FakeUsbBackend([*pieces, disconnect_error(), rest])
    source = UsbBulkSource(backend=backend, read_size=64, read_timeout_ms=10, backoff=FAST)
    path, status = _record_to(tmp_path, source.chunks(), len(STREAM))
    assert path.read_bytes() == bytes(backend.delivered) == STREAM
    assert backend.opened == 2 and source.reconnects == 1
    assert max(len(c[2]) for c in read_capture_chunks(path)) <= 64  # reads are bounded by the read size
    packets, _ = _packets_in(path)
    assert len(packets) == len(VECTORS) == status.packets


def test_usb_device_found_by_vendor_and_duml_interface():
    backend = FakeUsbBackend(product_id=0x0020)
    device = usb.core.find(idVendor=0x2CA3, backend=backend)
    from capture.transports import find_duml_bulk_in

    assert find_duml_bulk_in(device).bEndpointAddress == 0x85


def test_usb_missing_device_is_a_clear_error():
    source = UsbBulkSource(product_id=0x9999, backend=FakeUsbBackend())
    with pytest.raises(TransportError, match=r"^cannot open USB device 2ca3:9999: no such device connected$"):
        next(source.chunks())


def test_usb_device_without_duml_interface_names_the_device_not_errno():
    backend = FakeUsbBackend()
    backend.interfaces[1].bInterfaceSubClass = 0x42  # not the DUML interface
    source = UsbBulkSource(backend=backend)
    with pytest.raises(TransportError, match=r"^cannot open USB device 2ca3:\*: bus 1 address 5: device 2ca3:001f has "
                                             r"no DUML bulk interface"):
        next(source.chunks())


class ScriptedHid:
    """A hidapi-shaped device reading from a shared script; an exception item is raised once."""

    def __init__(self, script):
        self.script = script
        self.closed = False

    def read(self, size, timeout_ms=0):
        if not self.script:
            time.sleep(timeout_ms / 1000)
            return []
        item = self.script.pop(0)
        if isinstance(item, BaseException):
            raise item
        return list(item[:size])

    def write(self, data):
        return len(data)

    def close(self):
        self.closed = True


def test_injected_hid_device_reconnects(tmp_path):
    reports = [STREAM[i:i + 64] for i in range(0, len(STREAM), 64)]
    script = [*reports[:2], OSError("read error"), *reports[2:]]
    opened = []

    def open_device():
        opened.append(ScriptedHid(script))
        return opened[-1]

    source = HidSource(open_device, report_size=64, read_timeout_ms=5, backoff=FAST)
    path, _ = _record_to(tmp_path, source.chunks(), len(STREAM))
    assert path.read_bytes() == STREAM
    assert len(opened) == 2 and opened[0].closed and opened[1].closed


def test_unopenable_serial_port_is_a_clear_error(tmp_path):
    with pytest.raises(TransportError, match="cannot open serial port .*no-such-tty"):
        next(SerialSource(str(tmp_path / "no-such-tty")).chunks())


@pytest.mark.parametrize("baudrate", [-1, 0, 9600.5, True])
def test_a_baud_rate_that_is_not_a_positive_whole_number_is_refused_before_opening(baudrate):
    with pytest.raises(TransportError, match=f"serial port loop://: baud rate must be .* got {baudrate!r}"):
        SerialSource("loop://", baudrate=baudrate)
    assert SerialSource("loop://", baudrate=9600).baudrate == 9600


def _first_chunks(source, count):
    chunks = source.chunks()
    try:
        return [next(chunks).data for _ in range(count)]
    finally:
        chunks.close()


def test_serial_reads_take_everything_waiting_at_once_up_to_the_chunk_limit():
    source = SerialSource("loop://", read_timeout_s=0.01, max_chunk_bytes=1000)
    source.open()
    source.connection.write(bytes(range(250)) * 10)  # 2500 bytes already waiting (loop:// holds up to 4096)
    assert [len(c) for c in _first_chunks(source, 3)] == [1000, 1000, 500]


def test_socket_reads_take_what_the_os_holds_not_one_byte(tmp_path):
    payload = bytes(range(256)) * 400  # 102400 bytes
    with socket.create_server(("127.0.0.1", 0)) as server:
        source = SerialSource(f"socket://127.0.0.1:{server.getsockname()[1]}", read_timeout_s=0.05)
        source.open()
        reads = []
        port_read = source.connection.read
        source.connection.read = lambda size: reads.append(size) or port_read(size)
        connection, _ = server.accept()
        with connection:
            connection.sendall(payload)
            time.sleep(0.1)  # all of it reaches the receiving socket's buffer
            chunks = _first_chunks(source, 2)
    assert chunks[0] + chunks[1] == payload[:65536 + len(chunks[1])]
    assert len(chunks[0]) == 65536  # the whole limit at once although socket:// says in_waiting == 1
    assert reads == [1, 65535, 1, 65535]  # a waiting read of one byte, then one read of all that waits
