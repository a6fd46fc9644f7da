"""Send times for DUML packets that arrived as a backlog, from what the packets themselves say.

A capture stamps each packet with its arrival (the index line or pcap record of its last byte). A link may hold
packets back and then deliver them in a burst: a cable plugged in after take-off, an app that buffers, a reconnect,
a recorder that starts late. Stamped by arrival, 40 s of take-off telemetry delivered in 4 s is a track squeezed
tenfold, and photos interpolated on it land metres to tens of metres off.

Each telemetry stream -- one sender's pushes of one message (OSD General at 10 Hz, Gimbal Params, Camera State,
Home Point) -- is sent at a steady rate and numbers its packets: the DUML sequence number advances by a steady
step per packet (1 for a P3X's OSD pushes, 40 for its gimbal pushes; by every packet of the aircraft on the
virtual drone). So a stream's sequence numbers, unwrapped (u16), are its send schedule ``n`` and its rate
(seconds per sequence step ``T``) is measured over the capture itself, from the intervals
``(arrival[i + k] - arrival[i]) / (n[i + k] - n[i])`` of windows of :data:`RATE_WINDOW_PACKETS` packets: a window
inside a backlog is squeezed (its interval too short), one over a pause of the link without lost numbers too long,
and the rest agree; the rate is the median of those that agree with the windows' 75th percentile, which holds for
a backlog of up to 3/4 of the capture. Lost packets keep their steps, so they keep their time.

A packet cannot arrive before it was sent, so a packet is late by ``late[i] = b[i] - min(b[j], j >= i)`` with
``b = arrival - n * T``: how much earlier the packets after it say it was sent. On a steady link this is the
latency jitter (at most 0.27 s measured on the virtual drone's live links and the real P3X captures); a backlog
is a run of packets later than :data:`CAUGHT_UP_S` whose lateness passes :data:`BACKLOG_MIN_S`. Only such runs
are retimed, to ``arrival - late`` -- the send time plus the link's least latency, on the same footing as the
packets around them; everything else keeps its arrival time.

A step that is not a plausible advance (backward, zero on a stream that counts, or beyond
:data:`MAX_SEQ_STEPS` median steps: a restart, a long loss) splits the stream: no time is carried across it.
A stream whose numbers do not advance is scheduled by packet count; one of fewer than
:data:`MIN_STREAM_PACKETS` packets keeps its arrival times (its rate cannot be measured).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Smallest lateness (s) that makes a run of late packets a backlog: above the latency jitter of a working link.
BACKLOG_MIN_S = 0.5
#: A backlog ends where the packets are no later than this (s): caught up, within a working link's jitter.
CAUGHT_UP_S = 0.1
#: Packets per window over which a stream's rate is measured (about 5 s of OSD General).
RATE_WINDOW_PACKETS = 50
#: The windows' intervals per step: this percentile, above the squeezed ones of a backlog (up to 3/4 of them) and
#: below windows over a pause (up to 1/4), is near the rate; the rate is the median of those within
#: :data:`RATE_AGREEMENT` of it (the latency jitter spreads them by about 1 %).
RATE_PERCENTILE = 75.0
RATE_AGREEMENT = 0.05
#: Fewest packets of a stream for its rate to be measured.
MIN_STREAM_PACKETS = 20
#: Largest sequence step, in median steps, still read as packets lost in between (beyond: the stream is split).
MAX_SEQ_STEPS = 100
SEQ_MODULUS = 1 << 16


@dataclass(frozen=True)
class Burst:
    """One backlog of one stream: its packets (count), the stream bytes of the first and last, the largest
    lateness (s) and the send-time span (UTC seconds) they were given."""

    stream: str
    packets: int
    first_offset: int
    last_offset: int
    max_late_s: float
    start_s: float
    end_s: float


def seq_schedule(seq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(n, piece)`` of one stream's sequence numbers (u16, in arrival order): ``n`` the unwrapped schedule in
    sequence steps (packet count where the numbers do not advance), ``piece`` the index of the part between
    breaks (module docstring) each packet belongs to."""
    steps = np.diff(seq.astype(np.int64)) % SEQ_MODULUS
    forward = steps[(steps > 0) & (steps < SEQ_MODULUS // 2)]
    if len(forward) == 0 or np.median(forward) == 0:
        return np.arange(len(seq), dtype=np.float64), np.zeros(len(seq), dtype=np.int64)
    median = float(np.median(forward))
    breaks = (steps == 0) | (steps >= SEQ_MODULUS // 2) | (steps > MAX_SEQ_STEPS * median)
    n = np.concatenate([[0], np.cumsum(np.where(breaks, 0, steps))]).astype(np.float64)
    return n, np.concatenate([[0], np.cumsum(breaks)])


def seconds_per_step(arrival_s: np.ndarray, n: np.ndarray, piece: np.ndarray) -> float | None:
    """The stream's send interval per sequence step (s), from windows of :data:`RATE_WINDOW_PACKETS` packets inside
    one piece (module docstring); None where no window has a positive span."""
    k = min(RATE_WINDOW_PACKETS, len(n) - 1)
    same_piece = piece[k:] == piece[:-k]
    steps = (n[k:] - n[:-k])[same_piece]
    span = (arrival_s[k:] - arrival_s[:-k])[same_piece]
    intervals = span[steps > 0] / steps[steps > 0]
    if len(intervals) == 0 or np.percentile(intervals, RATE_PERCENTILE) <= 0:
        return None
    rough = np.percentile(intervals, RATE_PERCENTILE)
    return float(np.median(intervals[np.abs(intervals - rough) <= RATE_AGREEMENT * rough]))


def lateness(arrival_s: np.ndarray, n: np.ndarray, piece: np.ndarray, step_s: float) -> np.ndarray:
    """How late (s, >= 0) each packet arrived against the packets after it in its piece (module docstring)."""
    late = np.zeros(len(n))
    for part in np.unique(piece):
        rows = np.flatnonzero(piece == part)
        b = arrival_s[rows] - n[rows] * step_s
        late[rows] = b - np.minimum.accumulate(b[::-1])[::-1]
    return late


def late_runs(late: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` of each run of packets later than :data:`CAUGHT_UP_S` whose lateness passes
    :data:`BACKLOG_MIN_S`."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (late > CAUGHT_UP_S).astype(np.int8), [0]])))
    return [(int(s), int(e)) for s, e in zip(edges[::2], edges[1::2]) if late[s:e].max() > BACKLOG_MIN_S]


def send_times(arrival_s, stream, seq, offsets, names: dict[int, str]) -> tuple[np.ndarray, list[Burst]]:
    """Times (UTC s) for packets with arrival times ``arrival_s``, stream ids ``stream`` (named by ``names``),
    DUML sequence numbers ``seq`` and stream byte offsets ``offsets`` (arrays in arrival order): the arrival
    time, except for the packets of a backlog, timed from their sequence numbers (module docstring)."""
    arrival_s = np.asarray(arrival_s, dtype=np.float64)
    stream, seq, offsets = (np.asarray(a, dtype=np.int64) for a in (stream, seq, offsets))
    times, bursts = arrival_s.copy(), []
    for key in np.unique(stream):
        rows = np.flatnonzero(stream == key)
        if len(rows) < MIN_STREAM_PACKETS:
            continue
        n, piece = seq_schedule(seq[rows])
        step_s = seconds_per_step(arrival_s[rows], n, piece)
        if step_s is None:
            continue
        late = lateness(arrival_s[rows], n, piece, step_s)
        for start, end in late_runs(late):
            run = rows[start:end]
            times[run] = arrival_s[run] - late[start:end]
            bursts.append(Burst(names[int(key)], end - start, int(offsets[run[0]]), int(offsets[run[-1]]),
                                float(late[start:end].max()), float(times[run].min()), float(times[run].max())))
    return times, bursts


def backlog_note(bursts: list[Burst]) -> str | None:
    """The report note counting the packets timed from their sequence numbers, or None without a backlog."""
    if not bursts:
        return None
    by_stream: dict[str, int] = {}
    for burst in bursts:
        by_stream[burst.stream] = by_stream.get(burst.stream, 0) + burst.packets
    worst = max(bursts, key=lambda burst: burst.max_late_s)
    streams = ", ".join(f"{name} {count}" for name, count in by_stream.items())
    return (f"backlog: {sum(by_stream.values())} packets ({streams}) arrived up to {worst.max_late_s:.2f} s late "
            f"in {len(bursts)} stream bursts (the worst at stream bytes {worst.first_offset}..{worst.last_offset}): "
            "timed from their DUML sequence numbers at their stream's own measured rate, not by arrival")
