"""A synthetic orbit flight with known poses, for tests and benchmarks of the log readers and geotagging.

The aircraft circles a centre at constant height and speed, nose and camera towards the centre; telemetry
is sampled at a chosen rate with noise; the shutter fires about every ``photo_interval_s``; the camera's
clock is ``camera_offset_s`` behind telemetry UTC (``offset = UTC - camera``) and EXIF keeps whole seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightplan.geodesy import LocalFrame

from .attitude import camera_matrix_world, wrap_deg
from .logs.photos import PhotoInfo
from .track import ReadReport, Track


@dataclass(frozen=True)
class Orbit:
    """Circle of ``radius_m`` at ``height_m`` above take-off (the centre, at ``frame``'s origin), flown
    counter-clockwise seen from above at ``speed_m_s``, starting east of the centre at ``start_s`` (UTC)."""

    frame: LocalFrame
    radius_m: float = 50.0
    height_m: float = 30.0
    speed_m_s: float = 0.694
    start_s: float = 1_700_000_000.0
    aircraft_pitch_deg: float = -2.0
    aircraft_roll_deg: float = 1.5

    def angle_rad(self, t):
        return (np.asarray(t, float) - self.start_s) * self.speed_m_s / self.radius_m

    def enu(self, t) -> np.ndarray:
        """Camera position (N, 3) in the frame's ENU metres."""
        a = self.angle_rad(t)
        return np.stack([self.radius_m * np.cos(a), self.radius_m * np.sin(a), np.full_like(a, self.height_m)], -1)

    def gimbal_ypr(self, t) -> np.ndarray:
        """Absolute gimbal yaw/pitch/roll (N, 3), looking at the centre on the ground."""
        e, n, _ = self.enu(t).T
        yaw = np.degrees(np.arctan2(-e, -n))  # bearing from the aircraft to the centre
        pitch = -math.degrees(math.atan2(self.height_m, self.radius_m))
        return np.stack([wrap_deg(yaw), np.full_like(yaw, pitch), np.zeros_like(yaw)], -1)

    def aircraft_ypr(self, t) -> np.ndarray:
        yaw = self.gimbal_ypr(t)[:, 0]
        return np.stack([yaw, np.full_like(yaw, self.aircraft_pitch_deg), np.full_like(yaw, self.aircraft_roll_deg)], -1)

    def R_world_cam(self, t) -> np.ndarray:
        g = self.gimbal_ypr(t)
        return camera_matrix_world(g[:, 0], g[:, 1], g[:, 2])


@dataclass(frozen=True)
class Noise:
    """Telemetry noise: position white noise (m, 1 sigma), attitude quantisation (deg, DJI sends 0.1 deg),
    timestamp jitter (s), shutter-event time jitter (s), shutter interval jitter (s)."""

    position_m: float = 0.01
    angle_step_deg: float = 0.1
    time_jitter_s: float = 0.002
    event_jitter_s: float = 0.005
    interval_jitter_s: float = 0.02


NOISE_FREE = Noise(0.0, 0.0, 0.0, 0.0, 0.02)


def telemetry(orbit: Orbit, duration_s: float, rate_hz: float, noise: Noise, rng: np.random.Generator,
              shutter_s: np.ndarray) -> Track:
    """The track a logger would record while flying ``orbit`` (events = shutter times + jitter)."""
    times = orbit.start_s + np.arange(0.0, duration_s, 1.0 / rate_hz)
    sample_times = times + rng.normal(0.0, noise.time_jitter_s, len(times)) if noise.time_jitter_s else times
    enu = orbit.enu(sample_times) + rng.normal(0.0, noise.position_m, (len(times), 3)) if noise.position_m \
        else orbit.enu(sample_times)
    lat, lon, h = orbit.frame.to_geodetic(*enu.T)

    def quantise(values):
        return np.round(values / noise.angle_step_deg) * noise.angle_step_deg if noise.angle_step_deg else values

    gimbal, aircraft = quantise(orbit.gimbal_ypr(sample_times)), quantise(orbit.aircraft_ypr(sample_times))
    columns = {
        "lat_deg": lat, "lon_deg": lon, "height_above_takeoff_m": h - orbit.frame.h0_m, "absolute_height_m": h,
        "gimbal_yaw_deg": gimbal[:, 0], "gimbal_pitch_deg": gimbal[:, 1], "gimbal_roll_deg": gimbal[:, 2],
        "aircraft_yaw_deg": aircraft[:, 0], "aircraft_pitch_deg": aircraft[:, 1], "aircraft_roll_deg": aircraft[:, 2],
        "speed_m_s": np.full(len(times), orbit.speed_m_s),
    }
    events = shutter_s + rng.normal(0.0, noise.event_jitter_s, len(shutter_s)) if noise.event_jitter_s else shutter_s
    return Track.from_rows(times, columns, ReadReport("synthetic", "synthetic", len(times), len(times)),
                           photo_times_s=events)


def shutter_times(orbit: Orbit, duration_s: float, interval_s: float, noise: Noise, rng: np.random.Generator):
    """Shutter times about every ``interval_s`` from 2 s after the start to 2 s before the end."""
    count = int((duration_s - 4.0) / interval_s)
    steps = interval_s + rng.normal(0.0, noise.interval_jitter_s, count)
    shutter = orbit.start_s + 2.0 + np.cumsum(steps)
    return shutter[shutter < orbit.start_s + duration_s - 2.0]


def photos_for(shutter_s: np.ndarray, camera_offset_s: float, orbit: Orbit | None = None,
               subsecond: bool = False) -> list[PhotoInfo]:
    """PhotoInfo per shutter time: EXIF time on the camera clock (``UTC - camera_offset_s``) truncated to 1 s
    (or 1 ms), and, given the orbit, the photo's own GPS position as DJI writes it (8 decimals)."""
    resolution = 0.001 if subsecond else 1.0
    camera = np.floor((shutter_s - camera_offset_s) / resolution) * resolution
    photos = [PhotoInfo(Path(f"IMG_{i:04d}.JPG"), float(t), resolution) for i, t in enumerate(camera)]
    if orbit is not None:
        lat, lon, h = orbit.frame.to_geodetic(*orbit.enu(shutter_s).T)
        for photo, la, lo, hh in zip(photos, lat, lon, h):
            photo.values.update(lat_deg=round(float(la), 8), lon_deg=round(float(lo), 8), absolute_height_m=float(hh))
    return photos
