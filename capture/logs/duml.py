"""DUML telemetry -> ``Track``: a raw capture ``NAME.duml`` (+ ``NAME.duml.idx``) or a pcap (link type 150).

Packets are deframed and time-stamped by :func:`capture.decode.timed_packets` and decoded by
:func:`capture.messages.default_registry`; each telemetry message becomes one row of the track:

* OSD General (0x03/0x43): lat/lon, height above take-off, aircraft yaw/pitch/roll, horizontal speed
  ``hypot(vx, vy)``. Latitude and longitude exactly 0 mean "no GPS fix yet": such rows are rejected
  (``no GPS fix``), as are positions outside +-90/+-180 degrees;
* Gimbal Params (0x04/0x05): gimbal yaw/pitch/roll (absolute, NED);
* OSD Home Point (0x03/0x44): the first home point that is set is the take-off point (``Track.home``, its
  altitude as the absolute height there); frames before that (home state bit 0 clear, lat/lon the
  800000.0 rad "not set" value) are rejected (``home point not set``);
* Camera State (0x02/0x80): a photo event at each shutter edge, by ONE signal
  (:func:`capture.messages.is_shutter_edge`, ``photo_state`` by default).

Time: the arrival UTC of the packet's LAST byte -- from the ``.duml.idx`` sidecar for a raw capture, from the
record timestamps for a pcap. A raw capture without its index has no times at all (the frames carry none),
so it is an error (a start time would not help: nothing says when each packet came); packets no index line
covers (a kill between a data flush and its index line) are rejected (``no arrival time``). Packets that
arrived as a backlog (a burst of packets held back by the link) are timed from their DUML sequence numbers at
their stream's own rate instead (:mod:`capture.logs.backlog`), counted in a note. The shutter
fell between the camera state that shows it and the one before, so a photo event is placed midway between
their times: within half a camera-state push interval of the shutter (``Track.event_time_error_s``), with
no lag on average.

Counting: ``rows_read`` = telemetry messages (the four kinds above, plus malformed ones of any registered
kind); each is used or rejected with a reason (``no GPS fix``, ``home point not set``, ``malformed
message``, ``response packet``, ...) and its offset in the DUML byte stream (the file offset for a raw
capture; for a pcap, the offset in its records' data laid end to end). The report's notes give the
deframer's skipped bytes and rejected frames by reason and the counts of messages the track does not use
(undecoded, date/time).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..attitude import wrap_deg
from ..decode import TimedPacket, timed_packets
from ..duml import Deframer, DeframerStats
from ..messages import (CameraState, GimbalParams, HomePoint, MalformedMessage, MessageRegistry, OsdGeneral,
                        default_registry, is_shutter_edge)
from ..raw import CaptureIndexError, index_path
from ..track import Home, LogFormatError, ReadReport, Track, position_problem
from ..transports import TransportError, is_pcap, replay_file
from .backlog import backlog_note, send_times

TELEMETRY = (OsdGeneral, GimbalParams, HomePoint, CameraState)


def looks_like_duml(path: Path) -> bool:
    """True for a pcap, a ``.duml`` file, or a file with a ``.idx`` sidecar beside it."""
    return path.suffix.lower() == ".duml" or index_path(path).exists() or is_pcap(path)


def read_duml_track(path, *, shutter_signal: str = "photo_state") -> Track:
    """Read a raw DUML capture (with its ``.idx``) or a DUML pcap into a UTC ``Track`` (module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise LogFormatError(f"{path}: no such file")
    if not is_pcap(path) and not index_path(path).exists():
        raise LogFormatError(f"{path}: no {index_path(path).name} beside it; a raw capture's packet times come "
                             "only from that index (write captures with 'aerostereo-ingest record', or read a pcap)")
    registry, deframer = default_registry(), Deframer()
    builder = TrackBuilder(ReadReport(str(path), "duml"), shutter_signal, registry)
    truncation: list[str] = []
    try:
        for timed in timed_packets(replay_file(path, truncation), deframer):
            builder.add(timed, registry.decode(timed.packet))
    except (TransportError, CaptureIndexError) as error:
        raise LogFormatError(str(error)) from None
    builder.report.notes.extend(truncation)
    if deframer.stats.packets == 0:
        raise LogFormatError(f"{path}: no DUML frame found in {deframer.stats.bytes_fed} bytes "
                             "(not a DUML capture?)")
    builder.report.notes.extend(stream_notes(deframer.stats, registry))
    return builder.track(deframer.stats.packets)


def stream_notes(stats: DeframerStats, registry: MessageRegistry) -> list[str]:
    """Deframer skip counters and the counts of messages the track does not use, as report notes."""
    skipped = {reason: n for reason, n in stats.skipped_bytes.items() if n}
    rejected = {reason: n for reason, n in stats.rejected_frames.items() if n and reason != "no_sync"}
    used = {registry.spec_for(record_type).kind for record_type in TELEMETRY}
    unused = {kind: n for kind, n in registry.counts.items()
              if n and kind not in used and not kind.startswith("malformed_")}  # malformed ones are rejected rows
    return [
        f"deframer: {stats.bytes_fed} bytes, {stats.packets} frames; skipped bytes: {counts_text(skipped)}; "
        f"rejected frames: {counts_text(rejected)}",
        f"messages not used for the track: {counts_text(unused)}",
    ]


def counts_text(counts: dict[str, int]) -> str:
    return ", ".join(f"{name} {n}" for name, n in counts.items()) or "none"


class TrackBuilder:
    """Collects rows, home points and shutter edges from decoded packets, in arrival order; every telemetry packet
    with an arrival time is a timing sample of its stream (sender and command) for :func:`send_times`."""

    def __init__(self, report: ReadReport, shutter_signal: str, registry: MessageRegistry) -> None:
        self.report = report
        self.shutter_signal = shutter_signal
        self.registry = registry
        self.arrivals: list[float] = []  # per timing sample: arrival UTC s, stream id, DUML seq, stream offset
        self.streams: list[int] = []
        self.seqs: list[int] = []
        self.offsets: list[int] = []
        self.stream_ids: dict[tuple, int] = {}
        self.stream_names: dict[int, str] = {}
        self.row_samples: list[int] = []  # the timing sample of each row
        self.rows: list[dict[str, float]] = []
        self.homes: list[Home] = []
        self.camera_samples: list[int] = []
        self.shutter_edges: list[bool] = []  # per camera-state push: the shutter fell since the push before
        self.previous_camera: CameraState | None = None

    def add(self, timed: TimedPacket, record) -> None:
        """Use or reject one decoded packet; messages that are not telemetry are only counted (registry)."""
        if not isinstance(record, (*TELEMETRY, MalformedMessage)):
            return
        self.report.rows_read += 1
        where = f"at stream byte {timed.offset}"
        if isinstance(record, MalformedMessage):
            return self.reject(f"malformed message: {record.reason} {where}")
        kind = type(record).__name__
        if timed.packet.is_response:
            return self.reject(f"response packet: {kind} {where} is an answer, not a telemetry push")
        if timed.receive_time_utc is None:
            return self.reject(f"no arrival time: {kind} {where} has no index line (cut off by a kill) or pcap "
                               "record time (a corrupt record)")
        sample = self.add_sample(timed, self.registry.spec_for(record).kind)
        if isinstance(record, OsdGeneral):
            self.add_osd(sample, record, where)
        elif isinstance(record, GimbalParams):
            self.add_row(sample, gimbal_row(record))
        elif isinstance(record, HomePoint):
            self.add_home(record, where)
        else:
            self.add_camera_state(sample, record)

    def add_sample(self, timed: TimedPacket, kind: str) -> int:
        """Record the packet's arrival, stream and sequence number; returns its sample index."""
        packet = timed.packet
        key = (packet.sender, packet.cmd_set, packet.cmd_id)
        stream = self.stream_ids.setdefault(key, len(self.stream_ids))
        self.stream_names[stream] = kind
        self.arrivals.append(timed.receive_time_utc.timestamp())
        self.streams.append(stream)
        self.seqs.append(packet.seq)
        self.offsets.append(timed.offset)
        return len(self.arrivals) - 1

    def reject(self, reason: str) -> None:
        self.report.reject(None, reason)

    def add_row(self, sample: int, row: dict[str, float]) -> None:
        self.row_samples.append(sample)
        self.rows.append(row)
        self.report.rows_used += 1

    def add_osd(self, sample: int, osd: OsdGeneral, where: str) -> None:
        if not osd.has_fix:
            return self.reject(f"no GPS fix: OSD {where} has lat/lon exactly 0 ({osd.gps_satellites} satellites)")
        if problem := position_problem(osd.latitude_deg, osd.longitude_deg):
            return self.reject(f"{problem} (OSD {where})")
        self.add_row(sample, osd_row(osd))

    def add_home(self, home: HomePoint, where: str) -> None:
        if not home.is_set:
            return self.reject(f"home point not set: home {where} (state 0x{home.home_state:04x})")
        self.homes.append(Home(home.home_latitude_deg, home.home_longitude_deg, home.home_altitude_m))
        self.report.rows_used += 1

    def add_camera_state(self, sample: int, state: CameraState) -> None:
        self.shutter_edges.append(is_shutter_edge(self.previous_camera, state, self.shutter_signal))
        self.previous_camera = state
        self.camera_samples.append(sample)
        self.report.rows_used += 1

    def track(self, frames: int) -> Track:
        """The collected rows as a ``Track``; LogFormatError if no OSD or gimbal row could be used."""
        if not self.rows:
            reasons = ", ".join(f"{n} {reason}" for reason, n in self.report.reasons().most_common()) or "none"
            raise LogFormatError(f"{self.report.source}: no usable OSD or gimbal telemetry in {frames} frames "
                                 f"(rejected: {reasons})")
        times, bursts = send_times(self.arrivals, self.streams, self.seqs, self.offsets, self.stream_names)
        camera_times = times[self.camera_samples]
        self.report.notes.extend(self.notes(camera_times, backlog_note(bursts)))
        names = sorted({name for row in self.rows for name in row})
        columns = {name: np.array([row.get(name, math.nan) for row in self.rows]) for name in names}
        return Track.from_rows(times[self.row_samples], columns, self.report,
                               photo_times_s=self.photo_times(camera_times),
                               home=self.homes[0] if self.homes else None,
                               event_time_error_s=0.5 * camera_interval_s(camera_times))

    def photo_times(self, camera_times: np.ndarray) -> np.ndarray:
        """A photo event midway between the camera state that shows a shutter edge and the one before it."""
        edges = np.flatnonzero(self.shutter_edges)
        return 0.5 * (camera_times[edges - 1] + camera_times[edges])

    def notes(self, camera_times: np.ndarray, backlog: str | None) -> list[str]:
        notes = ["times: arrival UTC of each packet's last byte"] + ([backlog] if backlog else [])
        if len(camera_times):
            notes.append(f"{len(self.photo_times(camera_times))} photo events from {len(camera_times)} camera-state "
                         f"pushes (shutter signal {self.shutter_signal}; events midway between two pushes, within "
                         f"{0.5 * camera_interval_s(camera_times):.3f} s of the shutter)")
        else:
            notes.append("no camera-state pushes: no photo events")
        no_fix = self.report.reasons()["no GPS fix"]
        if no_fix and not any("lat_deg" in row for row in self.rows):
            notes.append(f"no GPS fix in any of the {no_fix} OSD messages: the track has no positions")
        if not self.homes:
            notes.append("no home point set in this capture: the take-off point is the first GPS position")
        elif len(set(self.homes)) > 1:
            notes.append(f"home point moved ({len(set(self.homes))} different ones); the first is the take-off point")
        return notes


def camera_interval_s(camera_times: np.ndarray) -> float:
    """Median interval between camera-state pushes (0 if unknown): a shutter falls within one of them."""
    return float(np.median(np.diff(np.sort(camera_times)))) if len(camera_times) > 1 else 0.0


def osd_row(osd: OsdGeneral) -> dict[str, float]:
    """Track fields of one OSD General record (degrees, metres, m/s)."""
    return {"lat_deg": osd.latitude_deg, "lon_deg": osd.longitude_deg,
            "height_above_takeoff_m": osd.height_above_takeoff_m,
            "aircraft_yaw_deg": float(wrap_deg(osd.yaw_deg)), "aircraft_pitch_deg": osd.pitch_deg,
            "aircraft_roll_deg": osd.roll_deg, "speed_m_s": math.hypot(osd.velocity_x_mps, osd.velocity_y_mps)}


def gimbal_row(gimbal: GimbalParams) -> dict[str, float]:
    """Track fields of one Gimbal Params record (absolute NED degrees)."""
    return {"gimbal_yaw_deg": float(wrap_deg(gimbal.yaw_deg)), "gimbal_pitch_deg": gimbal.pitch_deg,
            "gimbal_roll_deg": gimbal.roll_deg}
