"""The live view of ``aerostereo-ingest record --mission``: a thread that decodes a copy of the recorded chunks into
a :class:`capture.live_state.LiveState` and shows it -- a full-screen view (stdlib ``curses``) on a terminal, plain
lines on stderr otherwise.

The recording comes first: the recorder appends each chunk to the capture before handing it to
:meth:`LiveMonitor.put`, a put on an unbounded queue that never blocks, so the view cannot slow or change what is
written. The monitor thread decodes every chunk in order (it must see every packet to count the photos) and draws
at most once per ``refresh_s`` and only when it has caught up: when it falls behind it skips drawing, never bytes.
Times shown are seconds since the view started, on the recorder's clock.
"""

from __future__ import annotations

import curses
import queue
import sys
import threading
import time
from typing import Callable, TextIO

from capture.duml import Deframer
from capture.live_state import BATTERY_MIN_DROP_PERCENT, Alert, LiveState
from capture.messages import MessageRegistry
from capture.transports import Chunk

#: How often the monitor looks at the clock while nothing arrives (s, wall time): a silence is seen this late.
TICK_S = 0.02
#: The plain log's status line: every this many seconds (wall time), and each warning once when it is raised.
LOG_EVERY_S = 10.0
_STOP = object()


def _minutes(seconds: float) -> str:
    return f"{int(seconds // 60)}:{int(seconds % 60):02d}"


def status_lines(state: LiveState, now: float) -> list[tuple[str, str]]:
    """The view's text as ``(topic, text)``: link, GPS and battery, height and speed, path, gimbal, photos."""
    link, progress, plan, osd = state.link, state.progress, state.plan, state.osd
    since = "-" if link.last_packet_t is None else f"{now - link.last_packet_t:.1f} s"
    lines = [("LINK", f"{link.bytes_per_s():.0f} B/s, {link.bytes} bytes, {link.packets} packets, CRC errors "
                      f"{link.header_crc_errors} header / {link.packet_crc_errors} packet, last packet {since} ago")]
    if osd is None:
        lines += [("GPS", "no OSD yet"), ("BATTERY", "-"), ("HEIGHT", "-")]
    else:
        fix = f"fix, {osd.gps_satellites} satellites, level {osd.gps_level}" if osd.has_fix else "NO FIX"
        speed = (osd.velocity_x_mps ** 2 + osd.velocity_y_mps ** 2) ** 0.5
        lines += [("GPS", fix),
                  ("BATTERY", f"{osd.battery_percent} %, " + _battery_use(state)),
                  ("HEIGHT", f"{osd.height_above_takeoff_m:.1f} m (plan {plan.altitude_at(progress.along_m):.1f}), "
                             f"speed {speed:.1f} m/s")]
    mission = "finished" if progress.finished else "on the mission" if progress.started else "not on the path yet"
    cross = "-" if progress.cross_m is None else f"{progress.cross_m:.1f} m"
    left = 0.0 if progress.finished else plan.time_to_finish_s(progress.along_m)
    share = 100 * progress.along_m / plan.length_m
    error = progress.along_error_m
    schedule = "" if error is None else f" ({abs(error):.1f} m {'ahead of' if error >= 0 else 'behind'} the plan)"
    lines.append(("PATH", f"{mission}, leg {progress.leg + 1}/{plan.legs}, cross-track {cross}, along-track "
                          f"{progress.along_m:.0f}/{plan.length_m:.0f} m{schedule}, {share:.0f} % done, finish in "
                          f"{_minutes(left)}"))
    pitch = "-" if state.gimbal_pitch_deg is None else f"{state.gimbal_pitch_deg:.1f}"
    lines.append(("GIMBAL", f"pitch {pitch} deg (plan {plan.gimbal_pitch_at(progress.along_m):.1f})"))
    lines.append(("PHOTOS", f"{state.photos} of {plan.planned_photos()} planned, longest shutter gap "
                            f"{state.longest_gap_s:.1f} s"))
    return lines


def _battery_use(state: LiveState) -> str:
    rate = state.battery_rate_percent_per_s()
    if rate == 0:
        return f"its use not measured yet (the reading has not dropped {BATTERY_MIN_DROP_PERCENT} points)"
    return f"the rest of the flight needs {state.battery_needed_percent():.0f} % at {60 * rate:.1f} %/min"


def alert_line(alert: Alert, t0: float) -> str:
    """One warning as text: when it was raised (and cleared), what it said."""
    ended = "" if alert.end_t is None else f", cleared after {alert.end_t - alert.start_t:.1f} s"
    return f"{alert.start_t - t0:8.1f} s  {alert.kind.upper()}: {alert.message}{ended}"


class LineDisplay:
    """Plain lines on ``stream``: a status line every :data:`LOG_EVERY_S` and each warning when raised."""

    def __init__(self, stream: TextIO | None = None, every_s: float = LOG_EVERY_S) -> None:
        self.stream, self.every_s, self._last = stream or sys.stderr, every_s, -float("inf")

    def start(self) -> None:
        pass

    def raised(self, alert: Alert, t0: float) -> None:
        print(f"WARNING {alert_line(alert, t0)}", file=self.stream, flush=True)

    def show(self, state: LiveState, now: float, t0: float) -> None:
        if time.monotonic() - self._last >= self.every_s:
            self._last = time.monotonic()
            print(f"{now - t0:8.1f} s  " + " | ".join(f"{topic.lower()}: {text}"
                                                      for topic, text in status_lines(state, now)),
                  file=self.stream, flush=True)

    def stop(self, state: LiveState, now: float, t0: float) -> None:
        self._last = -float("inf")
        self.show(state, now, t0)


class ScreenDisplay:
    """A full-screen view with ``curses``: the status lines, then the warnings (those that last in reverse video)."""

    def __init__(self, title: str) -> None:
        self.title, self.screen = title, None

    @staticmethod
    def usable() -> bool:
        """Whether curses knows this terminal (``$TERM``): otherwise the plain lines are shown."""
        try:
            curses.setupterm()
        except curses.error:
            return False
        return True

    def start(self) -> None:
        self.screen = curses.initscr()
        curses.noecho()
        curses.cbreak()  # Ctrl-C still interrupts the recorder
        try:
            curses.curs_set(0)
        except curses.error:  # a terminal that cannot hide its cursor
            pass

    def raised(self, alert: Alert, t0: float) -> None:
        pass  # drawn with the rest

    def show(self, state: LiveState, now: float, t0: float) -> None:
        screen = self.screen
        screen.erase()
        height, width = screen.getmaxyx()
        rows = [(f"{self.title}   t {now - t0:.1f} s", curses.A_BOLD),
                *((f"{topic:<8}{text}", 0) for topic, text in status_lines(state, now))]
        rows.append((f"WARNINGS ({len(state.active)} now, {len(state.warnings)} in all)", curses.A_BOLD))
        rows += [(alert_line(alert, t0), curses.A_REVERSE if alert.end_t is None else 0)
                 for alert in reversed(state.warnings)]
        try:
            for y, (text, attribute) in enumerate(rows[:height]):
                screen.addnstr(y, 0, text, max(width - 1, 1), attribute)
        except curses.error:  # a terminal resized while drawing: the next refresh draws it whole
            pass
        screen.refresh()

    def stop(self, state: LiveState, now: float, t0: float) -> None:
        if self.screen is not None:
            curses.nocbreak()
            curses.echo()
            curses.endwin()
            self.screen = None


class LiveMonitor:
    """Decode chunks handed over by :meth:`put` into ``state`` on a thread of its own and show them on ``display``
    (module docstring); ``now`` is the recorder's clock (the one that stamps the chunks). Use as a context manager:
    the thread runs inside it and the display is closed when it ends, whatever happened."""

    def __init__(self, state: LiveState, registry: MessageRegistry, now: Callable[[], float], display,
                 refresh_s: float = 0.5) -> None:
        self.state, self.registry, self.now, self.display = state, registry, now, display
        self.refresh_s = refresh_s
        self.t0: float | None = None
        self.error: BaseException | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._deframer = Deframer()
        self._thread = threading.Thread(target=self._run, name="live view", daemon=True)

    def put(self, chunk: Chunk) -> None:
        """Hand a recorded chunk over (never blocks)."""
        self._queue.put(chunk)

    def __enter__(self) -> "LiveMonitor":
        self.display.start()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        try:
            self._queue.put(_STOP)
            self._thread.join()
        finally:  # a second Ctrl-C while the view finishes still gives the terminal back
            try:
                self.display.stop(self.state, self.now(), self.t0 if self.t0 is not None else self.now())
            except Exception as error:  # the recording is whole; the caller says the view failed
                self.error = self.error or error

    def _run(self) -> None:
        drawn, reported = -float("inf"), 0
        try:
            while True:
                try:
                    item = self._queue.get(timeout=TICK_S)
                except queue.Empty:
                    item = None
                if item is _STOP:
                    break
                if item is not None:
                    self._decode(item)
                now = self.now()
                self.t0 = now if self.t0 is None else self.t0
                self.state.tick(now)
                for alert in self.state.warnings[reported:]:
                    self.display.raised(alert, self.t0)
                reported = len(self.state.warnings)
                if time.monotonic() - drawn >= self.refresh_s and self._queue.empty():
                    self.display.show(self.state, now, self.t0)
                    drawn = time.monotonic()
        except Exception as error:  # the recording goes on; the caller says what stopped the view
            self.error = error

    def _decode(self, chunk: Chunk) -> None:
        t = chunk.receive_time_monotonic
        if self.t0 is None:
            self.t0 = t
        for _, packet in self._deframer.feed(chunk.data):
            self.state.on_packet(t, self.registry.decode(packet))
        stats = self._deframer.stats
        self.state.on_bytes(t, stats.bytes_fed, stats.packets, stats.rejected_frames["bad_header_crc"],
                            stats.rejected_frames["bad_packet_crc"])
