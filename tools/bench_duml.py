"""Benchmark: DUML deframing (with both CRCs), telemetry decoding and the whole ``decode`` CLI on a synthetic dump.

Traffic per simulated second, like a P3X FC/OFDM link: OSD General 10 Hz, Gimbal Params 50 Hz, Home Point 1 Hz,
plus ~100 Hz of other chatter (random cmd ids, 1-60 byte payloads); then 1 % of all bytes are corrupted.
A 1 MB block of such traffic is generated and repeated up to the requested size. For the CLI rows the dump is
written as a raw capture (``.duml`` + ``.idx``, 4 KiB chunks 10 ms apart, as ``record`` writes them) and decoded to
CSV by ``aerostereo-ingest decode``: in-process (``capture.cli.main``) and as a command (Python start and imports
included). Time is wall-clock; CPU is the process's CPU time (the two differ when the machine is shared).

    PYTHONPATH=. .venv/bin/python tools/bench_duml.py              # 100 MB
    PYTHONPATH=. .venv/bin/python tools/bench_duml.py --size-mb 19  # issue 18's 19 MB, as in docs/ingest-duml.md
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
from capture.messages import GimbalParams, HomePoint, OsdGeneral, default_registry, encode_message
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


def bench(size_mb: int, chunk_mb: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    block = synthetic_block(rng, 1 << 20)
    stream = corrupt((block * (size_mb * (1 << 20) // len(block) + 1))[:size_mb << 20], 0.01, rng)
    chunk = int(chunk_mb * (1 << 20))
    chunks = [stream[i:i + chunk] for i in range(0, len(stream), chunk)]
    megabytes = len(stream) / 1e6

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

    sample = stream[:1 << 20]
    start = time.perf_counter()
    fast = crc16(sample)
    fast_s = time.perf_counter() - start
    start = time.perf_counter()
    slow = _bytewise_crc16(sample)
    slow_s = time.perf_counter() - start

    with tempfile.TemporaryDirectory() as folder:
        capture = Path(folder) / "dump.duml"
        with atomic_capture(capture) as writer:
            for i in range(0, len(stream), 4096):
                writer.append(dt.datetime(2024, 1, 1, tzinfo=dt.timezone.utc) + dt.timedelta(seconds=i / 409600),
                              1000.0 + i / 409600, stream[i:i + 4096])
        cli_in_process = _cpu_and_wall(lambda: cli.main(["decode", str(capture), "--out", f"{folder}/a.csv"]))
        cli_command = _cpu_and_wall(lambda: subprocess.run(
            [sys.executable, "-m", "capture", "decode", str(capture), "--out", f"{folder}/b.csv"],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), children=True)

    print(f"synthetic dump: {megabytes:.1f} MB ({len(stream)} bytes), 1 % corrupted bytes, fed in {chunk_mb} MB "
          f"chunks; {frames} intact frames; skipped bytes {stats.skipped_bytes}")
    print()
    print("| stage | time (s) | CPU (s) | MB/s | MB/s of CPU | packets/s | vs USB 2.0 FS (1.5 MB/s) "
          "| vs 115200 baud (11.5 kB/s) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    rows = [("deframe + both CRCs (FrameBatch)", deframe_s, deframe_cpu_s),
            ("  of which CRC16 (crc_hqx)", crc_timer.seconds, None),
            ("  of which framing (numpy scan, CRC8, greedy)", deframe_s - crc_timer.seconds, None),
            ("deframe + Packet objects", packets_s, None), ("decode records (registry)", decode_s, None),
            ("deframe + Packets + decode", packets_s + decode_s, None),
            ("whole CLI `decode` .duml+.idx -> CSV, in-process", cli_in_process[1], cli_in_process[0]),
            ("whole CLI `decode` as a command (+ Python start, imports)", cli_command[1], cli_command[0])]
    for name, seconds, cpu_s in rows:
        rate = len(stream) / seconds
        cpu = "" if cpu_s is None else f"{cpu_s:.2f}"
        cpu_rate = "" if cpu_s is None else f"{len(stream) / cpu_s / 1e6:.1f}"
        print(f"| {name} | {seconds:.2f} | {cpu} | {rate / 1e6:.1f} | {cpu_rate} | {frames / seconds:,.0f} | "
              f"{rate / USB_FULL_SPEED_BPS:.0f}x | {rate / UART_115200_BPS:,.0f}x |")
    print()
    print("| CRC16 over 1 MB | time (ms) | MB/s | result |")
    print("|---|---:|---:|---|")
    print(f"| bytes.translate + binascii.crc_hqx | {fast_s * 1e3:.2f} | {len(sample) / fast_s / 1e6:.0f} "
          f"| 0x{fast:04x} |")
    print(f"| Python table loop, one byte at a time (baseline) | {slow_s * 1e3:.0f} | {len(sample) / slow_s / 1e6:.1f}"
          f" | 0x{slow:04x} ({'same' if slow == fast else 'DIFFERENT'}) |")
    four_hours = UART_115200_BPS * 4 * 3600
    seconds = four_hours / (len(stream) / deframe_s)
    print(f"\na 4-hour 115200-baud log ({four_hours / 1e6:.0f} MB) deframes in {seconds:.1f} s")


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
    args = parser.parse_args()
    bench(args.size_mb, args.chunk_mb, args.seed)


if __name__ == "__main__":
    main()
