"""Benchmark: DUML deframing (with both CRCs), telemetry decoding and the whole ``decode`` CLI on synthetic dumps.

Message mixes (``--mixes``, the first two by default), each a 1 MB block of traffic repeated up to the requested
size with 1 % of all bytes then corrupted:

- ``sparse``, per simulated second like a P3X FC/OFDM link: OSD General 10 Hz, Gimbal Params 50 Hz, Home Point
  1 Hz, plus ~100 Hz of other chatter (random cmd ids, 1-60 byte payloads): 40 % of the intact frames decoded;
- ``gimbal-dense``: Gimbal Params every 1 ms and OSD General every 50 ms, nothing else: every intact frame is a
  telemetry row (the mix that cost the most per byte when ``decode`` made its rows one packet at a time);
- ``date-time-dense`` (on request): Date and Time Set frames only, the most rows per byte any decoded message
  gives.

For the CLI rows the dump is written as a raw capture (``.duml`` + ``.idx``, 4 KiB chunks 10 ms apart, as
``record`` writes them) and decoded to CSV by ``aerostereo-ingest decode``: in-process (``capture.cli.main``) and
as a command (Python start and imports included), each both ways: as shipped (each message's frames decoded and
written together, numpy) and one packet at a time (the baseline: every spec's ``ColumnLayout`` removed, so each
record is decoded and formatted alone, as ``decode`` did before; the same CSV, checked). Time is wall-clock; CPU
is the process's CPU time (the two differ when the machine is shared).

    PYTHONPATH=. .venv/bin/python tools/bench/bench_duml.py              # 100 MB
    PYTHONPATH=. .venv/bin/python tools/bench/bench_duml.py --size-mb 19  # issue 18's 19 MB, as in docs/ingest-duml.md
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import io
import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from capture import cli, duml
from capture.duml import Deframer, Packet, crc16
from capture.messages import (DateTimeSet, GimbalParams, HomePoint, MessageRegistry, OsdGeneral, default_registry,
                              default_specs, encode_message)
from capture.raw import atomic_capture

USB_FULL_SPEED_BPS = 12e6 / 8  # bytes/s, USB 2.0 full speed signalling rate (an upper bound)
UART_115200_BPS = 115200 / 10  # bytes/s, 8N1


def synthetic_block(rng: np.random.Generator, size: int) -> bytes:
    """About ``size`` bytes of intact realistic traffic."""
    parts, seq, second = [], 0, 0
    while sum(map(len, parts)) < size:
        for tick in range(100):  # 10 ms ticks
            t = second + tick / 100
            if tick % 10 == 0:
                parts.append(encode_message(_osd(t), seq=seq).encode())
            if tick % 2 == 0:
                parts.append(encode_message(GimbalParams(-30.0 + 0.1 * (tick % 50), 0.0, 12.3, 0x80, 0.0, 0.0, 0, 1),
                                            seq=seq).encode())
            if tick == 0:
                parts.append(encode_message(HomePoint(18.56, 54.37, 12.5, 1, 60, 0, 0, 25, 0, 208, bytes(36)),
                                            seq=seq).encode())
            payload = rng.integers(0, 256, int(rng.integers(1, 61)), dtype=np.uint8).tobytes()
            parts.append(Packet(3, 9, seq & 0xFFFF, 0, 3, int(rng.integers(0x45, 0xFF)), payload).encode())
            seq += 1
        second += 1
    return b"".join(parts)


def gimbal_dense_block(rng: np.random.Generator, size: int) -> bytes:
    """About ``size`` bytes of intact traffic: Gimbal Params every 1 ms, OSD General every 50 ms (``rng`` unused:
    the same signature as :func:`synthetic_block`)."""
    parts, seq = [], 0
    while sum(map(len, parts)) < size:
        for tick in range(1000):
            parts.append(encode_message(GimbalParams(-30.0 + 0.1 * (tick % 50), 0.0, 12.3, 0x80, 0.0, 0.0, 0, 1),
                                        seq=seq).encode())
            if tick % 50 == 0:
                parts.append(encode_message(_osd(seq / 1000), seq=seq).encode())
            seq += 1
    return b"".join(parts)


def date_time_dense_block(rng: np.random.Generator, size: int) -> bytes:
    """About ``size`` bytes of Date and Time Set frames only: 20 bytes each, the most telemetry rows per byte of any
    decoded message (``rng`` unused)."""
    parts, total = [], 0
    while total < size:
        seq = len(parts)
        parts.append(encode_message(DateTimeSet(2024, 1 + seq % 12, 1 + seq % 28, seq % 24, seq % 60, seq % 60),
                                    seq=seq).encode())
        total += len(parts[-1])
    return b"".join(parts)


MIXES = {"sparse": synthetic_block, "gimbal-dense": gimbal_dense_block, "date-time-dense": date_time_dense_block}
DEFAULT_MIXES = ["sparse", "gimbal-dense"]


def per_packet_registry() -> MessageRegistry:
    """The default messages without their column layouts: ``decode`` makes every row one packet at a time."""
    return MessageRegistry([spec._replace(columns=None) for spec in default_specs()])


# `aerostereo-ingest ARGS` as a command with the per-packet registry (the baseline)
_PER_PACKET_COMMAND = ("import sys; from capture import cli; from tools.bench.bench_duml import per_packet_registry; "
                       "cli.default_registry = per_packet_registry; sys.exit(cli.main(sys.argv[1:]))")


def _osd(t: float) -> OsdGeneral:
    angle = 2 * math.pi * t / 120
    return OsdGeneral(18.56 + 0.0005 * math.cos(angle), 54.37 + 0.0003 * math.sin(angle), 30.0, 0.5, 0.3, 0.0,
                      -2.0, 1.0, round(math.degrees(angle) % 360 - 180, 1), 6, 0, 0x00845011, 12, 0, 0, 0, 80, 0.0,
                      round(t, 1), 1, 0, 0, 9, 2, 0)


def corrupt(data: bytes, fraction: float, rng: np.random.Generator) -> bytes:
    array = np.frombuffer(data, dtype=np.uint8).copy()
    positions = rng.choice(len(array), int(fraction * len(array)), replace=False)
    array[positions] ^= rng.integers(1, 256, len(positions), dtype=np.uint8)
    return array.tobytes()


class _Timed:
    """Wraps a module function and accumulates the time spent in it."""

    def __init__(self, function):
        self.function, self.seconds = function, 0.0

    def __call__(self, *args):
        start = time.perf_counter()
        try:
            return self.function(*args)
        finally:
            self.seconds += time.perf_counter() - start


def bench(size_mb: int, chunk_mb: float, seed: int, mixes: list[str]) -> None:
    rng = np.random.default_rng(seed)
    summary = []
    for mix in mixes:
        block = MIXES[mix](rng, 1 << 20)
        stream = corrupt((block * (size_mb * (1 << 20) // len(block) + 1))[:size_mb << 20], 0.01, rng)
        print(f"## mix `{mix}`\n")
        summary.append((mix, len(stream), *_decode_runs(stream)))
        _stage_table(stream, chunk_mb)
    _crc_table(stream[:1 << 20])
    print(f"\n## `decode` by mix: as shipped against one packet at a time (the baseline), {size_mb} MiB each\n")
    print("| mix | telemetry rows | way | in-process (s) | MB/s | as a command (s) | MB/s | its CPU (s) "
          "| command vs baseline |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for mix, size, rows, runs in summary:
        baseline = runs["one packet at a time"][1][1]
        for way, (in_process, command) in runs.items():
            print(f"| {mix} | {rows:,} | {way} | {in_process[1]:.2f} | {size / in_process[1] / 1e6:.1f} | "
                  f"{command[1]:.2f} | {size / command[1] / 1e6:.1f} | {command[0]:.2f} | {baseline / command[1]:.1f}x |")


def _decode_runs(stream: bytes) -> tuple[int, dict]:
    """Telemetry rows, and per way (as shipped, one packet at a time) the ``(CPU, wall)`` seconds of the whole
    ``decode`` in-process and as a command; both ways must write the same CSV."""
    with tempfile.TemporaryDirectory() as folder:
        capture = Path(folder) / "dump.duml"
        with atomic_capture(capture) as writer:
            for i in range(0, len(stream), 4096):
                writer.append(dt.datetime(2024, 1, 1, tzinfo=dt.timezone.utc) + dt.timedelta(seconds=i / 409600),
                              1000.0 + i / 409600, stream[i:i + 4096])
        runs, outputs = {}, []
        for way, registry, command in (("as shipped", default_registry, ["-m", "capture"]),
                                       ("one packet at a time", per_packet_registry, ["-c", _PER_PACKET_COMMAND])):
            arguments = ["decode", str(capture), "--out", f"{folder}/{len(outputs)}.csv"]
            cli.default_registry = registry
            try:
                in_process = _cpu_and_wall(lambda: cli.main(arguments))
            finally:
                cli.default_registry = default_registry
            outputs.append(Path(arguments[-1]).read_bytes())
            runs[way] = (in_process, _cpu_and_wall(lambda: subprocess.run(
                [sys.executable, *command, *arguments], check=True, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL), children=True))
        if outputs[0] != outputs[1]:
            raise AssertionError("the two ways wrote different CSVs")
        return outputs[0].count(b"\n") - 1, runs


def _stage_table(stream: bytes, chunk_mb: float) -> None:
    """Deframing, Packet building and record decoding of ``stream`` fed in ``chunk_mb`` chunks."""
    chunk = int(chunk_mb * (1 << 20))
    chunks = [stream[i:i + chunk] for i in range(0, len(stream), chunk)]
    crc_timer = _Timed(duml._crc16_ok)
    duml._crc16_ok = crc_timer
    deframer = Deframer()
    start, cpu_start = time.perf_counter(), time.process_time()
    frames = 0
    for data in chunks:
        frames += len(deframer.feed_frames(data)[2].starts)
    frames += len(deframer.feed_frames(b"", final=True)[2].starts)
    deframe_s, deframe_cpu_s = time.perf_counter() - start, time.process_time() - cpu_start
    duml._crc16_ok = crc_timer.function
    stats = deframer.stats
    assert stats.packet_bytes + stats.total_skipped == len(stream)

    deframer = Deframer()
    start = time.perf_counter()
    for data in chunks:
        deframer.feed(data)
    deframer.flush()
    packets_s = time.perf_counter() - start

    deframer, registry = Deframer(), default_registry()
    start = time.perf_counter()
    for data in chunks:
        for _, packet in deframer.feed(data):
            registry.decode(packet)
    for _, packet in deframer.flush():
        registry.decode(packet)
    decode_s = time.perf_counter() - start - packets_s

    print(f"synthetic dump: {len(stream) / 1e6:.1f} MB ({len(stream)} bytes), 1 % corrupted bytes, fed in "
          f"{chunk_mb} MB chunks; {frames} intact frames; skipped bytes {stats.skipped_bytes}")
    print()
    print("| stage | time (s) | CPU (s) | MB/s | MB/s of CPU | packets/s | vs USB 2.0 FS (1.5 MB/s) "
          "| vs 115200 baud (11.5 kB/s) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    rows = [("deframe + both CRCs (FrameBatch)", deframe_s, deframe_cpu_s),
            ("  of which CRC16 (by columns, or crc_hqx)", crc_timer.seconds, None),
            ("  of which framing (numpy scan, CRC8, greedy)", deframe_s - crc_timer.seconds, None),
            ("deframe + Packet objects", packets_s, None), ("decode records one by one (registry)", decode_s, None),
            ("deframe + Packets + decode", packets_s + decode_s, None)]
    for name, seconds, cpu_s in rows:
        rate = len(stream) / seconds
        cpu = "" if cpu_s is None else f"{cpu_s:.2f}"
        cpu_rate = "" if cpu_s is None else f"{len(stream) / cpu_s / 1e6:.1f}"
        print(f"| {name} | {seconds:.2f} | {cpu} | {rate / 1e6:.1f} | {cpu_rate} | {frames / seconds:,.0f} | "
              f"{rate / USB_FULL_SPEED_BPS:.0f}x | {rate / UART_115200_BPS:,.0f}x |")
    four_hours = UART_115200_BPS * 4 * 3600
    print(f"\na 4-hour 115200-baud log ({four_hours / 1e6:.0f} MB) deframes in "
          f"{four_hours / (len(stream) / deframe_s):.1f} s\n")


def _crc_table(sample: bytes) -> None:
    start = time.perf_counter()
    fast = crc16(sample)
    fast_s = time.perf_counter() - start
    start = time.perf_counter()
    slow = _bytewise_crc16(sample)
    slow_s = time.perf_counter() - start
    print(f"| CRC16 over {len(sample) / 1e6:.1f} MB | time (ms) | MB/s | result |")
    print("|---|---:|---:|---|")
    print(f"| bytes.translate + binascii.crc_hqx | {fast_s * 1e3:.2f} | {len(sample) / fast_s / 1e6:.0f} "
          f"| 0x{fast:04x} |")
    print(f"| Python table loop, one byte at a time (baseline) | {slow_s * 1e3:.0f} | {len(sample) / slow_s / 1e6:.1f}"
          f" | 0x{slow:04x} ({'same' if slow == fast else 'DIFFERENT'}) |")


def _cpu_and_wall(run, children: bool = False) -> tuple[float, float]:
    """``(CPU seconds, wall seconds)`` of ``run()`` (CPU of child processes when ``children``); stdout dropped."""
    who = resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF
    before, start = resource.getrusage(who), time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        run()
    wall, after = time.perf_counter() - start, resource.getrusage(who)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, wall


def _bytewise_crc16(data: bytes, seed: int = duml.CRC16_SEED) -> int:
    table = [0] * 256
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
        table[byte] = crc
    crc = seed
    for byte in data:
        crc = (crc >> 8) ^ table[(crc ^ byte) & 0xFF]
    return crc


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size-mb", type=int, default=100)
    parser.add_argument("--chunk-mb", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--mixes", nargs="+", choices=list(MIXES), default=DEFAULT_MIXES)
    args = parser.parse_args()
    bench(args.size_mb, args.chunk_mb, args.seed, args.mixes)


if __name__ == "__main__":
    main()
