"""Flight and link faults the virtual drone can be asked for (``aerostereo-render fly``'s "flight faults" options,
all off by default), so a live view (:mod:`capture.live_state`) can be tested on real bytes.

Times are seconds of flight time (the telemetry clock: since the motors started); each fault lasts ``[start_s,
end_s)``. What each does, and where:

* :class:`Gust`: pushes the aircraft horizontally, at right angles to its planned path at the gust's start (to the
  right of travel), by ``offset_m``; the push rises and falls smoothly over :data:`GUST_RISE_S` and holds in
  between (:meth:`Gust.offset_at`, added to the flight's own gust deviation in :meth:`sim.drone.flight.Flight.state_at`:
  the true path, the photos and the telemetry all follow it).
* :class:`LinkSilence`: the link sends nothing (a dropout window added to the link's own,
  :func:`sim.drone.schedule.telemetry_schedule`); the camera still takes its photos.
* :class:`GimbalStuck`: the true gimbal pitch stays at ``pitch_deg`` (photos and telemetry).
* :class:`BatteryDrain`: from ``start_s`` to the landing the battery runs down ``factor`` times faster
  (:meth:`FlightFaults.battery_time_s`, the battery clock OSD's percentage is read from).

``truth.json`` lists them under ``"faults"`` (:meth:`FlightFaults.truth`): ``{"kind", "start_s", "end_s",
"start_utc", "end_utc", ...its parameters}``.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass, fields

import numpy as np

from capture.messages import MAX_FLY_TIME_S

#: Seconds a gust's push takes to rise to its full offset (and to fall back at its end): a smoothstep.
GUST_RISE_S = 1.0
#: Bounds of the faults' parameters (what ``fly`` accepts).
MAX_FAULT_START_S = MAX_FLY_TIME_S  # the longest flight OSD's fly time holds
MAX_FAULT_DURATION_S = 600.0
MAX_GUST_OFFSET_M = 100.0
MAX_DRAIN_FACTOR = 100.0


class FaultAfterLanding(ValueError):
    """A fault asked to start once the flight has landed (its message names the option)."""


def _check_window(name: str, start_s: float, duration_s: float | None) -> None:
    if not 0.0 <= start_s <= MAX_FAULT_START_S:
        raise ValueError(f"{name}: START {start_s:g} s: expected seconds of flight time in [0, {MAX_FAULT_START_S:g}]")
    if duration_s is not None and not 0.0 < duration_s <= MAX_FAULT_DURATION_S:
        raise ValueError(f"{name}: DURATION {duration_s:g} s: expected seconds in (0, {MAX_FAULT_DURATION_S:g}]")


@dataclass(frozen=True)
class Gust:
    """A push of ``offset_m`` metres off the path for ``duration_s`` from ``start_s``."""

    start_s: float
    duration_s: float
    offset_m: float
    kind = "gust"
    option = "--gust"

    def __post_init__(self) -> None:
        _check_window(self.option, self.start_s, self.duration_s)
        if not 0.0 < self.offset_m <= MAX_GUST_OFFSET_M:
            raise ValueError(f"{self.option}: METRES {self.offset_m:g}: expected a push in "
                             f"(0, {MAX_GUST_OFFSET_M:g}] m")
        if self.duration_s < 2 * GUST_RISE_S:
            raise ValueError(f"{self.option}: DURATION {self.duration_s:g} s: a gust rises and falls over "
                             f"{GUST_RISE_S:g} s each, so it lasts at least {2 * GUST_RISE_S:g} s")

    def offset_at(self, t_s: np.ndarray, direction_enu: np.ndarray):
        """The push (N,3) m along the horizontal unit vector ``direction_enu``, its velocity (m/s) and acceleration
        (m/s^2) at times ``t_s``: a smoothstep up over :data:`GUST_RISE_S`, held, a smoothstep down."""
        t = np.atleast_1d(np.asarray(t_s, float))
        rise, rise_d, rise_dd = _smoothstep((t - self.start_s) / GUST_RISE_S)
        fall, fall_d, fall_dd = _smoothstep((self.start_s + self.duration_s - t) / GUST_RISE_S)  # runs backwards
        size = self.offset_m * rise * fall
        rate = self.offset_m * (rise_d * fall - rise * fall_d) / GUST_RISE_S
        accel = self.offset_m * (rise_dd * fall - 2 * rise_d * fall_d + rise * fall_dd) / GUST_RISE_S ** 2
        return (size[:, None] * direction_enu, rate[:, None] * direction_enu, accel[:, None] * direction_enu)


def _smoothstep(x: np.ndarray):
    """``3x^2 - 2x^3`` clipped to [0, 1], its first and second derivatives (in x)."""
    x = np.clip(x, 0.0, 1.0)
    inside = (x > 0) & (x < 1)
    return x * x * (3 - 2 * x), np.where(inside, 6 * x * (1 - x), 0.0), np.where(inside, 6 - 12 * x, 0.0)


@dataclass(frozen=True)
class LinkSilence:
    """Nothing sent for ``duration_s`` from ``start_s``."""

    start_s: float
    duration_s: float
    kind = "link_silence"
    option = "--link-silence"

    def __post_init__(self) -> None:
        _check_window(self.option, self.start_s, self.duration_s)


@dataclass(frozen=True)
class GimbalStuck:
    """The gimbal pitch held at ``pitch_deg`` (0 horizon, -90 nadir) for ``duration_s`` from ``start_s``."""

    start_s: float
    duration_s: float
    pitch_deg: float
    kind = "gimbal_stuck"
    option = "--gimbal-stuck"

    def __post_init__(self) -> None:
        _check_window(self.option, self.start_s, self.duration_s)
        if not -90.0 <= self.pitch_deg <= 0.0:
            raise ValueError(f"{self.option}: PITCH {self.pitch_deg:g}: expected degrees in [-90, 0] (0 the horizon, "
                             "-90 straight down: the gimbal's range)")


@dataclass(frozen=True)
class BatteryDrain:
    """From ``start_s`` to the landing, the battery runs down ``factor`` times faster."""

    start_s: float
    factor: float
    kind = "battery_drain"
    option = "--battery-drain"

    def __post_init__(self) -> None:
        _check_window(self.option, self.start_s, None)
        if not 1.0 < self.factor <= MAX_DRAIN_FACTOR:
            raise ValueError(f"{self.option}: FACTOR {self.factor:g}: expected how many times faster, in "
                             f"(1, {MAX_DRAIN_FACTOR:g}]")


@dataclass(frozen=True)
class FlightFaults:
    """The faults of one flight (each None when not asked for)."""

    gust: Gust | None = None
    link_silence: LinkSilence | None = None
    gimbal_stuck: GimbalStuck | None = None
    battery_drain: BatteryDrain | None = None

    def asked(self) -> list:
        """The faults asked for, in field order."""
        return [fault for fault in (getattr(self, f.name) for f in fields(self)) if fault is not None]

    def check_flight(self, duration_s: float) -> None:
        """:class:`FaultAfterLanding` naming the option of a fault that starts after the flight has landed."""
        for fault in self.asked():
            if fault.start_s >= duration_s:
                raise FaultAfterLanding(f"{fault.option}: START {fault.start_s:g} s: the flight lasts "
                                        f"{duration_s:.1f} s; expected a start within it")

    def silence_windows(self) -> np.ndarray:
        """The link silence as ``(K, 2)`` ``[start, end)`` seconds (K = 0 or 1)."""
        silence = self.link_silence
        if silence is None:
            return np.zeros((0, 2))
        return np.array([[silence.start_s, silence.start_s + silence.duration_s]])

    def gimbal_pitch_deg(self, t_s: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
        """``pitch_deg`` at times ``t_s`` with the stuck gimbal's pitch inside its window."""
        stuck = self.gimbal_stuck
        if stuck is None:
            return pitch_deg
        inside = (t_s >= stuck.start_s) & (t_s < stuck.start_s + stuck.duration_s)
        return np.where(inside, stuck.pitch_deg, pitch_deg)

    def battery_time_s(self, t_s: np.ndarray) -> np.ndarray:
        """The battery's clock at flight times ``t_s``: seconds of normal use it has spent (faster after a drain)."""
        drain = self.battery_drain
        t_s = np.asarray(t_s, float)
        if drain is None:
            return t_s
        return np.where(t_s > drain.start_s, drain.start_s + drain.factor * (t_s - drain.start_s), t_s)

    def truth(self, start_utc: dt.datetime, duration_s: float) -> list[dict]:
        """``truth.json``'s ``"faults"``: each fault's kind, its window in flight seconds and UTC (ending at the
        landing at the latest), and its parameters."""
        entries = []
        for fault in self.asked():
            parameters = asdict(fault)
            duration = parameters.pop("duration_s", None)
            end_s = min(duration_s, fault.start_s + duration) if duration is not None else duration_s
            entries.append({"kind": fault.kind, "start_s": fault.start_s, "end_s": end_s,
                            "start_utc": (start_utc + dt.timedelta(seconds=fault.start_s)).isoformat(),
                            "end_utc": (start_utc + dt.timedelta(seconds=end_s)).isoformat(),
                            **{k: v for k, v in parameters.items() if k != "start_s"}})
        return entries


NO_FAULTS = FlightFaults()
