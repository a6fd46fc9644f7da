"""DUML v1 CRCs, Packet encoding and the deframer against the published vectors and hand-built streams."""

import pytest
from duml_vectors import VECTOR_11_HEADER_AND_PAYLOAD_PREFIX, VECTORS, frame

from capture.duml import (CRC8_SEED, Deframer, Packet, crc8, crc16, deframe, device_address, make_cmd_type)


def _bitwise_crc(data: bytes, seed: int, poly: int) -> int:
    """The textbook bit-at-a-time reflected CRC (no table, no tricks) as an independent reference."""
    crc = seed
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ poly if crc & 1 else crc >> 1
    return crc


def test_crc_check_values():
    assert crc8(b"123456789") == 0xFB
    assert crc16(b"123456789") == 0x7109


@pytest.mark.parametrize("data", [b"", b"\x00", b"\xff" * 7, bytes(range(256)) * 3])
def test_fast_crc16_equals_bitwise_reference(data):
    assert crc16(data) == _bitwise_crc(data, 0x3692, 0x8408)
    assert crc16(data, seed=0x1013) == _bitwise_crc(data, 0x1013, 0x8408)
    assert crc8(data) == _bitwise_crc(data, CRC8_SEED, 0x8C)


@pytest.mark.parametrize("length, expected", [(0x0D, 0x33), (0x0E, 0x66), (0x14, 0x6D), (0x19, 0xE4), (0x3F, 0x8F),
                                              (0x44, 0x1A), (0x51, 0x09)])
def test_header_crc8_table_from_notes(length, expected):
    assert crc8(bytes((0x55, length, 0x04))) == expected


@pytest.mark.parametrize("name", sorted(VECTORS))
def test_vector_crcs_and_reencoding(name):
    data = frame(name)
    assert crc8(data[:3]) == data[3]
    assert crc16(data[:-2]) == int.from_bytes(data[-2:], "little")
    [(offset, packet)] = list(deframe([data]))
    assert offset == 0
    assert packet.encode() == data


def test_vector_11_header_crc_and_fields():
    prefix = bytes.fromhex(VECTOR_11_HEADER_AND_PAYLOAD_PREFIX)
    assert len(prefix) == 11 + 32 and crc8(prefix[:3]) == prefix[3] == 0x09
    assert prefix[1] | (prefix[2] & 3) << 8 == 81  # 81-byte frame, 68-byte payload


def test_vector_header_fields():
    [(_, first)] = list(deframe([frame("1_rc_channel_params_get")]))
    assert first == Packet(sender=10, receiver=6, seq=0x34EB, cmd_type=0x40, cmd_set=0x06, cmd_id=0x01, payload=b"")
    assert first.ack_type == 2 and not first.is_response and first.encryption == 0
    [(_, response)] = list(deframe([frame("4_fc_response")]))
    assert response.is_response and response.sender == 3 and response.receiver == 10 and response.payload == b"\x00"
    [(_, indexed)] = list(deframe([frame("6_pc_idx1_to_dm3xx")]))
    assert indexed.sender == device_address(10, 1) and indexed.receiver == device_address(8, 1)


def test_built_vector_2_matches_encoder():
    packet = Packet(device_address(10), device_address(6), 0x34EB, make_cmd_type(ack_type=2), 0x06, 0x24, b"\x01")
    assert packet.encode() == frame("2_rc_simulate_flight_mode_set")


@pytest.mark.parametrize("field, value", [("sender", 256), ("seq", -1), ("cmd_id", 300)])
def test_encode_rejects_out_of_range_fields(field, value):
    packet = Packet(1, 2, 3, 0, 4, 5, b"")._replace(**{field: value})
    with pytest.raises(ValueError, match=field):
        packet.encode()


def test_encode_rejects_oversized_payload():
    with pytest.raises(ValueError, match="payload"):
        Packet(1, 2, 3, 0, 4, 5, bytes(1011)).encode()


def _all_vectors() -> bytes:
    return b"".join(frame(name) for name in sorted(VECTORS))


def test_split_at_every_byte_position():
    stream = _all_vectors()
    expected = list(deframe([stream]))
    for cut in range(len(stream) + 1):
        assert list(deframe([stream[:cut], stream[cut:]])) == expected
    assert list(deframe(bytes([b]) for b in stream)) == expected


def test_sof_inside_payload_does_not_start_a_frame():
    payload = bytes.fromhex("55 0d 04 33 0a 06 eb 34 40 06 01 74 24")  # a whole valid frame as payload
    outer = Packet(3, 10, 7, 0, 0x03, 0x8F, payload)
    deframer = Deframer()
    assert [p for _, p in deframer.feed(outer.encode())] == [outer]
    assert deframer.stats.total_skipped == 0


def test_skip_counters_by_reason():
    garbage = bytes(range(0x10, 0x30))  # no 0x55
    good = Packet(3, 2, 1, 0, 3, 0x43, bytes(50)).encode()
    corrupt = bytearray(Packet(4, 3, 2, 0, 4, 5, bytes(12)).encode())
    corrupt[15] ^= 0x04
    bad_version = bytes((0x55, 0x0D, 0x08)) + bytes((crc8(bytes((0x55, 0x0D, 0x08))),))
    bad_length = bytes((0x55, 0x05, 0x04)) + bytes((crc8(bytes((0x55, 0x05, 0x04))),))
    bad_header = b"\x55\x0d\x04\x34"
    tail = Packet(3, 2, 9, 0, 3, 0x43, bytes(50)).encode()[:30]
    stream = garbage + good + bytes(corrupt) + good + bad_version + bad_length + bad_header + good + tail
    deframer = Deframer()
    packets = deframer.feed(stream) + deframer.flush()
    assert [offset for offset, _ in packets] == [32, 32 + 63 + 25, 32 + 63 + 25 + 63 + 12]
    skipped = deframer.stats.skipped_bytes
    assert skipped == {"no_sync": 32 + 3, "bad_header_crc": 1, "unknown_version": 4, "bad_length": 4,
                       "bad_packet_crc": 25, "truncated": 30}
    assert deframer.stats.packet_bytes + deframer.stats.total_skipped == len(stream) == deframer.stats.bytes_fed


def test_lying_length_is_held_back_then_released():
    lying = bytes((0x55, 0xE8, 0x07))  # claims 1000 bytes
    lying += bytes((crc8(lying),))
    packets = [Packet(3, 2, seq, 0, 3, 0x43, bytes(50)) for seq in range(5)]
    deframer = Deframer()
    assert deframer.feed(lying + b"".join(p.encode() for p in packets)) == []  # 319 bytes < 1000: wait
    assert deframer.stats.pending_bytes == 4 + 5 * 63
    released = deframer.flush()
    assert [p for _, p in released] == packets
    assert deframer.stats.skipped_bytes["truncated"] == 4  # cut short by the real frames it claimed
    assert deframer.stats.pending_bytes == 0


def test_lying_length_resolved_once_enough_data_arrives():
    lying = bytes((0x55, 0x40, 0x04))  # claims 64 bytes
    lying += bytes((crc8(lying),))
    frames = [Packet(3, 2, seq, 0, 3, 0x43, bytes(50)).encode() for seq in range(3)]
    deframer = Deframer()
    yielded = deframer.feed(lying + frames[0][:30]) + deframer.feed(frames[0][30:] + frames[1] + frames[2])
    assert [offset for offset, _ in yielded] == [4, 67, 130]


def test_nested_and_chained_overlaps_follow_the_left_to_right_scan():
    inner = Packet(10, 6, 1, 0x40, 6, 1, b"").encode()
    middle = Packet(3, 10, 2, 0, 3, 0x8F, b"\x00" + inner)  # a frame carrying a frame
    outer = Packet(3, 10, 3, 0, 3, 0x8F, middle.encode()[:5])  # carries the head of another frame
    tail = Packet(4, 3, 4, 0, 4, 5, bytes(12))
    stream = middle.encode() + outer.encode() + middle.encode()[5:] + tail.encode()
    deframer = Deframer()
    found = [p for _, p in deframer.feed(stream) + deframer.flush()]
    # middle is accepted (its inner frame is payload); outer is accepted; the rest of the split middle frame
    # holds the inner frame intact, which is then found on its own; the tail follows
    assert found == [middle, outer, Packet(10, 6, 1, 0x40, 6, 1, b""), tail]
    assert deframer.stats.packet_bytes + deframer.stats.total_skipped == len(stream)


def test_one_large_feed_is_scanned_in_pieces_without_losing_frames():
    from capture.duml import _MAX_SCAN_BYTES

    unit = _all_vectors() + b"\x01\x02\x03"
    repeats = 2 * _MAX_SCAN_BYTES // len(unit) + 3
    deframer = Deframer()
    packets = deframer.feed(unit * repeats) + deframer.flush()
    assert len(packets) == repeats * len(VECTORS)
    assert deframer.stats.skipped_bytes["no_sync"] == 3 * repeats
