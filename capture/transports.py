"""Byte sources: live serial, USB bulk and HID links, and replays of raw captures and pcaps.

Every source is iterable through ``chunks(stop)`` and yields :class:`Chunk` ``(receive_time_utc,
receive_time_monotonic, data)``. Live sources open their device when iteration starts (a failure there is a
:class:`TransportError`, so a CLI can stop with a clear message), then survive disconnects: on the library's
own disconnect errors (``serial.SerialException``, ``usb.core.USBError``, ``OSError`` from hidapi) they close,
wait with exponential backoff and reopen, and keep going until ``stop`` is set. Hardware is reached only
through the libraries' seams: ``serial.serial_for_url``, ``usb.core.find(backend=...)`` and a hidapi-shaped
device factory, so tests use ``loop://``, :mod:`capture.fakeusb` and injected objects.
"""

from __future__ import annotations

import datetime as dt
import io
import struct
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, NamedTuple

import dpkt
import numpy as np
import serial
import usb.core
import usb.util
from serial.urlhandler.protocol_socket import Serial as SocketSerial

from capture.raw import read_capture_chunks

DJI_VENDOR_ID = 0x2CA3
DUML_INTERFACE_SUBCLASS = 0x43
PCAP_LINKTYPE_DUML = 150  # DLT_USER3, as used by o-gs comm_serial2pcap


class Chunk(NamedTuple):
    """Bytes as one read returned them, with the host's UTC and monotonic receive times (seconds)."""

    receive_time_utc: dt.datetime | None
    receive_time_monotonic: float | None
    data: bytes


class TransportError(RuntimeError):
    """A device or file that cannot be opened or read (one-line, user-facing message)."""


def error_text(error: BaseException) -> str:
    """The message of ``error`` without the ``[Errno None]`` that pyusb's USBError (an OSError) puts first."""
    if isinstance(error, OSError) and error.errno is None and error.strerror:
        return error.strerror
    return str(error)


class Clock:
    """Host clocks; injectable so tests can control time."""

    def utc(self) -> dt.datetime:
        return dt.datetime.now(dt.timezone.utc)

    def monotonic(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float, stop: threading.Event) -> None:
        stop.wait(seconds)


@dataclass(frozen=True)
class Backoff:
    """Reconnect delays: ``initial_s``, multiplied by ``factor`` after each failed try, at most ``maximum_s``."""

    initial_s: float = 0.1
    factor: float = 2.0
    maximum_s: float = 5.0

    def delays(self) -> Iterator[float]:
        delay = self.initial_s
        while True:
            yield delay
            delay = min(delay * self.factor, self.maximum_s)


class LiveSource:
    """Shared read/reconnect loop; subclasses say how to open, read and close, and what a disconnect is."""

    description = "device"
    disconnect_errors: tuple[type[BaseException], ...] = (OSError,)

    def __init__(self, backoff: Backoff = Backoff(), clock: Clock | None = None) -> None:
        self.backoff = backoff
        self.clock = clock or Clock()
        self.reconnects = 0
        self.connection = None
        self.link_events: list[str] = []  # what happened to the link, in words, in order (losses and returns)
        self.on_link_event: Callable[[str], None] | None = None  # told each of them as it happens
        self.lost_since_s: float | None = None  # monotonic time the link was lost, None while it is up

    def _open(self):
        raise NotImplementedError

    def _read(self, connection) -> bytes:
        """Some bytes, or b"" when nothing arrived within the read timeout."""
        raise NotImplementedError

    def _close(self, connection) -> None:
        raise NotImplementedError

    def open(self) -> None:
        """Open the device now (``chunks`` does it if needed); TransportError when it cannot be opened."""
        try:
            self.connection = self._open()
        except (*self.disconnect_errors, ValueError) as error:  # ValueError: a setting the port refuses
            raise TransportError(f"cannot open {self.description}: {error_text(error)}") from None

    def chunks(self, stop: threading.Event | None = None) -> Iterator[Chunk]:
        """Yield chunks until ``stop`` is set; ``self.connection`` is the open device meanwhile."""
        stop = stop or threading.Event()
        if self.connection is None:
            self.open()
        try:
            while not stop.is_set():
                try:
                    data = self._read(self.connection)
                except self.disconnect_errors as error:
                    self._close_quietly(self.connection)
                    self._link_lost(error)
                    self.connection = self._reconnect(stop)
                    continue
                if data:
                    yield Chunk(self.clock.utc(), self.clock.monotonic(), data)
        finally:
            if self.connection is not None:
                self._close_quietly(self.connection)
            self.connection = None

    __iter__ = chunks

    def _reconnect(self, stop: threading.Event):
        for delay in self.backoff.delays():
            self.clock.sleep(delay, stop)
            if stop.is_set():
                return None
            try:
                connection = self._open()
            except self.disconnect_errors:
                continue
            self.reconnects += 1
            self._tell(f"{self.description}: link back after {self.clock.monotonic() - self.lost_since_s:.1f} s")
            self.lost_since_s = None
            return connection

    def _link_lost(self, error: BaseException) -> None:
        self.lost_since_s = self.clock.monotonic()
        self._tell(f"{self.description}: link lost ({error_text(error)}); every byte before it is kept; "
                   "reconnecting")

    def _tell(self, event: str) -> None:
        self.link_events.append(event)
        if self.on_link_event is not None:
            self.on_link_event(event)

    def _close_quietly(self, connection) -> None:
        try:
            self._close(connection)
        except self.disconnect_errors:
            pass


class SerialSource(LiveSource):
    """A serial port or pyserial URL (``/dev/ttyACM0``, ``COM3``, ``loop://``, ``socket://h:p``, ``rfc2217://``)."""

    disconnect_errors = (serial.SerialException, OSError)

    def __init__(self, url: str, baudrate: int = 115200, read_timeout_s: float = 0.05, max_chunk_bytes: int = 65536,
                 **kwargs) -> None:
        super().__init__(**kwargs)
        if isinstance(baudrate, bool) or not isinstance(baudrate, int) or baudrate <= 0:
            raise TransportError(f"serial port {url}: baud rate must be a positive whole number of bits per second, "
                                 f"got {baudrate!r}")
        self.url, self.baudrate, self.read_timeout_s = url, baudrate, read_timeout_s
        self.max_chunk_bytes = max_chunk_bytes
        self.description = f"serial port {url}"

    def _open(self):
        """Open the port keeping what arrives while it opens: pyserial's ``open()`` ends by discarding the input
        buffer, which on ``socket://`` means every byte the sender streamed since the connection was made."""
        port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=self.read_timeout_s,
                                     do_not_open=True)
        port.reset_input_buffer = _keep_input
        port.open()
        return port

    def _read(self, port) -> bytes:
        """Wait up to the read timeout for a first byte, then take at once what is already waiting (up to
        ``max_chunk_bytes`` in all), so every chunk reaches the caller (and the capture file) as it arrives.

        A disconnect after some bytes arrived returns those bytes; the next read reports the disconnect.
        """
        data = port.read(1)
        if not data:
            return data
        try:
            data += self._read_waiting(port, self.max_chunk_bytes - 1)
        except self.disconnect_errors:
            pass
        return data

    def _read_waiting(self, port, limit: int) -> bytes:
        """Up to ``limit`` bytes that need no waiting. ``in_waiting`` counts them, except on ``socket://``
        where it only says 1 for any amount: there one non-blocking read (``timeout = 0``, which that handler
        applies without any exchange) takes what the OS holds."""
        if not isinstance(port, SocketSerial):
            return port.read(min(port.in_waiting, limit))
        port.timeout = 0
        try:
            return port.read(limit)
        finally:
            port.timeout = self.read_timeout_s

    def _close(self, port) -> None:
        port.close()


def _keep_input() -> None:
    """Stands in for a port's ``reset_input_buffer`` while it opens: received bytes are never thrown away."""


class _UsbLink(NamedTuple):
    device: usb.core.Device
    endpoint_in: usb.core.Endpoint


class UsbBulkSource(LiveSource):
    """The DUML bulk IN endpoint of a DJI USB device (vendor interface, subclass 0x43), through pyusb.

    ``backend`` is passed to ``usb.core.find`` (None: pyusb's default libusb backend).
    """

    disconnect_errors = (usb.core.USBError, ValueError)

    def __init__(self, vendor_id: int = DJI_VENDOR_ID, product_id: int | None = None, backend=None,
                 read_size: int = 4096, read_timeout_ms: int = 100, **kwargs) -> None:
        super().__init__(**kwargs)
        self.vendor_id, self.product_id, self.backend = vendor_id, product_id, backend
        self.read_size, self.read_timeout_ms = read_size, read_timeout_ms
        self.description = f"USB device {vendor_id:04x}:{'*' if product_id is None else f'{product_id:04x}'}"

    def _open(self) -> _UsbLink:
        match = {"idVendor": self.vendor_id} | ({} if self.product_id is None else {"idProduct": self.product_id})
        try:
            devices = list(usb.core.find(find_all=True, backend=self.backend, **match))
        except usb.core.NoBackendError as error:
            raise usb.core.USBError(f"no libusb backend ({error})") from None
        if not devices:
            raise usb.core.USBError("no such device connected")
        problems = []
        for device in devices:
            try:
                _ensure_configured(device)
                return _UsbLink(device, find_duml_bulk_in(device))
            except (usb.core.USBError, ValueError) as error:
                problems.append(f"bus {device.bus} address {device.address}: {error_text(error)}")
        raise usb.core.USBError("; ".join(problems))

    def _read(self, link: _UsbLink) -> bytes:
        try:
            return bytes(link.endpoint_in.read(self.read_size, timeout=self.read_timeout_ms))
        except usb.core.USBTimeoutError:
            return b""

    def _close(self, link: _UsbLink) -> None:
        usb.util.dispose_resources(link.device)


def _ensure_configured(device: usb.core.Device) -> None:
    """Select the first configuration unless one is active (a composite device usually is configured)."""
    try:
        device.get_active_configuration()
    except usb.core.USBError:
        try:
            device.set_configuration()
        except usb.core.USBError as error:
            raise usb.core.USBError(f"cannot select its configuration ({error_text(error)})") from None


def find_duml_bulk_in(device: usb.core.Device) -> usb.core.Endpoint:
    """The bulk IN endpoint of the active configuration's vendor interface with subclass 0x43."""
    for interface in device.get_active_configuration():
        if interface.bInterfaceClass == 0xFF and interface.bInterfaceSubClass == DUML_INTERFACE_SUBCLASS:
            endpoint = usb.util.find_descriptor(interface, custom_match=_is_bulk_in)
            if endpoint is not None:
                return endpoint
    raise ValueError(f"device {device.idVendor:04x}:{device.idProduct:04x} has no DUML bulk interface "
                     f"(vendor class, subclass 0x{DUML_INTERFACE_SUBCLASS:02x}, bulk IN endpoint)")


def _is_bulk_in(endpoint) -> bool:
    return (usb.util.endpoint_direction(endpoint.bEndpointAddress) == usb.util.ENDPOINT_IN
            and usb.util.endpoint_type(endpoint.bmAttributes) == usb.util.ENDPOINT_TYPE_BULK)


class HidSource(LiveSource):
    """A HID device with hidapi's shape: ``open_device()`` returns an object with ``read(size, timeout_ms)``
    (a list of ints, empty on timeout), ``write`` and ``close``. Reports are passed on as they are."""

    disconnect_errors = (OSError, ValueError)

    def __init__(self, open_device: Callable[[], object], report_size: int = 64, read_timeout_ms: int = 100,
                 description: str = "HID device", **kwargs) -> None:
        super().__init__(**kwargs)
        self.open_device, self.report_size, self.read_timeout_ms = open_device, report_size, read_timeout_ms
        self.description = description

    def _open(self):
        return self.open_device()

    def _read(self, device) -> bytes:
        return bytes(device.read(self.report_size, self.read_timeout_ms))

    def _close(self, device) -> None:
        device.close()


def hidapi_opener(vendor_id: int, product_id: int) -> Callable[[], object]:
    """Factory for :class:`HidSource` that opens a real device with the ``hidapi`` package."""

    def open_device():
        import hid

        device = hid.device()
        device.open(vendor_id, product_id)
        return device

    return open_device


def replay_file(path: str | Path, problems: list[str] | None = None) -> Iterator[Chunk]:
    """Chunks of a raw capture (``.duml`` + ``.idx``), a pcap or a pcapng with link type 150, as received.

    Damage that still leaves data to read (a cut-short last record, a corrupt record length) is described in
    ``problems`` (when given) and read past; see :func:`read_pcap` and :func:`read_pcapng`.
    """
    path = Path(path)
    if path.is_dir():
        raise TransportError(f"{path}: is a directory, expected a capture file (.duml, .pcap or .pcapng)")
    if not path.is_file():
        raise TransportError(f"{path}: no such file")
    kind = capture_format(path)
    if kind == "pcap":
        return read_pcap(path, problems)
    if kind == "pcapng":
        return read_pcapng(path, problems)
    return (Chunk(*chunk) for chunk in read_capture_chunks(path))


def capture_format(path: str | Path) -> str:
    """``pcap`` or ``pcapng`` by the file's magic number, else ``raw`` (a ``.duml`` raw capture)."""
    with open(path, "rb") as handle:
        magic = handle.read(4)
    return "pcap" if magic in _PCAP_MAGIC else "pcapng" if magic == _PCAPNG_MAGIC else "raw"


def is_pcap(path: str | Path) -> bool:
    """Whether ``path`` is a packet capture (classic pcap or pcapng), so it carries its own times."""
    return capture_format(path) != "raw"


_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"  # section header block type
_PCAP_MAGIC = {b"\xd4\xc3\xb2\xa1": ("<", 1e-6), b"\xa1\xb2\xc3\xd4": (">", 1e-6),
               b"\x4d\x3c\xb2\xa1": ("<", 1e-9), b"\xa1\xb2\x3c\x4d": (">", 1e-9)}
_PCAP_HEADER_BYTES = 24
_PCAP_RECORD_BYTES = 16  # seconds, fraction, captured length, original length (u32 each)
_PCAP_MAX_SNAPLEN = 262144  # libpcap's largest; a header snap length of 0 means "no limit" up to it
_PCAP_MAX_GAP_S = 86400  # a record more than a day after the one before it is taken for corrupt bytes
_PCAP_RESYNC_WINDOW = 1 << 18  # offsets searched at once for the next valid record after a corrupt one


def read_pcap(path: str | Path, problems: list[str] | None = None) -> Iterator[Chunk]:
    """Records of a classic pcap holding DUML (link type 150); the monotonic time counts from the first.

    A record header is valid when its fraction is below one second and its captured length is at most the file's
    snap length and the original length. A file cut short inside its last record (a capture killed mid-write)
    yields that record's bytes that are there, then stops. A record is corrupt when its header is invalid, or
    when its length ends where a whole header follows whose time is impossible (a wrong length that still
    looked possible): reading resumes at the next valid record header after its header (one whose record ends
    at the end of the file or at another valid header, at most a day after the last good record), and the bytes
    in between are passed on without times, so no telemetry is lost and no bytes get another record's time.
    Each such event appends one line naming the byte offset to ``problems``. This reader is kept by hand
    because library readers (dpkt, scapy) trust a corrupt length and swallow the rest of the file.
    TransportError for a file that is not a pcap, whose header is cut short, or whose link type is not DUML.
    """
    data = Path(path).read_bytes()
    endian, tick = _PCAP_MAGIC.get(data[:4], (None, None))
    if endian is None:
        raise TransportError(f"{path}: not a pcap file (magic {data[:4].hex()})")
    if len(data) < _PCAP_HEADER_BYTES:
        raise TransportError(f"{path}: pcap file header cut short ({len(data)} of {_PCAP_HEADER_BYTES} bytes)")
    snaplen, linktype = struct.unpack_from(endian + "2I", data, 16)
    if linktype != PCAP_LINKTYPE_DUML:
        raise TransportError(f"{path}: pcap link type {linktype}, expected {PCAP_LINKTYPE_DUML} (DUML, DLT_USER3)")
    headers = _PcapHeaders(data, endian, round(1 / tick), min(snaplen or _PCAP_MAX_SNAPLEN, _PCAP_MAX_SNAPLEN))
    return _pcap_chunks(path, data, headers, tick, problems)


class _PcapHeaders:
    """Record headers of a pcap's bytes at any offset, and whether they are valid (see :func:`read_pcap`)."""

    def __init__(self, data: bytes, endian: str, fractions_per_s: int, snaplen: int) -> None:
        self.data, self.endian, self.fractions_per_s, self.snaplen = data, endian, fractions_per_s, snaplen
        self.unpack = struct.Struct(endian + "4I").unpack_from

    def valid(self, position: int) -> bool:
        _, fraction, captured, original = self.unpack(self.data, position)
        return fraction < self.fractions_per_s and captured <= min(self.snaplen, original)

    def followed_well(self, position: int) -> bool:
        """Whether the record at ``position`` ends at or past the end of the data (or of a header cut short
        there), or where a header starts whose time is valid and within a day after this record's (its length
        may still be corrupt: that is the next record's problem, not a sign that this length is wrong)."""
        seconds, _, captured, _ = self.unpack(self.data, position)
        end = position + _PCAP_RECORD_BYTES + captured
        if end + _PCAP_RECORD_BYTES > len(self.data):
            return True
        next_seconds, next_fraction, _, _ = self.unpack(self.data, end)
        return next_fraction < self.fractions_per_s and seconds - 1 <= next_seconds <= seconds + _PCAP_MAX_GAP_S

    def fits(self, position: int) -> bool:
        """A valid header whose record ends exactly at the end of the data or at another valid header."""
        if position + _PCAP_RECORD_BYTES > len(self.data) or not self.valid(position):
            return False
        end = position + _PCAP_RECORD_BYTES + self.unpack(self.data, position)[2]
        return end == len(self.data) or (end + _PCAP_RECORD_BYTES <= len(self.data) and self.valid(end))

    def next_fitting(self, after: int, last_seconds: int | None) -> int | None:
        """The first offset past ``after`` that :meth:`fits`, holds at least one byte and, when a record was read
        before (``last_seconds``), a time from one second before it to a day after. Candidates are found with
        numpy, one window of :data:`_PCAP_RESYNC_WINDOW` offsets at a time (memory stays small)."""
        start = after + 1
        while start + _PCAP_RECORD_BYTES <= len(self.data):
            words = self._words(start, min(len(self.data), start + _PCAP_RESYNC_WINDOW + _PCAP_RECORD_BYTES - 1))
            count = len(words) - 12  # offsets whose whole 16-byte header is in the window
            seconds, fraction, captured, original = (words[k:k + count] for k in (0, 4, 8, 12))
            valid = ((fraction < self.fractions_per_s) & (captured > 0)
                     & (captured <= np.minimum(original, self.snaplen)))
            if last_seconds is not None:
                valid &= (seconds.astype(np.int64) + 1 >= last_seconds) & (seconds <= last_seconds + _PCAP_MAX_GAP_S)
            found = next((start + int(p) for p in np.flatnonzero(valid) if self.fits(start + int(p))), None)
            if found is not None:
                return found
            start += count
        return None

    def _words(self, start: int, stop: int) -> np.ndarray:
        """The u32 (in the file's byte order) starting at each byte offset from ``start`` to ``stop - 4``."""
        b = np.frombuffer(self.data, np.uint8, count=stop - start, offset=start).astype(np.uint32)
        parts = (b[:-3], b[1:-2], b[2:-1], b[3:])
        low_first = parts if self.endian == "<" else parts[::-1]
        return low_first[0] | low_first[1] << 8 | low_first[2] << 16 | low_first[3] << 24


def _pcap_chunks(path, data: bytes, headers: _PcapHeaders, tick: float, problems) -> Iterator[Chunk]:
    position, first, last_seconds = _PCAP_HEADER_BYTES, None, None
    while position < len(data):
        if position + _PCAP_RECORD_BYTES > len(data):
            _note(problems, f"{path}: truncated record at byte {position}: its header is cut short "
                            f"({len(data) - position} of {_PCAP_RECORD_BYTES} bytes), dropped")
            return
        seconds, fraction, captured, _ = headers.unpack(data, position)
        body = position + _PCAP_RECORD_BYTES
        if not headers.valid(position) or not headers.followed_well(position):
            resume = headers.next_fitting(body - 1, last_seconds)
            end = len(data) if resume is None else resume
            why = (f"captured length {captured}, fraction {fraction}: impossible with snap length {headers.snaplen}"
                   if not headers.valid(position) else
                   f"captured length {captured} ends at byte {body + captured}, where no record header starts")
            _note(problems, f"{path}: corrupt record at byte {position} ({why}): "
                            + (f"{end - body} bytes up to the next valid record at byte {resume} decoded without "
                               "times" if resume is not None else
                               f"no valid record after it, its last {end - body} bytes decoded without times"))
            if end > body:
                yield Chunk(None, None, data[body:end])
            position = end
            continue
        stamp, last_seconds = seconds + fraction * tick, seconds
        first = stamp if first is None else first
        payload = data[body:body + captured]
        yield Chunk(dt.datetime.fromtimestamp(stamp, dt.timezone.utc), stamp - first, payload)
        if len(payload) < captured:
            _note(problems, f"{path}: truncated record at byte {position}: {len(payload)} of {captured} bytes "
                            "there, kept")
            return
        position = body + captured


def read_pcapng(path: str | Path, problems: list[str] | None = None) -> Iterator[Chunk]:
    """Packets of a pcapng (Wireshark's format) holding DUML, read with ``dpkt.pcapng.Reader``.

    Each enhanced packet block becomes a chunk stamped with its timestamp (the interface's resolution and
    offset applied); the monotonic time counts from the first. TransportError for a file whose section header
    or interface description cannot be read or whose link type is not DUML (150). A block that cannot be read
    (cut short by a kill, or corrupt) ends the reading; one line naming its byte offset goes to ``problems``.
    """
    data = Path(path).read_bytes()
    stream = io.BytesIO(data)
    try:
        reader = dpkt.pcapng.Reader(stream)
    except (ValueError, struct.error, dpkt.Error) as error:
        raise TransportError(f"{path}: not a readable pcapng file ({str(error) or type(error).__name__})") from None
    if reader.datalink() != PCAP_LINKTYPE_DUML:
        raise TransportError(f"{path}: pcapng link type {reader.datalink()}, expected {PCAP_LINKTYPE_DUML} "
                             "(DUML, DLT_USER3)")
    return _pcapng_chunks(path, data, stream, reader, problems)


def _pcapng_chunks(path, data: bytes, stream: io.BytesIO, reader, problems) -> Iterator[Chunk]:
    position, first = stream.tell(), None
    try:
        for stamp, payload in reader:
            first = stamp if first is None else first
            yield Chunk(dt.datetime.fromtimestamp(stamp, dt.timezone.utc), stamp - first, bytes(payload))
            position = stream.tell()
    except (ValueError, struct.error, dpkt.Error) as error:
        reason = "cut short" if isinstance(error, dpkt.NeedData) else str(error) or type(error).__name__
        _note(problems, f"{path}: unreadable block at byte {position} ({reason}): the "
                        f"{len(data) - position} bytes from there on are not read")


def _note(problems: list[str] | None, problem: str) -> None:
    if problems is not None:
        problems.append(problem)
