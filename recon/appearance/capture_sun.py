"""The capture sun of every photo: where the sun stood (apparent azimuth and elevation, from the ephemeris of
:func:`sim.sampling.sun.solar_position`) over the scene's origin at the photo's UTC time.

A photo's UTC time comes from its geotag (the telemetry's clock, with the camera clock offset that geotagging found)
or from its EXIF time when the camera wrote its time zone (``OffsetTimeOriginal``) or the user gives it
(``--capture-utc-offset``); else from its EXIF clock and the UTC offset its shadows show
(:func:`recon.appearance.shadow_timing.fit_utc_offset`). Either way the shadows may refine the clock and the model's yaw
(:func:`recon.appearance.shadow_timing.refine_capture_time`). A photo set that cannot be timed is not guessed at: it
gets no capture sun, and its texture keeps the capture day's light (said in the log and in ``texture_report.json``).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

import numpy as np

from flightplan.geodesy import LocalFrame
from recon.appearance.shadow_timing import ShadowFit
from sim.render.shade import Sun
from sim.sampling.sun import solar_position


@dataclass(frozen=True)
class CaptureSuns:
    """Each photo's capture sun: ``azimuth_deg``, ``elevation_deg`` (K,) the true sun, where its time came from, and
    the shadow fit that timed or refined it (``timing``; its ``yaw_deg`` turns the sun into the model's frame)."""

    names: tuple[str, ...]
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    time_source: str
    timing: ShadowFit | None = None

    @property
    def directions_enu(self) -> np.ndarray:
        """(K, 3) unit vectors towards each photo's sun in the model's ENU frame (the true sun turned by the
        timing's yaw), zeros where it was down."""
        yaw = 0.0 if self.timing is None else self.timing.yaw_deg
        directions = np.array([Sun(az + yaw, el).direction_enu for az, el in zip(self.azimuth_deg, self.elevation_deg)])
        directions[self.elevation_deg <= 0] = 0.0
        return directions

    def for_names(self, names) -> "CaptureSuns":
        """The suns of ``names`` (in that order)."""
        index = {name: k for k, name in enumerate(self.names)}
        rows = [index[name] for name in names]
        return CaptureSuns(tuple(names), self.azimuth_deg[rows], self.elevation_deg[rows], self.time_source,
                           self.timing)

    def description(self) -> dict:
        """What scene.json records: the time source, the shadow fit (if any) and each photo's true sun,
        ``[azimuth, elevation]`` degrees."""
        timing = {} if self.timing is None else {"shadow_fit": self.timing.description()}
        return {"time_source": self.time_source, **timing,
                "per_photo": {name: [round(float(az), 3), round(float(el), 3)]
                              for name, az, el in zip(self.names, self.azimuth_deg, self.elevation_deg)}}


def capture_suns(names, utc_time_s: np.ndarray, origin: LocalFrame, time_source: str,
                 timing: ShadowFit | None = None) -> CaptureSuns:
    """The capture suns of photos ``names`` taken at ``utc_time_s`` (seconds since the epoch, UTC) over ``origin``."""
    positions = [solar_position(origin.lat0_deg, origin.lon0_deg,
                                dt.datetime.fromtimestamp(float(t), dt.timezone.utc)) for t in utc_time_s]
    azimuth, elevation = (np.array(values, dtype=float) for values in zip(*positions))
    return CaptureSuns(tuple(names), azimuth, elevation, time_source, timing)


def utc_offset_text(offset_h: float) -> str:
    """``+HH:MM`` of a UTC offset in hours (east positive)."""
    minutes = round(abs(offset_h) * 60.0)
    return f"{'-' if offset_h < 0 else '+'}{minutes // 60:02d}:{minutes % 60:02d}"


def is_timed(utc_time_s) -> bool:
    """Whether every photo has a UTC time."""
    return utc_time_s is not None and len(utc_time_s) > 0 and all(math.isfinite(float(t)) for t in utc_time_s)
