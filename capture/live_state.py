"""What the live view shows, computed from decoded telemetry as it arrives: pure state, no I/O, no clock of its own.

Every update carries its time ``t`` in seconds on one clock: the receive time of the chunk that completed the
packet (:class:`capture.transports.Chunk`'s ``receive_time_monotonic``), and :meth:`LiveState.tick` is called with
the same clock's "now" so that silences are seen while nothing arrives. Positions are measured against a
:class:`capture.live_plan.PlannedPath` (its frame: east/north metres from the first waypoint).

Warnings (:data:`WARNING_KINDS`), each raised when its condition starts and cleared when it ends:

* ``off_path``: on the mission, the aircraft is more than ``off_path_m`` (horizontally) from the planned path;
* ``gimbal``: on the mission, the gimbal pitch is more than ``gimbal_tolerance_deg`` from the planned pitch;
* ``shutter_gap``: on a leg with timed photos, no shutter event for longer than the interval allows
  (:meth:`LiveLimits.longest_gap_s`: the planner warns that a Mini SE may skip shots at 1 s, so one skipped shot
  is allowed) while the camera's pushes kept coming: a gap with a hole in the pushes (longer than
  :data:`PUSH_HOLE_FACTOR` times their shortest interval: a push, and the shutter edge it showed, may be lost) is
  not known to be the camera's, and neither counts for ``longest_gap_s``;
* ``link_silent``: no packet for more than ``silent_after_s``;
* ``battery``: the battery, at the rate it has been used, would fall below ``battery_reserve_percent`` before the
  path is finished and the aircraft is home (:meth:`LiveState.battery_needed_percent`); it is cleared once it would
  end :data:`BATTERY_CLEAR_MARGIN_PERCENT` above it.

"On the mission" runs from the moment the aircraft is within ``off_path_m`` of the first waypoint (horizontally and
in height) until it is within ``off_path_m`` of the path's end.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from capture.live_plan import CRUISE_SPEED_MPS, DESCENT_RATE_MPS, PlannedPath
from capture.messages import CameraState, GimbalParams, HomePoint, OsdGeneral, is_shutter_edge

WARNING_KINDS = ("off_path", "gimbal", "shutter_gap", "link_silent", "battery")
#: How far a shutter event read from the camera's pushes may be from the shot (s): a push interval or two.
SHUTTER_JITTER_S = 0.5
#: Shots in a row a Mini SE may skip at a 1 s interval without a warning (the planner's own caveat).
SKIPPED_SHOTS_ALLOWED = 1
#: A wait between camera pushes longer than this many times their shortest interval is a hole (pushes were lost).
PUSH_HOLE_FACTOR = 1.5
#: Windows (s) over which the battery's use is measured; the fastest of them predicts the rest.
BATTERY_WINDOWS_S = (2.0, 5.0, 10.0, 30.0)
#: The least drop (whole percent points) the battery's rate is measured over.
BATTERY_MIN_DROP_PERCENT = 2
#: A battery warning is cleared only once the battery would end this much above the reserve (percent points).
BATTERY_CLEAR_MARGIN_PERCENT = 5.0
#: Seconds over which the link's byte rate is averaged.
RATE_WINDOW_S = 5.0


@dataclass(frozen=True)
class LiveLimits:
    """When the live view warns (see the module docstring)."""

    off_path_m: float = 5.0
    gimbal_tolerance_deg: float = 5.0
    silent_after_s: float = 1.0
    battery_reserve_percent: float = 15.0

    def longest_gap_s(self, interval_s: float) -> float:
        """The longest shutter gap allowed at a photo interval of ``interval_s``."""
        return (SKIPPED_SHOTS_ALLOWED + 1) * interval_s + SHUTTER_JITTER_S


@dataclass
class Alert:
    """One warning: its kind, when it was raised (and cleared, None while it lasts) and what it said then."""

    kind: str
    start_t: float
    message: str
    end_t: float | None = None


@dataclass
class LinkHealth:
    """Bytes and packets so far, CRC errors (header, packet) and the time of the last packet."""

    bytes: int = 0
    packets: int = 0
    header_crc_errors: int = 0
    packet_crc_errors: int = 0
    last_packet_t: float | None = None
    recent: deque = field(default_factory=deque)  # (t, total bytes) over the last RATE_WINDOW_S

    def bytes_per_s(self) -> float:
        if len(self.recent) < 2 or self.recent[-1][0] <= self.recent[0][0]:
            return 0.0
        return (self.recent[-1][1] - self.recent[0][1]) / (self.recent[-1][0] - self.recent[0][0])


@dataclass
class Progress:
    """Where the aircraft is against the plan: along-track (m), cross-track (m), leg, and mission state."""

    along_m: float = 0.0
    cross_m: float | None = None
    along_error_m: float | None = None  # along-track minus where the plan's schedule is (+ ahead, - behind)
    leg: int = 0
    started_t: float | None = None  # when the aircraft reached the path's start
    finished: bool = False

    @property
    def started(self) -> bool:
        return self.started_t is not None

    @property
    def on_mission(self) -> bool:
        return self.started and not self.finished


class LiveState:
    """The running state of a flight against ``plan`` (module docstring); ``warnings`` lists every warning raised,
    ``active`` the ones that last."""

    def __init__(self, plan: PlannedPath, limits: LiveLimits = LiveLimits()) -> None:
        self.plan, self.limits = plan, limits
        self.link = LinkHealth()
        self.progress = Progress()
        self.osd: OsdGeneral | None = None
        self.gimbal_pitch_deg: float | None = None
        self.home_en: tuple[float, float] | None = None
        self.photos = 0
        self.longest_gap_s = 0.0
        self.warnings: list[Alert] = []
        self.active: dict[str, Alert] = {}
        self._camera: CameraState | None = None
        self._last_push_t: float | None = None
        self._push_interval_s = np.inf  # the shortest interval between camera pushes so far
        self._hole_end_t = -np.inf  # the first push after the last hole in the pushes
        self._last_shutter_t: float | None = None
        self._battery_percent: int | None = None  # the last reading
        self._battery_changes: deque = deque()  # over the longest window (see _on_battery)
        self._first_battery_change: tuple[float, int] | None = None

    # --- input --------------------------------------------------------------------------------------------
    def on_bytes(self, t: float, total_bytes: int, packets: int, header_crc_errors: int,
                 packet_crc_errors: int) -> None:
        """The link's totals at ``t`` (from the deframer)."""
        link = self.link
        link.bytes, link.header_crc_errors, link.packet_crc_errors = total_bytes, header_crc_errors, packet_crc_errors
        link.packets = packets
        link.recent.append((t, total_bytes))
        while link.recent and link.recent[0][0] < t - RATE_WINDOW_S:
            link.recent.popleft()

    def on_packet(self, t: float, record) -> None:
        """One decoded packet at ``t``: ``record`` is its message (OSD, gimbal, home, camera) or anything else."""
        link = self.link
        link.last_packet_t = t
        self._end("link_silent", t)
        if isinstance(record, OsdGeneral):
            self._on_osd(t, record)
        elif isinstance(record, GimbalParams):
            self._on_gimbal(t, record.pitch_deg)
        elif isinstance(record, HomePoint) and record.is_set:
            self.home_en = self.plan.position_en(record.home_latitude_deg, record.home_longitude_deg)
        elif isinstance(record, CameraState):
            self._on_camera(t, record)

    def tick(self, now: float) -> None:
        """Check what can go wrong while nothing arrives: a silent link, a shutter that stopped."""
        last = self.link.last_packet_t
        if last is not None and now - last > self.limits.silent_after_s:
            self._start("link_silent", now, f"no packet for {now - last:.1f} s")
        self._check_shutter(now)

    # --- messages -----------------------------------------------------------------------------------------
    def _on_osd(self, t: float, osd: OsdGeneral) -> None:
        self.osd = osd
        self._on_battery(t, osd.battery_percent)
        if not osd.has_fix:
            return
        east, north = self.plan.position_en(osd.latitude_deg, osd.longitude_deg)
        if self.home_en is None:
            self.home_en = (east, north)  # the first fix, until the home point arrives
        progress, limit = self.progress, self.limits.off_path_m
        along, cross = self.plan.locate(east, north, progress.along_m)
        height_error = osd.height_above_takeoff_m - self.plan.altitude_at(along)
        if not progress.started and along < limit and cross < limit and abs(height_error) < limit:
            progress.started_t = t
        if progress.on_mission:
            progress.along_m, progress.cross_m, progress.leg = along, cross, self.plan.leg_at(along)
            progress.along_error_m = along - self.plan.along_after_s(t - progress.started_t)
            if self.plan.length_m - along < limit:
                progress.finished = True
        self._set("off_path", t, progress.on_mission and cross > limit,
                  f"{cross:.1f} m off the path on leg {progress.leg + 1} (limit {limit:g} m)")
        self._check_battery(t)

    def _on_gimbal(self, t: float, pitch_deg: float) -> None:
        self.gimbal_pitch_deg = pitch_deg
        planned = self.plan.gimbal_pitch_at(self.progress.along_m)
        off = abs(pitch_deg - planned)
        self._set("gimbal", t, self.progress.on_mission and off > self.limits.gimbal_tolerance_deg,
                  f"gimbal pitch {pitch_deg:.1f} deg, planned {planned:.1f} "
                  f"(limit +-{self.limits.gimbal_tolerance_deg:g})")

    def _on_camera(self, t: float, camera: CameraState) -> None:
        if self._last_push_t is not None:
            since = t - self._last_push_t
            if since > PUSH_HOLE_FACTOR * self._push_interval_s:
                self._hole_end_t = t
            self._push_interval_s = min(self._push_interval_s, max(since, 1e-3))
        self._last_push_t = t
        if is_shutter_edge(self._camera, camera):
            self.photos += 1
            if self._pushes_unbroken_since(self._last_shutter_t):
                self.longest_gap_s = max(self.longest_gap_s, t - self._last_shutter_t)
            self._last_shutter_t = t
            self._end("shutter_gap", t)
        self._camera = camera

    def _pushes_unbroken_since(self, t: float | None) -> bool:
        """Whether every camera push since ``t`` arrived (no hole in them)."""
        return t is not None and self._hole_end_t <= t

    def _check_shutter(self, now: float) -> None:
        last = self._last_shutter_t
        interval = self.plan.photo_interval_at(self.progress.along_m)
        if interval <= 0 or not self.progress.on_mission or not self._pushes_unbroken_since(last):
            return
        if now - self._last_push_t > PUSH_HOLE_FACTOR * self._push_interval_s:
            return  # a hole now: the camera may be shooting unseen
        allowed = self.limits.longest_gap_s(interval)
        if now - last > allowed:
            self._start("shutter_gap", now, f"no photo for {now - last:.1f} s at a {interval:g} s interval "
                                                       f"(allowed {allowed:g} s)")

    # --- battery ------------------------------------------------------------------------------------------
    def _on_battery(self, t: float, percent: int) -> None:
        """Keep the moments ``(t, percent)`` the shown percentage changed (the first reading showing each value)."""
        if self._battery_percent is not None and percent != self._battery_percent:
            self._battery_changes.append((t, percent))
            if self._first_battery_change is None:
                self._first_battery_change = (t, percent)
            while self._battery_changes[0][0] < t - max(BATTERY_WINDOWS_S):
                self._battery_changes.popleft()
        self._battery_percent = percent

    def battery_rate_percent_per_s(self) -> float:
        """The battery's use (percent per second): the fastest of its averages over :data:`BATTERY_WINDOWS_S` and
        since its first change. A whole-percent reading changes when the charge crosses a half percent, so between
        two changes exactly their difference was spent (timed to a reading's interval). It takes a drop of at least
        :data:`BATTERY_MIN_DROP_PERCENT` (a single step could be a reading's jitter); 0 until then."""
        changes = self._battery_changes
        if not changes:
            return 0.0
        now, percent_now = changes[-1]
        firsts = [next(change for change in changes if change[0] >= now - window) for window in BATTERY_WINDOWS_S]
        rates = [(percent - percent_now) / (now - t) for t, percent in [*firsts, self._first_battery_change]
                 if percent - percent_now >= BATTERY_MIN_DROP_PERCENT and now > t]  # a burst has no timing
        return max(rates, default=0.0)

    def time_left_s(self) -> float:
        """Seconds to finish the path (at the legs' speeds) and come home: back at :data:`CRUISE_SPEED_MPS`, down at
        :data:`DESCENT_RATE_MPS`."""
        osd = self.osd
        if self.progress.finished and osd is not None and osd.has_fix:
            finish, leave_en = 0.0, np.array(self.plan.position_en(osd.latitude_deg, osd.longitude_deg))
        else:
            finish, leave_en = self.plan.time_to_finish_s(self.progress.along_m), self.plan.points_en[-1]
        home_en = np.array(self.home_en if self.home_en is not None else (0.0, 0.0))
        height = self.plan.altitude_m[-1] if osd is None else max(osd.height_above_takeoff_m, 0.0)
        return finish + float(np.linalg.norm(leave_en - home_en)) / CRUISE_SPEED_MPS + height / DESCENT_RATE_MPS

    def battery_needed_percent(self) -> float:
        """The battery the rest of the flight needs at the measured rate (percent)."""
        return self.battery_rate_percent_per_s() * self.time_left_s()

    def _check_battery(self, t: float) -> None:
        if self.osd is None:
            return
        left = self.osd.battery_percent - self.battery_needed_percent()
        reserve = self.limits.battery_reserve_percent
        margin = BATTERY_CLEAR_MARGIN_PERCENT if "battery" in self.active else 0.0  # no flicker at the edge
        self._set("battery", t, left < reserve + margin,
                  f"battery {self.osd.battery_percent} %, the rest of the flight needs "
                  f"{self.battery_needed_percent():.0f} % (reserve {reserve:g} %)")

    # --- warnings -----------------------------------------------------------------------------------------
    def _set(self, kind: str, t: float, on: bool, message: str) -> None:
        if on:
            self._start(kind, t, message)
        else:
            self._end(kind, t)

    def _start(self, kind: str, t: float, message: str) -> None:
        if kind not in self.active:
            warning = Alert(kind, t, message)
            self.active[kind] = warning
            self.warnings.append(warning)

    def _end(self, kind: str, t: float) -> None:
        warning = self.active.pop(kind, None)
        if warning is not None:
            warning.end_t = t
