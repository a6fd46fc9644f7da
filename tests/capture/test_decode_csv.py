"""The fast decode path: frames of undecoded commands are counted but never built, and the CSV lines made with
one ``%`` formatting each are what the csv module writes and reads back."""

import csv
import dataclasses
import datetime as dt
import io

import numpy as np
from duml_vectors import VECTORS, frame

from capture.decode import TelemetryRows, TimedPacket, csv_columns, decode_to_csv
from capture.duml import Deframer, Packet
from capture.messages import MessageRegistry, MessageSpec, default_registry
from capture.transports import Chunk
from tools.bench_duml import corrupt, synthetic_block

T0 = dt.datetime(2024, 5, 1, 12, 0, 0, 123456, tzinfo=dt.timezone.utc)


def _stream(size: int = 200_000) -> bytes:
    rng = np.random.default_rng(3)
    return corrupt(synthetic_block(rng, size), 0.01, rng)


def test_deframer_asked_for_some_commands_builds_exactly_those_and_counts_the_rest():
    stream = _stream()
    everything, some = Deframer(), Deframer(commands=[(0x03, 0x43), (0x04, 0x05)])
    all_packets = everything.feed(stream) + everything.flush()
    wanted = some.feed(stream) + some.flush()
    assert wanted == [(o, p) for o, p in all_packets if (p.cmd_set, p.cmd_id) in {(0x03, 0x43), (0x04, 0x05)}]
    assert some.stats.packets == everything.stats.packets
    assert some.stats.unbuilt_packets == len(all_packets) - len(wanted) > 0
    assert some.stats.skipped_bytes == everything.stats.skipped_bytes


def _reference_csv(chunks, registry) -> str:
    """The telemetry CSV as csv.DictWriter writes it, one packet at a time with no shortcut."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=csv_columns(registry), restval="")
    writer.writeheader()
    deframer = Deframer()
    for chunk in chunks:
        for offset, packet in deframer.feed(chunk.data):
            record = registry.decode(packet)
            if not dataclasses.is_dataclass(record):
                continue
            row = {"utc_time": chunk.receive_time_utc.strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
                   "monotonic_s": f"{chunk.receive_time_monotonic:.6f}", "offset": offset,
                   "kind": registry.spec_for(record).kind, "seq": packet.seq, "sender": packet.sender,
                   "receiver": packet.receiver}
            for name in csv_columns(registry)[7:]:
                if hasattr(record, name):
                    value = getattr(record, name)
                    row[name] = int(value) if isinstance(value, bool) else value
            writer.writerow(row)
    return text.getvalue()


def test_decoded_csv_is_byte_identical_to_the_csv_module(tmp_path):
    stream = b"".join(frame(name) for name in sorted(VECTORS)) + _stream(100_000)
    # every chunk ends on a frame boundary here, so a packet's time is its own chunk's
    frames = Deframer().feed(stream)
    bounds = [0] + [offset + packet.frame_length for offset, packet in frames]
    chunks = [Chunk(T0 + dt.timedelta(seconds=i / 7), 100.0 + i / 7, stream[a:b])
              for i, (a, b) in enumerate(zip(bounds, bounds[1:]))]
    out = tmp_path / "t.csv"
    summary = decode_to_csv(chunks, out, default_registry())
    assert summary.rows > 100
    assert out.read_bytes().decode() == _reference_csv(chunks, default_registry())


@dataclasses.dataclass(frozen=True)
class Note:
    text: str
    level: int

    @property
    def loud(self) -> bool:
        return self.level > 2


def test_text_values_are_quoted_the_csv_way_and_bools_written_as_0_or_1():
    spec = MessageSpec(0x20, 0x01, "note, with {braces} and 100 %", Note, 0, 100, lambda b: Note(b.decode(), 3),
                       lambda r: r.text.encode(), 1, 2)
    rows = TelemetryRows(MessageRegistry([spec]))
    timed = TimedPacket(5, T0, 1.5, Packet(1, 2, 7, 0, 0x20, 0x01, b""))
    line = rows.line(timed, Note('a "quoted", text\nline', 3))
    parsed = next(csv.DictReader(io.StringIO(rows.header() + line)))
    assert parsed == {"utc_time": "2024-05-01T12:00:00.123456Z", "monotonic_s": "1.500000", "offset": "5",
                      "kind": "note, with {braces} and 100 %", "seq": "7", "sender": "1", "receiver": "2",
                      "text": 'a "quoted", text\nline', "level": "3", "loud": "1"}
