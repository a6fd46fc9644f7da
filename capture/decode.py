"""From received chunks to time-stamped packets and decoded telemetry rows (the ``decode`` pipeline).

Chunks are joined into blocks of about a megabyte before deframing (the deframer is vectorised per feed),
and every packet gets the receive time of the chunk holding its LAST byte: the moment it became complete.
The CSV is written a block at a time: the frames of each message with a :class:`ColumnLayout` are decoded and
formatted together with numpy (:mod:`capture.csv_text`), others one by one, and the lines are put back in
stream order.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import operator
import os
from dataclasses import fields
from typing import Callable, Iterable, Iterator, NamedTuple

import numpy as np

from capture.csv_text import join_cells, number_text, strings_text
from capture.duml import HEADER_LENGTH, MIN_FRAME_LENGTH, Deframer, FrameBatch, FramePiece, Packet, packets_from_frames
from capture.messages import MessageRegistry, MessageSpec
from capture.transports import Chunk
from cliutil.atomic import atomic_path

_HISTORY_BYTES = 4096  # > the 1023 bytes a deframer can hold back, so older chunks can be forgotten


class TimedPacket(NamedTuple):
    offset: int  # stream offset of the frame's 0x55
    receive_time_utc: dt.datetime | None
    receive_time_monotonic: float | None
    packet: Packet


class TimedFrames(NamedTuple):
    """The frames of one deframed block and, per frame, the receive times of the chunk holding its last byte."""

    piece: FramePiece
    times: list[tuple]  # (receive_time_utc, receive_time_monotonic) of the chunks that completed these frames
    time_index: np.ndarray  # per frame, its chunk's position in ``times``


def timed_frames(chunks: Iterable[Chunk], deframer: Deframer, block_bytes: int = 1 << 20) -> Iterator[TimedFrames]:
    """Deframe ``chunks`` (flushing at the end) a block of about ``block_bytes`` at a time; blocks with no frame
    are left out."""
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
            yield from _stamp(deframer.feed_pieces(b"".join(block)), starts, times)
            keep = max(0, int(np.searchsorted(starts, stream_size - _HISTORY_BYTES, side="right")) - 1)
            del starts[:keep], times[:keep]
            block, block_size = [], 0
    yield from _stamp(deframer.feed_pieces(b"".join(block)) + [deframer.flush_piece()], starts, times)


def _stamp(pieces: list[FramePiece], starts: list[int], times: list[tuple]) -> Iterator[TimedFrames]:
    for piece in pieces:
        if len(piece.frames.starts):
            last_bytes = piece.offset + piece.frames.starts + piece.frames.lengths - 1
            chunk_index = np.searchsorted(np.asarray(starts), last_bytes, side="right") - 1
            used, time_index = np.unique(chunk_index, return_inverse=True)
            yield TimedFrames(piece, [times[i] for i in used.tolist()], time_index)


def timed_packets(chunks: Iterable[Chunk], deframer: Deframer, block_bytes: int = 1 << 20) -> Iterator[TimedPacket]:
    """Deframe ``chunks`` (flushing at the end) and stamp each packet with its completion time."""
    for (buffer, offset, frames), times, time_index in timed_frames(chunks, deframer, block_bytes):
        for start, i, packet in zip((frames.starts + offset).tolist(), time_index.tolist(),
                                    packets_from_frames(buffer, frames)):
            yield TimedPacket(start, *times[i], packet)


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
    :func:`csv_columns` order, byte for byte what ``csv.DictWriter`` writes (floats as ``repr``, bools 0/1).

    :meth:`block` makes the lines of a whole block of frames, each message's frames together
    (:mod:`capture.csv_text`) when its spec has a :class:`ColumnLayout`; :meth:`line` makes one record's line
    (one ``%`` formatting; numbers and bools need no quoting, text is quoted the csv way)."""

    def __init__(self, registry: MessageRegistry) -> None:
        self.registry = registry
        self.columns = csv_columns(registry)
        self._layouts: dict[type, _RowLayout] = {}
        self._templates: dict[type, _LineTemplate | None] = {}
        self._specs = {spec.cmd_set << 8 | spec.cmd_id: spec for spec in registry.specs}
        self._time: tuple = (object(), "", "")  # (utc object, its ISO text, monotonic text) of the last packet

    def header(self) -> str:
        return _csv_line(self.columns)

    def block(self, timed: TimedFrames) -> tuple[bytes, int]:
        """``(UTF-8 lines, how many)`` for the decodable frames of ``timed``, in stream order. Every frame is
        counted on the registry: by kind, as ``malformed_KIND`` (a payload length outside the spec's range; no
        line) or as ``undecoded`` (no spec)."""
        buffer, _, frames = timed.piece
        array = np.frombuffer(buffer, dtype=np.uint8)
        keys = array[frames.starts + 9].astype(np.int64) << 8 | array[frames.starts + 10]
        payload_lengths = frames.lengths - MIN_FRAME_LENGTH
        times = _time_texts(timed.times)
        parts, malformed = [], []
        for key in np.unique(keys).tolist():
            spec, rows = self._specs.get(key), np.flatnonzero(keys == key)
            if spec is None:
                self.registry.count("undecoded", len(rows))
                continue
            fits = (payload_lengths[rows] >= spec.min_payload) & (payload_lengths[rows] <= spec.max_payload)
            if not fits.all():
                malformed.append((int(rows[~fits][0]), spec.kind, len(rows) - int(np.count_nonzero(fits))))
            rows = rows[fits]
            if len(rows):
                self.registry.count(spec.kind, len(rows))
                parts.append((rows, *self._lines(spec, timed, rows, times)))
        for _, kind, packets in sorted(malformed):  # counters appear in the order of their first frame
            self.registry.count(f"malformed_{kind}", packets)
        return _in_stream_order(parts), sum(len(rows) for rows, _, _ in parts)

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
                values[position] = _csv_cell(values[position])
            values = tuple(values)
        _, iso, mono_text = self._time
        return template % ((iso, mono_text, offset, packet.seq, packet.sender, packet.receiver) + values)

    def _layout(self, record_type: type) -> _RowLayout:
        names = _record_columns(record_type)
        declared = [_declared_type(record_type, name) for name in names]
        placeholders = {name: "%s" for name in names}
        kind = _csv_cell(self.registry.spec_for(record_type).kind).replace("%", "%%")
        record_cells = [placeholders.get(column, "") for column in self.columns[len(_PACKET_COLUMNS):]]
        layout = _RowLayout(",".join(["%s", "%s", "%s", kind, "%s", "%s", "%s", *record_cells]) + "\r\n",
                            operator.attrgetter(*names),
                            [i for i, t in enumerate(declared) if t == "bool"],
                            [i for i, t in enumerate(declared) if t not in ("bool", "int", "float")])
        self._layouts[record_type] = layout
        return layout

    def _lines(self, spec: MessageSpec, timed: TimedFrames, rows: np.ndarray,
               times: tuple[np.ndarray, np.ndarray]) -> tuple[bytes, np.ndarray]:
        """``(lines, each one's length)`` for the frames ``rows`` of ``timed``, all of message ``spec``."""
        if spec.record_type not in self._templates:
            self._templates[spec.record_type] = self._template(spec.record_type)
        template = self._templates[spec.record_type]
        if spec.columns is None or template is None:
            return self._lines_one_by_one(spec, timed, rows)
        buffer, offset, frames = timed.piece
        array = np.frombuffer(buffer, dtype=np.uint8)
        starts = frames.starts[rows]
        payloads = array[(starts + HEADER_LENGTH)[:, None] + np.arange(spec.columns.dtype.itemsize)]
        values = _with_properties(spec.record_type, spec.columns.decode(payloads), len(rows))
        utc, mono = (text[timed.time_index[rows]] for text in times)
        seq = array[starts + 6].astype(np.uint16) | array[starts + 7].astype(np.uint16) << 8
        packet_cells = [utc, b",", mono, b",", number_text(starts + offset), template.kind, number_text(seq), b",",
                        number_text(array[starts + 4]), b",", number_text(array[starts + 5])]
        record_cells = [cell if isinstance(cell, bytes) else number_text(values[cell]) for cell in template.record]
        return join_cells(packet_cells + record_cells, len(rows))

    def _lines_one_by_one(self, spec: MessageSpec, timed: TimedFrames, rows: np.ndarray) -> tuple[bytes, np.ndarray]:
        buffer, offset, frames = timed.piece
        batch = FrameBatch(frames.starts[rows], frames.lengths[rows])
        lines = [self.line(TimedPacket(offset + start, *timed.times[i], packet), spec.decode(packet.payload)).encode()
                 for start, i, packet in zip(batch.starts.tolist(), timed.time_index[rows].tolist(),
                                             packets_from_frames(buffer, batch))]
        return b"".join(lines), np.fromiter(map(len, lines), dtype=np.int64, count=len(lines))

    def _template(self, record_type: type) -> _LineTemplate | None:
        """None when the kind's text holds a NUL byte (which :func:`join_cells` would drop: such lines are made
        one by one)."""
        kind = _csv_cell(self.registry.spec_for(record_type).kind)
        names = set(_record_columns(record_type))
        record: list = [b""]
        for column in self.columns[len(_PACKET_COLUMNS):]:
            record[-1] += b","
            if column in names:
                record += [column, b""]
        record[-1] += b"\r\n"
        return None if "\0" in kind else _LineTemplate(f",{kind},".encode(), record)


class _LineTemplate(NamedTuple):
    """A record type's line after the packet's offset and before its seq, and after its receiver."""

    kind: bytes  # the kind with the commas around it
    record: list  # the record columns: fixed bytes (commas, empty cells, the line end) and column names


def _with_properties(record_type: type, columns: dict[str, np.ndarray], rows: int) -> dict[str, np.ndarray]:
    """``columns`` (a record type's fields for ``rows`` records) and the record type's properties evaluated on
    them (properties are written to work on arrays, see :mod:`capture.messages`)."""
    records = _Records(record_type, columns)
    return columns | {name: np.broadcast_to(np.asarray(getattr(records, name)), (rows,))
                      for name, value in vars(record_type).items() if isinstance(value, property)}


class _Records:
    """Many records of one type as arrays: its fields, and its properties evaluated on them when read."""

    def __init__(self, record_type: type, columns: dict[str, np.ndarray]) -> None:
        self._record_type, self._columns = record_type, columns

    def __getattr__(self, name: str):
        if name in self._columns:
            return self._columns[name]
        attribute = vars(self._record_type).get(name)
        if not isinstance(attribute, property):
            raise AttributeError(f"{self._record_type.__name__} has no field or property {name!r}")
        return attribute.fget(self)


def _time_texts(times: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """The utc_time and monotonic_s cells of chunks with receive times ``times``, as text arrays."""
    return (strings_text([_iso(utc) for utc, _ in times]),
            strings_text(["" if mono is None else f"{mono:.6f}" for _, mono in times]))


def _in_stream_order(parts: list[tuple[np.ndarray, bytes, np.ndarray]]) -> bytes:
    """The lines of ``parts`` (per message: its frames' positions in the block, their lines, each line's length)
    merged in frame order: one slice per run of neighbouring frames of one message."""
    if len(parts) < 2:
        return parts[0][1] if parts else b""
    part = np.concatenate([np.full(len(rows), i) for i, (rows, _, _) in enumerate(parts)])
    ends = np.concatenate([np.cumsum(lengths) for _, _, lengths in parts])
    starts = ends - np.concatenate([lengths for _, _, lengths in parts])
    order = np.argsort(np.concatenate([rows for rows, _, _ in parts]))
    part, starts, ends = part[order], starts[order], ends[order]
    first = np.flatnonzero(np.diff(part, prepend=-1))  # the first line of each run
    last = np.append(first[1:], len(part)) - 1
    texts = [text for _, text, _ in parts]
    return b"".join([texts[i][a:b] for i, a, b in zip(part[first].tolist(), starts[first].tolist(),
                                                       ends[last].tolist())])


def _csv_line(cells: list) -> str:
    """``cells`` as ``csv.writer`` writes them (quoted where needed, ``\\r\\n`` at the end)."""
    text = io.StringIO()
    csv.writer(text).writerow(cells)
    return text.getvalue()


def _csv_cell(value) -> str:
    """``value`` as ``csv.writer`` writes it among other cells: quoted where needed, and nothing for an empty
    text (alone on a line, csv would quote it)."""
    return _csv_line([value, ""])[:-3]


def _iso(time: dt.datetime | None) -> str:
    return "" if time is None else time.astimezone(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


class DecodeSummary(NamedTuple):
    rows: int
    message_counts: dict[str, int]
    skipped_bytes: dict[str, int]
    rejected_frames: dict[str, int]
    bytes_read: int
    packets: int


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
    with atomic_path(out_path) as temporary, open(temporary, "wb") as handle:
        handle.write(rows.header().encode())
        for timed in timed_frames(chunks, deframer):
            text, lines = rows.block(timed)
            handle.write(text)
            count += lines
        if not deframer.stats.packets:
            raise NoFramesError(deframer.stats.bytes_fed)  # inside atomic_path: the temporary goes, not the target
    stats = deframer.stats
    registry.count_undecoded(stats.unbuilt_packets)
    return DecodeSummary(count, dict(registry.counts), dict(stats.skipped_bytes), dict(stats.rejected_frames),
                         stats.bytes_fed, stats.packets)
