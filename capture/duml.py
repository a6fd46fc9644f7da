"""DUML v1 codec: the two CRCs, the :class:`Packet` value type and the incremental :class:`Deframer`.

Frame layout (all multi-byte fields little-endian), from ``shared/research/dji-telemetry.md`` section 1::

    0     0x55 start of frame
    1-2   u16: bits 0-9 whole frame length (header and CRC16 included), bits 10-15 protocol version (1)
    3     CRC8 over bytes 0..2            (reflected poly 0x31, seed 0x77)
    4     sender   (device type | index << 5)
    5     receiver (same encoding)
    6-7   u16 sequence number
    8     cmd_type: bit 7 response, bits 5-6 ack type, bits 0-2 encryption
    9     cmd_set
    10    cmd_id
    11..  payload (length - 13 bytes)
    -2    u16 CRC16 over everything before it (reflected poly 0x1021, seed 0x3692)

Speed. The CRC16 is reflected (LSB first) while :func:`binascii.crc_hqx` computes the same polynomial
non-reflected (MSB first). Reversing the bit order of every input byte (one ``bytes.translate``), running
``crc_hqx`` with the bit-reversed seed and bit-reversing the 16-bit result gives the reflected CRC, all in C.
The deframer translates each fed buffer once and then calls ``crc_hqx`` once per candidate frame on a
zero-copy ``memoryview`` slice. The header CRC8 covers three bytes only; it is evaluated with numpy table
lookups for every ``0x55`` in a buffer at once.
"""

from __future__ import annotations

import binascii
import enum
from dataclasses import dataclass, field
from typing import Iterable, Iterator, NamedTuple

import numpy as np

SOF = 0x55
PROTOCOL_VERSION = 1
HEADER_LENGTH = 11
CRC16_LENGTH = 2
MIN_FRAME_LENGTH = HEADER_LENGTH + CRC16_LENGTH
MAX_FRAME_LENGTH = 0x3FF
MAX_PAYLOAD_LENGTH = MAX_FRAME_LENGTH - MIN_FRAME_LENGTH
CRC8_SEED = 0x77
CRC16_SEED = 0x3692  # P3/P4/Mavic; OGS also lists 0x1012 Naza-M, 0x1013 Phantom 2, 0x7000 Naza-M V2

_CRC8_POLY_REFLECTED = 0x8C
_CRC16_POLY_REFLECTED = 0x8408


def _reverse_bits(value: int, width: int) -> int:
    return int(f"{value:0{width}b}"[::-1], 2)


def _crc8_table() -> np.ndarray:
    table = np.zeros(256, dtype=np.uint8)
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ _CRC8_POLY_REFLECTED if crc & 1 else crc >> 1
        table[byte] = crc
    return table


def _crc16_table() -> np.ndarray:
    crc = np.arange(256, dtype=np.uint16)
    for _ in range(8):
        crc = np.where(crc & 1, (crc >> 1) ^ _CRC16_POLY_REFLECTED, crc >> 1).astype(np.uint16)
    return crc


_CRC8_TABLE = _crc8_table()
_CRC16_TABLE = _crc16_table()
# a frame length shared by at least this many candidates per byte is CRC-checked by columns (fewer: crc_hqx per
# frame is faster; one numpy step per byte costs about what 20-40 crc_hqx calls do)
_COLUMN_CRC_FRAMES_PER_BYTE = 100
_CRC8_TABLE_BYTES = _CRC8_TABLE.tobytes()
_BIT_REVERSED_BYTES = bytes(_reverse_bits(b, 8) for b in range(256))


def _bit_reversed_u16() -> np.ndarray:
    """Every u16 bit-reversed (each byte reversed, the two swapped); numpy, as a Python loop took 40 ms to import."""
    reversed_bytes = np.frombuffer(_BIT_REVERSED_BYTES, np.uint8).astype(np.uint16)
    values = np.arange(1 << 16)
    return reversed_bytes[values & 0xFF] << 8 | reversed_bytes[values >> 8]


_BIT_REVERSED_U16 = _bit_reversed_u16()


def crc8(data: bytes, seed: int = CRC8_SEED) -> int:
    """DUML header CRC8 (reflected poly 0x31, no xorout) of ``data``; used on 3-byte headers."""
    crc = seed
    for byte in data:
        crc = _CRC8_TABLE_BYTES[crc ^ byte]
    return crc


def crc16(data: bytes, seed: int = CRC16_SEED) -> int:
    """DUML packet CRC16 (reflected poly 0x1021, no xorout) of ``data``, computed in C via ``crc_hqx``."""
    return int(_BIT_REVERSED_U16[_crc16_of_bit_reversed(bytes(data).translate(_BIT_REVERSED_BYTES), seed)])


def _crc16_of_bit_reversed(bit_reversed: bytes | memoryview, seed: int) -> int:
    """Non-reflected CRC of bit-reversed input; bit-reverse the result to get the DUML CRC16."""
    return binascii.crc_hqx(bit_reversed, _reverse_bits(seed, 16))


class Packet(NamedTuple):
    """One DUML v1 frame, without its framing (length, version and CRCs are derived on encode).

    ``sender``/``receiver`` are ``device_type | device_index << 5``; ``cmd_type`` is the raw byte 8
    (use :func:`make_cmd_type` to build it and the properties below to read it).
    """

    sender: int
    receiver: int
    seq: int
    cmd_type: int
    cmd_set: int
    cmd_id: int
    payload: bytes = b""

    @property
    def is_response(self) -> bool:
        return bool(self.cmd_type & 0x80)

    @property
    def ack_type(self) -> int:
        """0 no ACK, 1 ACK before exec (push), 2 ACK after exec."""
        return (self.cmd_type >> 5) & 0x03

    @property
    def encryption(self) -> int:
        """0 none, 1 AES-128, 2 self-defined, 3 XOR, 4 DES-56, 5 DES-112, 6 AES-192, 7 AES-256."""
        return self.cmd_type & 0x07

    @property
    def frame_length(self) -> int:
        return MIN_FRAME_LENGTH + len(self.payload)

    def encode(self, crc16_seed: int = CRC16_SEED) -> bytes:
        """The complete frame bytes, both CRCs included. Raises ValueError on out-of-range fields."""
        for name in ("sender", "receiver", "cmd_type", "cmd_set", "cmd_id"):
            if not 0 <= getattr(self, name) <= 0xFF:
                raise ValueError(f"Packet.{name}={getattr(self, name)} is not a byte (0..255)")
        if not 0 <= self.seq <= 0xFFFF:
            raise ValueError(f"Packet.seq={self.seq} is not a u16 (0..65535)")
        if len(self.payload) > MAX_PAYLOAD_LENGTH:
            raise ValueError(f"payload of {len(self.payload)} bytes exceeds the DUML maximum {MAX_PAYLOAD_LENGTH}")
        length = self.frame_length
        start = bytes((SOF, length & 0xFF, (length >> 8) | (PROTOCOL_VERSION << 2)))
        body = start + bytes((crc8(start), self.sender, self.receiver, self.seq & 0xFF, self.seq >> 8,
                              self.cmd_type, self.cmd_set, self.cmd_id)) + bytes(self.payload)
        return body + crc16(body, crc16_seed).to_bytes(2, "little")


def make_cmd_type(is_response: bool = False, ack_type: int = 0, encryption: int = 0) -> int:
    """Byte 8 of a frame from its parts (see :class:`Packet` properties)."""
    if not 0 <= ack_type <= 3 or not 0 <= encryption <= 7:
        raise ValueError(f"ack_type {ack_type} must be 0..3 and encryption {encryption} 0..7")
    return (0x80 if is_response else 0) | ack_type << 5 | encryption


def device_address(device_type: int, index: int = 0) -> int:
    """Sender/receiver byte: device type (0..31, e.g. 3 flight controller, 10 PC) and index (0..7)."""
    if not 0 <= device_type <= 31 or not 0 <= index <= 7:
        raise ValueError(f"device type {device_type} must be 0..31 and index {index} 0..7")
    return device_type | index << 5


class SkipReason(enum.IntEnum):
    """Why the deframer dropped a byte. Each skipped byte is counted under exactly one reason."""

    NO_SYNC = 0  # not inside any rejected frame candidate: searching for 0x55
    BAD_HEADER_CRC = 1  # a 0x55 whose header CRC8 failed (only that byte)
    UNKNOWN_VERSION = 2  # header CRC ok but protocol version != 1 (the 4 header bytes)
    BAD_LENGTH = 3  # header CRC ok but length < 13 (the 4 header bytes)
    BAD_PACKET_CRC = 4  # header ok, CRC16 over the claimed length failed (the claimed span)
    TRUNCATED = 5  # header ok but the frame was cut short by another frame or by the end of the stream


_MAX_SCAN_BYTES = 4 << 20

# what a candidate frame turned out to be (SkipReason values for rejections, plus two states)
_CANDIDATE_OK = 100
_CANDIDATE_PENDING = 101


@dataclass
class DeframerStats:
    """Running totals. Invariant: ``bytes_fed == packet_bytes + sum(skipped_bytes) + pending_bytes``."""

    bytes_fed: int = 0
    packets: int = 0
    unbuilt_packets: int = 0  # intact frames of commands outside ``Deframer(commands=...)``: counted, not built
    packet_bytes: int = 0
    pending_bytes: int = 0
    skipped_bytes: dict[str, int] = field(default_factory=lambda: {r.name.lower(): 0 for r in SkipReason})
    rejected_frames: dict[str, int] = field(default_factory=lambda: {r.name.lower(): 0 for r in SkipReason})

    @property
    def total_skipped(self) -> int:
        return sum(self.skipped_bytes.values())


class FrameBatch(NamedTuple):
    """Accepted frames of one buffer: start index in the buffer and frame length (numpy int64 arrays)."""

    starts: np.ndarray
    lengths: np.ndarray


class FramePiece(NamedTuple):
    """Accepted frames of one scanned buffer; ``buffer[0]`` is at stream offset ``offset``."""

    buffer: bytes
    offset: int
    frames: FrameBatch


class Deframer:
    """Incremental DUML v1 deframer: feed arbitrary chunks, get ``(stream_offset, Packet)`` pairs.

    Scanning follows the OGS packetiser: a frame candidate starts at every ``0x55``; it is accepted when its
    header CRC8, version (1), length (>= 13) and CRC16 all check out, and candidates are taken greedily left
    to right, so a ``0x55`` inside an accepted frame never starts another. A rejected candidate drops only
    its ``0x55`` from the search, so a lying length costs nothing but the bytes it covered. A candidate whose
    claimed length reaches past the data fed so far is held back (at most 1023 bytes) until more arrives or
    :meth:`flush` declares it truncated. Never yields a frame whose CRCs fail.
    """

    def __init__(self, crc16_seed: int = CRC16_SEED, commands: Iterable[tuple[int, int]] | None = None) -> None:
        """``commands``: ``(cmd_set, cmd_id)`` pairs to build Packets for (None: all); intact frames of other
        commands are checked and counted in ``stats.packets`` and ``stats.unbuilt_packets`` only (faster)."""
        self.crc16_seed = crc16_seed
        self._commands = None if commands is None else np.array(sorted(s << 8 | i for s, i in commands))
        self.stats = DeframerStats()
        self._pending = b""
        self._pending_offset = 0  # stream offset of self._pending[0]

    def feed(self, data: bytes) -> list[tuple[int, Packet]]:
        """Append ``data`` to the stream; return the frames completed by it, in stream order."""
        return _offsets_and_packets(self.feed_pieces(data))

    def flush(self) -> list[tuple[int, Packet]]:
        """End of stream: resolve held-back bytes (frames cut short are counted as truncated)."""
        return _offsets_and_packets([self.flush_piece()])

    def feed_pieces(self, data: bytes) -> list[FramePiece]:
        """:meth:`feed` without Packets: the frames completed by ``data`` (of the commands asked for), per
        scanned buffer (at most 4 MiB of new data each). Used by bulk decoders."""
        pieces = []
        for start in range(0, len(data), _MAX_SCAN_BYTES):  # bounds the per-byte scratch arrays
            piece = bytes(data[start:start + _MAX_SCAN_BYTES])
            self.stats.bytes_fed += len(piece)
            pieces.append(self._piece(self._pending + piece, final=False))
        return pieces

    def flush_piece(self) -> FramePiece:
        """:meth:`flush` without Packets."""
        return self._piece(self._pending, final=True)

    def feed_frames(self, data: bytes, final: bool = False) -> tuple[bytes, int, FrameBatch]:
        """Lower-level :meth:`feed`: return ``(buffer, buffer_stream_offset, FrameBatch)`` without Packets, for
        every command and with no bound on the buffer. The frames' bytes are ``buffer[start:start + length]``.
        Used by the benchmark."""
        self.stats.bytes_fed += len(data)
        buffer = self._pending + bytes(data)
        return buffer, self._pending_offset, self._scan_and_consume(buffer, final)

    def _piece(self, buffer: bytes, final: bool) -> FramePiece:
        offset = self._pending_offset
        return FramePiece(buffer, offset, self._wanted(buffer, self._scan_and_consume(buffer, final)))

    def _wanted(self, buffer: bytes, batch: FrameBatch) -> FrameBatch:
        """The frames of ``batch`` whose command was asked for; the others are counted as unbuilt."""
        if self._commands is None or len(batch.starts) == 0:
            return batch
        array = np.frombuffer(buffer, dtype=np.uint8)
        keys = array[batch.starts + 9].astype(np.int64) << 8 | array[batch.starts + 10]
        wanted = np.isin(keys, self._commands)
        self.stats.unbuilt_packets += int(len(wanted) - np.count_nonzero(wanted))
        return FrameBatch(batch.starts[wanted], batch.lengths[wanted])

    def _scan_and_consume(self, buffer: bytes, final: bool) -> FrameBatch:
        scan = _scan(buffer, final, self.crc16_seed)
        for reason, count in zip(SkipReason, scan.skipped_counts):
            self.stats.skipped_bytes[reason.name.lower()] += count
        for reason, count in zip(SkipReason, scan.rejected_counts):
            self.stats.rejected_frames[reason.name.lower()] += count
        self.stats.packets += len(scan.frames.starts)
        self.stats.packet_bytes += int(scan.frames.lengths.sum())
        self._pending = buffer[scan.decided:]
        self._pending_offset += scan.decided
        self.stats.pending_bytes = len(self._pending)
        return scan.frames


def deframe(chunks: Iterable[bytes], deframer: Deframer | None = None) -> Iterator[tuple[int, Packet]]:
    """Yield ``(stream_offset, Packet)`` for every intact frame in ``chunks``, flushing at the end."""
    deframer = deframer or Deframer()
    for chunk in chunks:
        yield from deframer.feed(chunk)
    yield from deframer.flush()


def _offsets_and_packets(pieces: list[FramePiece]) -> list[tuple[int, Packet]]:
    """``(stream_offset, Packet)`` for every frame of ``pieces``."""
    pairs = []
    for buffer, offset, frames in pieces:
        pairs += zip((frames.starts + offset).tolist(), packets_from_frames(buffer, frames))
    return pairs


def packets_from_frames(buffer: bytes, frames: FrameBatch) -> list[Packet]:
    """Build :class:`Packet` objects for accepted frames (header fields gathered with numpy)."""
    if len(frames.starts) == 0:
        return []
    array = np.frombuffer(buffer, dtype=np.uint8)
    starts = frames.starts
    columns = [array[starts + k].tolist() for k in (4, 5)]
    seq = (array[starts + 6].astype(np.int64) | array[starts + 7].astype(np.int64) << 8).tolist()
    cmd_type, cmd_set, cmd_id = (array[starts + k].tolist() for k in (8, 9, 10))
    payload_starts = (starts + HEADER_LENGTH).tolist()
    payload_ends = (starts + frames.lengths - CRC16_LENGTH).tolist()
    make = Packet._make
    return [make((s, r, q, t, cs, ci, buffer[a:b])) for s, r, q, t, cs, ci, a, b in
            zip(columns[0], columns[1], seq, cmd_type, cmd_set, cmd_id, payload_starts, payload_ends)]


class _Scan(NamedTuple):
    frames: FrameBatch
    decided: int  # buffer[:decided] is fully accounted for (frames + skipped bytes)
    skipped_counts: list[int]  # skipped bytes per SkipReason
    rejected_counts: list[int]  # number of rejected candidates per SkipReason


def _scan(buffer: bytes, final: bool, crc16_seed: int) -> _Scan:
    array = np.frombuffer(buffer, dtype=np.uint8)
    size = len(array)
    starts = np.flatnonzero(array == SOF)
    status, lengths = _classify_candidates(buffer, array, starts, final, crc16_seed)
    ok = status == _CANDIDATE_OK
    accepted = _greedy_non_overlapping(starts[ok], starts[ok] + lengths[ok])
    acc_starts, acc_lengths = starts[ok][accepted], lengths[ok][accepted]
    acc_ends = acc_starts + acc_lengths
    decided = _decided_prefix(starts[status == _CANDIDATE_PENDING], acc_starts, acc_ends, size)
    keep = acc_starts < decided
    acc_starts, acc_ends, acc_lengths = acc_starts[keep], acc_ends[keep], acc_lengths[keep]
    in_decided = starts < decided
    rejected = in_decided & ~ok & ~_covered_by(starts, acc_starts, acc_ends)
    # a failed CRC16 whose claimed span holds the start of an accepted frame was cut short by it
    next_start = _next_accepted_start(starts, acc_starts, decided)
    cut = rejected & (status == SkipReason.BAD_PACKET_CRC) & (next_start < starts + lengths)
    status[cut] = SkipReason.TRUNCATED
    rej_starts, rej_status = starts[rejected], status[rejected]
    rej_ends = np.minimum(rej_starts + _claimed_extent(rej_status, lengths[rejected]), next_start[rejected])
    skipped = _skipped_counts(acc_starts, acc_ends, decided, rej_starts, rej_ends, rej_status)
    rejected_counts = np.bincount(rej_status.astype(np.int64), minlength=len(SkipReason))[:len(SkipReason)].tolist()
    return _Scan(FrameBatch(acc_starts, acc_lengths), decided, skipped, rejected_counts)


def _classify_candidates(buffer: bytes, array: np.ndarray, starts: np.ndarray, final: bool, crc16_seed: int):
    """Status (SkipReason or _CANDIDATE_OK/_PENDING) and claimed length of every 0x55 candidate."""
    size = len(array)
    status = np.full(len(starts), _CANDIDATE_PENDING, dtype=np.int64)
    lengths = np.zeros(len(starts), dtype=np.int64)
    has_header = starts + 4 <= size
    h = starts[has_header]
    b1, b2, b3 = array[h + 1], array[h + 2], array[h + 3]
    header_ok = _CRC8_TABLE[_CRC8_TABLE[_CRC8_TABLE[CRC8_SEED ^ SOF] ^ b1] ^ b2] == b3
    length = b1.astype(np.int64) | (b2.astype(np.int64) & 0x03) << 8
    version = b2 >> 2
    h_status = np.where(~header_ok, SkipReason.BAD_HEADER_CRC,
                        np.where(version != PROTOCOL_VERSION, SkipReason.UNKNOWN_VERSION,
                                 np.where(length < MIN_FRAME_LENGTH, SkipReason.BAD_LENGTH, _CANDIDATE_PENDING)))
    complete = (h_status == _CANDIDATE_PENDING) & (h + length <= size)
    h_status[complete] = np.where(_crc16_ok(buffer, array, h[complete], length[complete], crc16_seed),
                                  _CANDIDATE_OK, SkipReason.BAD_PACKET_CRC)
    status[has_header] = h_status
    lengths[has_header] = np.where(header_ok, length, 0)
    if final:
        truncated = status == _CANDIDATE_PENDING
        status[truncated] = SkipReason.TRUNCATED
        lengths[truncated & ~has_header] = size - starts[truncated & ~has_header]
    return status, lengths


def _crc16_ok(buffer: bytes, array: np.ndarray, starts: np.ndarray, lengths: np.ndarray, seed: int) -> np.ndarray:
    """Whether each candidate frame's stored CRC16 matches: frames of a length that many candidates share are
    checked a byte position at a time over all of them (numpy), the others one by one with ``crc_hqx``."""
    computed = np.empty(len(starts), dtype=np.uint16)
    common, counts = np.unique(lengths, return_counts=True)
    for length in common[counts >= _COLUMN_CRC_FRAMES_PER_BYTE * common].tolist():
        group = np.flatnonzero(lengths == length)
        computed[group] = _crc16_by_columns(array, starts[group], length - CRC16_LENGTH, seed)
    rest = np.flatnonzero(~np.isin(lengths, common[counts >= _COLUMN_CRC_FRAMES_PER_BYTE * common]))
    if len(rest):
        reversed_view = memoryview(buffer.translate(_BIT_REVERSED_BYTES))
        seed_reversed = _reverse_bits(seed, 16)
        crc_hqx = binascii.crc_hqx
        computed[rest] = _BIT_REVERSED_U16[np.fromiter(
            (crc_hqx(reversed_view[s:s + n], seed_reversed) for s, n in
             zip(starts[rest].tolist(), (lengths[rest] - CRC16_LENGTH).tolist())), dtype=np.uint16, count=len(rest))]
    ends = starts + lengths - CRC16_LENGTH
    return computed == (array[ends].astype(np.uint16) | array[ends + 1].astype(np.uint16) << 8)


def _crc16_by_columns(array: np.ndarray, starts: np.ndarray, size: int, seed: int) -> np.ndarray:
    """CRC16 of ``array[start:start + size]`` for every start (table-driven, one byte position at a time)."""
    columns = array[starts[None, :] + np.arange(size)[:, None]]
    crc = np.full(len(starts), seed, dtype=np.uint16)
    for column in columns:
        crc = (crc >> 8) ^ _CRC16_TABLE[(crc ^ column) & 0xFF]
    return crc


def _greedy_non_overlapping(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Mask of the intervals a left-to-right greedy scan keeps (starts sorted ascending)."""
    keep = np.ones(len(starts), dtype=bool)
    if len(starts) < 2:
        return keep
    reach = np.maximum.accumulate(ends)
    overlapping = np.flatnonzero(starts[1:] < reach[:-1]) + 1
    if len(overlapping) == 0:
        return keep
    # rare (nested frames, chance CRC matches): walk only the overlapping intervals in Python. Each run of
    # overlapping intervals follows a non-overlapping "head" that is always kept.
    last_end, previous = 0, -2
    for i in overlapping.tolist():
        if i - 1 != previous:
            last_end = ends[i - 1]
        if starts[i] < last_end:
            keep[i] = False
        else:
            last_end = ends[i]
        previous = i
    return keep


def _decided_prefix(pending: np.ndarray, acc_starts: np.ndarray, acc_ends: np.ndarray, size: int) -> int:
    """The first held-back candidate not inside an accepted frame bounds what can be decided now."""
    for start in pending.tolist():
        i = int(np.searchsorted(acc_starts, start, side="right")) - 1
        if i < 0 or acc_ends[i] <= start:
            return start
    return size


def _covered_by(positions: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Mask of positions strictly inside (or at the start of) one of the sorted disjoint intervals."""
    i = np.searchsorted(starts, positions, side="right") - 1
    return (i >= 0) & (positions < ends[np.maximum(i, 0)]) if len(starts) else np.zeros(len(positions), bool)


def _next_accepted_start(positions: np.ndarray, acc_starts: np.ndarray, limit: int) -> np.ndarray:
    """For each position, the start of the first accepted frame after it (or ``limit``)."""
    i = np.searchsorted(acc_starts, positions, side="right")
    padded = np.append(acc_starts, limit)
    return np.minimum(padded[i], limit)


def _claimed_extent(status: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """How many bytes a rejected candidate accounts for (see SkipReason)."""
    return np.select([status == SkipReason.BAD_HEADER_CRC,
                      (status == SkipReason.UNKNOWN_VERSION) | (status == SkipReason.BAD_LENGTH)],
                     [1, 4], default=lengths)


def _skipped_counts(acc_starts, acc_ends, decided, rej_starts, rej_ends, rej_status) -> list[int]:
    """Bytes of ``[0, decided)`` outside accepted frames, counted per SkipReason (index = reason code).

    A skipped byte belongs to the rejected candidate at or before it that reaches furthest, when that
    candidate's extent covers it; otherwise it is NO_SYNC. Between two candidate starts that owner is fixed, so
    each candidate k owns ``[start_k, min(start_k+1, reach_k))`` and the counts are that interval's overlap with
    the gaps between accepted frames: interval arithmetic, not one entry per byte.
    """
    gap_starts = np.concatenate(([0], acc_ends))
    gap_lengths = np.concatenate((acc_starts, [decided])) - gap_starts
    counts = np.zeros(len(SkipReason), dtype=np.int64)
    total = int(gap_lengths.sum())
    if len(rej_starts):
        reach = np.maximum.accumulate(rej_ends)
        holder = np.maximum.accumulate(np.where(rej_ends == reach, np.arange(len(rej_ends)), 0))
        owned_ends = np.minimum(np.append(rej_starts[1:], decided), reach)
        gap_bytes_before = np.concatenate(([0], np.cumsum(gap_lengths)))

        def in_gaps_before(x: np.ndarray) -> np.ndarray:  # skipped bytes in [0, x)
            j = np.searchsorted(gap_starts, x, side="right") - 1
            return gap_bytes_before[j] + np.clip(x - gap_starts[j], 0, gap_lengths[j])

        owned = np.maximum(in_gaps_before(np.maximum(owned_ends, rej_starts)) - in_gaps_before(rej_starts), 0)
        counts += np.bincount(rej_status[holder], weights=owned, minlength=len(SkipReason)).astype(np.int64)
    counts[SkipReason.NO_SYNC] += total - int(counts.sum())
    return counts.tolist()
