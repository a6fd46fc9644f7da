"""The real Phantom 3 UART captures (o-gs/dji-packet-dumps, recorded indoors before a GPS fix)."""

import collections
import datetime as dt
import struct

import dpkt
import pytest

from capture.decode import timed_packets
from capture.duml import Deframer
from capture.messages import DateTimeSet, GimbalParams, HomePoint, OsdGeneral, default_registry
from capture import transports
from capture.transports import Chunk, TransportError, read_pcap, replay_file

RUNS = {"run1": 4651, "run3": 13024}


def _pcap(shared_data, run):
    return shared_data / "dji" / f"dji-packet-dumps__p3x_ofdm_to_center_{run}.pcap"


@pytest.mark.parametrize("run", sorted(RUNS))
def test_real_pcap_decodes_without_a_single_error(shared_data, run):
    records = list(read_pcap(_pcap(shared_data, run)))
    deframer = Deframer()
    timed = list(timed_packets(replay_file(_pcap(shared_data, run)), deframer))
    assert len(timed) == len(records) == RUNS[run]  # one DUML frame per pcap record
    assert deframer.stats.total_skipped == 0 and sum(deframer.stats.rejected_frames.values()) == 0
    assert deframer.stats.packet_bytes == sum(len(r.data) for r in records)
    # every packet is stamped with its own record's time
    assert [t.receive_time_utc for t in timed] == [r.receive_time_utc for r in records]
    assert records[0].receive_time_utc.date() == dt.date(2017, 12, 20)

    registry = default_registry()
    decoded = [registry.decode(t.packet) for t in timed]
    osd = [r for r in decoded if isinstance(r, OsdGeneral)]
    gimbal = [r for r in decoded if isinstance(r, GimbalParams)]
    homes = [r for r in decoded if isinstance(r, HomePoint)]
    assert len(osd) > 200 and len(gimbal) > 1000 and len(homes) > 10
    # recorded indoors without GPS (see the .txt): no fix, so lat/lon are exactly 0.0 and no satellites
    assert all(not r.has_fix and r.gps_satellites == 0 and r.product_type == 2 for r in osd)
    assert all(-180.0 <= r.yaw_deg <= 180.0 and abs(r.pitch_deg) < 10 for r in osd)  # standing on a level floor
    # the home point is the "not set" sentinel (800000.0 rad) on every frame
    assert all(not h.is_set and h.go_home_height_m == 60 for h in homes)
    assert all(-90.0 <= g.pitch_deg <= 47.0 for g in gimbal)


def test_osd_push_rate_is_10_hz(shared_data):
    registry = default_registry()
    times = [t.receive_time_monotonic for t in timed_packets(replay_file(_pcap(shared_data, "run3")), Deframer())
             if isinstance(registry.decode(t.packet), OsdGeneral) and t.packet.receiver == 9]
    span = times[-1] - times[0]
    assert (len(times) - 1) / span == pytest.approx(10.0, rel=0.05)


def test_date_time_set_is_local_time_one_hour_ahead(shared_data):
    registry = default_registry()
    exchange = [(t, registry.decode(t.packet)) for t in timed_packets(replay_file(_pcap(shared_data, "run3")),
                                                                       Deframer())
                if (t.packet.cmd_set, t.packet.cmd_id) == (0x03, 0x1C)]
    assert [t.packet.is_response for t, _ in exchange] == [False, True]
    timed, record = exchange[0]
    assert isinstance(record, DateTimeSet)
    offset = record.as_datetime() - timed.receive_time_utc.replace(tzinfo=None)
    assert abs(offset - dt.timedelta(hours=1)) < dt.timedelta(seconds=10)  # Gdansk, CET = UTC+1


def test_all_message_kinds_are_counted(shared_data):
    registry = default_registry()
    kinds = collections.Counter()
    for timed in timed_packets(replay_file(_pcap(shared_data, "run1")), Deframer()):
        registry.decode(timed.packet)
        kinds[timed.packet.cmd_set, timed.packet.cmd_id] += 1
    assert sum(registry.counts.values()) == RUNS["run1"]
    assert registry.counts["osd_general"] == kinds[0x03, 0x43]
    assert registry.counts["undecoded"] == RUNS["run1"] - sum(kinds[k] for k in [(3, 0x43), (3, 0x44), (4, 5),
                                                                               (2, 0x80), (3, 0x1C)])


def test_pcap_with_wrong_link_type_is_rejected(tmp_path, shared_data):
    data = bytearray(_pcap(shared_data, "run1").read_bytes()[:200])
    data[20] = 1  # Ethernet
    path = tmp_path / "ether.pcap"
    path.write_bytes(bytes(data))
    with pytest.raises(TransportError, match="link type 1, expected 150"):
        list(replay_file(path))


def test_pcap_cut_short_in_its_last_record_keeps_what_is_there(tmp_path, shared_data):
    whole = _pcap(shared_data, "run1").read_bytes()
    records = list(read_pcap(_pcap(shared_data, "run1")))
    first_two = 24 + 2 * 16 + len(records[0].data) + len(records[1].data)
    path = tmp_path / "killed.pcap"
    path.write_bytes(whole[:first_two + 16 + 5])  # the third record's header and 5 of its bytes
    problems = []
    chunks = list(replay_file(path, problems))
    assert [c.data for c in chunks] == [records[0].data, records[1].data, records[2].data[:5]]
    assert problems == [f"{path}: truncated record at byte {first_two}: 5 of {len(records[2].data)} bytes there, kept"]
    path.write_bytes(whole[:first_two + 7])  # cut inside the third record's header
    problems = []
    assert len(list(replay_file(path, problems))) == 2
    assert problems == [f"{path}: truncated record at byte {first_two}: its header is cut short (7 of 16 bytes), "
                        "dropped"]


def test_pcap_with_a_cut_short_file_header_says_so(tmp_path, shared_data):
    path = tmp_path / "short.pcap"
    path.write_bytes(_pcap(shared_data, "run1").read_bytes()[:10])
    with pytest.raises(TransportError, match=r"short.pcap: pcap file header cut short \(10 of 24 bytes\)"):
        list(replay_file(path))


def _decode_damaged(path, data: bytearray, original):
    """Write the damaged capture ``data`` to ``path``; (path, its timed packets, the original's, the problems)."""
    path.write_bytes(bytes(data))
    problems = []
    damaged = list(timed_packets(replay_file(path, problems), Deframer()))
    return path, damaged, list(timed_packets(replay_file(original), Deframer())), problems


def _record_offsets(data: bytes) -> list[int]:
    """Byte offsets of a little-endian pcap's record headers (the real captures are intact)."""
    offsets, position = [], 24
    while position < len(data):
        offsets.append(position)
        position += 16 + int.from_bytes(data[position + 8:position + 12], "little")
    return offsets


@pytest.mark.parametrize("window", [None, 7])  # 7: the search for the next record crosses many windows
def test_pcap_record_with_a_corrupt_length_is_named_and_nothing_after_it_is_lost(tmp_path, shared_data, window,
                                                                                   monkeypatch):
    if window:
        monkeypatch.setattr(transports, "_PCAP_RESYNC_WINDOW", window)
    original = _pcap(shared_data, "run3")
    data = bytearray(original.read_bytes())
    offsets = _record_offsets(bytes(data))
    corrupt = offsets[len(offsets) // 2]
    data[corrupt + 8:corrupt + 12] = (0xDEADBEEF).to_bytes(4, "little")
    path, damaged, intact, problems = _decode_damaged(tmp_path / "corrupt.pcap", data, original)
    assert problems == [f"{path}: corrupt record at byte {corrupt} (captured length 3735928559, fraction "
                        f"{int.from_bytes(data[corrupt + 4:corrupt + 8], 'little')}: impossible with snap length "
                        "65535): "
                        f"{offsets[len(offsets) // 2 + 1] - corrupt - 16} bytes up to the next valid record at byte "
                        f"{offsets[len(offsets) // 2 + 1]} decoded without times"]
    assert [t.packet for t in damaged] == [t.packet for t in intact]  # every frame, the corrupt record's too
    untimed = [i for i, t in enumerate(damaged) if t.receive_time_utc is None]
    assert untimed == [len(offsets) // 2]  # one DUML frame per record: only the corrupt record's lost its time
    assert all(d.receive_time_utc == i.receive_time_utc for d, i in zip(damaged, intact) if d.receive_time_utc)


def test_pcap_record_whose_length_is_wrong_but_possible_is_found_by_what_follows_it(tmp_path, shared_data):
    original = _pcap(shared_data, "run3")
    data = bytearray(original.read_bytes())
    offsets = _record_offsets(bytes(data))
    k = next(i for i in range(len(offsets) // 2, len(offsets)) if offsets[i + 1] - offsets[i] > 40)
    corrupt, length = offsets[k], offsets[k + 1] - offsets[k] - 16
    data[corrupt + 8:corrupt + 16] = struct.pack("<2I", length - 5, length - 5)
    path, damaged, intact, problems = _decode_damaged(tmp_path / "short_length.pcap", data, original)
    assert problems == [f"{path}: corrupt record at byte {corrupt} (captured length {length - 5} ends at byte "
                        f"{offsets[k + 1] - 5}, where no record header starts): {length} bytes up to the next valid "
                        f"record at byte {offsets[k + 1]} decoded without times"]
    assert [t.packet for t in damaged] == [t.packet for t in intact]
    assert [i for i, t in enumerate(damaged) if t.receive_time_utc is None] == [k]


def test_pcap_whose_only_record_is_corrupt_passes_its_bytes_on_untimed(tmp_path, shared_data):
    data = bytearray(_pcap(shared_data, "run1").read_bytes())
    end = _record_offsets(bytes(data))[1]
    data[24 + 8:24 + 12] = (1 << 31).to_bytes(4, "little")
    path = tmp_path / "one.pcap"
    path.write_bytes(bytes(data[:end]))
    problems = []
    chunks = list(replay_file(path, problems))
    assert chunks == [Chunk(None, None, bytes(data[40:end]))]
    assert problems[0].endswith(f"no valid record after it, its last {end - 40} bytes decoded without times")


def _as_pcapng(records, path, linktype=150):
    with open(path, "wb") as handle:
        writer = dpkt.pcapng.Writer(handle, snaplen=65535, linktype=linktype)
        for record in records:
            writer.writepkt(record.data, ts=record.receive_time_utc.timestamp())


def test_pcapng_is_read_with_its_packet_times(tmp_path, shared_data):
    records = list(read_pcap(_pcap(shared_data, "run1")))
    path = tmp_path / "wireshark.pcapng"
    _as_pcapng(records, path)
    chunks = list(replay_file(path))
    assert [c.data for c in chunks] == [r.data for r in records]
    assert max(abs((c.receive_time_utc - r.receive_time_utc).total_seconds()) for c, r in zip(chunks, records)) < 1e-6
    assert chunks[0].receive_time_monotonic == 0.0
    assert chunks[-1].receive_time_monotonic == pytest.approx(records[-1].receive_time_monotonic, abs=1e-6)


def test_pcapng_cut_short_keeps_the_packets_before_the_cut(tmp_path, shared_data):
    records = list(read_pcap(_pcap(shared_data, "run1")))[:3]
    path = tmp_path / "killed.pcapng"
    _as_pcapng(records, path)
    whole = path.read_bytes()
    path.write_bytes(whole[:-10])
    problems = []
    assert [c.data for c in replay_file(path, problems)] == [r.data for r in records[:2]]
    last_block = len(whole) - (32 + (len(records[2].data) + 3) // 4 * 4)
    left = len(whole) - 10 - last_block
    assert problems == [f"{path}: unreadable block at byte {last_block} (cut short): the {left} bytes from there on "
                        "are not read"]


def test_pcapng_with_another_link_type_or_garbage_is_refused(tmp_path, shared_data):
    ethernet = tmp_path / "ether.pcapng"
    _as_pcapng(list(read_pcap(_pcap(shared_data, "run1")))[:2], ethernet, linktype=1)
    with pytest.raises(TransportError, match="pcapng link type 1, expected 150"):
        replay_file(ethernet)
    garbage = tmp_path / "garbage.pcapng"
    garbage.write_bytes(b"\x0a\x0d\x0d\x0a" + bytes(range(60)))
    with pytest.raises(TransportError, match="garbage.pcapng: not a readable pcapng file"):
        replay_file(garbage)
