"""The fast decode path: frames of undecoded commands are counted but never built, each message's frames are
decoded and written together, and the CSV is byte for byte what csv.DictWriter writes one packet at a time (and
what ``decode`` wrote before it worked by message), with every frame counted."""

import bisect
import csv
import dataclasses
import datetime as dt
import hashlib
import io

import numpy as np
import pytest
from duml_vectors import VECTORS, frame

from capture.decode import TelemetryRows, TimedPacket, _record_columns, _with_properties, csv_columns, decode_to_csv
from capture.duml import Deframer, Packet
from capture.messages import MessageRegistry, MessageSpec, default_registry, default_specs
from capture.transports import Chunk
from tools.bench.bench_duml import corrupt, gimbal_dense_block, synthetic_block

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


def _reference(chunks, registry) -> tuple[str, dict]:
    """The telemetry CSV as csv.DictWriter writes it, one packet at a time with no shortcut (each packet stamped
    with the chunk holding its last byte), and the registry's counts of every packet."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=csv_columns(registry), restval="")
    writer.writeheader()
    stream = b"".join(chunk.data for chunk in chunks)
    chunk_starts = np.cumsum([0] + [len(chunk.data) for chunk in chunks]).tolist()
    deframer = Deframer()
    for offset, packet in deframer.feed(stream) + deframer.flush():
        record = registry.decode(packet)
        if not dataclasses.is_dataclass(record):
            continue
        chunk = chunks[bisect.bisect_right(chunk_starts, offset + packet.frame_length - 1) - 1]
        utc, mono = chunk.receive_time_utc, chunk.receive_time_monotonic
        row = {"utc_time": "" if utc is None else utc.strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
               "monotonic_s": "" if mono is None else f"{mono:.6f}", "offset": offset,
               "kind": registry.spec_for(record).kind, "seq": packet.seq, "sender": packet.sender,
               "receiver": packet.receiver}
        for name in csv_columns(registry)[7:]:
            if hasattr(record, name):
                value = getattr(record, name)
                row[name] = int(value) if isinstance(value, bool) else value
        writer.writerow(row)
    return text.getvalue(), registry.counts


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
    assert out.read_bytes().decode() == _reference(chunks, default_registry())[0]


@dataclasses.dataclass(frozen=True)
class Note:
    text: str
    level: int

    @property
    def loud(self) -> bool:
        return self.level > 2


NOTE_SPEC = MessageSpec(0x20, 0x01, "note, with {braces} and 100 %", Note, 0, 100,
                        lambda b: Note(b.decode("latin-1"), len(b) % 5), lambda r: r.text.encode("latin-1"), 1, 2)

# registered commands with payloads of a length their layout does not have: counted as malformed, no row
MALFORMED = [Packet(4, 3, 1, 0, 0x04, 0x05, bytes(5)), Packet(3, 2, 2, 0, 0x03, 0x43, bytes(60)),
             Packet(2, 3, 3, 0, 0x03, 0x1C, bytes(8)), Packet(3, 2, 4, 0, 0x03, 0x44, bytes(3))]
NOTES = [Packet(1, 2, i, 0, 0x20, 0x01, b'a "quoted", text\nline\x00' * (i % 3)) for i in range(200)]


def _with_frames(stream: bytes, packets: list[Packet], rng: np.random.Generator) -> bytes:
    """``stream`` with the frames of ``packets`` inserted at random places (cutting whatever they land in)."""
    cuts = np.sort(rng.integers(0, len(stream), len(packets))).tolist()
    pieces = [stream[a:b] for a, b in zip([0] + cuts, cuts + [len(stream)])]
    return b"".join(piece + packet.encode() for piece, packet in zip(pieces, packets + [Packet(0, 0, 0, 0, 0, 0)]))


def _capture_chunks(stream: bytes) -> list[Chunk]:
    """4 KiB chunks 10 ms apart as ``record`` writes them, the first three without receive times (a capture
    whose index misses its start)."""
    return [Chunk(*((None, None) if i < 3 else (T0 + dt.timedelta(seconds=i / 100), 100.0 + i / 100)),
                  stream[start:start + 4096]) for i, start in enumerate(range(0, len(stream), 4096))]


def _chunks_of(mix: str) -> list[Chunk]:
    rng = np.random.default_rng(11)
    stream = corrupt((gimbal_dense_block if mix == "gimbal-dense" else synthetic_block)(rng, 300_000), 0.01, rng)
    return _capture_chunks(_with_frames(stream, MALFORMED * 20 + NOTES, rng) if "notes" in mix else stream)


def _registry_of(mix: str) -> MessageRegistry:
    return MessageRegistry(default_specs() + [NOTE_SPEC]) if "notes" in mix else default_registry()


@pytest.mark.parametrize("mix", ["sparse", "gimbal-dense", "sparse, malformed frames, notes decoded one by one"])
def test_csv_and_counts_are_those_of_the_per_packet_path(tmp_path, mix):
    chunks = _chunks_of(mix)
    summary = decode_to_csv(chunks, tmp_path / "t.csv", _registry_of(mix))
    expected_csv, expected_counts = _reference(chunks, _registry_of(mix))
    written = (tmp_path / "t.csv").read_bytes()
    assert written == expected_csv.encode()
    assert summary.rows == written.count(b"\r\n") - 1 > 1000
    # every frame counted (decoded, malformed or undecoded), in the order decode prints them: kinds, malformed ones
    # as first met, then undecoded (0 when none)
    expected = {key: count for key, count in expected_counts.items() if key != "undecoded"}
    assert list(summary.message_counts.items()) == [*expected.items(), ("undecoded", expected_counts.get("undecoded", 0))]
    if "malformed" in mix:
        assert all(summary.message_counts[f"malformed_{kind}"] >= 20
                   for kind in ("gimbal_params", "osd_general", "date_time_set", "home_point"))


# sha256 of the gimbal-dense mix above and of the CSV that the per-packet decode_to_csv (before each message's
# frames were decoded together, commit d0d6b80) wrote for it
GIMBAL_DENSE_STREAM = "fe91f8d5f8e5cbda8367eba5514649d49c7063a4cf6afd527822eb87470ca681"
GIMBAL_DENSE_CSV = "b844333c5ffc1879be9c4a234c6b78ae6119b8adf702b57b922707b9930d4259"


def test_gimbal_dense_csv_is_what_the_per_packet_code_wrote(tmp_path):
    chunks = _chunks_of("gimbal-dense")
    assert hashlib.sha256(b"".join(c.data for c in chunks)).hexdigest() == GIMBAL_DENSE_STREAM, \
        "the synthetic stream changed: its golden CSV must be made again by the per-packet reference"
    decode_to_csv(chunks, tmp_path / "t.csv", default_registry())
    assert hashlib.sha256((tmp_path / "t.csv").read_bytes()).hexdigest() == GIMBAL_DENSE_CSV


@pytest.mark.filterwarnings("error")  # NaN and inf pass silently, as in the records
@pytest.mark.parametrize("spec", default_specs(), ids=lambda spec: spec.kind)
def test_column_layouts_decode_as_the_records_do(spec):
    """Every field and property, for random payloads of every allowed length (NaN and inf doubles included)."""
    rng = np.random.default_rng(spec.cmd_id)
    lengths = rng.integers(spec.min_payload, min(spec.max_payload, spec.min_payload + 40) + 1, 3000)
    payloads = [rng.integers(0, 256, length, dtype=np.uint8).tobytes() for length in lengths]
    size = spec.columns.dtype.itemsize
    columns = spec.columns.decode(np.frombuffer(b"".join(p[:size] for p in payloads), np.uint8).reshape(-1, size))
    values = _with_properties(spec.record_type, columns, len(payloads))
    for name in _record_columns(spec.record_type):
        expected = [getattr(spec.decode(payload), name) for payload in payloads]
        assert list(map(repr, values[name].tolist())) == list(map(repr, expected)), name


def test_text_values_are_quoted_the_csv_way_and_bools_written_as_0_or_1():
    rows = TelemetryRows(MessageRegistry([NOTE_SPEC]))
    timed = TimedPacket(5, T0, 1.5, Packet(1, 2, 7, 0, 0x20, 0x01, b""))
    line = rows.line(timed, Note('a "quoted", text\nline', 3))
    parsed = next(csv.DictReader(io.StringIO(rows.header() + line)))
    assert parsed == {"utc_time": "2024-05-01T12:00:00.123456Z", "monotonic_s": "1.500000", "offset": "5",
                      "kind": "note, with {braces} and 100 %", "seq": "7", "sender": "1", "receiver": "2",
                      "text": 'a "quoted", text\nline', "level": "3", "loud": "1"}
