"""Live recording: source chunks -> raw capture file first, then a running decode for the status line."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable, Iterable

from capture.duml import Deframer
from capture.messages import MessageRegistry, OsdGeneral
from capture.raw import RawCaptureWriter
from capture.transports import Chunk


@dataclass
class RecordStatus:
    """What the status line shows. Rates are averages since the start (per second)."""

    elapsed_s: float = 0.0
    bytes: int = 0
    packets: int = 0
    header_crc_errors: int = 0
    packet_crc_errors: int = 0
    last_osd: OsdGeneral | None = None

    def line(self) -> str:
        rate = 1.0 / self.elapsed_s if self.elapsed_s > 0 else 0.0
        position = "no OSD yet"
        if self.last_osd is not None:
            osd = self.last_osd
            position = (f"{osd.latitude_deg:.6f},{osd.longitude_deg:.6f} h {osd.height_above_takeoff_m:.1f} m "
                        f"yaw {osd.yaw_deg:.1f} sats {osd.gps_satellites}" if osd.has_fix else "no GPS fix")
        return (f"{self.elapsed_s:7.1f} s  {self.bytes} B ({self.bytes * rate:.0f} B/s)  {self.packets} packets "
                f"({self.packets * rate:.1f}/s)  CRC errors: header {self.header_crc_errors} packet "
                f"{self.packet_crc_errors}  last: {position}")


def record(chunks: Iterable[Chunk], writer: RawCaptureWriter, registry: MessageRegistry,
           on_status: Callable[[RecordStatus], None] | None = None, status_interval_s: float = 0.5,
           tap: Callable[[Chunk], None] | None = None) -> RecordStatus:
    """Append every chunk to ``writer`` (flushed) BEFORE parsing it, then hand it to ``tap`` (a live view's
    non-blocking put, :class:`capture.live_view.LiveMonitor`) and update the status. Returns the last status.

    Stops when ``chunks`` ends (the source's stop event) or on KeyboardInterrupt (Ctrl-C).
    """
    deframer = Deframer()
    status = RecordStatus()
    started = time.monotonic()
    last_report = started
    try:
        for chunk in chunks:
            writer.append(chunk.receive_time_utc, chunk.receive_time_monotonic, chunk.data)
            status.bytes += len(chunk.data)
            if tap is not None:
                tap(chunk)
            for _, packet in deframer.feed(chunk.data):
                record_ = registry.decode(packet)
                if isinstance(record_, OsdGeneral):
                    status.last_osd = record_
            now = time.monotonic()
            _refresh(status, deframer, now - started)
            if on_status is not None and now - last_report >= status_interval_s:
                on_status(status)
                last_report = now
    except KeyboardInterrupt:
        pass
    _refresh(status, deframer, time.monotonic() - started)
    return status


def _refresh(status: RecordStatus, deframer: Deframer, elapsed_s: float) -> None:
    status.elapsed_s = elapsed_s
    status.packets = deframer.stats.packets
    status.header_crc_errors = deframer.stats.rejected_frames["bad_header_crc"]
    status.packet_crc_errors = deframer.stats.rejected_frames["bad_packet_crc"]


def stop_after(duration_s: float | None) -> threading.Event:
    """An event that sets itself after ``duration_s`` seconds (never when None)."""
    stop = threading.Event()
    if duration_s is not None:
        timer = threading.Timer(duration_s, stop.set)
        timer.daemon = True
        timer.start()
    return stop
