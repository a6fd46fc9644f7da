"""The flight as the app would log it: a ``capture.track.Track`` of the telemetry the aircraft sent, written as
a Litchi-style flight-log CSV and a DJI SRT with :mod:`capture.logs.writers` (what ``--logs`` adds)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from capture.logs.writers import write_litchi_csv, write_srt
from capture.track import Home, ReadReport, Track


def telemetry_track(mission, start_utc: dt.datetime, geoid_undulation_m: float = 0.0) -> Track:
    """One row per OSD record sent (UTC = ``start_utc`` + telemetry time), with the gimbal record of the same
    instant (NaN where none was sent); photo events at the shutter records; home = the recorded home point.
    Heights: ``height_above_takeoff_m`` barometric; ``absolute_height_m`` (and the home's) above sea level = the
    recorded home's ellipsoidal height - ``geoid_undulation_m`` (N, m) + the barometric height."""
    osd = mission.telemetry.osd
    gimbal = {r.t_s: r for r in mission.telemetry.gimbal}
    home_lat, home_lon, home_h_ellipsoid = mission.sensors.measured_home()
    home_h = home_h_ellipsoid - geoid_undulation_m
    t = np.array([r.t_s for r in osd])
    nan = float("nan")
    g = [gimbal.get(r.t_s) for r in osd]
    columns = {
        "lat_deg": [r.latitude_deg for r in osd], "lon_deg": [r.longitude_deg for r in osd],
        "height_above_takeoff_m": [r.height_above_takeoff_m for r in osd],
        "absolute_height_m": [home_h + r.height_above_takeoff_m for r in osd],
        "aircraft_yaw_deg": [r.yaw_deg for r in osd], "aircraft_pitch_deg": [r.pitch_deg for r in osd],
        "aircraft_roll_deg": [r.roll_deg for r in osd],
        "speed_m_s": [float(np.hypot(r.velocity_north_mps, r.velocity_east_mps)) for r in osd],
        "gimbal_yaw_deg": [x.yaw_deg if x else nan for x in g], "gimbal_pitch_deg": [x.pitch_deg if x else nan for x in g],
        "gimbal_roll_deg": [x.roll_deg if x else nan for x in g],
    }
    start = start_utc.timestamp()
    report = ReadReport("virtual drone", "telemetry", len(osd), len(osd))
    return Track.from_rows(start + t, {k: np.asarray(v, float) for k, v in columns.items()}, report,
                           photo_times_s=[start + r.t_s for r in mission.telemetry.shutter],
                           home=Home(home_lat, home_lon, home_h))


def write_flight_logs(mission, start_utc: dt.datetime, out_dir, geoid_undulation_m: float = 0.0) -> tuple[Path, Path]:
    """Write ``flight_log.csv`` (Litchi flight-log columns: its ``altitude(m)`` is the height above take-off, as
    in Litchi's own logs, never a GPS altitude) and ``flight.srt`` (dated DJI style: ``rel_alt`` above take-off,
    ``abs_alt`` above sea level, see :func:`telemetry_track`) into ``out_dir``."""
    track = telemetry_track(mission, start_utc, geoid_undulation_m)
    csv_path, srt_path = Path(out_dir) / "flight_log.csv", Path(out_dir) / "flight.srt"
    write_litchi_csv(track, csv_path)
    write_srt(track, srt_path, style="dated")
    return csv_path, srt_path
