"""The virtual drone's telemetry link: its records as DUML frames, damaged by the link, delivered to a sink.

:func:`duml_frames` encodes a flight's telemetry (``sim.drone.schedule``) with :func:`capture.messages.encode_message`:
OSD General (0x03/0x43), Gimbal Params (0x04/0x05), Home Point (0x03/0x44) and Camera State (0x02/0x80). The
camera pushes its state at a fixed ``CAMERA_STATE_HZ``, as a real one does; ``photo_state`` is 1 (single shot)
for one push interval from the shutter, so exactly one push shows each photo, and ``remaining_shots`` counts
down -- the edge ``capture`` reads as a photo event (placed midway between that push and the one before). Each frame is passed through ``FlownMission.damage_link`` in send order.

Frames carry their send time in seconds on the telemetry clock (since the motors started). Sinks:

* :func:`write_raw_capture` -- a raw capture ``NAME.duml`` + ``.idx`` whose receive times are the send times
  (simulated arrival, no latency), written atomically;
* :func:`stream` -- any ``write(bytes)`` callable (a pyserial port from ``serial.serial_for_url``: ``loop://``,
  ``socket://host:port``; the fake pyusb backend's ``push``), paced by a :class:`MissionClock`.
* :class:`FrameServer` -- a one-shot TCP server streaming to the first client (``aerostereo-ingest record --port
  socket://127.0.0.1:PORT``), paced the same way.

Time on live links: :class:`MissionClock` maps the host's monotonic clock to flight time at ``speedup`` times
real time and to UTC from ``start_utc``. It has the shape of :class:`capture.transports.Clock`, so a recorder
that stamps chunks with it records arrival times on the same time line as the photos' EXIF (at ``speedup``
1 that is simply the host's clock).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import socket
import threading
import time
from typing import Callable, Iterable, NamedTuple

import numpy as np

from capture.messages import CameraState, GimbalParams, HomePoint, OsdGeneral, encode_message
from capture.raw import atomic_capture
from capture.transports import Clock
from sim.drone.imperfections import in_windows
from sim.drone.schedule import GimbalRecord, HomeRecord, OsdRecord, ShutterRecord

#: Camera State push rate (Hz); ``photo_state`` stays "single shot" for one push interval after a shutter.
CAMERA_STATE_HZ = 5.0
#: How far a photo event read from the pushes can be from its shutter: half a push interval. With photos at a
#: fixed interval the error is the same for every photo, so the estimated clock offset carries it too.
PHOTO_EVENT_ERROR_S = 0.5 / CAMERA_STATE_HZ
#: DJI flight modes (OSD ctrl_info bits 0-6): 6 = GPS_Atti (P-mode); 14 = waypoint mission.
MODE_GPS_ATTI, MODE_WAYPOINT = 6, 14
GPS_LEVEL_GOOD = 5
REMAINING_SHOTS_AT_START = 9999
OSD_TEMPLATE = OsdGeneral(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ctrl_info=MODE_GPS_ATTI, latest_app_command=0,
                          controller_state=0, gps_satellites=0, gohome_reason=0, motor_start_fail=0, ctrl_state_ext=0,
                          battery_percent=100, ultrasonic_height_m=0.0, fly_time_s=0.0, motor_start_count=1,
                          battery_alarm1=0, battery_alarm2=0, version_match=1, product_type=0,
                          imu_init_fail_reason=0)
CAMERA_TEMPLATE = CameraState(status_flags=1 << 9, camera_mode=0, sd_total_mb=30000, sd_free_mb=20000,
                              remaining_shots=REMAINING_SHOTS_AT_START, remaining_time_s=0, file_index_mode=0)


class Frame(NamedTuple):
    """One DUML frame as the link delivers it (possibly damaged) and its send time (s, telemetry clock)."""

    t_s: float
    data: bytes


def osd_message(r: OsdRecord) -> OsdGeneral:
    """OSD General for a telemetry record; velocity x/y/z are north/east/down (m/s), as DJI sends them."""
    return dataclasses.replace(
        OSD_TEMPLATE, longitude_deg=r.longitude_deg, latitude_deg=r.latitude_deg,
        height_above_takeoff_m=r.height_above_takeoff_m, velocity_x_mps=r.velocity_north_mps,
        velocity_y_mps=r.velocity_east_mps, velocity_z_mps=r.velocity_down_mps, pitch_deg=r.pitch_deg,
        roll_deg=r.roll_deg, yaw_deg=r.yaw_deg, ctrl_info=MODE_WAYPOINT if r.phase == "mission" else MODE_GPS_ATTI,
        controller_state=GPS_LEVEL_GOOD << 18, gps_satellites=r.satellites, battery_percent=r.battery_percent,
        fly_time_s=r.fly_time_s)


def gimbal_message(r: GimbalRecord) -> GimbalParams:
    """Gimbal Params (absolute NED degrees), yaw-follow mode."""
    return GimbalParams(r.pitch_deg, r.roll_deg, r.yaw_deg, mode_flags=2 << 6, roll_adjust_deg=0.0,
                        joystick_yaw_deg=0.0, limit_flags=0, version_flags=1)


def home_message(r: HomeRecord) -> HomePoint:
    """Home Point, set (state bit 0); its altitude is the take-off point's ellipsoidal height (m)."""
    return HomePoint(r.longitude_deg, r.latitude_deg, r.height_ellipsoid_m, home_state=1, go_home_height_m=30,
                     course_lock_angle=0, data_recorder_status=0, data_recorder_remaining_capacity=0,
                     data_recorder_remaining_time=0, data_recorder_file_index=0)


def camera_states(shutter: Iterable[ShutterRecord], duration_s: float, dropouts_s: np.ndarray):
    """``(t_s, CameraState)`` pushes every 1/CAMERA_STATE_HZ (pushes inside a link dropout are lost; the
    shutter records already are); ``photo_state`` 1 at the first push at or after a shutter."""
    shots = np.array([r.t_s for r in shutter])
    period_s = 1.0 / CAMERA_STATE_HZ
    times = np.arange(0.0, duration_s + 1e-9, period_s)
    times = times[~in_windows(times, dropouts_s)]
    taken_before = np.searchsorted(shots, times, side="right")
    last_shot = np.concatenate([[-np.inf], shots])[taken_before]  # -inf before the first shot (or with none)
    shooting = times - last_shot < period_s - 1e-9
    return [(float(t), dataclasses.replace(
                CAMERA_TEMPLATE, status_flags=CAMERA_TEMPLATE.status_flags | (int(s) << 3),
                remaining_shots=REMAINING_SHOTS_AT_START - int(n)))
            for t, s, n in zip(times, shooting, taken_before)]


def telemetry_messages(mission) -> list[tuple[float, object]]:
    """Every DUML message of a :class:`sim.drone.FlownMission` as ``(t_s, record)``, in send order."""
    telemetry = mission.telemetry
    timed = [(r.t_s, osd_message(r)) for r in telemetry.osd]
    timed += [(r.t_s, gimbal_message(r)) for r in telemetry.gimbal]
    timed += [(r.t_s, home_message(r)) for r in telemetry.home]
    timed += camera_states(telemetry.shutter, mission.flight.duration_s, telemetry.dropouts_s)
    return sorted(timed, key=lambda item: item[0])  # stable: ties keep OSD, gimbal, home, camera order


def duml_frames(mission) -> list[Frame]:
    """The flight's DUML frames as the link delivers them (``mission.damage_link`` applied, in order).

    The link's damage is drawn from the mission's link generator as the frames are made: encode once and give
    the same frames to every sink.
    """
    return [Frame(t, mission.damage_link(encode_message(record, seq).encode()))
            for seq, (t, record) in enumerate(telemetry_messages(mission))]


def write_raw_capture(frames: list[Frame], path, start_utc: dt.datetime) -> None:
    """Write ``frames`` as a raw capture ``path`` + ``path.idx``: one chunk per frame, received at
    ``start_utc + t_s`` (monotonic time = ``t_s``); both files atomically. Frames the link lost entirely
    (empty) are skipped."""
    with atomic_capture(path) as writer:
        for frame in frames:
            writer.append(start_utc + dt.timedelta(seconds=frame.t_s), frame.t_s, frame.data)


class MissionClock(Clock):
    """Flight time at ``speedup`` times real time since construction (or :meth:`restart`), and UTC from
    ``start_utc`` (None: this machine's clock, :attr:`follows_host`). Implements :class:`capture.transports.Clock`
    (``utc``, ``monotonic``, ``sleep``) on the flight's time line, so a recorder using it stamps chunks in flight
    time."""

    def __init__(self, speedup: float = 1.0, start_utc: dt.datetime | None = None):
        if not (math.isfinite(speedup) and speedup > 0):
            raise ValueError(f"speed-up must be a positive number, got {speedup}")
        self.speedup = speedup
        #: Whether the flight started "now": its UTC is this machine's at every (re)start, as a recorder in another
        #: process stamps it.
        self.follows_host = start_utc is None
        self.start_utc = start_utc or dt.datetime.now(dt.timezone.utc)
        self._anchor = time.monotonic()

    def restart(self, at_s: float = 0.0) -> None:
        """Flight time ``at_s`` is now (a stream that starts mid-flight); a clock that :attr:`follows_host` moves its
        ``start_utc`` with it, so that flight time ``at_s`` is this machine's UTC now."""
        self._anchor = time.monotonic() - at_s / self.speedup
        if self.follows_host:
            self.start_utc = dt.datetime.now(dt.timezone.utc) - dt.timedelta(seconds=at_s)

    def flight_time_s(self) -> float:
        """Seconds of flight time since the start."""
        return (time.monotonic() - self._anchor) * self.speedup

    def utc(self) -> dt.datetime:
        return self.start_utc + dt.timedelta(seconds=self.flight_time_s())

    def monotonic(self) -> float:
        return self.flight_time_s()

    def sleep(self, seconds: float, stop: threading.Event) -> None:
        stop.wait(seconds / self.speedup)

    def wait_until(self, t_s: float) -> None:
        """Block until flight time ``t_s`` (returns at once when it has passed)."""
        delay = (t_s - self.flight_time_s()) / self.speedup
        if delay > 0:
            time.sleep(delay)


def stream(frames: list[Frame], write: Callable[[bytes], object], clock: MissionClock,
           progress: Callable[[int], object] | None = None) -> int:
    """Send ``frames`` through ``write`` at their send times on ``clock``; frames due together go in one write.

    Returns the number of bytes written. ``progress(n)`` is called with the frames sent by each write.
    """
    sent = 0
    start = 0
    while start < len(frames):
        end = start
        while end < len(frames) and frames[end].t_s == frames[start].t_s:
            end += 1
        clock.wait_until(frames[start].t_s)
        data = b"".join(frame.data for frame in frames[start:end])
        if data:
            write(data)
            sent += len(data)
        if progress is not None:
            progress(end - start)
        start = end
    return sent


class FrameServer(threading.Thread):
    """A one-shot TCP server on ``host`` (port chosen by the system: :attr:`port`) that streams ``frames`` to the
    first client, paced by ``clock`` (default: ``speedup`` times real time from ``start_utc``), restarted when the
    client connects at flight time ``from_s`` (give it the frames from there; a receiver stamping with the same clock
    has the flight's time line), then closes: the virtual
    drone's end of ``aerostereo-ingest record --port socket://HOST:PORT``, until the client leaves. ``sent``: bytes
    of the writes the kernel took whole; ``stream_s``: wall seconds from the connection to the last write."""

    def __init__(self, frames: list[Frame], speedup: float = 1.0, start_utc: dt.datetime | None = None,
                 host: str = "127.0.0.1", from_s: float = 0.0, clock: MissionClock | None = None) -> None:
        super().__init__(name="frame server", daemon=True)
        self.frames, self.from_s = frames, from_s
        self.listener = socket.create_server((host, 0))
        self.port = self.listener.getsockname()[1]
        self.sent, self.stream_s = 0, 0.0
        self.clock = clock or MissionClock(speedup, start_utc)

    def run(self) -> None:
        with self.listener:
            connection, _ = self.listener.accept()
        with connection:
            self.clock.restart(at_s=self.from_s)
            started = time.monotonic()
            try:
                stream(self.frames, self._sender(connection), self.clock)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the client left (a recorder's --duration ran out): what it took is in ``sent``
            self.stream_s = time.monotonic() - started

    def _sender(self, connection: socket.socket) -> Callable[[bytes], None]:
        def send(data: bytes) -> None:
            connection.sendall(data)
            self.sent += len(data)
        return send
