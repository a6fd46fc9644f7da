"""From received chunks to time-stamped packets and decoded telemetry rows (the ``decode`` pipeline).

Chunks are joined into blocks of about a megabyte before deframing (the deframer is vectorised per feed),
and every packet gets the receive time of the chunk holding its LAST byte: the moment it became complete.
"""

from __future__ import annotations

import csv
import datetime as dt
import os
from dataclasses import fields
from typing import Iterable, Iterator, NamedTuple

import numpy as np

from capture.duml import Deframer, Packet
from capture.messages import MalformedMessage, MessageRegistry, UndecodedMessage
from capture.transports import Chunk
from flightplan.atomic import atomic_path

_HISTORY_BYTES = 4096  # > the 1023 bytes a deframer can hold back, so older chunks can be forgotten


class TimedPacket(NamedTuple):
    offset: int  # stream offset of the frame's 0x55
    receive_time_utc: dt.datetime | None
    receive_time_monotonic: float | None
    packet: Packet


def timed_packets(chunks: Iterable[Chunk], deframer: Deframer, block_bytes: int = 1 << 20) -> Iterator[TimedPacket]:
    """Deframe ``chunks`` (flushing at the end) and stamp each packet with its completion time."""
    starts: list[int] = []
    times: list[tuple] = []
    block: list[bytes] = []
    block_size = stream_size = 0
    for chunk in chunks:
        starts.append(stream_size)
        times.append((chunk.receive_time_utc, chunk.receive_time_monotonic))
        block.append(chunk.data)
        stream_size += len(chunk.data)
        block_size += len(chunk.data)
        if block_size >= block_bytes:
            yield from _stamp(deframer.feed(b"".join(block)), starts, times)
            keep = max(0, int(np.searchsorted(starts, stream_size - _HISTORY_BYTES, side="right")) - 1)
            del starts[:keep], times[:keep]
            block, block_size = [], 0
    yield from _stamp(deframer.feed(b"".join(block)), starts, times)
    yield from _stamp(deframer.flush(), starts, times)


def _stamp(pairs: list[tuple[int, Packet]], starts: list[int], times: list[tuple]) -> Iterator[TimedPacket]:
    if not pairs:
        return
    last_bytes = np.array([offset + packet.frame_length - 1 for offset, packet in pairs])
    chunk_index = np.searchsorted(np.asarray(starts), last_bytes, side="right") - 1
    for (offset, packet), i in zip(pairs, chunk_index.tolist()):
        yield TimedPacket(offset, *times[i], packet)


def csv_columns(registry: MessageRegistry) -> list[str]:
    """Header of the telemetry CSV: time and packet columns, then every record field and property."""
    columns = ["utc_time", "monotonic_s", "offset", "kind", "seq", "sender", "receiver"]
    for spec in registry.specs:
        for name in _record_columns(spec.record_type):
            if name not in columns:
                columns.append(name)
    return columns


def _record_columns(record_type: type) -> list[str]:
    properties = [name for name, value in vars(record_type).items() if isinstance(value, property)]
    return [f.name for f in fields(record_type) if f.name != "extension"] + properties


def telemetry_row(timed: TimedPacket, kind: str, record) -> dict:
    """One CSV row (a dict keyed by :func:`csv_columns`) for a decoded record."""
    row = {"utc_time": _iso(timed.receive_time_utc),
           "monotonic_s": "" if timed.receive_time_monotonic is None else f"{timed.receive_time_monotonic:.6f}",
           "offset": timed.offset, "kind": kind, "seq": timed.packet.seq,
           "sender": timed.packet.sender, "receiver": timed.packet.receiver}
    for name in _record_columns(type(record)):
        value = getattr(record, name)
        row[name] = int(value) if isinstance(value, bool) else value
    return row


def _iso(time: dt.datetime | None) -> str:
    return "" if time is None else time.astimezone(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


class DecodeSummary(NamedTuple):
    rows: int
    message_counts: dict[str, int]
    skipped_bytes: dict[str, int]
    rejected_frames: dict[str, int]
    bytes_read: int
    packets: int


def decode_to_csv(chunks: Iterable[Chunk], out_path: str | os.PathLike, registry: MessageRegistry) -> DecodeSummary:
    """Write one row per decoded telemetry message to ``out_path`` (atomically) and summarise."""
    deframer = Deframer()
    rows = 0
    with atomic_path(out_path) as temporary, open(temporary, "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=csv_columns(registry), restval="")
        writer.writeheader()
        for timed in timed_packets(chunks, deframer):
            record = registry.decode(timed.packet)
            if isinstance(record, (UndecodedMessage, MalformedMessage)):
                continue
            writer.writerow(telemetry_row(timed, registry.spec_for(record).kind, record))
            rows += 1
    stats = deframer.stats
    return DecodeSummary(rows, dict(registry.counts), dict(stats.skipped_bytes), dict(stats.rejected_frames),
                         stats.bytes_fed, stats.packets)
