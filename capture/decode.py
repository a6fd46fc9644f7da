"""From received chunks to time-stamped packets and decoded telemetry rows (the ``decode`` pipeline).

Chunks are joined into blocks of about a megabyte before deframing (the deframer is vectorised per feed),
and every packet gets the receive time of the chunk holding its LAST byte: the moment it became complete.
"""

from __future__ import annotations

import csv
import datetime as dt
import gc
import io
import operator
import os
from contextlib import contextmanager
from dataclasses import fields
from typing import Callable, Iterable, Iterator, NamedTuple

import numpy as np

from capture.duml import Deframer, Packet
from capture.messages import MalformedMessage, MessageRegistry, UndecodedMessage
from capture.transports import Chunk
from cliutil.atomic import atomic_path

_LINES_PER_WRITE = 4096  # CSV lines joined into one write
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


_PACKET_COLUMNS = ["utc_time", "monotonic_s", "offset", "kind", "seq", "sender", "receiver"]


def csv_columns(registry: MessageRegistry) -> list[str]:
    """Header of the telemetry CSV: time and packet columns, then every record field and property."""
    columns = list(_PACKET_COLUMNS)
    for spec in registry.specs:
        for name in _record_columns(spec.record_type):
            if name not in columns:
                columns.append(name)
    return columns


def _record_columns(record_type: type) -> list[str]:
    properties = [name for name, value in vars(record_type).items() if isinstance(value, property)]
    return [f.name for f in fields(record_type) if f.name != "extension"] + properties


def _declared_type(record_type: type, name: str) -> str:
    """The declared type of the field or property ``name`` of ``record_type``, as text (``int``, ``bool``...)."""
    attribute = vars(record_type).get(name)
    if isinstance(attribute, property):
        declared = attribute.fget.__annotations__.get("return")
    else:
        declared = next(f.type for f in fields(record_type) if f.name == name)
    return getattr(declared, "__name__", str(declared))


class _RowLayout(NamedTuple):
    """How a record type's CSV line is made: one ``%`` formatting of a template with its columns' values."""

    template: str  # the whole line with "%s" for the packet fields and the record's values, "" elsewhere
    values: Callable  # record -> tuple of its columns' values (one C-level attrgetter)
    bool_positions: list[int]  # positions in that tuple of bools (written 0/1, as csv does for int(bool))
    text_positions: list[int]  # positions of values that are not numbers (quoted the csv way)


class TelemetryRows:
    """CSV lines (``\\r\\n``-terminated, as ``csv.writer`` writes them) for decoded records, in
    :func:`csv_columns` order. Numbers and bools need no quoting, so a line is one ``%`` formatting; the packet
    time is formatted once per chunk, not per packet. This is what makes ``decode`` several times faster than
    ``csv.DictWriter`` (``%s`` writes a float as ``repr``, as csv does)."""

    def __init__(self, registry: MessageRegistry) -> None:
        self.registry = registry
        self.columns = csv_columns(registry)
        self._layouts: dict[type, _RowLayout] = {}
        self._time: tuple = (object(), "", "")  # (utc object, its ISO text, monotonic text) of the last packet

    def header(self) -> str:
        return _csv_line(self.columns)

    def line(self, timed: TimedPacket, record) -> str:
        template, values_of, bool_positions, text_positions = (self._layouts.get(type(record))
                                                               or self._layout(type(record)))
        offset, utc, mono, packet = timed
        if utc is not self._time[0]:  # packets of one chunk share their time objects
            self._time = (utc, _iso(utc), "" if mono is None else f"{mono:.6f}")
        values = values_of(record)
        if bool_positions or text_positions:
            values = list(values)
            for position in bool_positions:
                values[position] = int(values[position])
            for position in text_positions:
                values[position] = _csv_line([values[position]])[:-2]
            values = tuple(values)
        _, iso, mono_text = self._time
        return template % ((iso, mono_text, offset, packet.seq, packet.sender, packet.receiver) + values)

    def _layout(self, record_type: type) -> _RowLayout:
        names = _record_columns(record_type)
        declared = [_declared_type(record_type, name) for name in names]
        placeholders = {name: "%s" for name in names}
        kind = _csv_line([self.registry.spec_for(record_type).kind])[:-2].replace("%", "%%")
        record_cells = [placeholders.get(column, "") for column in self.columns[len(_PACKET_COLUMNS):]]
        layout = _RowLayout(",".join(["%s", "%s", "%s", kind, "%s", "%s", "%s", *record_cells]) + "\r\n",
                            operator.attrgetter(*names),
                            [i for i, t in enumerate(declared) if t == "bool"],
                            [i for i, t in enumerate(declared) if t not in ("bool", "int", "float")])
        self._layouts[record_type] = layout
        return layout


def _csv_line(cells: list) -> str:
    """``cells`` as ``csv.writer`` writes them (quoted where needed, ``\\r\\n`` at the end)."""
    text = io.StringIO()
    csv.writer(text).writerow(cells)
    return text.getvalue()


def _iso(time: dt.datetime | None) -> str:
    return "" if time is None else time.astimezone(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


class DecodeSummary(NamedTuple):
    rows: int
    message_counts: dict[str, int]
    skipped_bytes: dict[str, int]
    rejected_frames: dict[str, int]
    bytes_read: int
    packets: int


@contextmanager
def _cycle_collector_paused() -> Iterator[None]:
    """Pause Python's cycle collector: decoding allocates a few short-lived, acyclic objects per packet (freed
    by reference counting), and the collector's passes over them cost 15-20 % of ``decode``'s CPU."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


class NoFramesError(ValueError):
    """The input held no intact DUML frame: nothing is written (an existing output is left as it was)."""

    def __init__(self, bytes_read: int) -> None:
        super().__init__(f"no DUML frame found in {bytes_read} bytes (not a DUML capture?)")


def decode_to_csv(chunks: Iterable[Chunk], out_path: str | os.PathLike, registry: MessageRegistry) -> DecodeSummary:
    """Write one row per decoded telemetry message to ``out_path`` (atomically) and summarise;
    :class:`NoFramesError` (and no file written) when the chunks hold no intact frame."""
    deframer = Deframer(commands=registry.commands)  # other commands are counted, not built, so not decoded
    rows = TelemetryRows(registry)
    count = 0
    with _cycle_collector_paused(), atomic_path(out_path) as temporary, \
            open(temporary, "w", newline="", encoding="utf-8") as handle:
        handle.write(rows.header())
        lines = []
        for timed in timed_packets(chunks, deframer):
            record = registry.decode(timed.packet)
            if not isinstance(record, (UndecodedMessage, MalformedMessage)):
                lines.append(rows.line(timed, record))
            if len(lines) == _LINES_PER_WRITE:
                handle.write("".join(lines))
                count, lines = count + len(lines), []
        handle.write("".join(lines))
        count += len(lines)
        if not deframer.stats.packets:
            raise NoFramesError(deframer.stats.bytes_fed)  # inside atomic_path: the temporary goes, not the target
    stats = deframer.stats
    registry.count_undecoded(stats.unbuilt_packets)
    return DecodeSummary(count, dict(registry.counts), dict(stats.skipped_bytes), dict(stats.rejected_frames),
                         stats.bytes_fed, stats.packets)
