"""The telemetry the aircraft sends, as plain timed records (measured values), ready to be encoded as DUML.

Streams and default rates follow real DJI traffic (research/dji-telemetry.md §2.7): OSD General 10 Hz,
gimbal (50 Hz on a P3X; 10 Hz here by default, configurable), home point 1 Hz, and a camera shutter event
per photo actually taken. Times are seconds on the telemetry clock (since the motors started). Records
inside a link dropout window are not sent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.drone.flight import PHASES, Flight
from sim.drone.imperfections import dropout_windows, in_windows
from sim.drone.sensors import Sensors

#: Full battery lasts this long (Mini SE: "30 min maximum flight time", at best; 25 min is a typical day).
BATTERY_ENDURANCE_S = 25 * 60.0
#: Satellites in view reported in OSD (constant: the sky does not change during a short flight).
SATELLITES = 14


@dataclass(frozen=True)
class TelemetryRates:
    """Send rates of the streams (Hz)."""

    osd_hz: float = 10.0
    gimbal_hz: float = 10.0
    home_hz: float = 1.0


@dataclass(frozen=True)
class OsdRecord:
    """OSD General: measured position (degrees; the encoder converts to radians), barometric height above
    take-off (m), ground velocity NED (m/s), aircraft attitude (degrees, yaw in [-180, 180))."""

    t_s: float
    latitude_deg: float
    longitude_deg: float
    height_above_takeoff_m: float
    velocity_north_mps: float
    velocity_east_mps: float
    velocity_down_mps: float
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    phase: str
    motors_on: bool
    in_air: bool
    satellites: int
    battery_percent: int
    fly_time_s: float


@dataclass(frozen=True)
class GimbalRecord:
    """Gimbal attitude in the earth frame (degrees): pitch 0 = horizon, -90 = nadir; yaw from north."""

    t_s: float
    pitch_deg: float
    roll_deg: float
    yaw_deg: float


@dataclass(frozen=True)
class HomeRecord:
    """Home point as recorded at take-off: degrees and ellipsoidal height (m)."""

    t_s: float
    latitude_deg: float
    longitude_deg: float
    height_ellipsoid_m: float


@dataclass(frozen=True)
class ShutterRecord:
    """The camera took photo ``photo_index`` (0-based over the scheduled photos) at ``t_s``."""

    t_s: float
    photo_index: int


@dataclass(frozen=True)
class Telemetry:
    """All records of a flight, per stream in time order, and the dropout windows that removed some."""

    osd: tuple[OsdRecord, ...]
    gimbal: tuple[GimbalRecord, ...]
    home: tuple[HomeRecord, ...]
    shutter: tuple[ShutterRecord, ...]
    dropouts_s: np.ndarray

    def merged(self) -> list:
        """Every record of every stream in send order (by time; ties keep OSD, gimbal, home, shutter order)."""
        records = [*self.osd, *self.gimbal, *self.home, *self.shutter]
        return sorted(records, key=lambda r: r.t_s)


def _sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    return np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)


def osd_records(flight: Flight, sensors: Sensors, t_s: np.ndarray) -> list[OsdRecord]:
    """OSD General records at times ``t_s``; the battery runs down evenly over :data:`BATTERY_ENDURANCE_S` of its
    clock (the flight's, faster after a battery-drain fault)."""
    truth = flight.state_at(t_s)
    m = sensors.measure(truth)
    battery_s = flight.faults.battery_time_s(t_s)
    battery = np.clip(np.round(100.0 * (1.0 - battery_s / BATTERY_ENDURANCE_S)), 0, 100).astype(int)
    return [
        OsdRecord(
            t_s=float(t), latitude_deg=float(m.latitude_deg[i]), longitude_deg=float(m.longitude_deg[i]),
            height_above_takeoff_m=float(m.height_above_takeoff_m[i]),
            velocity_north_mps=float(m.velocity_enu_mps[i, 1]), velocity_east_mps=float(m.velocity_enu_mps[i, 0]),
            velocity_down_mps=float(-m.velocity_enu_mps[i, 2]),
            yaw_deg=float(m.aircraft_ypr_deg[i, 0]), pitch_deg=float(m.aircraft_ypr_deg[i, 1]),
            roll_deg=float(m.aircraft_ypr_deg[i, 2]),
            phase=PHASES[truth.phase[i]], motors_on=True, in_air=bool(truth.phase[i] != 0),
            satellites=SATELLITES, battery_percent=int(battery[i]), fly_time_s=float(t),
        )
        for i, t in enumerate(t_s)
    ]


def gimbal_records(flight: Flight, sensors: Sensors, t_s: np.ndarray) -> list[GimbalRecord]:
    """Gimbal attitude records at times ``t_s``."""
    g = sensors.measure(flight.state_at(t_s)).gimbal_ypr_deg
    return [GimbalRecord(float(t), float(g[i, 1]), float(g[i, 2]), float(g[i, 0])) for i, t in enumerate(t_s)]


def telemetry_schedule(flight: Flight, sensors: Sensors, shutter_times_s: np.ndarray, photo_indices: np.ndarray,
                       rng: np.random.Generator, rates: TelemetryRates = TelemetryRates()) -> Telemetry:
    """Every record the aircraft sends during ``flight``, minus those lost in link dropouts (drawn from ``rng``,
    and the flight's link-silence fault)."""
    imp = flight.imperfections
    windows = dropout_windows(flight.duration_s, imp.dropout_rate_per_min, imp.dropout_mean_s, rng)
    windows = np.concatenate([windows, flight.faults.silence_windows()])

    def kept(times):
        return times[~in_windows(times, windows)]

    home_lat, home_lon, home_h = sensors.measured_home()
    shutter_times_s = np.asarray(shutter_times_s, float)
    shutter_kept = ~in_windows(shutter_times_s, windows)
    return Telemetry(
        osd=tuple(osd_records(flight, sensors, kept(_sample_times(flight.duration_s, rates.osd_hz)))),
        gimbal=tuple(gimbal_records(flight, sensors, kept(_sample_times(flight.duration_s, rates.gimbal_hz)))),
        home=tuple(HomeRecord(float(t), home_lat, home_lon, home_h)
                   for t in kept(_sample_times(flight.duration_s, rates.home_hz))),
        shutter=tuple(ShutterRecord(float(t), int(i))
                      for t, i in zip(shutter_times_s[shutter_kept], np.asarray(photo_indices)[shutter_kept])),
        dropouts_s=windows,
    )
